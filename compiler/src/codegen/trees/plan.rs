//! What the tree-mixture emitter computes before it emits anything: the scaled
//! potentials as the generated code rounds them, every forest's tables (post-order
//! with depths, parents, children, roots) and `ln Z_t`, and the report (stack bounds,
//! state and table bytes, multiply-adds).

use graphspn_runtime::__private::{FactorCache, MAX_MESSAGE_ERROR, message_error, parallel_sweeps};

use crate::treemix::{NO_PARENT, RootedForest, SpanningTrees, TreeMixture};

use super::super::emit::Lit;
use super::super::surface::{CodeReport, fused_bytes};
use super::super::{Arithmetic, CodegenError, CodegenOptions, Precision, Vectorisation};

/// Sizes and types every emitter of a tree-mixture module needs.
pub(super) struct Context {
    /// Scalar type and literals.
    pub l: Lit,
    /// Places.
    pub n: usize,
    /// Classes.
    pub c: usize,
    /// Forests.
    pub t: usize,
    /// Classes per lane vector (1: scalar code).
    pub width: usize,
    /// Lane vectors per row (`⌈C / width⌉`).
    pub k: usize,
    /// Rows of the per-depth stacks: the largest height + 2.
    pub h: usize,
    /// Bytes of one scalar.
    pub scalar: usize,
    /// Scalar `f32` code for a target without an FPU: rows of `SoftF32` (integer fast
    /// paths, bit-identical to `f32`) instead of `f32`, and fixed-point messages where
    /// the model's bound allows ([`Potentials::fixed`]).
    pub soft: bool,
}

impl Context {
    pub fn new(
        model: &TreeMixture,
        trees: &SpanningTrees,
        options: &CodegenOptions,
    ) -> Result<Context, CodegenError> {
        let (n, c, t) = (
            trees.forests.first().map_or(0, RootedForest::num_places),
            model.num_classes(),
            trees.len(),
        );
        options.check(n)?;
        if !(2..=256).contains(&c) {
            return Err(CodegenError::Unsupported(format!(
                "a tree mixture is compiled for 2 to 256 classes, the model has {c} (`graphspn infer` evaluates it)"
            )));
        }
        if !(1..=crate::treemix::model::MAX_TREES).contains(&t) {
            return Err(CodegenError::BadOption(format!(
                "a tree mixture is compiled with 1 to {} trees, got {t}",
                crate::treemix::model::MAX_TREES
            )));
        }
        let width = match (options.vectorisation, options.precision) {
            (Vectorisation::Scalar, _) => 1,
            (Vectorisation::Simd, Precision::F32) => 8,
            (Vectorisation::Simd, Precision::F64) => 4,
        };
        let h = trees
            .forests
            .iter()
            .map(|f| f.height() as usize)
            .max()
            .unwrap_or(0)
            + 2;
        Ok(Context {
            l: Lit::new(options.precision),
            n,
            c,
            t,
            width,
            k: c.div_ceil(width),
            h,
            // `options.check` allows fixed point only for `f32` scalar code.
            soft: options.arithmetic == Arithmetic::Fixed,
            scalar: match options.precision {
                Precision::F32 => 4,
                Precision::F64 => 8,
            },
        })
    }

    /// Bytes of one row of lane vectors.
    pub fn row_bytes(&self) -> usize {
        self.k * self.width * self.scalar
    }

    /// A value rounded to the generated code's precision.
    pub fn round(&self, v: f64) -> f64 {
        match self.l.precision() {
            Precision::F32 => f64::from(v as f32),
            Precision::F64 => v,
        }
    }
}

/// `ψ` and `u` scaled to a largest entry of 1, and the message matrices, rounded as
/// the generated code holds them (`[a · C + j]`): folded (scalar code, see the
/// runtime's `TreeModel::folded`) `up = ψ·diag(u)` and `down = diag(u)·ψ`, each
/// product of the scaled values rounded once; otherwise both `ψ`.
pub(super) struct Potentials {
    pub up: Vec<f64>,
    pub down: Vec<f64>,
    pub unary: Vec<f64>,
    pub folded: bool,
    /// The message matrices in Q0.32 (`[a · C + j]`, rounded once from the exact
    /// products) where messages are computed in fixed point: `SoftF32` rows whose
    /// per-message bound (the runtime's `message_error`) is at most
    /// `MAX_MESSAGE_ERROR`; with that bound.
    pub fixed: Option<FixedPotentials>,
}

/// The Q0.32 message matrices of [`Potentials::fixed`] and their error bound.
pub(super) struct FixedPotentials {
    pub up: Vec<u32>,
    pub down: Vec<u32>,
    /// `η`: the relative error bound of one message entry.
    pub error: f64,
}

