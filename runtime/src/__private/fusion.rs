//! Exact fusion of a place's observations, shared by the streaming states of every model
//! family.
//!
//! A place's fused evidence is the element-wise product of every row observed there (or
//! of the row last set and the observations since). Renormalising that product to a
//! largest entry of 1 after each observation is not enough: the other entries keep
//! shrinking until they are subnormal (about 100 cycles per operation on x86) and then
//! exactly 0, and a class at 0 never comes back however much evidence for it follows.
//!
//! [`Fused`] keeps per class the product as `mantissa · 2^(top − deficit)`: a mantissa in
//! `[1, 2)`, a `u16` deficit (binary orders of magnitude below the best class) and one
//! `i32` exponent `top` of the best class. Each observation costs one rounding per class
//! (relative `ε/2` of the scalar type), nothing underflows, and a class far behind rises
//! again exactly as the product says. Two saturations are documented deviations from the
//! exact product:
//!
//! - a deficit saturates at 65,535 (a class `2^-65535 ≈ e^-45425` times the best): the
//!   class then recovers sooner than the exact product would let it;
//! - `top` saturates at `i32::MIN`/`i32::MAX` (a product beyond `e^±1.49·10^9`): only
//!   [`ln_shift`], the log-likelihood's offset, is then wrong.
//!
//! The row that inference reads ([`Fused::observe`]'s second result) is `mantissa ·
//! 2^-deficit`: the product scaled by the power of two `2^-top`, largest entry in
//! `[1, 2)`, exact, with classes below `2^flush` of the best set to 0 (the model family
//! chooses `flush`: [`Real::PRODUCT_FLUSH_EXP`] for GraphSPN models whose templates all
//! compute in linear space, which multiply up to five evidence entries, so their
//! products stay normal — subnormal products cost a step 20% on x86 after 10^6
//! observations; [`Real::MIN_EXP`] for tree mixtures, whose rows keep every normal
//! entry (see `tree`), and for GraphSPN models with a log-space template, which has
//! assignments of probability 0: there a flushed class could make the likelihood 0
//! where the rows' is not). Such a class changes a place's
//! likelihood by less than `C · 2^flush` relatively; it changes a result only where the
//! model's odds for it exceed `2^-flush` against the evidence. A label is never read as
//! 0 that way: a labelled place's row enters only through its label's value, which
//! [`fused_log_scale`] takes exactly from the fused form. The log-likelihood of the
//! fused evidence is the inference's log-likelihood of those rows plus [`ln_shift`]
//! (`γ · ln 2 · Σ top` over observed places, for a model that raises rows to the power
//! `γ`).

use super::{Real, log_scale_with};

/// Largest deficit of a fused class (see the module docs).
const MAX_DEFICIT: i32 = u16::MAX as i32;

/// One place's fused evidence, exact up to one rounding per observation (see the module
/// docs). All zeros ([`Fused::ZERO`]) is the state of a place not yet initialised; a
/// place without evidence is [`Fused::ONES`].
#[derive(Clone, Copy, Debug)]
pub struct Fused<T, const C: usize> {
    /// Per class the mantissa in `[1, 2)`, or 0 for a class without mass.
    mant: [T; C],
    /// Per class the binary orders of magnitude below the best class.
    deficit: [u16; C],
    /// Binary exponent of the best class's product.
    top: i32,
    /// Binary exponent by which the stored row lies below the product: 0 for a row kept
    /// as given, `top` for a fused row.
    shift: i32,
}

impl<T: Real, const C: usize> Fused<T, C> {
    /// Class `c`'s exact value in the scale of the row [`Fused::observe`] returned, as a
    /// mantissa and a binary exponent (`mant · 2^-deficit`, normal or not); `None` for
    /// a class without mass or out of range.
    pub fn exact(&self, c: usize) -> Option<(T, i32)> {
        match (self.mant.get(c), self.deficit.get(c)) {
            (Some(&m), Some(&d)) if m > T::ZERO => Some((m, -i32::from(d))),
            _ => None,
        }
    }

