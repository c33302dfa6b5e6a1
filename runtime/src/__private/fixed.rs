//! The fixed-point kernel for targets without a floating-point unit (RV32IMAC,
//! Cortex-M0+/M3): template values and adjoints in unsigned Q0.32, `v / 2^32`.
//!
//! # Why Q0.32 holds every value
//!
//! A linear-space template (normalised weights, evidence rows scaled to a largest
//! entry of 1) is a multilinear polynomial with non-negative coefficients, so every
//! node value and every adjoint `∂T/∂node` is at most its value with every evidence
//! entry at 1, which is `≤ 1` (see `graphspn-compiler`'s `codegen::fixed` module for
//! the argument and the few intermediates — sums of a vector, floor products — that
//! need integer bits and are kept shifted). Entries are truncated to Q0.32 (1.0 becomes
//! `2^32 − 1`), weights are rounded down, and every product keeps the high word of the
//! 64-bit product (`mulhu` on RISC-V, `umull` on Arm): each operation rounds *down*,
//! so a computed value never exceeds the exact one and no sum overflows. Sums wrap
//! (`wrapping_add`) only in the sense of not checking: the bound above excludes it.
//!
//! # Error bound
//!
//! Each truncation loses less than `2^-32`, and its sensitivity (the adjoint of the
//! value it rounds) is `≤ 1`, so the root's absolute error is below `E·2^-32`, where
//! the generator counts `E` per template function. The wrappers here return the
//! fixed-point result only when the root is at least `min` (the generator's
//! `E·2^(k−32)`, a relative error `≤ 2^-k`), and otherwise evaluate the template's
//! `f32` functions: small values, where the absolute error would matter, are never
//! answered by the integer kernel.

use core::ops::{Add, AddAssign, Mul};

/// An unsigned Q0.32 fixed-point value `self.0 / 2^32` (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
#[repr(transparent)]
pub struct Fx(pub u32);

impl Fx {
    /// `0`.
    pub const ZERO: Fx = Fx(0);
    /// `1 − 2^-32`, the largest value (stands for 1: the product of a value and `ONE`
    /// rounds down by less than `2^-32`).
    pub const ONE: Fx = Fx(u32::MAX);

    /// The value itself (the generated code's spelling of a constant).
    #[inline(always)]
    pub fn splat(v: Fx) -> Fx {
        v
    }

    /// `Σ_i v_i · 2^-s`: the sum of a vector kept with `s` integer bits (the generator
    /// picks `s` with `2^s ≥` the vector's length, so it cannot overflow).
    #[inline(always)]
    pub fn sum_shr<const K: usize>(v: &[Fx; K], s: u32) -> Fx {
        let mut acc = 0u32;
        for x in v {
            acc = acc.wrapping_add(x.0 >> s);
        }
        Fx(acc)
    }

    /// The largest entry (`0` for an empty array).
    #[inline(always)]
    pub fn max_of<const K: usize>(v: &[Fx; K]) -> Fx {
        let mut m = 0u32;
        for x in v {
            m = m.max(x.0);
        }
        Fx(m)
    }

    /// `self · 2^s` (the generator shifts only values whose exact result is `< 1`).
    #[inline(always)]
    pub fn times_pow2(self, s: u32) -> Fx {
        Fx(self.0 << s)
    }

    /// `self · 2^-s`, rounded down (a value the generator kept scaled by `2^s`).
    #[inline(always)]
    pub fn div_pow2(self, s: u32) -> Fx {
        Fx(self.0 >> s)
    }
}

impl Mul for Fx {
    type Output = Fx;
    /// The product, rounded down (the high word of the 64-bit product).
    #[inline(always)]
    fn mul(self, o: Fx) -> Fx {
        Fx(((u64::from(self.0) * u64::from(o.0)) >> 32) as u32)
    }
}

impl Add for Fx {
    type Output = Fx;
    /// The sum (the generator's bounds keep it below `2^32`).
    #[inline(always)]
    fn add(self, o: Fx) -> Fx {
        Fx(self.0.wrapping_add(o.0))
    }
}

