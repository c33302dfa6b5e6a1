//! Structural validation of an [`Spn`]: ids, ordering, weights, completeness,
//! decomposability, reachability.
//!
//! Scopes are interned bitsets: every distinct scope is stored once and every node
//! holds a scope id, so a sum checks completeness with one integer comparison per
//! edge and a product checks decomposability with one bitset AND per edge
//! (`⌈vars/64⌉` words). Validation is `O(E · ⌈vars/64⌉)` time.

use std::collections::HashMap;

use thiserror::Error;

use super::{Node, NodeId, Spn};

/// Tolerance on `|Σ weights − 1|` accepted by [`Spn::validate`].
pub const WEIGHT_SUM_TOLERANCE: f64 = 1e-9;

/// What is structurally wrong with an [`Spn`], and at which node or variable.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum SpnError {
    /// The SPN has no variables.
    #[error("the SPN has no variables (classes is empty)")]
    NoVariables,
    /// A variable has zero classes.
    #[error("variable {var} has 0 classes")]
    ZeroClasses {
        /// The variable.
        var: u32,
    },
    /// The root id is not a node.
    #[error("root node {root} is out of range (the SPN has {len} nodes)")]
    RootOutOfRange {
        /// The root id.
        root: NodeId,
        /// Number of nodes.
        len: usize,
    },
    /// A child id is not a node.
    #[error("node {node}: child {child} is out of range (the SPN has {len} nodes)")]
    ChildOutOfRange {
        /// The parent.
        node: NodeId,
        /// The bad child id.
        child: NodeId,
        /// Number of nodes.
        len: usize,
    },
    /// A sum has a different number of children and weights.
    #[error("sum node {node} has {children} children but {weights} weights")]
    WeightCountMismatch {
        /// The sum.
        node: NodeId,
        /// Number of children.
        children: usize,
        /// Number of weights.
        weights: usize,
    },
    /// A sum has no children.
    #[error("sum node {node} has no children")]
    EmptySum {
        /// The sum.
        node: NodeId,
    },
    /// A product has no children.
    #[error("product node {node} has no children")]
    EmptyProduct {
        /// The product.
        node: NodeId,
    },
    /// A weight is NaN or infinite.
    #[error("sum node {node}: weight {index} is not finite ({weight})")]
    NonFiniteWeight {
        /// The sum.
        node: NodeId,
        /// Position of the weight.
        index: usize,
        /// The weight.
        weight: f64,
    },
    /// A weight is negative.
    #[error("sum node {node}: weight {index} is negative ({weight})")]
    NegativeWeight {
        /// The sum.
        node: NodeId,
        /// Position of the weight.
        index: usize,
        /// The weight.
        weight: f64,
    },
    /// A sum's weights do not add up to 1 (within [`WEIGHT_SUM_TOLERANCE`]).
    #[error("sum node {node}: weights sum to {total}, not 1 (tolerance 1e-9; call Spn::normalise)")]
    NotNormalised {
        /// The sum.
        node: NodeId,
        /// The weights' total.
        total: f64,
    },
    /// A sum's weights are all zero (it cannot be normalised).
    #[error("sum node {node}: all weights are zero")]
    ZeroWeightSum {
        /// The sum.
        node: NodeId,
    },
    /// A leaf names a variable that does not exist.
    #[error("leaf node {node}: variable {var} is out of range (the SPN has {num_vars} variables)")]
    LeafVarOutOfRange {
        /// The leaf.
        node: NodeId,
        /// Its variable.
        var: u32,
        /// Number of variables.
        num_vars: usize,
    },
    /// A leaf names a class its variable does not have.
    #[error(
        "leaf node {node}: class {class} of variable {var} is out of range (it has {classes} classes)"
    )]
    LeafClassOutOfRange {
        /// The leaf.
        node: NodeId,
        /// Its variable.
        var: u32,
        /// Its class.
        class: u32,
        /// Classes of the variable.
        classes: u32,
    },
    /// The child graph has a cycle.
    #[error("the SPN has a cycle through nodes {nodes:?}")]
    Cycle {
        /// Node ids along the cycle, each a child of the previous (and the first a child of the last).
        nodes: Vec<NodeId>,
    },
    /// A child does not come before its parent (no cycle, but not in topological order).
    #[error(
        "node {node}: child {child} does not come before its parent (nodes must be in topological order)"
    )]
    Misordered {
        /// The parent.
        node: NodeId,
        /// The child whose id is not smaller.
        child: NodeId,
    },
    /// A sum's children have different scopes (incompleteness).
    #[error(
        "sum node {node} is not complete: child {child_a} has scope {scope_a:?} but child {child_b} has scope {scope_b:?}"
    )]
    Incomplete {
        /// The sum.
        node: NodeId,
        /// First child.
        child_a: NodeId,
        /// Scope (sorted variables) of the first child.
        scope_a: Vec<u32>,
        /// A child with a different scope.
        child_b: NodeId,
        /// Its scope.
        scope_b: Vec<u32>,
    },
    /// A product's children share a variable (non-decomposability).
    #[error(
        "product node {node} is not decomposable: variable {var} is in the scope of more than one child (child {child})"
    )]
    NotDecomposable {
        /// The product.
        node: NodeId,
        /// The shared variable.
        var: u32,
        /// The child that repeats the variable.
        child: NodeId,
    },
    /// A variable appears in no leaf reachable from the root.
    #[error("variable {var} does not occur in the SPN (the root's scope lacks it)")]
    VariableNotInScope {
        /// The variable.
        var: u32,
    },
    /// A node cannot be reached from the root.
    #[error("node {node} is unreachable from root {root} ({count} unreachable nodes in all)")]
    Unreachable {
        /// The first unreachable node.
        node: NodeId,
        /// The root.
        root: NodeId,
        /// Number of unreachable nodes.
        count: usize,
    },
}

