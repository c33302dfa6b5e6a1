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
use std::fmt::Write;

use super::emit::{Lit, P};
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
    fn vec_name(&self, g: usize) -> String {
        if g < self.plan.n {
            format!("x[{g}]")
        } else {
            format!("b{}", g - self.plan.n)
        }
    }

    fn elem(&self, g: usize, i: usize) -> String {
        format!("{}[{i}]", self.vec_name(g))
    }

    /// `a[i] * b[j] * c[k]` of tuple `t`, leaving out input position `skip`.
    fn product(&self, seg: &Segment, t: usize, skip: Option<usize>) -> Option<String> {
        let idx = tuple(seg, t);
        let f: Vec<String> = seg
            .inputs
            .iter()
            .zip(&idx)
            .enumerate()
            .filter(|&(q, _)| Some(q) != skip)
            .map(|(_, (&g, &i))| self.elem(g, i))
            .collect();
        (!f.is_empty()).then(|| f.join(" * "))
    }

    /// `let sv{g} = V::sum(&vec)` (or `max_of`) once per input vector.
    fn reduce(&self, g: usize, max: bool, done: &mut BTreeSet<usize>, body: &mut String) {
        if done.insert(g) {
            let (name, f) = if max { ("mv", "max_of") } else { ("sv", "sum") };
            let _ = writeln!(body, "let {name}{g} = V::{f}(&{});", self.vec_name(g));
        }
    }

    /// Forward statements computing every block `b{k}`; returns the multiply count.
    fn forward(&self, l: &Lit, max: bool, body: &mut String) -> usize {
        let mut ops = 0;
        let mut done = BTreeSet::new();
        let agg = if max { "mv" } else { "sv" };
        for (b, block) in self.plan.blocks.iter().enumerate() {
            let _ = writeln!(body, "let mut b{b} = [V::ZERO; {}];", block.sums.len());
            let seg_rows: Vec<Vec<Row>> = block.segments.iter().map(rows).collect();
            for (s, seg) in block.segments.iter().enumerate() {
                if seg_rows[s].iter().any(|r| r.floor > 0.0) {
                    for &g in &seg.inputs {
                        self.reduce(g, max, &mut done, body);
                    }
                    let f: Vec<String> = seg.inputs.iter().map(|g| format!("{agg}{g}")).collect();
                    ops += f.len() - 1;
                    let _ = writeln!(body, "let fp{b}_{s} = {};", f.join(" * "));
                }
            }
            // Row `m` gathers its terms from every segment (`seg_rows[s][m]`).
            #[allow(clippy::needless_range_loop)]
            for m in 0..block.sums.len() {
                let acc = format!("b{b}[{m}]");
                for (s, seg) in block.segments.iter().enumerate() {
                    let row = &seg_rows[s][m];
                    if row.floor > 0.0 {
                        let f = format!("fp{b}_{s} * V::splat({})", l.num(row.floor));
                        ops += 1;
                        let _ = if max {
                            writeln!(body, "{acc} = {acc}.max({f});")
                        } else {
                            writeln!(body, "{acc} = {acc} + {f};")
                        };
                    }
                    for &(t, d, w) in &row.above {
                        let Some(p) = self.product(seg, t, None) else {
                            continue;
                        };
                        ops += seg.inputs.len();
                        let _ = if max {
                            writeln!(body, "{acc} = {acc}.max({p} * V::splat({}));", l.num(w))
                        } else {
                            writeln!(
                                body,
                                "{acc} = ({p}).mul_add(V::splat({}), {acc});",
                                l.num(d)
                            )
                        };
                    }
                }
            }
        }
        ops
    }

    fn root(&self) -> String {
        format!("b{}[{}]", self.plan.root.0, self.plan.root.1)
    }

    fn sig_x(&self) -> String {
        format!("x: &[[V; {}]; {}]", self.plan.classes, self.plan.n)
    }

    /// `fn <prefix>_fwd(x) -> V`: the value of every lane's component.
    pub fn fwd(&self, l: &Lit, out: &mut String) -> usize {
        let mut body = String::new();
        let ops = self.forward(l, false, &mut body);
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_fwd({}) -> V {{ {body} {} }}",
            self.prefix,
            self.sig_x(),
            self.root()
        );
        ops
    }

    /// `fn <prefix>_max(x) -> V`: the max-product value of every lane's component.
    pub fn max(&self, l: &Lit, out: &mut String) -> usize {
        let mut body = String::new();
        let ops = self.forward(l, true, &mut body);
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_max({}) -> V {{ {body} {} }}",
            self.prefix,
            self.sig_x(),
            self.root()
        );
        ops
    }

    /// `fn <prefix>_post(x, post) -> V`: the value and the local posteriors
    /// `post[i][c] = x_i[c]·∂T/∂x_i[c] / T` of every lane, by reverse-mode adjoints.
    pub fn post(&self, l: &Lit, out: &mut String) -> usize {
        let p = self.plan;
        let mut body = String::new();
        let mut ops = self.forward(l, false, &mut body);
        // The forward sweep defined `sv{g}` for the inputs of segments with a floor.
        let _ = writeln!(body, "let mut gx = [[V::ZERO; {}]; {}];", p.classes, p.n);
        for (b, block) in p.blocks.iter().enumerate() {
            let _ = writeln!(body, "let mut g{b} = [V::ZERO; {}];", block.sums.len());
        }
        let _ = writeln!(body, "g{}[{}] = V::splat(1.0);", p.root.0, p.root.1);
        let gvec = |g: usize| -> String {
            if g < p.n {
                format!("gx[{g}]")
            } else {
                format!("g{}", g - p.n)
            }
        };
        for (b, block) in p.blocks.iter().enumerate().rev() {
            for seg in &block.segments {
                let seg_rows = rows(seg);
                let floors: Vec<(usize, f64)> = seg_rows
                    .iter()
                    .enumerate()
                    .filter(|(_, r)| r.floor > 0.0)
                    .map(|(m, r)| (m, r.floor))
                    .collect();
                if !floors.is_empty() {
                    let terms: Vec<String> = floors
                        .iter()
                        .map(|&(m, f)| format!("g{b}[{m}] * V::splat({})", l.num(f)))
                        .collect();
                    ops += terms.len();
                    let _ = writeln!(body, "let gf = {};", terms.join(" + "));
                    for (q, &g) in seg.inputs.iter().enumerate() {
                        let others: Vec<String> = seg
                            .inputs
                            .iter()
                            .enumerate()
                            .filter(|&(o, _)| o != q)
                            .map(|(_, &o)| format!("sv{o}"))
                            .collect();
                        let v = if others.is_empty() {
                            "gf".to_string()
                        } else {
                            ops += others.len();
                            format!("gf * {}", others.join(" * "))
                        };
                        let _ = writeln!(body, "{P}add_all(&mut {}, {v});", gvec(g));
                    }
                }
                for (m, row) in seg_rows.iter().enumerate() {
                    for &(t, d, _) in &row.above {
                        let idx = tuple(seg, t);
                        let _ = writeln!(body, "let h = g{b}[{m}] * V::splat({});", l.num(d));
                        ops += 1;
                        for (q, &g) in seg.inputs.iter().enumerate() {
                            let target = format!("{}[{}]", gvec(g), idx[q]);
                            match self.product(seg, t, Some(q)) {
                                Some(o) => {
                                    ops += seg.inputs.len() - 1;
                                    let _ =
                                        writeln!(body, "{target} = ({o}).mul_add(h, {target});");
                                }
                                None => {
                                    let _ = writeln!(body, "{target} = {target} + h;");
                                }
                            }
                        }
                    }
                }
            }
        }
        ops += 2 * p.n * p.classes;
        let _ = writeln!(body, "{P}post_rows(x, &gx, {}, post);", self.root());
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_post({}, post: &mut [[V; {}]; {}]) -> V {{ {body} {} }}",
            self.prefix,
            self.sig_x(),
            p.classes,
            p.n,
            self.root()
        );
        ops
    }

    /// `fn <prefix>_mpe(x, lab) -> T`: the max-product value of one component and, by
    /// backtracking the best tuple of every selected sum, its arg-max labelling.
    pub fn mpe(&self, l: &Lit, out: &mut String) -> usize {
        let t = l.t;
        let p = self.plan;
        let mut ops = 0;
        let mut body = String::new();
        let mut done = BTreeSet::new();
        let vec_name = |g: usize| -> String {
            if g < p.n {
                format!("x[{g}]")
            } else {
                format!("b{}", g - p.n)
            }
        };
        for (b, block) in p.blocks.iter().enumerate() {
            let m_len = block.sums.len();
            let _ = writeln!(
                body,
                "let mut b{b} = [0.0{t}; {m_len}]; let mut a{b} = [[0u16; 4]; {m_len}];"
            );
            let seg_rows: Vec<Vec<Row>> = block.segments.iter().map(rows).collect();
            for (seg, sr) in block.segments.iter().zip(&seg_rows) {
                if sr.iter().any(|r| r.floor > 0.0) {
                    for &g in &seg.inputs {
                        if done.insert(g) {
                            let _ =
                                writeln!(body, "let (mv{g}, iv{g}) = {P}amax(&{});", vec_name(g));
                        }
                    }
                }
            }
            // Row `m` gathers its candidates from every segment (`seg_rows[s][m]`).
            #[allow(clippy::needless_range_loop)]
            for m in 0..m_len {
                let _ = writeln!(body, "let mut r = -1.0{t};");
                for (s, seg) in block.segments.iter().enumerate() {
                    let row = &seg_rows[s][m];
                    let code = |idx: Vec<String>| -> String {
                        let mut c = vec![format!("{s}")];
                        c.extend(idx);
                        c.resize(4, "0".into());
                        format!("[{}]", c.join(", "))
                    };
                    if row.floor > 0.0 {
                        let f: Vec<String> = seg.inputs.iter().map(|g| format!("mv{g}")).collect();
                        let ivs: Vec<String> =
                            seg.inputs.iter().map(|g| format!("iv{g}")).collect();
                        ops += f.len();
                        let _ = writeln!(
                            body,
                            "{P}sel(&mut r, &mut a{b}[{m}], {} * {}, {});",
                            f.join(" * "),
                            l.num(row.floor),
                            code(ivs)
                        );
                    }
                    for &(tt, _, w) in &row.above {
                        let idx = tuple(seg, tt);
                        let f: Vec<String> = seg
                            .inputs
                            .iter()
                            .zip(&idx)
                            .map(|(&g, &i)| format!("{}[{i}]", vec_name(g)))
                            .collect();
                        ops += f.len();
                        let _ = writeln!(
                            body,
                            "{P}sel(&mut r, &mut a{b}[{m}], {} * {}, {});",
                            f.join(" * "),
                            l.num(w),
                            code(idx.iter().map(|i| i.to_string()).collect())
                        );
                    }
                }
                let _ = writeln!(body, "b{b}[{m}] = r.max(0.0);");
            }
        }
        for v in 0..p.n {
            let _ = writeln!(body, "let mut sx{v} = [false; {}];", p.classes);
        }
        for (b, block) in p.blocks.iter().enumerate() {
            let _ = writeln!(body, "let mut s{b} = [false; {}];", block.sums.len());
        }
        let _ = writeln!(body, "s{}[{}] = true;", p.root.0, p.root.1);
        for (b, block) in p.blocks.iter().enumerate().rev() {
            for (s, seg) in block.segments.iter().enumerate() {
                let sels: Vec<String> = seg
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
                    sels.join(", ")
                );
            }
        }
        for v in 0..p.n {
            let _ = writeln!(body, "{P}sel_label(&sx{v}, &mut lab[{v}]);");
        }
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_mpe(x: &[[{t}; {}]; {}], lab: &mut [u16; {}]) -> {t} {{ {body} {} }}",
            self.prefix,
            p.classes,
            p.n,
            p.n,
            self.root()
        );
        ops
    }
}
