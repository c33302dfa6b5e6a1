//! The generation-time analysis that decides, per template, whether linear-space
//! evaluation is safe (the inputs are checked by [`crate::inputs::check_inputs`]).
//!
//! # Why linear space is safe when [`Numerics::Linear`] is chosen
//!
//! Generated code scales every place's evidence row so its largest entry is exactly 1
//! (`x_p = α_p / s_p`; `S` is homogeneous of degree 1 in each row, so
//! `ln S(α) = Σ_p ln s_p + ln S(x)`). A template SPN `T` with normalised weights is a
//! multilinear polynomial with non-negative coefficients in the `x` entries, so
//! `T(x) ≥ T(onehot(argmax x)) ≥ LB`, where `LB` is the minimum of `T` over all one-hot
//! class assignments (enumerated here). Every node value is `≤ 1` (it is a normalised
//! distribution evaluated at entries `≤ 1`). When `LB ≥` the precision's threshold
//! (`1e-20` for `f32`, `1e-200` for `f64`), any intermediate term that underflows
//! contributes an absolute error of at most the smallest normal number (`1.2e-38` for
//! `f32`) per term, i.e. a relative error `≤ #terms · 1.2e-38 / 1e-20 < 1e-14` of the
//! template's value, negligible against rounding. The same argument, with the minimum
//! of the max-product network over one-hot assignments, covers MPE. Otherwise (weights
//! not normalised, a zero weight pattern, or too many assignments to enumerate) the
//! template is generated in log space, which is always correct.

use std::collections::BTreeMap;

use crate::decompose::Decomposition;
use crate::spn::{Node, Spn};

use super::Precision;
use super::kernels::Plan;

/// How a template's functions compute.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Numerics {
    /// Linear space; values are `≥ min_value` (and max-product values `≥ min_max`)
    /// for scaled evidence.
    Linear {
        /// Lower bound of the template value for scaled evidence.
        min_value: f64,
        /// Lower bound of the max-product value for scaled evidence.
        min_max: f64,
    },
    /// Log space (every node holds a natural-log value).
    Log,
}

/// Largest number of one-hot assignments enumerated to bound a template from below.
pub const MAX_ASSIGNMENTS: u64 = 2_000_000;
/// Largest `assignments × nodes` work spent on that bound (the default 10-class
/// symmetric Star: 10^5 × 4,101 nodes, about 2 s in an optimised build).
pub const MAX_WORK: u64 = 2_000_000_000;

/// Value of every node for leaf inputs `x[var][class]` (sum or max at sum nodes).
pub fn eval_nodes(spn: &Spn, x: &[Vec<f64>], max: bool) -> Vec<f64> {
    let mut v = vec![0.0; spn.nodes.len()];
    for (i, n) in spn.nodes.iter().enumerate() {
        v[i] = match n {
            Node::Leaf { var, class } => x[*var as usize][*class as usize],
            Node::Product { children } => children.iter().map(|&c| v[c as usize]).product(),
            Node::Sum { children, weights } => {
                let terms = children
                    .iter()
                    .zip(weights)
                    .map(|(&c, w)| w * v[c as usize]);
                if max {
                    terms.fold(0.0, f64::max)
                } else {
                    terms.sum()
                }
            }
        };
    }
    v
}

/// Whether every sum's weights add up to 1 (within `1e-6`) and the SPN is complete and
/// decomposable at one-hot inputs, checked cheaply: the value at all-ones input is 1.
fn normalised(spn: &Spn) -> bool {
    let sums_ok = spn.nodes.iter().all(|n| match n {
        Node::Sum { weights, .. } => (weights.iter().sum::<f64>() - 1.0).abs() <= 1e-6,
        _ => true,
    });
    if !sums_ok {
        return false;
    }
    let ones: Vec<Vec<f64>> = spn.classes.iter().map(|&c| vec![1.0; c as usize]).collect();
    let v = eval_nodes(spn, &ones, false);
    (v[spn.root as usize] - 1.0).abs() <= 1e-6
}

