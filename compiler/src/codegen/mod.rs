//! Code generation: straight-line `no_std` Rust for a known map, and the `build.rs` builder.
//!
//! Both model families compile to modules with the same public API (the stateless
//! functions, the constants, the streaming `State`, the `CompiledMap` impl; shared
//! parts in `surface.rs`): [`generate`] for a GraphSPN (below), [`generate_trees`] for
//! a tree mixture (`trees/`: potentials and per-forest tables run over by the
//! runtime's tree driver). [`Builder`] reads a model file of either family.
//!
//! [`generate`] turns a learned [`Model`], a [`TopoMap`] and its decompositions (the
//! instance GraphSPN of the paper's Alg. 1: `S(α) = Σ_d (1/D) Π_k T_{t(k)}(α_k)`) into
//! the source of one Rust module that computes, without allocation, panics or
//! `unsafe`: the log-likelihood, the marginals `P(Y_p = c | α)`, the max-product
//! (MPE) labelling and the log-likelihood of a (partially) labelled map.
//!
//! Shape of the output (see `wiring/`, `sparse/` and `template.rs` for details):
//! - one set of straight-line functions per template SPN (value, value + local
//!   posteriors, max-product value, MPE with backtracking), shared by every component
//!   of that template, in *floor + sparse* form: each weighted sum is its smallest
//!   weight times the product of its inputs' sums plus one multiply-add per weight
//!   above it (exact, about 5x fewer multiply-adds for trained templates);
//! - per map only `static` tables (each component's places and decompositions),
//!   run over by the generic driver in `graphspn_runtime`: code size is
//!   `O(templates)` and table size `O(map)`;
//! - numerics: each place's evidence row is scaled to a maximum of 1; templates are
//!   evaluated in linear space when a generation-time lower bound proves it safe (see
//!   [`analysis`]), in log space otherwise; decomposition products keep an exact
//!   power-of-two exponent, so no `f64` arithmetic is needed in `f32` code;
//! - [`Vectorisation`]: components in SIMD lane groups on the host, one at a time on
//!   targets without float SIMD (microcontrollers);
//! - a caller-owned streaming `State` re-evaluates only the components containing a
//!   place whose evidence changed.
//!
//! [`Builder`] and [`compile`] wrap [`generate`] for `build.rs` scripts.

pub mod analysis;
mod build_error;
mod builder;
mod emit;
mod fixed;
mod kernels;
mod sparse;
mod surface;
mod template;
mod trees;
mod wiring;

pub use surface::CodeReport;

pub use build_error::BuildError;
pub use builder::{
    AnyInputs, Builder, GENERATED_MARKER, Inputs, TreeInputs, check_module_name, compile,
    is_generated_file, load_any_model, load_decompositions, load_map, load_model, write_if_changed,
};

use thiserror::Error;

use crate::decompose::Decomposition;
use crate::inputs::{InputsError, check_inputs};
use crate::learn::Model;
use crate::map::TopoMap;
use crate::treemix::{SpanningTrees, TreeMixError, TreeMixture};

/// Floating-point type of the generated code.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// `f32` everywhere (decomposition log-probabilities still accumulate in `f64`).
    #[default]
    F32,
    /// `f64` everywhere.
    F64,
}

/// How many components one call of a template function evaluates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Vectorisation {
    /// One component per call, plain scalar code: targets without float SIMD
    /// (Cortex-M, RISC-V MCUs), where emulated vectors would cost more than they save.
    Scalar,
    /// Components in SIMD lane groups (8 in `f32`, 4 in `f64`): x86-64, AArch64.
    #[default]
    Simd,
}

impl Vectorisation {
    /// The choice for a compilation target given as Cargo's `CARGO_CFG_TARGET_ARCH`
    /// (`x86_64`, `aarch64`, `arm`, `riscv32`, ...): SIMD lane groups on x86-64 and
    /// AArch64, scalar code everywhere else.
    pub fn for_arch(arch: &str) -> Vectorisation {
        match arch {
            "x86_64" | "aarch64" => Vectorisation::Simd,
            _ => Vectorisation::Scalar,
        }
    }
}

