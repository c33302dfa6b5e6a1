//! Reading an evidence file (`infer --evidence`, `docs/FORMATS.md`) as a stream.
//!
//! The file is parsed in one pass from a buffered reader: every row is checked
//! against the map as it is read (place id, length, values) and stored in place
//! order, so memory is one row per place of the map whatever the file holds, and a
//! row longer than the map's class count is counted, not kept. A file larger than
//! an evidence file of the map can need ([`size_limit`]) is refused before it is
//! read. Errors name the file and the line of the row's key: the lines serde reads
//! are counted as it reads them ([`LineCounter`]), so no line is looked up twice.

use std::cell::{Cell, RefCell};
use std::fmt;
use std::io::{BufReader, Read};
use std::path::Path;
use std::rc::Rc;

use anyhow::{Result, anyhow, bail};
use graphspn_compiler::json_error::json_message;
use graphspn_compiler::map::TopoMap;
use graphspn_compiler::map::cold::Dropped;
use serde::de::{DeserializeSeed, IgnoredAny, MapAccess, SeqAccess, Visitor};

/// Version of the evidence file format.
pub const EVIDENCE_FORMAT: u32 = 1;

/// Largest evidence file (bytes) accepted for a map of `places` places and
/// `classes` classes: 64 KiB plus 64 bytes per value and two more per row (a
/// pretty-printed row with full-precision numbers takes about 25 bytes per value).
pub fn size_limit(places: usize, classes: usize) -> u64 {
    (64 << 10) + places as u64 * (classes as u64 + 2) * 64
}

/// A reader that counts the newlines it has passed on. serde_json reads one byte at a
/// time and looks at most one byte ahead, so when a key has been read, the count is
/// the number of line breaks before it.
struct LineCounter<R> {
    inner: R,
    newlines: Rc<Cell<usize>>,
    bytes: Rc<Cell<u64>>,
}

impl<R: Read> Read for LineCounter<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        let k = buf[..n].iter().filter(|&&b| b == b'\n').count();
        self.newlines.set(self.newlines.get() + k);
        self.bytes.set(self.bytes.get() + n as u64);
        Ok(n)
    }
}

/// What the rows are checked against, and where they go.
struct Target<'a> {
    map: &'a TopoMap,
    dropped: &'a Dropped,
    /// `--evidence FILE`, the prefix of every message.
    at: String,
    newlines: Rc<Cell<usize>>,
    /// One row per place (all ones: no evidence).
    rows: Vec<Vec<f64>>,
    /// Per place: the key and line of its row, once read.
    seen: Vec<Option<(Box<str>, usize)>>,
    /// The first problem found in a row (reported instead of serde's error).
    problem: RefCell<Option<anyhow::Error>>,
}

impl Target<'_> {
    fn fail<E: serde::de::Error>(&self, e: anyhow::Error) -> E {
        *self.problem.borrow_mut() = Some(e);
        E::custom("bad evidence row")
    }

    /// Checks the row of `key` read at `line` (its values in `row`, `len` of them)
    /// and stores it.
    fn accept(&mut self, key: &str, line: usize, row: Vec<f64>, len: usize) -> Result<()> {
        let at = format!("{}:{line}", self.at);
        let Ok(id) = key.parse::<u32>() else {
            bail!("{at}: {key:?} is not a place id");
        };
        let map = self.map;
        let Some(i) = map.index_of_id(id) else {
            match self.dropped.reason(id) {
                Some(why) => bail!(
                    "{at}: place id {id} was dropped when loading map {:?}: {why}",
                    map.name
                ),
                None => bail!("{at}: place id {id} is not in map {:?}", map.name),
            }
        };
        if let Some((first, first_line)) = &self.seen[i] {
            bail!(
                "{at}: place id {id} is listed twice (first as {first:?} on line {first_line}); give each place one row"
            );
        }
        let c = map.classes.len();
        if len != c {
            bail!(
                "{at}: place id {id} has {len} likelihoods, the map has {c} classes ({})",
                map.classes.names().join(", ")
            );
        }
        if let Some(k) = row.iter().position(|a| !a.is_finite() || *a < 0.0) {
            bail!(
                "{at}: place id {id}: likelihood of class {} is {} (must be finite and >= 0)",
                map.classes.name(k as u16),
                row[k]
            );
        }
        if row.iter().all(|&a| a == 0.0) {
            bail!("{at}: place id {id}: every likelihood is 0");
        }
        self.seen[i] = Some((key.into(), line));
        self.rows[i] = row;
        Ok(())
    }
}

/// The top-level object: `format` and `evidence`, nothing else.
struct FileSeed<'t, 'a>(&'t mut Target<'a>);