impl SpnError {
    /// The node the error is about, when it is about one node.
    pub fn node(&self) -> Option<NodeId> {
        use SpnError::*;
        match self {
            NoVariables | ZeroClasses { .. } | VariableNotInScope { .. } => None,
            RootOutOfRange { root, .. } => Some(*root),
            Cycle { nodes } => nodes.first().copied(),
            ChildOutOfRange { node, .. }
            | WeightCountMismatch { node, .. }
            | EmptySum { node }
            | EmptyProduct { node }
            | NonFiniteWeight { node, .. }
            | NegativeWeight { node, .. }
            | NotNormalised { node, .. }
            | ZeroWeightSum { node }
            | LeafVarOutOfRange { node, .. }
            | LeafClassOutOfRange { node, .. }
            | Misordered { node, .. }
            | Incomplete { node, .. }
            | NotDecomposable { node, .. }
            | Unreachable { node, .. } => Some(*node),
        }
    }
}

/// Interned bitset scopes.
struct Scopes {
    words: usize,
    sets: Vec<u64>,
    index: HashMap<Box<[u64]>, u32>,
}

impl Scopes {
    fn new(num_vars: usize) -> Self {
        Scopes {
            words: num_vars.div_ceil(64).max(1),
            sets: Vec::new(),
            index: HashMap::new(),
        }
    }

    fn get(&self, id: u32) -> &[u64] {
        let s = id as usize * self.words;
        &self.sets[s..s + self.words]
    }

    fn intern(&mut self, bits: &[u64]) -> u32 {
        if let Some(&id) = self.index.get(bits) {
            return id;
        }
        let id = self.index.len() as u32;
        self.sets.extend_from_slice(bits);
        self.index.insert(bits.into(), id);
        id
    }

    fn vars(&self, id: u32) -> Vec<u32> {
        bits_to_vars(self.get(id))
    }
}

fn bits_to_vars(bits: &[u64]) -> Vec<u32> {
    let mut out = Vec::new();
    for (w, &word) in bits.iter().enumerate() {
        let mut x = word;
        while x != 0 {
            let b = x.trailing_zeros();
            out.push(w as u32 * 64 + b);
            x &= x - 1;
        }
    }
    out
}