impl AddAssign for Fx {
    #[inline(always)]
    fn add_assign(&mut self, o: Fx) {
        *self = *self + o;
    }
}

/// The lane operations generated fixed-point code calls as `Lanes::mul_add` and
/// `Lanes::max` (the same spelling as the float kernels).
pub trait FxLanes {
    /// `self·a + b`, the product rounded down.
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// The larger value.
    fn max(self, o: Self) -> Self;
}

impl FxLanes for Fx {
    #[inline(always)]
    fn mul_add(self, a: Fx, b: Fx) -> Fx {
        self * a + b
    }
    #[inline(always)]
    fn max(self, o: Fx) -> Fx {
        Fx(self.0.max(o.0))
    }
}

/// `v` in `[0, 1]` as Q0.32, rounded down (`1.0` and above give [`Fx::ONE`], values
/// below `2^-32`, `-0.0` and other negative or NaN inputs of unchecked evidence give 0
/// or `ONE`, never a panic). Integer operations only: no soft-float call.
#[inline(always)]
pub fn fx_from_f32(v: f32) -> Fx {
    let b = v.to_bits();
    if b >> 31 != 0 {
        return Fx::ZERO;
    }
    // v = m · 2^(e − 150) with the implicit bit, so v · 2^32 = m · 2^(e − 118).
    let e = (b >> 23) as i32;
    let m = (b & 0x7f_ffff) | 0x80_0000;
    let s = e - 118;
    if s >= 9 {
        Fx::ONE
    } else if s >= 0 {
        Fx(m << s)
    } else if s > -24 {
        Fx(m >> -s)
    } else {
        Fx::ZERO
    }
}

/// The value of `v` as `f32` (one rounding).
#[inline(always)]
pub fn fx_to_f32(v: Fx) -> f32 {
    v.0 as f32 * (1.0 / 4_294_967_296.0)
}

/// The scaled rows of a component (`[0, 1]`, largest entry 1) as Q0.32.
#[inline(always)]
pub fn fx_rows<const C: usize, const NV: usize>(x: &[[f32; C]; NV]) -> [[Fx; C]; NV] {
    let mut q = [[Fx::ZERO; C]; NV];
    for (qr, xr) in q.iter_mut().zip(x) {
        for (o, &v) in qr.iter_mut().zip(xr) {
            *o = fx_from_f32(v);
        }
    }
    q
}

/// A template's value on scaled rows `x` by its fixed-point function `fx`, or by its
/// `f32` function `fl` when the fixed-point value is below `min` (see the module
/// docs: the result then has relative error `≤ 2^-k` or is the `f32` one).
#[inline(always)]
pub fn fx_fwd<const C: usize, const NV: usize>(
    x: &[[f32; C]; NV],
    min: u32,
    fx: impl FnOnce(&[[Fx; C]; NV]) -> Fx,
    fl: impl FnOnce(&[[f32; C]; NV]) -> f32,
) -> f32 {
    let v = fx(&fx_rows(x));
    #[cfg(feature = "fallback-counts")]
    crate::fallback_counts::count_value(v.0 < min);
    if v.0 >= min { fx_to_f32(v) } else { fl(x) }
}

/// A template's value and local posteriors `post[i][c] = x_i[c]·∂T/∂x_i[c] / T` by its
/// fixed-point function `fx` (which returns the value and writes the adjoints), or by
/// its `f32` function `fl` when the value is below `min`.
#[inline(always)]
pub fn fx_post<const C: usize, const NV: usize>(
    x: &[[f32; C]; NV],
    post: &mut [[f32; C]; NV],
    min: u32,
    fx: impl FnOnce(&[[Fx; C]; NV], &mut [[Fx; C]; NV]) -> Fx,
    fl: impl FnOnce(&[[f32; C]; NV], &mut [[f32; C]; NV]) -> f32,
) -> f32 {
    let q = fx_rows(x);
    let mut g = [[Fx::ZERO; C]; NV];
    let v = fx(&q, &mut g);
    #[cfg(feature = "fallback-counts")]
    crate::fallback_counts::count_posterior(v.0 < min);
    if v.0 < min {
        return fl(x, post);
    }
    let ratio = Ratio::new(v);
    for ((pr, qr), gr) in post.iter_mut().zip(&q).zip(&g) {
        for ((o, &a), &b) in pr.iter_mut().zip(qr).zip(gr) {
            *o = ratio.of(a * b);
        }
    }
    fx_to_f32(v)
}

