//! The decomposition file: a set of decompositions of one map, as JSON.
//!
//! ```json
//! {
//!   "format": 1,
//!   "map": "Freiburg/seq1_cloudy1",
//!   "decompositions": [
//!     {"components": [
//!       {"template": "star", "places": [12, 7, 13, 30, 31]},
//!       {"template": "singleton", "places": [5]}
//!     ]}
//!   ]
//! }
//! ```
//!
//! Components name their template by NAME and their places by place ID (not
//! index), in the template's canonical node order, so a file stays meaningful
//! when read against a template list in another order. Writing is
//! deterministic (one component per line, in stored order). Reading checks
//! everything: syntax (with line and column), the format version, the map
//! name, template names, place ids, and that each decomposition is a valid
//! partition into matches ([`Decomposition::validate`]).

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::{Component, DecomposeError, Decomposition};
use crate::map::{PlaceId, TopoMap};
use crate::template::Template;

/// The format version written and accepted.
pub const FORMAT_VERSION: u64 = 1;

/// Why a decomposition file could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum DecompositionFileError {
    /// Reading or writing the file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Another error, in a named file.
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// The error.
        source: Box<DecompositionFileError>,
    },
    /// Malformed JSON or a field of the wrong type / missing / unknown.
    #[error("line {line}, column {column}: {message}")]
    Syntax {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What serde_json reported.
        message: String,
    },
    /// The `format` field is not [`FORMAT_VERSION`].
    #[error(
        "unsupported decomposition file format {found} (this version reads format {FORMAT_VERSION})"
    )]
    Format {
        /// The version in the file.
        found: u64,
    },
    /// The file was written for another map.
    #[error("the file is for map {found:?}, not {expected:?}")]
    MapMismatch {
        /// The map given.
        expected: String,
        /// The map named in the file.
        found: String,
    },
    /// The template list given to read the file against is unusable (e.g. two
    /// templates share a name, so names are ambiguous).
    #[error("template list: {source}")]
    Templates {
        /// What is wrong.
        source: DecomposeError,
    },
    /// A component names a template not in the list.
    #[error(
        "decomposition {decomposition}, component {component}: unknown template {name:?} (known: {known})"
    )]
    UnknownTemplateName {
        /// Decomposition index.
        decomposition: usize,
        /// Component index.
        component: usize,
        /// The name.
        name: String,
        /// Known names, comma-separated.
        known: String,
    },
    /// A component names a place id the map does not have.
    #[error("decomposition {decomposition}, component {component}: unknown place id {id}")]
    UnknownPlaceId {
        /// Decomposition index.
        decomposition: usize,
        /// Component index.
        component: usize,
        /// The id.
        id: PlaceId,
    },
    /// A decomposition is not a valid partition into template matches.
    #[error("decomposition {decomposition}: {source}")]
    Invalid {
        /// Decomposition index.
        decomposition: usize,
        /// What is wrong (names the place id covered twice / not covered, or the component).
        source: DecomposeError,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileRepr {
    format: u64,
    map: String,
    decompositions: Vec<DecompositionRepr>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DecompositionRepr {
    components: Vec<ComponentRepr>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ComponentRepr {
    template: String,
    places: Vec<PlaceId>,
}

fn json_string(s: &str) -> String {
    // Serialising a &str cannot fail.
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into())
}

/// The JSON text of `decompositions` of `map` made with `templates`. Each
/// decomposition is validated first, so only valid files are written.
pub fn to_json(
    decompositions: &[Decomposition],
    map: &TopoMap,
    templates: &[Template],
) -> Result<String, DecompositionFileError> {
    for (i, d) in decompositions.iter().enumerate() {
        d.validate(map, templates)
            .map_err(|source| DecompositionFileError::Invalid {
                decomposition: i,
                source,
            })?;
    }
    let mut s = String::new();
    s.push_str("{\n");
    let _ = writeln!(s, "  \"format\": {FORMAT_VERSION},");
    let _ = writeln!(s, "  \"map\": {},", json_string(&map.name));
    s.push_str("  \"decompositions\": [");
    for (i, d) in decompositions.iter().enumerate() {
        s.push_str(if i == 0 { "\n" } else { ",\n" });
        s.push_str("    {\"components\": [");
        for (j, c) in d.components.iter().enumerate() {
            s.push_str(if j == 0 { "\n" } else { ",\n" });
            let ids: Vec<String> = c
                .places
                .iter()
                .map(|&p| map.place(p).id.to_string())
                .collect();
            let _ = write!(
                s,
                "      {{\"template\": {}, \"places\": [{}]}}",
                json_string(&templates[c.template].name),
                ids.join(", ")
            );
        }
        s.push_str(if d.components.is_empty() {
            "]}"
        } else {
            "\n    ]}"
        });
    }
    s.push_str(if decompositions.is_empty() {
        "]\n}\n"
    } else {
        "\n  ]\n}\n"
    });
    Ok(s)
}

/// Reads decompositions from JSON `text`, against `map` and `templates`
/// (component template indices refer to `templates`). Every decomposition is
/// validated.
pub fn from_json(
    text: &str,
    map: &TopoMap,
    templates: &[Template],
) -> Result<Vec<Decomposition>, DecompositionFileError> {
    from_repr(serde_json::from_str(text).map_err(syntax)?, map, templates)
}

fn syntax(e: serde_json::Error) -> DecompositionFileError {
    DecompositionFileError::Syntax {
        line: e.line(),
        column: e.column(),
        message: crate::json_error::json_message(&e),
    }
}

/// How many decompositions the file at `path` holds, read as a stream without keeping
/// them (so a caller can refuse a file too large for its work before loading it).
/// Only the syntax is checked; [`load`] checks the rest.
pub fn count(path: &Path) -> Result<usize, DecompositionFileError> {
    struct Count(usize);
    impl<'de> Deserialize<'de> for Count {
        fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            struct V;
            impl<'de> serde::de::Visitor<'de> for V {
                type Value = Count;
                fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                    f.write_str("a list of decompositions")
                }
                fn visit_seq<A: serde::de::SeqAccess<'de>>(
                    self,
                    mut s: A,
                ) -> Result<Count, A::Error> {
                    let mut n = 0;
                    while s.next_element::<serde::de::IgnoredAny>()?.is_some() {
                        n += 1;
                    }
                    Ok(Count(n))
                }
            }
            d.deserialize_seq(V)
        }
    }
    #[derive(Deserialize)]
    struct Counted {
        decompositions: Count,
    }
    let in_file = |e| DecompositionFileError::InFile {
        path: path.to_path_buf(),
        source: Box::new(e),
    };
    let reader = open(path)?;
    let c: Counted = serde_json::from_reader(reader).map_err(|e| in_file(syntax(e)))?;
    Ok(c.decompositions.0)
}

