//! The paper's experiments: validation, reproduction, report.
//!
//! `evidence` is the evidence simulation ([`crate::noise`]), re-exported here under
//! its former name.

pub use crate::noise as evidence;
pub mod ceiling;
pub mod config;
pub mod error;
pub mod figures;
pub mod grid;
pub mod models;
pub mod novelty;
pub mod protocol;
pub mod report;
pub mod reproduce;
pub mod result_tables;
pub mod results;
pub mod sets;
pub mod settings;
pub mod stats;
pub mod summary;
pub mod validate;
pub mod validation_report;