fn children_of(node: &Node) -> &[NodeId] {
    match node {
        Node::Leaf { .. } => &[],
        Node::Sum { children, .. } | Node::Product { children } => children,
    }
}

/// Finds a cycle in the child graph (ids already known to be in range), iteratively.
fn find_cycle(spn: &Spn) -> Option<Vec<NodeId>> {
    let n = spn.nodes.len();
    // 0 = unvisited, 1 = on stack, 2 = done.
    let mut state = vec![0u8; n];
    let mut stack: Vec<(NodeId, usize)> = Vec::new();
    for start in 0..n {
        if state[start] != 0 {
            continue;
        }
        stack.push((start as NodeId, 0));
        state[start] = 1;
        while let Some(&mut (node, ref mut next)) = stack.last_mut() {
            let children = children_of(&spn.nodes[node as usize]);
            if *next < children.len() {
                let c = children[*next];
                *next += 1;
                match state[c as usize] {
                    0 => {
                        state[c as usize] = 1;
                        stack.push((c, 0));
                    }
                    1 => {
                        let pos = stack.iter().position(|&(x, _)| x == c).unwrap_or(0);
                        return Some(stack[pos..].iter().map(|&(x, _)| x).collect());
                    }
                    _ => {}
                }
            } else {
                state[node as usize] = 2;
                stack.pop();
            }
        }
    }
    None
}

impl Spn {
    /// Checks every structural invariant, including that every sum's weights add up
    /// to 1 within [`WEIGHT_SUM_TOLERANCE`]. Runs in `O(E · ⌈vars/64⌉)`.
    pub fn validate(&self) -> Result<(), SpnError> {
        self.validate_impl(true)
    }

    /// Like [`Spn::validate`] but accepts sums whose (finite, non-negative, not all zero)
    /// weights do not add up to 1.
    pub fn validate_unnormalised(&self) -> Result<(), SpnError> {
        self.validate_impl(false)
    }

    /// Rescales every sum's weights to add up to 1. Fails (changing nothing) if a weight
    /// is negative or not finite, or if a sum's weights are all zero.
    pub fn normalise(&mut self) -> Result<(), SpnError> {
        for (id, node) in self.nodes.iter().enumerate() {
            if let Node::Sum { weights, .. } = node {
                check_weights(id as NodeId, weights)?;
                if weights.iter().sum::<f64>() <= 0.0 {
                    return Err(SpnError::ZeroWeightSum { node: id as NodeId });
                }
            }
        }
        for node in &mut self.nodes {
            if let Node::Sum { weights, .. } = node {
                let total: f64 = weights.iter().sum();
                for w in weights.iter_mut() {
                    *w /= total;
                }
            }
        }
        Ok(())
    }

