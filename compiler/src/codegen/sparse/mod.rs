//! Straight-line template functions in *floor + sparse* form, for templates whose SPN
//! has the block structure of [`super::kernels::plan`].
//!
//! # The form
//!
//! Every row `m` of a block segment computes `s[m] = Σ_t w[m][t]·x_t` over the tuples
//! `t = (i, j, k)` of the segment's inputs (`x_t = a[i]·b[j]·c[k]`). Learned weights are
//! mostly the row's smoothing floor `f = min_t w[m][t]` (about 90% of them in the
//! trained templates), so each row is written as
//!
//! `s[m] = f·(Σa)(Σb)(Σc) + Σ_{t: w[m][t] > f} (w[m][t] − f)·x_t`,
//!
//! which is exact (every term is non-negative: no cancellation) and costs one product
//! of input sums plus one multiply-add per weight above the floor, instead of one per
//! tuple. The backward sweep (adjoints, for local posteriors) has the same form, and
//! the max-product value is `max(f·(max a)(max b)(max c), max_{t: w > f} w·x_t)`.
//!
//! The terms of a row that share one input's index are grouped ([`Groups`]):
//! `Σ_j d_ij·a[i]·b[j]` over a group is `a[i]·q_i` with `q_i = Σ_j d_ij·b[j]`, one
//! multiply-add per term and one per group instead of a product and a multiply-add per
//! term; the backward sweep reuses `q_i` as the adjoint of `a[i]` (−10% instructions for
//! the log-likelihood, −18% for the marginals on Cortex-M4F at 230 places). Fixed-point
//! code keeps `q_i` scaled by a power of two that its values at ones allow
//! (`SparseCode::group_shift`): its roundings are that much smaller.
//!
//! Lane operations are called through the trait (`Lanes::max`, `Lanes::mul_add`): in a
//! scalar module `V` is `f32`, whose inherent `max` is the NaN-aware `fmaxf` library
//! call on Cortex-M4F (it cost MPE 40% of its instructions) and whose inherent
//! `mul_add` (std) is a fused multiply-add, a library call on x86-64 without FMA.
//!
//! Every statement has constant indices (no bounds checks, no loops); the functions
//! are generic in the lane vector `V` of the module (`f32`/`f64` on targets without
//! float SIMD, one component per call; 8 or 4 SIMD lanes on the host). The MPE
//! function (`mpe.rs`) runs its sweep on lanes too and backtracks each lane.

use std::cell::Cell;
use std::collections::BTreeSet;

use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};

use super::emit::{Lit, int, join, rt};
use super::kernels::{Plan, Segment};

mod backward;
mod mpe;
mod scaling;

/// An above-floor term of a row: `(tuple index, weight − floor, weight)`.
type Term = (usize, f64, f64);

/// One row of a segment in floor + sparse form.
struct Row {
    /// The smallest weight of the row.
    floor: f64,
    /// `(tuple index, weight − floor, weight)` for every weight above the floor.
    above: Vec<Term>,
}

fn rows(seg: &Segment) -> Vec<Row> {
    seg.weights
        .iter()
        .map(|w| {
            let floor = w.iter().copied().fold(f64::INFINITY, f64::min).max(0.0);
            let above = w
                .iter()
                .enumerate()
                .filter(|&(_, &v)| v > floor)
                .map(|(t, &v)| (t, v - floor, v))
                .collect();
            Row { floor, above }
        })
        .collect()
}

/// The inputs of `seg` but the one at position `q`.
fn other_inputs(seg: &Segment, q: usize) -> impl Iterator<Item = usize> + '_ {
    seg.inputs
        .iter()
        .enumerate()
        .filter(move |&(p, _)| p != q)
        .map(|(_, &g)| g)
}

/// The above-floor terms of one row, grouped by the index they take at one input
/// position `pos` (`(index, [(tuple, weight − floor, weight)])`): a group's terms share that
/// factor, so the row adds `a[i]·(Σ d·(rest of the tuple))` once per group instead of
/// one product per term. `pos` is the position giving the fewest groups (the first on
/// ties): deterministic.
struct Groups {
    /// The shared input position.
    pos: usize,
    /// `(index at pos, terms)`, in order of first appearance.
    groups: Vec<(usize, Vec<Term>)>,
}

