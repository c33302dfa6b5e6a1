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
//! Blocks are then computed by the const-generic kernels of
//! `graphspn_runtime::__private` with the weights in `static` arrays (row-major,
//! `w[m][i][j][k]`): the lane kernels `v1_*`, `v2_*`, `v3_*` evaluate a group of
//! components at once, one per SIMD lane (values, adjoints, max-product values and
//! their arguments), and `decode_arg` / `d*_back` backtrack each lane's MPE labelling
//! from the recorded arguments. Generated
//! template functions are a few calls, whatever the number of SPN edges. Templates
//! that do not match keep the per-node code of `template.rs`.
//!
//! Kernels are used only for linear-space templates (see [`super::analysis`]): they
//! compute exactly the same sums of products as the per-node code, in another order
//! (rounding differs by a few ulp), and zero weights just contribute zero terms.

use std::collections::BTreeMap;
use std::fmt::Write;

use crate::spn::{Node, NodeId, Spn};

use super::emit::{Lit, P};

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
    // (vector, index) of a leaf or sum.
    let elem = |id: NodeId| -> Option<(usize, usize)> {
        match &nodes[id as usize] {
            Node::Leaf { var, class } => Some((*var as usize, *class as usize)),
            Node::Sum { .. } => slot.get(&id).copied(),
            Node::Product { .. } => None,
        }
    };
    let mut blocks: Vec<Block> = Vec::with_capacity(groups.len());
    for (b, sums) in groups.iter().enumerate() {
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
        blocks.push(Block {
            sums: sums.clone(),
            segments: segs,
        });
    }
    let root = slot.get(&spn.root)?;
    Some(Plan {
        n,
        classes,
        blocks,
        root: (root.0 - n, root.1),
    })
}

/// Components per lane group for a scalar type (`f32`: 8, `f64`: 4), the width of the
/// runtime's lane vectors (`graphspn_runtime::__private::{LANES_F32, LANES_F64}`).
pub fn lanes(l: &Lit) -> usize {
    if l.t == "f32" { 8 } else { 4 }
}

/// The runtime's lane vector type for a scalar type.
pub fn lane_type(l: &Lit) -> String {
    if l.t == "f32" {
        format!("{P}Lanes32")
    } else {
        format!("{P}Lanes64")
    }
}

/// Emits the kernel-based template functions for a recognised plan: lane-group
/// functions for values, local posteriors and max-product values (`_fwdv`, `_postv`,
/// `_mpvv`, one component per SIMD lane) and a one-component MPE function (`_mpe`).
pub struct KernelCode<'a> {
    /// Function name prefix, e.g. `t0_star`.
    pub prefix: String,
    /// The block structure.
    pub plan: &'a Plan,
}

