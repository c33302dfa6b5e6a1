//! Host side of GraphSPN (Zheng, Pronobis & Rao, AAAI 2018) in Rust.
//!
//! One module per concern, each named after the part of the paper it implements:
//!
//! | module | what |
//! |---|---|
//! | [`spn`] | sum-product networks: representation, validation, JSON format |
//! | [`interpreter`] | the exact reference evaluator: log-likelihood, marginals, MPE |
//! | [`map`] | topological maps, the COLD and JSON loaders, the synthetic office-floor generator |
//! | [`template`] | sub-graph templates (Singleton, Pair, Three, Star, user-defined) and matching |
//! | [`decompose`] | decompositions of a map into template-shaped components (the paper's Alg. 2) |
//! | [`render`] | SVG drawings of maps, marginals and decompositions |
//! | [`learn`] | template SPN structure generation and EM training; the model file |
//! | [`instance`] | the instance GraphSPN of a map (the paper's Alg. 1) |
//! | [`codegen`] | straight-line `no_std` Rust for a known map, and the `build.rs` builder |
//! | [`mrf`] | Markov random field baselines with loopy belief propagation |
//! | [`experiments`] | evidence simulation and the paper's experiments |
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod codegen;
pub mod decompose;
pub mod experiments;
pub mod instance;
pub mod interpreter;
pub mod learn;
pub mod map;
pub mod mrf;
pub mod render;
pub mod spn;
pub mod template;

pub use graphspn_runtime as runtime;