/// Decides linear or log space for one template SPN (see the module docs).
///
/// With the template's block structure (`plan`, see `kernels.rs`) the lower bounds come
/// from `plan_lower_bounds` without enumerating assignments (for the trained Star
/// it is within 15% of the enumerated minimum); otherwise every one-hot assignment is
/// evaluated node by node, up to [`MAX_ASSIGNMENTS`] and [`MAX_WORK`].
pub(crate) fn numerics(spn: &Spn, precision: Precision, plan: Option<&Plan>) -> Numerics {
    let threshold = match precision {
        Precision::F32 => 1e-20,
        Precision::F64 => 1e-200,
    };
    if !normalised(spn) {
        return Numerics::Log;
    }
    let (min_value, min_max) = match plan {
        Some(p) => plan_lower_bounds(p),
        None => match enumerated_minima(spn) {
            Some(b) => b,
            None => return Numerics::Log,
        },
    };
    if min_value >= threshold && min_max >= threshold {
        Numerics::Linear { min_value, min_max }
    } else {
        Numerics::Log
    }
}

/// The minima of the value and the max-product value over all one-hot assignments,
/// node by node; `None` when that is more than [`MAX_ASSIGNMENTS`] or [`MAX_WORK`].
fn enumerated_minima(spn: &Spn) -> Option<(f64, f64)> {
    let n = spn.num_vars();
    let c = spn.classes.first().copied().unwrap_or(1) as u64;
    let count = c.checked_pow(n as u32)?;
    if count > MAX_ASSIGNMENTS || count.saturating_mul(spn.nodes.len() as u64) > MAX_WORK {
        return None;
    }
    let mut x: Vec<Vec<f64>> = vec![vec![0.0; c as usize]; n];
    let mut y = vec![0usize; n];
    let (mut min_value, mut min_max) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..count {
        for (row, &cls) in x.iter_mut().zip(&y) {
            row.iter_mut().for_each(|v| *v = 0.0);
            row[cls] = 1.0;
        }
        min_value = min_value.min(eval_nodes(spn, &x, false)[spn.root as usize]);
        min_max = min_max.min(eval_nodes(spn, &x, true)[spn.root as usize]);
        for digit in y.iter_mut() {
            *digit += 1;
            if *digit < c as usize {
                break;
            }
            *digit = 0;
        }
    }
    Some((min_value, min_max))
}

/// Lower bounds of a block-structured template's value and max-product value over all
/// one-hot assignments, without enumerating them (for templates with too many).
///
/// Bottom-up per block entry: a segment's term at assignment `y` is
/// `Σ_t w_t Π_b val_b(y)[t_b]` over the tuples `t` whose variable indices match `y`,
/// and the block inputs `b` depend on disjoint variables (decomposability), so its
/// minimum over `y` is at least `min_{y_vars} Σ_t w_t Π_b LB_b[t_b]`; a block's minimum
/// is at least the sum of its segments' minima. For max-product, `min_y max_t ≥
/// max_t min_y` gives `max_seg min_{y_vars} max_t w_t Π_b LB_b[t_b]`. Looser than the
/// enumerated minimum, never above it.
fn plan_lower_bounds(plan: &Plan) -> (f64, f64) {
    let mut lb_sum: Vec<Vec<f64>> = Vec::with_capacity(plan.blocks.len());
    let mut lb_max: Vec<Vec<f64>> = Vec::with_capacity(plan.blocks.len());
    for block in &plan.blocks {
        let m_len = block.sums.len();
        let mut out_sum = vec![0.0f64; m_len];
        let mut out_max = vec![0.0f64; m_len];
        for seg in &block.segments {
            let vars: usize = seg
                .inputs
                .iter()
                .zip(&seg.dims)
                .filter(|(g, _)| **g < plan.n)
                .map(|(_, d)| d)
                .product();
            let mut acc_sum = vec![vec![0.0f64; vars]; m_len];
            let mut acc_max = vec![vec![0.0f64; vars]; m_len];
            let size: usize = seg.dims.iter().product();
            for t in 0..size {
                // Indices of the tuple (row-major, last input fastest).
                let (mut rest, mut key, mut key_mult) = (t, 0usize, 1usize);
                let (mut p_sum, mut p_max) = (1.0f64, 1.0f64);
                for (&g, &d) in seg.inputs.iter().zip(&seg.dims).rev() {
                    let i = rest % d;
                    rest /= d;
                    if g < plan.n {
                        key += i * key_mult;
                        key_mult *= d;
                    } else {
                        p_sum *= lb_sum[g - plan.n][i];
                        p_max *= lb_max[g - plan.n][i];
                    }
                }
                for (m, wm) in seg.weights.iter().enumerate() {
                    acc_sum[m][key] += wm[t] * p_sum;
                    acc_max[m][key] = acc_max[m][key].max(wm[t] * p_max);
                }
            }
            for m in 0..m_len {
                let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
                out_sum[m] += min(&acc_sum[m]);
                out_max[m] = out_max[m].max(min(&acc_max[m]));
            }
        }
        lb_sum.push(out_sum);
        lb_max.push(out_max);
    }
    (
        lb_sum[plan.root.0][plan.root.1],
        lb_max[plan.root.0][plan.root.1],
    )
}

