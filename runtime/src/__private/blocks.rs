//! Max-product kernels for one component with argmax bookkeeping, and the
//! backtracking that turns the recorded arguments into labels (MPE).
//!
//! Weights are laid out as for the lane kernels, `w[m][i][j][k]` (last input
//! innermost). Every kernel keeps the running maximum of `out[m]` with a strict `>`,
//! so ties go to the lowest split (segments run in order), then the lowest `i`, `j`,
//! `k`; `arg[m] = [segment, i, j, k]` records the winning tuple.

use super::Real;

/// `out[m] = max(out[m], max_i w[m][i]·a[i])`, recording `[seg, i, 0, 0]` where it grew.
#[inline(never)]
pub fn d1_maxa<R: Real, const M: usize, const A: usize>(
    seg: u16,
    w: &[[R; A]; M],
    a: &[R; A],
    out: &mut [R; M],
    arg: &mut [[u16; 4]; M],
) {
    for ((o, am), wm) in out.iter_mut().zip(arg.iter_mut()).zip(w) {
        for ((&x, &y), i) in wm.iter().zip(a).zip(0u16..) {
            let p = x * y;
            if p > *o {
                *o = p;
                *am = [seg, i, 0, 0];
            }
        }
    }
}

/// `out[m] = max(out[m], max_{i,j} w[m][i][j]·a[i]·b[j])`, recording `[seg, i, j, 0]`.
#[inline(never)]
pub fn d2_maxa<R: Real, const M: usize, const A: usize, const B: usize>(
    seg: u16,
    w: &[[[R; B]; A]; M],
    (a, b): (&[R; A], &[R; B]),
    out: &mut [R; M],
    arg: &mut [[u16; 4]; M],
) {
    for ((o, am), wm) in out.iter_mut().zip(arg.iter_mut()).zip(w) {
        for ((wi, &ai), i) in wm.iter().zip(a).zip(0u16..) {
            for ((&x, &bj), j) in wi.iter().zip(b).zip(0u16..) {
                let p = x * bj * ai;
                if p > *o {
                    *o = p;
                    *am = [seg, i, j, 0];
                }
            }
        }
    }
}

/// `out[m] = max(out[m], max_{i,j,k} w[m][i][j][k]·a[i]·b[j]·c[k])`, recording
/// `[seg, i, j, k]`.
#[inline(never)]
pub fn d3_maxa<R: Real, const M: usize, const A: usize, const B: usize, const K: usize>(
    seg: u16,
    w: &[[[[R; K]; B]; A]; M],
    (a, b, c): (&[R; A], &[R; B], &[R; K]),
    out: &mut [R; M],
    arg: &mut [[u16; 4]; M],
) {
    for ((o, am), wm) in out.iter_mut().zip(arg.iter_mut()).zip(w) {
        for ((wi, &ai), i) in wm.iter().zip(a).zip(0u16..) {
            for ((wj, &bj), j) in wi.iter().zip(b).zip(0u16..) {
                let s = ai * bj;
                for ((&x, &ck), k) in wj.iter().zip(c).zip(0u16..) {
                    let p = x * ck * s;
                    if p > *o {
                        *o = p;
                        *am = [seg, i, j, k];
                    }
                }
            }
        }
    }
}

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
    arg: &[[u16; 4]; M],
    sa: &mut [bool; A],
) {
    for (&s, am) in sel.iter().zip(arg) {
        if s && am[0] == seg {
            mark(sa, am[1]);
        }
    }
}

/// Marks the `a`, `b` entries chosen by the selected sums whose best tuple is in `seg`.
#[inline(always)]
pub fn d2_back<const M: usize, const A: usize, const B: usize>(
    seg: u16,
    sel: &[bool; M],
    arg: &[[u16; 4]; M],
    sa: &mut [bool; A],
    sb: &mut [bool; B],
) {
    for (&s, am) in sel.iter().zip(arg) {
        if s && am[0] == seg {
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
    arg: &[[u16; 4]; M],
    sa: &mut [bool; A],
    sb: &mut [bool; B],
    sc: &mut [bool; K],
) {
    for (&s, am) in sel.iter().zip(arg) {
        if s && am[0] == seg {
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
