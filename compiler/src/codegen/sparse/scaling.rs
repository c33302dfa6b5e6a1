//! Fixed-point scales of the floor + sparse functions (see `codegen::fixed`): the
//! powers of two that a group's inner sum and each vector's adjoints are kept scaled
//! by, so that their roundings are that much smaller, and the error units those
//! roundings count.

use proc_macro2::{Literal, TokenStream};
use quote::quote;

use super::{SparseCode, Term, other_inputs};
use crate::codegen::kernels::Segment;

impl SparseCode<'_> {
    /// Fixed-point code: the `s` of the power of two `2^s` that a group's inner sum
    /// `q = Σ d·(rest of the tuple)` and its constants are kept scaled by — the largest
    /// `s ≤ 31` with `2^s` times the group's mass at ones `Σ d·(rest at ones)` (and
    /// every `d`) below 1, so that `q` cannot overflow and its roundings are `2^-s` of
    /// a unit of the row. `0` in float code.
    pub(super) fn group_shift(&self, seg: &Segment, pos: usize, terms: &[Term]) -> u32 {
        let Some(o) = self.at_ones.as_ref().filter(|_| self.fixed) else {
            return 0;
        };
        let mass: f64 = terms
            .iter()
            .map(|&(t, d, _)| d * self.rest_at_ones(o, seg, t, pos))
            .sum();
        let peak = terms.iter().map(|&(_, d, _)| d).fold(mass, f64::max);
        headroom(peak, 31) as u32
    }

    /// The product at ones of the factors of tuple `t` but the one at `pos`.
    pub(super) fn rest_at_ones(
        &self,
        o: &crate::codegen::fixed::AtOnes,
        seg: &Segment,
        t: usize,
        pos: usize,
    ) -> f64 {
        let idx = seg.tuple(t);
        other_inputs(seg, pos)
            .zip(idx.iter().enumerate().filter(|&(p, _)| p != pos))
            .map(|(g, (_, &i))| o.value[g][i])
            .product()
    }

    /// Fixed-point code: the error units, in the row's value, of a group of terms
    /// (`a[i]·q` with `q = Σ_t d_t·r_t`, kept scaled by `2^s`), each rounding weighted
    /// by its sensitivity at ones: a multiply of the rest `r_t` reaches the row times
    /// `d_t·a[i]`; the multiply by the constant and the constant's own rounding (of
    /// `2^-s`, times `r_t`) times `a[i]·2^-s`; the product `a[i]·q` `2^-s`, and its
    /// shift back one unit. `0` in float code.
    pub(super) fn group_units(
        &self,
        seg: &Segment,
        pos: usize,
        i: usize,
        terms: &[Term],
        s: u32,
    ) -> f64 {
        let Some(o) = self.at_ones.as_ref().filter(|_| self.fixed) else {
            return 0.0;
        };
        let (a, unit) = (o.value[seg.inputs[pos]][i], 2f64.powi(-(s as i32)));
        let rest_multiplies = seg.inputs.len().saturating_sub(2) as f64;
        let terms: f64 = terms
            .iter()
            .map(|&(t, d, _)| {
                let r = self.rest_at_ones(o, seg, t, pos);
                a * (rest_multiplies * d + unit * (1.0 + r))
            })
            .sum();
        terms + unit + if s > 0 { 1.0 } else { 0.0 }
    }

    /// Fixed-point code: the `S` of the power of two `2^S` that vector `g`'s adjoints
    /// are kept scaled by in the backward sweep — the largest `S ≤ 30` that keeps its
    /// adjoints at ones below 1 (`0` for the root's block, whose root adjoint is 1) —
    /// so that their roundings are `2^-S` of a unit. `0` in float code.
    pub(super) fn adjoint_shift(&self, g: usize) -> i32 {
        let Some(o) = self.at_ones.as_ref().filter(|_| self.fixed) else {
            return 0;
        };
        headroom(o.adjoint[g].iter().copied().fold(0.0, f64::max), 30)
    }

    /// How much of a scale change `up` (a power of two) can go into constants `c`:
    /// all of a scale-down (`up ≤ 0`: the constants only shrink), and of a scale-up
    /// the largest power that keeps every `c·2^up` below 1 ([`headroom`]).
    pub(super) fn fold(&self, c: &[f64], up: i32) -> i32 {
        if up <= 0 {
            return up;
        }
        headroom(c.iter().copied().fold(0.0, f64::max), up)
    }

    /// `v`, a value scaled by `2^s`, rescaled by `2^up` (fixed point): an exact left
    /// shift, or a right shift that rounds once more, counted in the backward units
    /// at the target's scale `2^scale`.
    pub(super) fn rescale(&self, v: TokenStream, up: i32, scale: i32) -> TokenStream {
        match up {
            0 => v,
            u if u > 0 => {
                let u = Literal::u32_unsuffixed(u as u32);
                quote!((#v).times_pow2(#u))
            }
            u => {
                self.add_backward_units(1.0, scale);
                let u = Literal::u32_unsuffixed((-u) as u32);
                quote!((#v).div_pow2(#u))
            }
        }
    }

    /// Adds `count` roundings of a value scaled by `2^scale` to the backward sweep's
    /// error units (each `2^-scale` of a unit of the posteriors).
    pub(super) fn add_backward_units(&self, count: f64, scale: i32) {
        if self.fixed {
            self.backward_units
                .set(self.backward_units.get() + count * 2f64.powi(-scale));
        }
    }
}

/// The largest `s ≤ limit` with `peak·(1 + 10^-5)·2^s < 1`: how far a value bounded by
/// `peak` at ones can be scaled up in Q0.32 (the margin covers values at ones that
/// exceed 1 by the `1e-6` that `normalised` allows).
fn headroom(peak: f64, limit: i32) -> i32 {
    let peak = peak * (1.0 + 1e-5);
    let mut s = 0;
    while s < limit && peak * 2f64.powi(s + 1) < 1.0 {
        s += 1;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codegen::kernels::{Block, Plan};

    /// `group_shift` keeps `2^s` times the group's mass at ones `Σ d·(rest at ones)`
    /// below 1, the rest a product of values at ones. Normalised templates have every
    /// value at ones 1 (within `1e-6`); here a block of value 2 at ones makes the rest
    /// count.
    #[test]
    fn group_shift_keeps_the_mass_at_ones_below_one() {
        let segment = |inputs: Vec<usize>, dims: Vec<usize>, weights: Vec<Vec<f64>>| Segment {
            inputs,
            dims,
            weights,
        };
        // Variables 0 and 1 (2 classes); block 0 has two sums of variable 0's entries,
        // 2 and 1 at ones; block 1 (the root) sums (variable 1, block 0) with weights
        // 0.3.
        let plan = Plan {
            n: 2,
            classes: 2,
            blocks: vec![
                Block {
                    sums: vec![2, 3],
                    segments: vec![segment(
                        vec![0],
                        vec![2],
                        vec![vec![1.0, 1.0], vec![0.5, 0.5]],
                    )],
                },
                Block {
                    sums: vec![4],
                    segments: vec![segment(vec![1, 2], vec![2, 2], vec![vec![0.3; 4]])],
                },
            ],
            root: (1, 0),
        };
        let code = SparseCode::fixed("t".into(), &plan);
        let seg = &plan.blocks[1].segments[0];
        // The group of variable 1's entry 0 with tuple 0 (block 0's first sum): 0.3
        // times 2 at ones. 2^0·0.6 < 1 ≤ 2^1·0.6.
        let group = [(0, 0.3, 0.3)];
        assert_eq!(code.group_shift(seg, 0, &group), 0);
        // With tuple 1 (block 0's second sum, 1 at ones): 0.3, one shift.
        assert_eq!(code.group_shift(seg, 0, &[(1, 0.3, 0.3)]), 1);
        // The group of block 0's first sum (tuples 0 and 2: variable 1's entries 0
        // and 1): 0.3 + 0.3 at ones.
        let two = [(0, 0.3, 0.3), (2, 0.3, 0.3)];
        assert_eq!(code.group_shift(seg, 1, &two), 0);
        // Half the constants: 0.3 at ones, 2^1·0.3 < 1 ≤ 2^2·0.3.
        let group = [(0, 0.15, 0.15)];
        assert_eq!(code.group_shift(seg, 0, &group), 1);
        // Float code is never scaled.
        assert_eq!(
            SparseCode::float("t".into(), &plan).group_shift(seg, 0, &group),
            0
        );
    }
}
