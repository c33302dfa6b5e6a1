//! EM training: exact M-step on full tables, monotone objective, convergence to
//! the sampling distribution, pruning (symmetry and tying: `learn_tied.rs`).

mod harness;

use graphspn_compiler::learn::structure::num_weights;
use graphspn_compiler::learn::train::{dedupe, log_likelihood, log_likelihoods, prune};
use graphspn_compiler::learn::{
    DenseParams, EmKind, Progress, TrainError, TrainingSettings, augment_with_automorphisms,
    dense_structure, train,
};
use graphspn_compiler::spn::Node;
use harness::learn::*;

fn fixed(s: f64, epochs: usize, em: EmKind) -> TrainingSettings {
    TrainingSettings {
        epochs,
        smoothing_start: s,
        smoothing_end: s,
        em,
        ..TrainingSettings::default()
    }
}

/// KL(p || q) in nats over a full table.
fn kl(p: &[f64], q: &[f64]) -> f64 {
    p.iter()
        .zip(q)
        .filter(|(a, _)| **a > 0.0)
        .map(|(a, b)| a * (a / b).ln())
        .sum()
}

#[test]
fn full_tables_learn_smoothed_frequencies() {
    // Pair (10×10) and Three (10×10×10) are single sums over all tuples: hard EM
    // must give exactly (count + s_last) / (N + C^n · s_last).
    for (n, m, max_kl) in [(2usize, 20_000usize, 0.02), (3, 30_000, 0.12)] {
        let table = mixture_table(n, 10, 3, 40 + n as u64);
        let samples = sample_table(&table, n, 10, m, 1);
        let mut spn = dense_structure(n, 10, &DenseParams::default(), 5).unwrap();
        let settings = TrainingSettings::default();
        let rep = train(&mut spn, &samples, &settings, Progress::Hidden).unwrap();
        assert_eq!(rep.log_likelihood_per_epoch.len(), 10);
        let s = settings.smoothing_end;
        let cells = 10f64.powi(n as i32);
        let mut counts = vec![0.0; table.len()];
        for x in &samples {
            counts[index_of(x, 10)] += 1.0;
        }
        let assignments = all_labellings(n, 10);
        let q: Vec<f64> = assignments.iter().map(|x| value(&spn, x)).collect();
        for (i, x) in assignments.iter().enumerate() {
            let expect = (counts[i] + s) / (m as f64 + cells * s);
            assert!(
                (q[i] - expect).abs() <= 1e-12 * expect,
                "n={n} {x:?}: {} vs {expect}",
                q[i]
            );
        }
        let d = kl(&table, &q);
        assert!(d < max_kl, "n={n}: KL(true || learned) = {d}");
        // Reported log-likelihood agrees with the independent evaluator.
        let ll: f64 = samples.iter().map(|x| value(&spn, x).ln()).sum::<f64>() / m as f64;
        let last = *rep.log_likelihood_per_epoch.last().unwrap();
        assert!((ll - last).abs() < 1e-9, "{ll} vs {last}");
    }
}

#[test]
fn hard_em_objective_is_monotone_with_fixed_smoothing() {
    for seed in 0..3 {
        let table = mixture_table(5, 4, 4, 100 + seed);
        let samples = sample_table(&table, 5, 4, 5_000, seed);
        for em in [EmKind::Hard, EmKind::Soft] {
            let mut spn = dense_structure(5, 4, &DenseParams::default(), seed).unwrap();
            let rep = train(&mut spn, &samples, &fixed(2.0, 12, em), Progress::Hidden).unwrap();
            let obj = &rep.objective_per_epoch;
            for w in obj.windows(2) {
                assert!(
                    w[1] >= w[0] - 1e-9,
                    "{em:?} seed {seed}: objective fell {obj:?}"
                );
            }
            assert!(obj[obj.len() - 1] > obj[0]);
            let ll = &rep.log_likelihood_per_epoch;
            assert!(
                ll[ll.len() - 1] > rep.initial_log_likelihood,
                "{em:?} {ll:?}"
            );
            if em == EmKind::Soft {
                // Soft EM's objective is the true likelihood (plus the prior).
                for w in ll.windows(2) {
                    assert!(w[1] >= w[0] - 1e-3, "{ll:?}");
                }
            }
        }
    }
}

