//! The stateless passes of generated tree-mixture code: log-likelihood (labelled or
//! not), marginals and MPE (see the module docs of `tree`). Where the generator chose
//! to ([`FactorCache`](super::FactorCache): always on SIMD hosts, on microcontrollers when the table fits
//! the stack budget) an entry point first computes the evidence factor `φ` of every
//! place once ([`Cached`]: `O(places · C)` scratch), which every forest's passes then
//! share; otherwise each pass computes `φ` where it needs it ([`Rows`]).

use super::super::{Acc, Lanes, Real, above, best, mix};
use super::{
    Cached, Factors, Forest, Rows, TreeModel, argmax, belief, down_message, fill, hmax, hsum,
    max_message, mul, mul_norm, pack, up_message,
};
use crate::EvidenceError;

impl<V: Lanes, const C: usize, const K: usize> TreeModel<V, C, K> {
    /// `u` where a root's belief still needs it (folded models), else `None`.
    #[inline(always)]
    pub(crate) fn root_unary(&self) -> Option<&[V; K]> {
        self.folded.then_some(&self.unary)
    }

    /// A root's belief `b` with `u` multiplied in where the evidence factor left it out.
    #[inline(always)]
    pub(crate) fn root_belief(&self, mut b: [V; K]) -> [V; K] {
        if let Some(u) = self.root_unary() {
            mul(&mut b, u);
        }
        b
    }
}

/// `acc · 2^(k - z_exp) · e^(-z_rem)`: a forest's value over its `Z_t`.
#[inline(always)]
pub(crate) fn over_z<T: Real>(mut acc: Acc<T>, k: i32, f: &Forest<T>) -> Acc<T> {
    acc.mul_pow2(k.wrapping_sub(f.z_exp));
    acc.mul_log(T::ZERO - f.z_rem);
    acc
}

/// Runs `body` with the factor source the generator chose for the entry point:
/// [`Cached`] (`cache`: every `φ` computed once into a table on the stack, `O(places ·
/// C)` bytes, which every forest's passes then share) or [`Rows`] (each pass computes
/// `φ` where it needs it: no table).
#[inline(always)]
pub(crate) fn with_factors<V: Lanes, const C: usize, const K: usize, const N: usize, R>(
    m: &TreeModel<V, C, K>,
    e: &[[V::Scalar; C]; N],
    labels: Option<&[u16; N]>,
    cache: bool,
    body: impl FnOnce(&dyn Factors<V, K>) -> R,
) -> R {
    let rows = Rows { m, e, labels };
    if cache {
        cached::<V, K, N, R>(&rows, body)
    } else {
        body(&rows)
    }
}

/// [`with_factors`] with the table (its own frame holds it).
#[inline(never)]
pub(crate) fn cached<V: Lanes, const K: usize, const N: usize, R>(
    src: &impl Factors<V, K>,
    body: impl FnOnce(&dyn Factors<V, K>) -> R,
) -> R {
    let mut table = [([V::ZERO; K], 0i32); N];
    fill(src, &mut table);
    body(&Cached { table: &table })
}

/// One post-order sweep of forest `f` with a stack of `H` rows (`H` > the forest's
/// height + 1): the belief of every place (`φ` of the place, then its children's
/// messages multiplied in as they complete, exactly the order of [`belief`]) goes to
/// `root(v, b)` for a root and to `message(v, b)` otherwise, whose result (normalised,
/// with its exponent) is multiplied into the parent's belief. Returns the sum of the
/// exponents of every normalisation.
#[inline(always)]
fn sweep<V: Lanes, const K: usize, const H: usize>(
    src: &dyn Factors<V, K>,
    f: &Forest<V::Scalar>,
    unary: Option<&[V; K]>,
    mut message: impl FnMut(usize, &[V; K]) -> ([V; K], i32),
    mut root: impl FnMut(usize, &[V; K]),
) -> i32 {
    let mut s = Sweep::<V, K, H>::new();
    let mut k = 0i32;
    for &vd in f.post {
        s.step((src, f, unary), vd, &mut k, &mut message, &mut root);
    }
    k
}

