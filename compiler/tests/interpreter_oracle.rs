//! The interpreter against brute-force enumeration of every joint assignment (and,
//! for max-product, of every induced tree) on random SPNs.
//!
//! Proptest runs with a fixed ChaCha seed (`PROPTEST_SEED` below); each case draws a
//! `case_seed` that fully determines the SPN, evidence and fixed classes, and every
//! failure message prints it, so `check_case(case_seed, selective)` replays it.

mod harness;

use graphspn_compiler::interpreter::{BATCH, Evaluator, Evidence, InferenceError};
use graphspn_compiler::runtime::EvidenceError;
use graphspn_compiler::spn::{Node, RandomSpnParams, Spn, random_spn};
use harness::all_assignments;
use proptest::prelude::*;
use proptest::test_runner::{RngAlgorithm, RngSeed};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const PROPTEST_SEED: u64 = 0x6A5B_5EED_2018;
const TREE_LIMIT: usize = 1_000_000;

/// Linear-space value of the SPN with indicators for the full assignment `x` and
/// α = 1 (weights only), by plain memoised recursion.
fn indicator_value(spn: &Spn, node: usize, x: &[u32], memo: &mut [Option<f64>]) -> f64 {
    if let Some(v) = memo[node] {
        return v;
    }
    let v = match &spn.nodes[node] {
        Node::Leaf { var, class } => {
            if x[*var as usize] == *class {
                1.0
            } else {
                0.0
            }
        }
        Node::Sum { children, weights } => children
            .iter()
            .zip(weights)
            .map(|(&c, &w)| w * indicator_value(spn, c as usize, x, memo))
            .sum(),
        Node::Product { children } => children
            .iter()
            .map(|&c| indicator_value(spn, c as usize, x, memo))
            .product(),
    };
    memo[node] = Some(v);
    v
}

/// `ln S(x, α)`: for a complete, decomposable SPN every induced monomial holds exactly
/// one leaf per variable, so `S(x, α) = S(x, 1) · Π_v α_v[x_v]`.
fn log_joint(spn: &Spn, x: &[u32], alpha: &[Vec<f64>]) -> f64 {
    let mut memo = vec![None; spn.nodes.len()];
    let p = indicator_value(spn, spn.root as usize, x, &mut memo);
    let mut lj = p.ln();
    for (v, &c) in x.iter().enumerate() {
        lj += alpha[v][c as usize].ln();
    }
    lj
}

fn lse(xs: &[f64]) -> f64 {
    let m = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if m == f64::NEG_INFINITY {
        return m;
    }
    m + xs.iter().map(|x| (x - m).exp()).sum::<f64>().ln()
}

/// Log-values of every induced tree under `node` whose value is not 0 (a single `-∞`
/// stands for "all are 0"; zero trees never win a max), or None if more than TREE_LIMIT.
fn induced_trees(
    spn: &Spn,
    node: usize,
    leaf_log: &dyn Fn(u32, u32) -> f64,
    memo: &mut Vec<Option<Option<Vec<f64>>>>,
) -> Option<Vec<f64>> {
    if let Some(r) = &memo[node] {
        return r.clone();
    }
    let r = match &spn.nodes[node] {
        Node::Leaf { var, class } => Some(vec![leaf_log(*var, *class)]),
        Node::Sum { children, weights } => {
            let mut out = Vec::new();
            let mut ok = true;
            for (&c, &w) in children.iter().zip(weights) {
                match induced_trees(spn, c as usize, leaf_log, memo) {
                    Some(ts) if out.len() + ts.len() <= TREE_LIMIT => {
                        out.extend(ts.iter().map(|t| w.ln() + t))
                    }
                    _ => {
                        ok = false;
                        break;
                    }
                }
            }
            ok.then_some(out)
        }
        Node::Product { children } => {
            let mut out = vec![0.0];
            let mut ok = true;
            for &c in children {
                match induced_trees(spn, c as usize, leaf_log, memo) {
                    Some(ts) if out.len() * ts.len() <= TREE_LIMIT => {
                        out = out
                            .iter()
                            .flat_map(|a| ts.iter().map(move |b| a + b))
                            .collect();
                    }
                    _ => {
                        ok = false;
                        break;
                    }
                }
            }
            ok.then_some(out)
        }
    };
    let r = r.map(|mut ts| {
        ts.retain(|t| *t > f64::NEG_INFINITY);
        if ts.is_empty() {
            ts.push(f64::NEG_INFINITY);
        }
        ts
    });
    memo[node] = Some(r.clone());
    r
}

