//! Fixed-point messages for tree modules on targets without an FPU: `ψ·b` as `C²`
//! integer multiply-adds instead of `C²` soft-float multiplies and adds (most of a
//! pass's work there; 80–90 instructions each on a Cortex-M3).
//!
//! The matrices are unsigned Q0.32 (`round(ψ · 2^32)`, at most `2^32 − 1`; the
//! generator rounds them once from the model's exact values). A row `b` of
//! non-negative finite `f32` values enters as Q0.32 relative to its largest exponent:
//! every entry's 24-bit significand shifted to that exponent (entries more than 32
//! binades below the largest keep at most one unit). Every product keeps the high word
//! of its 64-bit product (`mulhu` on RISC-V, `umull` on Arm) and is summed in 64 bits,
//! so no sum overflows. The message comes out normalised like every other row (its
//! entries' exact sum in `[1, 2)`), each entry rounded once to `f32` (half up).
//!
//! # Error bound (per message entry, relative)
//!
//! With `u = 2^-31 · max b` (the unit of the shifted row: the largest entry's
//! significand has its top bit at bit 31, so `u ≤ 2^-31 max b` when that entry is
//! normal, as every row the passes send is: see the module docs of `tree`) and
//! `ψ_min` the smallest matrix entry (largest entry `≤ 1`):
//!
//! - truncating `b(j)` to the unit loses `< u` per entry, `Σ_j ψ(a, j)·u ≤ C·u` in all;
//! - each high word truncates `< u`: `C·u` in all;
//! - rounding `ψ` to Q0.32 changes each entry by at most `2^-33`, i.e. by `2^-33/ψ_min`
//!   of itself;
//! - the result's rounding to `f32`: `2^-24` of itself.
//!
//! As `m(a) ≥ ψ(a, j*)·max b ≥ ψ_min · max b` (`j*` the largest entry of `b`), every
//! entry of the message is within `η = 2^-24 + (2C + 1/4)·2^-31/ψ_min` of
//! `Σ_j ψ(a, j) b(j)` relatively ([`message_error`]; the generator computes it for the
//! model and uses these messages only where it is at most [`MAX_MESSAGE_ERROR`]).
//! Every other operation of the passes is the `f32` one (`SoftF32`), and products of
//! non-negative rows add relative errors, so a forest's value is within `n·η` of the
//! `f32` passes' value relatively (`n` places, one message each), and a marginal within
//! `4n·η` absolutely (`2n` messages in an upward and a downward pass, then a ratio).
//!
//! # Max-product messages (`mpe`)
//!
//! [`max_message_bits`] computes `m(a) = max_j ψ(a, j) b(j)` from the same products:
//! each term is off by less than `2u + 2^-33 · max b` in all (its two truncations and
//! `ψ`'s rounding), so the largest is too, and with `m(a) ≥ ψ_min · max b` and the
//! rounding to `f32` every entry is within `2^-24 + (2 + 1/4)·2^-31/ψ_min ≤ η`
//! relatively. A forest's max-product value is then within `n·η` of the `f32` sweep's.
//! The arg-max is that of the fixed-point terms, each within `η` of its exact value, so
//! to first order the labelling `mpe` returns attains the largest value within `2n·η`
//! (it is exactly the best one unless two labellings are that close).

/// The largest per-message error [`message_error`] for which the generator emits
/// fixed-point messages (`2^-12`); a model with smaller potentials keeps `f32`
/// messages.
pub const MAX_MESSAGE_ERROR: f64 = 1.0 / 4096.0;

/// `η`, the relative error bound of one fixed-point message entry for `classes`
/// classes and smallest matrix entry `psi_min` (see the module docs).
pub fn message_error(classes: usize, psi_min: f64) -> f64 {
    let c = classes as f64;
    1.0 / 16_777_216.0 + (2.0 * c + 0.25) / 2_147_483_648.0 / psi_min
}