/// What a [`sweep`] runs over: the evidence factors, the forest and the roots' unary
/// row (three arguments, not fields of [`Sweep`]: as fields they cost Cortex-M4F code
/// 1.5% more instructions).
type SweepOf<'a, V, const K: usize> = (
    &'a dyn Factors<V, K>,
    &'a Forest<<V as Lanes>::Scalar>,
    Option<&'a [V; K]>,
);

/// The state of a [`sweep`]: the rows of the places whose parent is not complete yet
/// (one per depth). The sum of the exponents is the caller's (`k` of [`Sweep::step`]:
/// a local there, which microcontroller code keeps in a register).
struct Sweep<V: Lanes, const K: usize, const H: usize> {
    slots: [[V; K]; H],
    has: [bool; H],
}

impl<V: Lanes, const K: usize, const H: usize> Sweep<V, K, H> {
    #[inline(always)]
    fn new() -> Self {
        Sweep {
            slots: [[V::ZERO; K]; H],
            has: [false; H],
        }
    }

    /// One place `[v, d]` of the post-order of forest `f` (see [`sweep`]); adds the
    /// exponents of its normalisations to `k`.
    #[inline(always)]
    fn step(
        &mut self,
        (src, f, unary): SweepOf<'_, V, K>,
        [v, d]: [u16; 2],
        k: &mut i32,
        message: &mut impl FnMut(usize, &[V; K]) -> ([V; K], i32),
        root: &mut impl FnMut(usize, &[V; K]),
    ) {
        let (v, d) = (usize::from(v), usize::from(d));
        let factor = |v: usize, k: &mut i32| {
            let (b, eb) = src.factor(v);
            *k = k.wrapping_add(eb);
            b
        };
        let b = match (self.has.get_mut(d + 1), self.slots.get(d + 1)) {
            (Some(h), Some(s)) if *h => {
                *h = false;
                *s
            }
            _ => factor(v, k),
        };
        if d == 0 {
            let mut r = b;
            if let Some(u) = unary {
                mul(&mut r, u);
            }
            root(v, &r);
            return;
        }
        let (msg, e) = message(v, &b);
        *k = k.wrapping_add(e);
        if let (Some(h), Some(s)) = (self.has.get_mut(d), self.slots.get_mut(d)) {
            // The parent's row so far (its `φ` for its first child), times the message,
            // written back once.
            let mut p = if *h {
                *s
            } else {
                *h = true;
                factor(usize::from(f.parent_of(v)), k)
            };
            *k = k.wrapping_add(mul_norm(&mut p, &msg));
            *s = p;
        }
    }
}

/// `P_t(α)`, the value of forest `f` (`max`: the max-product value `max_y P_t(y) Π
/// α^γ`), in one post-order sweep with a stack of `H` rows.
#[inline(never)]
fn tree_value<V: Lanes, const C: usize, const K: usize, const H: usize>(
    m: &TreeModel<V, C, K>,
    src: &dyn Factors<V, K>,
    f: &Forest<V::Scalar>,
    max: bool,
) -> Acc<V::Scalar> {
    let mut acc = Acc::ONE;
    let k = sweep::<V, K, H>(
        src,
        f,
        m.root_unary(),
        |_, b| value_message(m, b, max),
        |_, b| acc.mul(root_value(b, max)),
    );
    over_z(acc, k, f)
}

/// The upward message of a value sweep: max-product (`max`) or sum-product.
#[inline(always)]
fn value_message<V: Lanes, const C: usize, const K: usize>(
    m: &TreeModel<V, C, K>,
    b: &[V; K],
    max: bool,
) -> ([V; K], i32) {
    if max {
        max_message(m, b, None)
    } else {
        up_message(m, b)
    }
}

/// A root's value in a value sweep: the largest entry of its belief (`max`) or their
/// sum.
#[inline(always)]
fn root_value<V: Lanes, const K: usize>(b: &[V; K], max: bool) -> V::Scalar {
    if max { hmax(b) } else { hsum(b) }
}

