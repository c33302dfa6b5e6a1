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
//! Every row is kept with the sum of its entries in `[1, 2)` (so its largest entry in
//! `[1/C, 2)`) by exact power-of-two scaling; the exponents are summed as integers per
//! forest, so a forest's value is `m · 2^k` with one rounding per multiplication and
//! no overflow however large the map. No `f64` arithmetic happens in `f32` code. (The
//! sum, not the largest entry, picks the scale: a few additions instead of `C`
//! compares, which cost four instructions each on a Cortex-M4F. Power-of-two scaling
//! is exact, so the choice changes no result.) On targets without an FPU (`SoftF32`
//! rows, [`Lanes::norm_by_max`]) the largest entry picks it instead, in integers (an
//! integer maximum of the bits, then the exponent field changed: a few instructions
//! per entry against a soft-float add and multiply), so there a row's largest entry
//! lies in `[1, 2)` and its sum in `[1, 2C)`; the ranges below hold with room to
//! spare. Those targets also compute messages in fixed point where the model allows
//! ([`FixedMatrices`], with its own error bound: see `fixed_messages.rs`).
//!
//! - Evidence: a place's factor is `φ = u ⊙ x^γ` with `x = α / 2^E` (`E` the binary
//!   exponent of the row's sum, or of its largest entry if the sum overflows: exact),
//!   or for a labelled place only the label's entry (`x_l = α_l / 2^{E_l}`). On SIMD
//!   hosts entries of `x` below `2^⌈(MIN_EXP + 20)/γ⌉` are flushed to 0 before the
//!   power ([`phi_flush_exp`]), so every nonzero entry of `x^γ` and of `φ` is normal.
//!   `φ`'s largest entry is at least `2^-20 · C^-γ ≥ 2^-84`. Scalar code folds `u` into
//!   the message matrices instead ([`TreeModel::folded`]): `φ = x^γ`, largest entry at
//!   least `C^-γ ≥ 2^-64`.
//! - Messages `ψ·b` need no flush: `ψ > 0` with a largest/smallest ratio `2^ρ` of at
//!   most `1e6 < 2^20` (checked by the model), so every entry of a message is at least
//!   `2^-ρ` of its largest, `2^-(ρ+8)` once normalised (`u` folded into a downward
//!   message's matrix, also checked at `1e6`, adds its own `2^-20`).
//! - Beliefs (products of `φ` and messages) are renormalised after every factor, so
//!   the largest entry of every product formed is at least `2^-113` (a leaf's `φ`
//!   times a downward message, see `full_below`), inside the normal range. On SIMD
//!   hosts entries below the smallest normal value `2^MIN_EXP` (`2^-126` in `f32`,
//!   `2^-1022` in `f64`) are flushed to 0 after every factor, as a CPU that flushes
//!   subnormals would: no subnormal is carried from one row operation to the next (an
//!   x86 CPU takes ~100 cycles per subnormal operand; a product of a tiny entry and a
//!   message can still round to a subnormal once, before its flush, which only
//!   evidence or neighbours that rule a class out by more than `2^90` cause). Scalar
//!   code (microcontrollers) does not flush: `C` compares per row cost more there than
//!   the rest of the row's work, and a Cortex-M FPU handles subnormals in hardware at
//!   full speed (or flushes them to zero when the firmware sets `FPSCR.FZ`; soft-float
//!   is exact either way). Its tiny entries keep gradual underflow's absolute error of
//!   at most `2^-150`, a flush below `2^-149` at worst. Both keep every normal entry, so
//!   SIMD and scalar code answer alike up to rounding (fixtures `trees_sharp_hubs_*`).
//!
//! **Error bound.** A belief at place `v` is `φ` times the messages of `v`'s children
//! (and, in marginals, the downward message), renormalised after each factor. An entry
//! dropped (flushed, or lost to underflow) when `r` of those factors are still to come
//! is at most `2^MIN_EXP` of its row's sum; each factor still to come can raise it
//! against the row's best class by at most its own largest/smallest ratio (`2^ρ`;
//! `2^(ρ+20)` for a downward message with `u` folded in), and the completed belief's
//! message `ψ·b` changes by at most `2^ρ` times the share of the belief it lost. So
//! such an entry changes the forest's value by at most `C · 2^(MIN_EXP + ρ·(r+1))`
//! relatively, and a pass over `n` places by at most `n` times the largest of those.
//! In `f32` with the largest potential ratio (`ρ = 20`), `C ≤ 256` and `n ≤ 65,535`
//! that is below `2^-26` (one rounding) while `r ≤ 2`; with `ρ = 12.3` (the demo
//! model), `C = 10` and `n ≤ 1,000` while `r ≤ 6`; in `f64` while `r ≤ 46`. Beyond
//! that, a class whose entry fell below `2^MIN_EXP` of its row can be lost where the
//! factors still to come favour it by more: this is the range of the precision, the
//! same on every target (scalar code reaches `2^-149` instead of `2^-126`), not a
//! flush rule. Exact zeros (evidence of probability zero) stay exact.
//!
//! # Passes
//!
//! - value (`tree_value` in `pass.rs`): one post-order sweep per forest with a stack of one row per
//!   depth (`O(height · C)` memory): `log_likelihood`, `labelled_log_likelihood`, and
//!   the max-product value of `mpe`;
//! - stored upward pass and downward pass (`pass.rs`): the messages of every place
//!   (`O(places · C)`), then marginals with a stack of one row per depth;
//! - MPE backtracking: a max-product sweep of the best forest keeping one arg-max byte
//!   per place and parent class, then labels top-down;
//! - the streaming state (`state.rs`) caches every forest's stored upward pass.