fn close_rel(a: f64, b: f64, tol: f64) -> bool {
    (a == b) || (a - b).abs() <= tol * b.abs().max(1.0)
}

fn random_evidence(rng: &mut ChaCha8Rng, classes: &[u32]) -> Vec<Vec<f64>> {
    classes
        .iter()
        .map(|&k| {
            let mut row: Vec<f64> = (0..k)
                .map(|_| match rng.random_range(0..10) {
                    0 | 1 => 0.0,
                    2 | 3 => 10f64.powf(-rng.random_range(200.0..300.0)),
                    4 => 1e-300,
                    _ => rng.random_range(0.0..1.0),
                })
                .collect();
            if row.iter().all(|&a| a == 0.0) {
                let i = rng.random_range(0..k as usize);
                row[i] = 1e-300;
            }
            row
        })
        .collect()
}

/// Random SPNs small enough to enumerate: up to 6 variables of up to 4 classes.
fn small_spn_params(selective: bool) -> RandomSpnParams {
    RandomSpnParams {
        max_vars: 6,
        max_classes: 4,
        max_depth: 5,
        max_children: 4,
        zero_weight_prob: 0.15,
        share_prob: 0.3,
        selective,
    }
}

/// What one case checked (for coverage assertions).
#[derive(Default, Debug)]
struct Checked {
    zero_likelihood: bool,
    trees_checked: bool,
}