/// Division by a fixed Q0.32 value `v > 0` in integer operations (no soft-float
/// call): `v` normalised to `[2^31, 2^32)` by a shift `s`, and `2^63 / (v·2^s)`
/// computed once.
struct Ratio {
    /// The normalising shift.
    s: u32,
    /// `v` itself.
    v: u32,
    /// `⌊2^63 / vn⌋`, at most `2^32 − 1`.
    r: u32,
}

impl Ratio {
    #[inline(always)]
    fn new(v: Fx) -> Ratio {
        let v = v.0.max(1);
        let s = v.leading_zeros();
        // `v << s ≥ 2^31`: the division never fails (checked: no panic path).
        let r = (1u64 << 63)
            .checked_div(u64::from(v << s))
            .map_or(u32::MAX, |r| r.min(u64::from(u32::MAX)) as u32);
        Ratio { s, v, r }
    }

    /// `min(p, v) / v` as `f32`, rounded down (error below `2^-22` of it plus
    /// `2^-30`).
    #[inline(always)]
    fn of(&self, p: Fx) -> f32 {
        // min(p, v)·2^s < 2^32, and q = ⌊p·2^s·r / 2^32⌋ ≈ (p / v)·2^31 ≤ 2^31.
        let pn = p.0.min(self.v) << self.s;
        let q = ((u64::from(pn) * u64::from(self.r)) >> 32) as u32;
        if q == 0 {
            return 0.0;
        }
        // q = 1.m · 2^(31 − z): the value q·2^-31 has exponent −z.
        let z = q.leading_zeros();
        let mantissa = ((q << z) << 1) >> 9;
        f32::from_bits(((127 - z) << 23) | mantissa)
    }
}

/// The decomposition weights of a streaming state as unsigned Q1.31 (`v / 2^31`),
/// rounded down: what [`state_marginals_fx`] multiplies by.
#[inline]
pub fn fx_weights<const D: usize>(w: &[f32; D]) -> [u32; D] {
    let mut q = [0u32; D];
    for (o, &v) in q.iter_mut().zip(w) {
        *o = fx_from_f32(v).0 >> 1;
    }
    q
}

/// The streaming state's marginals without an FPU: adds every cached component's local
/// posteriors, weighted by the sum of its decompositions' weights `wq` (Q1.31, see
/// [`fx_weights`]), into `out` as Q1.31 integers held in the `f32` bits (integer
/// multiply-adds: a `SoftF32` multiply and add cost about 85 instructions). Call with
/// `out` zeroed and finish with [`fx_finish_rows`]. Each term rounds down by less than
/// `2^-31` after its inputs lost less than `2^-32` each, so an entry is within `3·D·2^-31`
/// (absolute, `D` decompositions) of the float sum; sums stay below 2 (weights and
/// posteriors are at most `1` up to float rounding), so nothing overflows.
#[inline(never)]
pub fn state_marginals_fx<
    W: super::Lanes<Scalar = f32>,
    const L: usize,
    const NV: usize,
    const C: usize,
    const N: usize,
    const D: usize,
>(
    t: &super::Tpl<W, L, NV, C>,
    post: &[[f32; C]],
    wq: &[u32; D],
    out: &mut [[f32; C]; N],
) {
    super::engine::cached_scatter(t, post, |mask| fx_weight_of(wq, mask), fx_add_term, out);
}

