//! Sum-product networks over categorical variables.
//!
//! An [`Spn`] is a rooted DAG of [`Node`]s stored in topological order: every
//! child comes before its parent in [`Spn::nodes`]. Leaves are the paper's
//! intermediate product layer: the indicator `λ[Y_var = class]` multiplied by the
//! local evidence value `α_var^class` (α = 1 means "no evidence"). Sums carry
//! non-negative weights; products multiply their children.

use serde::{Deserialize, Serialize};

/// Index of a node in [`Spn::nodes`].
pub type NodeId = u32;

/// One node of an [`Spn`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Node {
    /// `λ[Y_var = class] · α_var^class`.
    Leaf {
        /// Variable index, `0..spn.num_vars()`.
        var: u32,
        /// Class index, `0..spn.classes[var]`.
        class: u32,
    },
    /// `Σ_j weights[j] · value(children[j])`; weights are finite and ≥ 0.
    Sum {
        /// Child node ids (each smaller than this node's id).
        children: Vec<NodeId>,
        /// One weight per child.
        weights: Vec<f64>,
    },
    /// `Π_j value(children[j])`; children have pairwise disjoint scopes.
    Product {
        /// Child node ids (each smaller than this node's id).
        children: Vec<NodeId>,
    },
}

/// A sum-product network over categorical variables `0..classes.len()`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spn {
    /// Number of classes of each variable (`classes[v]` ≥ 1).
    pub classes: Vec<u32>,
    /// Nodes in topological order (children before parents).
    pub nodes: Vec<Node>,
    /// The root node.
    pub root: NodeId,
}

impl Spn {
    /// Number of variables.
    pub fn num_vars(&self) -> usize {
        self.classes.len()
    }

    /// Number of edges (children of sums and products).
    pub fn num_edges(&self) -> usize {
        self.nodes
            .iter()
            .map(|n| match n {
                Node::Leaf { .. } => 0,
                Node::Sum { children, .. } | Node::Product { children } => children.len(),
            })
            .sum()
    }
}

pub mod builder;
pub mod format;
pub mod mixing;
pub mod random;
pub mod validate;

pub use builder::SpnBuilder;
pub use format::{SPN_FORMAT_VERSION, SpnFormatError};
pub use mixing::Mixing;
pub use random::{RandomSpnParams, random_spn};
pub use validate::SpnError;
