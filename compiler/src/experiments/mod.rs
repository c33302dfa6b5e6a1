//! Evidence simulation and the paper's experiments.

pub mod evidence;
pub mod report;
pub mod reproduce;
pub mod validate;
