//! The streaming state's side of the engine: re-evaluating the components a new
//! row touches, the chunked partial products of their values per decomposition,
//! and every place's marginal mixed from the cached local posteriors.

use crate::__private::{Lanes, Real};

use super::{Acc, Tpl, accumulate, gather, weight};

/// Streaming state and one-pass marginals: re-evaluates group `g` of a template on
/// evidence `e` (`table`: see [`gather`](crate::__private::gather)) and stores each real component's value into `val` (indexed by
/// component within the template) and its local posteriors into `post` (see
/// [`PostRows`]).
#[inline(never)]
pub fn eval_group<
    W: Lanes,
    const L: usize,
    const NV: usize,
    const C: usize,
    const N: usize,
    P: PostRows<W::Scalar, C> + ?Sized,
>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    table: Option<&[[W::Scalar; C]; N]>,
    g: usize,
    val: &mut [W::Scalar],
    post: &mut P,
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
    P: PostRows<W::Scalar, C> + ?Sized,
>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    table: Option<&[[W::Scalar; C]; N]>,
    comps: &[I],
    first: usize,
    val: &mut [W::Scalar],
    post: &mut P,
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

/// Where [`eval_group`] and [`eval_components`] store a component's local posterior
/// rows: the template's component cache (a slice of rows, component `k`'s variable
/// `v` at row `k·NV + v`), or on SIMD hosts the streaming state's place-major rows per
/// decomposition (`[[[T; C]; N]; D]`, row `[d][place]` for every decomposition `d`
/// containing the component).
pub trait PostRows<T, const C: usize> {
    /// Stores the local posteriors of variable `v` of the template's component `k`
    /// (`NV` variables per component), at place `q`, in decompositions `mask`: `fill`
    /// writes the row in place (called once per destination row).
    fn put_with<const NV: usize>(
        &mut self,
        k: usize,
        v: usize,
        q: u16,
        mask: u64,
        fill: impl Fn(&mut [T; C]),
    );
}

impl<T, const C: usize> PostRows<T, C> for [[T; C]] {
    #[inline(always)]
    fn put_with<const NV: usize>(
        &mut self,
        k: usize,
        v: usize,
        _q: u16,
        _mask: u64,
        fill: impl Fn(&mut [T; C]),
    ) {
        if let Some(o) = self.get_mut(k * NV + v) {
            fill(o);
        }
    }
}

impl<T, const C: usize, const N: usize, const D: usize> PostRows<T, C> for [[[T; C]; N]; D] {
    #[inline(always)]
    fn put_with<const NV: usize>(
        &mut self,
        _k: usize,
        _v: usize,
        q: u16,
        mask: u64,
        fill: impl Fn(&mut [T; C]),
    ) {
        // Filled anew in every decomposition, not copied from the first: reading a row
        // back right after its scalar stores stalls store-to-load forwarding (on the
        // host's 230-place step, that copy was a tenth of the time in `eval_components`).
        for (d, rows) in self.iter_mut().enumerate() {
            if (mask >> d) & 1 == 1
                && let Some(o) = rows.get_mut(usize::from(q))
            {
                fill(o);
            }
        }
    }
}

/// Evaluates the lane group `p` and stores lane `l`'s value and local posteriors as
/// those of component `comps[l]` (lanes past `comps.len()` are dropped).
#[inline(always)]
fn store_group<
    W: Lanes,
    const L: usize,
    const NV: usize,
    const C: usize,
    const N: usize,
    P: PostRows<W::Scalar, C> + ?Sized,
