//! The block kernels: forward, backward and max-product contractions of a block's
//! weight table with its input vectors, one component per lane (see the parent
//! module's docs for the layout).

use super::Lanes;
use crate::__private::Real;

/// `out[m] += Σ_i w[m][i]·a[i]`.
#[inline(never)]
pub fn v1_fwd<V: Lanes, const M: usize, const A: usize>(
    w: &[[V::Scalar; A]; M],
    a: &[V; A],
    out: &mut [V; M],
) {
    for (o, wm) in out.iter_mut().zip(w) {
        let mut acc = V::ZERO;
        for (&x, ai) in wm.iter().zip(a) {
            acc = V::splat(x).mul_add(*ai, acc);
        }
        *o += acc;
    }
}

/// Adjoint of [`v1_fwd`]: `ga[i] += Σ_m w[m][i]·g[m]`.
#[inline(never)]
pub fn v1_bwd<V: Lanes, const M: usize, const A: usize>(
    w: &[[V::Scalar; A]; M],
    g: &[V; M],
    ga: &mut [V; A],
) {
    let mut acc = *ga;
    for (wm, gm) in w.iter().zip(g) {
        for (&x, o) in wm.iter().zip(acc.iter_mut()) {
            *o = V::splat(x).mul_add(*gm, *o);
        }
    }
    *ga = acc;
}

/// `out[m] = max(out[m], max_i w[m][i]·a[i])`.
#[inline(never)]
pub fn v1_max<V: Lanes, const M: usize, const A: usize>(
    w: &[[V::Scalar; A]; M],
    a: &[V; A],
    out: &mut [V; M],
) {
    for (o, wm) in out.iter_mut().zip(w) {
        let mut acc = *o;
        for (&x, ai) in wm.iter().zip(a) {
            acc = acc.max(V::splat(x) * *ai);
        }
        *o = acc;
    }
}

/// Shared body of [`v2_fwd`] and [`v2_fwdk`]: keeps `u[m][i] = Σ_j w[m][i][j]·b[j]`.
#[inline(always)]
fn v2_body<V: Lanes, const M: usize, const A: usize, const B: usize>(
    w: &[[[V::Scalar; B]; A]; M],
    a: &[V; A],
    b: &[V; B],
    u: &mut [[V; A]; M],
    out: &mut [V; M],
) {
    for ((wm, um), o) in w.iter().zip(u.iter_mut()).zip(out.iter_mut()) {
        let mut om = V::ZERO;
        for ((wi, ui), ai) in wm.iter().zip(um.iter_mut()).zip(a) {
            let mut acc = V::ZERO;
            for (&x, bj) in wi.iter().zip(b) {
                acc = V::splat(x).mul_add(*bj, acc);
            }
            *ui = acc;
            om = acc.mul_add(*ai, om);
        }
        *o += om;
    }
}

/// `out[m] += Σ_{i,j} w[m][i][j]·a[i]·b[j]`.
#[inline(never)]
pub fn v2_fwd<V: Lanes, const M: usize, const A: usize, const B: usize>(
    w: &[[[V::Scalar; B]; A]; M],
    a: &[V; A],
    b: &[V; B],
    out: &mut [V; M],
) {
    let mut u = [[V::ZERO; A]; M];
    v2_body(w, a, b, &mut u, out);
}

/// [`v2_fwd`] keeping `u[m][i] = Σ_j w[m][i][j]·b[j]` for [`v2_bwd`].
#[inline(never)]
pub fn v2_fwdk<V: Lanes, const M: usize, const A: usize, const B: usize>(
    w: &[[[V::Scalar; B]; A]; M],
    a: &[V; A],
    b: &[V; B],
    u: &mut [[V; A]; M],
    out: &mut [V; M],
) {
    v2_body(w, a, b, u, out);
}

