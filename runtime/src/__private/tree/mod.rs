//! The generic driver of generated tree-mixture code: exact sum-product (and
//! max-product) message passing in the spanning forests of a compiled map.
//!
//! A generated module holds one [`TreeModel`]: the shared pairwise potential `ψ` (by
//! columns) and unary potential `u`, both scaled to a largest entry of 1, the evidence
//! exponent `γ`, how marginals are mixed, and per forest a [`Forest`] of `static`
//! tables (a depth-first post-order with depths, parents, children, roots, `ln Z_t`).
//! Everything here runs over those tables; the loops' trip counts never depend on the
//! evidence. A *row* of class values is `[V; K]`: `V` a lane vector holding
//! [`Lanes::WIDTH`] classes (`V = f32`, `K = C` on microcontrollers; `V = f32x8`,
//! `K = ⌈C/8⌉` with zero padding lanes on hosts with SIMD).
//!
//! # Numerics (the flush rule and its error bound)
//!
//! Every row is kept with its largest entry in `[1, 2)` by exact power-of-two scaling;
//! the exponents are summed as integers per forest, so a forest's value is
//! `m · 2^k` with one rounding per multiplication and no overflow or underflow however
//! large the map. No `f64` arithmetic happens in `f32` code.
//!
//! - Evidence: a place's factor is `φ = u ⊙ x^γ` with `x = α / 2^E` (`E` the binary
//!   exponent of the row's largest entry: exact), or for a labelled place only the
//!   label's entry (`x_l = α_l / 2^{E_l}`). Entries of `x` below `2^⌈TINY_EXP/γ⌉` are
//!   flushed to 0 before the power, so every nonzero `x^γ` is at least `2^TINY_EXP`
//!   and every nonzero entry of `φ` at least `2^(TINY_EXP - 20)`.
//! - Messages `ψ·b` need no flush: `ψ > 0` with a largest/smallest ratio of at most
//!   `1e6 < 2^20` (checked by the model), so every entry of a normalised message is at
//!   least `2^-20`.
//! - Beliefs (products of `φ` and messages) are renormalised after every factor and
//!   entries below `2^TINY_EXP` (`2^-80` in `f32`, `2^-600` in `f64`) are flushed to 0.
//!   Nothing ever becomes subnormal: the smallest nonzero product formed is
//!   `2^TINY_EXP · 2^-20 · 2^-20`, far above the normal range's end.
//!
//! A flushed entry `b(c)` of a belief at place `v` changes the forest's value `Σ_c
//! b(c)·R(c)` by at most `C · 2^TINY_EXP · 2^20` relatively (the rest of the forest,
//! `R`, varies by at most the potential ratio across classes), so a whole pass over
//! `n` places changes by at most `4·n·C·2^(TINY_EXP+20)` relatively (`≤ 2^-39` in `f32`
//! for the largest maps the generator accepts, `n ≤ 65,535`, `C ≤ 256`): far below
//! one rounding. Exact zeros (evidence of probability zero) stay exact.
//!
//! # Passes
//!
//! - value ([`tree_value`]): one post-order sweep per forest with a stack of one row per
//!   depth (`O(height · C)` memory): `log_likelihood`, `labelled_log_likelihood`, and
//!   the max-product value of `mpe`;
//! - stored upward pass and downward pass (`pass.rs`): the messages of every place
//!   (`O(places · C)`), then marginals with a stack of one row per depth;
//! - MPE backtracking: a max-product sweep of the best forest keeping one arg-max byte
//!   per place and parent class, then labels top-down;
//! - the streaming state (`state.rs`) caches every forest's stored upward pass.

mod pass;
mod state;

pub use pass::*;
pub use state::*;

use super::{Lanes, Real, above};

/// The "no label" / "no parent" marker of the tables.
pub const NONE: u16 = u16::MAX;

/// One spanning forest of a compiled map: `static` tables of place indices.
pub struct Forest<T> {
    /// Depth-first post-order of every place with its depth (roots: 0): children
    /// before their parent; its reverse is a pre-order in which each subtree is
    /// contiguous (so a node's parent is the last node seen one level up).
    pub post: &'static [[u16; 2]],
    /// Parent of every place ([`NONE`] for a root).
    pub parent: &'static [u16],
    /// The children of place `v` are `kids[kid_start[v]..kid_start[v + 1]]`.
    pub kid_start: &'static [u16],
    /// Children lists, see [`Forest::kid_start`].
    pub kids: &'static [u16],
    /// The roots (one per connected component of the map).
    pub roots: &'static [u16],
    /// `ln Z_t = z_exp · ln 2 + z_rem`: the forest's value without evidence (with the
    /// scaled potentials as the generated code rounds them).
    pub z_exp: i32,
    /// See [`Forest::z_exp`].
    pub z_rem: T,
}

