//! Evidence rows as the passes read them: validated once ([`check_rows`], the one
//! check of every entry point), scaled to a largest entry of 1 (or one-hot for a
//! label) and gathered into lane groups.

use crate::__private::{Lanes, Real};
use crate::EvidenceError;

use super::Acc;

/// `ln Π_p s_p`, where `s_p` is the largest value of row `p`, or the value of its
/// label when labelled (`label < C`); `-inf` when some `s_p = 0`. The product keeps
/// an exact power-of-two exponent (one rounding per place, one `ln` in all).
#[inline]
pub fn log_scale<T: Real, const N: usize, const C: usize>(e: &[[T; C]; N], labels: &[u16; N]) -> T {
    log_scale_with(e, labels, |_, _| None)
}

/// [`log_scale`], where a labelled place takes `flushed(place, label)` instead of its
/// row's value when that is `Some((m, x))`: the value `m · 2^x` in the row's scale (the
/// streaming state's exact fused value of a label its row reads as 0,
/// `Fused::flushed_label`).
#[inline(always)]
pub(crate) fn log_scale_with<T: Real, const N: usize, const C: usize>(
    e: &[[T; C]; N],
    labels: &[u16; N],
    flushed: impl Fn(usize, usize) -> Option<(T, i32)>,
) -> T {
    let mut acc = Acc::ONE;
    for (q, (row, &l)) in e.iter().zip(labels).enumerate() {
        let s = row_scale(row, l);
        if let Some((m, x)) = flushed(q, usize::from(l)) {
            acc.mul(m);
            acc.mul_pow2(x);
        } else if s.scalable() {
            acc.mul(s);
        } else {
            // A subnormal scale would lose bits in the product (and one in the top
            // binade could overflow it): its exponent goes in exactly. Zero stays zero.
            let (m, x) = s.split();
            acc.mul(m);
            acc.mul_pow2(x);
        }
    }
    acc.ln()
}

/// Whether float operations are library calls here: targets other than x86, AArch64
/// and Arm with the hard-float ABI (Cortex-M3, RV32IMAC, ...). On a Cortex-M4F the
/// integer form of a compare costs more than the float one.
const SOFT_FLOAT: bool = !cfg!(any(
    target_arch = "x86_64",
    target_arch = "x86",
    target_arch = "aarch64",
    target_abi = "eabihf"
));

/// The largest value of `row`, or the value of `label` when `label < C`.
#[inline(always)]
fn row_scale<T: Real, const C: usize>(row: &[T; C], label: u16) -> T {
    match row.get(usize::from(label)) {
        Some(&v) => v,
        None => row_max(row, SOFT_FLOAT),
    }
}

/// The largest value of a checked row (`0` for none): with `integer_compares` (targets
/// without an FPU) by integer compares of the magnitudes, the same result for values
/// `≥ 0`, instead of soft-float compare calls.
#[inline(always)]
fn row_max<T: Real, const C: usize>(row: &[T; C], integer_compares: bool) -> T {
    row.iter().copied().fold(T::ZERO, |a, b| {
        let larger = if integer_compares {
            b.magnitude_key() > a.magnitude_key()
        } else {
            b > a
        };
        if larger { b } else { a }
    })
}

/// How a row with largest entry `s > 0` is scaled to a largest entry of 1: `(1 / s,
/// 0)`, applied as `v · (1 / s)`; or, when `1 / s` would leave the normal range (`s`
/// subnormal, where it overflows, or in the top binade, where it is subnormal), `(1 /
/// m, e)` for `s = m · 2^e`, applied as `v · 2^-e · (1 / m)` ([`unscale`]). One integer
/// range check on the common path.
#[inline(always)]
fn inverse_scale<T: Real>(s: T) -> (T, i32) {
    if s.scalable() {
        (T::ONE / s, 0)
    } else {
        split_inverse(s)
    }
}

/// [`inverse_scale`] of a scale outside the normal range (out of line: never on the
/// hot path of real evidence).
#[cold]
#[inline(never)]
fn split_inverse<T: Real>(s: T) -> (T, i32) {
    let (m, e) = s.split();
    (T::ONE / m, e)
}

/// `v · 2^-e · inv`: an entry `v` of a row scaled by [`inverse_scale`]'s `(inv, e)`
/// (`e ≠ 0`), the power of two in two exact steps ([`Real::pow2_pair`]).
#[cold]
#[inline(never)]
fn unscale<T: Real>(v: T, inv: T, e: i32) -> T {
    let (a, b) = T::pow2_pair(-e);
    v * a * b * inv
}

