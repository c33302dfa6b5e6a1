//! MPE backtracking for one component: turns the best tuple of every block sum
//! (`arg[m] = [segment, i, j, k]`, decoded from the lane kernels' `*_maxa` codes by
//! `decode_arg`) into the selected entries of each input, from the root down.

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