#[test]
fn decaying_schedule_raises_likelihood_and_beats_independence() {
    let table = mixture_table(5, 4, 3, 9);
    let samples = sample_table(&table, 5, 4, 20_000, 2);
    let mut spn = dense_structure(5, 4, &DenseParams::default(), 1).unwrap();
    let settings = TrainingSettings::default();
    let rep = train(&mut spn, &samples, &settings, Progress::Hidden).unwrap();
    let ll = &rep.log_likelihood_per_epoch;
    assert!(
        ll[ll.len() - 1] > rep.initial_log_likelihood + 0.1,
        "{ll:?}"
    );
    assert_eq!(rep.smoothing_per_epoch[0], 30.0);
    assert_eq!(*rep.smoothing_per_epoch.last().unwrap(), 5.0);
    // The learned model is normalised and close to the truth.
    let assignments = all_labellings(5, 4);
    let q: Vec<f64> = assignments.iter().map(|x| value(&spn, x)).collect();
    let z: f64 = q.iter().sum();
    assert!((z - 1.0).abs() < 1e-12);
    let d = kl(&table, &q);
    // Independence (product of marginals) as a baseline to beat.
    let mut marg = vec![vec![0.0; 4]; 5];
    for x in &samples {
        for (i, &c) in x.iter().enumerate() {
            marg[i][c as usize] += 1.0 / samples.len() as f64;
        }
    }
    let indep: Vec<f64> = assignments
        .iter()
        .map(|x| {
            x.iter()
                .enumerate()
                .map(|(i, &c)| marg[i][c as usize])
                .product()
        })
        .collect();
    let d_indep = kl(&table, &indep);
    assert!(d < d_indep, "KL learned {d} vs independent {d_indep}");
}

#[test]
fn dedupe_counts_multiplicity_and_training_is_deterministic() {
    let samples = vec![vec![1u16, 2], vec![0, 0], vec![1, 2], vec![1, 2]];
    assert_eq!(dedupe(&samples), vec![(vec![0, 0], 1), (vec![1, 2], 3)]);
    let table = mixture_table(5, 3, 2, 1);
    let s = sample_table(&table, 5, 3, 2_000, 1);
    let run = |batch| {
        let mut spn = dense_structure(5, 3, &DenseParams::default(), 9).unwrap();
        let set = TrainingSettings {
            batch_size: batch,
            ..TrainingSettings::default()
        };
        let rep = train(&mut spn, &s, &set, Progress::Hidden).unwrap();
        (spn, rep)
    };
    let (a, ra) = run(2000);
    let (b, rb) = run(7);
    assert_eq!(a, b, "batch size changed the result");
    assert_eq!(ra.log_likelihood_per_epoch, rb.log_likelihood_per_epoch);
}

