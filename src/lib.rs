//! `graphspn`: learn GraphSPNs over topological semantic maps, answer exact queries
//! about any map, and compile the model of a known map into straight-line `no_std` Rust.
//!
//! This crate re-exports the workspace members; the command-line tool is `src/main.rs`.
#![forbid(unsafe_code)]

pub use graphspn_compiler as compiler;
pub use graphspn_compiler::*;
pub use graphspn_runtime as runtime;
