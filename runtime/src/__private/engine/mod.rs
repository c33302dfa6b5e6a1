//! The generic driver of generated code: evaluates every component of a map through
//! its template's generated functions, mixes the decompositions, and keeps the cache
//! of the streaming state.
//!
//! A generated module holds, per template, a [`Tpl`]: the template's component table
//! (places of each component, in groups of `L` components evaluated at once, one per
//! lane of `W`; `L = 1` and `W` = the scalar on targets without float SIMD) and its
//! generated straight-line functions (value, value + local posteriors, max-product
//! value, scalar MPE with backtracking). The loops here run over those constant
//! tables: their trip counts never depend on the evidence.
//!
//! Values of decompositions are products of many component values; they are kept as
//! [`Acc`]: a mantissa in `[1, 2)` and an integer power of two (exact), so a product
//! of thousands of factors neither underflows nor loses more than one rounding per
//! factor, and differences between decompositions are taken on the exponents first.

use super::{Lanes, Real};

mod evidence;
mod streaming;

pub use evidence::*;
pub use streaming::*;

/// A template's value + local posteriors function (see [`Tpl::post`]).
pub type PostFn<W, const NV: usize, const C: usize> = fn(&[[W; C]; NV], &mut [[W; C]; NV]) -> W;
/// A template's MPE function (see [`Tpl::mpe`]).
pub type MpeFn<W, const L: usize, const NV: usize, const C: usize> =
    fn(&[[W; C]; NV], &mut [[u16; NV]; L]) -> W;

/// `a > b`; `false` when either is NaN.
#[inline(always)]
pub(crate) fn above<T: PartialOrd>(a: T, b: T) -> bool {
    a > b
}

/// One template of a compiled map: its component table and generated functions.
///
/// `W` is the lane vector (`L` components per call), `NV` the template's places, `C`
/// the number of classes.
pub struct Tpl<W: Lanes, const L: usize, const NV: usize, const C: usize> {
    /// Places of every group of `L` components (padded with the group's first member).
    pub places: &'static [[[u16; NV]; L]],
    /// Per component (group `g`, lane `l` is component `g·L + l`): bit `d` set when
    /// decomposition `d` contains it. Components past the end are padding.
    pub decs: &'static [u64],
    /// `true` when the functions return natural-log values (log-space template).
    pub log: bool,
    /// Value of each lane's component on scaled evidence.
    pub fwd: fn(&[[W; C]; NV]) -> W,
    /// Value and local posteriors `x_i[c]·∂T/∂x_i[c] / T` of each lane's component.
    pub post: PostFn<W, NV, C>,
    /// Max-product value of each lane's component.
    pub max: fn(&[[W; C]; NV]) -> W,
    /// Max-product value of each lane's component and its arg-max labelling (lane
    /// `l`'s into `lab[l]`, one class per variable).
    pub mpe: MpeFn<W, L, NV, C>,
}

/// A non-negative product kept as `m · 2^e · e^lg` (`m` in `[1, 2)` or `0`), see the
/// module docs.
#[derive(Clone, Copy, Debug)]
pub struct Acc<T> {
    m: T,
    e: i32,
    lg: T,
}

impl<T: Real> Acc<T> {
    /// The empty product, `1`.
    pub const ONE: Acc<T> = Acc {
        m: T::ONE,
        e: 0,
        lg: T::ZERO,
    };

    /// All-zero bits (the product 0): what a `const` all-zero `State` holds before its
    /// first use computes the products (so it lives in `.bss`, with no image in flash).
    pub const ZERO: Acc<T> = Acc {
        m: T::ZERO,
        e: 0,
        lg: T::ZERO,
    };

    /// Multiplies by a linear value `v ≥ 0` (one rounding).
    #[inline(always)]
    pub fn mul(&mut self, v: T) {
        let (m, e) = (self.m * v).split();
        self.m = m;
        self.e += e;
    }

    /// Multiplies by `2^k` (exact).
    #[inline(always)]
    pub fn mul_pow2(&mut self, k: i32) {
        self.e = self.e.saturating_add(k);
    }

    /// Multiplies by `e^l` for a log value `l`.
    #[inline(always)]
    pub fn mul_log(&mut self, l: T) {
        self.lg += l;
    }

    /// `ln` of the product (`-inf` for `0`).
    #[inline]
    pub fn ln(&self) -> T {
        self.m.ln() + T::from_i32(self.e) * T::LN_2 + self.lg
    }

