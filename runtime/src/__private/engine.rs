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
use crate::EvidenceError;

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
#[inline]
pub fn mix<T: Real, const D: usize>(acc: &[Acc<T>; D]) -> Option<(T, [T; D])> {
    let mut best: Option<&Acc<T>> = None;
    for a in acc {
        if a.is_zero() {
            continue;
        }
        match best {
            Some(b) if a.ln_ratio(b) <= T::ZERO => {}
            _ => best = Some(a),
        }
    }
    let best = best?;
    let mut w = [T::ZERO; D];
    let mut s = T::ZERO;
    for (o, a) in w.iter_mut().zip(acc) {
        if !a.is_zero() {
            *o = a.ln_ratio(best).exp();
            s += *o;
        }
    }
    let inv = T::ONE / s;
    for o in w.iter_mut() {
        *o *= inv;
    }
    Some((best.ln() + s.ln() - T::from_i32(D as i32).ln(), w))
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

/// The scaled rows of one group's components, lane `l` holding component `p[l]`
/// (`labels`: one-hot rows for labelled places; zero rows for places out of range),
/// read from `table` (the rows of [`scale_rows`]) on SIMD hosts when given, else
/// scaled from `e` (scalar code never reads a table).
#[inline(always)]
pub fn gather<W: Lanes, const L: usize, const NV: usize, const C: usize, const N: usize>(
    e: &[[W::Scalar; C]; N],
    labels: Option<&[u16; N]>,
    table: Option<&[[W::Scalar; C]; N]>,
    p: &[[u16; NV]; L],
) -> [[W; C]; NV] {
    if W::WIDTH > 1
        && let Some(s) = table
    {
        return gather_scaled::<W, L, NV, C, N>(s, p);
    }
    gather_raw::<W, L, NV, C, N>(e, labels, p)
}

/// [`gather`] from rows scaled by [`scale_rows`]: loads and an in-register transpose
/// ([`Lanes::from_rows`]).
#[inline(always)]
fn gather_scaled<W: Lanes, const L: usize, const NV: usize, const C: usize, const N: usize>(
    s: &[[W::Scalar; C]; N],
    p: &[[u16; NV]; L],
) -> [[W; C]; NV] {
    let zero = [W::Scalar::ZERO; C];
    let mut x = [[W::ZERO; C]; NV];
    for (v, xv) in x.iter_mut().enumerate() {
        let mut src = [&zero; L];
        for (o, pl) in src.iter_mut().zip(p) {
            if let Some(r) = pl.get(v).and_then(|&q| s.get(usize::from(q))) {
                *o = r;
            }
        }
        *xv = W::from_rows(&src);
    }
    x
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
) -> [[W; C]; NV] {
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
    let mut x = [[W::ZERO; C]; NV];
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
    x
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
        let x = gather::<W, L, NV, C, N>(e, Some(labels), table, p);
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
    let x = gather::<W, L, NV, C, N>(e, None, table, p);
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
    for (g, p) in t.places.iter().enumerate() {
        let (_, post) = post_group(t, e, table, p);
        let masks = t.decs.get(g * L..).unwrap_or(&[]);
        let mut wl = [W::Scalar::ZERO; L];
        for (o, &mask) in wl.iter_mut().zip(masks) {
            *o = weight(w, mask);
        }
        for (i, pv) in post.iter().enumerate() {
            let pv = class_lanes::<W, L, C>(pv);
            for (l, (pl, &wl)) in p.iter().zip(&wl).enumerate().take(masks.len()) {
                let Some(o) = pl.get(i).and_then(|&q| out.get_mut(usize::from(q))) else {
                    continue;
                };
                for (oc, pc) in o.iter_mut().zip(&pv) {
                    *oc += wl * pc.get(l).copied().unwrap_or(W::Scalar::ZERO);
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
    let x = gather::<W, L, NV, C, N>(e, None, table, batch);
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

/// Streaming state and one-pass marginals: re-evaluates group `g` of a template on
/// evidence `e` (`table`: see [`gather`]) and stores each real component's value into `val` (indexed by
/// component within the template) and its local posteriors into `post` (rows
/// `u·NV ..`).
#[inline(never)]
pub fn eval_group<W: Lanes, const L: usize, const NV: usize, const C: usize, const N: usize>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    table: Option<&[[W::Scalar; C]; N]>,
    g: usize,
    val: &mut [W::Scalar],
    post: &mut [[W::Scalar; C]],
) {
    let Some(p) = t.places.get(g) else {
        return;
    };
    let first = g * L;
    let real = t.decs.len().saturating_sub(first).min(L);
    let mut comps = [0usize; L];
    for (l, k) in comps.iter_mut().enumerate() {
        *k = first + l;
    }
    store_group(t, e, table, p, comps.get(..real).unwrap_or(&[]), val, post);
}

/// Streaming state: re-evaluates this template's components among `comps` (global
/// component indices, this template's being `first .. first + t.decs.len()`; others
/// and padding are skipped), `L` per call in lane groups assembled on the fly, and
/// stores their values and local posteriors like [`eval_group`].
#[inline(never)]
pub fn eval_components<
    W: Lanes,
    const L: usize,
    const NV: usize,
    const C: usize,
    const N: usize,
    I: Copy + Into<u64>,
>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    table: Option<&[[W::Scalar; C]; N]>,
    comps: &[I],
    first: usize,
    val: &mut [W::Scalar],
    post: &mut [[W::Scalar; C]],
) {
    let mut batch = [[0u16; NV]; L];
    let mut ks = [0usize; L];
    let mut n = 0;
    for &c in comps {
        let Some(k) = local_component(t, c, first) else {
            continue;
        };
        let Some(pl) = t.places.get(k / L).and_then(|g| g.get(k % L)) else {
            continue;
        };
        if let (Some(b), Some(o)) = (batch.get_mut(n), ks.get_mut(n)) {
            *b = *pl;
            *o = k;
        }
        n += 1;
        if n == L {
            store_group(t, e, table, &batch, &ks, val, post);
            n = 0;
        }
    }
    if n > 0 {
        store_group(t, e, table, &batch, ks.get(..n).unwrap_or(&[]), val, post);
    }
}

/// Template `t`'s index of global component `c` (`t`'s components being global
/// `first ..`), or `None` for another template's component or padding.
#[inline(always)]
fn local_component<W: Lanes, const L: usize, const NV: usize, const C: usize, I: Into<u64>>(
    t: &Tpl<W, L, NV, C>,
    c: I,
    first: usize,
) -> Option<usize> {
    let k = usize::try_from(c.into()).ok()?.checked_sub(first)?;
    (k < t.decs.len()).then_some(k)
}

/// Evaluates the lane group `p` and stores lane `l`'s value and local posteriors as
/// those of component `comps[l]` (lanes past `comps.len()` are dropped).
#[inline(always)]
fn store_group<W: Lanes, const L: usize, const NV: usize, const C: usize, const N: usize>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    table: Option<&[[W::Scalar; C]; N]>,
    p: &[[u16; NV]; L],
    comps: &[usize],
    val: &mut [W::Scalar],
    post: &mut [[W::Scalar; C]],
) {
    // Not through `post_group`: its returned arrays cost a 1.6 KB copy per update.
    let x = gather::<W, L, NV, C, N>(e, None, table, p);
    let mut pw = [[W::ZERO; C]; NV];
    let v = (t.post)(&x, &mut pw).to_lanes::<L>();
    for (&vl, &k) in v.iter().zip(comps) {
        if let Some(o) = val.get_mut(k) {
            *o = vl;
        }
    }
    for (i, pv) in pw.iter().enumerate() {
        let pv = class_lanes::<W, L, C>(pv);
        for (l, &k) in comps.iter().enumerate() {
            if let Some(o) = post.get_mut(k * NV + i) {
                for (oc, pc) in o.iter_mut().zip(&pv) {
                    *oc = pc.get(l).copied().unwrap_or(W::Scalar::ZERO);
                }
            }
        }
    }
}

/// Streaming state: multiplies every cached component value of a template into its
/// decompositions' accumulators.
#[inline(never)]
pub fn state_values<W: Lanes, const L: usize, const NV: usize, const C: usize, const D: usize>(
    t: &Tpl<W, L, NV, C>,
    val: &[W::Scalar],
    acc: &mut [Acc<W::Scalar>; D],
) {
    state_values_of(t.decs, val, t.log, acc);
}

/// [`state_values`] of the components with decomposition masks `masks` and values
/// `vals` (`log`: log-space values).
#[inline(always)]
fn state_values_of<T: Real, const D: usize>(
    masks: &[u64],
    vals: &[T],
    log: bool,
    acc: &mut [Acc<T>; D],
) {
    for (&mask, &v) in masks.iter().zip(vals) {
        accumulate(acc, mask, v, log);
    }
}

/// Components per partial product of the streaming state ([`chunk_values`]).
pub const VALUE_CHUNK: usize = 16;

/// Streaming state: the partial products, per decomposition, of every chunk of
/// [`VALUE_CHUNK`] cached component values of a template (`parts[c]` for components
/// `c·VALUE_CHUNK ..`), recomputed from the values.
#[inline(never)]
pub fn chunk_values<W: Lanes, const L: usize, const NV: usize, const C: usize, const D: usize>(
    t: &Tpl<W, L, NV, C>,
    val: &[W::Scalar],
    parts: &mut [[Acc<W::Scalar>; D]],
) {
    for (c, part) in parts.iter_mut().enumerate() {
        update_chunk(t, val, c, part);
    }
}

/// Streaming state: recomputes the partial products of the chunks holding this
/// template's components among `comps` (global indices, this template's from
/// `first`; ascending, so each chunk is recomputed once).
#[inline(never)]
pub fn update_chunks<
    W: Lanes,
    const L: usize,
    const NV: usize,
    const C: usize,
    const D: usize,
    I: Copy + Into<u64>,
>(
    t: &Tpl<W, L, NV, C>,
    comps: &[I],
    first: usize,
    val: &[W::Scalar],
    parts: &mut [[Acc<W::Scalar>; D]],
) {
    let mut last = usize::MAX;
    for &k in comps {
        let Some(k) = local_component(t, k, first) else {
            continue;
        };
        if k / VALUE_CHUNK == last {
            continue;
        }
        last = k / VALUE_CHUNK;
        if let Some(part) = parts.get_mut(last) {
            update_chunk(t, val, last, part);
        }
    }
}

/// The partial products of chunk `c` of a template's cached values.
#[inline(always)]
fn update_chunk<W: Lanes, const L: usize, const NV: usize, const C: usize, const D: usize>(
    t: &Tpl<W, L, NV, C>,
    val: &[W::Scalar],
    c: usize,
    part: &mut [Acc<W::Scalar>; D],
) {
    *part = [Acc::ONE; D];
    let start = c * VALUE_CHUNK;
    let end = (start + VALUE_CHUNK).min(t.decs.len());
    if let (Some(masks), Some(vals)) = (t.decs.get(start..end), val.get(start..)) {
        state_values_of(masks, vals, t.log, part);
    }
}

/// Streaming state: the decompositions' products from the partial products of every
/// chunk (each `m` in `[1, 2)`: the mantissas are multiplied, renormalising after every
/// 64 chunks, and the exponents and logs added).
#[inline(never)]
pub fn combine_chunks<T: Real, const D: usize>(parts: &[[Acc<T>; D]], acc: &mut [Acc<T>; D]) {
    for block in parts.chunks(64) {
        for part in block {
            for (a, p) in acc.iter_mut().zip(part) {
                a.m *= p.m;
                a.e = a.e.saturating_add(p.e);
                a.lg += p.lg;
            }
        }
        for a in acc.iter_mut() {
            a.mul(T::ONE);
        }
    }
}

/// Streaming state: adds every cached component's local posteriors, weighted by its
/// decompositions' posterior weights, into `out`.
#[inline(never)]
pub fn state_marginals<
    W: Lanes,
    const L: usize,
    const NV: usize,
    const C: usize,
    const N: usize,
    const D: usize,
>(
    t: &Tpl<W, L, NV, C>,
    post: &[[W::Scalar; C]],
    w: &[W::Scalar; D],
    out: &mut [[W::Scalar; C]; N],
) {
    let places = t.places.iter().flat_map(|g| g.iter());
    for ((&mask, pl), rows) in t.decs.iter().zip(places).zip(post.chunks_exact(NV)) {
        let wu = weight(w, mask);
        for (&q, r) in pl.iter().zip(rows) {
            if let Some(o) = out.get_mut(usize::from(q)) {
                for (oc, &pc) in o.iter_mut().zip(r) {
                    *oc += wu * pc;
                }
            }
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

/// Every place's marginal from the streaming state: `out[q] = Σ_d w_d ·
/// post[slots[q][d]]` (see [`mix_rows`]).
#[inline(never)]
pub fn mix_places<T: Real, const C: usize, const D: usize, const N: usize>(
    post: &[[T; C]],
    slots: &[[u32; D]; N],
    w: &[T; D],
    out: &mut [[T; C]; N],
) {
    for (o, s) in out.iter_mut().zip(slots) {
        mix_rows(post, s, w, o);
    }
}

/// `Σ_i w_i · rows[i]` over the given rows (out-of-range rows are skipped): one place's
/// marginal from the streaming state.
#[inline]
pub fn mix_rows<T: Real, const C: usize, const D: usize>(
    post: &[[T; C]],
    slots: &[u32; D],
    w: &[T; D],
    out: &mut [T; C],
) {
    // Summed in a local and stored once: a store into `out` after each row made the
    // host's mix of all places 1.45× slower (1.03 against 0.71 µs at 230 places).
    let mut acc = [T::ZERO; C];
    for (&s, &wd) in slots.iter().zip(w) {
        if let Some(r) = post.get(s as usize) {
            for (o, &v) in acc.iter_mut().zip(r) {
                *o += wd * v;
            }
        }
    }
    *out = acc;
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

    /// A one-variable template of 40 components (three chunks, the last partial) in
    /// three decompositions, some shared; its functions are never called here.
    fn chunked_template() -> Tpl<f32, 1, 1, 2> {
        fn unused(_: &[[f32; 2]; 1]) -> f32 {
            0.0
        }
        fn unused_post(_: &[[f32; 2]; 1], _: &mut [[f32; 2]; 1]) -> f32 {
            0.0
        }
        fn unused_mpe(_: &[[f32; 2]; 1], _: &mut [[u16; 1]; 1]) -> f32 {
            0.0
        }
        static PLACES: [[[u16; 1]; 1]; 40] = [[[0]]; 40];
        static DECS: [u64; 40] = {
            let mut d = [0u64; 40];
            let mut i = 0;
            while i < 40 {
                d[i] = [0b001, 0b010, 0b100, 0b011, 0b111][i % 5];
                i += 1;
            }
            d
        };
        Tpl {
            places: &PLACES,
            decs: &DECS,
            log: false,
            fwd: unused,
            post: unused_post,
            max: unused,
            mpe: unused_mpe,
        }
    }

    /// The state's chunked partial products give every decomposition's product (to
    /// the roundings of another multiplication order), and after values change,
    /// recomputing only their chunks gives exactly a full recomputation.
    #[test]
    fn chunk_products_match_the_full_product_and_update_exactly() {
        let t = chunked_template();
        let mut val = [0f32; 40];
        for (i, v) in val.iter_mut().enumerate() {
            *v = 0.5 + ((i * 37) % 17) as f32 / 10.0;
        }
        val[7] = 1e-30;
        let mut full = [Acc::ONE; 3];
        state_values(&t, &val, &mut full);
        let mut parts = [[Acc::ONE; 3]; 3];
        chunk_values(&t, &val, &mut parts);
        let mut acc = [Acc::ONE; 3];
        combine_chunks(&parts, &mut acc);
        for (a, f) in acc.iter().zip(&full) {
            assert!((a.ln() - f.ln()).abs() < 1e-4, "{} vs {}", a.ln(), f.ln());
        }
        // Components 3 and 35 (chunks 0 and 2) change; 99 and MAX are not this
        // template's and are skipped.
        val[3] = 3.0;
        val[35] = 1e-20;
        update_chunks(&t, &[3u16, 35, 99, u16::MAX], 0, &val, &mut parts);
        let mut fresh = [[Acc::ONE; 3]; 3];
        chunk_values(&t, &val, &mut fresh);
        for (p, f) in parts.iter().flatten().zip(fresh.iter().flatten()) {
            assert_eq!((p.m, p.e, p.lg), (f.m, f.e, f.lg));
        }
        // Offsets: the same components as global indices 100 + k.
        val[20] = 2.0;
        update_chunks(&t, &[120u32], 100, &val, &mut parts);
        chunk_values(&t, &val, &mut fresh);
        assert_eq!(
            (parts[1][0].m, parts[1][0].e),
            (fresh[1][0].m, fresh[1][0].e)
        );
    }
}