/// How many forests a value sweep runs side by side (see `tree_values_n`): one in
/// scalar code (`lanes` = 1: microcontrollers); on SIMD hosts four, or two, as long as
/// their stacks of rows (`rows` = the largest height + 2 each) hold no more rows than
/// the map has places, so an entry point's stack stays near that of `marginals`
/// (which keeps a row per place); the generator's stack bound counts the same number.
pub const fn parallel_sweeps(lanes: usize, places: usize, rows: usize) -> usize {
    if lanes == 1 {
        1
    } else if 4 * rows <= places {
        4
    } else if 2 * rows <= places {
        2
    } else {
        1
    }
}

/// [`tree_value`] of `P` forests in one loop, a place of each per step: `P`
/// independent chains of dependent operations side by side (SIMD hosts, where each
/// chain alone leaves most of the core idle: 4 forests take 0.77× the time of one at
/// a time at 230 places).
#[inline(never)]
fn tree_values_n<V: Lanes, const C: usize, const K: usize, const H: usize, const P: usize>(
    m: &TreeModel<V, C, K>,
    src: &dyn Factors<V, K>,
    fs: [&Forest<V::Scalar>; P],
    max: bool,
) -> [Acc<V::Scalar>; P] {
    let mut accs = [Acc::ONE; P];
    let mut sweeps = [(); P].map(|_| Sweep::<V, K, H>::new());
    let mut ks = [0i32; P];
    let unary = m.root_unary();
    let n = fs.iter().map(|f| f.post.len()).max().unwrap_or(0);
    for i in 0..n {
        for (((s, k), acc), f) in sweeps.iter_mut().zip(&mut ks).zip(&mut accs).zip(fs) {
            if let Some(&vd) = f.post.get(i) {
                s.step(
                    (src, f, unary),
                    vd,
                    k,
                    &mut |_, b| value_message(m, b, max),
                    &mut |_, b| acc.mul(root_value(b, max)),
                );
            }
        }
    }
    for ((a, &k), f) in accs.iter_mut().zip(&ks).zip(fs) {
        *a = over_z(*a, k, f);
    }
    accs
}

/// The values of every forest (see [`tree_value`]; on SIMD hosts [`parallel_sweeps`]
/// at a time, see [`tree_values_n`]).
#[inline(always)]
pub(crate) fn values<
    V: Lanes,
    const C: usize,
    const K: usize,
    const N: usize,
    const H: usize,
    const T: usize,
>(
    m: &TreeModel<V, C, K>,
    src: &dyn Factors<V, K>,
    max: bool,
) -> [Acc<V::Scalar>; T] {
    let mut accs = [Acc::ONE; T];
    let p = parallel_sweeps(V::WIDTH, N, H);
    let mut i = 0;
    while i < T {
        let left = T - i;
        let q = if p >= 4 && left >= 4 {
            4
        } else if p >= 2 && left >= 2 {
            2
        } else {
            1
        };
        let (Some(a), Some(f)) = (accs.get_mut(i..i + q), m.forests.get(i..i + q)) else {
            break;
        };
        match (a, f) {
            ([a0, a1, a2, a3], [f0, f1, f2, f3]) => {
                [*a0, *a1, *a2, *a3] =
                    tree_values_n::<V, C, K, H, 4>(m, src, [f0, f1, f2, f3], max);
            }
            ([a0, a1], [f0, f1]) => {
                [*a0, *a1] = tree_values_n::<V, C, K, H, 2>(m, src, [f0, f1], max);
            }
            ([a0], [f0]) => *a0 = tree_value::<V, C, K, H>(m, src, f0, max),
            _ => {}
        }
        i += q;
    }
    accs
}

/// `ln S(α)` with every place of `labels` restricted to its label (`u16::MAX`: the
/// whole row): `ln (1/T) Σ_t P_t(α)`. Relative error a few `ε` per place.
pub fn tree_log_likelihood<
    V: Lanes,
    const C: usize,
    const K: usize,
    const N: usize,
    const H: usize,
    const T: usize,
