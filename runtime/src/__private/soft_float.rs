//! [`SoftF32`]: an `f32` lane for targets without an FPU whose multiply, add, divide and
//! compares take integer fast paths for the values tree-mixture passes compute —
//! non-negative, finite, normal or zero — and give exactly the IEEE-754 results
//! (round to nearest, ties to even) of `f32` arithmetic. Every other operand (negative,
//! subnormal, infinite, NaN) and every result outside the normal range goes through
//! the target's `f32` operation (a soft-float call), so a `SoftF32` computation is
//! bit-identical to the same computation in `f32` on every input.
//!
//! Why: without an FPU every `f32` operation is a call into the compiler's soft-float
//! routines, which handle signs, subnormals, infinities and NaNs on every operation
//! (about 40–70 instructions on RV32IMAC); the fast paths here need a 32×32→64-bit
//! multiply or one alignment shift and a rounding step; division four 32-bit integer
//! divisions.

use core::ops::{Add, AddAssign, Div, Mul};

use super::Real;
use super::lanes::Lanes;
use super::tree::{max_message_bits, message_bits};

/// An `f32` whose arithmetic is done in integers where the operands allow it (see the
/// module docs); bit-identical to `f32` arithmetic.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[repr(transparent)]
pub struct SoftF32(pub f32);

/// Mantissa field of an `f32`.
const MANT: u32 = 0x007f_ffff;
/// The implicit leading bit of a normal `f32`'s significand.
const IMPLICIT: u32 = 0x0080_0000;
/// Bits of `+inf`: every finite non-negative `f32` has smaller bits.
const INF: u32 = 0x7f80_0000;

/// Whether the biased exponent field `e` (sign bit included above it) is that of a
/// positive normal value.
#[inline(always)]
fn normal(e: u32) -> bool {
    e.wrapping_sub(1) < 254
}

/// `m + up` (a 24-bit significand with its leading bit, rounded up or not) at biased
/// exponent `e`, when the result is a normal finite `f32` (a carry out of the
/// significand raises the exponent).
#[inline(always)]
fn pack(e: i32, m: u32, up: bool) -> Option<u32> {
    let bits = (((e - 1) as u32) << 23).wrapping_add(m + u32::from(up));
    (e >= 1 && bits < INF).then_some(bits)
}

/// The bits of `a · b` for non-negative finite operands with a normal (or zero)
/// result, rounded to nearest even; `None` otherwise.
#[inline(always)]
pub fn mul_bits(a: u32, b: u32) -> Option<u32> {
    let (ea, eb) = (a >> 23, b >> 23);
    if !normal(ea) || !normal(eb) {
        // A zero times a finite non-negative value is +0; the rest is not ours.
        return ((a == 0 && b < INF) || (b == 0 && a < INF)).then_some(0);
    }
    // Significands at the top of 32-bit words: the product lies in [2^62, 2^64).
    let p = u64::from((a & MANT | IMPLICIT) << 8) * u64::from((b & MANT | IMPLICIT) << 8);
    let (mut hi, mut lo) = ((p >> 32) as u32, p as u32);
    let top = hi >> 31;
    if top == 0 {
        hi = (hi << 1) | (lo >> 31);
        lo <<= 1;
    }
    // hi: 24 significand bits over 8 rounding bits; lo: what lies below.
    let (m, r) = (hi >> 8, hi & 0xff);
    let up = r > 0x80 || (r == 0x80 && (lo != 0 || m & 1 == 1));
    pack(ea as i32 + eb as i32 - 127 + top as i32, m, up)
}