    /// `ln(self / o)`, exact in the exponents (`-inf` when `self` is `0`).
    #[inline]
    pub fn ln_ratio(&self, o: &Acc<T>) -> T {
        (self.m / o.m).ln() + T::from_i32(self.e - o.e) * T::LN_2 + (self.lg - o.lg)
    }

    /// `true` when the product is `0` (or its log is `-inf`).
    #[inline]
    pub fn is_zero(&self) -> bool {
        !above(self.m, T::ZERO) || !above(self.lg, T::NEG_INFINITY)
    }
}

/// The decompositions' mixture: `ln Ŝ = ln((1/D) Σ_d Π_k T_k)` and the posterior weight
/// `w_d` of each decomposition, or `None` when every decomposition is `0`.
///
/// A decomposition more than `-Real::NEGLIGIBLE_LN` nats below the best (`2^-32` of it in
/// `f32`, `2^-61` in `f64`) gets weight exactly `0` and is left out of `Ŝ`: together the
/// D − 1 such terms move `ln Ŝ` and every weighted sum by less than `D·2^-32` (`f32`)
/// relative, a small fraction of one rounding; and no mix then multiplies by a
/// subnormal weight (about 100 cycles each on x86).
#[inline]
pub fn mix<T: Real, const D: usize>(acc: &[Acc<T>; D]) -> Option<(T, [T; D])> {
    // The log of each mantissa once (in `[0, ln 2)`): the comparisons and weights then
    // take differences of the exponents exactly and of these small logs (6 logs and
    // D − 1 exponentials per call instead of 12 and D through `ln_ratio`; the streaming
    // state calls this after every update).
    let mut lm = [T::ZERO; D];
    for (l, a) in lm.iter_mut().zip(acc) {
        if !a.is_zero() {
            *l = a.m.ln();
        }
    }
    let rel = |a: &Acc<T>, la: T, b: &Acc<T>, lb: T| {
        (la - lb) + T::from_i32(a.e - b.e) * T::LN_2 + (a.lg - b.lg)
    };
    let mut best: Option<(&Acc<T>, T)> = None;
    for (a, &la) in acc.iter().zip(&lm) {
        if a.is_zero() {
            continue;
        }
        match best {
            Some((b, lb)) if rel(a, la, b, lb) <= T::ZERO => {}
            _ => best = Some((a, la)),
        }
    }
    let (best, lb) = best?;
    let mut w = [T::ZERO; D];
    let mut s = T::ZERO;
    for ((o, a), &la) in w.iter_mut().zip(acc).zip(&lm) {
        if core::ptr::eq(a, best) {
            *o = T::ONE;
        } else if !a.is_zero() {
            let r = rel(a, la, best, lb);
            if r > T::NEGLIGIBLE_LN {
                *o = r.exp();
            }
        }
        s += *o;
    }
    let inv = T::ONE / s;
    for o in w.iter_mut() {
        *o *= inv;
    }
    // `ln((1/D) Σ_d Π_k T_k)`: the best product's log plus `ln(s / D)`.
    let best_ln = lb + T::from_i32(best.e) * T::LN_2 + best.lg;
    Some((best_ln + (s / T::from_i32(D as i32)).ln(), w))
}

/// Index of the largest decomposition value (lowest index on ties), or `None` when
/// every decomposition is `0`.
#[inline]
pub fn best<T: Real, const D: usize>(acc: &[Acc<T>; D]) -> Option<usize> {
    let mut best: Option<usize> = None;
    for (d, a) in acc.iter().enumerate() {
        if a.is_zero() {
            continue;
        }
        match best.and_then(|b| acc.get(b)) {
            Some(b) if a.ln_ratio(b) <= T::ZERO => {}
            _ => best = Some(d),
        }
    }
    best
}

/// Multiplies every component's value (`max`: its max-product value) into the
/// accumulator of each decomposition containing it.
#[inline(never)]
pub fn value_pass<
    W: Lanes,
    const L: usize,
    const NV: usize,
    const C: usize,
    const N: usize,
    const D: usize,
>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    labels: &[u16; N],
    table: Option<&[[W::Scalar; C]; N]>,
    max: bool,
    acc: &mut [Acc<W::Scalar>; D],
) {
    for (g, p) in t.places.iter().enumerate() {
        let mut x = [[W::ZERO; C]; NV];
        gather::<W, L, NV, C, N>(e, Some(labels), table, p, &mut x);
        let v = if max { (t.max)(&x) } else { (t.fwd)(&x) };
        let masks = t.decs.get(g * L..).unwrap_or(&[]);
        for (&mask, &vl) in masks.iter().zip(&v.to_lanes::<L>()) {
            accumulate(acc, mask, vl, t.log);
        }
    }
}