>(
    t: &Tpl<W, L, NV, C>,
    e: &[[W::Scalar; C]; N],
    table: Option<&[[W::Scalar; C]; N]>,
    p: &[[u16; NV]; L],
    comps: &[usize],
    val: &mut [W::Scalar],
    post: &mut P,
) {
    // Not through `post_group`: its returned arrays cost a 1.6 KB copy per update.
    let mut x = [[W::ZERO; C]; NV];
    gather::<W, L, NV, C, N>(e, None, table, p, &mut x);
    let mut pw = [[W::ZERO; C]; NV];
    let v = (t.post)(&x, &mut pw).to_lanes::<L>();
    for (&vl, &k) in v.iter().zip(comps) {
        if let Some(o) = val.get_mut(k) {
            *o = vl;
        }
    }
    // Lane `l` of each class vector is read in place: a `[class][lane]` copy of the
    // vectors first (`class_lanes`) cost the host's streaming step 4%. The stateless
    // `posterior_pass` keeps that copy: reading in place cost the Cortex-M4F 0.3% more
    // instructions and 104 bytes more stack there.
    for (i, pv) in pw.iter().enumerate() {
        for (l, (&k, pl)) in comps.iter().zip(p).enumerate() {
            let (q, mask) = (pl.get(i).copied(), t.decs.get(k).copied());
            post.put_with::<NV>(k, i, q.unwrap_or(u16::MAX), mask.unwrap_or(0), |o| {
                for (oc, pc) in o.iter_mut().zip(pv) {
                    *oc = pc.lanes().get(l).copied().unwrap_or(W::Scalar::ZERO);
                }
            });
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
    cached_scatter(
        t,
        post,
        |mask| weight(w, mask),
        |o, wu, p| *o += wu * p,
        out,
    );
}

/// The loop of [`state_marginals`]: each cached component's local posteriors added
/// into its places' rows of `out` by `add(entry, weight_of(mask), posterior)` (`mask`:
/// the component's decompositions).
#[inline(always)]
pub(crate) fn cached_scatter<
    W: Lanes,
    A: Copy,
    const L: usize,
    const NV: usize,
    const C: usize,
    const N: usize,
>(
    t: &Tpl<W, L, NV, C>,
    post: &[[W::Scalar; C]],
    weight_of: impl Fn(u64) -> A,
    add: impl Fn(&mut W::Scalar, A, W::Scalar),
    out: &mut [[W::Scalar; C]; N],
) {
    let places = t.places.iter().flat_map(|g| g.iter());
    for ((&mask, pl), rows) in t.decs.iter().zip(places).zip(post.chunks_exact(NV)) {
        let wu = weight_of(mask);
        for (&q, r) in pl.iter().zip(rows) {
            if let Some(o) = out.get_mut(usize::from(q)) {
                for (oc, &pc) in o.iter_mut().zip(r) {
                    add(oc, wu, pc);
                }
            }
        }
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
    *out = weighted_sum(w, |d| post.get(*slots.get(d)? as usize));
}

/// `Σ_d w_d · row(d)`, in order of `d`; a decomposition without a row (`None`) adds
/// nothing.
#[inline(always)]
fn weighted_sum<'a, T: Real + 'a, const C: usize, const D: usize>(
    w: &[T; D],
    row: impl Fn(usize) -> Option<&'a [T; C]>,
) -> [T; C] {
    // Summed in a local and stored once: a store into `out` after each row made the
    // host's mix of all places 1.45× slower (1.03 against 0.71 µs at 230 places).
    let mut acc = [T::ZERO; C];
    for (d, &wd) in w.iter().enumerate() {
        let Some(r) = row(d) else { continue };
        for (o, &v) in acc.iter_mut().zip(r) {
            *o += wd * v;
        }
    }
    acc
}

/// Every place's marginal from the place-major rows of the decompositions:
/// `out = Σ_d w_d · dpost[d]`, `L` entries per vector multiply-add over contiguous
/// memory (no row indices; on a SIMD host 1.4× faster than [`mix_places`]'s rows
/// gathered through the component cache, whose 40-byte rows straddle cache lines).
#[inline(never)]
pub fn mix_decompositions<
    W: Lanes,
    const L: usize,
    const C: usize,
    const N: usize,
    const D: usize,
>(
    dpost: &[[[W::Scalar; C]; N]; D],
    w: &[W::Scalar; D],
    out: &mut [[W::Scalar; C]; N],
) {
    let (chunks, rest) = out.as_flattened_mut().as_chunks_mut::<L>();
    let tail = chunks.len() * L;
    for (i, o) in chunks.iter_mut().enumerate() {
        let mut acc = W::ZERO;
        for (rows, &wd) in dpost.iter().zip(w) {
            if let Some(x) = rows.as_flattened().as_chunks::<L>().0.get(i) {
                acc = W::from_lanes(x).mul_add(W::splat(wd), acc);
            }
        }
        *o = acc.to_lanes::<L>();
    }
    for (j, o) in rest.iter_mut().enumerate() {
        let mut acc = W::Scalar::ZERO;
        for (rows, &wd) in dpost.iter().zip(w) {
            if let Some(&x) = rows.as_flattened().get(tail + j) {
                acc += wd * x;
            }
        }
        *o = acc;
    }
}

/// One place's marginal from the place-major rows of the decompositions (see
/// [`mix_decompositions`]).
#[inline]
pub fn mix_place<T: Real, const C: usize, const N: usize, const D: usize>(
    dpost: &[[[T; C]; N]; D],
    w: &[T; D],
    place: usize,
    out: &mut [T; C],
) {
    *out = weighted_sum(w, |d| dpost.get(d)?.get(place));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-variable template of 40 components (three chunks, the last partial) in
    /// three decompositions, some shared; its functions are never called here.
    fn chunked_template() -> Tpl<f32, 1, 1, 2> {
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
        stub_template(&PLACES, &DECS)
    }

    /// A one-lane template over `places` and `decs` whose SPN functions are stubs
    /// (the tests using it never call them).
    fn stub_template<const NV: usize, const C: usize>(
        places: &'static [[[u16; NV]; 1]],
        decs: &'static [u64],
    ) -> Tpl<f32, 1, NV, C> {
        fn value<const NV: usize, const C: usize>(_: &[[f32; C]; NV]) -> f32 {
            0.0
        }
        fn post<const NV: usize, const C: usize>(
            _: &[[f32; C]; NV],
            _: &mut [[f32; C]; NV],
        ) -> f32 {
            0.0
        }
        fn mpe<const NV: usize, const C: usize>(_: &[[f32; C]; NV], _: &mut [[u16; NV]; 1]) -> f32 {
            0.0
        }
        Tpl {
            places,
            decs,
            log: false,
            fwd: value::<NV, C>,
            post: post::<NV, C>,
            max: value::<NV, C>,
            mpe: mpe::<NV, C>,
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
        // Components 3 and 16 (chunks 0 and 1): the second is in a new chunk even
        // though 16 mod 16 is the first one's chunk index.
        val[3] = 0.25;
        val[16] = 4.0;
        update_chunks(&t, &[3u16, 16], 0, &val, &mut parts);
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

    /// A template's components are the global indices `first .. first + len`: the
    /// next template's first component is not one of them.
    #[test]
    fn local_components_are_the_templates_own() {
        let (t, _) = pairs_template();
        assert_eq!(local_component(&t, 10u32, 10), Some(0));
        assert_eq!(local_component(&t, 14u32, 10), Some(4));
        assert_eq!(local_component(&t, 15u32, 10), None);
        assert_eq!(local_component(&t, 9u32, 10), None);
        assert_eq!(local_component(&t, u16::MAX, 0), None);
    }

    /// Four places, three decompositions of two-place components (component 0 is in
    /// decompositions 0 and 1), three classes: `(template, slots)`, where `slots[q][d]`
    /// is the row of place `q`'s component in decomposition `d`.
    #[allow(clippy::type_complexity)]
    fn pairs_template() -> (Tpl<f32, 1, 2, 3>, [[u32; 3]; 4]) {
        static PLACES: [[[u16; 2]; 1]; 5] = [[[0, 1]], [[2, 3]], [[3, 2]], [[1, 2]], [[3, 0]]];
        static DECS: [u64; 5] = [0b011, 0b001, 0b010, 0b100, 0b100];
        let t = stub_template(&PLACES, &DECS);
        (t, [[0, 0, 9], [1, 1, 6], [2, 5, 7], [3, 4, 8]])
    }

    /// Rows stored through [`PostRows`] into the component cache land at `k·NV + v`,
    /// and into the place-major rows of every decomposition of the component; mixing
    /// the latter gives the marginals of mixing the cache's rows through the slots, in
    /// lanes of eight (with a scalar tail) and one scalar at a time.
    #[test]
    fn decomposition_rows_mix_like_the_component_rows() {
        let (t, slots) = pairs_template();
        let mut post = [[0f32; 3]; 10];
        for (i, r) in post.iter_mut().enumerate() {
            for (k, x) in r.iter_mut().enumerate() {
                *x = 0.1 + ((i * 7 + k * 3) % 11) as f32 / 11.0;
            }
        }
        let store =
            |post: &[[f32; 3]; 10], cache: &mut [[f32; 3]], dpost: &mut [[[f32; 3]; 4]; 3]| {
                for (k, (g, &mask)) in t.places.iter().zip(t.decs).enumerate() {
                    for (v, &q) in g[0].iter().enumerate() {
                        let row = post[k * 2 + v];
                        cache.put_with::<2>(k, v, q, mask, |o| *o = row);
                        dpost.put_with::<2>(k, v, q, mask, |o| *o = row);
                    }
                }
            };
        let check_with = |dpost: &[[[f32; 3]; 4]; 3], post: &[[f32; 3]], w: [f32; 3]| {
            let mut plain = [[0f32; 3]; 4];
            for (q, row) in plain.iter_mut().enumerate() {
                for (d, &wd) in w.iter().enumerate() {
                    if let Some(r) = post.get(slots[q][d] as usize) {
                        for (o, &x) in row.iter_mut().zip(r) {
                            *o += wd * x;
                        }
                    }
                }
            }
            let mut want = [[0f32; 3]; 4];
            mix_places(post, &slots, &w, &mut want);
            let mut lanes = [[0f32; 3]; 4];
            mix_decompositions::<crate::__private::Lanes32, 8, 3, 4, 3>(dpost, &w, &mut lanes);
            let mut scalar = [[0f32; 3]; 4];
            mix_decompositions::<f32, 1, 3, 4, 3>(dpost, &w, &mut scalar);
            for (q, want) in want.iter().enumerate() {
                let mut one = [0f32; 3];
                mix_place(dpost, &w, q, &mut one);
                for k in 0..3 {
                    for got in [lanes[q][k], scalar[q][k], one[k], plain[q][k]] {
                        assert!(
                            (got - want[k]).abs() < 1e-6,
                            "place {q} class {k}: {got} vs {}",
                            want[k]
                        );
                    }
                }
            }
        };
        // Weights of three decompositions, then of one alone (the others exactly 0, as
        // `mix` leaves negligible ones), checked against a plain sum.
        let check = |dpost: &[[[f32; 3]; 4]; 3], post: &[[f32; 3]]| {
            for w in [[0.5f32, 0.3, 0.2], [0.0, 1.0, 0.0], [0.0, 0.0, 0.75]] {
                check_with(dpost, post, w);
            }
        };
        let mut cache = [[0f32; 3]; 10];
        let mut dpost = [[[0f32; 3]; 4]; 3];
        store(&post, &mut cache, &mut dpost);
        assert_eq!(cache, post);
        check(&dpost, &post);
        // The shared component 0 is written into both of its decompositions, and the
        // others' rows stay.
        post[0] = [0.3, 0.3, 0.4];
        let row = post[0];
        dpost.put_with::<2>(0, 0, 0, 0b011, |o| *o = row);
        cache.put_with::<2>(0, 0, 0, 0b011, |o| *o = row);
        assert_eq!(cache, post);
        assert_eq!(
            (dpost[0][0], dpost[1][0], dpost[2][0]),
            (post[0], post[0], post[9])
        );
        check(&dpost, &post);
        // Places out of range are skipped.
        dpost.put_with::<2>(0, 0, 7, 0b111, |o| *o = [9.0; 3]);
        cache.put_with::<2>(5, 0, 0, 0, |o| *o = [9.0; 3]);
        assert_eq!(cache, post);
        check(&dpost, &post);
    }
}