/// The bits of `a + b` for non-negative finite operands, each normal or zero, with a
/// finite result, rounded to nearest even; `None` otherwise.
#[inline(always)]
pub fn add_bits(a: u32, b: u32) -> Option<u32> {
    // Non-negative values are ordered as their bits: `a` is the larger.
    let (a, b) = if a < b { (b, a) } else { (a, b) };
    let (ea, eb) = (a >> 23, b >> 23);
    if b == 0 {
        return (a < INF).then_some(a);
    }
    if !normal(ea) || !normal(eb) {
        return None;
    }
    let d = ea - eb;
    if d >= 25 {
        // `b` is below half an ulp of `a`.
        return Some(a);
    }
    // Significands over 7 rounding bits; `b` aligned to `a`, with a sticky bit for
    // what the shift drops.
    let mb = (b & MANT | IMPLICIT) << 7;
    let mut sticky = mb & ((1u32 << d) - 1) != 0;
    let mut s = ((a & MANT | IMPLICIT) << 7) + (mb >> d);
    let mut e = ea as i32;
    if s >> 31 != 0 {
        sticky |= s & 1 != 0;
        s >>= 1;
        e += 1;
    }
    let (m, r) = (s >> 7, s & 0x7f);
    let up = r > 0x40 || (r == 0x40 && (sticky || m & 1 == 1));
    pack(e, m, up)
}

/// The bits of `a / b` for non-negative finite normal operands (or `a = 0`) with a
/// normal (or zero) result, rounded to nearest even; `None` otherwise. Long division
/// of the significands in four 32-bit integer divisions (one instruction each on
/// RV32IM and Cortex-M3).
#[inline(always)]
pub fn div_bits(a: u32, b: u32) -> Option<u32> {
    let (ea, eb) = (a >> 23, b >> 23);
    if !normal(ea) || !normal(eb) {
        // Zero over a positive normal value is +0; the rest is not ours.
        return (a == 0 && normal(eb)).then_some(0);
    }
    let (mut ma, mb) = ((a & MANT) | IMPLICIT, (b & MANT) | IMPLICIT);
    let mut e = ea as i32 - eb as i32 + 127;
    if ma < mb {
        ma <<= 1;
        e -= 1;
    }
    // ma / mb in [1, 2): q = ⌊ma · 2^25 / mb⌋ in [2^25, 2^26), in chunks of 7, 8, 8
    // and 2 bits (every dividend below 2^32).
    let n = ma << 7;
    let (mut q, mut r) = (n / mb, n % mb);
    for bits in [8u32, 8, 2] {
        let n = r << bits;
        q = (q << bits) | (n / mb);
        r = n % mb;
    }
    // q: 24 significand bits over 2 rounding bits; r: what lies below (a quotient of
    // two 24-bit significands is never an exact tie, but the rule is written whole).
    let (m, g) = (q >> 2, q & 3);
    let up = g > 2 || (g == 2 && (r != 0 || m & 1 == 1));
    pack(e, m, up)
}

/// `2^e` for `-126 ≤ e ≤ 127` (a normal `f32`). `Real::pow2` clamps `e` first, which
/// costs 0.3–1% of a tree call on the no-FPU targets (measured) for a range these
/// callers never leave.
#[inline(always)]
fn pow2(e: i32) -> f32 {
    f32::from_bits(((e + 127) as u32) << 23)
}

/// `a > b` as `f32` compares it: an integer compare when both bit patterns are at most
/// `+inf`'s (non-negative, not NaN: their bits order them); negative and NaN operands,
/// whose bits lie above, go through the float compare. The sign test is implied by the
/// two bounds, but with it the firmware is 3 KB smaller on Cortex-M3 than with
/// `max(x, y) <= INF` alone (measured; the same instruction counts).
#[inline(always)]
fn greater(a: f32, b: f32) -> bool {
    let (x, y) = (a.to_bits(), b.to_bits());
    if (x | y) >> 31 == 0 && x <= INF && y <= INF {
        x > y
    } else {
        slow_greater(a, b)
    }
}

/// `a > b` by the target's float compare (see [`slow_mul`]).
#[cold]
#[inline(never)]
fn slow_greater(a: f32, b: f32) -> bool {
    a > b
}

/// `a · b` by the target's `f32` operation. Out of line and cold: inlined, the
/// compiler treats a float multiply as cheap and speculates it ahead of the fast
/// path's branch — a soft-float call on every operation.
#[cold]
#[inline(never)]
fn slow_mul(a: f32, b: f32) -> f32 {
    a * b
}

/// `a / b` by the target's `f32` operation (see [`slow_mul`]).
#[cold]
#[inline(never)]
fn slow_div(a: f32, b: f32) -> f32 {
    a / b
}

/// `a + b` by the target's `f32` operation (see [`slow_mul`]).
#[cold]
#[inline(never)]
fn slow_add(a: f32, b: f32) -> f32 {
    a + b
}

