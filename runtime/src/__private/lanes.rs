//! Dense region kernels over SIMD *lanes*: one lane per template component.
//!
//! Generated code evaluates the components of one template in groups of [`LANES_F32`]
//! (`f32`) or [`LANES_F64`] (`f64`): component `l` of a group lives in lane `l` of
//! every vector, so each template weight is broadcast once and multiplied into a whole
//! vector of components. Every operation is then a full-width SIMD operation whatever
//! the (often odd) block sizes of the template — ten classes, five sums per region —
//! and the weight tables are read once per group instead of once per component.
//!
//! Kernels compute a block's `M` sums `out[m] += Σ W[m][i][j][k]·a[i]·b[j]·c[k]` over
//! the cartesian product of its `k ≤ 3` input vectors, with `W` in row-major order
//! (last input innermost), the layout of the generated `static` tables. Forward kernels
//! ending in `k` keep the partial contractions for the matching backward kernel, which
//! accumulates the adjoints of the inputs from the adjoint `g` of the outputs. `*_max`
//! kernels are the max-product versions (`out[m] = max(out[m], max W·a·b·c)`).
//!
//! The vector types come from the `wide` crate: 256-bit AVX(+FMA) operations when the
//! target has them (e.g. `-C target-cpu=x86-64-v3` or `native`), pairs of SSE2 or NEON
//! operations otherwise, and plain arrays on targets without SIMD. Multiply-adds are
//! fused only where the target has FMA, so results differ between targets by rounding.

use core::ops::{Add, AddAssign, Mul};

use super::Real;

/// Components per group in `f32` code (one 256-bit vector).
pub const LANES_F32: usize = 8;
/// Components per group in `f64` code (one 256-bit vector).
pub const LANES_F64: usize = 4;

/// A vector of `f32` components.
pub type Lanes32 = wide::f32x8;
/// A vector of `f64` components.
pub type Lanes64 = wide::f64x4;

/// A SIMD vector with one lane per component (see the module docs).
pub trait Lanes:
    Copy + Add<Output = Self> + Mul<Output = Self> + AddAssign + core::ops::Div<Output = Self>
{
    /// The scalar of one lane.
    type Scalar: Real;
    /// All lanes `0`.
    const ZERO: Self;
    /// Lanes per vector (1 for a scalar).
    const WIDTH: usize;
    /// The lanes as a slice of [`Lanes::WIDTH`] scalars.
    fn lanes(&self) -> &[Self::Scalar];
    /// Lane-wise flush of tiny values: `0` where `self < t`, `self` elsewhere.
    fn flush(self, t: Self) -> Self;
    /// The largest lane (pairwise, in `log2(WIDTH)` steps; lanes are never NaN here).
    fn hmax(self) -> Self::Scalar;
    /// The sum of the lanes (pairwise, in `log2(WIDTH)` steps).
    fn hsum(self) -> Self::Scalar;
    /// All lanes `s`.
    fn splat(s: Self::Scalar) -> Self;
    /// `self·a + b` per lane (fused where the target has FMA).
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// Lane-wise maximum (inputs are never NaN here).
    fn max(self, o: Self) -> Self;
    /// Where `p > *best` (strictly): `*best = p` and `*arg = code`.
    fn arg_max(best: &mut Self, arg: &mut Self, p: Self, code: Self);
    /// Lane `l` (`0` when out of range).
    fn lane(self, l: usize) -> Self::Scalar;
    /// Sets lane `l` to `v` (no effect when out of range).
    fn set_lane(&mut self, l: usize, v: Self::Scalar);
    /// The vector whose lane `l` is `a[l]` (lanes past `L` are `0`, entries past the
    /// vector's width ignored).
    fn from_lanes<const L: usize>(a: &[Self::Scalar; L]) -> Self;
    /// The first `L` lanes as an array (`0` past the vector's width).
    fn to_lanes<const L: usize>(self) -> [Self::Scalar; L];
    /// Rows to lanes: `out[c]` holds `rows[l][c]` in lane `l` (a transpose; lanes past
    /// `L` are `0`).
    #[inline(always)]
    fn from_rows<const L: usize, const C: usize>(rows: &[&[Self::Scalar; C]; L]) -> [Self; C] {
        let mut out = [Self::ZERO; C];
        classes_from_rows(rows, &mut out, 0);
        out
    }
    /// Sum of the lanes of every vector of `v`, lane by lane: `Σ_i v[i]`.
    #[inline(always)]
    fn sum<const K: usize>(v: &[Self; K]) -> Self {
        let mut s = Self::ZERO;
        for &x in v {
            s += x;
        }
        s
    }
    /// Lane-wise maximum over the vectors of `v` (`0` for an empty array).
    #[inline(always)]
    fn max_of<const K: usize>(v: &[Self; K]) -> Self {
        let mut s = Self::ZERO;
        for &x in v {
            s = s.max(x);
        }
        s
    }
    /// Scales a row of non-negative values by a power of two in integer arithmetic so
    /// that its largest entry lies in `[1, 2)`, and returns the exponent (the row
    /// before = the row after `· 2^e`; a zero row gives 0); `None` for lanes without
    /// that path (every lane type but `SoftF32`), which the tree driver normalises by
    /// the exponent of the row's sum instead.
    #[inline(always)]
    fn norm_by_max<const K: usize>(_a: &mut [Self; K]) -> Option<i32> {
        None
    }
    /// A tree message `ψ·b` by a Q0.32 matrix (`psi[a][j]`, see the tree driver's
    /// fixed-point messages), normalised, with its exponent; `None` for lanes without
    /// that path (every lane type but the no-FPU targets' `SoftF32`).
    #[inline(always)]
    fn fixed_message<const C: usize, const K: usize>(
        _psi: &[[u32; C]; C],
        _b: &[Self; K],
    ) -> Option<([Self; K], i32)> {
        None
    }
    /// The max-product tree message `max_j ψ(a, j) b(j)` by a Q0.32 matrix, normalised
    /// to a largest entry in `[1, 2]`, with its exponent; `arg[a]` gets the smallest `j`
    /// attaining the fixed-point maximum. `None` (and `arg` untouched) for lanes
    /// without that path, as [`Lanes::fixed_message`].
    #[inline(always)]
    fn fixed_max_message<const C: usize, const K: usize>(
        _psi: &[[u32; C]; C],
        _b: &[Self; K],
        _arg: &mut [u8; C],
    ) -> Option<([Self; K], i32)> {
        None
    }
}

