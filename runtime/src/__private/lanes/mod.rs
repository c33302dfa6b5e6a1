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