impl Mul for SoftF32 {
    type Output = SoftF32;
    #[inline(always)]
    fn mul(self, o: SoftF32) -> SoftF32 {
        match mul_bits(self.0.to_bits(), o.0.to_bits()) {
            Some(b) => SoftF32(f32::from_bits(b)),
            None => SoftF32(slow_mul(self.0, o.0)),
        }
    }
}

impl Add for SoftF32 {
    type Output = SoftF32;
    #[inline(always)]
    fn add(self, o: SoftF32) -> SoftF32 {
        match add_bits(self.0.to_bits(), o.0.to_bits()) {
            Some(b) => SoftF32(f32::from_bits(b)),
            None => SoftF32(slow_add(self.0, o.0)),
        }
    }
}

impl AddAssign for SoftF32 {
    #[inline(always)]
    fn add_assign(&mut self, o: SoftF32) {
        *self = *self + o;
    }
}

impl Div for SoftF32 {
    type Output = SoftF32;
    #[inline(always)]
    fn div(self, o: SoftF32) -> SoftF32 {
        match div_bits(self.0.to_bits(), o.0.to_bits()) {
            Some(b) => SoftF32(f32::from_bits(b)),
            None => SoftF32(slow_div(self.0, o.0)),
        }
    }
}

/// One `f32` per "vector", as the scalar `f32` lanes, with the integer fast paths.
impl Lanes for SoftF32 {
    type Scalar = f32;
    const ZERO: Self = SoftF32(0.0);
    const WIDTH: usize = 1;
    #[inline(always)]
    fn lanes(&self) -> &[f32] {
        core::slice::from_ref(&self.0)
    }
    #[inline(always)]
    fn flush(self, t: Self) -> Self {
        if greater(t.0, self.0) {
            Self::ZERO
        } else {
            self
        }
    }
    #[inline(always)]
    fn hmax(self) -> f32 {
        self.0
    }
    #[inline(always)]
    fn hsum(self) -> f32 {
        self.0
    }
    #[inline(always)]
    fn splat(s: f32) -> Self {
        SoftF32(s)
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        self * a + b
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        if greater(o.0, self.0) { o } else { self }
    }
    #[inline(always)]
    fn arg_max(best: &mut Self, arg: &mut Self, p: Self, code: Self) {
        if greater(p.0, best.0) {
            *best = p;
            *arg = code;
        }
    }
    #[inline(always)]
    fn lane(self, l: usize) -> f32 {
        if l == 0 { self.0 } else { 0.0 }
    }
    #[inline(always)]
    fn set_lane(&mut self, l: usize, v: f32) {
        if l == 0 {
            self.0 = v;
        }
    }
    #[inline(always)]
    fn from_lanes<const L: usize>(a: &[f32; L]) -> Self {
        SoftF32(a.first().copied().unwrap_or(0.0))
    }
    #[inline(always)]
    fn to_lanes<const L: usize>(self) -> [f32; L] {
        let mut b = [0.0; L];
        if let Some(o) = b.first_mut() {
            *o = self.0;
        }
        b
    }
    #[inline(never)]
    fn norm_by_max<const K: usize>(a: &mut [Self; K]) -> Option<i32> {
        // Non-negative values are ordered as their bits.
        let top = a.iter().fold(0u32, |m, x| m.max(x.0.to_bits()));
        if top == 0 {
            return Some(0);
        }
        let et = top >> 23;
        if !normal(et) || top >> 31 != 0 {
            return None;
        }
        let e = et as i32 - 127;
        for x in a.iter_mut() {
            let bits = x.0.to_bits();
            let ex = (bits >> 23) as i32;
            if ex >= 1 && ex - e >= 1 {
                // Normal, and stays normal: the exponent field alone changes (exact).
                *x = SoftF32(f32::from_bits(bits.wrapping_sub((e as u32) << 23)));
            } else if bits != 0 {
                // Zero-or-subnormal input or result: the soft-float multiply, in two
                // exact steps where `2^-e` alone is not a normal `f32`.
                *x = SoftF32(if e >= 127 {
                    let (a, b) = <f32 as Real>::pow2_pair(-e);
                    slow_mul(slow_mul(x.0, a), b)
                } else {
                    slow_mul(x.0, pow2(-e))
                });
            }
        }
        Some(e)
    }
    #[inline(never)]
    fn fixed_message<const C: usize, const K: usize>(
        psi: &[[u32; C]; C],
        b: &[Self; K],
    ) -> Option<([Self; K], i32)> {
        let (m, e) = message_bits(psi, &row_bits(b));
        Some((soft_row(&m), e))
    }
    #[inline(never)]
    fn fixed_max_message<const C: usize, const K: usize>(
        psi: &[[u32; C]; C],
        b: &[Self; K],
        arg: &mut [u8; C],
    ) -> Option<([Self; K], i32)> {
        let (m, e) = max_message_bits(psi, &row_bits(b), arg);
        Some((soft_row(&m), e))
    }
}

