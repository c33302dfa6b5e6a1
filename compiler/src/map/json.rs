//! Our JSON map format (version 1).
//!
//! ```json
//! {
//!   "format": 1,
//!   "name": "floor",
//!   "classes": ["DW", "CR"],
//!   "places": [{ "id": 0, "class": "CR", "placeholder": false, "x": 0.0, "y": 0.8 }],
//!   "edges": [[0, 1]]
//! }
//! ```
//!
//! Places are written in place order (sorted by id), one per line, classes by
//! name (`null` when unannotated), edges as sorted id pairs `[a, b]` with
//! `a < b`, one per line. Output is deterministic and floats round-trip
//! exactly (shortest representation; read back with serde_json's
//! `float_roundtrip`).

use std::path::Path;

use serde::de::{DeserializeSeed, IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Serialize};

use super::{ClassSet, MapError, Place, PlaceId, TopoMap};

/// The map format version this build writes and reads.
pub const MAP_FORMAT: u64 = 1;

/// The file as written ([`MapSeed`] reads it, keeping at most a given number of places).
#[derive(Serialize)]
struct MapFile {
    format: u64,
    name: String,
    classes: Vec<String>,
    places: Vec<PlaceJson>,
    edges: Vec<[PlaceId; 2]>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PlaceJson {
    id: PlaceId,
    class: Option<String>,
    placeholder: bool,
    x: f64,
    y: f64,
}

/// Pretty printing (two-space indent), except that containers nested three
/// deep (one place object, one edge pair) are written on one line:
/// `{"id": 3, "class": "CR", ...}`, `[3, 7]`.
#[derive(Default)]
struct OnePerLine {
    pretty: serde_json::ser::PrettyFormatter<'static>,
    depth: usize,
}

const COMPACT_DEPTH: usize = 3;

impl OnePerLine {
    fn compact(&self) -> bool {
        self.depth >= COMPACT_DEPTH
    }
}

type Io = std::io::Result<()>;

impl serde_json::ser::Formatter for OnePerLine {
    fn begin_array<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> Io {
        self.depth += 1;
        if self.compact() {
            w.write_all(b"[")
        } else {
            self.pretty.begin_array(w)
        }
    }
    fn end_array<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> Io {
        let compact = self.compact();
        self.depth -= 1;
        if compact {
            w.write_all(b"]")
        } else {
            self.pretty.end_array(w)
        }
    }
    fn begin_array_value<W: ?Sized + std::io::Write>(&mut self, w: &mut W, first: bool) -> Io {
        if self.compact() {
            if first { Ok(()) } else { w.write_all(b", ") }
        } else {
            self.pretty.begin_array_value(w, first)
        }
    }
    fn end_array_value<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> Io {
        if self.compact() {
            Ok(())
        } else {
            self.pretty.end_array_value(w)
        }
    }
    fn begin_object<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> Io {
        self.depth += 1;
        if self.compact() {
            w.write_all(b"{")
        } else {
            self.pretty.begin_object(w)
        }
    }
    fn end_object<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> Io {
        let compact = self.compact();
        self.depth -= 1;
        if compact {
            w.write_all(b"}")
        } else {
            self.pretty.end_object(w)
        }
    }
    fn begin_object_key<W: ?Sized + std::io::Write>(&mut self, w: &mut W, first: bool) -> Io {
        if self.compact() {
            if first { Ok(()) } else { w.write_all(b", ") }
        } else {
            self.pretty.begin_object_key(w, first)
        }
    }
    fn begin_object_value<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> Io {
        if self.compact() {
            w.write_all(b": ")
        } else {
            self.pretty.begin_object_value(w)
        }
    }
    fn end_object_value<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> Io {
        if self.compact() {
            Ok(())
        } else {
            self.pretty.end_object_value(w)
        }
    }
}

fn json_error(e: serde_json::Error) -> MapError {
    MapError::Json {
        line: e.line(),
        column: e.column(),
        message: crate::json_error::json_message(&e),
    }
}

impl TopoMap {
    /// The map as pretty-printed JSON (format 1), deterministic.
    pub fn to_json(&self) -> String {
        let places = self
            .places()
            .map(|p| PlaceJson {
                id: p.id,
                class: p.class.map(|c| self.classes.name(c).to_string()),
                placeholder: p.placeholder,
                x: p.x,
                y: p.y,
            })
            .collect();
        let mut edges: Vec<[PlaceId; 2]> = self
            .edge_list()
            .into_iter()
            .map(|(a, b)| {
                let (ia, ib) = (self.place(a).id, self.place(b).id);
                [ia.min(ib), ia.max(ib)]
            })
            .collect();
        edges.sort_unstable();
        let file = MapFile {
            format: MAP_FORMAT,
            name: self.name.clone(),
            classes: self.classes.names().to_vec(),
            places,
            edges,
        };
        let mut buf = Vec::new();
        let mut ser = serde_json::Serializer::with_formatter(&mut buf, OnePerLine::default());
        // Serialising plain strings, numbers and bools into memory cannot fail.
        if file.serialize(&mut ser).is_err() {
            return String::new();
        }
        let mut s = String::from_utf8(buf).unwrap_or_default();
        s.push('\n');
        s
    }