/// The stateless `marginals`' posterior pass without an FPU: like
/// [`super::posterior_pass`], but each component's local posteriors are added, weighted
/// by the sum of its decompositions' weights `wq` (Q1.31, see [`fx_weights`]), into `out`
/// as Q1.31 integers held in the `f32` bits, as [`state_marginals_fx`] does (same
/// bound: within `3·D·2^-31` absolute of the float sum). Call with `out` zeroed and
/// finish with [`fx_finish_rows`].
#[inline(never)]
pub fn posterior_pass_fx<
    W: super::Lanes<Scalar = f32>,
    const L: usize,
    const NV: usize,
    const C: usize,
    const N: usize,
    const D: usize,
>(
    t: &super::Tpl<W, L, NV, C>,
    e: &[[f32; C]; N],
    table: Option<&[[f32; C]; N]>,
    wq: &[u32; D],
    out: &mut [[f32; C]; N],
) {
    super::engine::posterior_scatter(t, e, table, |mask| fx_weight_of(wq, mask), fx_add_term, out);
}

/// The Q1.31 weight of a component in the decompositions of `mask`: at most
/// `2^31·(1 + ε)`, the weights summing to 1 up to rounding.
#[inline(always)]
fn fx_weight_of<const D: usize>(wq: &[u32; D], mask: u64) -> u64 {
    u64::from(super::engine::masked_sum(wq, mask, 0u32))
}

/// Adds `wu·p` (Q1.31 weight, posterior `p` as Q0.32, the high word of the product)
/// to the Q1.31 sum held in `o`'s bits.
#[inline(always)]
fn fx_add_term(o: &mut f32, wu: u64, p: f32) {
    let term = ((u64::from(fx_from_f32(p).0) * wu) >> 32) as u32;
    *o = f32::from_bits(o.to_bits().wrapping_add(term));
}

/// Turns the Q1.31 sums [`state_marginals_fx`] left in `out`'s bits into `f32` values
/// (rounded down; integer operations only).
#[inline(never)]
pub fn fx_finish_rows<const C: usize, const N: usize>(out: &mut [[f32; C]; N]) {
    for o in out.iter_mut().flatten() {
        *o = q31_to_f32(o.to_bits());
    }
}