/// Adjoints of [`v2_fwdk`] for the output adjoint `g`:
/// `ga[i] += Σ_m g[m]·u[m][i]`, `gb[j] += Σ_{m,i} w[m][i][j]·g[m]·a[i]`.
#[inline(never)]
pub fn v2_bwd<V: Lanes, const M: usize, const A: usize, const B: usize>(
    w: &[[[V::Scalar; B]; A]; M],
    a: &[V; A],
    u: &[[V; A]; M],
    g: &[V; M],
    ga: &mut [V; A],
    gb: &mut [V; B],
) {
    let mut accb = *gb;
    for ((wm, um), gm) in w.iter().zip(u).zip(g) {
        for ((wi, ui), (ai, gai)) in wm.iter().zip(um).zip(a.iter().zip(ga.iter_mut())) {
            *gai = gm.mul_add(*ui, *gai);
            let h = *gm * *ai;
            for (&x, o) in wi.iter().zip(accb.iter_mut()) {
                *o = V::splat(x).mul_add(h, *o);
            }
        }
    }
    *gb = accb;
}

/// `out[m] = max(out[m], max_{i,j} w[m][i][j]·a[i]·b[j])`.
#[inline(never)]
pub fn v2_max<V: Lanes, const M: usize, const A: usize, const B: usize>(
    w: &[[[V::Scalar; B]; A]; M],
    a: &[V; A],
    b: &[V; B],
    out: &mut [V; M],
) {
    for (wm, o) in w.iter().zip(out.iter_mut()) {
        let mut om = *o;
        for (wi, ai) in wm.iter().zip(a) {
            let mut acc = V::ZERO;
            for (&x, bj) in wi.iter().zip(b) {
                acc = acc.max(V::splat(x) * *bj);
            }
            om = om.max(acc * *ai);
        }
        *o = om;
    }
}

/// Shared body of [`v3_fwd`] and [`v3_fwdk`].
#[inline(always)]
fn v3_body<V: Lanes, const M: usize, const A: usize, const B: usize, const K: usize>(
    w: &[[[[V::Scalar; K]; B]; A]; M],
    (a, b, c): (&[V; A], &[V; B], &[V; K]),
    u: &mut [[[V; B]; A]; M],
    v: &mut [[V; A]; M],
    out: &mut [V; M],
) {
    for (((wm, um), vm), o) in w
        .iter()
        .zip(u.iter_mut())
        .zip(v.iter_mut())
        .zip(out.iter_mut())
    {
        let mut om = V::ZERO;
        for (((wi, ui), vi), ai) in wm.iter().zip(um.iter_mut()).zip(vm.iter_mut()).zip(a) {
            let mut vv = V::ZERO;
            for ((wj, uj), bj) in wi.iter().zip(ui.iter_mut()).zip(b) {
                let mut acc = V::ZERO;
                for (&x, ck) in wj.iter().zip(c) {
                    acc = V::splat(x).mul_add(*ck, acc);
                }
                *uj = acc;
                vv = acc.mul_add(*bj, vv);
            }
            *vi = vv;
            om = vv.mul_add(*ai, om);
        }
        *o += om;
    }
}

/// `out[m] += Σ_{i,j,k} w[m][i][j][k]·a[i]·b[j]·c[k]`.
#[inline(never)]
pub fn v3_fwd<V: Lanes, const M: usize, const A: usize, const B: usize, const K: usize>(
    w: &[[[[V::Scalar; K]; B]; A]; M],
    a: &[V; A],
    b: &[V; B],
    c: &[V; K],
    out: &mut [V; M],
) {
    let mut u = [[[V::ZERO; B]; A]; M];
    let mut v = [[V::ZERO; A]; M];
    v3_body(w, (a, b, c), &mut u, &mut v, out);
}

