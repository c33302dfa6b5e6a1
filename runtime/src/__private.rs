//! Helpers called only by code that `graphspn-compiler` generates. Not part of the
//! public API: names and signatures may change with any compiler release.
//!
//! Every helper is allocation-free, panic-free (no indexing with run-time
//! indices; iterators only) and exists in an `_f32` and an `_f64` flavour.

use crate::EvidenceError;

pub use crate::compiled::{fixed, fixed_mut};

/// Natural log in `f64` (`ln 0 = -inf`).
#[inline]
pub fn ln64(x: f64) -> f64 {
    libm::log(x)
}

/// `e^x` in `f64`.
#[inline]
pub fn exp64(x: f64) -> f64 {
    libm::exp(x)
}

/// `ln Σ_d e^{a_d}` in `f64`; `-inf` when every term is `-inf`. Relative error a few ulp
/// of the result plus `ln` of the count's rounding (< 1e-15 absolute for D ≤ 1e6).
#[inline]
pub fn lse64<const D: usize>(a: &[f64; D]) -> f64 {
    let m = a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if m == f64::NEG_INFINITY {
        return m;
    }
    let s: f64 = a.iter().map(|&v| libm::exp(v - m)).sum();
    m + libm::log(s)
}

/// Index of the largest entry, lowest index on ties (`0` for an all-NaN or empty array).
#[inline]
pub fn argmax64<const D: usize>(a: &[f64; D]) -> usize {
    let mut best = 0;
    let mut bv = f64::NEG_INFINITY;
    for (i, &v) in a.iter().enumerate() {
        if v > bv {
            bv = v;
            best = i;
        }
    }
    best
}

/// Checks labels: each must be `< C` or `u16::MAX` (unknown). A bad label at place `p`
/// is reported as `WrongShape { place: p, expected: C, found: label }`.
pub fn check_labels<const N: usize>(
    labels: &[u16; N],
    classes: usize,
) -> Result<(), EvidenceError> {
    for (p, &l) in labels.iter().enumerate() {
        if l != u16::MAX && usize::from(l) >= classes {
            return Err(EvidenceError::WrongShape {
                place: p,
                expected: classes,
                found: usize::from(l),
            });
        }
    }
    Ok(())
}

