//! Region-block recognition and dense-kernel emission for template SPNs.
//!
//! # The pattern
//!
//! Dense template SPNs (Poon–Domingos style, see `learn::structure`) are built from
//! *regions*: every sum of a region has the same child list, and that list consists of
//! one or more *segments* (the region's splits), each the full cartesian product of a
//! few child vectors — a variable's leaves (its evidence row) or another region's sums.
//! Such a group of sums is a *block*: its `M` sums compute
//! `s[m] = Σ_seg Σ_{i,j,k} W_seg[m][i][j][k]·a[i]·b[j]·c[k]`, a small tensor contraction
//! that [`plan`] recognises generically from any [`Spn`]:
//! - every reachable sum belongs to the block of all sums with exactly its child list;
//! - every child of a sum is a leaf, a sum, or a product whose children are leaves and
//!   sums of pairwise different vectors (variables or blocks);
//! - children with the same set of vectors form a segment, which must hold every tuple
//!   of the cartesian product exactly once, with at most [`MAX_ARITY`] vectors;
//! - the root is a sum; a variable's vector is its `C` leaves in class order.
//!
//! Blocks are then emitted in floor + sparse form by `sparse/`, for linear-space
//! templates (see [`super::analysis`]): the same sums of products as the per-node
//! code, in another order (rounding differs by a few ulp). Templates that do not
//! match keep the per-node code of `template.rs`.

use std::collections::BTreeMap;

use crate::spn::{Node, NodeId, Spn};

/// Largest number of child vectors of one segment.
pub const MAX_ARITY: usize = 3;
/// Largest number of weights of one segment (`M·ΠK`), to keep statics reasonable.
pub const MAX_SEGMENT: usize = 1 << 20;
/// Largest number of tuples (over all segments) of one block: MPE codes stay exact
/// integers in `f32`.
pub const MAX_BLOCK_TUPLES: usize = 1 << 24;

/// One split of a block: the cartesian product of `inputs`.
#[derive(Clone, Debug)]
pub struct Segment {
    /// Input vectors, ascending (`< n`: variable, `≥ n`: block `g − n`).
    pub inputs: Vec<usize>,
    /// Length of each input.
    pub dims: Vec<usize>,
    /// `w[m][t]` for the row-major tuple index `t` over `dims` (first input slowest).
    pub weights: Vec<Vec<f64>>,
}

impl Segment {
    /// The per-input indices of tuple `t` (row-major, first input slowest).
    pub fn tuple(&self, mut t: usize) -> Vec<usize> {
        let mut idx = vec![0; self.dims.len()];
        for (q, &d) in self.dims.iter().enumerate().rev() {
            idx[q] = t % d;
            t /= d;
        }
        idx
    }
}

/// `M` sums with a common child list.
#[derive(Clone, Debug)]
pub struct Block {
    /// Sum node ids, ascending.
    pub sums: Vec<NodeId>,
    /// The splits, in order of first appearance in the child list.
    pub segments: Vec<Segment>,
}

/// A template SPN as blocks in topological order.
#[derive(Clone, Debug)]
pub struct Plan {
    /// Number of variables.
    pub n: usize,
    /// Classes per variable.
    pub classes: usize,
    /// Blocks, inputs before users.
    pub blocks: Vec<Block>,
    /// Block and index of the root sum.
    pub root: (usize, usize),
}

/// Recognises the block structure of `spn` (see the module docs), or `None`.
pub fn plan(spn: &Spn, classes: usize) -> Option<Plan> {
    let n = spn.num_vars();
    let nodes = &spn.nodes;
    let reach = reachable(spn)?;
    // Group sums by child list; blocks ordered by their first sum (topological).
    let mut by_children: BTreeMap<&[NodeId], Vec<NodeId>> = BTreeMap::new();
    for (i, node) in nodes.iter().enumerate() {
        if let (true, Node::Sum { children, .. }) = (reach[i], node) {
            by_children
                .entry(children.as_slice())
                .or_default()
                .push(i as NodeId);
        }
    }
    let mut groups: Vec<Vec<NodeId>> = by_children.into_values().collect();
    groups.sort_by_key(|g| g[0]);
    let mut slot: BTreeMap<NodeId, (usize, usize)> = BTreeMap::new();
    for (b, g) in groups.iter().enumerate() {
        for (m, &s) in g.iter().enumerate() {
            slot.insert(s, (n + b, m));
        }
    }
    let mut blocks: Vec<Block> = Vec::with_capacity(groups.len());
    for sums in &groups {
        let block = block(spn, classes, &slot, &blocks, sums)?;
        blocks.push(block);
    }
    let root = slot.get(&spn.root)?;
    Some(Plan {
        n,
        classes,
        blocks,
        root: (root.0 - n, root.1),
    })
}

