//! The `build.rs` front end: a prost-build-style [`Builder`], the one-call
//! [`compile`], and minimal file loaders.

use std::path::{Path, PathBuf};

use petgraph::graph::{NodeIndex, UnGraph};
use serde::Deserialize;

use super::{CodegenError, CodegenOptions, Precision, generate};
use crate::decompose::Decomposition;
use crate::learn::Model;
use crate::map::{ClassSet, Place, TopoMap};

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> CodegenError + '_ {
    move |source| CodegenError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T, CodegenError> {
    let text = std::fs::read_to_string(path).map_err(io(path))?;
    serde_json::from_str(&text).map_err(|e| CodegenError::Format {
        path: path.to_path_buf(),
        what: format!("line {}, column {}: {e}", e.line(), e.column()),
    })
}

/// Reads a model JSON file (the [`Model`] serde format).
// TODO(merge): replace with the learn module's loader once merged.
pub fn load_model(path: &Path) -> Result<Model, CodegenError> {
    json(path)
}

#[derive(Deserialize)]
struct MapFile {
    name: String,
    classes: Vec<String>,
    places: Vec<Place>,
    edges: Vec<(u32, u32)>,
}

/// Reads a map JSON file: `{"name", "classes": [..], "places": [{id, class, placeholder,
/// x, y}], "edges": [[id, id], ..]}`. Places are put in ascending id order.
// TODO(merge): replace with the map module's JSON loader once merged.
pub fn load_map(path: &Path) -> Result<TopoMap, CodegenError> {
    let f: MapFile = json(path)?;
    let bad = |what: String| CodegenError::Format {
        path: path.to_path_buf(),
        what,
    };
    let classes = ClassSet::new(f.classes).map_err(bad)?;
    let mut places = f.places;
    places.sort_by_key(|p| p.id);
    let mut graph = UnGraph::new_undirected();
    for p in &places {
        graph.add_node(p.clone());
    }
    let index = |id: u32| {
        places
            .binary_search_by_key(&id, |p| p.id)
            .map_err(|_| bad(format!("edge names unknown place {id}")))
    };
    for (a, b) in f.edges {
        let (ia, ib) = (index(a)?, index(b)?);
        if ia != ib {
            graph.update_edge(NodeIndex::new(ia), NodeIndex::new(ib), ());
        }
    }
    Ok(TopoMap {
        name: f.name,
        classes,
        graph,
    })
}

/// Reads decompositions: a JSON list of [`Decomposition`] (place indices in map order).
// TODO(merge): replace with the decompose module's loader once merged.
pub fn load_decompositions(path: &Path) -> Result<Vec<Decomposition>, CodegenError> {
    json(path)
}

/// Generates code for a model file and a map file with explicit decompositions into
/// `out` (written only if changed). For `build.rs` use, see [`Builder`].
pub fn compile(
    model: &Path,
    map: &Path,
    decompositions: &Path,
    out: &Path,
) -> Result<(), CodegenError> {
    Builder::new(model, map)
        .decompositions_file(decompositions)
        .out_file(out)
        .run()
        .map(|_| ())
}

/// Configures and runs code generation from files, for `build.rs` scripts.
///
/// ```no_run
/// // build.rs
/// graphspn_compiler::codegen::Builder::new("model.json", "map.json")
///     .decompositions_file("decompositions.json")
///     .module_name("office")
///     .run()
///     .unwrap();
/// // lib.rs: mod office { include!(concat!(env!("OUT_DIR"), "/office.rs")); }
/// ```
#[derive(Clone, Debug)]
pub struct Builder {
    model: PathBuf,
    map: PathBuf,
    decompositions: Option<PathBuf>,
    explicit: Option<Vec<Decomposition>>,
    precision: Precision,
    module_name: String,
    out_dir: Option<PathBuf>,
    out_file: Option<PathBuf>,
    chunk_size: usize,
}