impl<'de> DeserializeSeed<'de> for FileSeed<'_, '_> {
    type Value = ();
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for FileSeed<'_, '_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an evidence file: {\"format\": 1, \"evidence\": {...}}")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<(), A::Error> {
        use serde::de::Error;
        let (mut format, mut evidence) = (None, false);
        while let Some(key) = m.next_key::<String>()? {
            match key.as_str() {
                "format" if format.is_none() => {
                    let f = m.next_value::<u32>()?;
                    if f != EVIDENCE_FORMAT {
                        let e = anyhow!(
                            "{}: evidence format {f} (this tool reads format {EVIDENCE_FORMAT})",
                            self.0.at
                        );
                        return Err(self.0.fail(e));
                    }
                    format = Some(f);
                }
                "evidence" if !evidence => {
                    m.next_value_seed(RowsSeed(&mut *self.0))?;
                    evidence = true;
                }
                "format" => return Err(A::Error::duplicate_field("format")),
                "evidence" => return Err(A::Error::duplicate_field("evidence")),
                other => return Err(A::Error::unknown_field(other, &["format", "evidence"])),
            }
        }
        if !evidence {
            return Err(A::Error::missing_field("evidence"));
        }
        match format {
            Some(_) => Ok(()),
            None => Err(A::Error::missing_field("format")),
        }
    }
}

/// The `evidence` object: place id → row, checked and stored one by one.
struct RowsSeed<'t, 'a>(&'t mut Target<'a>);

impl<'de> DeserializeSeed<'de> for RowsSeed<'_, '_> {
    type Value = ();
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for RowsSeed<'_, '_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an object from place ids to likelihood lists")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<(), A::Error> {
        let t = self.0;
        let classes = t.map.classes.len();
        while let Some(key) = m.next_key::<String>()? {
            let line = t.newlines.get() + 1;
            let (row, len) = m.next_value_seed(RowSeed(classes))?;
            if let Err(e) = t.accept(&key, line, row, len) {
                return Err(t.fail(e));
            }
        }
        Ok(())
    }
}

/// One row: its first `classes` values are kept, the rest only counted.
struct RowSeed(usize);

impl<'de> DeserializeSeed<'de> for RowSeed {
    type Value = (Vec<f64>, usize);
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for RowSeed {
    type Value = (Vec<f64>, usize);
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a list of likelihoods")
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut s: A) -> Result<Self::Value, A::Error> {
        let mut row = Vec::with_capacity(self.0);
        let mut len = 0;
        while len < self.0 {
            match s.next_element::<f64>()? {
                Some(x) => row.push(x),
                None => return Ok((row, len)),
            }
            len += 1;
        }
        while s.next_element::<IgnoredAny>()?.is_some() {
            len += 1;
        }
        Ok((row, len))
    }
}

/// Reads the evidence file `file` for `map`: one row per place (place order), all
/// ones (no evidence) where none is given. Errors name the file, the line and the
/// place id; a place listed twice is an error; a place the COLD loader dropped is
/// explained; a file larger than [`size_limit`] is refused before it is read.
pub fn read_evidence(file: &Path, map: &TopoMap, dropped: &Dropped) -> Result<Vec<Vec<f64>>> {
    let at = format!("--evidence {}", file.display());
    let f = std::fs::File::open(file).map_err(|e| anyhow!("{at}: {e}"))?;
    let limit = size_limit(map.num_places(), map.classes.len());
    let size = f.metadata().map(|m| m.len()).unwrap_or(0);
    let too_large = |size: String| {
        anyhow!(
            "{at}: {size}, more than an evidence file for map {:?} can need (at most {}: {} places, {} classes); is it the evidence of this map?",
            map.name,
            megabytes(limit),
            map.num_places(),
            map.classes.len()
        )
    };
    if size > limit {
        return Err(too_large(megabytes(size)));
    }
    let newlines = Rc::new(Cell::new(0));
    let bytes = Rc::new(Cell::new(0));
    // A pipe or a growing file is cut after the limit (and then refused below).
    let reader = LineCounter {
        inner: BufReader::with_capacity(1 << 16, f.take(limit + 1)),
        newlines: newlines.clone(),
        bytes: bytes.clone(),
    };
    let mut target = Target {
        map,
        dropped,
        at: at.clone(),
        newlines,
        rows: vec![vec![1.0; map.classes.len()]; map.num_places()],
        seen: vec![None; map.num_places()],
        problem: RefCell::new(None),
    };
    let mut de = serde_json::Deserializer::from_reader(reader);
    let parsed = FileSeed(&mut target)
        .deserialize(&mut de)
        .and_then(|()| de.end());
    if bytes.get() > limit {
        return Err(too_large(format!("over {}", megabytes(limit))));
    }
    if let Some(e) = target.problem.take() {
        return Err(e);
    }
    match parsed {
        Ok(()) => Ok(target.rows),
        Err(e) if e.is_io() => bail!("{at}: {e}"),
        Err(e) => bail!(
            "{at}:{}:{}: not a valid evidence file: {}",
            e.line(),
            e.column(),
            json_message(&e)
        ),
    }
}

/// `bytes` in megabytes, e.g. `12.3 MB`.
fn megabytes(bytes: u64) -> String {
    format!("{:.1} MB", bytes as f64 / 1e6)
}
