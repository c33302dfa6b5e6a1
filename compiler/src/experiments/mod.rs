//! Evidence simulation and the paper's experiments.

pub mod evidence;