macro_rules! flavour {
    ($t:ident, $ln:path, $exp:path,
     $check:ident, $scale:ident, $prep:ident, $lnf:ident, $expf:ident, $dot:ident, $sum:ident,
     $prod:ident, $lse:ident, $argmax:ident, $flow:ident, $axpy:ident, $weights:ident,
     $lnrow:ident) => {
        /// Validates evidence: every value finite and `≥ 0`, every row with some mass.
        /// Errors name the place index and its id from `ids`.
        pub fn $check<const N: usize, const C: usize>(
            e: &[[$t; C]; N],
            ids: &[u32; N],
        ) -> Result<(), EvidenceError> {
            for (p, (row, &id)) in e.iter().zip(ids).enumerate() {
                let place_id = u64::from(id);
                let mut mass = false;
                for (class, &v) in row.iter().enumerate() {
                    if !v.is_finite() {
                        return Err(EvidenceError::NotFinite {
                            place: p,
                            place_id,
                            class,
                        });
                    }
                    if v < 0.0 {
                        return Err(EvidenceError::Negative {
                            place: p,
                            place_id,
                            class,
                        });
                    }
                    mass |= v > 0.0;
                }
                if !mass {
                    return Err(EvidenceError::NoMass { place: p, place_id });
                }
            }
            Ok(())
        }

        /// `Σ_p ln s_p` in `f64`, where `s_p` is the largest value of row `p`, or the
        /// value of its label when labelled (`label < C`). `-inf` when some `s_p = 0`.
        pub fn $scale<const N: usize, const C: usize>(e: &[[$t; C]; N], labels: &[u16; N]) -> f64 {
            let mut acc = 0.0f64;
            for (row, &l) in e.iter().zip(labels) {
                let s = match row.get(usize::from(l)) {
                    Some(&v) => v,
                    None => row.iter().copied().fold(0.0, $t::max),
                };
                acc += libm::log(f64::from(s));
            }
            acc
        }

        /// The scaled row `x = α / s` (largest entry exactly 1), or the one-hot row of
        /// `label` when `label < C`.
        #[inline(always)]
        pub fn $prep<const C: usize>(row: &[$t; C], label: u16) -> [$t; C] {
            let mut x = [0.0; C];
            if usize::from(label) < C {
                if let Some(v) = x.get_mut(usize::from(label)) {
                    *v = 1.0;
                }
                return x;
            }
            let s = row.iter().copied().fold(0.0, $t::max);
            let inv = 1.0 / s;
            for (o, &v) in x.iter_mut().zip(row) {
                *o = v * inv;
            }
            x
        }

        /// Natural log (`ln 0 = -inf`).
        #[inline(always)]
        pub fn $lnf(x: $t) -> $t {
            $ln(x)
        }

        /// `e^x`.
        #[inline(always)]
        pub fn $expf(x: $t) -> $t {
            $exp(x)
        }

        /// Elementwise natural log of every row.
        #[inline(always)]
        pub fn $lnrow<const N: usize, const C: usize>(x: &[[$t; C]; N]) -> [[$t; C]; N] {
            let mut o = [[0.0; C]; N];
            for (or, xr) in o.iter_mut().zip(x) {
                for (a, &b) in or.iter_mut().zip(xr) {
                    *a = $ln(b);
                }
            }
            o
        }

        /// `Σ_j w_j v_j` with eight independent accumulators (vectorisable).
        #[inline(always)]
        pub fn $dot<const K: usize>(w: &[$t; K], v: &[$t; K]) -> $t {
            let mut acc = [0.0 as $t; 8];
            let wc = w.chunks_exact(8);
            let vc = v.chunks_exact(8);
            let mut tail = 0.0;
            for (a, b) in wc.remainder().iter().zip(vc.remainder()) {
                tail += a * b;
            }
            for (a, b) in wc.zip(vc) {
                for ((s, x), y) in acc.iter_mut().zip(a).zip(b) {
                    *s += x * y;
                }
            }
            acc.iter().sum::<$t>() + tail
        }

        /// `Σ_j v_j`.
        #[inline(always)]
        pub fn $sum<const K: usize>(v: [$t; K]) -> $t {
            v.iter().sum()
        }

        /// `Π_j v_j`.
        #[inline(always)]
        pub fn $prod<const K: usize>(v: [$t; K]) -> $t {
            v.iter().product()
        }

        /// `ln Σ_j e^{a_j}`; `-inf` when all terms are `-inf` (never NaN for inputs
        /// in `[-inf, +inf)`). Error: a few ulp of the result.
        #[inline(always)]
        pub fn $lse<const K: usize>(a: [$t; K]) -> $t {
            let m = a.iter().copied().fold($t::NEG_INFINITY, $t::max);
            if m == $t::NEG_INFINITY {
                return m;
            }
            let s: $t = a.iter().map(|&v| $exp(v - m)).sum();
            m + $ln(s)
        }

        /// Largest entry and its index, lowest index on ties.
        #[inline(always)]
        pub fn $argmax<const K: usize>(a: [$t; K]) -> ($t, u16) {
            let mut best = 0u16;
            let mut bv = $t::NEG_INFINITY;
            for (i, &v) in a.iter().enumerate() {
                if v > bv {
                    bv = v;
                    best = i as u16;
                }
            }
            (bv, best)
        }

        /// Top-down flow through a log-space sum edge: `f · e^{a − v}` where `a` is the
        /// child's weighted log value and `v` the parent's log value; `0` when the parent
        /// is zero (`v = -inf`) or carries no flow.
        #[inline(always)]
        pub fn $flow(f: $t, a: $t, v: $t) -> $t {
            if v == $t::NEG_INFINITY || f == 0.0 {
                0.0
            } else {
                f * $exp(a - v)
            }
        }

        /// `out += w · g`.
        #[inline(always)]
        pub fn $axpy<const C: usize>(out: &mut [$t; C], w: $t, g: &[$t; C]) {
            for (o, &v) in out.iter_mut().zip(g) {
                *o += w * v;
            }
        }

        /// Posterior weight of each decomposition, `e^{ln(1/D) + lp_d − l̂}`.
        #[inline]
        pub fn $weights<const D: usize>(lp: &[f64; D], lhat: f64) -> [$t; D] {
            let lnd = -libm::log(D as f64);
            let mut w = [0.0; D];
            for (o, &l) in w.iter_mut().zip(lp) {
                *o = libm::exp(lnd + l - lhat) as $t;
            }
            w
        }
    };
}