    /// Class `c`'s exact value ([`Fused::exact`]) when `row`, this place's stored row,
    /// reads it as 0 (a class fused too far below the best for the row to hold);
    /// `None` when the row holds it (read the row) or it has no mass. The one rule by
    /// which a streaming state answers a label its row flushed, in both model families.
    #[inline(always)]
    pub fn flushed_label(&self, row: &[T; C], c: usize) -> Option<(T, i32)> {
        match row.get(c) {
            Some(&v) if v == T::ZERO => self.exact(c),
            _ => None,
        }
    }

    /// All zeros in memory: not yet initialised (a `static` state sits in `.bss`).
    pub const ZERO: Self = Fused {
        mant: [T::ZERO; C],
        deficit: [0; C],
        top: 0,
        shift: 0,
    };

    /// No evidence: a row of ones.
    pub const ONES: Self = Fused {
        mant: [T::ONE; C],
        deficit: [0; C],
        top: 0,
        shift: 0,
    };

    /// The exact form of a row that is stored as given (`set_evidence`, `set_all`).
    pub fn of(row: &[T; C]) -> Self {
        let mut mant = [T::ZERO; C];
        let mut ex = [0i32; C];
        let mut best = i32::MIN;
        for ((m, x), &a) in mant.iter_mut().zip(ex.iter_mut()).zip(row) {
            if a > T::ZERO {
                (*m, *x) = a.split();
                best = best.max(*x);
            }
        }
        let best = if best == i32::MIN { 0 } else { best };
        Fused {
            mant,
            deficit: deficits(&mant, &ex, best),
            top: best,
            shift: 0,
        }
    }

    /// Binary exponent by which the stored row lies below the product of the place's
    /// observations (see [`ln_shift`]).
    pub fn shift(&self) -> i32 {
        self.shift
    }

    /// The product of this evidence and `row` (exact up to one rounding per class), and
    /// the row inference reads for it (classes below `2^flush` of the best read as 0; see
    /// the module docs); `None` when no class keeps any mass. `row` must be checked
    /// (finite, `≥ 0`) by the caller; `flush` is negative.
    pub fn observe(&self, row: &[T; C], flush: i32) -> Option<(Self, [T; C])> {
        let mut mant = [T::ZERO; C];
        let mut ex = [0i32; C];
        let mut best = i32::MIN;
        for ((((o, x), &a), &m0), &d) in mant
            .iter_mut()
            .zip(ex.iter_mut())
            .zip(row)
            .zip(&self.mant)
            .zip(&self.deficit)
        {
            if a > T::ZERO && m0 > T::ZERO {
                let (ma, ea) = a.split();
                let (mp, ep) = (m0 * ma).split();
                *o = mp;
                *x = ea.wrapping_add(ep).wrapping_sub(i32::from(d));
                best = best.max(*x);
            }
        }
        if best == i32::MIN {
            return None;
        }
        let top = self.top.saturating_add(best);
        let fused = Fused {
            mant,
            deficit: deficits(&mant, &ex, best),
            top,
            shift: top,
        };
        Some((fused, fused.row(flush)))
    }

    /// `mantissa · 2^-deficit` per class (exact; largest entry in `[1, 2)`), classes
    /// below `2^flush` set to 0.
    fn row(&self, flush: i32) -> [T; C] {
        let mut r = [T::ZERO; C];
        for ((o, &m), &d) in r.iter_mut().zip(&self.mant).zip(&self.deficit) {
            let d = i32::from(d);
            if d <= -flush {
                *o = m * T::pow2(-d);
            }
        }
        r
    }
}

/// Deficits `best − x` of the nonzero classes, saturated at [`MAX_DEFICIT`].
fn deficits<T: Real, const C: usize>(mant: &[T; C], ex: &[i32; C], best: i32) -> [u16; C] {
    let mut d = [0u16; C];
    for ((o, &m), &x) in d.iter_mut().zip(mant).zip(ex) {
        if m > T::ZERO {
            *o = best.saturating_sub(x).clamp(0, MAX_DEFICIT) as u16;
        }
    }
    d
}

