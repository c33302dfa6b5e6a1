//! Template symmetries: data augmentation with automorphisms and weight tying.
//!
//! Two ways to make a template SPN respect the symmetries of its template (for
//! the Star: any permutation of the four leaves A–D; for Three: A↔B; for Pair:
//! P↔A):
//!
//! 1. [`augment_with_automorphisms`]: train on every sample under every
//!    automorphism. The data are then symmetric, so full tables (Pair, Three)
//!    become exactly symmetric, but a structure that is not itself symmetric
//!    (the Star's `{2,2,1}` split) is only approximately so after hard EM.
//! 2. Tying: build a structure closed under the group
//!    ([`super::structure::symmetric_dense_structure`]), compute the orbits of its
//!    sum edges under the group ([`edge_orbits`]) and keep the weights of each
//!    orbit equal during training (the M-step averages counts over the orbit,
//!    which is the exact constrained maximiser, so EM stays monotone). The SPN is
//!    then exactly invariant.

use std::collections::HashMap;

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;

#[cfg(feature = "host")]
use super::settings::TrainError;
use crate::map::ClassId;
use crate::spn::{Node, NodeId, Spn};

/// Why the symmetry of a structure could not be established.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SymmetryError {
    /// The structure has no image of `node` under the permutation.
    #[error(
        "the SPN structure is not invariant under automorphism #{perm} {permutation:?}: node {node} has no image"
    )]
    NotInvariant {
        /// Index of the permutation.
        perm: usize,
        /// The permutation.
        permutation: Vec<usize>,
        /// Node without an image.
        node: NodeId,
    },
    /// A permutation has the wrong length or is not a bijection.
    #[error(
        "automorphism #{perm} {permutation:?} is not a permutation of the SPN's {num_vars} variables"
    )]
    BadPermutation {
        /// Index of the permutation.
        perm: usize,
        /// The permutation.
        permutation: Vec<usize>,
        /// Number of SPN variables.
        num_vars: usize,
    },
    /// A child id does not precede its parent.
    #[error(
        "node {node} has child {child}, which does not precede it (nodes must be in topological order)"
    )]
    NotTopological {
        /// The parent.
        node: NodeId,
        /// The bad child.
        child: NodeId,
    },
}

#[cfg(feature = "host")]
/// Every sample under every permutation: for a sample `s` and permutation `π`,
/// the sample `s'[i] = s[π[i]]` (the component's nodes re-listed in the order
/// `π`). Output order: for each sample, its images in the order of
/// `automorphisms`. Include the identity to keep the originals (a template's
/// automorphism group does). Fails when a sample's length differs from a
/// permutation's or a permutation entry is out of range.
pub fn augment_with_automorphisms(
    samples: &[Vec<ClassId>],
    automorphisms: &[Vec<usize>],
) -> Result<Vec<Vec<ClassId>>, TrainError> {
    let mut out = Vec::with_capacity(samples.len() * automorphisms.len());
    for (index, s) in samples.iter().enumerate() {
        for p in automorphisms {
            if p.len() != s.len() || p.iter().any(|&i| i >= s.len()) {
                return Err(TrainError::SampleLength {
                    index,
                    len: s.len(),
                    num_vars: p.len(),
                });
            }
            out.push(p.iter().map(|&i| s[i]).collect());
        }
    }
    Ok(out)
}

/// Offsets of each node's weights in the flat list of sum edges (node order,
/// then child order); non-sum nodes get the offset of the next sum. The last
/// entry is the total.
pub(crate) fn sum_edge_offsets(spn: &Spn) -> Vec<usize> {
    let mut out = Vec::with_capacity(spn.nodes.len() + 1);
    let mut acc = 0;
    for n in &spn.nodes {
        out.push(acc);
        if let Node::Sum { children, .. } = n {
            acc += children.len();
        }
    }
    out.push(acc);
    out
}

/// The orbits of the sum edges of an SPN under a group of variable permutations.
#[derive(Clone, Debug, PartialEq)]
pub struct EdgeOrbits {
    /// For each sum edge (flat index: node order, then child order) its orbit.
    pub orbit_of: Vec<u32>,
    /// The edges of each orbit, ascending; orbits ordered by smallest edge.
    pub orbits: Vec<Vec<u32>>,
}