fn group_terms(seg: &Segment, row: &Row) -> Groups {
    let idx: Vec<Vec<usize>> = row.above.iter().map(|&(t, _, _)| seg.tuple(t)).collect();
    let group_at = |pos: usize| {
        let mut groups: Vec<(usize, Vec<Term>)> = Vec::new();
        for (&term, ix) in row.above.iter().zip(&idx) {
            match groups.iter_mut().find(|(i, _)| *i == ix[pos]) {
                Some((_, terms)) => terms.push(term),
                None => groups.push((ix[pos], vec![term])),
            }
        }
        groups
    };
    (0..seg.dims.len())
        .map(|pos| Groups {
            pos,
            groups: group_at(pos),
        })
        .min_by_key(|g| g.groups.len())
        .unwrap_or(Groups {
            pos: 0,
            groups: Vec::new(),
        })
}

/// Emits the functions of one template (see the module docs) and counts their
/// multiply(-add)s.
pub struct SparseCode<'a> {
    /// Function name prefix, e.g. `t0_star`.
    pub prefix: String,
    /// The block structure.
    pub plan: &'a Plan,
    /// Q0.32 fixed-point code (`fwd` and `post` only, see [`super::fixed`]) instead of
    /// the module's float lane type.
    pub fixed: bool,
    /// Fixed-point code: error units (of `2^-32`) of the shifted floor-form operations
    /// emitted since the last [`SparseCode::take_shift_units`].
    pub shift_units: Cell<usize>,
    /// Fixed-point code: values and adjoints at ones, and the root's error units of
    /// the last forward sweep, each rounding weighted by its sensitivity (see
    /// [`super::fixed`]).
    at_ones: Option<super::fixed::AtOnes>,
    forward_units: Cell<f64>,
    backward_units: Cell<f64>,
}

/// Multiply(-add) counts of one template's functions, per call (one call evaluates
/// every lane of a group).
#[derive(Clone, Copy, Debug, Default)]
pub struct Counts {
    /// `_fwd`.
    pub fwd: usize,
    /// `_post` (forward and backward sweep).
    pub post: usize,
    /// `_max`.
    pub max: usize,
    /// `_mpe`.
    pub mpe: usize,
}

impl<'a> SparseCode<'a> {
    /// The float code of `plan` under `prefix`.
    pub fn float(prefix: String, plan: &'a Plan) -> Self {
        SparseCode {
            prefix,
            plan,
            fixed: false,
            shift_units: Cell::new(0),
            at_ones: None,
            forward_units: Cell::new(0.0),
            backward_units: Cell::new(0.0),
        }
    }

    /// The fixed-point code of `plan` under `prefix` (`fwd` and `post`).
    pub fn fixed(prefix: String, plan: &'a Plan) -> Self {
        SparseCode {
            fixed: true,
            at_ones: Some(super::fixed::AtOnes::of(plan)),
            ..Self::float(prefix, plan)
        }
    }

    /// Fixed-point code: the root's error units of the last forward sweep (each
    /// rounding weighted by the adjoint at ones of what it rounds, entries included).
    pub fn forward_units(&self) -> f64 {
        self.forward_units.get()
    }

    /// Fixed-point code: the posteriors' error units of the last backward sweep (each
    /// rounding at its scale, see [`Self::adjoint_shift`]), besides its shifted
    /// floor-form operations ([`Self::take_shift_units`]).
    pub fn backward_units(&self) -> f64 {
        self.backward_units.get()
    }

    /// The error units of shifted operations emitted since the last call.
    pub fn take_shift_units(&self) -> usize {
        self.shift_units.replace(0)
    }

    fn ident(&self, suffix: &str) -> Ident {
        format_ident!("{}_{}", self.prefix, suffix)
    }

    /// A weight: a float literal, or in fixed-point code a Q0.32 constant.
    fn weight(&self, l: &Lit, w: f64) -> TokenStream {
        if self.fixed {
            super::fixed::constant(w)
        } else {
            l.num(w)
        }
    }

    /// `1` as a lane value.
    fn one(&self) -> TokenStream {
        if self.fixed {
            quote!(V::ONE)
        } else {
            quote!(V::splat(1.0))
        }
    }