/// How templates compute: hardware floats, or integers on targets without an FPU.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Arithmetic {
    /// Floating point in the module's [`Precision`] everywhere.
    #[default]
    Float,
    /// Q0.32 fixed-point value and posterior functions for block templates (integer
    /// multiplies and adds: no soft-float calls), each result kept only when its error
    /// bound is small enough (values within `2^-13` of themselves, local posteriors
    /// within `2^-10`), else recomputed in `f32` (see the generator's
    /// `fixed` module); the weighted local posteriors of `marginals` are summed in
    /// Q1.31 integers (within `3·D·2^-31` per marginal, `D` decompositions). The rest
    /// of the module (evidence scaling, decomposition weights, MPE) stays `f32`. Needs [`Precision::F32`] and [`Vectorisation::Scalar`]. A
    /// tree mixture computes its messages `ψ·b` in Q0.32 (integer multiply-adds,
    /// each entry within `η` of itself relatively, `η` in the report's
    /// `message_error`; kept `f32` for models whose smallest potential makes `η`
    /// exceed `2^-12`) and the rest in `f32` with the runtime's `SoftF32` rows:
    /// integer fast paths for its non-negative normal values, bit-identical to `f32`
    /// arithmetic, and rows rescaled by their largest entry's exponent in integers.
    Fixed,
}

impl Arithmetic {
    /// The choice for a compilation target triple (Cargo's `TARGET`): fixed point on
    /// targets without a floating-point unit — 32-bit Arm without the hard-float ABI
    /// (`thumbv6m-none-eabi`, `thumbv7m-none-eabi`, `thumbv8m.base-none-eabi`, ...) and
    /// RISC-V without the F extension (`riscv32imac-unknown-none-elf`,
    /// `riscv32imc-...`) — and floats everywhere else.
    pub fn for_target(triple: &str) -> Arithmetic {
        let arch = triple.split('-').next().unwrap_or("");
        let no_fpu = if let Some(isa) = arch
            .strip_prefix("riscv32")
            .or_else(|| arch.strip_prefix("riscv64"))
        {
            !isa.contains(['f', 'g'])
        } else if arch.starts_with("thumb") || arch.starts_with("arm") {
            !triple.ends_with("eabihf")
        } else {
            false
        };
        if no_fpu {
            Arithmetic::Fixed
        } else {
            Arithmetic::Float
        }
    }
}

/// Options of [`generate`].
#[derive(Clone, Debug)]
pub struct CodegenOptions {
    /// Scalar type of evidence, results and template arithmetic.
    pub precision: Precision,
    /// Scalar code or SIMD lane groups.
    pub vectorisation: Vectorisation,
    /// Float or fixed-point template arithmetic.
    pub arithmetic: Arithmetic,
    /// Name of the model written into the `@generated` header (e.g. its file name).
    pub model_label: String,
    /// Stack budget (bytes): generation fails when the computed worst-case stack of
    /// any generated entry point (template frames included) exceeds it. `None`:
    /// [`DEFAULT_STACK_BYTES`] (16 KiB) for scalar code (microcontrollers),
    /// [`DEFAULT_SIMD_STACK_BYTES`] (64 KiB) for SIMD lane groups (hosts, whose lane
    /// frames are 4–8 times larger).
    pub max_stack_bytes: Option<usize>,
}

/// The most decompositions a GraphSPN module can mix: the generated tables give each
/// component the set of decompositions holding it as one 64-bit mask.
pub const MAX_COMPILED_DECOMPOSITIONS: usize = 64;

/// Default stack budget of scalar code, see [`CodegenOptions::max_stack_bytes`].
pub const DEFAULT_STACK_BYTES: usize = 16 * 1024;
/// Default stack budget of SIMD code, see [`CodegenOptions::max_stack_bytes`].
pub const DEFAULT_SIMD_STACK_BYTES: usize = 64 * 1024;