flavour!(
    f32,
    libm::logf,
    libm::expf,
    check_f32,
    scale_f32,
    prep_f32,
    ln_f32,
    exp_f32,
    dot_f32,
    sum_f32,
    prod_f32,
    lse_f32,
    argmax_f32,
    flow_f32,
    axpy_f32,
    weights_f32,
    ln_rows_f32
);
flavour!(
    f64,
    libm::log,
    libm::exp,
    check_f64,
    scale_f64,
    prep_f64,
    ln_f64,
    exp_f64,
    dot_f64,
    sum_f64,
    prod_f64,
    lse_f64,
    argmax_f64,
    flow_f64,
    axpy_f64,
    weights_f64,
    ln_rows_f64
);

// ---------------------------------------------------------------------------
// Dense region kernels.
//
// A "region block" of a template SPN is `M` sums sharing one child list whose
// children are the full cartesian product of `k ≤ 3` child vectors `a` (len `A`),
// `b` (len `B`), `c` (len `K`): `out[m] = Σ W[m][i][j][k]·a[i]·b[j]·c[k]`. Weights
// are stored with the *last* input outermost (`w[k][j][m][i]`) so each contraction
// step is an `axpy` over a contiguous, fixed-size block (which LLVM vectorises);
// only the final step is `M` short dot products. All kernels accumulate into their
// outputs (several splits of one region add up). Max-product kernels keep the
// running maximum (strict `>`, so the lowest index wins ties).
// ---------------------------------------------------------------------------

/// The scalar types of generated code (`f32`, `f64`).
pub trait Real:
    Copy
    + PartialOrd
    + core::ops::Add<Output = Self>
    + core::ops::Mul<Output = Self>
    + core::ops::AddAssign
    + core::ops::MulAssign
    + core::ops::Div<Output = Self>
{
    /// `0`.
    const ZERO: Self;
    /// `1`.
    const ONE: Self;
}

impl Real for f32 {
    const ZERO: f32 = 0.0;
    const ONE: f32 = 1.0;
}

impl Real for f64 {
    const ZERO: f64 = 0.0;
    const ONE: f64 = 1.0;
}

/// `Σ a_i b_i` over the common length, with eight independent accumulators.
#[inline(always)]
fn dot<R: Real>(a: &[R], b: &[R]) -> R {
    let mut acc = [R::ZERO; 8];
    let ac = a.chunks_exact(8);
    let bc = b.chunks_exact(8);
    let mut tail = R::ZERO;
    for (x, y) in ac.remainder().iter().zip(bc.remainder()) {
        tail += *x * *y;
    }
    for (x, y) in ac.zip(bc) {
        for ((s, &p), &q) in acc.iter_mut().zip(x).zip(y) {
            *s += p * q;
        }
    }
    let [a0, a1, a2, a3, a4, a5, a6, a7] = acc;
    ((a0 + a1) + (a2 + a3)) + ((a4 + a5) + (a6 + a7)) + tail
}

/// `y += s·x` over the common length.
#[inline(always)]
fn axpy<R: Real>(y: &mut [R], s: R, x: &[R]) {
    for (o, &v) in y.iter_mut().zip(x) {
        *o += s * v;
    }
}

/// `y = max(y, s·x)` elementwise.
#[inline(always)]
fn axmax<R: Real>(y: &mut [R], s: R, x: &[R]) {
    for (o, &v) in y.iter_mut().zip(x) {
        let p = s * v;
        if p > *o {
            *o = p;
        }
    }
}

/// `y = max(y, s·x)` elementwise, recording `idx` in `arg` where `y` grew.
#[inline(always)]
fn axmax_arg<R: Real>(y: &mut [R], arg: &mut [u16], idx: u16, s: R, x: &[R]) {
    for ((o, a), &v) in y.iter_mut().zip(arg.iter_mut()).zip(x) {
        let p = s * v;
        if p > *o {
            *o = p;
            *a = idx;
        }
    }
}

/// `out[m] += Σ_i w[m][i]·a[i]`.
#[inline(never)]
pub fn d1_fwd<R: Real, const M: usize, const A: usize>(
    w: &[[R; A]; M],
    a: &[R; A],
    out: &mut [R; M],
) {
    for (o, row) in out.iter_mut().zip(w) {
        *o += dot(row, a);
    }
}

