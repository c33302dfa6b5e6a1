//! [`SpnBuilder`]: incremental construction of an [`Spn`] in topological order.

use std::collections::HashMap;

use super::validate::SpnError;
use super::{Node, NodeId, Spn};

/// Builds an [`Spn`] node by node. Every `add_*` returns the new node's id; children
/// must be ids returned earlier, so the nodes stay in topological order. Identical
/// leaves are deduplicated (asking twice for `(var, class)` returns the same id).
#[derive(Clone, Debug, Default)]
pub struct SpnBuilder {
    classes: Vec<u32>,
    nodes: Vec<Node>,
    leaves: HashMap<(u32, u32), NodeId>,
}

impl SpnBuilder {
    /// A builder for variables with `classes[v]` classes each.
    pub fn new(classes: Vec<u32>) -> Self {
        SpnBuilder {
            classes,
            nodes: Vec::new(),
            leaves: HashMap::new(),
        }
    }

    /// Number of nodes added so far.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True if no node has been added.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The classes per variable.
    pub fn classes(&self) -> &[u32] {
        &self.classes
    }

    fn push(&mut self, node: Node) -> NodeId {
        let id = self.nodes.len() as NodeId;
        self.nodes.push(node);
        id
    }

    /// The indicator leaf `λ[Y_var = class]` (deduplicated).
    pub fn add_leaf(&mut self, var: u32, class: u32) -> NodeId {
        if let Some(&id) = self.leaves.get(&(var, class)) {
            return id;
        }
        let id = self.push(Node::Leaf { var, class });
        self.leaves.insert((var, class), id);
        id
    }

    /// A weighted sum of earlier nodes.
    pub fn add_sum(&mut self, children: Vec<NodeId>, weights: Vec<f64>) -> NodeId {
        self.push(Node::Sum { children, weights })
    }

    /// A product of earlier nodes.
    pub fn add_product(&mut self, children: Vec<NodeId>) -> NodeId {
        self.push(Node::Product { children })
    }

    /// Finishes with `root` as the root and validates ([`Spn::validate`]).
    pub fn finish(self, root: NodeId) -> Result<Spn, SpnError> {
        let spn = self.finish_unchecked(root);
        spn.validate()?;
        Ok(spn)
    }

    /// Finishes, normalises every sum's weights ([`Spn::normalise`]) and validates.
    pub fn finish_normalised(self, root: NodeId) -> Result<Spn, SpnError> {
        let mut spn = self.finish_unchecked(root);
        spn.normalise()?;
        spn.validate()?;
        Ok(spn)
    }

    /// Finishes without any check (the result may be invalid).
    pub fn finish_unchecked(self, root: NodeId) -> Spn {
        Spn {
            classes: self.classes,
            nodes: self.nodes,
            root,
        }
    }
}