fn check_case(case_seed: u64, selective: bool) -> Result<Checked, String> {
    let params = small_spn_params(selective);
    let spn = random_spn(case_seed, &params);
    let ctx = |what: &str| {
        format!(
            "case_seed={case_seed} selective={selective}: {what}\nSPN: {}",
            spn.to_json()
        )
    };
    spn.validate()
        .map_err(|e| ctx(&format!("generator made an invalid SPN: {e}")))?;
    let mut rng = ChaCha8Rng::seed_from_u64(case_seed ^ 0xE71D_E7CE);
    let alpha = random_evidence(&mut rng, &spn.classes);
    let fixed: Vec<Option<u32>> = spn
        .classes
        .iter()
        .map(|&k| rng.random_bool(0.3).then(|| rng.random_range(0..k)))
        .collect();
    let evidence = Evidence::from_rows(alpha.clone());
    let mut ev = Evaluator::new(&spn).map_err(|e| ctx(&e.to_string()))?;
    let ctx = |what: &str| format!("{}\nalpha={alpha:?}\nfixed={fixed:?}", ctx(what));

    // Brute force over all assignments consistent with `fixed`.
    let xs: Vec<Vec<u32>> = all_assignments(&spn.classes)
        .into_iter()
        .filter(|x| x.iter().zip(&fixed).all(|(c, f)| f.is_none_or(|f| f == *c)))
        .collect();
    let ljs: Vec<f64> = xs.iter().map(|x| log_joint(&spn, x, &alpha)).collect();
    let brute_ll = lse(&ljs);

    let ll = ev.log_likelihood(&fixed, &evidence);
    let marg = ev.marginals(&fixed, &evidence);
    let mpe = ev.mpe(&fixed, &evidence);
    if brute_ll == f64::NEG_INFINITY {
        let zero = InferenceError::Evidence(EvidenceError::ZeroLikelihood);
        if ll.as_ref() != Err(&zero)
            || marg.as_ref().err() != Some(&zero)
            || mpe.as_ref().err() != Some(&zero)
        {
            return Err(ctx(&format!(
                "brute force likelihood is 0 but got {ll:?} / {:?} / {:?}",
                marg.err(),
                mpe.err()
            )));
        }
        return Ok(Checked {
            zero_likelihood: true,
            trees_checked: false,
        });
    }
    let ll = ll.map_err(|e| ctx(&format!("log_likelihood failed: {e}")))?;
    if !close_rel(ll, brute_ll, 1e-9) {
        return Err(ctx(&format!(
            "log_likelihood {ll} != brute force {brute_ll}"
        )));
    }
    let marg = marg.map_err(|e| ctx(&format!("marginals failed: {e}")))?;
    if !close_rel(marg.log_likelihood, brute_ll, 1e-9) {
        return Err(ctx("marginals.log_likelihood differs from brute force"));
    }
    for (v, &k) in spn.classes.iter().enumerate() {
        for c in 0..k {
            let sel: Vec<f64> = xs
                .iter()
                .zip(&ljs)
                .filter(|(x, _)| x[v] == c)
                .map(|(_, &l)| l)
                .collect();
            let p = (lse(&sel) - brute_ll).exp();
            let got = marg.probs[v][c as usize];
            if (got - p).abs() > 1e-9 || got.is_nan() {
                return Err(ctx(&format!("P(Y_{v}={c}) = {got}, brute force {p}")));
            }
        }
    }

    let mpe = mpe.map_err(|e| ctx(&format!("mpe failed: {e}")))?;
    for (v, (&a, f)) in mpe.assignment.iter().zip(&fixed).enumerate() {
        if f.is_some_and(|f| f != a) || a >= spn.classes[v] {
            return Err(ctx(&format!(
                "MPE assignment {:?} violates fixed/classes",
                mpe.assignment
            )));
        }
    }
    let joint_at = log_joint(&spn, &mpe.assignment, &alpha);
    if !close_rel(mpe.log_probability, joint_at, 1e-9) {
        return Err(ctx(&format!(
            "MPE log_probability {} != brute joint {joint_at} at {:?}",
            mpe.log_probability, mpe.assignment
        )));
    }
    let brute_max = ljs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if mpe.log_max_product > mpe.log_probability + 1e-9 * mpe.log_probability.abs().max(1.0)
        || mpe.log_probability > brute_max + 1e-9 * brute_max.abs().max(1.0)
    {
        return Err(ctx(&format!(
            "MPE ordering violated: max_product {} probability {} brute max {brute_max}",
            mpe.log_max_product, mpe.log_probability
        )));
    }
    if selective
        && (!close_rel(mpe.log_probability, brute_max, 1e-9)
            || !close_rel(joint_at, brute_max, 1e-9))
    {
        return Err(ctx(&format!(
            "selective MPE {:?} has log prob {} but the brute-force max is {brute_max}",
            mpe.assignment, mpe.log_probability
        )));
    }
    let leaf_log = |var: u32, class: u32| {
        if fixed[var as usize].is_some_and(|f| f != class) {
            f64::NEG_INFINITY
        } else {
            alpha[var as usize][class as usize].ln()
        }
    };
    let mut memo = vec![None; spn.nodes.len()];
    let trees = induced_trees(&spn, spn.root as usize, &leaf_log, &mut memo);
    let trees_checked = trees.is_some();
    if let Some(trees) = trees {
        let best = trees.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if !close_rel(mpe.log_max_product, best, 1e-9) {
            return Err(ctx(&format!(
                "log_max_product {} != best induced tree {best} (of {} trees)",
                mpe.log_max_product,
                trees.len()
            )));
        }
    }
    Ok(Checked {
        zero_likelihood: false,
        trees_checked,
    })
}

