//! Markov random field baselines (MRF-2, MRF-3) with loopy belief propagation.
//!
//! - [`factor_graph`](crate::mrf::factor_graph): a general discrete factor graph with dense tables, and
//!   brute-force exact inference for testing.
//! - [`bp`](crate::mrf::bp): sum-product loopy belief propagation with damping, two schedules
//!   and the Bethe approximation of `log Z`.
//! - [`model`](crate::mrf::model): the paper's baselines built on a [`crate::map::TopoMap`]:
//!   [`Mrf2`](crate::mrf::Mrf2) (a pairwise factor per edge) and [`Mrf3`](crate::mrf::Mrf3) (a three-variable factor
//!   per connected triple), with potentials from co-occurrence counts.

pub mod bp;
pub mod factor_graph;
pub mod model;

pub use bp::{BpOptions, BpResult, Schedule, loopy_bp};
pub use factor_graph::{ExactResult, Factor, FactorGraph, exact_inference, variable_elimination};
pub use model::{
    Cliques, CooccurrenceMrf, CooccurrenceParams, LabelledLikelihood, MAX_COUPLING, Mrf2, Mrf3,
    MrfModel, Normalisation,
};

use thiserror::Error;

/// Errors of factor-graph construction, inference and MRF training.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MrfError {
    /// A variable was declared with zero states.
    #[error("variable {var} has cardinality 0")]
    ZeroCardinality {
        /// Variable index.
        var: usize,
    },
    /// A factor with no variables.
    #[error("factor {factor} has no variables")]
    EmptyFactor {
        /// Factor id.
        factor: usize,
    },
    /// A factor names a variable that does not exist.
    #[error("factor {factor} uses variable {var}, but the graph has {num_vars} variables")]
    UnknownVariable {
        /// Factor id.
        factor: usize,
        /// Variable index.
        var: usize,
        /// Number of variables.
        num_vars: usize,
    },
    /// A factor lists a variable twice.
    #[error("factor {factor} lists variable {var} twice")]
    RepeatedVariable {
        /// Factor id.
        factor: usize,
        /// Variable index.
        var: usize,
    },
    /// A factor table would be too large.
    #[error(
        "factor {factor} has more than {} table entries",
        factor_graph::MAX_FACTOR_ENTRIES
    )]
    FactorTooLarge {
        /// Factor id.
        factor: usize,
    },
    /// A factor table of the wrong length.
    #[error("factor {factor}: table has {found} entries, expected {expected}")]
    TableSize {
        /// Factor id.
        factor: usize,
        /// Expected length.
        expected: usize,
        /// Given length.
        found: usize,
    },
    /// A negative or non-finite potential.
    #[error("factor {factor}: table entry {entry} is {value}, potentials must be finite and ≥ 0")]
    BadPotential {
        /// Factor id.
        factor: usize,
        /// Entry index.
        entry: usize,
        /// The bad value.
        value: f64,
    },
    /// A factor with more variables than BP supports.
    #[error("factor {factor} has {arity} variables; belief propagation supports at most {max}")]
    ArityTooLarge {
        /// Factor id.
        factor: usize,
        /// Its arity.
        arity: usize,
        /// Largest supported arity.
        max: usize,
    },
    /// An assignment of the wrong length.
    #[error("assignment has {found} values, the graph has {expected} variables")]
    AssignmentLength {
        /// Number of variables.
        expected: usize,
        /// Given length.
        found: usize,
    },
    /// A state index outside a variable's range.
    #[error("variable {var}: state {state} is out of range (cardinality {card})")]
    StateOutOfRange {
        /// Variable index.
        var: usize,
        /// Given state.
        state: usize,
        /// Cardinality.
        card: usize,
    },
    /// Exact inference refused: too many joint states.
    #[error("more than {max_states} joint states; exact enumeration refused")]
    TooManyStates {
        /// The limit.
        max_states: usize,
    },
    /// Every joint state has score zero.
    #[error("every joint state has probability zero (inconsistent factors)")]
    Inconsistent,
    /// Belief propagation produced a message or belief with no positive entry.
    #[error(
        "belief propagation contradiction at variable {var} (factor {factor:?}) in sweep {iteration}: every state has zero weight"
    )]
    Contradiction {
        /// Variable index.
        var: usize,
        /// Factor id, when the zero message came from a factor.
        factor: Option<usize>,
        /// Sweep number (1-based).
        iteration: usize,
    },
    /// Invalid BP or training options.
    #[error("invalid options: {0}")]
    BadOptions(String),
    /// A map or evidence that does not fit the model.
    #[error("{0}")]
    BadInput(String),
}