    /// Parse a JSON map. Errors give the line and column of malformed JSON, or
    /// the place id of an invalid place or edge.
    pub fn from_json(text: &str) -> Result<TopoMap, MapError> {
        let mut de = serde_json::Deserializer::from_str(text);
        parse_map(&mut de, usize::MAX)
    }

    /// Write the map as JSON to `path`.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), MapError> {
        let path = path.as_ref();
        std::fs::write(path, self.to_json()).map_err(|e| MapError::io(path, e))
    }

    /// Read a JSON map from `path`; errors name the file.
    pub fn load(path: impl AsRef<Path>) -> Result<TopoMap, MapError> {
        Self::load_limited(path, usize::MAX)
    }

    /// [`TopoMap::load`] of a map of at most `max_places` places. The file is read as a
    /// stream; places beyond the limit are counted, not kept, and the map is refused
    /// with [`MapError::TooManyPlaces`] (holding the count) before its graph is built.
    pub fn load_limited(path: impl AsRef<Path>, max_places: usize) -> Result<TopoMap, MapError> {
        let path = path.as_ref();
        let file = std::fs::File::open(path).map_err(|e| MapError::io(path, e))?;
        let mut de =
            serde_json::Deserializer::from_reader(std::io::BufReader::with_capacity(1 << 16, file));
        parse_map(&mut de, max_places).map_err(|e| match e {
            MapError::TooManyPlaces { places, limit, .. } => MapError::TooManyPlaces {
                path: path.to_path_buf(),
                places,
                limit,
            },
            e => e.in_file(path),
        })
    }
}

/// Parses a map from `de` in one pass: at most `max_places` places are kept (the rest
/// are only counted, and the map refused), the format version is checked where it is
/// read.
fn parse_map<'de, R: serde_json::de::Read<'de>>(
    de: &mut serde_json::Deserializer<R>,
    max_places: usize,
) -> Result<TopoMap, MapError> {
    let problem = std::cell::Cell::new(None);
    let seed = MapSeed {
        max_places,
        problem: &problem,
    };
    let parsed = seed
        .deserialize(&mut *de)
        .and_then(|f| de.end().map(|()| f));
    if let Some(e) = problem.take() {
        return Err(e);
    }
    let file = parsed.map_err(json_error)?;
    if file.places_seen > max_places {
        return Err(MapError::TooManyPlaces {
            path: Default::default(),
            places: file.places_seen,
            limit: max_places,
        });
    }
    let classes = ClassSet::new(file.classes).map_err(MapError::Classes)?;
    let mut places = Vec::with_capacity(file.places.len());
    for p in file.places {
        let class = match p.class {
            None => None,
            Some(name) => Some(classes.index_of(&name).ok_or(MapError::UnknownClass {
                id: p.id,
                class: name,
            })?),
        };
        places.push(Place {
            id: p.id,
            class,
            placeholder: p.placeholder,
            x: p.x,
            y: p.y,
        });
    }
    let edges = file.edges.into_iter().map(|[a, b]| (a, b)).collect();
    TopoMap::new(file.name, classes, places, edges)
}

/// A map file as read: the places kept and how many the file lists.
struct ReadMap {
    name: String,
    classes: Vec<String>,
    places: Vec<PlaceJson>,
    places_seen: usize,
    edges: Vec<[PlaceId; 2]>,
}

/// An edge as read: exactly two place ids `[a, b]` (a third is refused as such; as
/// `[PlaceId; 2]` it read "trailing characters").
struct EdgePair([PlaceId; 2]);