/// `ln Π_p s_p` of the streaming state's rows `e` as [`log_scale`](super::log_scale) reads it (the
/// largest value of a row, or its label's value), except that a labelled place whose
/// row flushed its label to 0 reads the label's exact fused value: a GraphSPN row keeps
/// classes down to `2^-24` of the best, and a label below that must give its likelihood,
/// not `ZeroLikelihood`. A labelled place's row enters only through this scale (the
/// passes read it as one-hot).
pub fn fused_log_scale<T: Real, const C: usize, const N: usize>(
    e: &[[T; C]; N],
    fused: &[Fused<T, C>; N],
    labels: &[u16; N],
) -> T {
    log_scale_with(e, labels, |q, c| {
        let row = e.get(q)?;
        fused.get(q)?.flushed_label(row, c)
    })
}

/// `ln` of the factor by which the stored rows, raised to `power` (a model's evidence
/// exponent: rows enter as `α^power`), lie below the fused evidence's: `power · ln 2 · Σ
/// shift` over the places (summed exactly in `i64`, one rounding at the end). Added to
/// the inference's log-likelihood of the stored rows it gives the log-likelihood of the
/// product of every observation.
pub fn ln_shift<T: Real, const C: usize, const N: usize>(
    fused: &[Fused<T, C>; N],
    power: u32,
) -> T {
    shift_ln(shift_sum(fused) * i64::from(power))
}

/// `Σ shift` over the places' fused rows (what a streaming state keeps, updated as
/// rows are stored).
pub fn shift_sum<T: Real, const C: usize, const N: usize>(fused: &[Fused<T, C>; N]) -> i64 {
    fused.iter().map(|f| i64::from(f.shift)).sum()
}

/// `ln 2 · sum`, exactly 0 for 0 (`sum`: a sum of [`Fused::shift`] times the evidence
/// exponent; one rounding).
pub fn shift_ln<T: Real>(sum: i64) -> T {
    if sum == 0 {
        T::ZERO
    } else {
        T::from_i64(sum) * T::LN_2
    }
}