/// Multiplies `v` (a log value when `log`) into every decomposition of `mask`.
#[inline(always)]
fn accumulate<T: Real, const D: usize>(acc: &mut [Acc<T>; D], mask: u64, v: T, log: bool) {
    for (d, a) in acc.iter_mut().enumerate() {
        if mask >> d & 1 == 1 {
            if log {
                a.mul_log(v);
            } else {
                a.mul(v);
            }
        }
    }
}

/// `Σ_{d ∋ component} w_d`.
#[inline(always)]
fn weight<T: Real, const D: usize>(w: &[T; D], mask: u64) -> T {
    masked_sum(w, mask, T::ZERO)
}

/// `zero + Σ w_d` over the decompositions `d` whose bit is set in `mask` (a component's
/// weight; floats, or the fixed-point mix's Q1.31 integers), in order of `d`.
#[inline(always)]
pub(crate) fn masked_sum<X: Copy + core::ops::Add<Output = X>, const D: usize>(
    w: &[X; D],
    mask: u64,
    zero: X,
) -> X {
    let mut s = zero;
    for (d, &wd) in w.iter().enumerate() {
        if mask >> d & 1 == 1 {
            s = s + wd;
        }
    }
    s
}

/// Value and local posteriors of group `p` of a template on evidence `e` (no labels;
/// `table`: see [`gather`]): `(values per lane, posterior vectors [variable][class])`.
#[inline(always)]
fn post_group<W: Lanes, const L: usize, const NV: usize, const C: usize, const N: usize>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    table: Option<&[[W::Scalar; C]; N]>,
    p: &[[u16; NV]; L],
) -> ([W::Scalar; L], [[W; C]; NV]) {
    let mut x = [[W::ZERO; C]; NV];
    gather::<W, L, NV, C, N>(e, None, table, p, &mut x);
    let mut post = [[W::ZERO; C]; NV];
    let v = (t.post)(&x, &mut post);
    (v.to_lanes::<L>(), post)
}

/// One variable's posterior vectors as `[class][lane]` scalars.
#[inline(always)]
fn class_lanes<W: Lanes, const L: usize, const C: usize>(pv: &[W; C]) -> [[W::Scalar; L]; C] {
    let mut out = [[W::Scalar::ZERO; L]; C];
    for (o, &v) in out.iter_mut().zip(pv) {
        *o = v.to_lanes::<L>();
    }
    out
}

/// Posterior pass of the stateless marginals: evaluates every component with its
/// local posteriors and adds them, weighted by its decompositions' posterior weights
/// `w`, into `out`.
#[inline(never)]
pub fn posterior_pass<
    W: Lanes,
    const L: usize,
    const NV: usize,
    const C: usize,
    const N: usize,
    const D: usize,
>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    table: Option<&[[W::Scalar; C]; N]>,
    w: &[W::Scalar; D],
    out: &mut [[W::Scalar; C]; N],
) {
    posterior_scatter(
        t,
        e,
        table,
        |mask| weight(w, mask),
        |o, wl, p| *o += wl * p,
        out,
    );
}

/// The loop of [`posterior_pass`]: each lane group's local posteriors, each component's
/// added into its places' rows of `out` by `add(entry, weight_of(mask), posterior)`
/// (`mask`: the component's decompositions).
#[inline(always)]
pub(crate) fn posterior_scatter<
    W: Lanes,
    A: Copy,
    const L: usize,
    const NV: usize,
    const C: usize,
    const N: usize,
>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    table: Option<&[[W::Scalar; C]; N]>,
    weight_of: impl Fn(u64) -> A,
    add: impl Fn(&mut W::Scalar, A, W::Scalar),
    out: &mut [[W::Scalar; C]; N],
) {
    for (g, p) in t.places.iter().enumerate() {
        let (_, post) = post_group(t, e, table, p);
        let masks = t.decs.get(g * L..).unwrap_or(&[]);
        let mut wl = [weight_of(0); L];
        for (o, &mask) in wl.iter_mut().zip(masks) {
            *o = weight_of(mask);
        }
        for (i, pv) in post.iter().enumerate() {
            let pv = class_lanes::<W, L, C>(pv);
            for (l, (pl, &wl)) in p.iter().zip(&wl).enumerate().take(masks.len()) {
                let Some(o) = pl.get(i).and_then(|&q| out.get_mut(usize::from(q))) else {
                    continue;
                };
                for (oc, pc) in o.iter_mut().zip(&pv) {
                    add(oc, wl, pc.get(l).copied().unwrap_or(W::Scalar::ZERO));
                }
            }
        }
    }
}