#[test]
fn pruning_keeps_a_valid_normalised_spn() {
    let table = mixture_table(5, 3, 2, 3);
    let samples = sample_table(&table, 5, 3, 5_000, 3);
    let mut spn = dense_structure(5, 3, &DenseParams::default(), 4).unwrap();
    train(
        &mut spn,
        &samples,
        &fixed(0.01, 8, EmKind::Hard),
        Progress::Hidden,
    )
    .unwrap();
    let before = num_weights(&spn);
    // What `prune` reports: the sum edges under the threshold, a sum's heaviest kept.
    let below: usize = spn
        .nodes
        .iter()
        .map(|n| match n {
            Node::Sum { weights, .. } => {
                let max = weights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                weights.iter().filter(|&&w| w < 1e-3 && w != max).count()
            }
            _ => 0,
        })
        .sum();
    let removed = prune(&mut spn, 1e-3).unwrap();
    assert!(removed > 0, "nothing pruned");
    assert_eq!(removed, below, "the count of removed edges");
    assert!(num_weights(&spn) < before);
    let z: f64 = all_labellings(5, 3).iter().map(|x| value(&spn, x)).sum();
    assert!((z - 1.0).abs() < 1e-12, "mass {z}");
    for (i, n) in spn.nodes.iter().enumerate() {
        if let Node::Sum { children, .. } | Node::Product { children } = n {
            assert!(!children.is_empty());
            assert!(children.iter().all(|&c| (c as usize) < i));
        }
    }
    // Every node is reachable: pruning dropped the orphans.
    let mut live = vec![false; spn.nodes.len()];
    live[spn.root as usize] = true;
    for i in (0..spn.nodes.len()).rev() {
        if live[i]
            && let Node::Sum { children, .. } | Node::Product { children } = &spn.nodes[i]
        {
            for &c in children {
                live[c as usize] = true;
            }
        }
    }
    assert!(live.iter().all(|l| *l));
    // log_likelihood agrees with the oracle.
    let x = &samples[0];
    assert!((log_likelihood(&spn, x).unwrap() - value(&spn, x).ln()).abs() < 1e-12);
    // An SPN with a child that does not precede its parent (here: one past the last
    // node) is refused as training refuses it, and left unchanged.
    let mut bad = spn.clone();
    let n = bad.nodes.len() as u32;
    if let Node::Sum { children, .. } = &mut bad.nodes[bad.root as usize] {
        children[0] = n;
    }
    let kept = bad.clone();
    let r = prune(&mut bad, 1e-3);
    assert!(matches!(r, Err(TrainError::BadSpn { .. })), "{r:?}");
    assert_eq!(bad, kept);
}

/// On a selective SPN (one sum over the indicators of one variable: a sample reaches
/// exactly one child) the MPE value of a sample is its likelihood, so the report's
/// per-sample MPE log-likelihood of every epoch equals its log-likelihood.
#[test]
fn the_reported_mpe_log_likelihood_is_per_sample() {
    let mut spn = indicator_sum(vec![0.5, 0.5]);
    let samples = vec![vec![0], vec![1], vec![1], vec![1]];
    let report = train(
        &mut spn,
        &samples,
        &fixed(0.01, 3, EmKind::Hard),
        Progress::Hidden,
    )
    .unwrap();
    assert_eq!(report.mpe_log_likelihood_per_epoch.len(), 3);
    for (mpe, ll) in report
        .mpe_log_likelihood_per_epoch
        .iter()
        .zip(&report.log_likelihood_per_epoch)
    {
        assert!((mpe - ll).abs() < 1e-12, "{mpe} vs {ll}");
        assert!(*ll > 2f64.ln() * -2.0, "per sample: {ll}");
    }
}

/// The batch form gives one log-likelihood per sample, each that of the single-sample
/// form and of the oracle, and refuses a bad sample by its index.
#[test]
fn log_likelihoods_are_those_of_each_sample() {
    let spn = dense_structure(3, 3, &DenseParams::default(), 5).unwrap();
    let samples = all_labellings(3, 3);
    let lls = log_likelihoods(&spn, &samples).unwrap();
    assert_eq!(lls.len(), samples.len());
    for (x, &l) in samples.iter().zip(&lls) {
        assert_eq!(l, log_likelihood(&spn, x).unwrap());
        assert!((l - value(&spn, x).ln()).abs() < 1e-12);
    }
    assert!(matches!(
        log_likelihoods(&spn, &[vec![0, 1, 2], vec![0, 1]]),
        Err(TrainError::SampleLength { index: 1, .. })
    ));
}

