//! The tree-mixture `State`'s exact fusion of observations (the issue-23 lesson: fused
//! evidence must neither underflow nor lock a class), on `graphspn-generated`'s demo
//! floor module:
//!
//! - hundreds of observations for one class, then more for another: the place ends on
//!   the second class, then back on the first, each time with the marginals and the
//!   fused row of an exact `f64` log-domain reference (a renormalised `f32` row would
//!   have flushed the second class to 0 after about 40 observations and stayed there);
//! - 10^6 random observations: at checkpoints every fused row agrees with the log-domain
//!   reference (no drift), every entry is 0 or a normal `f32` (no subnormals) and no
//!   class the reference keeps within `f32` range is 0 (nothing locked), and the
//!   state's marginals and log-likelihood agree with `TreeInstance` on the reference
//!   rows and with the stateless functions on the state's rows.

#[allow(dead_code)]
#[path = "../firmware/src/evidence.rs"]
mod evidence;

use evidence::SplitMix64;
use graphspn::codegen::{AnyInputs, Builder};
use graphspn::treemix::TreeInstance;
use graphspn_generated::demo_floor_trees::{
    self as m, Evidence, Marginals, NUM_CLASSES, NUM_PLACES, State,
};

/// The module's reference: `TreeInstance` with the inputs of `generated/build.rs`.
fn reference() -> TreeInstance {
    let demo = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("generated/demo");
    match Builder::new(demo.join("tree_model.json"), demo.join("floor.json"))
        .seed(0)
        .load_any()
        .unwrap()
    {
        AnyInputs::TreeMixture(i) => TreeInstance::build(&i.model, &i.map, i.trees).unwrap(),
        AnyInputs::Graphspn(_) => unreachable!("the demo tree model is a tree mixture"),
    }
}

/// The exact fused rows: per place and class `Σ ln α`, in `f64`.
struct LogRows(Vec<Vec<f64>>);

impl LogRows {
    fn new() -> LogRows {
        LogRows(vec![vec![0.0; NUM_CLASSES]; NUM_PLACES])
    }
    fn observe(&mut self, p: usize, row: &[f32; NUM_CLASSES]) {
        for (l, &a) in self.0[p].iter_mut().zip(row) {
            *l += f64::from(a).ln();
        }
    }
    /// Place `p`'s row relative to its best class: `ln α_c − max ln α`.
    fn relative(&self, p: usize) -> Vec<f64> {
        let max = self.0[p].iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        self.0[p].iter().map(|l| l - max).collect()
    }
    /// Every row as linear values with a largest entry of 1.
    fn rows(&self) -> Vec<Vec<f64>> {
        (0..NUM_PLACES)
            .map(|p| self.relative(p).into_iter().map(f64::exp).collect())
            .collect()
    }
}

/// The state against the reference: every fused row (no drift, no subnormals, nothing
/// locked), the marginals and log-likelihood against `TreeInstance` on the reference
/// rows and against the stateless functions on the state's rows.
fn check(s: &mut State, exact: &LogRows, inst: &mut TreeInstance, tag: &str) {
    let e: Evidence = *s.evidence();
    for (p, row) in e.iter().enumerate() {
        let rel = exact.relative(p);
        for (k, (&x, &r)) in row.iter().zip(&rel).enumerate() {
            let at = format!("{tag}: place {p} class {k}: state {x:e}, exact ln {r}");
            assert!(x == 0.0 || x >= f32::MIN_POSITIVE, "subnormal: {at}");
            if r > -80.0 {
                assert!(x > 0.0, "flushed or locked: {at}");
                assert!((f64::from(x).ln() - r).abs() < 1e-3, "drift: {at}");
            } else if r < -90.0 {
                assert_eq!(x, 0.0, "{at}");
            }
        }
    }
    inst.set_all_evidence(&exact.rows()).unwrap();
    let want = inst.marginals().unwrap();
    let mut out: Marginals = [[0.0; NUM_CLASSES]; NUM_PLACES];
    let ll = f64::from(s.marginals(&mut out).unwrap());
    let mut full: Marginals = [[0.0; NUM_CLASSES]; NUM_PLACES];
    let sl = f64::from(m::marginals(&e, &mut full).unwrap());
    let wl = want.mixed.log_likelihood;
    assert!(
        (ll - wl).abs() <= 1e-4 * wl.abs().max(1.0),
        "{tag}: ll {ll} vs exact {wl}"
    );
    assert!(
        (ll - sl).abs() <= 1e-5 * sl.abs().max(1.0),
        "{tag}: ll {ll} vs stateless {sl}"
    );
    for p in 0..NUM_PLACES {
        for k in 0..NUM_CLASSES {
            let (a, b, x) = (out[p][k], full[p][k], want.mixed.probs[p][k]);
            assert!(
                (f64::from(a) - x).abs() <= 1e-4,
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
fn favouring(class: usize, other: usize) -> [f32; NUM_CLASSES] {
    let mut row = [0.05; NUM_CLASSES];
    row[other] = 0.1;
    row[class] = 0.9;
    row
}

fn argmax(row: &[f32; NUM_CLASSES]) -> usize {
    (0..NUM_CLASSES).fold(0, |b, k| if row[k] > row[b] { k } else { b })
}

#[test]
fn a_class_outvoted_for_hundreds_of_observations_comes_back() {
    let (p, a, b) = (11, 2, 3);
    let mut s = State::new();
    let mut exact = LogRows::new();
    let mut inst = reference();
    let mut one = [0.0f32; NUM_CLASSES];
    // Net evidence after each phase: a by 9^300, b by 9^100, a by 9^50.
    for (phase, (class, count)) in [(a, 300), (b, 400), (a, 150)].into_iter().enumerate() {
        let row = favouring(class, a + b - class);
        for _ in 0..count {
            s.observe(p, &row).unwrap();
            exact.observe(p, &row);
        }
        check(&mut s, &exact, &mut inst, &format!("phase {phase}"));
        s.marginal(p, &mut one).unwrap();
        assert_eq!(argmax(&one), class, "phase {phase}: marginal {one:?}");
        assert!(one[class] > 0.999, "phase {phase}: {one:?}");
    }
}

#[test]
fn a_million_random_observations_stay_exact() {
    let mut rng = SplitMix64(23);
    let mut s = State::new();
    let mut exact = LogRows::new();
    let mut inst = reference();
    let mut row = [0.0f32; NUM_CLASSES];
    let total = 1_000_000;
    for i in 1..=total {
        let p = (rng.next_u64() % NUM_PLACES as u64) as usize;
        for x in row.iter_mut() {
            *x = rng.unit_f32();
        }
        s.observe(p, &row).unwrap();
        exact.observe(p, &row);
        if [1_000, 100_000, total].contains(&i) {
            check(
                &mut s,
                &exact,
                &mut inst,
                &format!("after {i} observations"),
            );
        }
    }
}