mod fixed_messages;
mod pass;
mod state;

pub use fixed_messages::*;
pub use pass::*;
pub use state::*;

use super::{Fused, Lanes, Real, above};

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
    /// The upward messages' matrix by columns (classes in lanes, padding lanes 0):
    /// `ψ·diag(u)` when [`TreeModel::folded`] (`psi_up[j]` holds `ψ(·, j) u(j)`, each
    /// product rounded once), else `ψ`; largest entry at most 1.
    pub psi_up: [[V; K]; C],
    /// The downward messages' matrix by columns: `diag(u)·ψ` when folded
    /// (`psi_down[j]` holds `u(·) ψ(·, j)`), else `ψ`.
    pub psi_down: [[V; K]; C],
    /// The unary potential `u` (padding lanes 0); largest entry 1.
    pub unary: [V; K],
    /// Where `u` enters. `false` (SIMD hosts): in every place's evidence factor `φ = u ⊙
    /// x^γ`, so the flush rule compares entries weighted by `u`. `true` (scalar code,
    /// which does not flush): `φ = x^γ`, and `u` is folded into the matrix of the
    /// message that leaves a place (upward) or enters it (downward), so only a root's
    /// belief is multiplied by `u`: `C` multiplies and loads fewer per evidence factor.
    pub folded: bool,
    /// 1 in padding lanes, 0 in class lanes (keeps divisions finite in padding).
    pub pad: [V; K],
    /// The evidence exponent `γ` (rows enter as `α^γ`).
    pub gamma: u32,
    /// `true`: marginals are the mean of the forests' exact marginals; `false`: the
    /// exact marginals of the mixture (each forest weighted by `P(t | α)`).
    pub average: bool,
    /// The forests, in mixture order.
    pub forests: &'static [Forest<V::Scalar>],
    /// Which entry points compute every place's `φ` once into a stack table.
    pub cache: FactorCache,
    /// The message matrices in Q0.32 where messages are computed in fixed point
    /// (targets without an FPU, when the model's bound allows: see
    /// [`FixedMatrices`]); `None`: `f32` messages.
    pub fixed: Option<FixedMatrices<C>>,
}

/// Which entry points first compute the evidence factor `φ` of every place once into a
/// table on the stack (`places · (C + 1)` scalars), shared by every forest's passes,
/// instead of computing it in each pass (a `T`-forest mixture computes each `φ` `T`
/// times in a value pass, `2T` times in `marginals`). The generator sets a flag when
/// the entry point's stack bound with the table fits the stack budget (always on SIMD
/// hosts); results are the same either way.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FactorCache {
    /// `log_likelihood`, `labelled_log_likelihood` and `mpe`.
    pub values: bool,
    /// The stateless `marginals`.
    pub marginals: bool,
    /// The streaming state's `marginals`.
    pub state: bool,
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