    /// Length of input vector `g` (a variable's classes or a block's sums).
    fn len_of(&self, g: usize) -> usize {
        match g.checked_sub(self.plan.n) {
            None => self.plan.classes,
            Some(b) => self.plan.blocks[b].sums.len(),
        }
    }

    /// Fixed-point code: the integer bits `sv{g}` is kept with.
    fn sum_bits(&self, g: usize) -> u32 {
        super::fixed::sum_bits(self.len_of(g))
    }

    /// Fixed-point code: `expr · 2^s` when `s > 0` (also counts its error units).
    fn shifted(&self, expr: TokenStream, s: u32) -> TokenStream {
        if s == 0 {
            return expr;
        }
        self.shift_units.set(self.shift_units.get() + (2usize << s));
        let s = Literal::u32_unsuffixed(s);
        quote!((#expr).times_pow2(#s))
    }

    /// Vector `g` of a sweep: a variable's `vars[g]` or block `{blocks}{g − n}`
    /// (values `x` / `b`, adjoints `gx` / `g`).
    fn vector(&self, g: usize, vars: &str, blocks: &str) -> TokenStream {
        if g < self.plan.n {
            let (vars, g) = (format_ident!("{vars}"), int(g));
            quote!(#vars[#g])
        } else {
            let b = format_ident!("{blocks}{}", g - self.plan.n);
            quote!(#b)
        }
    }

    /// Input vector `g`: a variable's row `x[g]` or block `b{g − n}`.
    fn vec_name(&self, g: usize) -> TokenStream {
        self.vector(g, "x", "b")
    }

    /// The adjoint vector of input `g`: `gx[g]` or `g{g − n}`.
    fn adjoint_name(&self, g: usize) -> TokenStream {
        self.vector(g, "gx", "g")
    }

    fn elem(&self, g: usize, i: usize) -> TokenStream {
        let v = self.vec_name(g);
        let i = int(i);
        quote!(#v[#i])
    }

    /// `a[i] * b[j] * c[k]` of tuple `t`, leaving out the input positions in `skip`;
    /// `None` when no factor is left. Also returns the number of factors.
    fn product(&self, seg: &Segment, t: usize, skip: &[usize]) -> (Option<TokenStream>, usize) {
        let idx = seg.tuple(t);
        let f: Vec<TokenStream> = seg
            .inputs
            .iter()
            .zip(&idx)
            .enumerate()
            .filter(|(q, _)| !skip.contains(q))
            .map(|(_, (&g, &i))| self.elem(g, i))
            .collect();
        let n = f.len();
        ((n > 0).then(|| join(f, &quote!(*))), n)
    }

    /// `let sv{g} = V::sum(&vec)` (or `max_of`) once per input vector.
    fn reduce(&self, g: usize, max: bool, done: &mut BTreeSet<usize>, body: &mut TokenStream) {
        if done.insert(g) {
            let v = self.vec_name(g);
            body.extend(if max {
                let name = format_ident!("mv{g}");
                quote!(let #name = V::max_of(&#v);)
            } else {
                let name = format_ident!("sv{g}");
                if self.fixed {
                    let k = self.sum_bits(g);
                    // Σ_i (x_i >> k): each truncation below 2^(k-32), times its
                    // sensitivity (≤ 1/len): under 2^k units in all.
                    self.shift_units.set(self.shift_units.get() + (1usize << k));
                    let k = Literal::u32_unsuffixed(k);
                    quote!(let #name = V::sum_shr(&#v, #k);)
                } else {
                    quote!(let #name = V::sum(&#v);)
                }
            });
        }
    }

    /// Forward statements computing every block `b{k}`; returns the multiply count.
    fn forward(&self, l: &Lit, max: bool, body: &mut TokenStream) -> usize {
        let mut ops = 0;
        let mut done = BTreeSet::new();
        let n = self.plan.n;
        let ones = self.at_ones.as_ref().filter(|_| !max);
        let mut units = ones.map_or(0.0, |o| o.entry_units(n));
        let agg = if max { "mv" } else { "sv" };
        for (b, block) in self.plan.blocks.iter().enumerate() {
            let bb = format_ident!("b{b}");
            let len = int(block.sums.len());
            body.extend(quote!(let mut #bb = [V::ZERO; #len];));
            let seg_rows: Vec<Vec<Row>> = block.segments.iter().map(rows).collect();
            for (s, seg) in block.segments.iter().enumerate() {
                if seg_rows[s].iter().any(|r| r.floor > 0.0) {
                    for &g in &seg.inputs {
                        self.reduce(g, max, &mut done, body);
                    }
                    let f: Vec<Ident> = seg
                        .inputs
                        .iter()
                        .map(|g| format_ident!("{agg}{g}"))
                        .collect();
                    ops += f.len() - 1;
                    let fp = format_ident!("fp{b}_{s}");
                    let f = join(f, &quote!(*));
                    body.extend(quote!(let #fp = #f;));
                    if let Some(o) = ones {
                        units += self.floor_units(o, b, s, &seg_rows[s]);
                    }
                }
            }
            // Row `m` gathers its terms from every segment (`seg_rows[s][m]`).
            #[allow(clippy::needless_range_loop)]
            for m in 0..block.sums.len() {
                let mi = int(m);
                let acc = quote!(#bb[#mi]);
                let shifts_before = self.shift_units.get();
                let mut row_units = 0.0;
                for (s, seg) in block.segments.iter().enumerate() {
                    let row = &seg_rows[s][m];
                    if row.floor > 0.0 {
                        let fp = format_ident!("fp{b}_{s}");
                        let f = if self.fixed && !max {
                            // `fp` holds Σk integer bits: scale the floor to match.
                            let bits = seg.inputs.iter().map(|&g| self.sum_bits(g)).sum();
                            let (c, s) = super::fixed::scaled_constant(row.floor, bits);
                            self.shifted(quote!(#fp * V::splat(#c)), s)
                        } else {
                            let floor = l.num(row.floor);
                            quote!(#fp * V::splat(#floor))
                        };
                        ops += 1;
                        // The multiply and its constant round once each.
                        row_units += 2.0;
                        body.extend(if max {
                            quote!(#acc = Lanes::max(#acc, #f);)
                        } else {
                            quote!(#acc = #acc + #f;)
                        });
                    }
                    let (o, u) = self.grouped_sum(l, seg, (b, s, m), row, &acc, max, body);
                    (ops, row_units) = (ops + o, row_units + u);
                }
                if let Some(o) = ones {
                    // The row's value reaches the root with its adjoint.
                    row_units += (self.shift_units.get() - shifts_before) as f64;
                    units += o.row(n, b, m) * row_units;
                }
            }
        }
        self.forward_units.set(units);
        ops
    }

    /// Fixed-point code: the root's error units of segment `s` of block `b`'s vector
    /// sums (`len·2^k` each) and floor product (`2^K` per multiply), weighted by their
    /// sensitivities `Σ_m A_m·f_m·Π(other sums)` at ones.
    fn floor_units(&self, o: &super::fixed::AtOnes, b: usize, s: usize, rows: &[Row]) -> f64 {
        let n = self.plan.n;
        let seg = &self.plan.blocks[b].segments[s];
        let reach: f64 = rows
            .iter()
            .enumerate()
            .map(|(m, r)| o.row(n, b, m) * r.floor)
            .sum();
        let bits: u32 = seg.inputs.iter().map(|&g| self.sum_bits(g)).sum();
        let product = (seg.inputs.len() - 1) as f64 * 2f64.powi(bits as i32) * reach;
        let sums: f64 = seg
            .inputs
            .iter()
            .enumerate()
            .map(|(q, &g)| {
                let others: f64 = other_inputs(seg, q).map(|h| o.sum(h)).product();
                self.len_of(g) as f64 * 2f64.powi(self.sum_bits(g) as i32) * reach * others
            })
            .sum();
        product + sums
    }

    /// The name of the inner sum of group `gi` of row `m` of segment `s` of block `b`
    /// (see [`Groups`]), kept for the backward sweep.
    fn inner(&(b, s, m): &(usize, usize, usize), gi: usize) -> Ident {
        format_ident!("q{b}_{s}_{m}_{gi}")
    }

    /// Adds the row's above-floor terms to `acc` group by group (see [`Groups`]): a
    /// group of one term as `x_t·d`, a larger one as `a[i]·q` with the inner sum
    /// `q = Σ d·(rest of the tuple)` bound to [`Self::inner`]. With `max`, the
    /// max-product form instead: `acc = max(acc, a[i]·max_t w_t·(rest of t))` (exact
    /// for the non-negative values an SPN holds). In fixed-point code `q` is kept
    /// scaled by the group's [`Self::group_shift`] `2^s` and added as
    /// `(a[i]·q)·2^-s`. Returns the multiply count and, for fixed-point code, the
    /// row's error units of these terms (see [`Self::group_units`]).
    #[allow(clippy::too_many_arguments)]
    fn grouped_sum(
        &self,
        l: &Lit,
        seg: &Segment,
        at: (usize, usize, usize),
        row: &Row,
        acc: &TokenStream,
        max: bool,
        body: &mut TokenStream,
    ) -> (usize, f64) {
        let (mut ops, mut units) = (0, 0.0);
        let Groups { pos, groups } = group_terms(seg, row);
        for (gi, (i, terms)) in groups.iter().enumerate() {
            if let [(t, d, w)] = terms[..] {
                let (Some(p), _) = self.product(seg, t, &[]) else {
                    continue;
                };
                ops += seg.inputs.len();
                // Each multiply and its constant round once.
                units += 2.0 * seg.inputs.len() as f64;
                let w = self.weight(l, if max { w } else { d });
                body.extend(if max {
                    quote!(#acc = Lanes::max(#acc, #p * V::splat(#w));)
                } else {
                    quote!(#acc = Lanes::mul_add(#p, V::splat(#w), #acc);)
                });
                continue;
            }
            let shift = if max {
                0
            } else {
                self.group_shift(seg, pos, terms)
            };
            let scale = 2f64.powi(shift as i32);
            // The weight of a term: above the floor (scaled) for a sum, whole for a max.
            let weight = |d: f64, w: f64| self.weight(l, if max { w } else { d * scale });
            let q = Self::inner(&at, gi);
            for (k, &(t, d, w)) in terms.iter().enumerate() {
                let w = weight(d, w);
                // The rest of a tuple of one input is the empty product (groups of two
                // or more terms only arise with two or more inputs).
                let rest = self.product(seg, t, &[pos]).0.unwrap_or_else(|| self.one());
                ops += seg.inputs.len() - 1;
                body.extend(match (k, max) {
                    (0, _) => quote!(let #q = (#rest) * V::splat(#w);),
                    (_, false) => quote!(let #q = Lanes::mul_add(#rest, V::splat(#w), #q);),
                    (_, true) => quote!(let #q = Lanes::max(#q, (#rest) * V::splat(#w));),
                });
            }
            ops += 1;
            let a = self.elem(seg.inputs[pos], *i);
            body.extend(if max {
                quote!(#acc = Lanes::max(#acc, #a * #q);)
            } else if shift > 0 {
                let s = Literal::u32_unsuffixed(shift);
                quote!(#acc = #acc + (#a * #q).div_pow2(#s);)
            } else {
                quote!(#acc = Lanes::mul_add(#a, #q, #acc);)
            });
            units += self.group_units(seg, pos, *i, terms, shift);
        }
        (ops, units)
    }

    fn root(&self) -> TokenStream {
        let b = format_ident!("b{}", self.plan.root.0);
        let m = int(self.plan.root.1);
        quote!(#b[#m])
    }

    /// `x: &[[V; C]; N]` (`Fx` in fixed-point code).
    fn arg_x(&self) -> TokenStream {
        let (c, n, v) = (int(self.plan.classes), int(self.plan.n), self.lane_type());
        quote!(x: &[[#v; #c]; #n])
    }

    /// The lane type in signatures: the module's `V`, or `Fx` in fixed-point code.
    fn lane_type(&self) -> TokenStream {
        if self.fixed {
            let rt = rt();
            quote!(#rt::Fx)
        } else {
            quote!(V)
        }
    }

    /// Fixed-point code: the items that make `V` and `Lanes` in the body mean `Fx`
    /// and its operations.
    fn body_prelude(&self) -> TokenStream {
        if self.fixed {
            let rt = rt();
            quote!(#[allow(unused_imports)] use #rt::{Fx, Fx as V, FxLanes as Lanes};)
        } else {
            TokenStream::new()
        }
    }

    /// `fn <prefix>_fwd(x) -> V`: the value of every lane's component; and its
    /// multiply count.
    pub fn fwd(&self, l: &Lit) -> (TokenStream, usize) {
        self.value_fn(l, false)
    }

    /// `fn <prefix>_max(x) -> V`: the max-product value of every lane's component;
    /// and its multiply count.
    pub fn max(&self, l: &Lit) -> (TokenStream, usize) {
        self.value_fn(l, true)
    }

    /// `_fwd` or `_max`: the forward sweep and the root.
    fn value_fn(&self, l: &Lit, max: bool) -> (TokenStream, usize) {
        let mut body = self.body_prelude();
        let ops = self.forward(l, max, &mut body);
        let name = self.ident(if max { "max" } else { "fwd" });
        let (x, root, v) = (self.arg_x(), self.root(), self.lane_type());
        (
            quote!(#[inline(never)] fn #name(#x) -> #v { #body #root }),
            ops,
        )
    }

    /// `fn <prefix>_post(x, post) -> V`: the value and the local posteriors
    /// `post[i][c] = x_i[c]·∂T/∂x_i[c] / T` of every lane, by reverse-mode adjoints;
    /// and its multiply count.
    pub fn post(&self, l: &Lit) -> (TokenStream, usize) {
        let p = self.plan;
        let rt = rt();
        let mut body = self.body_prelude();
        let mut ops = self.forward(l, false, &mut body);
        // The forward sweep defined `sv{g}` for the inputs of segments with a floor.
        let (c, n) = (int(p.classes), int(p.n));
        body.extend(quote!(let mut gx = [[V::ZERO; #c]; #n];));
        for (b, block) in p.blocks.iter().enumerate() {
            let g = format_ident!("g{b}");
            let len = int(block.sums.len());
            body.extend(quote!(let mut #g = [V::ZERO; #len];));
        }
        let (g_root, m_root) = (format_ident!("g{}", p.root.0), int(p.root.1));
        let one = self.one();
        self.backward_units.set(0.0);
        // The root's adjoint is 1: its block's scale is 0 (`adjoint_shift`).
        debug_assert_eq!(self.adjoint_shift(p.n + p.root.0), 0);
        body.extend(quote!(#g_root[#m_root] = #one;));
        for (b, block) in p.blocks.iter().enumerate().rev() {
            for (s, seg) in block.segments.iter().enumerate() {
                let seg_rows = rows(seg);
                let floors: Vec<(usize, f64)> = seg_rows
                    .iter()
                    .enumerate()
                    .filter(|(_, r)| r.floor > 0.0)
                    .map(|(m, r)| (m, r.floor))
                    .collect();
                ops += self.floor_adjoints(l, b, seg, &floors, &mut body);
                for (m, row) in seg_rows.iter().enumerate() {
                    ops += self.grouped_adjoints(l, seg, (b, s, m), row, &mut body);
                }
            }
        }
        ops += 2 * p.n * p.classes;
        let root = self.root();
        body.extend(if self.fixed {
            // The wrapper (`fx_post`) divides by the value after checking it; each
            // place's adjoints are first brought back from their scale (one more
            // rounding of each).
            let rows = (0..p.n).map(|v| {
                let (s, vi) = (self.adjoint_shift(v), int(v));
                if s == 0 {
                    quote!(post[#vi] = gx[#vi];)
                } else {
                    let s = Literal::u32_unsuffixed(s as u32);
                    quote!(post[#vi] = gx[#vi].map(|a| a.div_pow2(#s));)
                }
            });
            if (0..p.n).any(|v| self.adjoint_shift(v) > 0) {
                self.add_backward_units(1.0, 0);
            }
            quote!(#(#rows)*)
        } else {
            quote!(#rt::post_rows(x, &gx, #root, post);)
        });
        let (name, x, v) = (self.ident("post"), self.arg_x(), self.lane_type());
        (
            quote!(#[inline(never)] fn #name(#x, post: &mut [[#v; #c]; #n]) -> #v { #body #root }),
            ops,
        )
    }
}