/// The scaled row of a place (largest entry 1), or the one-hot row of its label.
#[inline(always)]
fn scaled_row<T: Real, const C: usize>(row: &[T; C], label: u16) -> [T; C] {
    let mut x = [T::ZERO; C];
    if let Some(v) = x.get_mut(usize::from(label)) {
        *v = T::ONE;
        return x;
    }
    let (inv, e) = inverse_scale(row_scale(row, u16::MAX));
    for (o, &v) in x.iter_mut().zip(row) {
        *o = if e == 0 { v * inv } else { unscale(v, inv, e) };
    }
    x
}

/// One place's scaled row (largest entry 1): what [`scale_rows`] writes for a place
/// without a label (the streaming state's table on SIMD hosts).
#[inline]
pub fn scale_row<T: Real, const C: usize>(row: &[T; C]) -> [T; C] {
    scaled_row(row, u16::MAX)
}

/// Writes every place's scaled row (largest entry 1), or the one-hot row of its label
/// (`labels`, `< C`), into `s`: the same values a gather from the rows themselves
/// computes, bit for bit. SIMD hosts pass this table to the passes (their `table`
/// argument), whose gathers are then loads only.
#[inline(never)]
pub fn scale_rows<T: Real, const C: usize, const N: usize>(
    e: &[[T; C]; N],
    labels: Option<&[u16; N]>,
    s: &mut [[T; C]; N],
) {
    for (q, (o, row)) in s.iter_mut().zip(e).enumerate() {
        let lab = labels.and_then(|ls| ls.get(q)).copied().unwrap_or(u16::MAX);
        *o = scaled_row(row, lab);
    }
}

/// Writes the scaled rows of one group's components into `x`, lane `l` holding
/// component `p[l]` (`labels`: one-hot rows for labelled places; zero rows for places
/// out of range), read from `table` (the rows of [`scale_rows`]) on SIMD hosts when
/// given, else scaled from `e` (scalar code never reads a table). Every entry of `x` is
/// written; it is an out-parameter, not a returned array, because returning the array
/// cost a copy of it (1.6 KB for a 5-place template on an AVX2 host) per group.
#[inline(always)]
pub fn gather<W: Lanes, const L: usize, const NV: usize, const C: usize, const N: usize>(
    e: &[[W::Scalar; C]; N],
    labels: Option<&[u16; N]>,
    table: Option<&[[W::Scalar; C]; N]>,
    p: &[[u16; NV]; L],
    x: &mut [[W; C]; NV],
) {
    if W::WIDTH > 1
        && let Some(s) = table
    {
        return gather_scaled::<W, L, NV, C, N>(s, p, x);
    }
    gather_raw::<W, L, NV, C, N>(e, labels, p, x);
}

/// [`gather`] from rows scaled by [`scale_rows`]: loads and an in-register transpose
/// ([`Lanes::from_rows`]).
#[inline(always)]
fn gather_scaled<W: Lanes, const L: usize, const NV: usize, const C: usize, const N: usize>(
    s: &[[W::Scalar; C]; N],
    p: &[[u16; NV]; L],
    x: &mut [[W; C]; NV],
) {
    let zero = [W::Scalar::ZERO; C];
    for (v, xv) in x.iter_mut().enumerate() {
        let mut src = [&zero; L];
        for (o, pl) in src.iter_mut().zip(p) {
            if let Some(r) = pl.get(v).and_then(|&q| s.get(usize::from(q))) {
                *o = r;
            }
        }
        *xv = W::from_rows(&src);
    }
}