/// [`v3_fwd`] keeping `u[m][i][j] = Σ_k w[m][i][j][k]·c[k]` and
/// `v[m][i] = Σ_j u[m][i][j]·b[j]` for [`v3_bwd`].
#[inline(never)]
pub fn v3_fwdk<V: Lanes, const M: usize, const A: usize, const B: usize, const K: usize>(
    w: &[[[[V::Scalar; K]; B]; A]; M],
    (a, b, c): (&[V; A], &[V; B], &[V; K]),
    u: &mut [[[V; B]; A]; M],
    v: &mut [[V; A]; M],
    out: &mut [V; M],
) {
    v3_body(w, (a, b, c), u, v, out);
}

/// Adjoints of [`v3_fwdk`] for the output adjoint `g`, added into `ga`, `gb`, `gc`.
#[inline(never)]
pub fn v3_bwd<V: Lanes, const M: usize, const A: usize, const B: usize, const K: usize>(
    w: &[[[[V::Scalar; K]; B]; A]; M],
    (a, b): (&[V; A], &[V; B]),
    (u, v): (&[[[V; B]; A]; M], &[[V; A]; M]),
    g: &[V; M],
    (ga, gb, gc): (&mut [V; A], &mut [V; B], &mut [V; K]),
) {
    let mut accc = *gc;
    for (((wm, um), vm), gm) in w.iter().zip(u).zip(v).zip(g) {
        for (((wi, ui), vi), (ai, gai)) in
            wm.iter().zip(um).zip(vm).zip(a.iter().zip(ga.iter_mut()))
        {
            *gai = gm.mul_add(*vi, *gai);
            let h = *gm * *ai;
            for (((wj, uj), bj), gbj) in wi.iter().zip(ui).zip(b).zip(gb.iter_mut()) {
                *gbj = h.mul_add(*uj, *gbj);
                let hh = h * *bj;
                for (&x, o) in wj.iter().zip(accc.iter_mut()) {
                    *o = V::splat(x).mul_add(hh, *o);
                }
            }
        }
    }
    *gc = accc;
}

/// `out[m] = max(out[m], max_{i,j,k} w[m][i][j][k]·a[i]·b[j]·c[k])`.
#[inline(never)]
pub fn v3_max<V: Lanes, const M: usize, const A: usize, const B: usize, const K: usize>(
    w: &[[[[V::Scalar; K]; B]; A]; M],
    a: &[V; A],
    b: &[V; B],
    c: &[V; K],
    out: &mut [V; M],
) {
    for (wm, o) in w.iter().zip(out.iter_mut()) {
        let mut om = *o;
        for (wi, ai) in wm.iter().zip(a) {
            let mut vv = V::ZERO;
            for (wj, bj) in wi.iter().zip(b) {
                let mut acc = V::ZERO;
                for (&x, ck) in wj.iter().zip(c) {
                    acc = acc.max(V::splat(x) * *ck);
                }
                vv = vv.max(acc * *bj);
            }
            om = om.max(vv * *ai);
        }
        *o = om;
    }
}

/// [`v1_max`] recording, where `out[m]` grew in a lane, the tuple code `code0 + i` in
/// `arg[m]` (codes number a block's tuples: segment offset plus the row-major tuple
/// index; see [`decode_arg`]).
#[inline(never)]
pub fn v1_maxa<V: Lanes, const M: usize, const A: usize>(
    code0: V::Scalar,
    w: &[[V::Scalar; A]; M],
    a: &[V; A],
    out: &mut [V; M],
    arg: &mut [V; M],
) {
    for ((o, am), wm) in out.iter_mut().zip(arg.iter_mut()).zip(w) {
        let mut code = code0;
        for (&x, ai) in wm.iter().zip(a) {
            V::arg_max(o, am, V::splat(x) * *ai, V::splat(code));
            code += V::Scalar::ONE;
        }
    }
}