/// Classes `from..` of [`Lanes::from_rows`], lane by lane.
#[inline(always)]
fn classes_from_rows<V: Lanes, const L: usize, const C: usize>(
    rows: &[&[V::Scalar; C]; L],
    out: &mut [V; C],
    from: usize,
) {
    for (c, o) in out.iter_mut().enumerate().skip(from) {
        let mut a = [V::Scalar::ZERO; L];
        for (x, r) in a.iter_mut().zip(rows) {
            *x = r.get(c).copied().unwrap_or(V::Scalar::ZERO);
        }
        *o = V::from_lanes(&a);
    }
}

macro_rules! lanes_impl {
    ($v:ident, $t:ident $(, $from_rows:ident)?) => {
        impl Lanes for $v {
            $(
            #[inline(always)]
            fn from_rows<const L: usize, const C: usize>(rows: &[&[$t; C]; L]) -> [Self; C] {
                $from_rows::<L, C>(rows)
            }
            )?
            type Scalar = $t;
            const ZERO: Self = $v::ZERO;
            const WIDTH: usize = core::mem::size_of::<$v>() / core::mem::size_of::<$t>();
            #[inline(always)]
            fn lanes(&self) -> &[$t] {
                self.as_array()
            }
            #[inline(always)]
            fn flush(self, t: Self) -> Self {
                self.simd_lt(t).select($v::ZERO, self)
            }
            #[inline(always)]
            fn hmax(self) -> $t {
                let mut v = self;
                let mut w = Self::WIDTH / 2;
                while w > 0 {
                    v = v.fast_max(swap_lanes(v, w));
                    w /= 2;
                }
                v.to_array()[0]
            }
            #[inline(always)]
            fn hsum(self) -> $t {
                let mut v = self;
                let mut w = Self::WIDTH / 2;
                while w > 0 {
                    v = v + swap_lanes(v, w);
                    w /= 2;
                }
                v.to_array()[0]
            }
            #[inline(always)]
            fn splat(s: $t) -> Self {
                $v::splat(s)
            }
            #[inline(always)]
            fn mul_add(self, a: Self, b: Self) -> Self {
                $v::mul_add(self, a, b)
            }
            #[inline(always)]
            fn max(self, o: Self) -> Self {
                self.fast_max(o)
            }
            #[inline(always)]
            fn arg_max(best: &mut Self, arg: &mut Self, p: Self, code: Self) {
                let gt = p.simd_gt(*best);
                // x86's `maxps p, best` is `p > best ? p : best` exactly (NaN and
                // equal zeros give `best`): one instruction instead of a blend.
                #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
                {
                    *best = p.fast_max(*best);
                }
                #[cfg(not(any(target_arch = "x86", target_arch = "x86_64")))]
                {
                    *best = gt.select(p, *best);
                }
                *arg = gt.select(code, *arg);
            }
            #[inline(always)]
            fn lane(self, l: usize) -> $t {
                self.to_array().get(l).copied().unwrap_or(0.0)
            }
            #[inline(always)]
            fn set_lane(&mut self, l: usize, v: $t) {
                let mut a = self.to_array();
                if let Some(o) = a.get_mut(l) {
                    *o = v;
                }
                *self = $v::from(a);
            }
            #[inline(always)]
            fn from_lanes<const L: usize>(a: &[$t; L]) -> Self {
                let mut b = $v::ZERO.to_array();
                for (o, &v) in b.iter_mut().zip(a) {
                    *o = v;
                }
                $v::from(b)
            }
            #[inline(always)]
            fn to_lanes<const L: usize>(self) -> [$t; L] {
                let mut b = [0.0; L];
                for (o, &v) in b.iter_mut().zip(&self.to_array()) {
                    *o = v;
                }
                b
            }
        }
    };
}