/// The bits of a row of `SoftF32` values, one class per lane (`K = C`).
#[inline(always)]
fn row_bits<const C: usize, const K: usize>(b: &[SoftF32; K]) -> [u32; C] {
    let mut bits = [0u32; C];
    for (o, x) in bits.iter_mut().zip(b) {
        *o = x.0.to_bits();
    }
    bits
}

/// A row of `f32` bits as `SoftF32` values (see [`row_bits`]).
#[inline(always)]
fn soft_row<const C: usize, const K: usize>(m: &[u32; C]) -> [SoftF32; K] {
    let mut out = [SoftF32(0.0); K];
    for (o, &x) in out.iter_mut().zip(m) {
        *o = SoftF32(f32::from_bits(x));
    }
    out
}

#[cfg(test)]
mod tests {
    use rand::{RngCore, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    /// A test operand: any bit pattern, or one near the patterns that matter (zero,
    /// the normal range's ends, ties, close exponents).
    fn operand(rng: &mut ChaCha8Rng, near: u32) -> u32 {
        let r = rng.next_u64();
        match r % 8 {
            0 => (r >> 32) as u32,
            1 => (r >> 8) as u32 & 0x7fff_ffff,
            2 => near.wrapping_add((r >> 40) as u32 % 64).wrapping_sub(32),
            3 => [0, 1, IMPLICIT, INF - 1, INF, 0x8000_0000, 0x7fc0_0000][(r >> 8) as usize % 7],
            4 => ((r >> 8) as u32 & MANT) | (((r >> 40) as u32 % 8 + 1) << 23),
            5 => ((r >> 8) as u32 & MANT) | ((250 + (r >> 40) as u32 % 5) << 23),
            _ => ((r >> 8) as u32 & 0x7fff_ffff) % INF,
        }
    }

    fn same(x: f32, y: f32) -> bool {
        x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan())
    }

    /// Every product, sum, quotient and compare equals `f32`'s, bit for bit, on 4 million
    /// operand pairs drawn around the fast paths' edges.
    #[test]
    fn arithmetic_is_bit_identical_to_f32() {
        let mut g = ChaCha8Rng::seed_from_u64(20261126);
        let (mut fast_mul, mut fast_add, mut fast_div) = (0, 0, 0);
        for i in 0..4_000_000u32 {
            let a = operand(&mut g, 0x3f80_0000);
            // The second operand near the first, or near a value a few binades off.
            let near = a.wrapping_add(((i % 29) << 23).wrapping_sub(14 << 23));
            let b = operand(&mut g, near);
            let (x, y) = (f32::from_bits(a), f32::from_bits(b));
            let (sx, sy) = (SoftF32(x), SoftF32(y));
            assert!(same((sx * sy).0, x * y), "{a:#x} * {b:#x}");
            assert!(same((sx + sy).0, x + y), "{a:#x} + {b:#x}");
            assert!(same((sx / sy).0, x / y), "{a:#x} / {b:#x}");
            assert_eq!(greater(x, y), x > y, "{a:#x} > {b:#x}");
            assert!(same(sx.max(sy).0, x.max_like(y)), "max {a:#x} {b:#x}");
            fast_mul += usize::from(mul_bits(a, b).is_some());
            fast_add += usize::from(add_bits(a, b).is_some());
            fast_div += usize::from(div_bits(a, b).is_some());
        }
        // The fast paths carry most of the pairs (the rest are other kinds of values).
        assert!(
            fast_mul > 1_000_000 && fast_add > 1_000_000 && fast_div > 1_000_000,
            "{fast_mul} {fast_add} {fast_div}"
        );
    }