fn config() -> ProptestConfig {
    eprintln!("proptest rng: ChaCha, seed {PROPTEST_SEED:#x}");
    ProptestConfig {
        cases: 256,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(PROPTEST_SEED),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn matches_brute_force_general(case_seed in any::<u64>()) {
        if let Err(msg) = check_case(case_seed, false) {
            prop_assert!(false, "{}", msg);
        }
    }

    #[test]
    fn matches_brute_force_selective(case_seed in any::<u64>()) {
        if let Err(msg) = check_case(case_seed, true) {
            prop_assert!(false, "{}", msg);
        }
    }
}

/// The random cases really exercise the hard paths: some zero likelihoods, most
/// induced-tree enumerations within the limit.
#[test]
fn coverage_of_fixed_seed_range() {
    let mut zero = 0;
    let mut trees = 0;
    let n = 300u64;
    for seed in 0..n {
        let c = check_case(seed, seed % 2 == 0).unwrap_or_else(|m| panic!("{m}"));
        zero += c.zero_likelihood as u32;
        trees += c.trees_checked as u32;
    }
    eprintln!("zero-likelihood cases: {zero}/{n}, induced trees enumerated: {trees}/{n}");
    assert!(zero > 0, "no zero-likelihood case in {n} seeds");
    let nonzero = n as u32 - zero;
    assert!(
        trees >= nonzero * 9 / 10,
        "only {trees}/{nonzero} tree enumerations fit the limit"
    );
}

#[test]
fn tiny_evidence_does_not_underflow() {
    // 6 variables, evidence 1e-300 everywhere: ln L = 6·ln(1e-300) ≈ −4144.6.
    let params = RandomSpnParams {
        max_vars: 6,
        ..RandomSpnParams::default()
    };
    let mut seed = 0;
    let spn = loop {
        let s = random_spn(seed, &params);
        if s.num_vars() == 6 {
            break s;
        }
        seed += 1;
    };
    let rows = spn
        .classes
        .iter()
        .map(|&k| vec![1e-300; k as usize])
        .collect();
    let mut ev = Evaluator::new(&spn).unwrap();
    let ll = ev
        .log_likelihood(&[None; 6], &Evidence::from_rows(rows))
        .unwrap();
    let expected = 6.0 * 1e-300f64.ln();
    assert!(
        (ll - expected).abs() < 1e-9 * expected.abs(),
        "{ll} vs {expected}"
    );
}

/// Batched queries (`*_batch`, [`BATCH`] lanes) agree lane by lane with the
/// one-query calls: max-product bit for bit, likelihoods to 1e-13 relative and
/// marginals to 1e-13 absolute (the lanes' vector exp is within 1 ulp of `f64::exp`),
/// and the same errors (an invalid or zero-likelihood lane does not disturb the
/// others). Seeds 0..300; each failure names its seed.
#[test]
fn batched_queries_agree_with_single_queries() {
    const K: usize = BATCH;
    let params = small_spn_params(false);
    let near = |a: &Result<f64, InferenceError>, b: &Result<f64, InferenceError>| match (a, b) {
        (Ok(x), Ok(y)) => close_rel(*x, *y, 1e-13),
        _ => a == b,
    };
    for seed in 0..300u64 {
        let spn = random_spn(seed, &params);
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xBA7C_4ED0);
        let lanes: Vec<(Vec<Option<u32>>, Evidence)> = (0..K)
            .map(|lane| {
                let mut alpha = random_evidence(&mut rng, &spn.classes);
                if lane == 2 && seed % 3 == 0 {
                    alpha[0][0] = -1.0; // an invalid lane
                }
                let fixed = spn
                    .classes
                    .iter()
                    .map(|&k| rng.random_bool(0.3).then(|| rng.random_range(0..k)))
                    .collect();
                (fixed, Evidence::from_rows(alpha))
            })
            .collect();
        let fixed: [&[Option<u32>]; K] = std::array::from_fn(|l| lanes[l].0.as_slice());
        let evidence: [&Evidence; K] = std::array::from_fn(|l| &lanes[l].1);
        let mut ev = Evaluator::new(&spn).unwrap();
        let ll = ev.log_likelihood_batch(fixed, evidence);
        let mx = ev.log_max_product_batch(fixed, evidence);
        let mg = ev.marginals_batch(fixed, evidence);
        for l in 0..K {
            let ctx = format!("{K} lanes, seed {seed} lane {l}");
            let one = ev.log_likelihood(fixed[l], evidence[l]);
            assert!(near(&ll[l], &one), "{ctx}: {:?} vs {one:?}", ll[l]);
            let one = ev.log_max_product(fixed[l], evidence[l]);
            assert_eq!(
                mx[l].as_ref().map(|v| v.to_bits()),
                one.as_ref().map(|v| v.to_bits()),
                "{ctx}"
            );
            let one = ev.marginals(fixed[l], evidence[l]);
            match (&mg[l], &one) {
                (Ok(a), Ok(b)) => {
                    assert!(
                        close_rel(a.log_likelihood, b.log_likelihood, 1e-13),
                        "{ctx}"
                    );
                    for (ra, rb) in a.probs.iter().zip(&b.probs) {
                        for (pa, pb) in ra.iter().zip(rb) {
                            assert!((pa - pb).abs() <= 1e-13, "{ctx}: {pa} vs {pb}");
                        }
                    }
                }
                (a, b) => assert_eq!(a.as_ref().err(), b.as_ref().err(), "{ctx}"),
            }
        }
    }
}