/// Scales `a` by a power of two so that the sum of its entries lies in `[1, 2)` (so its
/// largest entry lies in `[1/C, 2)`); returns the exponent `e` (the row before = the
/// row after `· 2^e`). A zero (or NaN) row is left as it is (`e = 0`). The row's sum
/// must lie in `[2^(MIN_EXP+1), 2^-MIN_EXP)` (every row the passes normalise does: see
/// the module docs). Lanes that rescale in integers ([`Lanes::norm_by_max`]: `SoftF32`)
/// put the largest entry in `[1, 2)` instead.
#[inline(always)]
pub(crate) fn norm<V: Lanes, const K: usize>(a: &mut [V; K]) -> i32 {
    if let Some(e) = V::norm_by_max(a) {
        return e;
    }
    let s = hsum(a);
    if !above(s, V::Scalar::ZERO) {
        return 0;
    }
    let (k, e) = s.normal_scale();
    scale(a, k);
    e
}

/// [`norm`], and on SIMD hosts entries below the smallest normal value `2^MIN_EXP`
/// (after scaling) flushed to zero, as a CPU that flushes subnormals would (see the
/// module docs: scalar code leaves tiny entries to the FPU, whose subnormal arithmetic
/// costs nothing extra on microcontrollers).
#[inline(always)]
pub(crate) fn norm_flush<V: Lanes, const K: usize>(a: &mut [V; K]) -> i32 {
    let e = norm(a);
    if V::WIDTH > 1 {
        let t = V::splat(V::Scalar::pow2(V::Scalar::MIN_EXP));
        for x in a.iter_mut() {
            *x = x.flush(t);
        }
    }
    e
}

/// `a ⊙= b`, then [`norm_flush`]: the product is formed in registers and `a` written
/// once.
#[inline(always)]
pub(crate) fn mul_norm<V: Lanes, const K: usize>(a: &mut [V; K], b: &[V; K]) -> i32 {
    let mut p = *a;
    mul(&mut p, b);
    let e = norm_flush(&mut p);
    *a = p;
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
    if V::WIDTH == 1 {
        return columns(psi, b, |o, c, s| c.mul_add(s, o));
    }
    // SIMD: even and odd classes in two accumulators (half the dependent chain of
    // multiply-adds), added at the end.
    let mut m = [[V::ZERO; K]; 2];
    each_class::<V, K, C>(b, |j, x| {
        if let (Some(col), Some(acc)) = (psi.get(j), m.get_mut(j % 2)) {
            let s = V::splat(x);
            for (o, &c) in acc.iter_mut().zip(col) {
                *o = c.mul_add(s, *o);
            }
        }
    });
    let [mut even, odd] = m;
    for (o, &x) in even.iter_mut().zip(&odd) {
        *o += x;
    }
    even
}

/// The upward message of a place whose belief is `b`: `ψ_up·b` normalised, and its
/// exponent (fixed point where the model has [`FixedMatrices`] and the lanes that
/// path, else [`matvec`] and [`norm`]).
#[inline(always)]
pub(crate) fn up_message<V: Lanes, const C: usize, const K: usize>(
    m: &TreeModel<V, C, K>,
    b: &[V; K],
) -> ([V; K], i32) {
    if let Some(r) = m.fixed.as_ref().and_then(|fx| V::fixed_message(&fx.up, b)) {
        return r;
    }
    let mut msg = matvec(&m.psi_up, b);
    let e = norm(&mut msg);
    (msg, e)
}

/// The downward message `ψ_down·r` up to a positive factor (its scale is never used:
/// the belief it multiplies is normalised), fixed point as in [`up_message`].
#[inline(always)]
pub(crate) fn down_message<V: Lanes, const C: usize, const K: usize>(
    m: &TreeModel<V, C, K>,
    r: &[V; K],
) -> [V; K] {
    match m
        .fixed
        .as_ref()
        .and_then(|fx| V::fixed_message(&fx.down, r))
    {
        Some((msg, _)) => msg,
        None => matvec(&m.psi_down, r),
    }
}

