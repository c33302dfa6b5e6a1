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
    let mut acc = Acc::ONE;
    for (row, &l) in e.iter().zip(labels) {
        acc.mul(row_scale(row, l));
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
        // Without an FPU, integer compares of the magnitudes (the same result for the
        // values `≥ 0` of checked evidence) instead of soft-float compare calls.
        None => row.iter().copied().fold(T::ZERO, |a, b| {
            let larger = if SOFT_FLOAT {
                b.magnitude_key() > a.magnitude_key()
            } else {
                b > a
            };
            if larger { b } else { a }
        }),
    }
}

/// The scaled row of a place (largest entry 1), or the one-hot row of its label.
#[inline(always)]
fn scaled_row<T: Real, const C: usize>(row: &[T; C], label: u16) -> [T; C] {
    let mut x = [T::ZERO; C];
    if let Some(v) = x.get_mut(usize::from(label)) {
        *v = T::ONE;
        return x;
    }
    let inv = T::ONE / row_scale(row, u16::MAX);
    for (o, &v) in x.iter_mut().zip(row) {
        *o = v * inv;
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
/// per-lane insertion). Out of line: inlined into every pass it costs microcontrollers
/// stack and instructions.
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
                Src::Row(row, W::Scalar::ONE / row_scale(row, u16::MAX))
            };
        }
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
}