/// Adjoint of [`d1_fwd`]: `ga[i] += Σ_m g[m]·w[m][i]`.
#[inline(never)]
pub fn d1_bwd<R: Real, const M: usize, const A: usize>(
    w: &[[R; A]; M],
    g: &[R; M],
    ga: &mut [R; A],
) {
    for (&gm, row) in g.iter().zip(w) {
        axpy(ga, gm, row);
    }
}

/// `out[m] = max(out[m], max_i w[m][i]·a[i])`.
#[inline(never)]
pub fn d1_max<R: Real, const M: usize, const A: usize>(
    w: &[[R; A]; M],
    a: &[R; A],
    out: &mut [R; M],
) {
    for (o, row) in out.iter_mut().zip(w) {
        for (&x, &y) in row.iter().zip(a) {
            let p = x * y;
            if p > *o {
                *o = p;
            }
        }
    }
}

/// [`d1_max`] that records `[seg, i, 0, 0]` in `arg[m]` where `out[m]` grew.
#[inline(never)]
pub fn d1_maxa<R: Real, const M: usize, const A: usize>(
    seg: u16,
    w: &[[R; A]; M],
    a: &[R; A],
    out: &mut [R; M],
    arg: &mut [[u16; 4]; M],
) {
    for ((o, am), row) in out.iter_mut().zip(arg.iter_mut()).zip(w) {
        for ((&x, &y), i) in row.iter().zip(a).zip(0u16..) {
            let p = x * y;
            if p > *o {
                *o = p;
                *am = [seg, i, 0, 0];
            }
        }
    }
}

/// Marks the `a` entries chosen by the selected sums whose best tuple is in `seg`.
#[inline(always)]
pub fn d1_back<const M: usize, const A: usize>(
    seg: u16,
    sel: &[bool; M],
    arg: &[[u16; 4]; M],
    sa: &mut [bool; A],
) {
    for (&s, am) in sel.iter().zip(arg) {
        if s && am[0] == seg {
            mark(sa, am[1]);
        }
    }
}

#[inline(always)]
fn mark<const A: usize>(s: &mut [bool; A], i: u16) {
    if let Some(v) = s.get_mut(usize::from(i)) {
        *v = true;
    }
}

/// Forward of a two-input block keeping the intermediate `u[m][i] = Σ_j w[j][m][i]·b[j]`
/// for [`d2_bwd`]; `out[m] += Σ_i u[m][i]·a[i]`.
#[inline(never)]
pub fn d2_fwdk<R: Real, const M: usize, const A: usize, const B: usize>(
    w: &[[[R; A]; M]; B],
    a: &[R; A],
    b: &[R; B],
    u: &mut [[R; A]; M],
    out: &mut [R; M],
) {
    let uf = u.as_flattened_mut();
    for (wj, &bj) in w.iter().zip(b) {
        axpy(uf, bj, wj.as_flattened());
    }
    for (o, um) in out.iter_mut().zip(u.iter()) {
        *o += dot(um, a);
    }
}

/// `out[m] += Σ_{i,j} w[j][m][i]·a[i]·b[j]`.
#[inline(never)]
pub fn d2_fwd<R: Real, const M: usize, const A: usize, const B: usize>(
    w: &[[[R; A]; M]; B],
    a: &[R; A],
    b: &[R; B],
    out: &mut [R; M],
) {
    let mut u = [[R::ZERO; A]; M];
    d2_fwdk(w, a, b, &mut u, out);
}

/// Adjoints of [`d2_fwdk`] for output adjoint `g`.
#[inline(never)]
pub fn d2_bwd<R: Real, const M: usize, const A: usize, const B: usize>(
    w: &[[[R; A]; M]; B],
    a: &[R; A],
    u: &[[R; A]; M],
    g: &[R; M],
    ga: &mut [R; A],
    gb: &mut [R; B],
) {
    let mut h = [[R::ZERO; A]; M];
    for ((hm, um), &gm) in h.iter_mut().zip(u).zip(g) {
        axpy(ga, gm, um);
        axpy(hm, gm, a);
    }
    let hf = h.as_flattened();
    for (o, wj) in gb.iter_mut().zip(w) {
        *o += dot(wj.as_flattened(), hf);
    }
}

