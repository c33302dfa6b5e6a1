//! Dense random template-SPN structures (Poon–Domingos style, as in the paper's
//! "Sum-Product Networks" section and the authors' published code).
//!
//! A *region* is a set of variables. The root region holds all variables. A
//! region with more than one variable is split `decompositions` times into
//! `min(subsets, |region|)` random subsets (balanced sizes by default); for each
//! split the region gets one product per combination of one child node per
//! subset (the cartesian product), and the region's sums (`sums` of them, one at
//! the root) mix all those products. The child nodes of a single-variable region
//! are its `C` leaves. Regions are shared: a subset that appears in several
//! splits is built once.
//!
//! With the authors' settings ([`DenseParams::default`]) and 10 classes this
//! gives: Pair = the full 10×10 table (100 products under the root), Three = the
//! full 10×10×10 table (1,000 products), Star = a `{2,2,1}` split with 1,250
//! weights in all.
//!
//! [`symmetric_dense_structure`] builds the same kind of structure closed under a
//! group of variable permutations (a template's automorphisms): every region's
//! set of splits is invariant, so with tied weights (see [`super::symmetry`]) the
//! SPN is exactly invariant under the group.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use rand::Rng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
// The structure parameters live with the other settings (`super::settings`, below
// every algorithm of `learn`); re-exported here, where they are used.
pub use super::settings::{DenseParams, SplitChoice};
use crate::spn::{Node, NodeId, Spn};

/// Why a structure could not be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StructureError {
    /// Zero variables or zero classes.
    #[error(
        "a template SPN needs at least one variable and one class (got {num_vars} variables, {num_classes} classes)"
    )]
    Empty {
        /// Variables requested.
        num_vars: usize,
        /// Classes requested.
        num_classes: u32,
    },
    /// A parameter out of range.
    #[error("invalid dense structure parameter: {0}")]
    BadParam(String),
    /// A permutation of the symmetry group is not a permutation of `0..num_vars`.
    #[error("automorphism #{index} {perm:?} is not a permutation of 0..{num_vars}")]
    BadPermutation {
        /// Position in the list.
        index: usize,
        /// The offending list.
        perm: Vec<usize>,
        /// Number of variables.
        num_vars: usize,
    },
}

/// Initial-weight jitter: each weight starts at `1 + JITTER·u`, `u ~ U[0, 1)`,
/// then each sum is normalised (so weights are within 1% of uniform).
pub const INIT_JITTER: f64 = 0.01;

/// Random splits drawn per decomposition by [`symmetric_dense_structure`], of
/// which the one with the fewest images under the group is kept.
pub const SPLIT_CANDIDATES: usize = 16;

type Scope = Vec<u32>;
type Partition = Vec<Scope>;

struct Builder<'a> {
    params: &'a DenseParams,
    group: &'a [Vec<usize>],
    nodes: Vec<Node>,
    leaves: Vec<Vec<NodeId>>,
    regions: BTreeMap<Scope, Vec<NodeId>>,
    rep_partitions: BTreeMap<Scope, Vec<Partition>>,
    products: HashMap<Vec<NodeId>, NodeId>,
    rng: ChaCha8Rng,
}

fn check(num_vars: usize, num_classes: u32, params: &DenseParams) -> Result<(), StructureError> {
    if num_vars == 0 || num_classes == 0 {
        return Err(StructureError::Empty {
            num_vars,
            num_classes,
        });
    }
    if num_vars > 1 {
        if params.decompositions == 0 {
            return Err(StructureError::BadParam(
                "decompositions must be ≥ 1".into(),
            ));
        }
        if params.subsets < 2 {
            return Err(StructureError::BadParam("subsets must be ≥ 2".into()));
        }
        if params.sums == 0 {
            return Err(StructureError::BadParam("sums must be ≥ 1".into()));
        }
    }
    Ok(())
}