#[test]
fn bad_input_is_reported() {
    let mut spn = dense_structure(2, 3, &DenseParams::default(), 0).unwrap();
    let s = TrainingSettings::default();
    assert_eq!(
        train(&mut spn, &[], &s, Progress::Hidden),
        Err(TrainError::NoSamples)
    );
    assert!(matches!(
        train(&mut spn, &[vec![0, 1, 2]], &s, Progress::Hidden),
        Err(TrainError::SampleLength { index: 0, .. })
    ));
    assert!(matches!(
        train(&mut spn, &[vec![0, 1], vec![0, 3]], &s, Progress::Hidden),
        Err(TrainError::ClassOutOfRange {
            index: 1,
            var: 1,
            ..
        })
    ));
    assert!(matches!(
        augment_with_automorphisms(&[vec![0, 1], vec![1]], &pair_group()),
        Err(TrainError::SampleLength { index: 1, .. })
    ));
    // A permutation shorter than the sample (its entries in range), and one of the
    // sample's length naming a variable past its end: each refused on its own.
    for bad in [vec![1, 0], vec![0, 3, 1]] {
        assert!(
            matches!(
                augment_with_automorphisms(&[vec![0, 1, 2]], std::slice::from_ref(&bad)),
                Err(TrainError::SampleLength {
                    index: 0,
                    len: 3,
                    ..
                })
            ),
            "{bad:?}"
        );
    }
    let zero = TrainingSettings {
        smoothing_end: 0.0,
        ..s
    };
    assert!(matches!(
        train(&mut spn, &[vec![0, 1]], &zero, Progress::Hidden),
        Err(TrainError::BadSettings(_))
    ));
}

#[test]
fn progress_is_plain_lines_off_terminal() {
    use graphspn_compiler::progress::Bar;
    // Test output is captured (not a terminal): `Auto` reports as plain lines (a log
    // file or CI sees progress), `Hidden` reports nothing.
    assert!(matches!(Progress::Auto.bar(10, "training"), Bar::Lines(_)));
    assert!(matches!(Progress::Hidden.bar(10, "training"), Bar::Hidden));
}

/// Soft EM adds a node's log-derivatives from its parents in log space: the sum must
/// stay finite when they differ by more than `ln f64::MAX` (709 nats). One root weight
/// of `1e-320` (−737 nats, finite and ≥ 0, so accepted) makes a region's sums
/// reachable through a product worth −737 nats and through products worth about −5;
/// such a weight must train like a weight of exactly 0 (its share is `e^−737`).
/// `ln(e^a + e^b)` computed as `a + ln(1 + e^(b − a))` from the smaller term overflows
/// to `+∞` there: the M-step gives those sums NaN weights (which the next epoch then
/// resets to its smoothing alone).
#[test]
fn soft_em_survives_parents_more_than_709_nats_apart() {
    let table = mixture_table(5, 3, 2, 21);
    let samples = sample_table(&table, 5, 3, 300, 21);
    let start = dense_structure(5, 3, &DenseParams::default(), 2).unwrap();
    let with_first_root_weight = |w0: f64| {
        let mut spn = start.clone();
        let root = spn.root as usize;
        let Node::Sum { weights, .. } = &mut spn.nodes[root] else {
            panic!("the root is a sum")
        };
        weights[0] = w0;
        let rep = train(
            &mut spn,
            &samples,
            &fixed(1.0, 2, EmKind::Soft),
            Progress::Hidden,
        )
        .unwrap();
        (spn, rep)
    };
    let (tiny, rep) = with_first_root_weight(1e-320);
    let (zero, rep0) = with_first_root_weight(0.0);
    let (mut worst, mut sums) = (0.0f64, 0);
    for (a, b) in tiny.nodes.iter().zip(&zero.nodes) {
        if let (Node::Sum { weights: wa, .. }, Node::Sum { weights: wb, .. }) = (a, b) {
            assert!(wa.iter().all(|w| w.is_finite() && *w > 0.0), "{wa:?}");
            for (x, y) in wa.iter().zip(wb) {
                worst = worst.max((x - y).abs());
            }
            sums += 1;
        }
    }
    assert!(sums > 1);
    assert!(worst < 1e-12, "1e-320 vs 0: weights differ by {worst}");
    for (l, l0) in rep
        .log_likelihood_per_epoch
        .iter()
        .zip(&rep0.log_likelihood_per_epoch)
    {
        assert!((l - l0).abs() < 1e-12, "{l} vs {l0}");
    }
}

