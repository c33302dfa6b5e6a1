//! The fixed-point kernel ([`super::Arithmetic::Fixed`]): Q0.32 integer versions of
//! the block templates' value and posterior functions, for targets without an FPU.
//!
//! # What is emitted
//!
//! For every block template (`sparse/`, linear numerics) the generator emits, beside
//! the `f32` functions (renamed `<t>_fl_fwd` / `<t>_fl_post`), their fixed-point twins
//! `<t>_fx_fwd` / `<t>_fx_post` over `graphspn_runtime::__private::Fx` (an unsigned
//! Q0.32 value `v / 2^32`), and the functions the driver calls, `<t>_fwd` / `<t>_post`,
//! which convert the scaled rows to Q0.32 (integer operations only), run the
//! fixed-point function and keep its result when the template value is at least the
//! template's threshold, else call the `f32` function. Max-product and MPE functions
//! stay `f32`.
//!
//! # Why no value overflows
//!
//! A linear-space template `T` has normalised weights and is evaluated on rows scaled
//! to a largest entry of 1: it is a multilinear polynomial with non-negative
//! coefficients, so every node value is at most its value with every entry at 1, which
//! is 1. The same holds for every adjoint `∂T/∂v` (`T` is linear in each node value,
//! and `T(1) = 1`). Entries are truncated to Q0.32 (1 becomes `1 − 2^-32`), weights
//! are rounded down, and a product keeps the high word of the 64-bit product, so a
//! computed value never exceeds the exact one, which is below 1: no sum overflows.
//! The floor form's intermediates that exceed 1 are kept with integer bits: the sum of
//! a vector of length `L` with `k = ⌈log₂ L⌉` bits ([`sum_bits`]), a product of such
//! sums with the sum of their bits, and the floor weight is scaled to match
//! ([`scaled_constant`]), the product shifted back when the weight needed it.
//!
//! # Error bound
//!
//! Each rounding loses less than one unit of `2^-32` (a shifted operation `2^s`
//! units), and moves the root by at most that times its sensitivity — the adjoint of
//! what it rounds, which is at most its adjoint with every entry at 1 ([`AtOnes`]).
//! The value function's bound `E` weights every sum row's roundings by the row's
//! adjoint at ones, the floor form's vector sums and products by theirs, and the
//! entries' truncations by theirs (a first-order bound: second-order terms are below
//! `2^-64` per pair). Within a row, a rounding counts with its own sensitivity at
//! ones: a group's inner sum `q = Σ d·(rest of the tuple)` (`sparse/`) is kept scaled
//! by `2^s`, the largest power of two that keeps its value at ones and its constants
//! below 1, so the multiplies by its constants and the constants' own roundings count
//! `2^-s` of a unit each, the multiplies inside a rest `d` times a unit, and the shift
//! back of `a[i]·q` one unit. (The Star of the 230-place demo map: 161 units where
//! two per counted multiply gave 2,154; its value threshold fell from 8.2e-3 to
//! 6.1e-4.) The posterior function's `E` adds every backward rounding at sensitivity 1 (an
//! adjoint's error reaches a local posterior with a factor at most 1), in the scale
//! of what it rounds: each vector's adjoints are kept scaled by `2^S`, the largest
//! power of two that keeps its adjoints at ones below 1 (the root's block `S = 0`; the
//! demo Star's blocks `2^3`, its places' rows `2^1`), each contribution brought to
//! its target's scale through its constant where that stays below 1, else by an
//! exact left shift or a right shift (one more rounding), and a place's adjoints
//! shifted back before the division: a rounding counts `2^-S` of a unit. (The demo
//! Star: 6,102 units for its posteriors where 15,678 were counted before; its
//! threshold fell from 7.5e-3 to 2.9e-3.) The driver's
//! function returns the fixed-point result only when the value `T` is at least
//! `E·2^(k−32)` with `k` = [`REL_BITS`] (14): its relative error is then at most
//! `2^-k`. The posterior function keeps its result when `T` is at least `E·2^(k−32)`
//! with `k` = [`POST_BITS`] (11): every local posterior `x·(∂T/∂x)/T` is then off by at
//! most `2^(1−k)` = `2^-10`, and its value (the same forward sweep) by `2^-13` of
//! itself (its threshold is also at least the value function's over 2). Below the
//! threshold the `f32` function answers.
//!
//! End to end, with `K` components in the largest decomposition: the log-likelihood is
//! off by at most `K·2^-13` nats (each decomposition's product of `K` values; the
//! streaming state keeps the posterior function's values) plus the `f32` rounding of
//! the float code, and a marginal by at most `2^-10 + 2K·2^-13` (its component's
//! posterior, and the decomposition weights).