impl FixedPotentials {
    /// The Q0.32 matrices of the exact folded products `up`, `down` (largest entry at
    /// most 1), when their bound allows.
    fn new(up: &[f64], down: &[f64], c: usize) -> Option<FixedPotentials> {
        let q = |m: &[f64]| -> Vec<u32> {
            m.iter()
                .map(|&x| (x * 2f64.powi(32)).round().min(f64::from(u32::MAX)) as u32)
                .collect()
        };
        let (up, down) = (q(up), q(down));
        let min = up.iter().chain(&down).copied().min().unwrap_or(0);
        let error = message_error(c, f64::from(min) / 2f64.powi(32));
        (min > 0 && error <= MAX_MESSAGE_ERROR).then_some(FixedPotentials { up, down, error })
    }
}

impl Potentials {
    pub fn new(model: &TreeMixture, cx: &Context) -> Potentials {
        let scaled = |v: &[f64]| {
            let max = v.iter().cloned().fold(0.0, f64::max);
            v.iter().map(|x| x / max).collect::<Vec<f64>>()
        };
        let (psi, unary) = (scaled(&model.potential), scaled(&model.unary));
        let c = cx.c;
        let folded = cx.width == 1;
        let entry = |i: usize, u: f64| if folded { psi[i] * u } else { psi[i] };
        let up: Vec<f64> = (0..c * c).map(|i| entry(i, unary[i % c])).collect();
        let down: Vec<f64> = (0..c * c).map(|i| entry(i, unary[i / c])).collect();
        let fixed = if cx.soft {
            FixedPotentials::new(&up, &down, c)
        } else {
            None
        };
        Potentials {
            up: up.iter().map(|&x| cx.round(x)).collect(),
            down: down.iter().map(|&x| cx.round(x)).collect(),
            unary: unary.iter().map(|&x| cx.round(x)).collect(),
            folded,
            fixed,
        }
    }
}

/// One forest's tables.
pub(super) struct ForestPlan {
    /// `(place, depth)` in depth-first post-order (roots and children in increasing
    /// place order).
    pub post: Vec<[usize; 2]>,
    /// Parent of every place (`None`: root).
    pub parent: Vec<Option<usize>>,
    /// `kid_start[v]..kid_start[v + 1]` indexes `kids`.
    pub kid_start: Vec<usize>,
    pub kids: Vec<usize>,
    pub roots: Vec<usize>,
    pub depth: Vec<usize>,
    /// `ln Z_t = z_exp · ln 2 + z_rem`.
    pub z_exp: i32,
    pub z_rem: f64,
}

impl ForestPlan {
    pub fn new(f: &RootedForest, pot: &Potentials, c: usize) -> ForestPlan {
        let n = f.num_places();
        let children = f.children();
        let parent: Vec<Option<usize>> = f
            .parent
            .iter()
            .map(|&p| (p != NO_PARENT).then_some(p as usize))
            .collect();
        let roots: Vec<usize> = f.roots().into_iter().map(|r| r as usize).collect();
        let mut kid_start = Vec::with_capacity(n + 1);
        let mut kids = Vec::new();
        for ch in &children {
            kid_start.push(kids.len());
            kids.extend(ch.iter().map(|&k| k as usize));
        }
        kid_start.push(kids.len());
        // Iterative depth-first search: a place is emitted after all its children.
        let mut post = Vec::with_capacity(n);
        for &r in &roots {
            let mut stack = vec![(r, 0usize)];
            while let Some(&mut (v, ref mut next)) = stack.last_mut() {
                if let Some(&k) = children[v].get(*next) {
                    *next += 1;
                    stack.push((k as usize, 0));
                } else {
                    post.push([v, f.depth[v] as usize]);
                    stack.pop();
                }
            }
        }
        let log_z = log_partition(&post, &children, pot, c);
        let z_exp = (log_z / std::f64::consts::LN_2).round() as i32;
        ForestPlan {
            post,
            parent,
            kid_start,
            kids,
            roots,
            depth: f.depth.iter().map(|&d| d as usize).collect(),
            z_exp,
            z_rem: log_z - f64::from(z_exp) * std::f64::consts::LN_2,
        }
    }

    /// Places with a parent.
    pub fn non_roots(&self) -> usize {
        self.parent.len() - self.roots.len()
    }
}