impl<T> Forest<T> {
    /// The children of place `v` (empty when out of range).
    #[inline(always)]
    pub fn kids_of(&self, v: usize) -> &'static [u16] {
        match (self.kid_start.get(v), self.kid_start.get(v + 1)) {
            (Some(&a), Some(&b)) => self.kids.get(usize::from(a)..usize::from(b)).unwrap_or(&[]),
            _ => &[],
        }
    }

    /// The parent of place `v` ([`NONE`] for a root or out of range).
    #[inline(always)]
    pub fn parent_of(&self, v: usize) -> u16 {
        self.parent.get(v).copied().unwrap_or(NONE)
    }
}

/// A tree mixture compiled for one map: potentials, evidence exponent, mixing and the
/// forests (see the module docs).
pub struct TreeModel<V: Lanes, const C: usize, const K: usize> {
    /// `ψ` by columns: `psi[j]` holds `ψ(·, j)` (classes in lanes, padding lanes 0);
    /// largest entry 1.
    pub psi: [[V; K]; C],
    /// The unary potential `u` (padding lanes 0); largest entry 1.
    pub unary: [V; K],
    /// 1 in padding lanes, 0 in class lanes (keeps divisions finite in padding).
    pub pad: [V; K],
    /// The evidence exponent `γ` (rows enter as `α^γ`).
    pub gamma: u32,
    /// `true`: marginals are the mean of the forests' exact marginals; `false`: the
    /// exact marginals of the mixture (each forest weighted by `P(t | α)`).
    pub average: bool,
    /// The forests, in mixture order.
    pub forests: &'static [Forest<V::Scalar>],
}

/// `a ⊙= b`.
#[inline(always)]
pub(crate) fn mul<V: Lanes, const K: usize>(a: &mut [V; K], b: &[V; K]) {
    for (x, &y) in a.iter_mut().zip(b) {
        *x = *x * y;
    }
}

/// `a *= s` for a scalar `s`.
#[inline(always)]
fn scale<V: Lanes, const K: usize>(a: &mut [V; K], s: V::Scalar) {
    let s = V::splat(s);
    for x in a.iter_mut() {
        *x = *x * s;
    }
}

/// Largest entry of a row (`0` for a row of zeros; padding lanes are 0).
#[inline(always)]
pub(crate) fn hmax<V: Lanes, const K: usize>(a: &[V; K]) -> V::Scalar {
    V::max_of(a).hmax()
}

/// Sum of the entries of a row.
#[inline(always)]
pub(crate) fn hsum<V: Lanes, const K: usize>(a: &[V; K]) -> V::Scalar {
    V::sum(a).hsum()
}

/// Index of the largest entry of a row (lowest class on ties; 0 for a zero row).
#[inline(always)]
pub(crate) fn argmax<V: Lanes, const K: usize>(a: &[V; K]) -> u16 {
    let (mut best, mut arg) = (V::Scalar::ZERO, 0u16);
    for (c, &x) in a.iter().flat_map(|v| v.lanes()).enumerate() {
        if x > best {
            best = x;
            arg = c as u16;
        }
    }
    arg
}

/// Scales `a` by a power of two so that its largest entry lies in `[1, 2)`; returns
/// the exponent `e` (the row before = the row after `· 2^e`). A zero (or NaN) row is
/// left as it is (`e = 0`).
#[inline(always)]
pub(crate) fn norm<V: Lanes, const K: usize>(a: &mut [V; K]) -> i32 {
    let m = hmax(a);
    if !above(m, V::Scalar::ZERO) {
        return 0;
    }
    let (_, e) = m.split();
    scale(a, V::Scalar::pow2(-e));
    e
}

/// [`norm`], and entries below `2^TINY_EXP` (after scaling) flushed to zero (see the
/// module docs), in one sweep.
#[inline(always)]
pub(crate) fn norm_flush<V: Lanes, const K: usize>(a: &mut [V; K]) -> i32 {
    let m = hmax(a);
    if !above(m, V::Scalar::ZERO) {
        return 0;
    }
    let (_, e) = m.split();
    let (s, t) = (
        V::splat(V::Scalar::pow2(-e)),
        V::splat(V::Scalar::pow2(V::Scalar::TINY_EXP)),
    );
    for x in a.iter_mut() {
        *x = (*x * s).flush(t);
    }
    e
}