/// The message matrices of a tree model in Q0.32 by rows: `up[a][j] = round(ψ_up(a, j) ·
/// 2^32)` (at most `2^32 − 1`), the same matrices as `TreeModel::psi_up` /
/// `psi_down`, rounded once from their exact values.
pub struct FixedMatrices<const C: usize> {
    /// The upward messages' matrix (`ψ·diag(u)` when folded).
    pub up: [[u32; C]; C],
    /// The downward messages' matrix (`diag(u)·ψ` when folded).
    pub down: [[u32; C]; C],
}

/// Significand field of an `f32`.
const MANT: u32 = 0x007f_ffff;
/// The implicit leading bit of a normal `f32`'s significand.
const IMPLICIT: u32 = 0x0080_0000;

/// `m = ψ·b` for a row `b` of non-negative finite `f32` values (their bits),
/// normalised: returns the bits of `m / 2^e` (entries summing to `[1, 2)`) and `e`.
/// A zero row gives zeros and `e = 0`. Error: see the module docs. (`SoftF32`'s
/// `fixed_message` calls it and is out of line: its `C²` unrolled multiply-adds are
/// kilobytes of machine code, which every pass of every map would repeat.)
#[inline(always)]
pub fn message_bits<const C: usize>(psi: &[[u32; C]; C], b: &[u32; C]) -> ([u32; C], i32) {
    let (q, emax) = fixed_row(b);
    let mut acc = [0u64; C];
    let mut total = 0u64;
    for (s, row) in acc.iter_mut().zip(psi) {
        let mut sum = 0u64;
        for (&p, &x) in row.iter().zip(&q) {
            sum += (u64::from(p) * u64::from(x)) >> 32;
        }
        *s = sum;
        total += sum;
    }
    float_row(&acc, total, emax)
}

/// The max-product message `m(a) = max_j ψ(a, j) b(j)` for a row `b` as in
/// [`message_bits`], normalised to a largest entry in `[1, 2]` (2 only by the
/// rounding): returns its bits and
/// `e`, and writes into `arg[a]` the smallest `j` attaining the fixed-point maximum.
/// A zero row gives zeros, `e = 0` and `arg` all 0. Error: within `η` (see the module
/// docs: the max-product bound is smaller than the sum's).
#[inline(always)]
pub fn max_message_bits<const C: usize>(
    psi: &[[u32; C]; C],
    b: &[u32; C],
    arg: &mut [u8; C],
) -> ([u32; C], i32) {
    let (q, emax) = fixed_row(b);
    let mut acc = [0u64; C];
    let mut top = 0u64;
    for ((s, best), row) in acc.iter_mut().zip(arg.iter_mut()).zip(psi) {
        let (mut m, mut at) = (0u32, 0u8);
        for (j, (&p, &x)) in row.iter().zip(&q).enumerate() {
            let t = ((u64::from(p) * u64::from(x)) >> 32) as u32;
            if t > m {
                (m, at) = (t, j as u8);
            }
        }
        (*s, *best) = (u64::from(m), at);
        top = top.max(u64::from(m));
    }
    float_row(&acc, top, emax)
}

/// A row's bits as Q0.32 relative to its largest exponent: `q(j) = b(j) ·
/// 2^(158 − emax)` truncated, and `emax` (the largest biased exponent, at least 1).
#[inline(always)]
fn fixed_row<const C: usize>(b: &[u32; C]) -> ([u32; C], u32) {
    // Non-negative values are ordered as their bits.
    let top = b.iter().fold(0u32, |m, &x| m.max(x));
    let emax = (top >> 23).max(1);
    let mut q = [0u32; C];
    for (o, &x) in q.iter_mut().zip(b) {
        let e = x >> 23;
        let mant = (x & MANT) | if e > 0 { IMPLICIT } else { 0 };
        *o = (mant << 8) >> (emax - e.max(1)).min(31);
    }
    (q, emax)
}