impl CodegenOptions {
    /// Whether the options go together and fit a map of `places` places, for either
    /// model family (the one check both generators run): at most 65,535 places (the
    /// tables index places with `u16`), and fixed-point arithmetic needs `f32` scalar
    /// code.
    pub fn check(&self, places: usize) -> Result<(), CodegenError> {
        if places > usize::from(u16::MAX) {
            return Err(CodegenError::BadOption(format!(
                "at most 65,535 places can be compiled, the map has {places}"
            )));
        }
        if self.arithmetic == Arithmetic::Fixed
            && (self.precision != Precision::F32 || self.vectorisation != Vectorisation::Scalar)
        {
            return Err(CodegenError::BadOption(format!(
                "fixed-point arithmetic needs f32 scalar code, got {:?} {:?}",
                self.precision, self.vectorisation
            )));
        }
        Ok(())
    }

    /// The stack budget in force: [`CodegenOptions::max_stack_bytes`] or its default.
    pub fn stack_budget(&self) -> usize {
        self.max_stack_bytes.unwrap_or(match self.vectorisation {
            Vectorisation::Scalar => DEFAULT_STACK_BYTES,
            Vectorisation::Simd => DEFAULT_SIMD_STACK_BYTES,
        })
    }
}

impl Default for CodegenOptions {
    fn default() -> Self {
        CodegenOptions {
            precision: Precision::F32,
            vectorisation: Vectorisation::Simd,
            arithmetic: Arithmetic::Float,
            model_label: "model".into(),
            max_stack_bytes: None,
        }
    }
}

/// Why code could not be generated.
#[derive(Debug, Error)]
pub enum CodegenError {
    /// The model, the map and the decompositions do not fit together (the check the
    /// instance GraphSPN shares; boxed to keep this error small).
    #[error(transparent)]
    Inputs(Box<InputsError>),
    /// A tree mixture, the map and the spanning forests do not fit together (the check
    /// the tree mixture's interpreter shares; boxed to keep this error small).
    #[error(transparent)]
    TreeInputs(Box<TreeMixError>),
    /// The option values are unusable.
    #[error("bad option: {0}")]
    BadOption(String),
    /// The model is outside what the generator compiles (e.g. a tree mixture with one
    /// class or more than 256); the interpreter still evaluates it.
    #[error("the model cannot be compiled: {0}")]
    Unsupported(String),
    /// The generated tokens do not form a Rust file (a bug in the generator).
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

impl From<InputsError> for CodegenError {
    fn from(e: InputsError) -> Self {
        CodegenError::Inputs(Box::new(e))
    }
}

impl From<TreeMixError> for CodegenError {
    fn from(e: TreeMixError) -> Self {
        CodegenError::TreeInputs(Box::new(e))
    }
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
    generate_with_report(model, map, decompositions, options).map(|(s, _)| s)
}

/// [`generate`], and what the generator knows about the code: worst-case stack per
/// entry point, state and table sizes, multiply-adds per call.
pub fn generate_with_report(
    model: &Model,
    map: &TopoMap,
    decompositions: &[Decomposition],
    options: &CodegenOptions,
) -> Result<(String, CodeReport), CodegenError> {
    check_inputs(model, map, decompositions)?;
    let (tokens, report) = wiring::module(model, map, decompositions, options)?;
    Ok((render(tokens, map, options)?, report))
}

/// Generates the Rust source of a compiled tree mixture: `model` over the spanning
/// forests `trees` of `map` (see [`crate::treemix`]), with the same public API as a
/// GraphSPN module. Pure and deterministic, like [`generate`].
pub fn generate_trees(
    model: &TreeMixture,
    map: &TopoMap,
    trees: &SpanningTrees,
    options: &CodegenOptions,
) -> Result<String, CodegenError> {
    generate_trees_with_report(model, map, trees, options).map(|(s, _)| s)
}

/// [`generate_trees`], and the generator's report.
pub fn generate_trees_with_report(
    model: &TreeMixture,
    map: &TopoMap,
    trees: &SpanningTrees,
    options: &CodegenOptions,
) -> Result<(String, CodeReport), CodegenError> {
    let (tokens, report) = trees::module(model, map, trees, options)?;
    Ok((render(tokens, map, options)?, report))
}

/// The module's tokens as formatted text under the `@generated` line.
fn render(
    tokens: proc_macro2::TokenStream,
    map: &TopoMap,
    options: &CodegenOptions,
) -> Result<String, CodegenError> {
    // Tokens to a syntax tree for prettyplease; the emitters build every item with
    // `quote!`, so this fails only on a generator bug.
    let file: syn::File = syn::parse2(tokens).map_err(|e| CodegenError::Internal(e.to_string()))?;
    Ok(generated_header(&options.model_label, &map.name) + &prettyplease::unparse(&file))
}

/// The `// @generated` line naming the model and the map. Control characters (a line
/// break would end the comment) and the characters that reorder text on screen
/// (which rustc refuses in comments: `text_direction_codepoint_in_comment`) are
/// written as `\u{..}` escapes.
fn generated_header(model_label: &str, map_name: &str) -> String {
    const REORDERING: [char; 12] = [
        '\u{061C}', '\u{200E}', '\u{200F}', '\u{202A}', '\u{202B}', '\u{202C}', '\u{202D}',
        '\u{202E}', '\u{2066}', '\u{2067}', '\u{2068}', '\u{2069}',
    ];
    let shown = |text: &str| -> String {
        text.chars()
            .map(|c| {
                if c.is_control() || REORDERING.contains(&c) {
                    c.escape_unicode().to_string()
                } else {
                    c.to_string()
                }
            })
            .collect()
    };
    // lint: a comment line, which token trees cannot carry
    format!(
        "// @generated by graphspn-compiler {} from {}, {}; do not edit\n",
        env!("CARGO_PKG_VERSION"),
        shown(model_label),
        shown(map_name)
    )
}

#[cfg(test)]
mod tests {
    use super::{CodegenError, CodegenOptions, Vectorisation, generated_header};