/// Calls `f(j, b_j)` for every class `j` of row `b` (its scalar entries).
#[inline(always)]
fn each_class<V: Lanes, const K: usize, const C: usize>(
    b: &[V; K],
    mut f: impl FnMut(usize, V::Scalar),
) {
    for (k, v) in b.iter().enumerate() {
        let lanes = v.lanes();
        for l in 0..V::WIDTH {
            let j = k * V::WIDTH + l;
            if j >= C {
                return;
            }
            if let Some(&x) = lanes.get(l) {
                f(j, x);
            }
        }
    }
}

/// `m(a) = ⊕_j ψ(a, j) b(j)` column by column, with `⊕` given by `add(acc, ψ(·, j),
/// b(j))` per lane vector.
#[inline(always)]
fn columns<V: Lanes, const C: usize, const K: usize>(
    psi: &[[V; K]; C],
    b: &[V; K],
    add: impl Fn(V, V, V) -> V,
) -> [V; K] {
    let mut m = [V::ZERO; K];
    each_class::<V, K, C>(b, |j, x| {
        if let Some(col) = psi.get(j) {
            let s = V::splat(x);
            for (o, &c) in m.iter_mut().zip(col) {
                *o = add(*o, c, s);
            }
        }
    });
    m
}

/// `ψ·b`: `m(a) = Σ_j ψ(a, j) b(j)`, column by column (one multiply-add per class pair;
/// `V = f32` on microcontrollers: a multiply and an add, never fused).
#[inline(always)]
pub(crate) fn matvec<V: Lanes, const C: usize, const K: usize>(
    psi: &[[V; K]; C],
    b: &[V; K],
) -> [V; K] {
    columns(psi, b, |o, c, s| c.mul_add(s, o))
}

/// Max-product `ψ·b`: `m(a) = max_j ψ(a, j) b(j)`.
#[inline(always)]
pub(crate) fn maxvec<V: Lanes, const C: usize, const K: usize>(
    psi: &[[V; K]; C],
    b: &[V; K],
) -> [V; K] {
    columns(psi, b, |o, c, s| o.max(c * s))
}

/// [`maxvec`] and its arg-max: `arg[a]` is the smallest `j` attaining `m(a)`.
#[inline(always)]
pub(crate) fn argvec<V: Lanes, const C: usize, const K: usize>(
    psi: &[[V; K]; C],
    b: &[V; K],
    arg: &mut [u8; C],
) -> [V; K] {
    let mut m = [V::ZERO; K];
    let mut code = [V::ZERO; K];
    each_class::<V, K, C>(b, |j, x| {
        if let Some(col) = psi.get(j) {
            let (s, cj) = (V::splat(x), V::splat(V::Scalar::from_index(j)));
            for ((o, a), &c) in m.iter_mut().zip(code.iter_mut()).zip(col) {
                V::arg_max(o, a, c * s, cj);
            }
        }
    });
    for (o, &c) in arg
        .iter_mut()
        .zip(code.iter().flat_map(|v| v.lanes()).take(C))
    {
        *o = c.index() as u8;
    }
    m
}

/// The lanes of `row` packed into a row of vectors (padding lanes 0).
#[inline(always)]
fn pack<V: Lanes, const C: usize, const K: usize>(row: &[V::Scalar; C]) -> [V; K] {
    let mut out = [V::ZERO; K];
    for (k, o) in out.iter_mut().enumerate() {
        let mut a = [V::Scalar::ZERO; 8];
        for (d, &s) in a
            .iter_mut()
            .zip(row.iter().skip(k * V::WIDTH))
            .take(V::WIDTH)
        {
            *d = s;
        }
        *o = V::from_lanes(&a);
    }
    out
}

/// `x · 2^-e` for every entry (two exact steps when `2^-e` alone would leave the
/// normal range).
#[inline(always)]
fn scale_pow2<V: Lanes, const K: usize>(x: &mut [V; K], e: i32) {
    if e.unsigned_abs() > 100 {
        let h = e / 2;
        scale(x, V::Scalar::pow2(-h));
        scale(x, V::Scalar::pow2(h - e));
    } else {
        scale(x, V::Scalar::pow2(-e));
    }
}