/// The max-product upward message of a place whose belief is `b`: `max_j ψ_up(a, j)
/// b(j)` normalised, and its exponent; with `arg`, `arg[a]` gets the smallest `j`
/// attaining it. Fixed point as in [`up_message`] (within `η`: see
/// `fixed_messages.rs`), else [`maxvec`] / [`argvec`] and [`norm`].
#[inline(always)]
pub(crate) fn max_message<V: Lanes, const C: usize, const K: usize>(
    m: &TreeModel<V, C, K>,
    b: &[V; K],
    arg: Option<&mut [u8; C]>,
) -> ([V; K], i32) {
    let mut spare = [0u8; C];
    let wanted = arg.is_some();
    let arg = arg.unwrap_or(&mut spare);
    if let Some(r) = m
        .fixed
        .as_ref()
        .and_then(|fx| V::fixed_max_message(&fx.up, b, arg))
    {
        return r;
    }
    let mut msg = if wanted {
        argvec(&m.psi_up, b, arg)
    } else {
        maxvec(&m.psi_up, b)
    };
    let e = norm(&mut msg);
    (msg, e)
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
pub(crate) fn pack<V: Lanes, const C: usize, const K: usize>(row: &[V::Scalar; C]) -> [V; K] {
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

/// `x · 2^-e` for every entry, in two exact steps ([`Real::pow2_pair`]; `phi` calls it
/// only for a sum outside [`Real::scalable`]'s range, where `2^-e` alone leaves the
/// normal range). Inlined: out of line, the call costs Cortex-M4F tree `marginals` 1.9%
/// more instructions (saved registers in every pass that inlines `phi`).
#[inline(always)]
fn scale_pow2<V: Lanes, const K: usize>(x: &mut [V; K], e: i32) {
    let (a, b) = V::Scalar::pow2_pair(-e);
    scale(x, a);
    scale(x, b);
}

/// The binary exponent below which SIMD hosts flush an entry of `x` (a row scaled to a
/// sum in `[1, 2)`) before `φ = u ⊙ x^γ`: `⌈(MIN_EXP + 20) / γ⌉`, so every nonzero
/// `x^k` (`k ≤ γ`) and `φ` entry is normal (`u ≥ 2^-20`), and nothing normal that `φ`
/// could hold is dropped.
#[inline(always)]
pub(crate) fn phi_flush_exp<T: Real>(gamma: u32) -> i32 {
    // Integer division truncates towards zero: the ceiling of a negative quotient.
    (T::MIN_EXP + 20) / gamma.max(1) as i32
}

/// The evidence factor `φ` of a place (see the module docs) and its exponent: the
/// exact factor is `φ · 2^e`. Not normalised: its largest entry lies in
/// `[2^-20 · C^-γ, 2^γ)` (`x`'s in `[1/C, 2)`, `u`'s in `[2^-20, 1]`; without `u` when
/// [`TreeModel::folded`]); on SIMD hosts every nonzero entry is normal (see
/// [`phi_flush_exp`]). `label < C` keeps only that class.
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
        // The sum's exponent (the largest entry's if the sum overflows, or where the
        // lanes scale by it in integers).
        let e = match V::norm_by_max(&mut x) {
            Some(e) => e,
            None => {
                let s = hsum(&x);
                if s.scalable() {
                    let (k, e) = s.normal_scale();
                    scale(&mut x, k);
                    e
                } else {
                    let (_, e) = if s.is_finite() { s } else { hmax(&x) }.split();
                    scale_pow2(&mut x, e);
                    e
                }
            }
        };
        if V::WIDTH > 1 {
            let t = V::splat(V::Scalar::pow2(phi_flush_exp::<V::Scalar>(m.gamma)));
            for v in x.iter_mut() {
                *v = v.flush(t);
            }
        }
        (x, e)
    };
    // `x^γ`, unrolled for the usual exponents (no loop-carried copy of `x`).
    let base = x;
    match m.gamma {
        0 | 1 => {}
        2 => mul(&mut x, &base),
        3 => {
            mul(&mut x, &base);
            mul(&mut x, &base);
        }
        g => {
            for _ in 1..g {
                mul(&mut x, &base);
            }
        }
    }
    if !m.folded {
        mul(&mut x, &m.unary);
    }
    (x, (m.gamma as i32).wrapping_mul(e))
}

/// `φ` of a labelled place whose label's value is `mant · 2^e` (`label < C`, `mant`
/// normal), given exactly: the streaming state passes a label its fused row reads as 0
/// this way. [`phi`] of the one-hot row of `mant`, its exponent raised by `γ·e`.
#[inline(always)]
pub(crate) fn phi_of_label<V: Lanes, const C: usize, const K: usize>(
    m: &TreeModel<V, C, K>,
    label: usize,
    mant: V::Scalar,
    e: i32,
) -> ([V; K], i32) {
    let mut one = [V::Scalar::ZERO; C];
    if let Some(o) = one.get_mut(label) {
        *o = mant;
    }
    let (x, k) = phi(m, &one, label as u16);
    (x, k.wrapping_add((m.gamma as i32).wrapping_mul(e)))
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

/// `φ` of every place computed once, with its exponent (see [`FactorCache`]).
pub(crate) struct Cached<'a, V: Lanes, const K: usize, const N: usize> {
    pub table: &'a [([V; K], i32); N],
}