impl Builder<'_> {
    fn random_partition(&mut self, scope: &[u32]) -> Partition {
        let k = self.params.subsets.min(scope.len());
        let mut vars = scope.to_vec();
        vars.shuffle(&mut self.rng);
        let mut parts: Vec<Scope> = vec![Vec::new(); k];
        if self.params.balanced {
            let (base, rem) = (vars.len() / k, vars.len() % k);
            let mut it = vars.into_iter();
            for (i, p) in parts.iter_mut().enumerate() {
                let size = base + usize::from(i < rem);
                p.extend(it.by_ref().take(size));
            }
        } else {
            for (i, v) in vars.into_iter().enumerate() {
                let j = if i < k {
                    i
                } else {
                    self.rng.random_range(0..k)
                };
                parts[j].push(v);
            }
        }
        for p in &mut parts {
            p.sort_unstable();
        }
        parts.sort();
        parts
    }

    fn apply(&self, g: &[usize], scope: &[u32]) -> Scope {
        let mut s: Scope = scope.iter().map(|&v| g[v as usize] as u32).collect();
        s.sort_unstable();
        s
    }

    /// Number of distinct images of split `p` of region `rep` under the group
    /// elements that fix `rep`.
    fn orbit_size(&self, rep: &[u32], p: &Partition) -> usize {
        let mut set = BTreeSet::new();
        for g in self.group {
            if self.apply(g, rep) != rep {
                continue;
            }
            let mut q: Partition = p.iter().map(|s| self.apply(g, s)).collect();
            q.sort();
            set.insert(q);
        }
        set.len()
    }

    /// Splits of `scope`: random ones, closed under the group when there is one.
    fn partitions(&mut self, scope: &[u32]) -> Vec<Partition> {
        if self.group.is_empty() {
            let mut set = BTreeSet::new();
            let mut out = Vec::new();
            for _ in 0..self.params.decompositions {
                let p = self.random_partition(scope);
                if set.insert(p.clone()) {
                    out.push(p);
                }
            }
            return out;
        }
        // Canonical representative of the region's orbit.
        let rep = self
            .group
            .iter()
            .map(|g| self.apply(g, scope))
            .min()
            .unwrap_or_else(|| scope.to_vec());
        if !self.rep_partitions.contains_key(&rep) {
            let mut set = BTreeSet::new();
            let mut parts = Vec::new();
            for _ in 0..self.params.decompositions {
                // Of a few random splits keep the one with the fewest images under
                // the group: the closed structure stays as small as possible
                // (Star: {P},{x,y},{z,w} has 3 images, {P,x},{y,z},{w} has 12).
                let mut p = self.random_partition(&rep);
                let mut best = self.orbit_size(&rep, &p);
                for _ in 1..SPLIT_CANDIDATES {
                    let q = self.random_partition(&rep);
                    let size = self.orbit_size(&rep, &q);
                    let better = match self.params.split_choice {
                        SplitChoice::FewestImages => size < best,
                        SplitChoice::MostImages => size > best,
                    };
                    if better {
                        (p, best) = (q, size);
                    }
                }
                if set.insert(p.clone()) {
                    parts.push(p);
                }
            }
            self.rep_partitions.insert(rep.clone(), parts);
        }
        let rep_parts = self.rep_partitions[&rep].clone();
        let mut set = BTreeSet::new();
        for g in self.group {
            if self.apply(g, &rep) != scope {
                continue;
            }
            for p in &rep_parts {
                let mut q: Partition = p.iter().map(|s| self.apply(g, s)).collect();
                q.sort();
                set.insert(q);
            }
        }
        set.into_iter().collect()
    }

    fn region(&mut self, scope: &[u32], is_root: bool) -> Vec<NodeId> {
        if scope.len() == 1 {
            return self.leaves[scope[0] as usize].clone();
        }
        if let Some(r) = self.regions.get(scope) {
            return r.clone();
        }
        let mut products = Vec::new();
        for part in self.partitions(scope) {
            let child_sets: Vec<Vec<NodeId>> =
                part.iter().map(|sub| self.region(sub, false)).collect();
            // Cartesian product, first subset varying slowest.
            let mut combos: Vec<Vec<NodeId>> = vec![Vec::new()];
            for set in &child_sets {
                let mut next = Vec::with_capacity(combos.len() * set.len());
                for c in &combos {
                    for &n in set {
                        let mut c2 = c.clone();
                        c2.push(n);
                        next.push(c2);
                    }
                }
                combos = next;
            }
            for mut children in combos {
                children.sort_unstable();
                let id = match self.products.get(&children) {
                    Some(&id) => id,
                    None => {
                        let id = self.nodes.len() as NodeId;
                        self.products.insert(children.clone(), id);
                        self.nodes.push(Node::Product { children });
                        id
                    }
                };
                products.push(id);
            }
        }
        let n_sums = if is_root { 1 } else { self.params.sums };
        let mut sums = Vec::with_capacity(n_sums);
        for _ in 0..n_sums {
            let id = self.nodes.len() as NodeId;
            self.nodes.push(Node::Sum {
                children: products.clone(),
                weights: vec![1.0; products.len()],
            });
            sums.push(id);
        }
        self.regions.insert(scope.to_vec(), sums.clone());
        sums
    }
}

