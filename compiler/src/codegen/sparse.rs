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
//! Every statement has constant indices (no bounds checks, no loops); the functions
//! are generic in the lane vector `V` of the module (`f32`/`f64` on targets without
//! float SIMD, one component per call; 8 or 4 SIMD lanes on the host). MPE
//! backtracking is always scalar, one component at a time.

use std::collections::BTreeSet;

use proc_macro2::{Ident, TokenStream};
use quote::{ToTokens, format_ident, quote};

use super::emit::{Lit, int, join, rt};
use super::kernels::{Plan, Segment};

/// One row of a segment in floor + sparse form.
struct Row {
    /// The smallest weight of the row.
    floor: f64,
    /// `(tuple index, weight − floor, weight)` for every weight above the floor.
    above: Vec<(usize, f64, f64)>,
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

/// The per-input indices of tuple `t` (row-major, first input slowest).
fn tuple(seg: &Segment, mut t: usize) -> Vec<usize> {
    let mut idx = vec![0; seg.dims.len()];
    for (q, &d) in seg.dims.iter().enumerate().rev() {
        idx[q] = t % d;
        t /= d;
    }
    idx
}

/// Emits the functions of one template (see the module docs) and counts their
/// multiply(-add)s.
pub struct SparseCode<'a> {
    /// Function name prefix, e.g. `t0_star`.
    pub prefix: String,
    /// The block structure.
    pub plan: &'a Plan,
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

impl SparseCode<'_> {
    fn ident(&self, suffix: &str) -> Ident {
        format_ident!("{}_{}", self.prefix, suffix)
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

    /// `a[i] * b[j] * c[k]` of tuple `t`, leaving out input position `skip`.
    fn product(&self, seg: &Segment, t: usize, skip: Option<usize>) -> Option<TokenStream> {
        let idx = tuple(seg, t);
        let f: Vec<TokenStream> = seg
            .inputs
            .iter()
            .zip(&idx)
            .enumerate()
            .filter(|&(q, _)| Some(q) != skip)
            .map(|(_, (&g, &i))| self.elem(g, i))
            .collect();
        (!f.is_empty()).then(|| join(f, &quote!(*)))
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
                quote!(let #name = V::sum(&#v);)
            });
        }
    }

    /// Forward statements computing every block `b{k}`; returns the multiply count.
    fn forward(&self, l: &Lit, max: bool, body: &mut TokenStream) -> usize {
        let mut ops = 0;
        let mut done = BTreeSet::new();
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
                }
            }
            // Row `m` gathers its terms from every segment (`seg_rows[s][m]`).
            #[allow(clippy::needless_range_loop)]
            for m in 0..block.sums.len() {
                let mi = int(m);
                let acc = quote!(#bb[#mi]);
                for (s, seg) in block.segments.iter().enumerate() {
                    let row = &seg_rows[s][m];
                    if row.floor > 0.0 {
                        let fp = format_ident!("fp{b}_{s}");
                        let floor = l.num(row.floor);
                        let f = quote!(#fp * V::splat(#floor));
                        ops += 1;
                        body.extend(if max {
                            quote!(#acc = #acc.max(#f);)
                        } else {
                            quote!(#acc = #acc + #f;)
                        });
                    }
                    for &(t, d, w) in &row.above {
                        let Some(p) = self.product(seg, t, None) else {
                            continue;
                        };
                        ops += seg.inputs.len();
                        body.extend(if max {
                            let w = l.num(w);
                            quote!(#acc = #acc.max(#p * V::splat(#w));)
                        } else {
                            let d = l.num(d);
                            quote!(#acc = (#p).mul_add(V::splat(#d), #acc);)
                        });
                    }
                }
            }
        }
        ops
    }

    fn root(&self) -> TokenStream {
        let b = format_ident!("b{}", self.plan.root.0);
        let m = int(self.plan.root.1);
        quote!(#b[#m])
    }

    /// `x: &[[V; C]; N]`.
    fn arg_x(&self) -> TokenStream {
        let c = int(self.plan.classes);
        let n = int(self.plan.n);
        quote!(x: &[[V; #c]; #n])
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
        let mut body = TokenStream::new();
        let ops = self.forward(l, max, &mut body);
        let name = self.ident(if max { "max" } else { "fwd" });
        let (x, root) = (self.arg_x(), self.root());
        (
            quote!(#[inline(never)] fn #name(#x) -> V { #body #root }),
            ops,
        )
    }

    /// `fn <prefix>_post(x, post) -> V`: the value and the local posteriors
    /// `post[i][c] = x_i[c]·∂T/∂x_i[c] / T` of every lane, by reverse-mode adjoints;
    /// and its multiply count.
    pub fn post(&self, l: &Lit) -> (TokenStream, usize) {
        let p = self.plan;
        let rt = rt();
        let mut body = TokenStream::new();
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
        body.extend(quote!(#g_root[#m_root] = V::splat(1.0);));
        for (b, block) in p.blocks.iter().enumerate().rev() {
            let gb = format_ident!("g{b}");
            for seg in &block.segments {
                let seg_rows = rows(seg);
                let floors: Vec<(usize, f64)> = seg_rows
                    .iter()
                    .enumerate()
                    .filter(|(_, r)| r.floor > 0.0)
                    .map(|(m, r)| (m, r.floor))
                    .collect();
                if !floors.is_empty() {
                    let terms: Vec<TokenStream> = floors
                        .iter()
                        .map(|&(m, f)| {
                            let (m, f) = (int(m), l.num(f));
                            quote!(#gb[#m] * V::splat(#f))
                        })
                        .collect();
                    ops += terms.len();
                    let terms = join(terms, &quote!(+));
                    body.extend(quote!(let gf = #terms;));
                    for (q, &g) in seg.inputs.iter().enumerate() {
                        let others: Vec<Ident> = seg
                            .inputs
                            .iter()
                            .enumerate()
                            .filter(|&(o, _)| o != q)
                            .map(|(_, &o)| format_ident!("sv{o}"))
                            .collect();
                        let v = if others.is_empty() {
                            quote!(gf)
                        } else {
                            ops += others.len();
                            let others = join(others, &quote!(*));
                            quote!(gf * #others)
                        };
                        let target = self.adjoint_name(g);
                        body.extend(quote!(#rt::add_all(&mut #target, #v);));
                    }
                }
                for (m, row) in seg_rows.iter().enumerate() {
                    let mi = int(m);
                    for &(t, d, _) in &row.above {
                        let idx = tuple(seg, t);
                        let d = l.num(d);
                        body.extend(quote!(let h = #gb[#mi] * V::splat(#d);));
                        ops += 1;
                        for (q, &g) in seg.inputs.iter().enumerate() {
                            let (vector, i) = (self.adjoint_name(g), int(idx[q]));
                            let target = quote!(#vector[#i]);
                            body.extend(match self.product(seg, t, Some(q)) {
                                Some(o) => {
                                    ops += seg.inputs.len() - 1;
                                    quote!(#target = (#o).mul_add(h, #target);)
                                }
                                None => quote!(#target = #target + h;),
                            });
                        }
                    }
                }
            }
        }
        ops += 2 * p.n * p.classes;
        let root = self.root();
        body.extend(quote!(#rt::post_rows(x, &gx, #root, post);));
        let (name, x) = (self.ident("post"), self.arg_x());
        (
            quote!(#[inline(never)] fn #name(#x, post: &mut [[V; #c]; #n]) -> V { #body #root }),
            ops,
        )
    }

    /// `fn <prefix>_mpe(x, lab) -> T`: the max-product value of one component and, by
    /// backtracking the best tuple of every selected sum, its arg-max labelling; and
    /// its multiply count.
    pub fn mpe(&self, l: &Lit) -> (TokenStream, usize) {
        let t = l.ty();
        let p = self.plan;
        let rt = rt();
        let mut ops = 0;
        let mut body = TokenStream::new();
        let mut done = BTreeSet::new();
        let (zero, minus_one) = (l.num(0.0), l.num(-1.0));
        for (b, block) in p.blocks.iter().enumerate() {
            let (bb, ab) = (format_ident!("b{b}"), format_ident!("a{b}"));
            let m_len = int(block.sums.len());
            body.extend(quote!(
                let mut #bb = [#zero; #m_len];
                let mut #ab = [[0u16; 4]; #m_len];
            ));
            let seg_rows: Vec<Vec<Row>> = block.segments.iter().map(rows).collect();
            for (seg, sr) in block.segments.iter().zip(&seg_rows) {
                if sr.iter().any(|r| r.floor > 0.0) {
                    for &g in &seg.inputs {
                        if done.insert(g) {
                            let (mv, iv) = (format_ident!("mv{g}"), format_ident!("iv{g}"));
                            let v = self.vec_name(g);
                            body.extend(quote!(let (#mv, #iv) = #rt::amax(&#v);));
                        }
                    }
                }
            }
            // Row `m` gathers its candidates from every segment (`seg_rows[s][m]`).
            #[allow(clippy::needless_range_loop)]
            for m in 0..block.sums.len() {
                let mi = int(m);
                body.extend(quote!(let mut r = #minus_one;));
                for (s, seg) in block.segments.iter().enumerate() {
                    let row = &seg_rows[s][m];
                    // The code of a tuple: segment, then one index per input, 0-padded.
                    let code = |idx: Vec<TokenStream>| -> TokenStream {
                        let mut c = vec![int(s).into_token_stream()];
                        c.extend(idx);
                        c.resize(4, int(0).into_token_stream());
                        let c = join(c, &quote!(,));
                        quote!([#c])
                    };
                    if row.floor > 0.0 {
                        let f = join(
                            seg.inputs.iter().map(|g| format_ident!("mv{g}")),
                            &quote!(*),
                        );
                        let ivs = seg
                            .inputs
                            .iter()
                            .map(|g| format_ident!("iv{g}").into_token_stream())
                            .collect();
                        ops += seg.inputs.len();
                        let (floor, code) = (l.num(row.floor), code(ivs));
                        body.extend(quote!(#rt::sel(&mut r, &mut #ab[#mi], #f * #floor, #code);));
                    }
                    for &(tt, _, w) in &row.above {
                        let idx = tuple(seg, tt);
                        let f = join(
                            seg.inputs.iter().zip(&idx).map(|(&g, &i)| self.elem(g, i)),
                            &quote!(*),
                        );
                        ops += seg.inputs.len();
                        let (w, code) = (
                            l.num(w),
                            code(idx.iter().map(|&i| int(i).into_token_stream()).collect()),
                        );
                        body.extend(quote!(#rt::sel(&mut r, &mut #ab[#mi], #f * #w, #code);));
                    }
                }
                body.extend(quote!(#bb[#mi] = r.max(0.0);));
            }
        }
        self.backtrack(&mut body);
        let c = int(p.classes);
        let (name, n, root) = (self.ident("mpe"), int(p.n), self.root());
        (
            quote!(#[inline(never)] fn #name(x: &[[#t; #c]; #n], lab: &mut [u16; #n]) -> #t { #body #root }),
            ops,
        )
    }

    /// MPE backtracking: from the root, mark the selected tuple of every selected
    /// sum, then write each variable's selected class into `lab`.
    fn backtrack(&self, body: &mut TokenStream) {
        let p = self.plan;
        let rt = rt();
        let c = int(p.classes);
        for v in 0..p.n {
            let sx = format_ident!("sx{v}");
            body.extend(quote!(let mut #sx = [false; #c];));
        }
        for (b, block) in p.blocks.iter().enumerate() {
            let sb = format_ident!("s{b}");
            let len = int(block.sums.len());
            body.extend(quote!(let mut #sb = [false; #len];));
        }
        let (s_root, m_root) = (format_ident!("s{}", p.root.0), int(p.root.1));
        body.extend(quote!(#s_root[#m_root] = true;));
        for (b, block) in p.blocks.iter().enumerate().rev() {
            let (sb, ab) = (format_ident!("s{b}"), format_ident!("a{b}"));
            for (s, seg) in block.segments.iter().enumerate() {
                let sels = join(
                    seg.inputs.iter().map(|&g| {
                        let sel = if g < p.n {
                            format_ident!("sx{g}")
                        } else {
                            format_ident!("s{}", g - p.n)
                        };
                        quote!(&mut #sel)
                    }),
                    &quote!(,),
                );
                let back = format_ident!("d{}_back", seg.dims.len());
                let s = int(s);
                body.extend(quote!(#rt::#back(#s, &#sb, &#ab, #sels);));
            }
        }
        for v in 0..p.n {
            let (sx, vi) = (format_ident!("sx{v}"), int(v));
            body.extend(quote!(#rt::sel_label(&#sx, &mut lab[#vi]);));
        }
    }
}
