//! Moving one group of components between per-place rows and lane vectors: the
//! evidence gather, the posterior store and scatter, and the MPE label scatter.

use super::{LANES_F32, LANES_F64, Lanes, Lanes32, Lanes64};

/// `labels[p[l][i]] = lab[l][i]` for every lane `l` and component place `i`.
#[inline(always)]
pub fn scatter_labels_lanes<const N: usize, const K: usize, const L: usize>(
    labels: &mut [u16; N],
    lab: &[[u16; K]; L],
    p: [[usize; K]; L],
) {
    for (ll, pl) in lab.iter().zip(&p) {
        crate::__private::scatter_labels(labels, ll, *pl);
    }
}

/// Local posteriors of one variable in every lane: `post[c] = x[c]·g[c]·inv`.
#[inline(always)]
pub fn post_lanes<V: Lanes, const C: usize>(x: &[V; C], g: &[V; C], inv: V, post: &mut [V; C]) {
    for ((o, &a), &b) in post.iter_mut().zip(x).zip(g) {
        *o = a * b * inv;
    }
}

macro_rules! lane_flavour {
    ($t:ident, $v:ident, $lanes:ident, $gather:ident, $store:ident, $scatter:ident,
     $values:ident, $inv:ident) => {
        /// The scaled evidence rows of the components of one group, lane `l` holding
        /// component `p[l]` (see `gather`: rows scaled to a maximum of 1, one-hot
        /// rows for labelled places).
        #[inline(always)]
        pub fn $gather<const N: usize, const C: usize, const K: usize>(
            e: &[[$t; C]; N],
            labels: &[u16; N],
            p: [[usize; K]; $lanes],
        ) -> [[$v; C]; K] {
            let mut t = [[[0.0; $lanes]; C]; K];
            for (l, &pl) in p.iter().enumerate() {
                let x = crate::__private::gather(e, labels, pl);
                for (tv, xv) in t.iter_mut().zip(&x) {
                    for (tc, &xc) in tv.iter_mut().zip(xv) {
                        if let Some(o) = tc.get_mut(l) {
                            *o = xc;
                        }
                    }
                }
            }
            let mut out = [[$v::ZERO; C]; K];
            for (ov, tv) in out.iter_mut().zip(&t) {
                for (oc, tc) in ov.iter_mut().zip(tv) {
                    *oc = $v::from(*tc);
                }
            }
            out
        }

        /// Stores the local posteriors of lane `l` at rows `off + l·K .. off + (l+1)·K`
        /// of a scratch array (rows out of range are skipped).
        #[inline(always)]
        pub fn $store<const S: usize, const C: usize, const K: usize>(
            g: &mut [[$t; C]; S],
            off: usize,
            post: &[[$v; C]; K],
        ) {
            for (v, pv) in post.iter().enumerate() {
                for (c, pc) in pv.iter().enumerate() {
                    for (l, &x) in pc.to_array().iter().enumerate() {
                        if let Some(o) = g.get_mut(off + l * K + v).and_then(|r| r.get_mut(c)) {
                            *o = x;
                        }
                    }
                }
            }
        }

        /// `out[p[l][i]] += w[l]·post[i]` (lane `l`) for every lane and component place.
        #[inline(always)]
        pub fn $scatter<const N: usize, const C: usize, const K: usize>(
            out: &mut [[$t; C]; N],
            w: [$t; $lanes],
            post: &[[$v; C]; K],
            p: [[usize; K]; $lanes],
        ) {
            for (v, pv) in post.iter().enumerate() {
                for (c, pc) in pv.iter().enumerate() {
                    let x = pc.to_array();
                    for ((&xl, &wl), pl) in x.iter().zip(&w).zip(&p) {
                        let Some(&q) = pl.get(v) else { continue };
                        if let Some(o) = out.get_mut(q).and_then(|r| r.get_mut(c)) {
                            *o += wl * xl;
                        }
                    }
                }
            }
        }

        /// The lanes of a vector as an array.
        #[inline(always)]
        pub fn $values(v: $v) -> [$t; $lanes] {
            v.to_array()
        }

        /// `1 / v` per lane.
        #[inline(always)]
        pub fn $inv(v: $v) -> $v {
            $v::splat(1.0) / v
        }
    };
}

lane_flavour!(
    f32,
    Lanes32,
    LANES_F32,
    gather_lanes_f32,
    store_lanes_f32,
    scatter_lanes_f32,
    values_f32,
    inv_lanes_f32
);
lane_flavour!(
    f64,
    Lanes64,
    LANES_F64,
    gather_lanes_f64,
    store_lanes_f64,
    scatter_lanes_f64,
    values_f64,
    inv_lanes_f64
);
