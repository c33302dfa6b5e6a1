//! Run-time support shared by the `graphspn` interpreter and the Rust code that
//! `graphspn-compiler` generates for a known map.
//!
//! Everything here is `no_std`, allocation-free and free of `unsafe`:
//! - [`numerics`]: log-space arithmetic (log-sum-exp with a documented error bound);
//! - [`EvidenceError`]: what is wrong with a row of local evidence, and where;
//! - [`CompiledMap`]: the trait every compiled map implements;
//! - with the `fallback-counts` feature, `fallback_counts()`: how often the fixed-point
//!   kernel of a target without an FPU handed a template call to `f32`.
//!
//! Items in [`__private`] exist only for generated code and may change without notice.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod error;
#[cfg(feature = "fallback-counts")]
pub mod fallback_counts;
pub mod numerics;

pub use error::EvidenceError;
#[cfg(feature = "fallback-counts")]
pub use fallback_counts::{FallbackCounts, fallback_counts, reset_fallback_counts};

/// Helpers called only by generated code. Not part of the public API.
#[doc(hidden)]
pub mod __private;
pub mod compiled;

pub use compiled::CompiledMap;