/// The reachable nodes of `spn`, or `None` when the root is not a sum or a product
/// has a product child.
fn reachable(spn: &Spn) -> Option<Vec<bool>> {
    let nodes = &spn.nodes;
    let root = spn.root as usize;
    if !matches!(nodes.get(root)?, Node::Sum { .. }) {
        return None;
    }
    let mut reach = vec![false; nodes.len()];
    reach[root] = true;
    for i in (0..nodes.len()).rev() {
        if !reach[i] {
            continue;
        }
        match &nodes[i] {
            Node::Leaf { .. } => {}
            Node::Sum { children, .. } => children.iter().for_each(|&c| reach[c as usize] = true),
            Node::Product { children } => {
                for &c in children {
                    if matches!(nodes[c as usize], Node::Product { .. }) {
                        return None;
                    }
                    reach[c as usize] = true;
                }
            }
        }
    }
    Some(reach)
}

/// The block of the sums `sums` (which share their child list), given the blocks
/// before it and every sum's `(vector, index)` slot; `None` when its children do not
/// form full cartesian segments of earlier vectors.
fn block(
    spn: &Spn,
    classes: usize,
    slot: &BTreeMap<NodeId, (usize, usize)>,
    blocks: &[Block],
    sums: &[NodeId],
) -> Option<Block> {
    let (n, nodes, b) = (spn.num_vars(), &spn.nodes, blocks.len());
    // (vector, index) of a leaf or sum.
    let elem = |id: NodeId| -> Option<(usize, usize)> {
        match &nodes[id as usize] {
            Node::Leaf { var, class } => Some((*var as usize, *class as usize)),
            Node::Sum { .. } => slot.get(&id).copied(),
            Node::Product { .. } => None,
        }
    };
    let Node::Sum { children, .. } = &nodes[sums[0] as usize] else {
        return None;
    };
    let mut segs: Vec<Segment> = Vec::new();
    let mut seen: Vec<Vec<bool>> = Vec::new();
    let mut seg_of: BTreeMap<Vec<usize>, usize> = BTreeMap::new();
    let m_len = sums.len();
    for (pos, &ch) in children.iter().enumerate() {
        let mut tuple: Vec<(usize, usize)> = match &nodes[ch as usize] {
            Node::Product { children } => {
                children.iter().map(|&c| elem(c)).collect::<Option<_>>()?
            }
            _ => vec![elem(ch)?],
        };
        tuple.sort_unstable();
        if tuple.windows(2).any(|w| w[0].0 == w[1].0) || tuple.len() > MAX_ARITY {
            return None;
        }
        let inputs: Vec<usize> = tuple.iter().map(|t| t.0).collect();
        // Inputs must be variables or earlier blocks.
        if inputs.iter().any(|&g| g >= n + b) {
            return None;
        }
        let s = match seg_of.get(&inputs) {
            Some(&s) => s,
            None => {
                let dims: Vec<usize> = inputs
                    .iter()
                    .map(|&g| {
                        if g < n {
                            classes
                        } else {
                            blocks[g - n].sums.len()
                        }
                    })
                    .collect();
                let size: usize = dims.iter().product();
                if size.saturating_mul(m_len) > MAX_SEGMENT {
                    return None;
                }
                seg_of.insert(inputs.clone(), segs.len());
                segs.push(Segment {
                    inputs,
                    dims,
                    weights: vec![vec![0.0; size]; m_len],
                });
                seen.push(vec![false; size]);
                segs.len() - 1
            }
        };
        let seg = &mut segs[s];
        let mut t = 0usize;
        for (&(_, idx), &d) in tuple.iter().zip(&seg.dims) {
            if idx >= d {
                return None;
            }
            t = t * d + idx;
        }
        if std::mem::replace(&mut seen[s][t], true) {
            return None;
        }
        for (m, &sum) in sums.iter().enumerate() {
            let Node::Sum { weights, .. } = &nodes[sum as usize] else {
                return None;
            };
            seg.weights[m][t] = weights[pos];
        }
    }
    if seen.iter().any(|s| s.iter().any(|&v| !v)) {
        return None;
    }
    // MPE records a block's best tuple as an `f32` code (segment offset plus tuple
    // index), exact below 2^24.
    if segs.iter().map(|s| s.weights[0].len()).sum::<usize>() > MAX_BLOCK_TUPLES {
        return None;
    }
    Some(Block {
        sums: sums.to_vec(),
        segments: segs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learn::{DenseParams, symmetric_dense_structure};
    use crate::template::Template;

    #[test]
    fn dense_star_is_recognised() {
        let t = Template::star();
        let spn = symmetric_dense_structure(5, 10, &DenseParams::default(), &t.automorphisms(), 3)
            .unwrap();
        let p = plan(&spn, 10).expect("plan");
        let weights: usize = p
            .blocks
            .iter()
            .flat_map(|b| &b.segments)
            .map(|s| s.weights.len() * s.weights[0].len())
            .sum();
        assert_eq!(weights, crate::learn::structure::num_weights(&spn));
        // Default split choice {P,x},{y,z},{w}: 4 pivot pairs + 6 leaf pairs + the root,
        // whose block concatenates the 12 images of the split.
        assert_eq!(p.blocks.len(), 11);
        assert_eq!(p.blocks.last().unwrap().segments.len(), 12);
        assert_eq!(p.blocks[0].sums.len(), 5);
        // The smaller closure {P},{x,y},{z,w}: 6 leaf pairs + the root with 3 images.
        let fewest = DenseParams {
            split_choice: crate::learn::SplitChoice::FewestImages,
            ..DenseParams::default()
        };
        let spn = symmetric_dense_structure(5, 10, &fewest, &t.automorphisms(), 3).unwrap();
        let p = plan(&spn, 10).expect("plan");
        assert_eq!(p.blocks.len(), 7);
        assert_eq!(p.blocks.last().unwrap().segments.len(), 3);
    }

    /// A segment of more than `MAX_ARITY` vectors is not a block, even when its tuples
    /// are complete: the root of 16 products of four two-class variables.
    #[test]
    fn segments_past_the_arity_limit_are_refused() {
        let mut b = crate::spn::SpnBuilder::new(vec![2; 4]);
        let products: Vec<NodeId> = (0..16u32)
            .map(|t| {
                let leaves = (0..4).map(|v| b.add_leaf(v, (t >> v) & 1)).collect();
                b.add_product(leaves)
            })
            .collect();
        let root = b.add_sum(products, vec![1.0 / 16.0; 16]);
        let spn = b.finish_normalised(root).unwrap();
        assert_eq!(MAX_ARITY, 3);
        assert!(plan(&spn, 2).is_none());
    }

    /// A segment is planned up to `MAX_SEGMENT` weights (sums × tuples) and refused
    /// past it: `m` sums over all 1,024 classes of one variable hold `m · 1,024`
    /// weights, exactly `MAX_SEGMENT` at `m = 1,024`.
    #[test]
    fn segments_are_planned_up_to_max_segment_weights() {
        const C: u32 = 1024;
        let plan_of = |m: usize| {
            let mut b = crate::spn::SpnBuilder::new(vec![C]);
            let leaves: Vec<NodeId> = (0..C).map(|c| b.add_leaf(0, c)).collect();
            let sums: Vec<NodeId> = (0..m)
                .map(|_| b.add_sum(leaves.clone(), vec![1.0 / f64::from(C); C as usize]))
                .collect();
            let root = b.add_sum(sums, vec![1.0 / m as f64; m]);
            plan(&b.finish_normalised(root).unwrap(), C as usize)
        };
        assert_eq!(MAX_SEGMENT, 1024 * 1024);
        assert!(plan_of(1024).is_some(), "exactly MAX_SEGMENT weights");
        assert!(plan_of(1025).is_none(), "past MAX_SEGMENT");
    }

    /// A sum whose child is a sum below a product is planned: every sum of a valid SPN
    /// is reachable, the sum below the product's sum included (the root mixes
    /// `S1 × Y1`, where `S1` is a one-child sum over `S2`, the sum over `Y0`'s leaves).
    #[test]
    fn a_sum_below_a_sum_below_a_product_is_planned() {
        let mut b = crate::spn::SpnBuilder::new(vec![2, 2]);
        let (y0a, y0b) = (b.add_leaf(0, 0), b.add_leaf(0, 1));
        let s2 = b.add_sum(vec![y0a, y0b], vec![0.3, 0.7]);
        let s1 = b.add_sum(vec![s2], vec![1.0]);
        let (y1a, y1b) = (b.add_leaf(1, 0), b.add_leaf(1, 1));
        let pa = b.add_product(vec![s1, y1a]);
        let pb = b.add_product(vec![s1, y1b]);
        let root = b.add_sum(vec![pa, pb], vec![0.4, 0.6]);
        let spn = b.finish_normalised(root).unwrap();
        let p = plan(&spn, 2).expect("a block structure");
        assert_eq!(p.blocks.len(), 3, "S2, S1 and the root");
    }
}