/// `out[m] = max(out[m], max_{i,j} w[j][m][i]·a[i]·b[j])`.
#[inline(never)]
pub fn d2_max<R: Real, const M: usize, const A: usize, const B: usize>(
    w: &[[[R; A]; M]; B],
    a: &[R; A],
    b: &[R; B],
    out: &mut [R; M],
) {
    let mut u = [[R::ZERO; A]; M];
    let uf = u.as_flattened_mut();
    for (wj, &bj) in w.iter().zip(b) {
        axmax(uf, bj, wj.as_flattened());
    }
    for (o, um) in out.iter_mut().zip(&u) {
        for (&x, &y) in um.iter().zip(a) {
            let p = x * y;
            if p > *o {
                *o = p;
            }
        }
    }
}

/// [`d2_max`] recording the best `[seg, i, j, 0]` in `arg[m]` where `out[m]` grew.
#[inline(never)]
pub fn d2_maxa<R: Real, const M: usize, const A: usize, const B: usize>(
    seg: u16,
    w: &[[[R; A]; M]; B],
    a: &[R; A],
    b: &[R; B],
    out: &mut [R; M],
    arg: &mut [[u16; 4]; M],
) {
    let mut u = [[R::ZERO; A]; M];
    let mut aj = [[0u16; A]; M];
    {
        let uf = u.as_flattened_mut();
        let af = aj.as_flattened_mut();
        for ((wj, &bj), j) in w.iter().zip(b).zip(0u16..) {
            if j == 0 {
                for (o, &x) in uf.iter_mut().zip(wj.as_flattened()) {
                    *o = x * bj;
                }
            } else {
                axmax_arg(uf, af, j, bj, wj.as_flattened());
            }
        }
    }
    for (((o, am), um), ajm) in out.iter_mut().zip(arg.iter_mut()).zip(&u).zip(&aj) {
        for (((&x, &y), i), &j) in um.iter().zip(a).zip(0u16..).zip(ajm) {
            let p = x * y;
            if p > *o {
                *o = p;
                *am = [seg, i, j, 0];
            }
        }
    }
}

/// Marks the `a`, `b` entries chosen by the selected sums whose best tuple is in `seg`.
#[inline(always)]
pub fn d2_back<const M: usize, const A: usize, const B: usize>(
    seg: u16,
    sel: &[bool; M],
    arg: &[[u16; 4]; M],
    sa: &mut [bool; A],
    sb: &mut [bool; B],
) {
    for (&s, am) in sel.iter().zip(arg) {
        if s && am[0] == seg {
            mark(sa, am[1]);
            mark(sb, am[2]);
        }
    }
}

/// Forward of a three-input block keeping `u[j][m][i] = Σ_k w[k][j][m][i]·c[k]` and
/// `v[m][i] = Σ_j u[j][m][i]·b[j]` for [`d3_bwd`]; `out[m] += Σ_i v[m][i]·a[i]`.
#[inline(never)]
pub fn d3_fwdk<R: Real, const M: usize, const A: usize, const B: usize, const K: usize>(
    w: &[[[[R; A]; M]; B]; K],
    a: &[R; A],
    b: &[R; B],
    c: &[R; K],
    u: &mut [[[R; A]; M]; B],
    v: &mut [[R; A]; M],
    out: &mut [R; M],
) {
    {
        let uf = u.as_flattened_mut().as_flattened_mut();
        for (wk, &ck) in w.iter().zip(c) {
            axpy(uf, ck, wk.as_flattened().as_flattened());
        }
    }
    let vf = v.as_flattened_mut();
    for (uj, &bj) in u.iter().zip(b) {
        axpy(vf, bj, uj.as_flattened());
    }
    for (o, vm) in out.iter_mut().zip(v.iter()) {
        *o += dot(vm, a);
    }
}

/// `out[m] += Σ_{i,j,k} w[k][j][m][i]·a[i]·b[j]·c[k]`.
#[inline(never)]
pub fn d3_fwd<R: Real, const M: usize, const A: usize, const B: usize, const K: usize>(
    w: &[[[[R; A]; M]; B]; K],
    a: &[R; A],
    b: &[R; B],
    c: &[R; K],
    out: &mut [R; M],
) {
    let mut u = [[[R::ZERO; A]; M]; B];
    let mut v = [[R::ZERO; A]; M];
    d3_fwdk(w, a, b, c, &mut u, &mut v, out);
}