/// A sample of probability zero is reported by its own tuple and first index, whatever
/// the chunking of the E-step: here the third distinct tuple (in sorted order) is
/// impossible (a zero weight on class 2 of variable 1); it is the first of the third
/// chunk with a batch size of 1, the first of the second with 2 and the third of the
/// only chunk with a large one.
#[test]
fn a_zero_probability_sample_is_reported_by_its_own_index() {
    let mut spn = graphspn_compiler::learn::uniform_spn(2, 3).unwrap();
    let Node::Sum { weights, .. } = &mut spn.nodes[7] else {
        panic!("node 7 is variable 1's sum")
    };
    weights[2] = 0.0;
    // Distinct tuples, sorted: [0, 0], [0, 1], [1, 2], [2, 1]: with batches of 2 the
    // impossible one opens the second batch.
    let samples = vec![
        vec![0u16, 0],
        vec![2, 1],
        vec![0, 1],
        vec![1, 2],
        vec![1, 2],
    ];
    for batch_size in [1, 2, 1000] {
        let settings = TrainingSettings {
            batch_size,
            ..TrainingSettings::default()
        };
        assert_eq!(
            train(&mut spn.clone(), &samples, &settings, Progress::Hidden),
            Err(TrainError::ZeroProbability {
                index: 3,
                sample: vec![1, 2]
            }),
            "batch size {batch_size}"
        );
    }
}

/// The reported objective is the documented one, with the smoothing of the epoch that
/// produced the weights: `(fit + s_e·Σ log w) / N` per sample, `fit` the MPE-tree
/// (hard) or SPN (soft) log-likelihood. A one-epoch run gives the weights after the
/// first epoch (smoothing 30 in both runs), so a two-epoch run (smoothing 30, then 5)
/// must report the same first objective; the penalty is recomputed from the weights.
#[test]
fn objective_uses_the_smoothing_of_its_epoch() {
    let table = mixture_table(4, 3, 2, 31);
    let samples = sample_table(&table, 4, 3, 500, 31);
    let n = samples.len() as f64;
    for em in [EmKind::Hard, EmKind::Soft] {
        let settings = |epochs| TrainingSettings {
            epochs,
            smoothing_start: 30.0,
            smoothing_end: 5.0,
            em,
            ..TrainingSettings::default()
        };
        let mut one = dense_structure(4, 3, &DenseParams::default(), 6).unwrap();
        let r1 = train(&mut one, &samples, &settings(1), Progress::Hidden).unwrap();
        let penalty: f64 = one
            .nodes
            .iter()
            .filter_map(|n| match n {
                Node::Sum { weights, .. } => Some(weights.iter().map(|w| w.ln()).sum::<f64>()),
                _ => None,
            })
            .sum();
        let fit = match em {
            EmKind::Hard => r1.mpe_log_likelihood_per_epoch[0],
            EmKind::Soft => r1.log_likelihood_per_epoch[0],
        };
        let want = fit + 30.0 * penalty / n;
        let got = r1.objective_per_epoch[0];
        assert!(
            (got - want).abs() < 1e-9 * want.abs(),
            "{em:?}: {got} vs {want}"
        );
        let mut two = dense_structure(4, 3, &DenseParams::default(), 6).unwrap();
        let r2 = train(&mut two, &samples, &settings(2), Progress::Hidden).unwrap();
        assert_eq!(r2.smoothing_per_epoch, vec![30.0, 5.0]);
        assert_eq!(
            r2.log_likelihood_per_epoch[0],
            r1.log_likelihood_per_epoch[0]
        );
        assert_eq!(r2.objective_per_epoch[0], got, "{em:?}");
    }
}

