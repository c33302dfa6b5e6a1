//! Evidence simulation and the paper's experiments.