/// Adjoints of [`d3_fwdk`] for output adjoint `g`.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
pub fn d3_bwd<R: Real, const M: usize, const A: usize, const B: usize, const K: usize>(
    w: &[[[[R; A]; M]; B]; K],
    a: &[R; A],
    b: &[R; B],
    u: &[[[R; A]; M]; B],
    v: &[[R; A]; M],
    g: &[R; M],
    ga: &mut [R; A],
    gb: &mut [R; B],
    gc: &mut [R; K],
) {
    let mut h = [[R::ZERO; A]; M];
    for ((hm, vm), &gm) in h.iter_mut().zip(v).zip(g) {
        axpy(ga, gm, vm);
        axpy(hm, gm, a);
    }
    let hf = h.as_flattened();
    let mut hh = [[[R::ZERO; A]; M]; B];
    for ((o, uj), (hhj, &bj)) in gb.iter_mut().zip(u).zip(hh.iter_mut().zip(b)) {
        *o += dot(uj.as_flattened(), hf);
        axpy(hhj.as_flattened_mut(), bj, hf);
    }
    let hhf = hh.as_flattened().as_flattened();
    for (o, wk) in gc.iter_mut().zip(w) {
        *o += dot(wk.as_flattened().as_flattened(), hhf);
    }
}

/// `out[m] = max(out[m], max_{i,j,k} w[k][j][m][i]·a[i]·b[j]·c[k])`.
#[inline(never)]
pub fn d3_max<R: Real, const M: usize, const A: usize, const B: usize, const K: usize>(
    w: &[[[[R; A]; M]; B]; K],
    a: &[R; A],
    b: &[R; B],
    c: &[R; K],
    out: &mut [R; M],
) {
    let mut u = [[[R::ZERO; A]; M]; B];
    {
        let uf = u.as_flattened_mut().as_flattened_mut();
        for (wk, &ck) in w.iter().zip(c) {
            axmax(uf, ck, wk.as_flattened().as_flattened());
        }
    }
    let mut v = [[R::ZERO; A]; M];
    {
        let vf = v.as_flattened_mut();
        for (uj, &bj) in u.iter().zip(b) {
            axmax(vf, bj, uj.as_flattened());
        }
    }
    for (o, vm) in out.iter_mut().zip(&v) {
        for (&x, &y) in vm.iter().zip(a) {
            let p = x * y;
            if p > *o {
                *o = p;
            }
        }
    }
}

/// [`d3_max`] recording the best `[seg, i, j, k]` in `arg[m]` where `out[m]` grew.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
pub fn d3_maxa<R: Real, const M: usize, const A: usize, const B: usize, const K: usize>(
    seg: u16,
    w: &[[[[R; A]; M]; B]; K],
    a: &[R; A],
    b: &[R; B],
    c: &[R; K],
    out: &mut [R; M],
    arg: &mut [[u16; 4]; M],
) {
    let mut u = [[[R::ZERO; A]; M]; B];
    let mut ak = [[[0u16; A]; M]; B];
    {
        let uf = u.as_flattened_mut().as_flattened_mut();
        let af = ak.as_flattened_mut().as_flattened_mut();
        for ((wk, &ck), k) in w.iter().zip(c).zip(0u16..) {
            if k == 0 {
                for (o, &x) in uf.iter_mut().zip(wk.as_flattened().as_flattened()) {
                    *o = x * ck;
                }
            } else {
                axmax_arg(uf, af, k, ck, wk.as_flattened().as_flattened());
            }
        }
    }
    let mut v = [[R::ZERO; A]; M];
    let mut aj = [[0u16; A]; M];
    {
        let vf = v.as_flattened_mut();
        let af = aj.as_flattened_mut();
        for ((uj, &bj), j) in u.iter().zip(b).zip(0u16..) {
            if j == 0 {
                for (o, &x) in vf.iter_mut().zip(uj.as_flattened()) {
                    *o = x * bj;
                }
            } else {
                axmax_arg(vf, af, j, bj, uj.as_flattened());
            }
        }
    }
    for (((o, am), vm), (ajm, m)) in out
        .iter_mut()
        .zip(arg.iter_mut())
        .zip(&v)
        .zip(aj.iter().zip(0usize..))
    {
        for (((&x, &y), i), &j) in vm.iter().zip(a).zip(0u16..).zip(ajm) {
            let p = x * y;
            if p > *o {
                *o = p;
                let k = ak
                    .get(usize::from(j))
                    .and_then(|r| r.get(m))
                    .and_then(|r| r.get(usize::from(i)))
                    .copied()
                    .unwrap_or(0);
                *am = [seg, i, j, k];
            }
        }
    }
}