impl KernelCode<'_> {
    fn w(&self, b: usize, s: usize) -> String {
        format!("W_{}_{b}_{s}", self.prefix.to_uppercase())
    }

    fn vec_ref(&self, g: usize, prefix: &str) -> String {
        if g < self.plan.n {
            format!("&x[{g}]")
        } else {
            format!("&{prefix}{}", g - self.plan.n)
        }
    }

    fn sig_xv(&self, l: &Lit) -> String {
        format!(
            "x: &[[{}; {}]; {}]",
            lane_type(l),
            self.plan.classes,
            self.plan.n
        )
    }

    /// `static` weight tables, one per segment, `w[m][i][j][k]` (row-major over the
    /// segment's inputs, last input innermost) as the runtime kernels expect.
    pub fn statics(&self, l: &Lit, out: &mut String) {
        let num = |v: f64| -> String {
            if l.t == "f32" {
                format!("{:?}", v as f32)
            } else {
                format!("{v:?}")
            }
        };
        for (b, block) in self.plan.blocks.iter().enumerate() {
            for (s, seg) in block.segments.iter().enumerate() {
                // Type: [[[T; K]; B]; A]; M], innermost dimension last.
                let mut ty = l.t.to_string();
                for d in seg.dims.iter().rev() {
                    ty = format!("[{ty}; {d}]");
                }
                ty = format!("[{ty}; {}]", block.sums.len());
                let rows: Vec<String> = seg
                    .weights
                    .iter()
                    .map(|wm| nest(&wm.iter().map(|&v| num(v)).collect::<Vec<_>>(), &seg.dims))
                    .collect();
                let _ = writeln!(out, "static {}: {ty} = [{}];", self.w(b, s), rows.join(","));
            }
        }
    }

    /// Forward statements over lanes computing every block output `b{k}`; `keep`
    /// stores the kernels' intermediates `u{k}_{s}`, `v{k}_{s}` for the backward sweep.
    fn forward(&self, l: &Lit, keep: bool, body: &mut String) {
        let v = lane_type(l);
        for (b, block) in self.plan.blocks.iter().enumerate() {
            let m_len = block.sums.len();
            let _ = writeln!(body, "let mut b{b} = [{v}::ZERO; {m_len}];");
            for (s, seg) in block.segments.iter().enumerate() {
                let ins: Vec<String> = seg.inputs.iter().map(|&g| self.vec_ref(g, "b")).collect();
                let w = self.w(b, s);
                let d = &seg.dims;
                let _ = match (d.len(), keep) {
                    (1, _) => writeln!(body, "{P}v1_fwd(&{w}, {}, &mut b{b});", ins[0]),
                    (2, false) => {
                        writeln!(body, "{P}v2_fwd(&{w}, {}, {}, &mut b{b});", ins[0], ins[1])
                    }
                    (2, true) => writeln!(
                        body,
                        "let mut u{b}_{s} = [[{v}::ZERO; {}]; {m_len}]; {P}v2_fwdk(&{w}, {}, {}, &mut u{b}_{s}, &mut b{b});",
                        d[0], ins[0], ins[1]
                    ),
                    (_, false) => writeln!(
                        body,
                        "{P}v3_fwd(&{w}, {}, {}, {}, &mut b{b});",
                        ins[0], ins[1], ins[2]
                    ),
                    (_, true) => writeln!(
                        body,
                        "let mut u{b}_{s} = [[[{v}::ZERO; {bb}]; {a}]; {m_len}]; let mut v{b}_{s} = [[{v}::ZERO; {a}]; {m_len}]; {P}v3_fwdk(&{w}, ({}, {}, {}), &mut u{b}_{s}, &mut v{b}_{s}, &mut b{b});",
                        ins[0],
                        ins[1],
                        ins[2],
                        a = d[0],
                        bb = d[1]
                    ),
                };
            }
        }
    }

    fn root(&self) -> String {
        format!("b{}[{}]", self.plan.root.0, self.plan.root.1)
    }

    /// `fn <prefix>_fwdv(x) -> [value; L]`: the values of a lane group (linear space).
    pub fn fwdv(&self, l: &Lit, out: &mut String) {
        let mut body = String::new();
        self.forward(l, false, &mut body);
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_fwdv({}) -> [{}; {}] {{ {body} {P}values_{}({}) }}",
            self.prefix,
            self.sig_xv(l),
            l.t,
            lanes(l),
            l.t,
            self.root()
        );
    }

    /// `fn <prefix>_postv(x, post) -> [value; L]`: also the local posteriors
    /// `post[i][c] = x_i[c]·∂T/∂x_i[c] / T` of every lane by reverse-mode adjoints
    /// through the blocks.
    pub fn postv(&self, l: &Lit, out: &mut String) {
        let t = l.t;
        let v = lane_type(l);
        let p = self.plan;
        let mut body = String::new();
        self.forward(l, true, &mut body);
        for var in 0..p.n {
            let _ = writeln!(body, "let mut gx{var} = [{v}::ZERO; {}];", p.classes);
        }
        for (b, block) in p.blocks.iter().enumerate() {
            let _ = writeln!(body, "let mut g{b} = [{v}::ZERO; {}];", block.sums.len());
        }
        let _ = writeln!(body, "g{}[{}] = {v}::splat(1.0);", p.root.0, p.root.1);
        let gref = |g: usize| -> String {
            if g < p.n {
                format!("&mut gx{g}")
            } else {
                format!("&mut g{}", g - p.n)
            }
        };
        for (b, block) in p.blocks.iter().enumerate().rev() {
            for (s, seg) in block.segments.iter().enumerate() {
                let w = self.w(b, s);
                let ins: Vec<String> = seg.inputs.iter().map(|&g| self.vec_ref(g, "b")).collect();
                let gs: Vec<String> = seg.inputs.iter().map(|&g| gref(g)).collect();
                let _ = match seg.dims.len() {
                    1 => writeln!(body, "{P}v1_bwd(&{w}, &g{b}, {});", gs[0]),
                    2 => writeln!(
                        body,
                        "{P}v2_bwd(&{w}, {}, &u{b}_{s}, &g{b}, {}, {});",
                        ins[0], gs[0], gs[1]
                    ),
                    _ => writeln!(
                        body,
                        "{P}v3_bwd(&{w}, ({}, {}), (&u{b}_{s}, &v{b}_{s}), &g{b}, ({}, {}, {}));",
                        ins[0], ins[1], gs[0], gs[1], gs[2]
                    ),
                };
            }
        }
        let _ = writeln!(body, "let inv = {P}inv_lanes_{t}({});", self.root());
        for var in 0..p.n {
            let _ = writeln!(
                body,
                "{P}post_lanes(&x[{var}], &gx{var}, inv, &mut post[{var}]);"
            );
        }
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_postv({}, post: &mut [[{v}; {}]; {}]) -> [{t}; {}] {{ {body} {P}values_{t}({}) }}",
            self.prefix,
            self.sig_xv(l),
            p.classes,
            p.n,
            lanes(l),
            self.root()
        );
    }

    /// `fn <prefix>_mpvv(x) -> [value; L]`: the max-product values of a lane group.
    pub fn mpvv(&self, l: &Lit, out: &mut String) {
        let t = l.t;
        let v = lane_type(l);
        let mut body = String::new();
        for (b, block) in self.plan.blocks.iter().enumerate() {
            let _ = writeln!(body, "let mut b{b} = [{v}::ZERO; {}];", block.sums.len());
            for (s, seg) in block.segments.iter().enumerate() {
                let ins: Vec<String> = seg.inputs.iter().map(|&g| self.vec_ref(g, "b")).collect();
                let _ = writeln!(
                    body,
                    "{P}v{}_max(&{}, {}, &mut b{b});",
                    seg.dims.len(),
                    self.w(b, s),
                    ins.join(", ")
                );
            }
        }
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_mpvv({}) -> [{t}; {}] {{ {body} {P}values_{t}({}) }}",
            self.prefix,
            self.sig_xv(l),
            lanes(l),
            self.root()
        );
    }

    /// `fn <prefix>_mpev(x, lab) -> [value; L]`: max-product values of a lane group
    /// and, by backtracking in every lane (`<prefix>_bt`), the argmax labelling of each
    /// component (ties → lowest split, then lowest indices).
    pub fn mpev(&self, l: &Lit, out: &mut String) {
        let t = l.t;
        let v = lane_type(l);
        let p = self.plan;
        let lanes = lanes(l);
        let mut body = String::new();
        for (b, block) in p.blocks.iter().enumerate() {
            let m_len = block.sums.len();
            let _ = writeln!(
                body,
                "let mut b{b} = [{v}::splat(-1.0); {m_len}]; let mut a{b} = [{v}::ZERO; {m_len}];"
            );
            let mut offset = 0usize;
            for (s, seg) in block.segments.iter().enumerate() {
                let ins: Vec<String> = seg.inputs.iter().map(|&g| self.vec_ref(g, "b")).collect();
                let args = if ins.len() == 1 {
                    ins[0].clone()
                } else {
                    format!("({})", ins.join(", "))
                };
                let _ = writeln!(
                    body,
                    "{P}v{}_maxa({offset}.0, &{}, {args}, &mut b{b}, &mut a{b});",
                    seg.dims.len(),
                    self.w(b, s),
                );
                offset += seg.weights[0].len();
            }
        }
        let args: Vec<String> = (0..p.blocks.len()).map(|b| format!("&a{b}")).collect();
        for lane in 0..lanes {
            let _ = writeln!(
                body,
                "{}_bt({lane}, {}, &mut lab[{lane}]);",
                self.prefix,
                args.join(", ")
            );
        }
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_mpev({}, lab: &mut [[u16; {}]; {lanes}]) -> [{t}; {lanes}] {{ {body} {P}values_{t}({}) }}",
            self.prefix,
            self.sig_xv(l),
            p.n,
            self.root()
        );
        self.bt(l, out);
    }

    /// `fn <prefix>_bt(lane, a0, a1, ..., lab)`: decodes the best tuples recorded in
    /// `lane` and backtracks from the root to the selected class of every variable.
    fn bt(&self, l: &Lit, out: &mut String) {
        let v = lane_type(l);
        let p = self.plan;
        let mut params = vec!["l: usize".to_string()];
        let mut body = String::new();
        for (b, block) in p.blocks.iter().enumerate() {
            let m_len = block.sums.len();
            params.push(format!("a{b}: &[{v}; {m_len}]"));
            let mut offset = 0usize;
            let segs: Vec<String> = block
                .segments
                .iter()
                .map(|seg| {
                    let d = |k: usize| seg.dims.get(k).copied().unwrap_or(1);
                    let text = format!("[{offset}, {}, {}, {}]", d(0), d(1), d(2));
                    offset += seg.weights[0].len();
                    text
                })
                .collect();
            let _ = writeln!(
                body,
                "let a{b} = {P}decode_arg(a{b}, l, [{}]);",
                segs.join(", ")
            );
        }
        params.push(format!("lab: &mut [u16; {}]", p.n));
        for var in 0..p.n {
            let _ = writeln!(body, "let mut sx{var} = [false; {}];", p.classes);
        }
        for (b, block) in p.blocks.iter().enumerate() {
            let _ = writeln!(body, "let mut s{b} = [false; {}];", block.sums.len());
        }
        let _ = writeln!(body, "s{}[{}] = true;", p.root.0, p.root.1);
        for (b, block) in p.blocks.iter().enumerate().rev() {
            for (s, seg) in block.segments.iter().enumerate() {
                let ss: Vec<String> = seg
                    .inputs
                    .iter()
                    .map(|&g| {
                        if g < p.n {
                            format!("&mut sx{g}")
                        } else {
                            format!("&mut s{}", g - p.n)
                        }
                    })
                    .collect();
                let _ = writeln!(
                    body,
                    "{P}d{}_back({s}, &s{b}, &a{b}, {});",
                    seg.dims.len(),
                    ss.join(", ")
                );
            }
        }
        for var in 0..p.n {
            let _ = writeln!(body, "{P}sel_label(&sx{var}, &mut lab[{var}]);");
        }
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_bt({}) {{ {body} }}",
            self.prefix,
            params.join(", ")
        );
    }
}

/// `flat` (row-major over `dims`) as nested array literals.
fn nest(flat: &[String], dims: &[usize]) -> String {
    match dims.split_first() {
        None => flat.first().cloned().unwrap_or_default(),
        Some((_, [])) => format!("[{}]", flat.join(",")),
        Some((_, rest)) => {
            let inner: usize = rest.iter().product();
            let parts: Vec<String> = flat.chunks(inner).map(|c| nest(c, rest)).collect();
            format!("[{}]", parts.join(","))
        }
    }
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
}