/// [`v2_max`] recording tuple codes `code0 + i·B + j` (see [`v1_maxa`]). The maximum
/// over `j` is taken per `i` first (the same products as [`v2_max`], and short
/// dependency chains), then over `i`; both with a strict `>` in increasing order, so
/// the lowest `(i, j)` among equal products wins.
#[inline(never)]
pub fn v2_maxa<V: Lanes, const M: usize, const A: usize, const B: usize>(
    code0: V::Scalar,
    w: &[[[V::Scalar; B]; A]; M],
    (a, b): (&[V; A], &[V; B]),
    out: &mut [V; M],
    arg: &mut [V; M],
) {
    let step = lane_codes::<V>(B);
    let zero = V::ZERO; // products are ≥ 0: a 0 start with the first code is the first tuple
    for ((o, am), wm) in out.iter_mut().zip(arg.iter_mut()).zip(w) {
        let mut row = V::splat(code0);
        for (wi, ai) in wm.iter().zip(a) {
            let (mut best, mut code) = (zero, row);
            let mut c = row;
            for (&x, bj) in wi.iter().zip(b) {
                V::arg_max(&mut best, &mut code, V::splat(x) * *bj, c);
                c += V::splat(V::Scalar::ONE);
            }
            V::arg_max(o, am, best * *ai, code);
            row += step;
        }
    }
}

/// [`v3_max`] recording tuple codes `code0 + (i·B + j)·K + k` (see [`v2_maxa`]: maxima
/// over `k`, then `j`, then `i`, with the products of [`v3_max`]).
#[inline(never)]
pub fn v3_maxa<V: Lanes, const M: usize, const A: usize, const B: usize, const K: usize>(
    code0: V::Scalar,
    w: &[[[[V::Scalar; K]; B]; A]; M],
    (a, b, c): (&[V; A], &[V; B], &[V; K]),
    out: &mut [V; M],
    arg: &mut [V; M],
) {
    let step_j = lane_codes::<V>(K);
    let step_i = lane_codes::<V>(B * K);
    let zero = V::ZERO; // products are ≥ 0: a 0 start with the first code is the first tuple
    for ((o, am), wm) in out.iter_mut().zip(arg.iter_mut()).zip(w) {
        let mut row_i = V::splat(code0);
        for (wi, ai) in wm.iter().zip(a) {
            let (mut best_i, mut code_i) = (zero, row_i);
            let mut row_j = row_i;
            for (wj, bj) in wi.iter().zip(b) {
                let (mut best_j, mut code_j) = (zero, row_j);
                let mut ck_code = row_j;
                for (&x, ck) in wj.iter().zip(c) {
                    V::arg_max(&mut best_j, &mut code_j, V::splat(x) * *ck, ck_code);
                    ck_code += V::splat(V::Scalar::ONE);
                }
                V::arg_max(&mut best_i, &mut code_i, best_j * *bj, code_j);
                row_j += step_j;
            }
            V::arg_max(o, am, best_i * *ai, code_i);
            row_i += step_i;
        }
    }
}

/// `n` as a lane vector (a code increment).
#[inline(always)]
fn lane_codes<V: Lanes>(n: usize) -> V {
    V::splat(V::Scalar::from_index(n))
}

/// The tuples recorded in lane `l` of a block's `arg` codes as `[segment, i, j, k]`,
/// for the block's segments given as `[offset, A, B, K]` (code offset and input
/// lengths, `1` for missing inputs), in order.
#[inline(always)]
pub fn decode_arg<V: Lanes, const M: usize, const S: usize>(
    arg: &[V; M],
    l: usize,
    segments: [[usize; 4]; S],
) -> [[u16; 4]; M] {
    let mut out = [[0u16; 4]; M];
    for (o, a) in out.iter_mut().zip(arg) {
        let code = a.lane(l).index();
        for (s, &[off, _, b, k]) in segments.iter().enumerate() {
            if code >= off {
                let t = code - off;
                let (i, j, kk) = (t / (b * k).max(1), (t / k.max(1)) % b.max(1), t % k.max(1));
                *o = [s as u16, i as u16, j as u16, kk as u16];
            }
        }
    }
    out
}