    /// The fast paths answer everywhere their documentation says (a zero operand
    /// included: rows with exact zeros are common), not only where they are exact.
    #[test]
    fn fast_paths_answer_zero_operands() {
        for v in [1.0f32, 0.75, 3.0e-38, 1.0e38, f32::MAX] {
            let a = v.to_bits();
            assert_eq!(mul_bits(a, 0), Some(0), "{v} · 0");
            assert_eq!(mul_bits(0, a), Some(0), "0 · {v}");
            assert_eq!(add_bits(a, 0), Some(a), "{v} + 0");
            assert_eq!(add_bits(0, a), Some(a), "0 + {v}");
        }
        assert_eq!(add_bits(0, 0), Some(0));
        assert_eq!(mul_bits(0, 0), Some(0));
        // Infinite operands are not theirs.
        let inf = f32::INFINITY.to_bits();
        assert_eq!(mul_bits(inf, 0), None);
        assert_eq!(add_bits(inf, 0), None);
    }

    /// `SoftF32` is a lane vector of one lane, like the `f32` scalar: every lane
    /// operation of the trait, and `f32`'s order for negative operands too.
    #[test]
    fn soft_f32_is_one_scalar_lane() {
        let v = SoftF32(0.75);
        assert_eq!(v.lane(0), 0.75);
        assert_eq!(v.lane(1), 0.0);
        let mut w = v;
        w.set_lane(0, 0.5);
        w.set_lane(1, 9.0);
        assert_eq!(w.0, 0.5);
        assert_eq!(v.to_lanes::<3>(), [0.75, 0.0, 0.0]);
        assert_eq!(SoftF32::from_lanes(&[0.25f32, 7.0]).0, 0.25);
        assert_eq!(v.flush(SoftF32(1.0)).0, 0.0, "below the threshold");
        assert_eq!(v.flush(SoftF32(0.75)).0, 0.75, "at the threshold");
        assert_eq!(v.mul_add(SoftF32(2.0), SoftF32(0.25)).0, 1.75);
        assert_eq!((v.hmax(), v.hsum()), (0.75, 0.75));
        for (a, b) in [
            (-1.0f32, -2.0),
            (-2.0, -1.0),
            (-1.0, 1.0),
            (1.0, -1.0),
            (-0.0, 0.0),
        ] {
            assert_eq!(greater(a, b), a > b, "{a} > {b}");
        }
    }

    /// The scalar `f32` lanes' `max`: `o` where `o > self`.
    trait MaxLike {
        fn max_like(self, o: Self) -> Self;
    }

    impl MaxLike for f32 {
        fn max_like(self, o: f32) -> f32 {
            if o > self { o } else { self }
        }
    }

    /// `norm_by_max` against `f64`: the row is scaled by exactly `2^-e` (zeros stay
    /// zero, subnormal inputs and results included) and its largest entry lies in
    /// `[1, 2)`.
    #[test]
    fn norm_by_max_scales_exactly() {
        let mut g = ChaCha8Rng::seed_from_u64(20261127);
        for case in 0..200_000u32 {
            let top = 1 + (g.next_u32() % 254);
            let mut row = [SoftF32(0.0); 7];
            for x in row.iter_mut() {
                let r = g.next_u32();
                let e = match r % 4 {
                    0 => 0,
                    1 => top,
                    _ => top.saturating_sub(r >> 24).max(u32::from(r & 16 != 0)),
                };
                let bits = if r % 7 == 0 {
                    0
                } else {
                    (e << 23) | (g.next_u32() & MANT)
                };
                *x = SoftF32(f32::from_bits(bits));
            }
            row[case as usize % 7] = SoftF32(f32::from_bits((top << 23) | (g.next_u32() & MANT)));
            let before = row.map(|x| f64::from(x.0));
            let e = SoftF32::norm_by_max(&mut row).expect("a normal largest entry");
            let largest = row.iter().map(|x| x.0).fold(0.0, f32::max);
            assert!(
                (1.0..2.0).contains(&largest),
                "case {case}: largest {largest}"
            );
            for (a, b) in before.iter().zip(&row) {
                let want = a * 2f64.powi(-e);
                // Exact unless the result is subnormal (one rounding there).
                let tol = if want < f64::from(f32::MIN_POSITIVE) {
                    2f64.powi(-150)
                } else {
                    0.0
                };
                assert!(
                    (f64::from(b.0) - want).abs() <= tol,
                    "case {case}: {a:e} · 2^{} = {:e}",
                    -e,
                    b.0
                );
            }
        }
        let mut zeros = [SoftF32(0.0); 3];
        assert_eq!(SoftF32::norm_by_max(&mut zeros), Some(0));
        // A subnormal or infinite largest entry is left to the float path.
        for top in [f32::MIN_POSITIVE / 4.0, f32::INFINITY] {
            let mut row = [SoftF32(0.0), SoftF32(top)];
            assert_eq!(SoftF32::norm_by_max(&mut row), None, "{top:e}");
        }
    }

