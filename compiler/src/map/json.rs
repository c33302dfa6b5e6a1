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

use serde::{Deserialize, Serialize};

use super::{ClassSet, MapError, Place, PlaceId, TopoMap};

/// The map format version this build writes and reads.
pub const MAP_FORMAT: u64 = 1;

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
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

#[derive(Deserialize)]
struct VersionOnly {
    format: u64,
}

fn json_error(e: serde_json::Error) -> MapError {
    MapError::Json {
        line: e.line(),
        column: e.column(),
        message: e.to_string(),
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
        // Check the version first so a future format gets a clear message.
        if let Ok(v) = serde_json::from_str::<VersionOnly>(text)
            && v.format != MAP_FORMAT
        {
            return Err(MapError::FormatVersion {
                found: v.format,
                supported: MAP_FORMAT,
            });
        }
        let file: MapFile = serde_json::from_str(text).map_err(json_error)?;
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

    /// Write the map as JSON to `path`.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), MapError> {
        let path = path.as_ref();
        std::fs::write(path, self.to_json()).map_err(|e| MapError::io(path, e))
    }

    /// Read a JSON map from `path`; errors name the file.
    pub fn load(path: impl AsRef<Path>) -> Result<TopoMap, MapError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| MapError::io(path, e))?;
        TopoMap::from_json(&text).map_err(|e| e.in_file(path))
    }
}