fn open(path: &Path) -> Result<std::io::BufReader<std::fs::File>, DecompositionFileError> {
    let f = std::fs::File::open(path).map_err(|source| DecompositionFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(std::io::BufReader::with_capacity(1 << 16, f))
}

fn from_repr(
    repr: FileRepr,
    map: &TopoMap,
    templates: &[Template],
) -> Result<Vec<Decomposition>, DecompositionFileError> {
    if repr.format != FORMAT_VERSION {
        return Err(DecompositionFileError::Format { found: repr.format });
    }
    if repr.map != map.name {
        return Err(DecompositionFileError::MapMismatch {
            expected: map.name.clone(),
            found: repr.map,
        });
    }
    for (i, t) in templates.iter().enumerate() {
        if templates[..i].iter().any(|u| u.name == t.name) {
            return Err(DecompositionFileError::Templates {
                source: DecomposeError::DuplicateTemplateName {
                    name: t.name.clone(),
                },
            });
        }
    }
    let by_name: HashMap<&str, usize> = templates
        .iter()
        .enumerate()
        .map(|(i, t)| (t.name.as_str(), i))
        .collect();
    let by_id: HashMap<PlaceId, usize> = map.places().enumerate().map(|(i, p)| (p.id, i)).collect();
    let mut out = Vec::with_capacity(repr.decompositions.len());
    for (i, d) in repr.decompositions.into_iter().enumerate() {
        let mut components = Vec::with_capacity(d.components.len());
        for (j, c) in d.components.into_iter().enumerate() {
            let template = *by_name.get(c.template.as_str()).ok_or_else(|| {
                DecompositionFileError::UnknownTemplateName {
                    decomposition: i,
                    component: j,
                    name: c.template.clone(),
                    known: templates
                        .iter()
                        .map(|t| t.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", "),
                }
            })?;
            let places = c
                .places
                .iter()
                .map(|id| {
                    by_id
                        .get(id)
                        .copied()
                        .ok_or(DecompositionFileError::UnknownPlaceId {
                            decomposition: i,
                            component: j,
                            id: *id,
                        })
                })
                .collect::<Result<Vec<_>, _>>()?;
            components.push(Component { template, places });
        }
        let dec = Decomposition { components };
        dec.validate(map, templates)
            .map_err(|source| DecompositionFileError::Invalid {
                decomposition: i,
                source,
            })?;
        out.push(dec);
    }
    Ok(out)
}

/// Writes [`to_json`] to `path`.
pub fn save(
    path: &Path,
    decompositions: &[Decomposition],
    map: &TopoMap,
    templates: &[Template],
) -> Result<(), DecompositionFileError> {
    let text =
        to_json(decompositions, map, templates).map_err(|e| DecompositionFileError::InFile {
            path: path.to_path_buf(),
            source: Box::new(e),
        })?;
    std::fs::write(path, text).map_err(|source| DecompositionFileError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads a file written by [`save`] (see [`from_json`]); errors name the file.
pub fn load(
    path: &Path,
    map: &TopoMap,
    templates: &[Template],
) -> Result<Vec<Decomposition>, DecompositionFileError> {
    // Read as a stream: the decompositions, not the file's text, are kept.
    let reader = open(path)?;
    serde_json::from_reader(reader)
        .map_err(syntax)
        .and_then(|repr| from_repr(repr, map, templates))
        .map_err(|e| DecompositionFileError::InFile {
            path: path.to_path_buf(),
            source: Box::new(e),
        })
}