/// The evidence factor `φ` of a place (see the module docs) and its exponent: the
/// exact factor is `φ · 2^e`. Not normalised: its largest entry lies in
/// `[2^-20, 2^γ)` (`x`'s in `[1, 2)`, `u`'s in `[2^-20, 1]`), every nonzero entry is at
/// least `2^(TINY_EXP - 20)`. `label < C` keeps only that class.
#[inline(always)]
pub(crate) fn phi<V: Lanes, const C: usize, const K: usize>(
    m: &TreeModel<V, C, K>,
    row: &[V::Scalar; C],
    label: u16,
) -> ([V; K], i32) {
    let zero = V::Scalar::ZERO;
    let lab = usize::from(label);
    let (mut x, e) = if lab < C {
        let (mant, e) = row.get(lab).copied().unwrap_or(zero).split();
        let mut one = [zero; C];
        if let Some(o) = one.get_mut(lab) {
            *o = mant;
        }
        (pack::<V, C, K>(&one), e)
    } else {
        let mut x = pack::<V, C, K>(row);
        let (_, e) = hmax(&x).split();
        scale_pow2(&mut x, e);
        let t = V::splat(V::Scalar::pow2(V::Scalar::TINY_EXP / m.gamma.max(1) as i32));
        for v in x.iter_mut() {
            *v = v.flush(t);
        }
        (x, e)
    };
    let base = x;
    for _ in 1..m.gamma {
        mul(&mut x, &base);
    }
    mul(&mut x, &m.unary);
    (x, (m.gamma as i32).wrapping_mul(e))
}

/// Where the passes take each place's evidence factor `φ` (and its exponent) from.
pub(crate) trait Factors<V: Lanes, const K: usize> {
    /// `φ` of place `v` and its exponent (see [`phi`]); zeros when out of range.
    fn factor(&self, v: usize) -> ([V; K], i32);
}

/// `φ` computed from the evidence rows when needed (labels: places `< C` restricted).
pub(crate) struct Rows<'a, V: Lanes, const C: usize, const K: usize, const N: usize> {
    pub m: &'a TreeModel<V, C, K>,
    pub e: &'a [[V::Scalar; C]; N],
    pub labels: Option<&'a [u16; N]>,
}

impl<V: Lanes, const C: usize, const K: usize, const N: usize> Factors<V, K>
    for Rows<'_, V, C, K, N>
{
    #[inline(always)]
    fn factor(&self, v: usize) -> ([V; K], i32) {
        let label = self.labels.and_then(|l| l.get(v)).copied().unwrap_or(NONE);
        match self.e.get(v) {
            Some(row) => phi(self.m, row, label),
            None => ([V::ZERO; K], 0),
        }
    }
}

/// `φ` of every place computed once (SIMD hosts: the passes of all forests share it).
pub(crate) struct Cached<'a, V: Lanes, const K: usize, const N: usize> {
    pub phi: &'a [[V; K]; N],
    pub exp: &'a [i32; N],
}

impl<V: Lanes, const K: usize, const N: usize> Factors<V, K> for Cached<'_, V, K, N> {
    #[inline(always)]
    fn factor(&self, v: usize) -> ([V; K], i32) {
        match (self.phi.get(v), self.exp.get(v)) {
            (Some(&p), Some(&x)) => (p, x),
            _ => ([V::ZERO; K], 0),
        }
    }
}

impl<V: Lanes, const C: usize, const K: usize, const N: usize> Rows<'_, V, C, K, N> {
    /// Every place's `φ` into `phi` and `exp` (for [`Cached`]).
    #[inline(never)]
    pub fn fill(&self, phi: &mut [[V; K]; N], exp: &mut [i32; N]) {
        for (v, (p, x)) in phi.iter_mut().zip(exp.iter_mut()).enumerate() {
            (*p, *x) = self.factor(v);
        }
    }
}

/// The belief of place `v` in forest `f`: `φ_v ⊙ Π_children m_c` with the children's
/// messages from `msgs`, normalised (flushed after every factor), and its exponent.
#[inline(always)]
pub(crate) fn belief<V: Lanes, const K: usize, const N: usize>(
    src: &dyn Factors<V, K>,
    f: &Forest<V::Scalar>,
    msgs: &[[V; K]; N],
    v: usize,
) -> ([V; K], i32) {
    let (mut b, mut k) = src.factor(v);
    for &c in f.kids_of(v) {
        if let Some(mc) = msgs.get(usize::from(c)) {
            mul(&mut b, mc);
            k = k.wrapping_add(norm_flush(&mut b));
        }
    }
    (b, k)
}