>(
    m: &TreeModel<V, C, K>,
    e: &[[V::Scalar; C]; N],
    labels: &[u16; N],
) -> Result<V::Scalar, EvidenceError> {
    let accs = with_factors(m, e, Some(labels), m.cache.values, |src| {
        values::<V, C, K, N, H, T>(m, src, false)
    });
    log_of_mix(&accs)
}

/// `ln` of the mixture of the forests' values, or `ZeroLikelihood`.
#[inline(always)]
pub(crate) fn log_of_mix<T: Real, const F: usize>(accs: &[Acc<T>; F]) -> Result<T, EvidenceError> {
    match mix(accs) {
        Some((l, _)) if l > T::NEG_INFINITY => Ok(l),
        _ => Err(EvidenceError::ZeroLikelihood),
    }
}

/// Upward pass of forest `f` keeping, in `msgs`, every non-root place's message to
/// its parent and every root's belief (normalised), and in `exps` (when given) each
/// place's exponent; returns the product of the roots' sums and the sum of the
/// exponents (the forest's value over `Z_t` is their product over `Z_t`).
#[inline(never)]
pub(crate) fn tree_upward<V: Lanes, const C: usize, const K: usize, const N: usize>(
    m: &TreeModel<V, C, K>,
    src: &dyn Factors<V, K>,
    f: &Forest<V::Scalar>,
    msgs: &mut [[V; K]; N],
    mut exps: Option<&mut [i32; N]>,
) -> (Acc<V::Scalar>, i32) {
    let mut k = 0i32;
    let mut acc = Acc::ONE;
    for &[v, d] in f.post {
        let v = usize::from(v);
        let (b, eb) = belief(src, f, msgs, v);
        let (out, ev) = if d == 0 {
            let r = m.root_belief(b);
            acc.mul(hsum(&r));
            (r, eb)
        } else {
            let (msg, em) = up_message(m, &b);
            (msg, eb.wrapping_add(em))
        };
        if let Some(s) = msgs.get_mut(v) {
            *s = out;
        }
        if let Some(x) = exps.as_deref_mut().and_then(|x| x.get_mut(v)) {
            *x = ev;
        }
        k = k.wrapping_add(ev);
    }
    (acc, k)
}

/// `r = a / (b + pad)`: the parent's full belief without the child's message (the
/// padding lanes, 0 in both, stay 0; rows without padding lanes skip the addition).
#[inline(always)]
fn without<V: Lanes, const C: usize, const K: usize>(
    a: &[V; K],
    b: &[V; K],
    pad: &[V; K],
) -> [V; K] {
    let mut r = *a;
    if K * V::WIDTH > C {
        for ((x, &y), &p) in r.iter_mut().zip(b).zip(pad) {
            *x = *x / (y + p);
        }
    } else {
        for (x, &y) in r.iter_mut().zip(b) {
            *x = *x / y;
        }
    }
    r
}

/// `full(v) = belief(v) ⊙ ψ·(full(parent) / m_v)`, normalised (`ψ` the downward
/// matrix). The downward message is not normalised: `full(parent)`'s entries sum to
/// `[1, 2)` and `m_v`'s entries lie in `[2^-28, 2)` (see the module docs), so its
/// entries lie in `[2^-29, C·2^29)` (`[2^-49, C·2^29)` with `u` folded in), and its
/// product with the belief (largest entry at least `2^-84`, or `2^-64` folded) has a
/// largest entry of at least `2^-113`: inside the normal range.
#[inline(always)]
pub(crate) fn full_below<V: Lanes, const C: usize, const K: usize, const N: usize>(
    m: &TreeModel<V, C, K>,
    src: &dyn Factors<V, K>,
    f: &Forest<V::Scalar>,
    msgs: &[[V; K]; N],
    v: usize,
    parent_full: &[V; K],
) -> [V; K] {
    let Some(mv) = msgs.get(v) else {
        return [V::ZERO; K];
    };
    let down = down_message(m, &without::<V, C, K>(parent_full, mv, &m.pad));
    let (mut b, _) = belief(src, f, msgs, v);
    mul_norm(&mut b, &down);
    b
}