fn build(
    num_vars: usize,
    num_classes: u32,
    params: &DenseParams,
    group: &[Vec<usize>],
    seed: u64,
) -> Result<Spn, StructureError> {
    check(num_vars, num_classes, params)?;
    let mut b = Builder {
        params,
        group,
        nodes: Vec::new(),
        leaves: Vec::new(),
        regions: BTreeMap::new(),
        rep_partitions: BTreeMap::new(),
        products: HashMap::new(),
        rng: ChaCha8Rng::seed_from_u64(seed),
    };
    for var in 0..num_vars as u32 {
        let mut ids = Vec::new();
        for class in 0..num_classes {
            ids.push(b.nodes.len() as NodeId);
            b.nodes.push(Node::Leaf { var, class });
        }
        b.leaves.push(ids);
    }
    let all: Scope = (0..num_vars as u32).collect();
    let root = if num_vars == 1 {
        let leaves = b.leaves[0].clone();
        let id = b.nodes.len() as NodeId;
        b.nodes.push(Node::Sum {
            weights: vec![1.0; leaves.len()],
            children: leaves,
        });
        id
    } else {
        b.region(&all, true)[0]
    };
    let mut spn = Spn {
        classes: vec![num_classes; num_vars],
        nodes: b.nodes,
        root,
    };
    super::symmetry::init_weights(&mut spn, group, b.rng.random(), INIT_JITTER)
        .map_err(|e| StructureError::BadParam(e.to_string()))?;
    Ok(spn)
}

/// The dense random structure for `num_vars` variables with `num_classes`
/// classes each, near-uniform normalised weights (within [`INIT_JITTER`] of
/// uniform). Same seed → identical SPN.
pub fn dense_structure(
    num_vars: usize,
    num_classes: u32,
    params: &DenseParams,
    seed: u64,
) -> Result<Spn, StructureError> {
    build(num_vars, num_classes, params, &[], seed)
}

/// Like [`dense_structure`], but every region's set of splits is closed under the
/// permutations `automorphisms` (each maps variable `v` to `perm[v]`; the list
/// should be a group, e.g. `Template::automorphisms()`), and initial weights are
/// tied along the group's orbits. The SPN is exactly invariant under the group
/// (up to floating-point rounding of the evaluation order) as long as training
/// keeps the weights tied ([`super::train::train_tied`]).
///
/// Each split is the one with the most (default) or fewest images under the group
/// among [`SPLIT_CANDIDATES`] random draws ([`SplitChoice`]). The price of exact
/// symmetry is size: with 10 classes the Star gets 8,000 weights (`{P,x},{y,z},{w}`,
/// 12 images under the 24 leaf permutations) or 3,750 (`{P},{x,y},{z,w}`, 3 images)
/// instead of the paper's 1,250; Pair and Three are full tables either way.
pub fn symmetric_dense_structure(
    num_vars: usize,
    num_classes: u32,
    params: &DenseParams,
    automorphisms: &[Vec<usize>],
    seed: u64,
) -> Result<Spn, StructureError> {
    for (index, perm) in automorphisms.iter().enumerate() {
        let mut seen = vec![false; num_vars];
        let ok = perm.len() == num_vars
            && perm
                .iter()
                .all(|&v| v < num_vars && !std::mem::replace(&mut seen[v], true));
        if !ok {
            return Err(StructureError::BadPermutation {
                index,
                perm: perm.clone(),
                num_vars,
            });
        }
    }
    build(num_vars, num_classes, params, automorphisms, seed)
}

/// The uniform SPN over one or more independent variables: a product of one sum
/// per variable over its `num_classes` leaves, each weight `1/num_classes` (for
/// `num_vars == 1` just the sum). Used for the Singleton template.
pub fn uniform_spn(num_vars: usize, num_classes: u32) -> Result<Spn, StructureError> {
    if num_vars == 0 || num_classes == 0 {
        return Err(StructureError::Empty {
            num_vars,
            num_classes,
        });
    }
    let mut nodes = Vec::new();
    let mut sums = Vec::new();
    for var in 0..num_vars as u32 {
        let start = nodes.len() as NodeId;
        for class in 0..num_classes {
            nodes.push(Node::Leaf { var, class });
        }
        sums.push(nodes.len() as NodeId);
        nodes.push(Node::Sum {
            children: (start..start + num_classes).collect(),
            weights: vec![1.0 / f64::from(num_classes); num_classes as usize],
        });
    }
    let root = if num_vars == 1 {
        sums[0]
    } else {
        nodes.push(Node::Product { children: sums });
        nodes.len() as NodeId - 1
    };
    Ok(Spn {
        classes: vec![num_classes; num_vars],
        nodes,
        root,
    })
}

/// Number of sum weights of an SPN (edges out of sum nodes).
pub fn num_weights(spn: &Spn) -> usize {
    spn.nodes
        .iter()
        .map(|n| match n {
            Node::Sum { weights, .. } => weights.len(),
            _ => 0,
        })
        .sum()
}