impl EdgeOrbits {
    /// Every edge in its own orbit (no tying).
    pub fn trivial(num_edges: usize) -> Self {
        EdgeOrbits {
            orbit_of: (0..num_edges as u32).collect(),
            orbits: (0..num_edges as u32).map(|e| vec![e]).collect(),
        }
    }

    /// True when no two edges are tied.
    pub fn is_trivial(&self) -> bool {
        self.orbits.len() == self.orbit_of.len()
    }
}

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let p = parent[parent[x as usize] as usize];
        parent[x as usize] = p;
        x = p;
    }
    x
}

/// Orbits of the sum edges under `automorphisms` (each maps variable `v` to
/// `perm[v]`). The action on nodes is read off the structure: a leaf
/// `(v, c)` goes to `(perm[v], c)`, a product to the product over the images of
/// its children, and the `k`-th sum (in node order) with a given set of children
/// to the `k`-th sum with the image set. Fails when some node has no image, i.e.
/// the structure is not invariant.
pub fn edge_orbits(spn: &Spn, automorphisms: &[Vec<usize>]) -> Result<EdgeOrbits, SymmetryError> {
    let offsets = sum_edge_offsets(spn);
    let num_edges = offsets[spn.nodes.len()];
    if automorphisms.is_empty() {
        return Ok(EdgeOrbits::trivial(num_edges));
    }
    let nv = spn.num_vars();
    let mut leaf_of: HashMap<(u32, u32), NodeId> = HashMap::new();
    let mut product_of: HashMap<Vec<NodeId>, NodeId> = HashMap::new();
    let mut sums_of: HashMap<Vec<NodeId>, Vec<NodeId>> = HashMap::new();
    let mut rank = vec![0usize; spn.nodes.len()];
    for (id, n) in spn.nodes.iter().enumerate() {
        let id = id as NodeId;
        match n {
            Node::Leaf { var, class } => {
                leaf_of.insert((*var, *class), id);
            }
            Node::Product { children } | Node::Sum { children, .. } => {
                if let Some(&c) = children.iter().find(|&&c| c >= id) {
                    return Err(SymmetryError::NotTopological { node: id, child: c });
                }
                let mut key = children.clone();
                key.sort_unstable();
                if matches!(n, Node::Product { .. }) {
                    product_of.insert(key, id);
                } else {
                    let list = sums_of.entry(key).or_default();
                    rank[id as usize] = list.len();
                    list.push(id);
                }
            }
        }
    }
    let mut parent: Vec<u32> = (0..num_edges as u32).collect();
    for (pi, perm) in automorphisms.iter().enumerate() {
        let mut seen = vec![false; nv];
        let ok = perm.len() == nv
            && perm
                .iter()
                .all(|&v| v < nv && !std::mem::replace(&mut seen[v], true));
        if !ok {
            return Err(SymmetryError::BadPermutation {
                perm: pi,
                permutation: perm.clone(),
                num_vars: nv,
            });
        }
        let not_inv = |node: usize| SymmetryError::NotInvariant {
            perm: pi,
            permutation: perm.clone(),
            node: node as NodeId,
        };
        let mut image = vec![0 as NodeId; spn.nodes.len()];
        for (id, n) in spn.nodes.iter().enumerate() {
            image[id] = match n {
                Node::Leaf { var, class } => {
                    let v = perm.get(*var as usize).ok_or_else(|| not_inv(id))?;
                    *leaf_of
                        .get(&(*v as u32, *class))
                        .ok_or_else(|| not_inv(id))?
                }
                Node::Product { children } => {
                    let mut key: Vec<NodeId> =
                        children.iter().map(|&c| image[c as usize]).collect();
                    key.sort_unstable();
                    *product_of.get(&key).ok_or_else(|| not_inv(id))?
                }
                Node::Sum { children, .. } => {
                    let mut key: Vec<NodeId> =
                        children.iter().map(|&c| image[c as usize]).collect();
                    key.sort_unstable();
                    *sums_of
                        .get(&key)
                        .and_then(|l| l.get(rank[id]))
                        .ok_or_else(|| not_inv(id))?
                }
            };
        }
        for (id, n) in spn.nodes.iter().enumerate() {
            if let Node::Sum { children, .. } = n {
                let img = image[id] as usize;
                let Node::Sum {
                    children: img_children,
                    ..
                } = &spn.nodes[img]
                else {
                    return Err(not_inv(id));
                };
                let pos: HashMap<NodeId, usize> = img_children
                    .iter()
                    .enumerate()
                    .map(|(j, &c)| (c, j))
                    .collect();
                for (j, &c) in children.iter().enumerate() {
                    let j2 = *pos.get(&image[c as usize]).ok_or_else(|| not_inv(id))?;
                    let a = find(&mut parent, (offsets[id] + j) as u32);
                    let b = find(&mut parent, (offsets[img] + j2) as u32);
                    if a != b {
                        let (lo, hi) = (a.min(b), a.max(b));
                        parent[hi as usize] = lo;
                    }
                }
            }
        }
    }
    let mut orbit_of = vec![0u32; num_edges];
    let mut orbits: Vec<Vec<u32>> = Vec::new();
    let mut orbit_index: HashMap<u32, u32> = HashMap::new();
    for e in 0..num_edges as u32 {
        let r = find(&mut parent, e);
        let o = *orbit_index.entry(r).or_insert_with(|| {
            orbits.push(Vec::new());
            (orbits.len() - 1) as u32
        });
        orbits[o as usize].push(e);
        orbit_of[e as usize] = o;
    }
    Ok(EdgeOrbits { orbit_of, orbits })
}