    /// `SoftF32`'s fixed-point message is `message_bits` on its rows' bits: within the
    /// bound of `f64`'s `ψ·b`, normalised; its max-product message is
    /// `max_message_bits`'s.
    #[test]
    fn fixed_messages_of_soft_rows() {
        use super::super::tree::message_error;
        const C: usize = 4;
        let psi: [[u32; C]; C] = [
            [u32::MAX, 1 << 31, 1 << 30, 1 << 29],
            [1 << 28, u32::MAX, 1 << 31, 1 << 30],
            [1 << 30, 1 << 29, u32::MAX, 1 << 31],
            [1 << 31, 1 << 30, 1 << 29, u32::MAX],
        ];
        let eta = message_error(C, 2f64.powi(-4));
        let mut g = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..1000 {
            let b = [(); C].map(|_| SoftF32((g.next_u32() >> 8) as f32 * 2f32.powi(-30)));
            let (m, e) = SoftF32::fixed_message(&psi, &b).expect("SoftF32 has the path");
            let mut sum = 0.0;
            for (row, x) in psi.iter().zip(&m) {
                let want: f64 = row
                    .iter()
                    .zip(&b)
                    .map(|(&p, y)| f64::from(p) / 2f64.powi(32) * f64::from(y.0))
                    .sum();
                let got = f64::from(x.0) * 2f64.powi(e);
                assert!((got - want).abs() <= eta * want, "{got:e} vs {want:e}");
                sum += f64::from(x.0);
            }
            assert!((1.0 - 1e-6..2.0 + 1e-6).contains(&sum), "sum {sum}");
            let mut arg = [u8::MAX; C];
            let (m, e) = SoftF32::fixed_max_message(&psi, &b, &mut arg).expect("the max path");
            let mut want_arg = [0u8; C];
            let want = max_message_bits(&psi, &b.map(|x| x.0.to_bits()), &mut want_arg);
            assert_eq!(
                (m.map(|x| x.0.to_bits()), e, arg),
                (want.0, want.1, want_arg)
            );
        }
    }

    /// Ties to even, carries out of the significand and the normal range's edges.
    #[test]
    fn rounding_edges() {
        let one = 1.0f32;
        let ulp = f32::EPSILON;
        for (a, b) in [
            (one, ulp / 2.0),             // a tie, rounds to even (down)
            (one + ulp, ulp / 2.0),       // a tie, rounds to even (up)
            (one, ulp / 2.0 + ulp / 4.0), // above the tie
            (f32::MAX, f32::MAX),         // overflow: the soft-float path
            (f32::MIN_POSITIVE, 0.5),     // subnormal product
            (2.0 - ulp, 2.0 - ulp),       // significand carry
            (1.5, 1.5),
            (0.0, f32::MAX),
        ] {
            let (sa, sb) = (SoftF32(a), SoftF32(b));
            assert_eq!((sa + sb).0.to_bits(), (a + b).to_bits(), "{a:e} + {b:e}");
            assert_eq!((sa * sb).0.to_bits(), (a * b).to_bits(), "{a:e} * {b:e}");
            if b != 0.0 {
                assert_eq!((sa / sb).0.to_bits(), (a / b).to_bits(), "{a:e} / {b:e}");
            }
        }
    }
}