/// Writes the MPE labels of the components of decomposition `d`.
#[inline(never)]
pub fn mpe_labels<W: Lanes, const L: usize, const NV: usize, const C: usize, const N: usize>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    table: Option<&[[W::Scalar; C]; N]>,
    d: usize,
    labels: &mut [u16; N],
) {
    // Scalar code reads no table (see `gather`).
    let table = if W::WIDTH > 1 { table } else { None };
    // The decomposition's components, `L` at a time: lanes past `n` keep an earlier
    // component's places (or place 0) and are not written back.
    let mut batch = [[0u16; NV]; L];
    let mut n = 0;
    for (g, p) in t.places.iter().enumerate() {
        for (l, pl) in p.iter().enumerate() {
            match t.decs.get(g * L + l) {
                Some(&mask) if mask >> d & 1 == 1 => {}
                _ => continue,
            }
            if let Some(b) = batch.get_mut(n) {
                *b = *pl;
            }
            n += 1;
            if n == L {
                mpe_batch(t, e, table, &batch, n, labels);
                n = 0;
            }
        }
    }
    if n > 0 {
        mpe_batch(t, e, table, &batch, n, labels);
    }
}

/// MPE labelling of the components of `batch` (one per lane): writes the classes of
/// the first `n` lanes' places into `labels`.
#[inline(always)]
fn mpe_batch<W: Lanes, const L: usize, const NV: usize, const C: usize, const N: usize>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    table: Option<&[[W::Scalar; C]; N]>,
    batch: &[[u16; NV]; L],
    n: usize,
    labels: &mut [u16; N],
) {
    let mut x = [[W::ZERO; C]; NV];
    gather::<W, L, NV, C, N>(e, None, table, batch, &mut x);
    let mut lab = [[0u16; NV]; L];
    (t.mpe)(&x, &mut lab);
    for (lab, pl) in lab.iter().zip(batch).take(n) {
        for (&c, &q) in lab.iter().zip(pl) {
            if let Some(o) = labels.get_mut(usize::from(q)) {
                *o = c;
            }
        }
    }
}

/// `a[i] += v` for every `i`.
#[inline(always)]
pub fn add_all<W: Copy + core::ops::AddAssign, const K: usize>(a: &mut [W; K], v: W) {
    for o in a.iter_mut() {
        *o += v;
    }
}

/// Local posteriors `post[i][c] = x[i][c]·g[i][c] / v` (lane-wise).
#[inline(always)]
pub fn post_rows<W: Lanes, const NV: usize, const C: usize>(
    x: &[[W; C]; NV],
    g: &[[W; C]; NV],
    v: W,
    post: &mut [[W; C]; NV],
) {
    let inv = W::splat(<W::Scalar as Real>::ONE) / v;
    for ((pv, xv), gv) in post.iter_mut().zip(x).zip(g) {
        for ((o, &a), &b) in pv.iter_mut().zip(xv).zip(gv) {
            *o = a * b * inv;
        }
    }
}

/// The largest entry and its index (lowest index on ties; `(0, 0)` when all are `≤ 0`).
#[inline(always)]
pub fn amax<T: Real, const K: usize>(v: &[T; K]) -> (T, u16) {
    let (mut best, mut arg) = (T::ZERO, 0u16);
    for (i, &x) in v.iter().enumerate() {
        if x > best {
            best = x;
            arg = i as u16;
        }
    }
    (best, arg)
}