impl<'de> Deserialize<'de> for EdgePair {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct PairVisitor;
        impl<'de> Visitor<'de> for PairVisitor {
            type Value = EdgePair;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("an edge: a pair of place ids [a, b]")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut s: A) -> Result<EdgePair, A::Error> {
                use serde::de::Error;
                let a = s
                    .next_element()?
                    .ok_or_else(|| A::Error::invalid_length(0, &self))?;
                let b = s
                    .next_element()?
                    .ok_or_else(|| A::Error::invalid_length(1, &self))?;
                let mut len = 2;
                while s.next_element::<IgnoredAny>()?.is_some() {
                    len += 1;
                }
                if len > 2 {
                    return Err(A::Error::invalid_length(len, &self));
                }
                Ok(EdgePair([a, b]))
            }
        }
        d.deserialize_seq(PairVisitor)
    }
}

/// Reads a [`MapFile`] keeping at most `max_places` places; a problem that is not
/// malformed JSON (the format version) goes to `problem`.
struct MapSeed<'a> {
    max_places: usize,
    problem: &'a std::cell::Cell<Option<MapError>>,
}

const FIELDS: &[&str] = &["format", "name", "classes", "places", "edges"];

impl<'de> DeserializeSeed<'de> for MapSeed<'_> {
    type Value = ReadMap;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<ReadMap, D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for MapSeed<'_> {
    type Value = ReadMap;
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a map: {\"format\": 1, \"name\": ..., \"classes\": [...], \"places\": [...], \"edges\": [...]}")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<ReadMap, A::Error> {
        use serde::de::Error;
        let mut format = None;
        let mut name = None;
        let mut classes = None;
        let mut places = None;
        let mut edges = None;
        while let Some(key) = m.next_key::<String>()? {
            let field = FIELDS.iter().copied().find(|f| *f == key);
            let dup = || A::Error::duplicate_field(field.unwrap_or_default());
            match key.as_str() {
                "format" => {
                    if format.is_some() {
                        return Err(dup());
                    }
                    let f: u64 = m.next_value()?;
                    if f != MAP_FORMAT {
                        self.problem.set(Some(MapError::FormatVersion {
                            found: f,
                            supported: MAP_FORMAT,
                        }));
                        return Err(A::Error::custom("unsupported map format"));
                    }
                    format = Some(f);
                }
                "name" if name.is_none() => name = Some(m.next_value::<String>()?),
                "classes" if classes.is_none() => classes = Some(m.next_value::<Vec<String>>()?),
                "places" if places.is_none() => {
                    places = Some(m.next_value_seed(PlacesSeed(self.max_places))?)
                }
                "edges" if edges.is_none() => {
                    // Not kept once the map is known to be refused.
                    let over = places
                        .as_ref()
                        .is_some_and(|(_, seen): &(Vec<PlaceJson>, usize)| *seen > self.max_places);
                    edges = Some(if over {
                        m.next_value::<IgnoredAny>()?;
                        Vec::new()
                    } else {
                        m.next_value::<Vec<EdgePair>>()?
                            .into_iter()
                            .map(|e| e.0)
                            .collect()
                    });
                }
                "name" | "classes" | "places" | "edges" => return Err(dup()),
                other => return Err(A::Error::unknown_field(other, FIELDS)),
            }
        }
        if format.is_none() {
            return Err(A::Error::missing_field("format"));
        }
        let (places, places_seen) = places.ok_or_else(|| A::Error::missing_field("places"))?;
        Ok(ReadMap {
            name: name.ok_or_else(|| A::Error::missing_field("name"))?,
            classes: classes.ok_or_else(|| A::Error::missing_field("classes"))?,
            places,
            places_seen,
            edges: edges.ok_or_else(|| A::Error::missing_field("edges"))?,
        })
    }
}

/// The `places` list: the first `.0` places kept, every place counted.
struct PlacesSeed(usize);

impl<'de> DeserializeSeed<'de> for PlacesSeed {
    type Value = (Vec<PlaceJson>, usize);
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for PlacesSeed {
    type Value = (Vec<PlaceJson>, usize);
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a list of places")
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut s: A) -> Result<Self::Value, A::Error> {
        let mut places = Vec::new();
        let mut seen = 0usize;
        while seen < self.0 {
            match s.next_element::<PlaceJson>()? {
                Some(p) => places.push(p),
                None => return Ok((places, seen)),
            }
            seen += 1;
        }
        while s.next_element::<IgnoredAny>()?.is_some() {
            seen += 1;
        }
        Ok((places, seen))
    }
}