/// `out[v] += w · full / Σ full`, in the lane type's arithmetic (the same operations
/// per class as on scalars).
#[inline(always)]
pub(crate) fn add_marginal<V: Lanes, const K: usize, const C: usize>(
    out: &mut [V::Scalar; C],
    full: &[V; K],
    w: V::Scalar,
) {
    let s = hsum(full);
    if !above(s, V::Scalar::ZERO) {
        return;
    }
    let k = V::splat(w / s);
    let mut acc = pack::<V, C, K>(out);
    for (a, &x) in acc.iter_mut().zip(full) {
        *a += x * k;
    }
    for (o, &x) in out.iter_mut().zip(acc.iter().flat_map(|v| v.lanes())) {
        *o = x;
    }
}

/// Downward pass of forest `f` from its stored upward pass `msgs` (see
/// [`tree_upward`]): adds `w · P_t(Y_v | α)` to `out[v]` for every place, with a stack
/// of `H` rows (one per depth).
#[inline(never)]
pub(crate) fn tree_downward<
    V: Lanes,
    const C: usize,
    const K: usize,
    const N: usize,
    const H: usize,
>(
    m: &TreeModel<V, C, K>,
    src: &dyn Factors<V, K>,
    f: &Forest<V::Scalar>,
    msgs: &[[V; K]; N],
    w: V::Scalar,
    out: &mut [[V::Scalar; C]; N],
) {
    let mut stack = [[V::ZERO; K]; H];
    for &[v, d] in f.post.iter().rev() {
        let (v, d) = (usize::from(v), usize::from(d));
        let full = match d.checked_sub(1).and_then(|p| stack.get(p)) {
            Some(pf) => full_below(m, src, f, msgs, v, pf),
            None => msgs.get(v).copied().unwrap_or([V::ZERO; K]),
        };
        if let Some(s) = stack.get_mut(d) {
            *s = full;
        }
        if let Some(o) = out.get_mut(v) {
            add_marginal(o, &full, w);
        }
    }
}

/// Every row of `out` divided by its sum.
#[inline(always)]
pub(crate) fn normalise_rows<T: Real, const C: usize, const N: usize>(out: &mut [[T; C]; N]) {
    for row in out.iter_mut() {
        let mut s = T::ZERO;
        for &x in row.iter() {
            s += x;
        }
        if s > T::ZERO {
            let inv = T::ONE / s;
            for x in row.iter_mut() {
                *x *= inv;
            }
        }
    }
}

/// Writes `P(Y_v = c | α)` of every place into `out` (mixed as the model says) and
/// returns `ln S(α)`: per forest a stored upward pass (`O(places · C)` scratch) and a
/// downward pass. With posterior mixing the forests' weights are accumulated online
/// (the running sum is rescaled when a larger forest value appears).
pub fn tree_marginals<
    V: Lanes,
    const C: usize,
    const K: usize,
    const N: usize,
    const H: usize,
    const T: usize,
>(
    m: &TreeModel<V, C, K>,
    e: &[[V::Scalar; C]; N],
    out: &mut [[V::Scalar; C]; N],
) -> Result<V::Scalar, EvidenceError> {
    *out = [[V::Scalar::ZERO; C]; N];
    let accs = with_factors(m, e, None, m.cache.marginals, |src| {
        marginals_from::<V, C, K, N, H, T>(m, src, out)
    });
    let Some((l, _)) = mix(&accs).filter(|(l, _)| *l > V::Scalar::NEG_INFINITY) else {
        return Err(EvidenceError::ZeroLikelihood);
    };
    normalise_rows(out);
    Ok(l)
}

/// The forests' passes of [`tree_marginals`]; returns the forests' values.
#[inline(always)]
fn marginals_from<
    V: Lanes,
    const C: usize,
    const K: usize,
    const N: usize,
    const H: usize,
    const T: usize,
