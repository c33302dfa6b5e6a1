//! MPE backtracking for one component: turns the best tuple of every block sum
//! (`[segment, i, j, k]`, see [`Args`]; in SIMD code unpacked from one lane of the
//! packed codes by [`LaneArgs`]) into the selected entries of each input, from the
//! root down.

use super::Real;
use super::lanes::Lanes;

#[inline(always)]
fn mark<const A: usize>(s: &mut [bool; A], i: u16) {
    if let Some(v) = s.get_mut(usize::from(i)) {
        *v = true;
    }
}

/// Marks the `a` entries chosen by the selected sums whose best tuple is in `seg`.
#[inline(always)]
pub fn d1_back<const M: usize, const A: usize>(
    seg: u16,
    sel: &[bool; M],
    arg: &impl Args<M>,
    sa: &mut [bool; A],
) {
    for (m, _) in sel.iter().enumerate().filter(|&(_, &s)| s) {
        let am = arg.arg(m);
        if am[0] == seg {
            mark(sa, am[1]);
        }
    }
}

/// Marks the `a`, `b` entries chosen by the selected sums whose best tuple is in `seg`.
#[inline(always)]
pub fn d2_back<const M: usize, const A: usize, const B: usize>(
    seg: u16,
    sel: &[bool; M],
    arg: &impl Args<M>,
    sa: &mut [bool; A],
    sb: &mut [bool; B],
) {
    for (m, _) in sel.iter().enumerate().filter(|&(_, &s)| s) {
        let am = arg.arg(m);
        if am[0] == seg {
            mark(sa, am[1]);
            mark(sb, am[2]);
        }
    }
}

/// Marks the `a`, `b`, `c` entries chosen by the selected sums whose best tuple is in `seg`.
#[inline(always)]
pub fn d3_back<const M: usize, const A: usize, const B: usize, const K: usize>(
    seg: u16,
    sel: &[bool; M],
    arg: &impl Args<M>,
    sa: &mut [bool; A],
    sb: &mut [bool; B],
    sc: &mut [bool; K],
) {
    for (m, _) in sel.iter().enumerate().filter(|&(_, &s)| s) {
        let am = arg.arg(m);
        if am[0] == seg {
            mark(sa, am[1]);
            mark(sb, am[2]);
            mark(sc, am[3]);
        }
    }
}

/// Sets `lab` to the lowest selected class (unchanged when none is selected).
#[inline(always)]
pub fn sel_label<const C: usize>(sel: &[bool; C], lab: &mut u16) {
    if let Some(c) = sel.iter().position(|&s| s) {
        *lab = c as u16;
    }
}

/// Every lane's largest entry of `v` (at least 0) and its index as a lane value: the
/// lowest index on ties, 0 when no entry is above 0. The lane form of
/// [`super::amax`].
#[inline(always)]
pub fn amax_lanes<V: Lanes, const K: usize>(v: &[V; K]) -> (V, V) {
    let (mut best, mut arg) = (V::ZERO, V::ZERO);
    for (i, &x) in v.iter().enumerate() {
        V::arg_max(&mut best, &mut arg, x, V::splat(V::Scalar::from_index(i)));
    }
    (best, arg)
}

/// The best tuples of a block's `M` sums.
pub trait Args<const M: usize> {
    /// Sum `m`'s best tuple `[segment, i, j, k]` (`[u16::MAX; 4]` past the end).
    fn arg(&self, m: usize) -> [u16; 4];
}

impl<const M: usize> Args<M> for [[u16; 4]; M] {
    #[inline(always)]
    fn arg(&self, m: usize) -> [u16; 4] {
        self.get(m).copied().unwrap_or([u16::MAX; 4])
    }
}

/// Lane `lane` of a block's packed best tuples, unpacked on demand (only the selected
/// sums' are). A code holds its fields from the lowest bits up as `k`, `j`, `i`,
/// `segment`, field `f` taking `widths[f]` bits (`widths` in the order segment, i, j,
/// k); the generator packs them only where every code is an integer the lane's float
/// holds exactly.
pub struct LaneArgs<'a, V, const M: usize> {
    /// The packed codes, one lane vector per sum.
    pub codes: &'a [V; M],
    /// The lane.
    pub lane: usize,
    /// Bits of each field.
    pub widths: [u32; 4],
}

impl<V: Lanes, const M: usize> Args<M> for LaneArgs<'_, V, M> {
    #[inline(always)]
    fn arg(&self, m: usize) -> [u16; 4] {
        let Some(v) = self.codes.get(m) else {
            return [u16::MAX; 4];
        };
        let mut code = v.lane(self.lane).index();
        let mut out = [0u16; 4];
        for (f, &w) in out.iter_mut().zip(&self.widths).rev() {
            *f = (code & ((1usize << w) - 1)) as u16;
            code >>= w;
        }
        out
    }
}

/// Lane `l` of every row of `x`, for a template whose MPE codes do not fit a lane
/// value (its scalar MPE function then runs once per lane).
#[inline(always)]
pub fn lane_rows<V: Lanes, const C: usize, const N: usize>(
    x: &[[V; C]; N],
    l: usize,
) -> [[V::Scalar; C]; N] {
    let mut out = [[V::Scalar::ZERO; C]; N];
    for (o, r) in out.iter_mut().zip(x) {
        for (oc, v) in o.iter_mut().zip(r) {
            *oc = v.lane(l);
        }
    }
    out
}