/// `v / 2^31` as `f32`, truncated (no soft-float call).
#[inline(always)]
fn q31_to_f32(v: u32) -> f32 {
    if v == 0 {
        return 0.0;
    }
    let lz = v.leading_zeros();
    // `v << lz` lies in [2^31, 2^32): the value is `(v << lz) / 2^31 · 2^-lz`.
    let m = (v << lz) >> 8 & 0x7f_ffff;
    f32::from_bits((127 - lz) << 23 | m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn q31_values_convert_to_f32_exactly_where_they_fit() {
        assert_eq!(q31_to_f32(0), 0.0);
        assert_eq!(q31_to_f32(1 << 31), 1.0);
        assert_eq!(q31_to_f32(1 << 30), 0.5);
        assert_eq!(q31_to_f32(3 << 30), 1.5);
        assert_eq!(q31_to_f32(u32::MAX), f32::from_bits(0x3fff_ffff));
        assert_eq!(q31_to_f32(1), 2f32.powi(-31));
        let mut x = 3u32;
        for _ in 0..100_000 {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let exact = f64::from(x) / f64::from(1u32 << 31);
            let got = f64::from(q31_to_f32(x));
            assert!(
                got <= exact && exact - got < exact * f64::from(f32::EPSILON),
                "{x}"
            );
        }
    }

    /// The fixed-point mix of a state against the float one, within its bound.
    #[test]
    fn fixed_point_state_marginals_are_within_their_bound() {
        use super::super::Tpl;
        fn unused_fwd(_: &[[f32; 3]; 2]) -> f32 {
            0.0
        }
        fn unused_post(_: &[[f32; 3]; 2], _: &mut [[f32; 3]; 2]) -> f32 {
            0.0
        }
        fn unused_mpe(_: &[[f32; 3]; 2], _: &mut [[u16; 2]; 1]) -> f32 {
            0.0
        }
        // Three 2-place components over 3 places and 3 decompositions: (0, 1) in
        // decompositions 0 and 1, (1, 2) in 2, (2, 0) in 0.
        static PLACES: [[[u16; 2]; 1]; 3] = [[[0, 1]], [[1, 2]], [[2, 0]]];
        static DECS: [u64; 3] = [0b011, 0b100, 0b001];
        let t: Tpl<f32, 1, 2, 3> = Tpl {
            places: &PLACES,
            decs: &DECS,
            log: false,
            fwd: unused_fwd,
            post: unused_post,
            max: unused_fwd,
            mpe: unused_mpe,
        };
        let mut x = 9u32;
        for _ in 0..1_000 {
            let mut post = [[0.0f32; 3]; 6];
            for row in post.iter_mut() {
                let mut s = 0.0;
                for v in row.iter_mut() {
                    x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    *v = (x >> 8) as f32 / 16_777_216.0;
                    s += *v;
                }
                for v in row.iter_mut() {
                    *v /= s;
                }
            }
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let a = (x >> 8) as f32 / 16_777_216.0;
            let w = [a * 0.5, 0.5 - a * 0.5, 0.5];
            let mut want = [[0.0f32; 3]; 3];
            super::super::state_marginals(&t, &post, &w, &mut want);
            let mut got = [[0.0f32; 3]; 3];
            state_marginals_fx(&t, &post, &fx_weights(&w), &mut got);
            fx_finish_rows(&mut got);
            for (g, w) in got.iter().flatten().zip(want.iter().flatten()) {
                let bound = 3.0 * 3.0 * 2f32.powi(-31) + 2.0 * f32::EPSILON * w;
                assert!((g - w).abs() <= bound, "{g} vs {w}");
            }
        }
    }

    #[test]
    fn conversion_rounds_down_and_saturates() {
        assert_eq!(fx_from_f32(1.0), Fx::ONE);
        assert_eq!(fx_from_f32(2.0), Fx::ONE);
        assert_eq!(fx_from_f32(f32::INFINITY), Fx::ONE);
        assert_eq!(fx_from_f32(0.5), Fx(1 << 31));
        assert_eq!(fx_from_f32(0.0), Fx::ZERO);
        assert_eq!(fx_from_f32(-0.0), Fx::ZERO);
        assert_eq!(fx_from_f32(-1.0), Fx::ZERO);
        assert_eq!(fx_from_f32(1e-12), Fx(0));
        assert_eq!(fx_from_f32(f32::MIN_POSITIVE), Fx::ZERO);
        for &v in &[0.3f32, 1e-3, 0.999_999_9, 2.5e-10, 7.1e-5] {
            let want = (f64::from(v) * 4_294_967_296.0).floor();
            assert_eq!(f64::from(fx_from_f32(v).0), want, "{v:e}");
        }
        assert_eq!(fx_to_f32(Fx(1 << 30)), 0.25);
    }

    #[test]
    fn ratios_match_float_division() {
        for &v in &[1u32, 7, 1 << 20, 3_000_000_000, u32::MAX, 1 << 31] {
            let ratio = Ratio::new(Fx(v));
            for &p in &[0u32, 1, v / 3, v / 2, v - v / 7, v, v.saturating_add(5)] {
                let want = f64::from(p.min(v)) / f64::from(v);
                let got = f64::from(ratio.of(Fx(p)));
                assert!(
                    got <= want * (1.0 + 1e-12)
                        && want - got <= want * 2f64.powi(-22) + 2f64.powi(-30),
                    "{p} / {v}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn products_round_down() {
        let (a, b) = (Fx(3_000_000_000), Fx(4_000_000_000));
        let exact = 3e9 * 4e9 / 4_294_967_296.0;
        assert_eq!(f64::from((a * b).0), f64::floor(exact));
        assert_eq!(Fx::ONE * Fx::ONE, Fx(u32::MAX - 1));
        assert_eq!(Fx::mul_add(a, Fx::ONE, Fx(5)), Fx(3_000_000_000 - 1 + 5));
        assert_eq!(Fx::sum_shr(&[Fx::ONE; 10], 4).0, 10 * (u32::MAX >> 4));
        assert_eq!(Fx::max_of(&[Fx(3), Fx(9), Fx(1)]), Fx(9));
        assert_eq!(Fx(3).times_pow2(2), Fx(12));
    }

    #[test]
    fn lane_operations_are_the_documented_ones() {
        let (a, b, c) = (Fx(3_000_000_000), Fx(1 << 31), Fx(7));
        assert_eq!(Fx::splat(a), a);
        let mut s = c;
        s += Fx(5);
        assert_eq!(s, Fx(12));
        assert_eq!(FxLanes::mul_add(a, b, c), Fx(1_500_000_000 + 7));
        assert_eq!(FxLanes::max(c, a), a);
        assert_eq!(FxLanes::max(a, c), a);
        let rows = fx_rows(&[[1.0f32, 0.5, 0.0], [0.25, 2.0, 1e-12]]);
        assert_eq!(
            rows,
            [
                [Fx::ONE, Fx(1 << 31), Fx::ZERO],
                [Fx(1 << 30), Fx::ONE, Fx::ZERO]
            ]
        );
    }

    /// A one-row "template" `T = Σ_c w_c x_c` with its adjoints `w_c`, in both
    /// arithmetics, for the wrappers' tests.
    const W: [f32; 2] = [0.25, 0.75];

    fn fx_value(x: &[[Fx; 2]; 1]) -> Fx {
        Fx(1 << 30) * x[0][0] + Fx(3 << 30) * x[0][1]
    }

    fn fl_value(x: &[[f32; 2]; 1]) -> f32 {
        W[0] * x[0][0] + W[1] * x[0][1]
    }

    #[test]
    fn value_wrapper_keeps_the_fixed_point_result_at_or_above_its_threshold() {
        let x = [[1.0f32, 0.5]];
        // T = 0.625 exactly in both arithmetics: 0.625 · 2^32 = 2,684,354,560.
        let v = fx_value(&fx_rows(&x)).0;
        assert_eq!(v, 2_684_354_559);
        let marked = |_: &[[f32; 2]; 1]| -1.0f32;
        assert_eq!(fx_fwd(&x, v, fx_value, marked), fx_to_f32(Fx(v)));
        assert_eq!(fx_fwd(&x, v + 1, fx_value, marked), -1.0);
        assert_eq!(fx_fwd(&x, v + 1, fx_value, fl_value), 0.625);
    }

    #[test]
    fn posterior_wrapper_divides_by_the_value_or_falls_back() {
        let x = [[1.0f32, 0.5]];
        let fx = |q: &[[Fx; 2]; 1], g: &mut [[Fx; 2]; 1]| {
            g[0] = [Fx(1 << 30), Fx(3 << 30)];
            fx_value(q)
        };
        let fl = |x: &[[f32; 2]; 1], post: &mut [[f32; 2]; 1]| {
            let v = fl_value(x);
            post[0] = [W[0] * x[0][0] / v, W[1] * x[0][1] / v];
            -v
        };
        let v = fx_value(&fx_rows(&x)).0;
        let mut post = [[9.0f32; 2]];
        let got = fx_post(&x, &mut post, v, fx, fl);
        assert_eq!(got, fx_to_f32(Fx(v)));
        // Local posteriors 0.4 and 0.6, from integers: within 2^-22 relative, below.
        for (&p, want) in post[0].iter().zip([0.4f64, 0.6]) {
            let p = f64::from(p);
            assert!(
                p <= want && want - p <= want * 2f64.powi(-21),
                "{p} vs {want}"
            );
        }
        let mut post = [[9.0f32; 2]];
        assert_eq!(fx_post(&x, &mut post, v + 1, fx, fl), -0.625);
        assert_eq!(post, [[0.4, 0.6]]);
    }
}
