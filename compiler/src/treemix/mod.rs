//! Tree mixtures: an exact model of a whole map that a microcontroller can afford.
//!
//! # The model
//!
//! For a map with places `V` and `C` classes, a tree mixture holds `T` spanning
//! forests `F_1..F_T` of the map (one tree per connected component; together they
//! cover every edge, [`trees`]) and one learned pairwise potential `ψ(a, b)` (`C × C`,
//! symmetric, > 0) and unary potential `u(c)` shared by every edge and place:
//!
//! ```text
//! P_t(y) = (1/Z_t) Π_v u(y_v) Π_{(a,b) ∈ F_t} ψ(y_a, y_b)        (a tree-structured MRF)
//! P(y)   = (1/T) Σ_t P_t(y)                                       (the mixture)
//! S(α)   = Σ_y P(y) Π_v α_v(y_v)^γ                                (likelihood of the evidence)
//! ```
//!
//! with the evidence rows `α_v` raised to an integer exponent `γ`. It is a
//! sum-product network: a sum over forests, each a product over places of sums over
//! the place's class given its parent's ([`spn`]), so every query is exact:
//! `ln S(α)`, the marginals `P(Y_v | α)` (the exact mixture, or the mean of the
//! forests' exact marginals: [`crate::spn::Mixing`]), the most probable
//! `(forest, labelling)` pair and the likelihood of a labelled map. Each forest costs
//! one upward pass of `C × C` matrix–vector products per place (and one downward pass
//! for marginals): `O(T · places · C²)`, no iteration, no convergence to check.
//!
//! Why: a GraphSPN partitions the map into pieces of at most five places, so evidence
//! never crosses a piece boundary; loopy belief propagation in an MRF chains evidence
//! along the map but is approximate and iterative. A spanning tree chains evidence
//! across the whole map exactly; a few trees that together cover every edge let every
//! neighbour of a place speak to it.
//!
//! # Modules
//!
//! - [`model`]: the model file ([`TreeMixture`]) and its one check;
//! - [`trees`]: the edge-covering spanning forests of a map ([`SpanningTrees`]);
//! - [`train`](mod@train) *(host)*: potentials from co-occurrence counts ([`TreeTraining`]);
//! - [`exact`] *(host)*: exact inference in `f64` ([`TreeInstance`]);
//! - [`fit`] *(host)*: noise-aware training of the potentials ([`fit_potentials`]);
//! - [`spn`] *(host)*: the explicit instance SPN, the interpreter's reference.

#[cfg(feature = "host")]
pub mod exact;
#[cfg(feature = "host")]
pub mod fit;
pub mod model;
#[cfg(feature = "host")]
pub mod spn;
#[cfg(feature = "host")]
pub mod train;
pub mod trees;

#[cfg(feature = "host")]
pub use exact::{TreeInstance, TreeMarginals};
#[cfg(feature = "host")]
pub use fit::{FitGraph, FitOptions, FitReport, fit_potentials};
pub use model::{MAX_TREES, TreeMixture};
#[cfg(feature = "host")]
pub use spn::instance_spn;
#[cfg(feature = "host")]
pub use train::{NoiseFit, TreeTraining, train_tree_mixture};
pub use trees::{NO_PARENT, RootedForest, SpanningTrees, check_inputs, check_map};

use graphspn_runtime::EvidenceError;
use thiserror::Error;

/// Why a tree mixture could not be trained, instantiated or queried.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum TreeMixError {
    /// The model (or its training settings) is invalid.
    #[error("tree mixture: {0}")]
    Model(String),
    /// The model cannot label the map (other classes, or no places).
    #[error(transparent)]
    Map(#[from] crate::map::MapFitError),
    /// The spanning forests do not fit the map.
    #[error("spanning trees: {0}")]
    BadTrees(String),
    /// Invalid evidence, or evidence of probability zero.
    #[error(transparent)]
    Evidence(#[from] EvidenceError),
    /// A place index outside the map.
    #[error("place index {place} is out of range (the map has {count} places)")]
    PlaceOutOfRange {
        /// The index given.
        place: usize,
        /// Number of places.
        count: usize,
    },
    /// A labelling has the wrong length or a class out of range.
    #[error("labelling: {0}")]
    BadLabels(String),
}