/// `prune_threshold > 0` prunes after training (the same as calling [`prune`] on the
/// trained SPN), and `0` leaves the trained SPN as it is.
#[test]
fn training_prunes_only_with_a_positive_threshold() {
    let table = mixture_table(5, 3, 2, 3);
    let samples = sample_table(&table, 5, 3, 2_000, 3);
    let start = dense_structure(5, 3, &DenseParams::default(), 4).unwrap();
    let mut plain = start.clone();
    train(
        &mut plain,
        &samples,
        &fixed(0.01, 4, EmKind::Hard),
        Progress::Hidden,
    )
    .unwrap();
    let mut by_hand = plain.clone();
    assert!(prune(&mut by_hand, 1e-3).unwrap() > 0, "nothing to prune");
    let mut pruned = start.clone();
    let settings = TrainingSettings {
        prune_threshold: 1e-3,
        ..fixed(0.01, 4, EmKind::Hard)
    };
    train(&mut pruned, &samples, &settings, Progress::Hidden).unwrap();
    assert_eq!(pruned, by_hand);
    assert!(num_weights(&pruned) < num_weights(&plain));
    // Threshold 0: not even renormalised.
    let mut again = start.clone();
    let zero = TrainingSettings {
        prune_threshold: 0.0,
        ..fixed(0.01, 4, EmKind::Hard)
    };
    train(&mut again, &samples, &zero, Progress::Hidden).unwrap();
    assert_eq!(again, plain);
}

/// Sum weights must be finite and ≥ 0: a negative, NaN or infinite weight is refused
/// naming its node, before any training.
#[test]
fn bad_weights_are_refused() {
    let start = uniform_spn_2x3();
    for bad in [-0.5, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut spn = start.clone();
        let Node::Sum { weights, .. } = &mut spn.nodes[3] else {
            panic!("node 3 is variable 0's sum")
        };
        weights[1] = bad;
        let before = spn.clone();
        let r = train(
            &mut spn,
            &[vec![0, 0], vec![1, 2]],
            &TrainingSettings::default(),
            Progress::Hidden,
        );
        assert!(
            matches!(r, Err(TrainError::BadSpn { node: 3, .. })),
            "weight {bad}: {r:?}"
        );
        assert_eq!(format!("{spn:?}"), format!("{before:?}"), "weight {bad}");
    }
}

fn uniform_spn_2x3() -> graphspn_compiler::spn::Spn {
    graphspn_compiler::learn::uniform_spn(2, 3).unwrap()
}

/// One epoch of soft EM is the documented M-step on the exact expected counts: `w_e ∝
/// Σ_n w_e · V_child(x_n) · ∂V/∂V_sum(x_n) / V(x_n) + s`, with the counts from an
/// independent forward/backward pass in linear space — through product nodes too (the
/// dense structure has sums under products).
#[test]
fn soft_em_step_is_the_m_step_on_expected_counts() {
    let (n, c, s) = (5usize, 3u16, 0.5);
    let table = mixture_table(n, c, 2, 77);
    let samples = sample_table(&table, n, c, 400, 77);
    let start = dense_structure(n, u32::from(c), &DenseParams::default(), 8).unwrap();
    let under_product = start.nodes.iter().any(|nd| match nd {
        Node::Product { children } => children
            .iter()
            .any(|&k| matches!(start.nodes[k as usize], Node::Sum { .. })),
        _ => false,
    });
    assert!(under_product, "the test needs a sum under a product");
    // Expected counts of every sum edge, by node index and child position.
    let nodes = &start.nodes;
    let mut counts: Vec<Vec<f64>> = nodes
        .iter()
        .map(|nd| match nd {
            Node::Sum { weights, .. } => vec![0.0; weights.len()],
            _ => vec![],
        })
        .collect();
    for x in &samples {
        let v = node_values(&start, x);
        let root = start.root as usize;
        let mut d = vec![0.0f64; nodes.len()];
        d[root] = 1.0;
        for i in (0..nodes.len()).rev() {
            match &nodes[i] {
                Node::Sum { children, weights } => {
                    for (j, (&k, w)) in children.iter().zip(weights).enumerate() {
                        d[k as usize] += w * d[i];
                        counts[i][j] += w * v[k as usize] * d[i] / v[root];
                    }
                }
                Node::Product { children } => {
                    for &k in children {
                        let others: f64 = children
                            .iter()
                            .filter(|&&o| o != k)
                            .map(|&o| v[o as usize])
                            .product();
                        d[k as usize] += d[i] * others;
                    }
                }
                Node::Leaf { .. } => {}
            }
        }
    }
    let mut spn = start.clone();
    let settings = TrainingSettings {
        prune_threshold: 0.0,
        ..fixed(s, 1, EmKind::Soft)
    };
    train(&mut spn, &samples, &settings, Progress::Hidden).unwrap();
    for (i, nd) in spn.nodes.iter().enumerate() {
        if let Node::Sum { weights, .. } = nd {
            let z: f64 = counts[i].iter().map(|k| k + s).sum();
            for (j, &w) in weights.iter().enumerate() {
                let want = (counts[i][j] + s) / z;
                assert!(
                    (w - want).abs() <= 1e-9 * want,
                    "sum {i} edge {j}: {w} vs {want}"
                );
            }
        }
    }
}