/// A component shared by one or more decompositions (same template, same places).
#[derive(Clone, Debug)]
pub struct Unique {
    /// Template index.
    pub template: usize,
    /// Places in template order.
    pub places: Vec<usize>,
    /// Decompositions containing it, ascending.
    pub decs: Vec<usize>,
}

/// Deduplicates components across decompositions, in order of first appearance.
pub fn unique_components(decompositions: &[Decomposition]) -> Vec<Unique> {
    let mut index: BTreeMap<(usize, &[usize]), usize> = BTreeMap::new();
    let mut out: Vec<Unique> = Vec::new();
    for (d, dec) in decompositions.iter().enumerate() {
        for comp in &dec.components {
            let key = (comp.template, comp.places.as_slice());
            match index.get(&key) {
                Some(&u) => {
                    if out[u].decs.last() != Some(&d) {
                        out[u].decs.push(d);
                    }
                }
                None => {
                    index.insert(key, out.len());
                    out.push(Unique {
                        template: comp.template,
                        places: comp.places.clone(),
                        decs: vec![d],
                    });
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codegen::kernels::plan;
    use crate::learn::{DenseParams, dense_structure, symmetric_dense_structure};
    use crate::template::Template;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_weights(spn: &mut Spn, rng: &mut ChaCha8Rng) {
        for node in spn.nodes.iter_mut() {
            if let Node::Sum { weights, .. } = node {
                weights
                    .iter_mut()
                    .for_each(|w| *w = rng.random_range(0.05..1.0));
                let total: f64 = weights.iter().sum();
                weights.iter_mut().for_each(|w| *w /= total);
            }
        }
    }

    /// Enumeration stops at either limit on its own: 21 binary variables give 2^21
    /// assignments, over [`MAX_ASSIGNMENTS`], though their work (64 nodes) is far under
    /// [`MAX_WORK`]; 2^20 of them are enumerated.
    #[test]
    fn enumeration_is_refused_past_the_assignment_limit_alone() {
        let independent = |n: u32| {
            let mut nodes = Vec::new();
            for var in 0..n {
                nodes.push(Node::Leaf { var, class: 0 });
                nodes.push(Node::Leaf { var, class: 1 });
            }
            let sums: Vec<u32> = (0..n)
                .map(|v| {
                    nodes.push(Node::Sum {
                        children: vec![2 * v, 2 * v + 1],
                        weights: vec![0.25, 0.75],
                    });
                    nodes.len() as u32 - 1
                })
                .collect();
            nodes.push(Node::Product { children: sums });
            Spn {
                classes: vec![2; n as usize],
                root: nodes.len() as u32 - 1,
                nodes,
            }
        };
        let big = independent(21);
        big.validate().unwrap();
        const { assert!(1 << 21 > MAX_ASSIGNMENTS && (1 << 21) * 64 < MAX_WORK) };
        assert_eq!(enumerated_minima(&big), None);
        let (value, max) = enumerated_minima(&independent(20)).expect("2^20 assignments");
        let expected = 0.25f64.powi(20);
        assert!((value / expected - 1.0).abs() < 1e-12 && (max / expected - 1.0).abs() < 1e-12);
        // And at the work limit alone: the same 2^20 assignments of an SPN padded to
        // 2,000 nodes (unreachable leaves) are 2.1e9 node evaluations, over MAX_WORK.
        let mut heavy = independent(20);
        while heavy.nodes.len() < 2000 {
            heavy.nodes.push(Node::Leaf { var: 0, class: 0 });
        }
        const { assert!((1 << 20) <= MAX_ASSIGNMENTS && (1 << 20) * 2000 > MAX_WORK) };
        assert_eq!(enumerated_minima(&heavy), None);
    }

    /// Two independent binary variables with sum weights `w` each.
    fn pair(w: [f64; 2]) -> Spn {
        pair_of(w, w)
    }

    /// [`pair`] with weights `w0` on variable 0's sum and `w1` on variable 1's.
    fn pair_of(w0: [f64; 2], w1: [f64; 2]) -> Spn {
        let mut nodes = vec![];
        for var in 0..2 {
            nodes.push(Node::Leaf { var, class: 0 });
            nodes.push(Node::Leaf { var, class: 1 });
        }
        nodes.push(Node::Sum {
            children: vec![0, 1],
            weights: w0.to_vec(),
        });
        nodes.push(Node::Sum {
            children: vec![2, 3],
            weights: w1.to_vec(),
        });
        nodes.push(Node::Product {
            children: vec![4, 5],
        });
        Spn {
            classes: vec![2, 2],
            root: 6,
            nodes,
        }
    }

    /// A template whose weights do not add up to 1 takes log space (its values have no
    /// bound to scale by); a normalised one is bounded and stays linear.
    #[test]
    fn unnormalised_templates_take_log_space() {
        assert!(normalised(&pair([0.25, 0.75])));
        assert!(!normalised(&pair([0.5, 0.75])));
        // Worth 1 at ones (2 · 0.5), but a sum worth 2: node values are not bounded by 1.
        assert!(!normalised(&pair_of([1.0, 1.0], [0.25, 0.25])));
        assert!(matches!(
            numerics(&pair([0.5, 0.75]), Precision::F32, None),
            Numerics::Log
        ));
        assert!(!matches!(
            numerics(&pair([0.25, 0.75]), Precision::F32, None),
            Numerics::Log
        ));
    }

    /// The block-wise bounds are positive lower bounds of the enumerated minima, and
    /// not far below them.
    #[test]
    fn block_bounds_are_below_the_enumerated_minima() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let star = Template::star();
        let mut spns = vec![
            symmetric_dense_structure(5, 6, &DenseParams::default(), &star.automorphisms(), 1)
                .unwrap(),
        ];
        for (vars, splits) in [(3, 1), (4, 2), (2, 1)] {
            let params = DenseParams {
                decompositions: splits,
                ..DenseParams::default()
            };
            spns.push(dense_structure(vars, 6, &params, 3).unwrap());
        }
        for mut spn in spns {
            random_weights(&mut spn, &mut rng);
            let p = plan(&spn, 6).expect("a block structure");
            let (lv, lm) = plan_lower_bounds(&p);
            let (ev, em) = enumerated_minima(&spn).expect("enumerable");
            for (bound, exact) in [(lv, ev), (lm, em)] {
                assert!(
                    bound > 0.0 && bound <= exact * (1.0 + 1e-12) && bound >= exact * 1e-3,
                    "{bound} vs {exact}"
                );
            }
        }
    }

    /// Linear space needs both lower bounds above the threshold: the value's and the
    /// max-product value's (MPE runs on the same linear functions). Two copies of
    /// `(1 − ε, ε)²` mixed half and half: at the one-hot `(1, 1)` the value is `ε²`
    /// (1.5e-20, above `f32`'s 1e-20) and the max-product value `ε²/2` (below).
    #[test]
    fn a_max_product_bound_below_the_threshold_takes_log_space() {
        let eps = 1.5e-20f64.sqrt();
        let mut nodes = vec![];
        for var in 0..2 {
            nodes.push(Node::Leaf { var, class: 0 });
            nodes.push(Node::Leaf { var, class: 1 });
        }
        let mut products = vec![];
        for _ in 0..2 {
            for var in 0..2u32 {
                nodes.push(Node::Sum {
                    children: vec![2 * var, 2 * var + 1],
                    weights: vec![1.0 - eps, eps],
                });
            }
            let n = nodes.len() as u32;
            nodes.push(Node::Product {
                children: vec![n - 2, n - 1],
            });
            products.push(nodes.len() as u32 - 1);
        }
        nodes.push(Node::Sum {
            children: products,
            weights: vec![0.5, 0.5],
        });
        let spn = Spn {
            classes: vec![2, 2],
            root: nodes.len() as u32 - 1,
            nodes,
        };
        spn.validate().unwrap();
        let (value, max) = enumerated_minima(&spn).unwrap();
        assert!(value >= 1e-20 && max < 1e-20, "{value:e} {max:e}");
        assert_eq!(numerics(&spn, Precision::F32, None), Numerics::Log);
        assert!(matches!(
            numerics(&spn, Precision::F64, None),
            Numerics::Linear { .. }
        ));
    }
}