/// [`gather`] from the rows as given: each row's scale is computed once per lane and
/// variable; every vector is then built from its `L` lane values in one step (no
/// per-lane insertion). A row whose largest entry lies outside the normal range (see
/// [`inverse_scale`]) sends the whole gather to [`gather_exact`] instead, which keeps
/// the loop below as short as it was without such rows. Out of line: inlined into
/// every pass it costs microcontrollers stack and instructions.
#[inline(never)]
fn gather_raw<W: Lanes, const L: usize, const NV: usize, const C: usize, const N: usize>(
    e: &[[W::Scalar; C]; N],
    labels: Option<&[u16; N]>,
    p: &[[u16; NV]; L],
    x: &mut [[W; C]; NV],
) {
    /// A lane's source for one variable: the place's row and its scale's inverse, a
    /// one-hot label, or nothing (a place out of range: zeros).
    #[derive(Clone, Copy)]
    enum Src<'a, T, const C: usize> {
        Row(&'a [T; C], T),
        Label(usize),
        Zero,
    }
    let mut src = [[Src::<W::Scalar, C>::Zero; L]; NV];
    let mut split = false;
    for (l, pl) in p.iter().enumerate() {
        for (sv, &q) in src.iter_mut().zip(pl) {
            let q = usize::from(q);
            let lab = labels
                .and_then(|ls| ls.get(q))
                .map_or(usize::MAX, |&x| usize::from(x));
            let (Some(row), Some(o)) = (e.get(q), sv.get_mut(l)) else {
                continue;
            };
            *o = if lab < C {
                Src::Label(lab)
            } else {
                let (inv, ex) = inverse_scale(row_scale(row, u16::MAX));
                split |= ex != 0;
                Src::Row(row, inv)
            };
        }
    }
    if split {
        return gather_exact::<W, L, NV, C, N>(e, labels, p, x);
    }
    for (xv, sv) in x.iter_mut().zip(&src) {
        for (c, xc) in xv.iter_mut().enumerate() {
            let mut a = [W::Scalar::ZERO; L];
            for (o, s) in a.iter_mut().zip(sv) {
                *o = match *s {
                    Src::Row(row, inv) => row.get(c).map_or(W::Scalar::ZERO, |&v| v * inv),
                    Src::Label(k) if k == c => W::Scalar::ONE,
                    _ => W::Scalar::ZERO,
                };
            }
            *xc = W::from_lanes(&a);
        }
    }
}

/// [`gather_raw`] when some row's largest entry lies outside the normal range: every
/// lane's row scaled by [`scaled_row`] (the same values as the common path and as
/// [`scale_rows`], bit for bit), then transposed.
#[cold]
#[inline(never)]
fn gather_exact<W: Lanes, const L: usize, const NV: usize, const C: usize, const N: usize>(
    e: &[[W::Scalar; C]; N],
    labels: Option<&[u16; N]>,
    p: &[[u16; NV]; L],
    x: &mut [[W; C]; NV],
) {
    for (v, xv) in x.iter_mut().enumerate() {
        let mut rows = [[W::Scalar::ZERO; C]; L];
        for (r, pl) in rows.iter_mut().zip(p) {
            let q = pl.get(v).map_or(usize::MAX, |&q| usize::from(q));
            if let Some(row) = e.get(q) {
                let lab = labels.and_then(|ls| ls.get(q)).copied();
                scale_into(row, lab.unwrap_or(u16::MAX), r);
            }
        }
        *xv = W::from_rows(&rows.each_ref());
    }
}

/// [`scaled_row`] written into `out`; out of line, so that each [`gather_exact`] (one
/// per template and lane width) stays a short loop around it.
#[inline(never)]
fn scale_into<T: Real, const C: usize>(row: &[T; C], label: u16, out: &mut [T; C]) {
    *out = scaled_row(row, label);
}

/// Validates every row of evidence with [`check_row`] (the one check of every entry
/// point, stateless and streaming); errors name the place index and its id from `ids`.
pub fn check_rows<T: Real, const N: usize, const C: usize>(
    e: &[[T; C]; N],
    ids: &[u32; N],
) -> Result<(), EvidenceError> {
    for (p, (row, &id)) in e.iter().zip(ids).enumerate() {
        check_row(row, p, id)?;
    }
    Ok(())
}