/// `v` with lanes `i` and `i ^ w` exchanged (a shuffle: one step of a pairwise
/// reduction).
#[inline(always)]
fn swap_lanes<V: SwapLanes<T, L>, T: Copy + Default, const L: usize>(v: V, w: usize) -> V {
    let a = v.array();
    let mut p = [T::default(); L];
    for (i, o) in p.iter_mut().enumerate() {
        *o = a.get(i ^ w).copied().unwrap_or_default();
    }
    V::from_array(p)
}

/// Conversions of a `wide` vector to and from its lanes (for [`swap_lanes`]).
trait SwapLanes<T, const L: usize> {
    fn array(self) -> [T; L];
    fn from_array(a: [T; L]) -> Self;
}

impl SwapLanes<f32, 8> for Lanes32 {
    #[inline(always)]
    fn array(self) -> [f32; 8] {
        self.to_array()
    }
    #[inline(always)]
    fn from_array(a: [f32; 8]) -> Self {
        Lanes32::new(a)
    }
}

impl SwapLanes<f64, 4> for Lanes64 {
    #[inline(always)]
    fn array(self) -> [f64; 4] {
        self.to_array()
    }
    #[inline(always)]
    fn from_array(a: [f64; 4]) -> Self {
        Lanes64::new(a)
    }
}

lanes_impl!(Lanes32, f32, rows_to_lanes32);
lanes_impl!(Lanes64, f64);

/// [`Lanes::from_rows`] for 8 `f32` lanes: classes in blocks of 8, each block loaded as
/// one vector per row and transposed in registers (`wide`'s AVX shuffles: no lane
/// assembled through memory); the classes after the last block lane by lane.
#[inline(always)]
fn rows_to_lanes32<const L: usize, const C: usize>(rows: &[&[f32; C]; L]) -> [Lanes32; C] {
    let mut out = [Lanes32::ZERO; C];
    let mut done = 0;
    if L == 8 {
        while done + 8 <= C {
            let mut block = [Lanes32::ZERO; 8];
            for (b, r) in block.iter_mut().zip(rows) {
                if let Some(v) = r
                    .get(done..done + 8)
                    .and_then(|s| <[f32; 8]>::try_from(s).ok())
                {
                    *b = Lanes32::new(v);
                }
            }
            let t = Lanes32::transpose(block);
            for (o, v) in out.iter_mut().skip(done).zip(t) {
                *o = v;
            }
            done += 8;
        }
    }
    classes_from_rows(rows, &mut out, done);
    out
}

/// One component per call: the scalar itself is the "vector" (targets without float
/// SIMD, e.g. Cortex-M4F or RISC-V MCUs). Multiply-adds are not fused (no `fma` in
/// `core`), so results are bit-identical on every IEEE target.
macro_rules! scalar_lanes {
    ($t:ident) => {
        impl Lanes for $t {
            type Scalar = $t;
            const ZERO: Self = 0.0;
            const WIDTH: usize = 1;
            #[inline(always)]
            fn lanes(&self) -> &[$t] {
                core::slice::from_ref(self)
            }
            #[inline(always)]
            fn flush(self, t: Self) -> Self {
                if self < t { 0.0 } else { self }
            }
            #[inline(always)]
            fn hmax(self) -> $t {
                self
            }
            #[inline(always)]
            fn hsum(self) -> $t {
                self
            }
            #[inline(always)]
            fn splat(s: $t) -> Self {
                s
            }
            #[inline(always)]
            fn mul_add(self, a: Self, b: Self) -> Self {
                self * a + b
            }
            #[inline(always)]
            fn max(self, o: Self) -> Self {
                if o > self { o } else { self }
            }
            #[inline(always)]
            fn arg_max(best: &mut Self, arg: &mut Self, p: Self, code: Self) {
                if p > *best {
                    *best = p;
                    *arg = code;
                }
            }
            #[inline(always)]
            fn lane(self, l: usize) -> $t {
                if l == 0 { self } else { 0.0 }
            }
            #[inline(always)]
            fn set_lane(&mut self, l: usize, v: $t) {
                if l == 0 {
                    *self = v;
                }
            }
            #[inline(always)]
            fn from_lanes<const L: usize>(a: &[$t; L]) -> Self {
                a.first().copied().unwrap_or(0.0)
            }
            #[inline(always)]
            fn to_lanes<const L: usize>(self) -> [$t; L] {
                let mut b = [0.0; L];
                if let Some(o) = b.first_mut() {
                    *o = self;
                }
                b
            }
        }
    };
}

scalar_lanes!(f32);
scalar_lanes!(f64);

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

/// `labels[p[l][i]] = lab[l][i]` for every lane `l` and component place `i`.
#[inline(always)]
pub fn scatter_labels_lanes<const N: usize, const K: usize, const L: usize>(
    labels: &mut [u16; N],
    lab: &[[u16; K]; L],
    p: [[usize; K]; L],
) {
    for (ll, pl) in lab.iter().zip(&p) {
        super::scatter_labels(labels, ll, *pl);
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
                let x = super::gather(e, labels, pl);
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