/// The streaming state's log-scale: `Σ lns + ln 2 · shift`, where `lns[q]` is `ln` of
/// the largest entry of place `q`'s stored row and `shift` the sum of the places'
/// [`Fused::shift`] (which the state keeps, so this is [`ln_shift`] without its pass
/// over every place's fused row). The float sum runs in eight partial sums combined
/// pairwise (no chain of `N` dependent adds); its error is at most that of the
/// sequential sum, `(N − 1)·ε·Σ|lns|`.
pub fn ln_scale<T: Real, const N: usize>(lns: &[T; N], shift: i64) -> T {
    let mut acc = [T::ZERO; 8];
    let mut chunks = lns.chunks_exact(8);
    for chunk in &mut chunks {
        for (a, &x) in acc.iter_mut().zip(chunk) {
            *a += x;
        }
    }
    for (a, &x) in acc.iter_mut().zip(chunks.remainder()) {
        *a += x;
    }
    let [a0, a1, a2, a3, a4, a5, a6, a7] = acc;
    ((a0 + a4) + (a2 + a6)) + ((a1 + a5) + (a3 + a7)) + shift_ln(shift)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `ln` of each class of the fused product, from the exact form.
    fn ln_product(f: &Fused<f32, 3>) -> [f64; 3] {
        let mut out = [f64::NEG_INFINITY; 3];
        for ((o, &m), &d) in out.iter_mut().zip(&f.mant).zip(&f.deficit) {
            if m > 0.0 {
                *o = f64::from(m).ln() + f64::from(f.top - i32::from(d)) * core::f64::consts::LN_2;
            }
        }
        out
    }

    #[test]
    fn products_stay_exact_far_below_the_normal_range() {
        let row = [0.9f32, 0.011, 0.5];
        let mut f = Fused::<f32, 3>::ONES;
        let mut want = [0.0f64; 3];
        for _ in 0..5_000 {
            f = f.observe(&row, f32::MIN_EXP).unwrap().0;
            for (w, &a) in want.iter_mut().zip(&row) {
                *w += f64::from(a).ln();
            }
        }
        for (g, w) in ln_product(&f).iter().zip(&want) {
            assert!((g - w).abs() <= 1e-6 * w.abs(), "{g} vs {w}");
        }
        let (_, r) = f.observe(&[1.0; 3], f32::MIN_EXP).unwrap();
        assert!((1.0..2.0).contains(&r[0]), "{r:?}");
        assert_eq!(
            r[1], 0.0,
            "far below the best class: flushed in the row only"
        );
    }

    #[test]
    fn a_class_far_behind_recovers_exactly() {
        let mut f = Fused::<f32, 3>::ONES;
        for _ in 0..300 {
            f = f.observe(&[0.9, 0.011, 0.011], f32::MIN_EXP).unwrap().0;
        }
        for _ in 0..400 {
            f = f.observe(&[0.011, 0.9, 0.011], f32::MIN_EXP).unwrap().0;
        }
        let (_, r) = f.observe(&[1.0; 3], f32::MIN_EXP).unwrap();
        assert_eq!(r[1].split().1, 0, "class 1 is the best: {r:?}");
        assert_eq!(r[0], 0.0);
        let l = ln_product(&f);
        let want = 100.0 * (0.9f64.ln() - 0.011f64.ln());
        assert!(((l[1] - l[0]) - want).abs() < 1e-3, "{l:?}");
    }

    #[test]
    fn ln_shift_is_the_log_of_the_dropped_scale() {
        let mut f = [Fused::<f32, 3>::ONES; 2];
        f[0] = Fused::of(&[4.0, 2.0, 1.0]);
        assert_eq!(ln_shift(&f, 1), 0.0, "a row kept as given has no shift");
        let (g, r) = f[0].observe(&[0.25, 0.25, 0.25], f32::MIN_EXP).unwrap();
        assert_eq!(r, [1.0, 0.5, 0.25]);
        f[0] = g;
        assert_eq!(ln_shift(&f, 1), 0.0, "4 · 0.25 = 1: nothing dropped");
        let (g, _) = f[1].observe(&[0.125, 0.0, 0.0], f32::MIN_EXP).unwrap();
        f[1] = g;
        assert!((ln_shift(&f, 1) - 0.125f32.ln()).abs() < 1e-6);
        // Rows entering as `α^3`: three times the dropped scale.
        assert!((ln_shift(&f, 3) - 3.0 * 0.125f32.ln()).abs() < 1e-5);
        assert!(
            f[1].observe(&[0.0, 1.0, 1.0], f32::MIN_EXP).is_none(),
            "no class left"
        );
    }

    #[test]
    fn ln_scale_is_the_sum_of_lns_and_the_shifts() {
        let mut x = 7u32;
        let mut lns = [0.0f32; 231];
        for v in lns.iter_mut() {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            *v = (x >> 8) as f32 / 16_777_216.0 * 80.0 - 60.0;
        }
        let exact: f64 = lns.iter().map(|&v| f64::from(v)).sum();
        let bound =
            230.0 * f64::from(f32::EPSILON) * lns.iter().map(|&v| f64::from(v).abs()).sum::<f64>();
        for shift in [0i64, 1, -3_000, 1 << 40] {
            let want = exact + shift as f64 * core::f64::consts::LN_2;
            let got = f64::from(ln_scale(&lns, shift));
            let tol = bound + want.abs() * f64::from(f32::EPSILON);
            assert!((got - want).abs() <= tol, "shift {shift}: {got} vs {want}");
        }
        assert_eq!(ln_scale(&[0.0f32; 5], 0), 0.0);
        assert_eq!(
            ln_scale(&[1.5f32; 3], 0),
            4.5,
            "a remainder shorter than 8 is summed"
        );
        // The state's kept sum is the fused rows' shifts, as `ln_shift` reads them.
        let mut f = [Fused::<f32, 3>::ONES; 2];
        f[1] = f[1].observe(&[0.125, 0.0, 0.0], f32::MIN_EXP).unwrap().0;
        let kept: i64 = f.iter().map(|g| i64::from(g.shift())).sum();
        assert_eq!(shift_sum(&f), kept);
        assert_eq!(ln_scale(&[0.0f32; 2], kept), ln_shift(&f, 1));
    }

    #[test]
    fn deficits_saturate_towards_recovering_sooner() {
        let mut f = Fused::<f32, 2>::ONES;
        for _ in 0..700 {
            f = f.observe(&[1.0, 1e-30], f32::MIN_EXP).unwrap().0;
        }
        assert_eq!(f.deficit[1], u16::MAX);
        assert_eq!(f.top, 0);
    }
}