/// Validates one row of evidence for place `p` (finite, `≥ 0`, some mass).
#[inline(always)]
pub fn check_row<T: Real, const C: usize>(
    row: &[T; C],
    place: usize,
    place_id: u32,
) -> Result<(), EvidenceError> {
    // Fast path: the row tested by integer compares of its bits, without a branch
    // (vectorisable on hosts, no float compare without an FPU); a bad row (or one
    // holding -0.0) takes the loop below, which names its first bad class.
    if T::plain_row(row) {
        return Ok(());
    }
    let place_id = u64::from(place_id);
    let mut mass = false;
    for (class, &v) in row.iter().enumerate() {
        if !v.is_finite() {
            return Err(EvidenceError::NotFinite {
                place,
                place_id,
                class,
            });
        }
        if v < T::ZERO {
            return Err(EvidenceError::Negative {
                place,
                place_id,
                class,
            });
        }
        mass |= v > T::ZERO;
    }
    if mass {
        Ok(())
    } else {
        Err(EvidenceError::NoMass { place, place_id })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bit test of `check_row`'s fast path agrees with the float tests on every
    /// kind of value and every pair of them, in both precisions.
    #[test]
    fn plain_row_matches_float_compares() {
        let f32s = [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            f32::MIN_POSITIVE / 4.0,
            -f32::MIN_POSITIVE / 4.0,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
        ];
        let plain = |v: f64| v.is_finite() && v >= 0.0 && v.is_sign_positive();
        for a in f32s {
            for b in f32s {
                let (x, y) = (f64::from(a), f64::from(b));
                let want = plain(x) && plain(y) && (x > 0.0 || y > 0.0);
                assert_eq!(f32::plain_row(&[a, b]), want, "{a:e} {b:e}");
                assert_eq!(f64::plain_row(&[x, y]), want, "{x:e} {y:e}");
            }
            let want = plain(f64::from(a)) && a > 0.0;
            assert_eq!(f32::plain_row(&[a]), want, "{a:e}");
        }
        assert!(check_row(&[0.0f32, -0.0, 2.0], 0, 7).is_ok());
        assert!(check_row(&[0.0f32, -1.0, 2.0], 0, 7).is_err());
        assert!(check_row(&[0.0f32, -0.0], 0, 7).is_err());
    }

    /// Both ways of finding a row's largest entry agree, on normal, subnormal and zero
    /// entries (the integer one runs only on targets without an FPU).
    #[test]
    fn row_max_by_integers_is_the_float_maximum() {
        let rows = [
            [0.5f32, 2.0, 1.0, 0.0],
            [f32::from_bits(1), 0.0, f32::from_bits(7), f32::from_bits(3)],
            [0.0, 0.0, 3.0, 3.0],
            [f32::MAX, 1.0, f32::MIN_POSITIVE, 0.25],
        ];
        for (row, want) in rows.iter().zip([2.0, f32::from_bits(7), 3.0, f32::MAX]) {
            assert_eq!(row_max(row, true), want, "{row:?}");
            assert_eq!(row_max(row, false), want, "{row:?}");
        }
        assert_eq!(row_max(&[0.125f64, 4.0, 0.5], true), 4.0);
    }

    /// Rows whose largest entry is subnormal (where `1 / max` overflows) or in the top
    /// binade (where it is subnormal) scale like any other, in both precisions.
    #[test]
    fn rows_outside_the_normal_range_scale_exactly() {
        let tiny = f32::from_bits(3); // 3 · 2^-149
        assert_eq!(
            scale_row(&[tiny, f32::from_bits(1), 0.0]),
            [1.0, 1.0 / 3.0, 0.0]
        );
        assert_eq!(scale_row(&[f32::MAX / 2.0, f32::MAX]), [0.5, 1.0]);
        let tiny = f64::from_bits(3);
        assert_eq!(scale_row(&[f64::from_bits(1), tiny]), [1.0 / 3.0, 1.0]);
        assert_eq!(scale_row(&[f64::MAX, f64::MAX / 4.0]), [1.0, 0.25]);
        // The lane gather scales them the same way.
        let e = [[f32::from_bits(3), f32::from_bits(1)], [f32::MAX, 1.0]];
        let mut x = [[0.0f32; 2]; 2];
        gather::<f32, 1, 2, 2, 2>(&e, None, None, &[[0, 1]], &mut x);
        assert_eq!(x, [[1.0, 1.0 / 3.0], [1.0, 1.0 / f32::MAX]]);
    }

    /// `log_scale` keeps the exponent of a subnormal scale exactly: with a product
    /// rounded in the subnormal range, two rows of largest entry `3 · 2^-149` would
    /// come out as `4 · 2^-149` or `5 · 2^-149`, not `9 · 2^-298`.
    #[test]
    fn log_scale_of_subnormal_rows_is_exact() {
        let t = f32::from_bits(3);
        let got = log_scale(&[[t, 0.0], [0.0, t]], &[u16::MAX, u16::MAX]);
        let want = 2.0 * (3f64.ln() - 149.0 * core::f64::consts::LN_2);
        assert!((f64::from(got) - want).abs() < 1e-4, "{got} {want}");
        let labelled = log_scale(&[[t, 1.0], [0.0, t]], &[0, 1]);
        assert!(
            (f64::from(labelled) - want).abs() < 1e-4,
            "{labelled} {want}"
        );
    }
}