/// `ln Z_t`: the forest's value `Σ_y Π u(y_v) Π ψ(y_a, y_b)` with the scaled, rounded
/// potentials as the generated code multiplies them (`u` in every belief, or folded
/// into the upward matrix and multiplied into the roots' beliefs only; messages
/// normalised by their sums, logs accumulated in `f64`).
fn log_partition(post: &[[usize; 2]], children: &[Vec<u32>], pot: &Potentials, c: usize) -> f64 {
    let n = children.len();
    let mut msg = vec![Vec::new(); n];
    let mut log_z = 0.0;
    for &[v, d] in post {
        let mut b = if pot.folded {
            vec![1.0; c]
        } else {
            pot.unary.clone()
        };
        for &k in &children[v] {
            for (x, m) in b.iter_mut().zip(&msg[k as usize]) {
                *x *= m;
            }
        }
        if d == 0 {
            let root: f64 = if pot.folded {
                b.iter().zip(&pot.unary).map(|(x, u)| x * u).sum()
            } else {
                b.iter().sum()
            };
            log_z += root.ln();
            continue;
        }
        let m: Vec<f64> = (0..c)
            .map(|a| (0..c).map(|j| pot.up[a * c + j] * b[j]).sum())
            .collect();
        let s: f64 = m.iter().sum();
        log_z += s.ln();
        msg[v] = m.into_iter().map(|x| x / s).collect();
    }
    log_z
}

/// The report: stack bounds (frames of the runtime driver's passes, measured on
/// Cortex-M4F and x86-64 well below these), state and table bytes, multiply-adds; and
/// where the `φ` table goes: on SIMD hosts into every entry point that can use it, on
/// scalar targets into each one whose bound with the table stays within `budget`.
pub(super) fn report(
    plans: &[ForestPlan],
    cx: &Context,
    budget: usize,
) -> (CodeReport, FactorCache) {
    let (n, c, t, h, s) = (cx.n, cx.c, cx.t, cx.h, cx.scalar);
    let row = cx.row_bytes();
    // Calls, saved registers and the accumulators of every forest; a pass's row
    // temporaries (belief, message, evidence factor, its power, the parent's row,
    // the division, the downward message; a fixed-point message's scratch is six
    // rows: the row's bits, its Q0.32 copy, 64-bit sums, the result, and for a
    // max-product one its arg-max bytes) with room for spills.
    // A table entry is a row and its exponent, padded to the row's alignment.
    let align = (cx.width * s).max(4);
    let table = n * (row + 4).next_multiple_of(align);
    let base = 1024 + t * (24 + s);
    let temps = 16 * row + 512;
    // SIMD code sweeps forests side by side for values (a stack of rows each).
    let value = parallel_sweeps(cx.width, n, h) * (h * (row + 1) + temps);
    let log_likelihood = base + value;
    let marginals = base + n * row + h * row + temps;
    let mpe = base + value + n * c;
    let path = h * (row + 2) + temps;
    let fits = |bytes: usize| cx.width > 1 || bytes + table <= budget;
    let cache = FactorCache {
        values: fits(mpe),
        marginals: fits(marginals),
        state: fits(base + value),
    };
    let with = |flag: bool, bytes: usize| if flag { bytes + table } else { bytes };
    let stack_log_likelihood = with(cache.values, log_likelihood);
    let stack_marginals = with(cache.marginals, marginals);
    let stack_mpe = with(cache.values, mpe);
    let state_updates = with(cache.state, base + value).max(base + path.max(value + n * c));
    // The rows, fused rows, messages and exponents, the roots' totals, the `i64` sum
    // of the fused rows' shifts and the ready flag; the `i64` aligns the state to 8.
    let fields = n * c * s + n * fused_bytes(c, s) + t * n * row + 4 * t * n + 4 * t + 8 + 1;
    let state_align = align.max(8);
    let state_bytes = fields.div_ceil(state_align) * state_align;
    let per_forest =
        |p: &ForestPlan| 4 * n + 2 * n + 2 * (n + 1) + 2 * p.kids.len() + 2 * p.roots.len() + 48;
    let table_bytes = plans.iter().map(per_forest).sum::<usize>() + (c + 2) * row;
    // One matrix–vector product is `C · K` lane-vector multiply-adds.
    let mv = c * cx.k;
    let edges: usize = plans.iter().map(ForestPlan::non_roots).sum();
    let best = plans.iter().map(ForestPlan::non_roots).max().unwrap_or(0);
    let path_len = |v: usize| plans.iter().map(|p| p.depth[v] + 1).sum::<usize>();
    let worst_path = (0..n).map(|v| path_len(v) - t).max().unwrap_or(0);
    let mut report = CodeReport {
        lanes: cx.width,
        components: t * n,
        stack_log_likelihood,
        stack_marginals,
        stack_mpe,
        stack_state: 0,
        state_bytes,
        table_bytes,
        macs_log_likelihood: edges * mv,
        macs_marginals: 2 * edges * mv,
        macs_mpe: (edges + best) * mv,
        macs_observe_marginals: (worst_path + edges) * mv,
        units_per_update: (0..n).map(path_len).sum::<usize>() as f64 / n.max(1) as f64,
        message_error: None,
    };
    report.stack_state = report.state_bound(state_updates);
    (report, cache)
}