impl<V: Lanes, const K: usize, const N: usize> Factors<V, K> for Cached<'_, V, K, N> {
    #[inline(always)]
    fn factor(&self, v: usize) -> ([V; K], i32) {
        self.table.get(v).copied().unwrap_or(([V::ZERO; K], 0))
    }
}

/// Every place's `φ` and exponent from `src` into `table` (for [`Cached`]).
#[inline(never)]
pub(crate) fn fill<V: Lanes, const K: usize, const N: usize>(
    src: &impl Factors<V, K>,
    table: &mut [([V; K], i32); N],
) {
    for (v, t) in table.iter_mut().enumerate() {
        *t = src.factor(v);
    }
}

/// [`Rows`] of the streaming state with labels, where a label the state's row reads as
/// 0 (a class fused below the smallest normal value of the best) takes its exact fused
/// value ([`phi_of_label`]): a labelled place's factor is its label's value alone.
pub(crate) struct FusedLabels<'a, V: Lanes, const C: usize, const K: usize, const N: usize> {
    pub rows: Rows<'a, V, C, K, N>,
    pub fused: &'a [Fused<V::Scalar, C>; N],
}

impl<V: Lanes, const C: usize, const K: usize, const N: usize> Factors<V, K>
    for FusedLabels<'_, V, C, K, N>
{
    #[inline(always)]
    fn factor(&self, v: usize) -> ([V; K], i32) {
        let label = self
            .rows
            .labels
            .and_then(|l| l.get(v))
            .copied()
            .unwrap_or(NONE);
        let lab = usize::from(label);
        let flushed = self.rows.e.get(v).zip(self.fused.get(v));
        match flushed.and_then(|(row, f)| f.flushed_label(row, lab)) {
            Some((mant, e)) => phi_of_label(self.rows.m, lab, mant, e),
            None => self.rows.factor(v),
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
            k = k.wrapping_add(mul_norm(&mut b, mc));
        }
    }
    (b, k)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The number of value sweeps side by side follows its documented rule (the
    /// generator's stack bound multiplies by the same number): one in scalar code, else
    /// four, two or one as their stacks of rows fit within the places.
    #[test]
    fn parallel_sweeps_fit_their_rows_within_the_places() {
        assert_eq!(parallel_sweeps(1, 1000, 5), 1);
        for (places, rows, p) in [(40, 10, 4), (39, 10, 2), (20, 10, 2), (19, 10, 1)] {
            assert_eq!(
                parallel_sweeps(8, places, rows),
                p,
                "{places} places, {rows} rows"
            );
        }
    }

    /// `φ`'s flush on SIMD hosts keeps `x^γ` normal after the unary potential (`≥
    /// 2^-20`) and drops nothing above that: the threshold is the ceiling of `(MIN_EXP
    /// + 20) / γ`, in both precisions.
    #[test]
    fn phi_flushes_exactly_what_would_leave_the_normal_range() {
        fn check<T: Real>() {
            let floor = T::MIN_EXP + 20;
            for gamma in 1..=8u32 {
                let t = phi_flush_exp::<T>(gamma);
                let g = gamma as i32;
                assert!(
                    t * g >= floor,
                    "γ = {gamma}: 2^{t} to the γ leaves the range"
                );
                assert!((t - 1) * g < floor, "γ = {gamma}: 2^{} would fit", t - 1);
            }
        }
        check::<f32>();
        check::<f64>();
    }

    /// `argmax` keeps the lowest class on ties, and answers 0 for a zero row, as its
    /// documentation says (through the API a tie only picks another labelling of the
    /// same value).
    #[test]
    fn argmax_keeps_the_lowest_of_equal_classes() {
        assert_eq!(argmax::<f32, 4>(&[0.5, 2.0, 2.0, 1.0]), 1);
        assert_eq!(argmax::<f32, 3>(&[0.0; 3]), 0);
        assert_eq!(argmax::<f64, 3>(&[0.25, 0.125, 0.5]), 2);
    }
}