/// A sample whose path through one child of the root has probability `1e-640`
/// (two weights of `1e-320`, ln ≈ −1474, far below `f64`'s range) next to a child of
/// probability 1/4: the log-sum-exp at the root is shifted by its largest term, so
/// the log-likelihood is ln(½·1e-640 + ½·¼) = ln(1/8), not `-inf` or an underflowed
/// sum.
#[test]
fn a_root_over_children_1400_nats_apart_keeps_its_log_likelihood() {
    use graphspn_compiler::spn::Spn;
    let leaf = |var, class| Node::Leaf { var, class };
    let sum = |children: Vec<u32>, weights: Vec<f64>| Node::Sum { children, weights };
    let nodes = vec![
        leaf(0, 0),
        leaf(0, 1),
        leaf(1, 0),
        leaf(1, 1),
        sum(vec![0, 1], vec![1e-320, 1.0]),
        sum(vec![2, 3], vec![1e-320, 1.0]),
        Node::Product {
            children: vec![4, 5],
        },
        sum(vec![0, 1], vec![0.5, 0.5]),
        sum(vec![2, 3], vec![0.5, 0.5]),
        Node::Product {
            children: vec![7, 8],
        },
        sum(vec![6, 9], vec![0.5, 0.5]),
    ];
    let spn = Spn {
        classes: vec![2, 2],
        nodes,
        root: 10,
    };
    let ll = log_likelihoods(&spn, &[vec![0, 0], vec![1, 1]]).unwrap();
    assert!((ll[0] - (0.125f64).ln()).abs() < 1e-12, "{}", ll[0]);
    assert!((ll[1] - (0.5f64 + 0.125).ln()).abs() < 1e-12, "{}", ll[1]);
}

/// Hard EM breaks ties between equally good children of a sum towards the first:
/// with two identical leaves for class 0 under equal weights, every class-0 sample's
/// count goes to the first, so after one epoch it holds `N + s` against `s`.
#[test]
fn hard_em_gives_a_tie_to_the_first_child() {
    use graphspn_compiler::spn::Spn;
    let mut spn = Spn {
        classes: vec![2],
        nodes: vec![
            Node::Leaf { var: 0, class: 0 },
            Node::Leaf { var: 0, class: 0 },
            Node::Leaf { var: 0, class: 1 },
            Node::Sum {
                children: vec![0, 1, 2],
                weights: vec![1.0 / 3.0; 3],
            },
        ],
        root: 3,
    };
    spn.validate().unwrap();
    let samples = vec![vec![0]; 10];
    train(
        &mut spn,
        &samples,
        &fixed(1.0, 1, EmKind::Hard),
        Progress::Hidden,
    )
    .unwrap();
    let Node::Sum { weights, .. } = &spn.nodes[3] else {
        panic!("the root is a sum")
    };
    // Counts 10, 0, 0 plus smoothing 1 each: 11/13, 1/13, 1/13.
    let expected = [11.0 / 13.0, 1.0 / 13.0, 1.0 / 13.0];
    for (w, e) in weights.iter().zip(expected) {
        assert!((w - e).abs() < 1e-12, "{weights:?}");
    }
}