>(
    m: &TreeModel<V, C, K>,
    src: &dyn Factors<V, K>,
    out: &mut [[V::Scalar; C]; N],
) -> [Acc<V::Scalar>; T] {
    let one = V::Scalar::ONE;
    let mut msgs = [[V::ZERO; K]; N];
    let mut accs = [Acc::ONE; T];
    let mut top: Option<Acc<V::Scalar>> = None;
    for (a, f) in accs.iter_mut().zip(m.forests) {
        let (acc, k) = tree_upward(m, src, f, &mut msgs, None);
        let acc = over_z(acc, k, f);
        *a = acc;
        if acc.is_zero() {
            continue;
        }
        let w = match top {
            _ if m.average => one,
            None => {
                top = Some(acc);
                one
            }
            Some(t) => {
                let r = acc.ln_ratio(&t);
                if r > V::Scalar::ZERO {
                    let down = (V::Scalar::ZERO - r).exp();
                    for x in out.iter_mut().flatten() {
                        *x *= down;
                    }
                    top = Some(acc);
                    one
                } else {
                    r.exp()
                }
            }
        };
        tree_downward::<V, C, K, N, H>(m, src, f, &msgs, w, out);
    }
    accs
}

/// Labels of the max-product labelling of forest `f`: a max-product sweep keeping
/// `arg[v][a]` (the best class of `v` when its parent has class `a`), then labels
/// top-down.
#[inline(never)]
fn mpe_labels<V: Lanes, const C: usize, const K: usize, const N: usize, const H: usize>(
    m: &TreeModel<V, C, K>,
    src: &dyn Factors<V, K>,
    f: &Forest<V::Scalar>,
    labels: &mut [u16; N],
) {
    let mut arg = [[0u8; C]; N];
    sweep::<V, K, H>(
        src,
        f,
        m.root_unary(),
        |v, b| match arg.get_mut(v) {
            Some(a) => max_message(m, b, Some(a)),
            None => ([V::ZERO; K], 0),
        },
        |v, b| {
            if let Some(l) = labels.get_mut(v) {
                *l = argmax(b);
            }
        },
    );
    for &[v, d] in f.post.iter().rev() {
        let v = usize::from(v);
        if d == 0 {
            continue;
        }
        let p = usize::from(f.parent_of(v));
        let lp = labels.get(p).map_or(0, |&l| usize::from(l));
        let best = arg
            .get(v)
            .and_then(|a| a.get(lp))
            .map_or(0, |&x| u16::from(x));
        if let Some(l) = labels.get_mut(v) {
            *l = best;
        }
    }
}

/// Writes the most probable `(forest, labelling)` pair's labelling into `labels` and
/// returns its natural-log value `max_t max_y ln((1/T) P_t(y) Π_v α_v(y_v)^γ)` (ties:
/// the first forest; within a forest the smallest class).
pub fn tree_mpe<
    V: Lanes,
    const C: usize,
    const K: usize,
    const N: usize,
    const H: usize,
    const T: usize,
>(
    m: &TreeModel<V, C, K>,
    e: &[[V::Scalar; C]; N],
    labels: &mut [u16; N],
) -> Result<V::Scalar, EvidenceError> {
    with_factors(m, e, None, m.cache.values, |src| {
        let accs = values::<V, C, K, N, H, T>(m, src, true);
        let (Some(t), Some(f)) = (best(&accs), best(&accs).and_then(|t| m.forests.get(t))) else {
            return Err(EvidenceError::ZeroLikelihood);
        };
        let v =
            accs.get(t).map_or(V::Scalar::NEG_INFINITY, |a| a.ln()) - V::Scalar::from_index(T).ln();
        if !above(v, V::Scalar::NEG_INFINITY) {
            return Err(EvidenceError::ZeroLikelihood);
        }
        mpe_labels::<V, C, K, N, H>(m, src, f, labels);
        Ok(v)
    })
}