    fn validate_impl(&self, normalised: bool) -> Result<(), SpnError> {
        let len = self.nodes.len();
        let num_vars = self.classes.len();
        if num_vars == 0 {
            return Err(SpnError::NoVariables);
        }
        if let Some(v) = self.classes.iter().position(|&c| c == 0) {
            return Err(SpnError::ZeroClasses { var: v as u32 });
        }
        if self.root as usize >= len {
            return Err(SpnError::RootOutOfRange {
                root: self.root,
                len,
            });
        }
        // Pass 1: local checks (ids, lengths, weights, leaves).
        let mut misordered = None;
        for (id, node) in self.nodes.iter().enumerate() {
            let id = id as NodeId;
            match node {
                Node::Leaf { var, class } => {
                    let Some(&k) = self.classes.get(*var as usize) else {
                        return Err(SpnError::LeafVarOutOfRange {
                            node: id,
                            var: *var,
                            num_vars,
                        });
                    };
                    if *class >= k {
                        return Err(SpnError::LeafClassOutOfRange {
                            node: id,
                            var: *var,
                            class: *class,
                            classes: k,
                        });
                    }
                }
                Node::Sum { children, weights } => {
                    if children.is_empty() {
                        return Err(SpnError::EmptySum { node: id });
                    }
                    if children.len() != weights.len() {
                        return Err(SpnError::WeightCountMismatch {
                            node: id,
                            children: children.len(),
                            weights: weights.len(),
                        });
                    }
                    check_weights(id, weights)?;
                    let total: f64 = weights.iter().sum();
                    if normalised && (total - 1.0).abs() > WEIGHT_SUM_TOLERANCE {
                        return Err(SpnError::NotNormalised { node: id, total });
                    }
                    if total <= 0.0 {
                        return Err(SpnError::ZeroWeightSum { node: id });
                    }
                }
                Node::Product { children } => {
                    if children.is_empty() {
                        return Err(SpnError::EmptyProduct { node: id });
                    }
                }
            }
            for &c in children_of(node) {
                if c as usize >= len {
                    return Err(SpnError::ChildOutOfRange {
                        node: id,
                        child: c,
                        len,
                    });
                }
                if c >= id && misordered.is_none() {
                    misordered = Some((id, c));
                }
            }
        }
        if let Some((node, child)) = misordered {
            return Err(match find_cycle(self) {
                Some(nodes) => SpnError::Cycle { nodes },
                None => SpnError::Misordered { node, child },
            });
        }
        // Pass 2: reachability (reverse topological order).
        let mut reachable = vec![false; len];
        reachable[self.root as usize] = true;
        for id in (0..len).rev() {
            if reachable[id] {
                for &c in children_of(&self.nodes[id]) {
                    reachable[c as usize] = true;
                }
            }
        }
        let count = reachable.iter().filter(|r| !**r).count();
        if count > 0 {
            let node = reachable.iter().position(|r| !*r).unwrap_or(0) as NodeId;
            return Err(SpnError::Unreachable {
                node,
                root: self.root,
                count,
            });
        }
        // Pass 3: scopes, completeness, decomposability.
        let mut scopes = Scopes::new(num_vars);
        let words = scopes.words;
        let mut scope_of = vec![0u32; len];
        let mut acc = vec![0u64; words];
        for (id, node) in self.nodes.iter().enumerate() {
            let nid = id as NodeId;
            scope_of[id] = match node {
                Node::Leaf { var, .. } => {
                    acc.iter_mut().for_each(|w| *w = 0);
                    acc[*var as usize / 64] |= 1u64 << (*var % 64);
                    scopes.intern(&acc)
                }
                Node::Sum { children, .. } => {
                    let first = scope_of[children[0] as usize];
                    for &c in &children[1..] {
                        let s = scope_of[c as usize];
                        if s != first {
                            return Err(SpnError::Incomplete {
                                node: nid,
                                child_a: children[0],
                                scope_a: scopes.vars(first),
                                child_b: c,
                                scope_b: scopes.vars(s),
                            });
                        }
                    }
                    first
                }
                Node::Product { children } => {
                    acc.iter_mut().for_each(|w| *w = 0);
                    for &c in children {
                        let cs = scopes.get(scope_of[c as usize]);
                        for (w, (a, &b)) in acc.iter_mut().zip(cs).enumerate() {
                            let shared = *a & b;
                            if shared != 0 {
                                return Err(SpnError::NotDecomposable {
                                    node: nid,
                                    var: w as u32 * 64 + shared.trailing_zeros(),
                                    child: c,
                                });
                            }
                            *a |= b;
                        }
                    }
                    scopes.intern(&acc)
                }
            };
        }
        let root_scope = scopes.get(scope_of[self.root as usize]);
        for v in 0..num_vars {
            if root_scope[v / 64] & (1u64 << (v % 64)) == 0 {
                return Err(SpnError::VariableNotInScope { var: v as u32 });
            }
        }
        Ok(())
    }
}

fn check_weights(node: NodeId, weights: &[f64]) -> Result<(), SpnError> {
    for (index, &weight) in weights.iter().enumerate() {
        if !weight.is_finite() {
            return Err(SpnError::NonFiniteWeight {
                node,
                index,
                weight,
            });
        }
        if weight < 0.0 {
            return Err(SpnError::NegativeWeight {
                node,
                index,
                weight,
            });
        }
    }
    Ok(())
}
