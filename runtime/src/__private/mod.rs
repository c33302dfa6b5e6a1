//! Helpers called only by code that `graphspn-compiler` generates. Not part of the
//! public API: names and signatures may change with any compiler release.
//!
//! Every helper is allocation-free, panic-free (no indexing with run-time
//! indices; iterators only) and exists in an `_f32` and an `_f64` flavour.

use crate::EvidenceError;

pub use crate::compiled::{fixed, fixed_mut};

/// Checks labels: each must be `< C` or `u16::MAX` (unknown). A bad label at place `p`
/// is reported as `LabelOutOfRange { place: p, label, classes: C }`.
pub fn check_labels<const N: usize>(
    labels: &[u16; N],
    classes: usize,
) -> Result<(), EvidenceError> {
    for (p, &l) in labels.iter().enumerate() {
        if l != u16::MAX && usize::from(l) >= classes {
            return Err(EvidenceError::LabelOutOfRange {
                place: p,
                label: l,
                classes,
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
        /// Validates evidence: every value finite and `≥ 0`, every row with some mass
        /// (with [`check_rows`], the check the streaming states use too).
        /// Errors name the place index and its id from `ids`.
        pub fn $check<const N: usize, const C: usize>(
            e: &[[$t; C]; N],
            ids: &[u32; N],
        ) -> Result<(), EvidenceError> {
            check_rows(e, ids)
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
// Dense region kernels: `lanes` (SIMD over groups of components: values, marginals,
// max-product values) and `blocks` (one component: MPE backtracking).
// ---------------------------------------------------------------------------

mod blocks;
mod engine;
mod fixed;
mod fusion;
mod lanes;
mod soft_float;
mod tree;

pub use blocks::*;
pub use engine::*;
pub use fixed::*;
pub use fusion::{Fused, fused_log_scale, ln_scale, ln_shift, shift_ln, shift_sum};
pub use lanes::*;
pub use soft_float::SoftF32;
pub use tree::*;

/// The scalar types of generated code (`f32`, `f64`).
pub trait Real:
    Copy
    + 'static
    + PartialOrd
    + core::fmt::Debug
    + core::ops::Add<Output = Self>
    + core::ops::Sub<Output = Self>
    + core::ops::Mul<Output = Self>
    + core::ops::AddAssign
    + core::ops::MulAssign
    + core::ops::Div<Output = Self>
{
    /// `0`.
    const ZERO: Self;
    /// `1`.
    const ONE: Self;
    /// `ln 2`.
    const LN_2: Self;
    /// `-inf`.
    const NEG_INFINITY: Self;
    /// `-(p + 8)·ln 2` for a `p`-bit significand: a weight below `e` to this power,
    /// relative to a weight of 1 in the same sum, is `2^-9` of the last bit of that sum
    /// (at least 1), so a mixture may drop it (see [`engine::mix`]).
    const NEGLIGIBLE_LN: Self;
    /// The value as an index (truncated; `0` for negative or NaN values).
    fn index(self) -> usize;
    /// An index as a value (exact below 2^24 for `f32`).
    fn from_index(i: usize) -> Self;
    /// An integer as a value (exact below 2^24 in magnitude for `f32`).
    fn from_i32(i: i32) -> Self;
    /// A 64-bit integer as a value (rounded to nearest).
    fn from_i64(i: i64) -> Self;
    /// Natural log (`ln 0 = -inf`).
    fn ln(self) -> Self;
    /// `e^x`.
    fn exp(self) -> Self;
    /// Neither NaN nor infinite.
    fn is_finite(self) -> bool;
    /// Whether every entry of `row` is finite and `≥ +0` and some entry `> 0`, from the
    /// bit patterns alone: the largest pattern as an unsigned integer lies strictly
    /// between `+0` and `+inf` (a set sign bit, an all-ones exponent or a row of zeros
    /// fails). One integer compare per entry, no float compare (none without an FPU,
    /// four instructions per entry with one on a Cortex-M4F). `-0.0` reads as not
    /// `≥ +0`.
    fn plain_row<const C: usize>(row: &[Self; C]) -> bool;
    /// The magnitude's bits as an integer (sign cleared): for values `≥ 0` (and
    /// `-0.0`), ordered as the values are, so the largest entry of an evidence row is
    /// found by integer compares (no soft-float call without an FPU).
    fn magnitude_key(self) -> u64;
    /// `(m, e)` with `self = m·2^e` exactly and `m` in `[1, 2)`; zero, infinite and NaN
    /// values are returned unchanged with `e = 0`, subnormals are normalised.
    fn split(self) -> (Self, i32);
    /// `(2^-e, e)` for a positive normal value `self` in `[2^e, 2^(e+1))` whose
    /// exponent lies in `MIN_EXP + 1 ..= -MIN_EXP` (both factors normal; exact): a few
    /// integer operations, no branch. Outside that domain (zero, subnormal, `≥ 2^127`
    /// in `f32`, infinite, NaN) the pair is meaningless; callers keep values inside.
    fn normal_scale(self) -> (Self, i32);
    /// Whether `self` lies in the domain of [`Real::normal_scale`] (one integer range
    /// check of the exponent bits; `false` for zero, subnormals, NaN, infinities and
    /// the top binade).
    fn scalable(self) -> bool;
    /// `2^e`, exact; `e` is clamped to the normal range (`-126..=127` for `f32`,
    /// `-1022..=1023` for `f64`).
    fn pow2(e: i32) -> Self;
    /// Two normal powers of two whose product is `2^e` (`2^(e/2)` and the rest), for
    /// `e` within twice the normal range (`-252..=254` for `f32`, `-2044..=2046` for
    /// `f64`; outside it the factors are meaningless): `x · a · b` scales by `2^e`
    /// where `2^e` alone would leave the normal range (a row whose largest entry is
    /// subnormal, or in the top binade). The one shared form of that exact two-step
    /// scale. Built from the bits without [`Real::pow2`]'s clamp: a caller's loop
    /// computes the pair once, ahead of the loop, and the clamp cost the no-FPU
    /// targets' tree calls 0.4–0.9% more instructions (measured).
    fn pow2_pair(e: i32) -> (Self, Self);
    /// Binary exponent of the smallest normal value (`-126` for `f32`, `-1022` for
    /// `f64`); also the tree-mixture driver's flush threshold on SIMD hosts (entries of
    /// a normalised row below `2^MIN_EXP` set to zero, as a CPU that flushes subnormals
    /// would; see `tree`).
    const MIN_EXP: i32;
    /// Binary exponent below which a GraphSPN state's fused evidence reads as 0 relative
    /// to the place's best class (`-24` for `f32`, `-200` for `f64`) when every template
    /// computes in linear space: a template multiplies up to five evidence entries, and
    /// five such factors stay in the normal range.
    const PRODUCT_FLUSH_EXP: i32;
}

macro_rules! real_impl {
    ($t:ident, $bits:ident, $mant:expr, $ebits:expr, $bias:expr, $emask:expr, $ln:path, $exp:path, $product:expr) => {
        impl Real for $t {
            const PRODUCT_FLUSH_EXP: i32 = $product;
            const MIN_EXP: i32 = 1 - $bias;
            #[inline(always)]
            fn pow2(e: i32) -> $t {
                let e = e.clamp(1 - $bias, $bias);
                $t::from_bits(((e + $bias) as $bits) << $mant)
            }
            #[inline(always)]
            fn pow2_pair(e: i32) -> ($t, $t) {
                let h = e / 2;
                let bits = |k: i32| $t::from_bits((k.wrapping_add($bias) as $bits) << $mant);
                (bits(h), bits(e.wrapping_sub(h)))
            }
            const ZERO: $t = 0.0;
            const ONE: $t = 1.0;
            const LN_2: $t = core::$t::consts::LN_2;
            const NEG_INFINITY: $t = $t::NEG_INFINITY;
            const NEGLIGIBLE_LN: $t = -(($mant + 9) as $t) * core::$t::consts::LN_2;
            #[inline(always)]
            fn index(self) -> usize {
                self as usize
            }
            #[inline(always)]
            fn from_index(i: usize) -> $t {
                i as $t
            }
            #[inline(always)]
            fn from_i32(i: i32) -> $t {
                i as $t
            }
            #[inline(always)]
            fn from_i64(i: i64) -> $t {
                i as $t
            }
            #[inline(always)]
            fn ln(self) -> $t {
                $ln(self)
            }
            #[inline(always)]
            fn exp(self) -> $t {
                $exp(self)
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                $t::is_finite(self)
            }
            #[inline(always)]
            fn plain_row<const C: usize>(row: &[$t; C]) -> bool {
                let inf = ($emask as $bits) << $mant;
                let top = row.iter().fold(0, |m: $bits, v| m.max(v.to_bits()));
                top.wrapping_sub(1) < inf - 1
            }
            #[inline(always)]
            fn magnitude_key(self) -> u64 {
                u64::from(self.to_bits() & !(1 << ($mant + $ebits)))
            }
            #[inline(always)]
            fn normal_scale(self) -> ($t, i32) {
                let ex = ((self.to_bits() >> $mant) & $emask) as i32;
                let scale = $t::from_bits(((2 * $bias - ex) as $bits) << $mant);
                (scale, ex - $bias)
            }
            #[inline(always)]
            fn scalable(self) -> bool {
                let ex = (self.to_bits() >> $mant) & $emask;
                (2..2 * $bias).contains(&ex)
            }
            #[inline(always)]
            fn split(self) -> ($t, i32) {
                let mut v = self;
                let mut shift = 0i32;
                let mut b = v.to_bits();
                let mut ex = ((b >> $mant) & $emask) as i32;
                if ex == 0 {
                    if v == 0.0 {
                        return (v, 0);
                    }
                    // Subnormal: scale into the normal range first (exact).
                    v *= 18446744073709551616.0; // 2^64
                    shift = -64;
                    b = v.to_bits();
                    ex = ((b >> $mant) & $emask) as i32;
                }
                if ex == $emask as i32 {
                    return (self, 0);
                }
                let m = $t::from_bits(
                    (b & !(($emask as $bits) << $mant)) | (($bias as $bits) << $mant),
                );
                (m, ex - $bias + shift)
            }
        }
    };
}

real_impl!(f32, u32, 23, 8, 127, 0xff, libm::logf, libm::expf, -24);
real_impl!(f64, u64, 52, 11, 1023, 0x7ff, libm::log, libm::exp, -200);

#[cfg(test)]
mod tests {
    use super::Real;

    /// Each factor of `pow2_pair(e)` is a normal power of two and their exponents add
    /// up to `e`, over twice the normal range of both types.
    fn pair_covers<T: Real>(range: core::ops::RangeInclusive<i32>) {
        for e in range {
            let (a, b) = T::pow2_pair(e);
            let ((ma, ea), (mb, eb)) = (a.split(), b.split());
            assert_eq!((ma, mb), (T::ONE, T::ONE), "2^{e}: {a:?} · {b:?}");
            let normal = |x: T| x.is_finite() && x >= T::pow2(T::MIN_EXP);
            assert!(normal(a) && normal(b), "2^{e}: {a:?} · {b:?}");
            assert_eq!(ea + eb, e, "2^{e}: {a:?} · {b:?}");
        }
    }

    #[test]
    fn pow2_pairs_are_exact_over_their_domain() {
        pair_covers::<f32>(-252..=254);
        pair_covers::<f64>(-2044..=2046);
    }
}