/// Where `c > *r` (strictly): `*r = c` and `*a = code` (arg-max of a block sum).
#[inline(always)]
pub fn sel<T: Real>(r: &mut T, a: &mut [u16; 4], c: T, code: [u16; 4]) {
    if c > *r {
        *r = c;
        *a = code;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `m · 2^k` as an accumulator (`m` in `[1, 2)`, `k` beyond the `f32` range allowed).
    fn acc(m: f32, k: i32) -> Acc<f32> {
        let mut a = Acc::ONE;
        a.mul(m);
        a.mul_pow2(k);
        a
    }

    #[test]
    fn products_of_zero_are_zero() {
        assert!(Acc::<f32>::ZERO.is_zero());
        assert!(!Acc::<f32>::ONE.is_zero());
        assert!(!acc(1.5, -400).is_zero());
        let mut a = acc(1.5, 3);
        a.mul(0.0);
        assert!(a.is_zero(), "a zero factor");
        let mut b = acc(1.5, 3);
        b.mul_log(f32::NEG_INFINITY);
        assert!(b.is_zero(), "a log factor of −∞");
        assert_eq!(mix(&[Acc::<f32>::ZERO, a, b]).map(|(l, _)| l), None);
        assert_eq!(best(&[Acc::<f32>::ZERO, a, b]), None);
    }

    /// A decomposition more than `-NEGLIGIBLE_LN` (22.18 nats in `f32`) below the best
    /// gets weight exactly 0 (never a subnormal), one closer keeps its weight, and
    /// neither moves `ln Ŝ` by more than a rounding.
    #[test]
    fn negligible_decompositions_get_weight_zero() {
        assert!((f32::NEGLIGIBLE_LN + 32.0 * core::f32::consts::LN_2).abs() < 1e-5);
        assert!((f64::NEGLIGIBLE_LN + 61.0 * core::f64::consts::LN_2).abs() < 1e-12);
        let logs = |lg: [f32; 3]| {
            lg.map(|l| {
                let mut a = acc(1.0, 0);
                a.mul_log(l);
                a
            })
        };
        let (l, w) = mix(&logs([0.0, -22.0, -22.5])).unwrap();
        assert_eq!((w[0], w[2]), (1.0 / (1.0 + (-22f32).exp()), 0.0), "{w:?}");
        assert!(w[1] > 0.0 && (w[1] - (-22f32).exp()).abs() < 1e-15, "{w:?}");
        assert!((l + 3f32.ln()).abs() < 1e-6, "{l}");
        // Far below the smallest normal f32 (e^-100): 0, not a subnormal.
        let (_, w) = mix(&logs([0.0, -100.0, -1.0])).unwrap();
        assert_eq!(w[1], 0.0);
        assert!(w[2] > 0.2);
    }

    /// Decompositions whose values lie `2^290` apart, far beyond the `f32` range: the
    /// weights and `ln Ŝ` come from exponent differences, so nothing overflows.
    #[test]
    fn mixing_takes_the_exponents_first() {
        let accs = [acc(1.5, -300), acc(1.25, -10), acc(1.0, -200), Acc::ZERO];
        let (l, w) = mix(&accs).unwrap();
        let want = (1.25f64.ln() - 10.0 * core::f64::consts::LN_2) - 4f64.ln();
        assert!((f64::from(l) - want).abs() < 1e-6, "{l} vs {want}");
        assert_eq!(w, [0.0, 1.0, 0.0, 0.0]);
        assert_eq!(best(&accs), Some(1));
        // Two comparable values: weights in proportion, `ln` of their mean.
        let accs = [acc(1.5, -300), acc(1.0, -299)];
        let (l, w) = mix(&accs).unwrap();
        let want = (3.5f64.ln() - 300.0 * core::f64::consts::LN_2) - 2f64.ln();
        assert!((f64::from(l) - want).abs() < 1e-5, "{l} vs {want}");
        assert!((w[0] - 1.5 / 3.5).abs() < 1e-6 && (w[1] - 2.0 / 3.5).abs() < 1e-6);
        assert_eq!(best(&accs), Some(1));
        // Log factors count like the exponents; ties go to the lowest index.
        let mut a = acc(1.0, 0);
        a.mul_log(-3.0);
        let mut b = acc(1.0, 0);
        b.mul_log(-2.0);
        assert_eq!(best(&[a, b, b]), Some(1));
        assert!((f64::from(b.ln_ratio(&a)) - 1.0).abs() < 1e-6);
        assert!(
            (f64::from(acc(1.5, -300).ln()) - (1.5f64.ln() - 300.0 * core::f64::consts::LN_2))
                .abs()
                < 1e-4
        );
    }

    /// MPE backtracking's selections keep the first of equal values, as documented:
    /// ties go to the lowest class (`amax`) and to the earlier candidate (`sel`).
    #[test]
    fn selections_keep_the_first_of_equal_values() {
        assert_eq!(amax(&[0.25f32, 0.5, 0.5, 0.125]), (0.5, 1));
        assert_eq!(amax(&[0.0f32, -1.0]), (0.0, 0));
        let (mut r, mut a) = (0.5f32, [1u16; 4]);
        sel(&mut r, &mut a, 0.5, [2; 4]);
        assert_eq!((r, a), (0.5, [1; 4]));
        sel(&mut r, &mut a, 0.75, [3; 4]);
        assert_eq!((r, a), (0.75, [3; 4]));
    }
}