/// Accumulators of a message on `q`'s scale (`m(a) = acc(a) · 2^(emax − 158)`) as
/// `f32` bits of `acc(a) / 2^l`, with `2^l ≤ reference < 2^(l+1)` (`reference`: the
/// sum or the largest of `acc`, at least every entry), each rounded once (half up),
/// and the message's exponent `l + emax − 158`. A zero `reference` gives zeros, 0.
#[inline(always)]
fn float_row<const C: usize>(acc: &[u64; C], reference: u64, emax: u32) -> ([u32; C], i32) {
    let mut out = [0u32; C];
    if reference == 0 {
        return (out, 0);
    }
    let l = 63 - reference.leading_zeros() as i32;
    for (o, &v) in out.iter_mut().zip(acc) {
        if v == 0 {
            continue;
        }
        let z = v.leading_zeros();
        // Biased exponent of v / 2^l (in [64, 127]: normal).
        let exp = 127 + (63 - z as i32) - l;
        let hi = ((v << z) >> 32) as u32;
        // 24 significand bits (leading bit included), rounded half up; a carry out of
        // the significand raises the exponent.
        let m = (hi >> 8) + ((hi >> 7) & 1);
        *o = (((exp - 1) as u32) << 23).wrapping_add(m);
    }
    (out, l + emax as i32 - 158)
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    /// The bound's formula: `2^-24 + (2C + 1/4)·2^-31/ψ_min`, exactly.
    #[test]
    fn the_bound_is_the_documented_formula() {
        assert_eq!(
            message_error(10, 1.0),
            2f64.powi(-24) + 20.25 * 2f64.powi(-31)
        );
        assert_eq!(
            message_error(3, 0.25),
            2f64.powi(-24) + 6.25 * 2f64.powi(-29)
        );
        assert_eq!(MAX_MESSAGE_ERROR, 2f64.powi(-12));
    }

    /// Random matrices and rows (entries spread over many binades, zeros, one-hot
    /// rows, tiny rows) against `f64`: every entry within the bound `η`, and the
    /// normalisation right (sum in `[1, 2)` up to the entries' rounding).
    #[test]
    fn messages_are_within_their_bound() {
        const C: usize = 10;
        let mut g = ChaCha8Rng::seed_from_u64(20261127);
        let (mut worst, mut worst_max) = (0f64, 0f64);
        for case in 0..20_000 {
            let spread = [1.0, 1e-2, 1e-4, 1e-6][case % 4];
            let mut exact = [[0f64; C]; C];
            let mut psi = [[0u32; C]; C];
            let mut psi_min = 1f64;
            for (ea, pa) in exact.iter_mut().zip(&mut psi) {
                for (e, p) in ea.iter_mut().zip(pa) {
                    let x: f64 = spread + (1.0 - spread) * g.random::<f64>().powi(3);
                    let q = (x * 2f64.powi(32)).round().min(u32::MAX as f64);
                    *p = q as u32;
                    *e = q / 2f64.powi(32);
                    psi_min = psi_min.min(*e);
                }
            }
            let scale = 2f32.powi(g.random_range(-120..20));
            let mut b = [0f32; C];
            for (k, x) in b.iter_mut().enumerate() {
                *x = match (case / 4) % 5 {
                    0 => g.random::<f32>(),
                    1 => g.random::<f32>().powi(20),
                    2 => f32::from(u8::from(k == case % C)),
                    3 => 2f32.powi(-g.random_range(0..60)),
                    _ => [0.0, 1.0, 1e-30][g.random_range(0..3)],
                } * scale;
            }
            let bits = b.map(f32::to_bits);
            let (out, e) = message_bits(&psi, &bits);
            if b.iter().all(|&x| x < f32::MIN_POSITIVE) {
                // Outside the bound's premise (a normal largest entry): only no panic.
                continue;
            }
            let eta = message_error(C, psi_min);
            worst_max = worst_max.max(check_max(&exact, &psi, &b, case, max_error(psi_min)));
            let mut sum = 0f64;
            for (a, (&o, row)) in out.iter().zip(&exact).enumerate() {
                let want: f64 = row.iter().zip(&b).map(|(&p, &x)| p * f64::from(x)).sum();
                let got = f64::from(f32::from_bits(o)) * 2f64.powi(e);
                sum += f64::from(f32::from_bits(o));
                if want == 0.0 {
                    assert_eq!(got, 0.0, "case {case} entry {a}");
                    continue;
                }
                let rel = (got - want).abs() / want;
                worst = worst.max(rel / eta);
                assert!(
                    rel <= eta,
                    "case {case} entry {a}: {got:e} vs {want:e} ({rel:e} > {eta:e})"
                );
            }
            assert!(
                (1.0 - 1e-6..2.0 + 1e-6).contains(&sum),
                "case {case}: sum {sum}"
            );
        }
        // The cases reach the bounds' neighbourhood (0.89 of the sum's, 0.40 of the
        // max-product's): they are not vacuous.
        assert!(worst > 0.5, "worst error {worst:e} of the bound");
        assert!(
            worst_max > 0.3,
            "worst max-product error {worst_max:e} of its bound"
        );
    }

    /// Ties (equal terms, zero rows) go to the smallest class, as in `f32` code.
    #[test]
    fn max_messages_break_ties_to_the_smallest_class() {
        let psi = [
            [1u32 << 31; 4],
            [1 << 30, 1 << 31, 1 << 31, 1 << 30],
            [7; 4],
            [9, 8, 9, 8],
        ];
        let one = 1f32.to_bits();
        let mut arg = [u8::MAX; 4];
        let (out, e) = max_message_bits(&psi, &[one; 4], &mut arg);
        assert_eq!(arg, [0, 1, 0, 0]);
        assert_eq!(out[0], out[1]);
        assert_eq!(f32::from_bits(out[0]) * 2f32.powi(e), 0.5);
        let (out, e) = max_message_bits(&psi, &[0; 4], &mut arg);
        assert_eq!((out, e, arg), ([0; 4], 0, [0; 4]));
        let (_, _) = max_message_bits(&psi, &[0, one, 0, one], &mut arg);
        assert_eq!(arg, [1, 1, 1, 1]);
    }

    /// The max-product bound of the module docs, `2^-24 + (2 + 1/4)·2^-31/ψ_min`, which
    /// is at most `η`.
    fn max_error(psi_min: f64) -> f64 {
        let e = 2f64.powi(-24) + 2.25 * 2f64.powi(-31) / psi_min;
        assert!(e <= message_error(1, psi_min));
        e
    }

    /// [`max_message_bits`] on one case against `f64`: every entry within `bound`
    /// relatively, the largest in `[1, 2]`, and each arg-max a class whose exact term
    /// is within `2·bound` of the exact maximum. Returns the largest error as a share of `bound`.
    fn check_max<const C: usize>(
        exact: &[[f64; C]; C],
        psi: &[[u32; C]; C],
        b: &[f32; C],
        case: usize,
        bound: f64,
    ) -> f64 {
        let mut arg = [u8::MAX; C];
        let (out, e) = max_message_bits(psi, &b.map(f32::to_bits), &mut arg);
        let mut worst = 0f64;
        let mut top = 0f64;
        for (a, (&o, row)) in out.iter().zip(exact).enumerate() {
            let mut terms = [0f64; C];
            for ((t, &p), &x) in terms.iter_mut().zip(row).zip(b) {
                *t = p * f64::from(x);
            }
            let want = terms.iter().fold(0f64, |m, &t| m.max(t));
            let got = f64::from(f32::from_bits(o)) * 2f64.powi(e);
            top = top.max(f64::from(f32::from_bits(o)));
            let at = usize::from(arg[a]);
            if want == 0.0 {
                assert_eq!((got, at), (0.0, 0), "case {case} entry {a}");
                continue;
            }
            let rel = (got - want).abs() / want;
            worst = worst.max(rel / bound);
            assert!(
                rel <= bound,
                "case {case} max entry {a}: {got:e} vs {want:e}"
            );
            assert!(
                terms[at] >= want * (1.0 - 2.0 * bound),
                "case {case} entry {a}: arg {at} attains {:e} of {want:e}",
                terms[at]
            );
        }
        assert!(
            top == 0.0 || (1.0..=2.0).contains(&top),
            "case {case}: largest {top}"
        );
        worst
    }
}