use proc_macro2::{Literal, TokenStream};
use quote::quote;

use super::emit::hex;
use super::kernels::Plan;

/// Relative error bits of a fixed-point template value: a value is kept when its
/// error bound is at most `2^-REL_BITS` of it (see the module docs).
pub const REL_BITS: u32 = 14;
/// The same for the posterior function: its local posteriors are kept when their error
/// bound is at most `2^(1 − POST_BITS)` (absolute), no looser than what the
/// decomposition weights' error already allows for a marginal.
pub const POST_BITS: u32 = 11;

/// `w` as a Q0.32 constant `Fx(⌊w·2^32⌋)` (clamped to `[0, 2^32 − 1]`; the body of a
/// fixed-point function imports `Fx`).
pub fn constant(w: f64) -> TokenStream {
    let v = hex(quantise(w));
    quote!(Fx(#v))
}

/// `⌊w·2^32⌋` clamped to `[0, 2^32 − 1]`: Rust's float-to-integer `as` saturates, so
/// a negative or NaN `w` gives 0 and the upper clamp is the only one written out.
fn quantise(w: f64) -> u64 {
    (((w * 4_294_967_296.0).floor()) as u64).min(u64::from(u32::MAX))
}

/// Integer bits of the sum of a vector of `len` entries in `[0, 1)`: `⌈log₂ len⌉`.
pub fn sum_bits(len: usize) -> u32 {
    len.max(1).next_power_of_two().trailing_zeros()
}

/// The floor weight `f` for a product of sums holding `bits` integer bits, as a Q0.32
/// constant of `f·2^(bits − s)` and the shift `s` (smallest with `f·2^(bits − s) < 1`)
/// that brings the product back to Q0.32.
pub fn scaled_constant(f: f64, bits: u32) -> (TokenStream, u32) {
    let mut s = 0;
    while s < bits && f * 2f64.powi((bits - s) as i32) >= 1.0 {
        s += 1;
    }
    (constant(f * 2f64.powi((bits - s) as i32)), s)
}

/// A template's vectors (variables, then blocks) with every evidence entry at 1: each
/// entry's value and its adjoint `∂T/∂v` there. Values and adjoints only grow with the
/// entries (non-negative weights), so these bound them for every scaled evidence, and
/// an adjoint at ones bounds how much a rounding in that entry moves the root.
pub struct AtOnes {
    /// `value[g][i]`.
    pub value: Vec<Vec<f64>>,
    /// `adjoint[g][i]`.
    pub adjoint: Vec<Vec<f64>>,
}

impl AtOnes {
    /// Evaluates `plan` at ones, forward and backward (one pass over its weights).
    pub fn of(plan: &Plan) -> AtOnes {
        let mut value: Vec<Vec<f64>> = vec![vec![1.0; plan.classes]; plan.n];
        for block in &plan.blocks {
            let mut v = vec![0.0; block.sums.len()];
            for seg in &block.segments {
                for (m, w) in seg.weights.iter().enumerate() {
                    for (t, &wt) in w.iter().enumerate().filter(|(_, w)| **w > 0.0) {
                        let idx = seg.tuple(t);
                        let p: f64 = seg
                            .inputs
                            .iter()
                            .zip(&idx)
                            .map(|(&g, &i)| value[g][i])
                            .product();
                        v[m] += wt * p;
                    }
                }
            }
            value.push(v);
        }
        let mut adjoint: Vec<Vec<f64>> = value.iter().map(|v| vec![0.0; v.len()]).collect();
        adjoint[plan.n + plan.root.0][plan.root.1] = 1.0;
        for (b, block) in plan.blocks.iter().enumerate().rev() {
            for seg in &block.segments {
                for (m, w) in seg.weights.iter().enumerate() {
                    let a = adjoint[plan.n + b][m];
                    for (t, &wt) in w.iter().enumerate().filter(|(_, w)| **w > 0.0 && a > 0.0) {
                        let idx = seg.tuple(t);
                        for q in 0..seg.inputs.len() {
                            let others: f64 = (0..seg.inputs.len())
                                .filter(|&o| o != q)
                                .map(|o| value[seg.inputs[o]][idx[o]])
                                .product();
                            adjoint[seg.inputs[q]][idx[q]] += a * wt * others;
                        }
                    }
                }
            }
        }
        AtOnes { value, adjoint }
    }

    /// The adjoint of row `m` of block `b`.
    pub fn row(&self, n: usize, b: usize, m: usize) -> f64 {
        self.adjoint[n + b][m]
    }

    /// The sum of vector `g`'s values.
    pub fn sum(&self, g: usize) -> f64 {
        self.value[g].iter().sum()
    }

    /// The error units of truncating the evidence entries: `Σ` of their adjoints.
    pub fn entry_units(&self, n: usize) -> f64 {
        self.adjoint[..n].iter().flatten().sum()
    }
}

/// The smallest Q0.32 value kept from a function with `units` error units:
/// `E·2^(bits − 32)` ([`REL_BITS`] or [`POST_BITS`]), as a raw `u32` (saturating: a
/// function whose bound is that loose never keeps a result).
pub fn threshold(units: u64, bits: u32) -> u64 {
    units.saturating_mul(1 << bits).min(u64::from(u32::MAX))
}

/// The thresholds of a template's value and posterior functions, from their error
/// units, as literals: the posterior function's value comes from the same forward
/// sweep as the value function's, so its threshold also keeps that value within
/// `2^(1 − REL_BITS)` of itself.
pub fn thresholds(fwd_units: u64, post_units: u64) -> (Literal, Literal) {
    let fwd = threshold(fwd_units, REL_BITS);
    let post = threshold(post_units, POST_BITS).max(threshold(fwd_units, REL_BITS - 1));
    (
        Literal::u32_unsuffixed(fwd as u32),
        Literal::u32_unsuffixed(post as u32),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At ones a normalised template is 1, each variable's entry adjoints add up to 1
    /// (`T` is linear in each row, and `T(1) = 1`), and no row's adjoint exceeds 1.
    #[test]
    fn values_and_adjoints_at_ones_match_the_model() {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        let model = crate::learn::Model::load(dir.join("../generated/demo/model.json")).unwrap();
        let mut planned = 0;
        let mut forward_units = vec![];
        let mut backward_units = vec![];
        for spn in &model.spns {
            let Some(plan) = crate::codegen::kernels::plan(spn, model.classes.len()) else {
                continue;
            };
            planned += 1;
            let o = AtOnes::of(&plan);
            let root = o.value[plan.n + plan.root.0][plan.root.1];
            assert!((root - 1.0).abs() < 1e-9, "root {root}");
            for v in 0..plan.n {
                let s: f64 = o.adjoint[v].iter().sum();
                assert!((s - 1.0).abs() < 1e-9, "variable {v}: {s}");
            }
            assert!((o.entry_units(plan.n) - plan.n as f64).abs() < 1e-6);
            // The value function's bound adds the roundings of its sums (each with a
            // non-negative sensitivity) to the entries' truncations: above them.
            let fx = crate::codegen::sparse::SparseCode::fixed("t".into(), &plan);
            let _ = fx.fwd(&crate::codegen::emit::Lit::new(
                crate::codegen::Precision::F32,
            ));
            assert!(fx.forward_units() > o.entry_units(plan.n) + 1.0);
            forward_units.push(fx.forward_units());
            // The posterior function's shifted units count each of its shifted vector
            // sums (`sum_shr(&v, k)`: under `2^k` units), read off the emitted code.
            fx.take_shift_units();
            let (code, _) = fx.post(&crate::codegen::emit::Lit::new(
                crate::codegen::Precision::F32,
            ));
            let units = fx.take_shift_units();
            backward_units.push(fx.backward_units());
            let text = code.to_string();
            let sums: usize = text
                .split("sum_shr")
                .skip(1)
                .map(|call| {
                    let args = call.split(')').next().unwrap_or("");
                    let k: u32 = args
                        .rsplit(',')
                        .next()
                        .unwrap_or("")
                        .trim()
                        .parse()
                        .unwrap();
                    1usize << k
                })
                .sum();
            assert!(
                sums > 0 && units >= sums,
                "{units} units, {sums} from vector sums"
            );
            assert!(
                o.adjoint[plan.n..]
                    .iter()
                    .flatten()
                    .all(|&a| a <= 1.0 + 1e-9)
            );
        }
        assert!(planned >= 3);
        // The value bounds of the demo model's Star, Three, Pair and Singleton, pinned:
        // they decide which templates keep their fixed-point values, so a change of the
        // bookkeeping (a sum's or a row's roundings counted differently) must be reviewed.
        // (Before the groups' inner sums were kept scaled: 2,153, 654, 120, 23.)
        let pinned = [
            160.55442483553617,
            74.07593999593882,
            30.88665635156628,
            23.0,
        ];
        assert_eq!(forward_units.len(), pinned.len());
        for (u, p) in forward_units.iter().zip(pinned) {
            assert!((u - p).abs() <= 1e-9 * p, "forward units {u}, pinned {p}");
        }
        // The same for the backward sweeps' roundings, each at its adjoints' scale.
        let pinned = [5732.630859375, 1097.78125, 97.8125, 1.25];
        assert_eq!(backward_units.len(), pinned.len());
        for (u, p) in backward_units.iter().zip(pinned) {
            assert!((u - p).abs() <= 1e-9 * p, "backward units {u}, pinned {p}");
        }
    }

    /// `AtOnes` is the template's value and its variables' adjoints at ones whatever the
    /// weights: on the demo Star with every sum's weights scaled apart (so no vector is
    /// 1 at ones, as in a normalised template, where products and quotients of values
    /// agree) against a direct evaluation of the SPN — `T` at ones, and `∂T/∂α_v,i` =
    /// `T` with row `v` the unit row `e_i` (`T` is linear in each row).
    #[test]
    fn values_and_adjoints_at_ones_of_an_unnormalised_template() {
        use crate::spn::Node;
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        let model = crate::learn::Model::load(dir.join("../generated/demo/model.json")).unwrap();
        let mut spn = model.spns[0].clone();
        let mut scale = 0.0;
        for node in &mut spn.nodes {
            if let Node::Sum { weights, .. } = node {
                scale += 0.37;
                for w in weights.iter_mut() {
                    *w *= 1.3 + (scale % 1.0);
                }
            }
        }
        let c = model.classes.len();
        let plan = crate::codegen::kernels::plan(&spn, c).expect("the Star has blocks");
        let eval = |row_of: &dyn Fn(usize, usize) -> f64| {
            let mut v: Vec<f64> = Vec::with_capacity(spn.nodes.len());
            for node in &spn.nodes {
                let x = match node {
                    Node::Leaf { var, class } => row_of(*var as usize, *class as usize),
                    Node::Sum { children, weights } => children
                        .iter()
                        .zip(weights)
                        .map(|(&ch, w)| w * v[ch as usize])
                        .sum(),
                    Node::Product { children } => {
                        children.iter().map(|&ch| v[ch as usize]).product()
                    }
                };
                v.push(x);
            }
            v[spn.root as usize]
        };
        let o = AtOnes::of(&plan);
        let root = o.value[plan.n + plan.root.0][plan.root.1];
        let want = eval(&|_, _| 1.0);
        assert!(
            (want - 1.0).abs() > 0.1,
            "the scaled template is not 1 at ones"
        );
        assert!(
            (root - want).abs() <= 1e-9 * want,
            "root {root}, SPN {want}"
        );
        for v in 0..plan.n {
            for i in 0..c {
                let want = eval(&|var, class| if var != v || class == i { 1.0 } else { 0.0 });
                let got = o.adjoint[v][i];
                assert!(
                    (got - want).abs() <= 1e-9 * want.max(1e-12),
                    "variable {v} class {i}: {got}, SPN {want}"
                );
            }
        }
    }

    /// A value is kept at `E·2^(REL_BITS − 32)`; a posterior function's result at the
    /// larger of its own `E·2^(POST_BITS − 32)` and the value's threshold halved (its
    /// value, from the same sweep, within `2^(1 − REL_BITS)` of itself); saturating.
    #[test]
    fn thresholds_are_the_documented_error_multiples() {
        let value = |t: &Literal| t.to_string().parse::<u64>().unwrap();
        let (fwd, post) = thresholds(1000, 10);
        assert_eq!(value(&fwd), 1000 << REL_BITS);
        assert_eq!(value(&post), 1000 << (REL_BITS - 1));
        let (fwd, post) = thresholds(10, 100_000);
        assert_eq!(value(&fwd), 10 << REL_BITS);
        assert_eq!(value(&post), 100_000 << POST_BITS);
        let (fwd, post) = thresholds(1 << 20, 1);
        assert_eq!(value(&fwd), u64::from(u32::MAX));
        assert_eq!(value(&post), u64::from(u32::MAX));
    }

    #[test]
    fn sums_get_enough_integer_bits() {
        assert_eq!(sum_bits(1), 0);
        assert_eq!(sum_bits(2), 1);
        assert_eq!(sum_bits(10), 4);
        assert_eq!(sum_bits(16), 4);
        assert_eq!(sum_bits(17), 5);
    }

    #[test]
    fn constants_round_down_and_floors_fit() {
        assert_eq!(quantise(0.5), 1 << 31);
        assert_eq!(quantise(1.0), u64::from(u32::MAX));
        assert_eq!(quantise(-1e-9), 0);
        assert_eq!(quantise(1e-12), 0);
        assert_eq!(quantise(f64::NAN), 0);
        assert_eq!(quantise(f64::INFINITY), u64::from(u32::MAX));
        assert_eq!(quantise(f64::NEG_INFINITY), 0);
        // A floor of 1/100 over a product of two 10-class sums (8 bits): 2.56 needs
        // two bits of shift.
        let (_, s) = scaled_constant(0.01, 8);
        assert_eq!(s, 2);
        let (_, s) = scaled_constant(0.001, 8);
        assert_eq!(s, 0);
    }
}