/// Marks the `a`, `b`, `c` entries chosen by the selected sums whose best tuple is in `seg`.
#[inline(always)]
pub fn d3_back<const M: usize, const A: usize, const B: usize, const K: usize>(
    seg: u16,
    sel: &[bool; M],
    arg: &[[u16; 4]; M],
    sa: &mut [bool; A],
    sb: &mut [bool; B],
    sc: &mut [bool; K],
) {
    for (&s, am) in sel.iter().zip(arg) {
        if s && am[0] == seg {
            mark(sa, am[1]);
            mark(sb, am[2]);
            mark(sc, am[3]);
        }
    }
}

/// Sets `lab` to the lowest selected class (unchanged when none is selected).
#[inline(always)]
pub fn sel_label<const C: usize>(sel: &[bool; C], lab: &mut u16) {
    if let Some(c) = sel.iter().position(|&s| s) {
        *lab = c as u16;
    }
}

/// Local posteriors of one variable: `post[c] = x[c]·g[c]·inv`.
#[inline(always)]
pub fn post_row<R: Real, const C: usize>(x: &[R; C], g: &[R; C], inv: R, post: &mut [R; C]) {
    for ((o, &a), &b) in post.iter_mut().zip(x).zip(g) {
        *o = a * b * inv;
    }
}

/// The scaled rows of places `p` (see `prep_f32`): `x = α/max α`, or the one-hot row of
/// the place's label when it is `< C`. Out-of-range places give zero rows.
#[inline(always)]
pub fn gather<R: Real, const N: usize, const C: usize, const K: usize>(
    e: &[[R; C]; N],
    labels: &[u16; N],
    p: [usize; K],
) -> [[R; C]; K] {
    let mut x = [[R::ZERO; C]; K];
    for (xr, &q) in x.iter_mut().zip(&p) {
        let (Some(row), Some(&l)) = (e.get(q), labels.get(q)) else {
            continue;
        };
        if let Some(v) = xr.get_mut(usize::from(l)) {
            *v = R::ONE;
            continue;
        }
        let mut s = R::ZERO;
        for &v in row {
            if v > s {
                s = v;
            }
        }
        let inv = R::ONE / s;
        for (o, &v) in xr.iter_mut().zip(row) {
            *o = v * inv;
        }
    }
    x
}

/// `out[p[i]] += w·g[i]` for every component place `i`.
#[inline(always)]
pub fn scatter_post<R: Real, const N: usize, const C: usize, const K: usize>(
    out: &mut [[R; C]; N],
    w: R,
    g: &[[R; C]; K],
    p: [usize; K],
) {
    for (gr, &q) in g.iter().zip(&p) {
        if let Some(o) = out.get_mut(q) {
            axpy(o, w, gr);
        }
    }
}

/// `labels[p[i]] = lab[i]` for every component place `i`.
#[inline(always)]
pub fn scatter_labels<const N: usize, const K: usize>(
    labels: &mut [u16; N],
    lab: &[u16; K],
    p: [usize; K],
) {
    for (&l, &q) in lab.iter().zip(&p) {
        if let Some(o) = labels.get_mut(q) {
            *o = l;
        }
    }
}

/// Rows `off..off + K` of a scratch array (`None` when out of range).
#[inline(always)]
pub fn rows<T, const S: usize, const K: usize>(g: &[T; S], off: usize) -> Option<&[T; K]> {
    g.get(off..).and_then(|r| r.first_chunk::<K>())
}

/// Mutable rows `off..off + K` of a scratch array (`None` when out of range).
#[inline(always)]
pub fn rows_mut<T, const S: usize, const K: usize>(
    g: &mut [T; S],
    off: usize,
) -> Option<&mut [T; K]> {
    g.get_mut(off..).and_then(|r| r.first_chunk_mut::<K>())
}
