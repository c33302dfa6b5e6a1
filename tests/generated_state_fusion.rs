//! The streaming `State`'s exact fusion of observations, for both model families
//! (`graphspn-generated`'s demo floor modules, GraphSPN and tree mixture): fused evidence
//! must neither underflow nor lock a class, and the state's log-likelihood is that of
//! the product of every observation.
//!
//! - hundreds of observations for one class, then more for another: the place ends on
//!   the second class, then back on the first, each time with the fused rows, marginals
//!   and log-likelihood of an exact `f64` log-domain reference (a renormalised `f32` row
//!   would have flushed the second class to 0 after about 40 observations and stayed
//!   there);
//! - 10^6 random observations: at checkpoints every fused row agrees with the log-domain
//!   reference (no drift), every entry is 0 or a normal `f32` (no subnormals), no class
//!   the reference keeps above the family's flush threshold is 0 (nothing locked), the marginals
//!   agree with the stateless functions on the reference rows and on the state's rows,
//!   and the log-likelihood equals the stateless log-likelihood of the product of the
//!   observations (the reference rows' plus `γ · Σ_p max_c ln Π α`).
//!
//! The reference's marginals come from the stateless generated functions, which
//! `generated_vs_interpreter` and `generated_trees` check against the interpreter.

#[allow(dead_code)]
#[path = "../firmware/src/evidence.rs"]
mod evidence;

use evidence::SplitMix64;
use graphspn_generated::{demo_floor, demo_floor_trees};
use graphspn_runtime::CompiledMap;

/// The exact fused rows: per place and class `Σ ln α`, in `f64`.
struct LogRows(Vec<Vec<f64>>);

impl LogRows {
    fn new(n: usize, c: usize) -> LogRows {
        LogRows(vec![vec![0.0; c]; n])
    }
    fn observe(&mut self, p: usize, row: &[f32]) {
        for (l, &a) in self.0[p].iter_mut().zip(row) {
            *l += f64::from(a).ln();
        }
    }
    /// Place `p`'s best class: `max ln α`.
    fn best(&self, p: usize) -> f64 {
        self.0[p].iter().cloned().fold(f64::NEG_INFINITY, f64::max)
    }
    /// Place `p`'s row relative to its best class: `ln α_c − max ln α`.
    fn relative(&self, p: usize) -> Vec<f64> {
        let max = self.best(p);
        self.0[p].iter().map(|l| l - max).collect()
    }
}

/// The largest entry of a row.
fn top(row: &[f32]) -> f32 {
    row.iter().cloned().fold(0.0, f32::max)
}

/// The state against the reference: every fused row (no drift, no subnormals, nothing
/// locked), the marginals against the stateless functions on the reference rows and on
/// the state's rows, the log-likelihood against the product's.
fn check<M: CompiledMap<Scalar = f32>>(s: &mut M::State, exact: &LogRows, tag: &str) {
    let (n, c) = (M::NUM_PLACES, M::NUM_CLASSES);
    let tag = format!("{} {tag}", M::MODEL_FAMILY);
    let e: Vec<M::Row> = M::state_evidence(s).to_vec();
    for (p, row) in e.iter().enumerate() {
        let (row, rel) = (row.as_ref(), exact.relative(p));
        let t = top(row);
        for (k, (&x, &r)) in row.iter().zip(&rel).enumerate() {
            let at = format!("{tag}: place {p} class {k}: state {x:e}, exact ln {r}");
            assert!(x == 0.0 || x >= f32::MIN_POSITIVE, "subnormal: {at}");
            // Classes below 2^flush of the best are 0 in the row the inference reads
            // (and kept exactly in the state): 2^-24 for GraphSPN templates (products
            // of five entries stay normal), the smallest normal 2^-126 for tree
            // mixtures.
            let flush = if M::MODEL_FAMILY == "graphspn" {
                24.0
            } else {
                126.0
            };
            let flush = -flush * std::f64::consts::LN_2;
            if r > flush + 1.0 {
                assert!(x > 0.0, "flushed or locked: {at}");
                assert!((f64::from(x / t).ln() - r).abs() < 1e-3, "drift: {at}");
            } else if r < flush - 1.0 {
                assert_eq!(x, 0.0, "{at}");
            }
        }
    }
    // The reference rows (largest entry 1) and what they lie below the product.
    let mut reference = vec![M::ZERO_ROW; n];
    for (p, r) in reference.iter_mut().enumerate() {
        for (o, l) in r.as_mut().iter_mut().zip(exact.relative(p)) {
            *o = l.exp() as f32;
        }
    }
    let gamma = f64::from(M::EVIDENCE_EXPONENT);
    let dropped: f64 = (0..n).map(|p| exact.best(p)).sum();
    let held: f64 = e.iter().map(|r| f64::from(top(r.as_ref())).ln()).sum();
    let mut want = vec![M::ZERO_ROW; n];
    let wl = f64::from(M::marginals(&reference, &mut want).unwrap()) + gamma * dropped;
    let mut full = vec![M::ZERO_ROW; n];
    let sl = f64::from(M::marginals(&e, &mut full).unwrap()) + gamma * (dropped - held);
    let mut out = vec![M::ZERO_ROW; n];
    let ll = f64::from(M::state_marginals(s, &mut out).unwrap());
    let l1 = f64::from(M::state_log_likelihood(s).unwrap());
    assert_eq!(ll, l1, "{tag}: marginals' ll vs log_likelihood");
    assert!(
        (ll - wl).abs() <= 1e-5 * wl.abs().max(1.0),
        "{tag}: ll {ll} vs the exact product's {wl}"
    );
    assert!(
        (ll - sl).abs() <= 1e-5 * sl.abs().max(1.0),
        "{tag}: ll {ll} vs stateless {sl}"
    );
    for p in 0..n {
        for k in 0..c {
            let (a, b, x) = (out[p].as_ref()[k], full[p].as_ref()[k], want[p].as_ref()[k]);
            assert!(
                (a - x).abs() <= 1e-4,
                "{tag}: marginal {p}/{k}: {a} vs exact {x}"
            );
            assert!(
                (a - b).abs() <= 1e-5,
                "{tag}: marginal {p}/{k}: {a} vs stateless {b}"
            );
        }
    }
}