/// Sum of `values` in ascending order: the result does not depend on the order
/// the values are given in, so tied sums normalise bit-identically.
pub(crate) fn order_free_sum(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values.iter().sum()
}

/// Sets every sum's weights from per-edge raw values (`raw[e] > 0`), normalised
/// per sum with [`order_free_sum`].
pub(crate) fn set_normalised(spn: &mut Spn, raw: &[f64]) {
    let mut off = 0;
    let mut scratch = Vec::new();
    for n in &mut spn.nodes {
        if let Node::Sum { weights, .. } = n {
            let k = weights.len();
            scratch.clear();
            scratch.extend_from_slice(&raw[off..off + k]);
            let z = order_free_sum(&mut scratch);
            for (w, r) in weights.iter_mut().zip(&raw[off..off + k]) {
                *w = r / z;
            }
            off += k;
        }
    }
}

/// Near-uniform initial weights, tied along the orbits of `automorphisms`: each
/// orbit draws `u ~ U[0,1)` (seeded, in orbit order), its edges get
/// `1 + jitter·u`, then every sum is normalised.
pub(crate) fn init_weights(
    spn: &mut Spn,
    automorphisms: &[Vec<usize>],
    seed: u64,
    jitter: f64,
) -> Result<(), SymmetryError> {
    let orbits = edge_orbits(spn, automorphisms)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let per_orbit: Vec<f64> = (0..orbits.orbits.len())
        .map(|_| 1.0 + jitter * rng.random::<f64>())
        .collect();
    let raw: Vec<f64> = orbits
        .orbit_of
        .iter()
        .map(|&o| per_orbit[o as usize])
        .collect();
    set_normalised(spn, &raw);
    Ok(())
}

#[cfg(all(test, feature = "host"))]
mod tests {
    use super::*;

    /// Each orbit's initial weight is `1 + jitter·u` with `u` the orbit's draw from
    /// the seeded generator, then each sum is normalised: with the identity alone,
    /// every edge is its own orbit.
    #[test]
    fn initial_weights_are_one_plus_jitter_times_the_draw() {
        let mut spn = Spn {
            classes: vec![3],
            nodes: vec![
                Node::Leaf { var: 0, class: 0 },
                Node::Leaf { var: 0, class: 1 },
                Node::Leaf { var: 0, class: 2 },
                Node::Sum {
                    children: vec![0, 1, 2],
                    weights: vec![0.0; 3],
                },
            ],
            root: 3,
        };
        init_weights(&mut spn, &[vec![0]], 9, 0.5).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let raw: Vec<f64> = (0..3).map(|_| 1.0 + 0.5 * rng.random::<f64>()).collect();
        let z: f64 = raw.iter().sum();
        let Node::Sum { weights, .. } = &spn.nodes[3] else {
            panic!("the root is a sum")
        };
        for (w, r) in weights.iter().zip(&raw) {
            assert!((w - r / z).abs() < 1e-15, "{weights:?} vs {raw:?}");
        }
    }
}