    /// A map name that would end the comment (a line break) or reorder it on screen
    /// (rustc refuses those characters in comments) is escaped in the header line.
    #[test]
    fn the_header_line_escapes_line_breaks_and_reordering_characters() {
        let h = generated_header("model.json", "B\u{fc}ro\u{2067}x\nfn evil() {}\u{202e}");
        assert_eq!(h.lines().count(), 1, "{h}");
        assert!(
            h.contains(r"Büro\u{2067}x\u{a}fn evil() {}\u{202e}; do not edit"),
            "{h}"
        );
    }

    /// The tables index places with `u16`: 65,535 places compile, one more is refused
    /// (with 65,536, the tree tables' `u16::MAX`, "no parent", would be a place too).
    #[test]
    fn the_place_limit_is_u16_max() {
        let options = CodegenOptions::default();
        assert!(options.check(65_535).is_ok());
        let err = options.check(65_536).unwrap_err();
        assert!(
            matches!(&err, CodegenError::BadOption(m) if m.contains("65,535") && m.contains("65536")),
            "{err}"
        );
    }

    /// SIMD lane groups where the target has float SIMD the generated code uses
    /// (x86-64, AArch64); scalar code on microcontrollers and anything unknown.
    #[test]
    fn vectorisation_follows_the_target_arch() {
        for arch in ["x86_64", "aarch64"] {
            assert_eq!(Vectorisation::for_arch(arch), Vectorisation::Simd, "{arch}");
        }
        for arch in ["arm", "riscv32", "riscv64", "xtensa", "avr", "x86", ""] {
            assert_eq!(
                Vectorisation::for_arch(arch),
                Vectorisation::Scalar,
                "{arch}"
            );
        }
    }
}
