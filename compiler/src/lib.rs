//! Host side of GraphSPN (Zheng, Pronobis & Rao, AAAI 2018) in Rust.
//!
//! One module per concern, each named after the part of the paper it implements:
//!
//! | module | what |
//! |---|---|
//! | [`spn`] | sum-product networks: representation, validation, JSON format |
//! | [`domain`] | the domains of numeric settings, and the one check per settings type |
//! | [`interpreter`] | the exact reference evaluator: log-likelihood, marginals, MPE |
//! | [`map`] | topological maps, the COLD and JSON loaders, the synthetic office-floor generator |
//! | [`template`] | sub-graph templates (Singleton, Pair, Three, Star, user-defined) and matching |
//! | [`decompose`] | decompositions of a map into template-shaped components (the paper's Alg. 2) |
//! | [`render`] | SVG drawings of maps, marginals and decompositions |
//! | [`learn`] | template SPN structure generation and EM training; the model file |
//! | [`treemix`] | tree mixtures: an exact mixture of edge-covering spanning trees (the second model family) |
//! | [`family`] | the model families and the loader that reads a model file of either |
//! | [`model_file`] | what both families' model files share: the `family` field, the error type, parse errors |
//! | [`inputs`] | the one check that a GraphSPN model, a map and decompositions fit together |
//! | [`json_error`] | JSON errors as one message with their position |
//! | [`instance`] | the instance GraphSPN of a map (the paper's Alg. 1) |
//! | [`codegen`] | straight-line `no_std` Rust for a known map, and the `build.rs` builder |
//! | [`mrf`] | Markov random field baselines with loopy belief propagation |
//! | [`noise`] | the paper's simulation of noisy local evidence (noise levels 1–6) |
//! | [`experiments`] | the paper's experiments: validation, reproduction, report |
//! | [`progress`] | progress of long steps on standard error: bars on a terminal, plain lines elsewhere |
//!
//! Features: `host` (default) is everything; `codegen` alone is code generation and
//! the loading it needs (maps, models, decompositions) — what a firmware's `build.rs`
//! depends on; without `host` the modules marked *(host)* below are absent.
#![forbid(unsafe_code)]
#![warn(missing_docs)]
// Without `host`, some helpers exist only for the absent modules.
#![cfg_attr(not(feature = "host"), allow(dead_code, unused_imports))]

#[cfg(feature = "codegen")]
pub mod codegen;
pub mod decompose;
pub mod domain;
/// *(host)*
#[cfg(feature = "host")]
pub mod experiments;
pub mod family;
pub mod inputs;
/// *(host)*
#[cfg(feature = "host")]
pub mod instance;
/// *(host)*
#[cfg(feature = "host")]
pub mod interpreter;
pub mod json_error;
pub mod learn;
pub mod map;
pub mod model_file;
/// *(host)*
#[cfg(feature = "host")]
pub mod mrf;
/// *(host)*
#[cfg(feature = "host")]
pub mod noise;
mod par;
/// *(host)*
#[cfg(feature = "host")]
pub mod progress;
/// *(host)*
#[cfg(feature = "host")]
pub mod render;
pub mod spn;
pub mod template;
pub mod treemix;

pub use graphspn_runtime as runtime;
