//! Code generation: straight-line `no_std` Rust for a known map, and the `build.rs` builder.
//!
//! [`generate`] turns a learned [`Model`], a [`TopoMap`] and its decompositions (the
//! instance GraphSPN of the paper's Alg. 1: `S(α) = Σ_d (1/D) Π_k T_{t(k)}(α_k)`) into
//! the source of one Rust module that computes, without allocation, panics or
//! `unsafe`: the log-likelihood, the marginals `P(Y_p = c | α)`, the max-product
//! (MPE) labelling and the log-likelihood of a (partially) labelled map.
//!
//! Shape of the output (see `wiring.rs` and `template.rs` for details):
//! - one set of functions per template SPN (forward, forward+backward, max-product),
//!   shared by every component of that template: code size is `O(template) + O(map)`;
//! - per-map wiring split into chunk functions of at most
//!   [`CodegenOptions::chunk_size`] components, so rustc compiles quickly;
//! - numerics: each place's evidence row is scaled to a maximum of 1; templates are
//!   evaluated in linear space when a generation-time lower bound proves it safe (see
//!   [`analysis`]), in log space otherwise; decomposition log-probabilities are
//!   accumulated in `f64`.
//!
//! [`Builder`] and [`compile`] wrap [`generate`] for `build.rs` scripts.

pub mod analysis;
mod builder;
mod emit;
mod kernels;
mod template;
mod wiring;

pub use builder::{
    BuildError, Builder, GENERATED_MARKER, Inputs, check_module_name, compile, is_generated_file,
    load_decompositions, load_map, load_model, write_if_changed,
};

use thiserror::Error;

use crate::decompose::Decomposition;
use crate::learn::Model;
use crate::map::TopoMap;

/// Floating-point type of the generated code.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// `f32` everywhere (decomposition log-probabilities still accumulate in `f64`).
    #[default]
    F32,
    /// `f64` everywhere.
    F64,
}

/// Options of [`generate`].
#[derive(Clone, Debug)]
pub struct CodegenOptions {
    /// Scalar type of evidence, results and template arithmetic.
    pub precision: Precision,
    /// Largest number of components per generated chunk function (≥ 1).
    pub chunk_size: usize,
    /// Name of the model written into the `@generated` header (e.g. its file name).
    pub model_label: String,
    /// Largest stack scratch (bytes) `marginals` may use to keep every component's
    /// local posteriors (one forward+backward pass per component). Maps needing more
    /// run a value pass first and recompute the posteriors in a second pass, which
    /// costs about a third more time. Default [`DEFAULT_STACK_BYTES`] (64 KiB).
    pub max_stack_bytes: usize,
}

/// Default of [`CodegenOptions::max_stack_bytes`].
pub const DEFAULT_STACK_BYTES: usize = 64 * 1024;

impl Default for CodegenOptions {
    fn default() -> Self {
        CodegenOptions {
            precision: Precision::F32,
            chunk_size: 64,
            model_label: "model".into(),
            max_stack_bytes: DEFAULT_STACK_BYTES,
        }
    }
}

/// Why code could not be generated.
#[derive(Debug, Error)]
pub enum CodegenError {
    /// The model and the map disagree on the number of classes.
    #[error("the model has {model} classes but the map has {map}")]
    ClassMismatch {
        /// Classes of the model.
        model: usize,
        /// Classes of the map.
        map: usize,
    },
    /// The model has a different number of templates and SPNs.
    #[error("the model has {templates} templates but {spns} SPNs")]
    ModelShape {
        /// Number of templates.
        templates: usize,
        /// Number of SPNs.
        spns: usize,
    },
    /// A template SPN is malformed.
    #[error("template {template}, SPN node {node}: {what}")]
    BadSpn {
        /// Template index.
        template: usize,
        /// Node id.
        node: usize,
        /// What is wrong.
        what: String,
    },
    /// The map has no places.
    #[error("the map has no places")]
    EmptyMap,
    /// No decompositions were given.
    #[error("no decompositions were given")]
    NoDecompositions,
    /// A component does not fit its template or the map.
    #[error("decomposition {decomposition}, component {component}: {what}")]
    BadComponent {
        /// Decomposition index.
        decomposition: usize,
        /// Component index within the decomposition.
        component: usize,
        /// What is wrong.
        what: String,
    },
    /// A place is in no component of a decomposition.
    #[error("decomposition {decomposition} does not cover place {place_id} (index {place})")]
    PlaceNotCovered {
        /// Decomposition index.
        decomposition: usize,
        /// Place index.
        place: usize,
        /// Place id.
        place_id: u32,
    },
    /// A place is in two components of a decomposition.
    #[error(
        "decomposition {decomposition} covers place {place_id} (index {place}) twice, in components {} and {}",
        components.0, components.1
    )]
    PlaceCoveredTwice {
        /// Decomposition index.
        decomposition: usize,
        /// Place index.
        place: usize,
        /// Place id.
        place_id: u32,
        /// The two components.
        components: (usize, usize),
    },
    /// The option values are unusable.
    #[error("bad option: {0}")]
    BadOption(String),
    /// The generated text did not parse (a bug in the generator).
    #[error("internal error: generated code does not parse: {0}")]
    Internal(String),
    /// Reading an input or writing the output failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// An input file is not valid JSON of the expected shape.
    #[error("{path}: {what}")]
    Format {
        /// The file.
        path: std::path::PathBuf,
        /// What is wrong (with line and column when known).
        what: String,
    },
}

/// Generates the Rust source of the compiled instance GraphSPN (see the module docs).
///
/// Pure: the same inputs give byte-identical output. The text starts with an
/// `@generated` line and is formatted with prettyplease; it is `no_std`-compatible and
/// meant to be `include!`d into a module of a crate depending on `graphspn-runtime`.
pub fn generate(
    model: &Model,
    map: &TopoMap,
    decompositions: &[Decomposition],
    options: &CodegenOptions,
) -> Result<String, CodegenError> {
    if options.chunk_size == 0 {
        return Err(CodegenError::BadOption(
            "chunk_size must be at least 1".into(),
        ));
    }
    analysis::check_inputs(model, map, decompositions)?;
    let body = wiring::module(model, map, decompositions, options);
    let file = syn::parse_file(&body).map_err(|e| CodegenError::Internal(e.to_string()))?;
    let header = format!(
        "// @generated by graphspn-compiler {} from {}, {}; do not edit\n",
        env!("CARGO_PKG_VERSION"),
        options.model_label.replace('\n', " "),
        map.name.replace('\n', " ")
    );
    Ok(header + &prettyplease::unparse(&file))
}