/// An observation favouring class `class` (0.9) over `other` (0.1) and the rest (0.05).
fn favouring<M: CompiledMap<Scalar = f32>>(class: usize, other: usize) -> M::Row {
    let mut row = M::ZERO_ROW;
    for x in row.as_mut() {
        *x = 0.05;
    }
    row.as_mut()[other] = 0.1;
    row.as_mut()[class] = 0.9;
    row
}

fn argmax(row: &[f32]) -> usize {
    (0..row.len()).fold(0, |b, k| if row[k] > row[b] { k } else { b })
}

fn outvoted_class_comes_back<M: CompiledMap<Scalar = f32>>() {
    let (p, a, b) = (11, 2, 3);
    let mut s = M::NEW_STATE;
    let mut exact = LogRows::new(M::NUM_PLACES, M::NUM_CLASSES);
    let mut one = M::ZERO_ROW;
    // Net evidence after each phase: a by 9^300, b by 9^100, a by 9^50.
    for (phase, (class, count)) in [(a, 300), (b, 400), (a, 150)].into_iter().enumerate() {
        let row = favouring::<M>(class, a + b - class);
        for _ in 0..count {
            M::observe(&mut s, p, &row).unwrap();
            exact.observe(p, row.as_ref());
        }
        check::<M>(&mut s, &exact, &format!("phase {phase}"));
        M::state_marginal(&mut s, p, &mut one).unwrap();
        let one = one.as_ref();
        assert_eq!(argmax(one), class, "phase {phase}: marginal {one:?}");
        assert!(one[class] > 0.999, "phase {phase}: {one:?}");
    }
}

fn million_observations_stay_exact<M: CompiledMap<Scalar = f32>>(seed: u64) {
    let mut rng = SplitMix64(seed);
    let mut s = M::NEW_STATE;
    let mut exact = LogRows::new(M::NUM_PLACES, M::NUM_CLASSES);
    let mut row = M::ZERO_ROW;
    let total = 1_000_000;
    for i in 1..=total {
        let p = (rng.next_u64() % M::NUM_PLACES as u64) as usize;
        for x in row.as_mut() {
            *x = rng.unit_f32();
        }
        M::observe(&mut s, p, &row).unwrap();
        exact.observe(p, row.as_ref());
        if [1_000, 100_000, total].contains(&i) {
            check::<M>(&mut s, &exact, &format!("after {i} observations"));
        }
    }
}

#[test]
fn a_class_outvoted_for_hundreds_of_observations_comes_back() {
    outvoted_class_comes_back::<demo_floor::Map>();
    outvoted_class_comes_back::<demo_floor_trees::Map>();
}

#[test]
fn a_million_random_observations_stay_exact_graphspn() {
    million_observations_stay_exact::<demo_floor::Map>(23);
}

#[test]
fn a_million_random_observations_stay_exact_tree_mixture() {
    million_observations_stay_exact::<demo_floor_trees::Map>(23);
}