impl Builder {
    /// A builder for `model` (JSON) and `map` (JSON).
    pub fn new(model: impl Into<PathBuf>, map: impl Into<PathBuf>) -> Self {
        Builder {
            model: model.into(),
            map: map.into(),
            decompositions: None,
            explicit: None,
            precision: Precision::F32,
            module_name: "map".into(),
            out_dir: None,
            out_file: None,
            chunk_size: CodegenOptions::default().chunk_size,
        }
    }

    /// Reads the decompositions from a JSON file.
    pub fn decompositions_file(mut self, path: impl Into<PathBuf>) -> Self {
        self.decompositions = Some(path.into());
        self
    }

    /// Uses these decompositions.
    // TODO(merge): `decompositions_from_seed(seed, count)` once the decomposer is merged.
    pub fn decompositions(mut self, d: Vec<Decomposition>) -> Self {
        self.explicit = Some(d);
        self
    }

    /// Scalar type of the generated code (default `f32`).
    pub fn precision(mut self, p: Precision) -> Self {
        self.precision = p;
        self
    }

    /// File stem of the output, `<name>.rs` in the output directory (default `map`).
    pub fn module_name(mut self, name: impl Into<String>) -> Self {
        self.module_name = name.into();
        self
    }

    /// Output directory (default `$OUT_DIR`).
    pub fn out_dir(mut self, dir: impl Into<PathBuf>) -> Self {
        self.out_dir = Some(dir.into());
        self
    }

    /// Exact output file (overrides `out_dir` and `module_name`).
    pub fn out_file(mut self, file: impl Into<PathBuf>) -> Self {
        self.out_file = Some(file.into());
        self
    }

    /// Components per generated chunk function (default 64).
    pub fn chunk_size(mut self, n: usize) -> Self {
        self.chunk_size = n;
        self
    }

    /// Loads the inputs, generates the module, writes it if its content changed and
    /// prints `cargo:rerun-if-changed=` for every input file. Returns the output path.
    pub fn run(self) -> Result<PathBuf, CodegenError> {
        let model = load_model(&self.model)?;
        let map = load_map(&self.map)?;
        println!("cargo:rerun-if-changed={}", self.model.display());
        println!("cargo:rerun-if-changed={}", self.map.display());
        let decs = match (self.explicit, &self.decompositions) {
            (Some(d), _) => d,
            (None, Some(path)) => {
                println!("cargo:rerun-if-changed={}", path.display());
                load_decompositions(path)?
            }
            (None, None) => {
                return Err(CodegenError::BadOption(
                    "no decompositions given (seeded decomposition is not available yet)".into(),
                ));
            }
        };
        let options = CodegenOptions {
            precision: self.precision,
            chunk_size: self.chunk_size,
            model_label: self
                .model
                .file_name()
                .map_or_else(|| "model".into(), |f| f.to_string_lossy().into_owned()),
        };
        let src = generate(&model, &map, &decs, &options)?;
        let out = match self.out_file {
            Some(f) => f,
            None => {
                let dir = match self.out_dir {
                    Some(d) => d,
                    None => std::env::var_os("OUT_DIR")
                        .map(PathBuf::from)
                        .ok_or_else(|| {
                            CodegenError::BadOption(
                                "OUT_DIR is not set and no out_dir was given".into(),
                            )
                        })?,
                };
                dir.join(format!("{}.rs", self.module_name))
            }
        };
        write_if_changed(&out, &src)?;
        Ok(out)
    }
}

/// Writes `text` to `path` unless the file already holds exactly that text
/// (keeps mtimes stable so cargo does not rebuild needlessly).
pub fn write_if_changed(path: &Path, text: &str) -> Result<(), CodegenError> {
    if std::fs::read_to_string(path).is_ok_and(|old| old == text) {
        return Ok(());
    }
    if let Some(dir) = path.parent()
        && !dir.as_os_str().is_empty()
    {
        std::fs::create_dir_all(dir).map_err(io(dir))?;
    }
    std::fs::write(path, text).map_err(io(path))
}
