//! The component-wise evaluator (`ComponentInstance`) against the explicit instance
//! SPN and the interpreter (the reference): log-likelihood, marginals, MPE and
//! labelled log-likelihood on random models and maps and on real COLD maps; cached
//! answers after random update sequences equal a fresh evaluation bit for bit; growth
//! follows `Instance::grow`.

mod harness;

use std::path::PathBuf;

use graphspn_compiler::decompose::synthetic::random_connected_map;
use graphspn_compiler::instance::{
    ComponentInstance, Instance, InstanceModel, InstanceParams, InstanceQueryError, Mixing,
};
use graphspn_compiler::interpreter::Evidence;
use graphspn_compiler::learn::Model;
use graphspn_compiler::map::{ClassId, TopoMap, cold};
use graphspn_compiler::spn::Node;
use harness::instance::{classes, random_model, random_rows, tiny_map};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
}

fn assert_close(a: f64, b: f64, what: &str) {
    assert!(close(a, b), "{what}: {a} vs {b} (diff {})", (a - b).abs());
}

/// Evidence rows with the awkward cases mixed in: one-hot, 1e-300, exact zeros.
fn hard_rows(n: usize, c: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    let mut rows = random_rows(n, c, rng);
    for row in rows.iter_mut() {
        match rng.random_range(0..6) {
            0 => {
                let k = rng.random_range(0..c);
                row.iter_mut()
                    .enumerate()
                    .for_each(|(j, a)| *a = f64::from(j == k));
            }
            1 => row.iter_mut().for_each(|a| *a *= 1e-300),
            2 => row[rng.random_range(0..c)] = 0.0,
            3 => row.iter_mut().for_each(|a| *a = 1.0),
            _ => {}
        }
    }
    rows
}

fn random_labels(n: usize, c: usize, rng: &mut ChaCha8Rng) -> Vec<Option<ClassId>> {
    (0..n)
        .map(|_| {
            rng.random_bool(0.3)
                .then(|| rng.random_range(0..c) as ClassId)
        })
        .collect()
}

/// Compares every query of `fast` (evidence already set to `rows`) with the explicit
/// reference `slow` on the same decompositions.
fn compare(
    fast: &mut ComponentInstance,
    slow: &mut InstanceModel,
    rows: &[Vec<f64>],
    rng: &mut ChaCha8Rng,
) {
    let c = fast.num_classes();
    let ev = Evidence::from_rows(rows.to_vec());
    let want = slow.marginals(&ev).unwrap();
    let got = fast.marginals().unwrap();
    assert_close(got.log_likelihood, want.log_likelihood, "log-likelihood");
    assert_close(
        fast.log_likelihood().unwrap(),
        want.log_likelihood,
        "cached ll",
    );
    for (p, (r, s)) in got.probs.iter().zip(&want.probs).enumerate() {
        for (k, (a, b)) in r.iter().zip(s).enumerate() {
            assert_close(*a, *b, &format!("marginal of place {p}, class {k}"));
        }
    }
    let p = rng.random_range(0..fast.num_places());
    for (a, b) in fast.marginal(p).unwrap().iter().zip(&want.probs[p]) {
        assert_close(*a, *b, "one marginal");
    }
    let labels = random_labels(fast.num_places(), c, rng);
    match (
        fast.log_likelihood_labelled(&labels),
        slow.log_likelihood_labelled(&labels, &ev),
    ) {
        (Ok(a), Ok(b)) => assert_close(a, b, "labelled log-likelihood"),
        (Err(_), Err(_)) => {}
        (a, b) => panic!("labelled: {a:?} vs {b:?}"),
    }
    for labels in [vec![], labels] {
        // Labels may contradict zero evidence: then both must refuse.
        let (got, want) = match (fast.mpe(&labels), slow.mpe(&labels, &ev)) {
            (Ok(a), Ok(b)) => (a, b),
            (Err(_), Err(_)) if !labels.is_empty() => continue,
            (a, b) => panic!("MPE: {a:?} vs {b:?}"),
        };
        assert_close(got.log_max_product, want.log_max_product, "MPE value");
        // Ties may pick another labelling of the same value: check ours has it.
        let ours: Vec<Option<ClassId>> =
            got.assignment.iter().map(|&k| Some(k as ClassId)).collect();
        let again = slow.mpe(&ours, &ev).unwrap();
        assert_close(again.log_max_product, got.log_max_product, "MPE labelling");
        assert_close(
            got.log_probability,
            again.log_probability,
            "MPE probability",
        );
        for (p, l) in labels.iter().enumerate() {
            if let Some(l) = l {
                assert_eq!(got.assignment[p], u32::from(*l), "clamped place {p}");
            }
        }
    }
}

fn both(
    model: &Model,
    map: &TopoMap,
    params: &InstanceParams,
) -> (ComponentInstance, InstanceModel) {
    let fast = ComponentInstance::for_map(model, map, params).unwrap();
    let inst = Instance::for_map(model, map, params).unwrap();
    assert_eq!(fast.decompositions(), &inst.decompositions[..]);
    assert_eq!(fast.num_components(), inst.num_copies());
    (fast, InstanceModel::new(inst).unwrap())
}

#[test]
fn matches_the_explicit_instance_on_random_models() {
    for seed in 0..8u64 {
        let c = 2 + seed as usize % 3;
        let model = random_model(c, seed % 2 == 0, seed);
        let map = tiny_map(10 + 3 * seed as usize, c, seed);
        let params = InstanceParams {
            decompositions: 1 + seed as usize % 4,
            candidates: 12,
            seed,
            ..InstanceParams::default()
        };
        let (mut fast, mut slow) = both(&model, &map, &params);
        let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
        // No evidence first (rows of ones, as `infer` without --evidence).
        let ones = vec![vec![1.0; c]; map.num_places()];
        compare(&mut fast, &mut slow, &ones, &mut rng);
        for _ in 0..3 {
            let rows = hard_rows(map.num_places(), c, &mut rng);
            fast.set_all_evidence(&rows).unwrap();
            compare(&mut fast, &mut slow, &rows, &mut rng);
        }
    }
}

fn cold_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../data/cold-topomaps")
}

fn demo_model() -> Model {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../generated/demo/model.json");
    Model::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn matches_the_explicit_instance_on_cold_maps() {
    let model = demo_model();
    let mut maps: Vec<TopoMap> = ["Freiburg", "Saarbrucken", "Stockholm"]
        .iter()
        .map(|b| {
            let dirs = cold::sequence_dirs(cold_dir().join(b)).unwrap();
            cold::load_sequence(&dirs[0]).unwrap()
        })
        .collect();
    // And the largest of the 90 maps.
    let all = cold::load_all(cold_dir()).unwrap();
    assert_eq!(all.len(), 90, "the 90 COLD maps ship in data/cold-topomaps");
    let largest = all.into_iter().max_by_key(TopoMap::num_places).unwrap();
    assert!(
        largest.num_places() >= 200,
        "{} places",
        largest.num_places()
    );
    maps.push(largest);
    let c = model.classes.len();
    for (i, map) in maps.iter().enumerate() {
        let params = InstanceParams {
            decompositions: 3,
            candidates: 9,
            seed: i as u64,
            ..InstanceParams::default()
        };
        let (mut fast, mut slow) = both(&model, map, &params);
        let mut rng = ChaCha8Rng::seed_from_u64(i as u64);
        let rows = hard_rows(map.num_places(), c, &mut rng);
        fast.set_all_evidence(&rows).unwrap();
        compare(&mut fast, &mut slow, &rows, &mut rng);
    }
}

/// A fresh evaluator on the same decompositions and evidence.
fn fresh(
    model: &Model,
    map: &TopoMap,
    fast: &ComponentInstance,
    rows: &[Vec<f64>],
) -> ComponentInstance {
    let mut f = ComponentInstance::build(model, map, fast.decompositions().to_vec()).unwrap();
    f.set_all_evidence(rows).unwrap();
    f
}

#[test]
fn cached_answers_after_updates_equal_a_fresh_evaluation() {
    for seed in 0..3u64 {
        let c = 3;
        let model = random_model(c, seed == 1, seed);
        let map = tiny_map(30, c, seed);
        let params = InstanceParams {
            decompositions: 4,
            candidates: 12,
            seed,
            ..InstanceParams::default()
        };
        let (mut fast, mut slow) = both(&model, &map, &params);
        let n = map.num_places();
        let mut rows = vec![vec![1.0; c]; n];
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for step in 0..1500 {
            let p = rng.random_range(0..n);
            if rng.random_bool(0.2) {
                fast.clear_evidence(p).unwrap();
                rows[p] = vec![1.0; c];
            } else {
                let row = hard_rows(1, c, &mut rng).remove(0);
                fast.set_evidence(p, &row).unwrap();
                rows[p] = row;
            }
            // Now and then all evidence at once, then updates before any query.
            if step % 300 == 150 {
                fast.set_all_evidence(&rows).unwrap();
                continue;
            }
            // Queries between updates read (and refresh) the cache.
            match step % 4 {
                0 => {
                    fast.marginal(rng.random_range(0..n)).unwrap();
                }
                1 => {
                    fast.log_likelihood().unwrap();
                }
                2 if step % 40 == 2 => {
                    fast.marginals().unwrap();
                }
                _ => {}
            }
            if step % 500 == 499 {
                let mut f = fresh(&model, &map, &fast, &rows);
                let (a, b) = (fast.marginals().unwrap(), f.marginals().unwrap());
                assert_eq!(a, b, "seed {seed} step {step}: cache vs fresh");
                assert_eq!(fast.mpe(&[]).unwrap(), f.mpe(&[]).unwrap());
                compare(&mut fast, &mut slow, &rows, &mut rng);
            }
        }
    }
}

#[test]
fn bad_updates_are_rejected_and_change_nothing() {
    let model = random_model(3, true, 7);
    let map = tiny_map(12, 3, 7);
    let mut fast = ComponentInstance::for_map(&model, &map, &InstanceParams::default()).unwrap();
    fast.set_evidence(3, &[0.2, 0.3, 0.5]).unwrap();
    let before = fast.marginals().unwrap();
    let err = fast.set_evidence(12, &[1.0, 1.0, 1.0]).unwrap_err();
    assert!(
        matches!(
            err,
            InstanceQueryError::PlaceOutOfRange {
                place: 12,
                count: 12
            }
        ),
        "{err}"
    );
    for row in [
        vec![f64::NAN, 1.0, 1.0],
        vec![-1.0, 1.0, 1.0],
        vec![0.0; 3],
        vec![1.0; 2],
    ] {
        let err = fast.set_evidence(3, &row).unwrap_err();
        assert!(
            err.to_string().contains("index 3") || err.to_string().contains('3'),
            "{err}"
        );
    }
    assert!(fast.clear_evidence(99).is_err());
    assert_eq!(fast.marginals().unwrap(), before);
    assert!(fast.mpe(&[Some(0)]).is_err(), "wrong label count");
    assert!(
        fast.log_likelihood_labelled(&[Some(9); 12]).is_err(),
        "class out of range"
    );
}

#[test]
fn zero_likelihood_is_an_error_not_a_nan() {
    // One-hot evidence on class 0 everywhere under a model that excludes it: make
    // every template's leaf for class 0 unreachable by zeroing its sum weights.
    let mut model = random_model(2, true, 3);
    for spn in &mut model.spns {
        let leaves: Vec<bool> = spn
            .nodes
            .iter()
            .map(|n| matches!(n, Node::Leaf { class: 0, .. }))
            .collect();
        let root = spn.root as usize;
        // Full tables: the root sum's children are products (or leaves for 1 node);
        // drop the weight of every child touching class 0, renormalise.
        let kids: Vec<bool> = match &spn.nodes[root] {
            Node::Sum { children, .. } => children
                .iter()
                .map(|&ch| match &spn.nodes[ch as usize] {
                    Node::Product { children } => children.iter().any(|&l| leaves[l as usize]),
                    _ => leaves[ch as usize],
                })
                .collect(),
            _ => unreachable!(),
        };
        if let Node::Sum { weights, .. } = &mut spn.nodes[root] {
            for (w, bad) in weights.iter_mut().zip(kids) {
                if bad {
                    *w = 0.0;
                }
            }
            let z: f64 = weights.iter().sum();
            weights.iter_mut().for_each(|w| *w /= z);
        }
    }
    let map = tiny_map(8, 2, 3);
    let mut fast = ComponentInstance::for_map(&model, &map, &InstanceParams::default()).unwrap();
    fast.set_evidence(0, &[1.0, 0.0]).unwrap();
    for e in [
        fast.log_likelihood().unwrap_err(),
        fast.marginals().unwrap_err(),
        fast.mpe(&[]).unwrap_err(),
    ] {
        assert!(
            e.to_string().contains("probability zero") || e.to_string().contains("zero"),
            "{e}"
        );
    }
    fast.clear_evidence(0).unwrap();
    let m = fast.marginals().unwrap();
    assert!(m.probs.iter().all(|r| r[0] == 0.0 && r[1] == 1.0));
}

#[test]
fn invalid_template_networks_are_named() {
    let mut model = random_model(2, true, 1);
    if let Node::Sum { weights, .. } = &mut model.spns[1].nodes.last_mut().unwrap() {
        weights[0] += 0.5;
    }
    let map = tiny_map(8, 2, 1);
    let err = ComponentInstance::for_map(&model, &map, &InstanceParams::default()).unwrap_err();
    let name = &model.templates[1].name;
    assert!(
        matches!(&err, InstanceQueryError::InvalidTemplateSpn { template, .. } if template == name),
        "{err}"
    );
}

#[test]
fn growth_follows_the_explicit_instance_and_keeps_caches() {
    for seed in 0..4u64 {
        let model = random_model(3, seed % 2 == 0, seed);
        let mut full = random_connected_map(40, 5, 10, seed);
        full.classes = classes(3);
        let prefix = |k: usize| full.induced_submap(&(0..k).collect::<Vec<_>>());
        let params = InstanceParams {
            seed,
            ..InstanceParams::default()
        };
        let first = prefix(24);
        let mut fast = ComponentInstance::for_map(&model, &first, &params).unwrap();
        let mut inst = Instance::for_map(&model, &first, &params).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut rows = random_rows(24, 3, &mut rng);
        fast.set_all_evidence(&rows).unwrap();
        fast.marginals().unwrap();
        for k in [32usize, 40] {
            let grown = prefix(k);
            let a = fast.grow(&model, &grown, seed + k as u64).unwrap();
            let b = inst.grow(&model, &grown, seed + k as u64).unwrap();
            // An update before any query after growing.
            let row = random_rows(1, 3, &mut rng).remove(0);
            fast.set_evidence(1, &row).unwrap();
            rows[1] = row;
            assert_eq!(a, b, "same reuse as the explicit instance");
            assert!(a.reused > 0, "{a:?}");
            assert_eq!(fast.decompositions(), &inst.decompositions[..]);
            rows.resize(k, vec![1.0; 3]);
            let mut slow = InstanceModel::new(inst.clone()).unwrap();
            compare(&mut fast, &mut slow, &rows, &mut rng);
            // The grown state equals a fresh evaluation of the grown map.
            let mut f = fresh(&model, &grown, &fast, &rows);
            assert_eq!(fast.marginals().unwrap(), f.marginals().unwrap());
            // Updates keep working on the new places.
            let row = random_rows(1, 3, &mut rng).remove(0);
            fast.set_evidence(k - 1, &row).unwrap();
            rows[k - 1] = row;
            let mut f = fresh(&model, &grown, &fast, &rows);
            assert_eq!(fast.marginals().unwrap(), f.marginals().unwrap());
        }
    }
}

#[test]
fn average_mixing_is_the_mean_of_the_decompositions_marginals() {
    let model = demo_model();
    let dirs = cold::sequence_dirs(cold_dir().join("Saarbrucken")).unwrap();
    let map = cold::load_sequence(&dirs[0]).unwrap();
    let params = InstanceParams {
        decompositions: 4,
        candidates: 12,
        seed: 5,
        strategy: graphspn_compiler::decompose::DecompositionStrategy::Cover,
    };
    let mut all = ComponentInstance::for_map(&model, &map, &params).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let rows = hard_rows(map.num_places(), model.classes.len(), &mut rng);
    all.set_all_evidence(&rows).unwrap();
    let posterior = all.marginals_mixed(Mixing::Posterior).unwrap();
    assert_eq!(posterior.probs, all.marginals().unwrap().probs);
    let average = all.marginals_mixed(Mixing::Average).unwrap();
    assert_eq!(average.log_likelihood, posterior.log_likelihood);
    // Each decomposition alone, then the plain mean.
    let singles: Vec<Vec<Vec<f64>>> = all
        .decompositions()
        .iter()
        .map(|d| {
            let mut one = ComponentInstance::build(&model, &map, vec![d.clone()]).unwrap();
            one.set_all_evidence(&rows).unwrap();
            one.marginals().unwrap().probs
        })
        .collect();
    let mut differs = false;
    for p in 0..map.num_places() {
        for c in 0..model.classes.len() {
            let mean = singles.iter().map(|s| s[p][c]).sum::<f64>() / singles.len() as f64;
            assert_close(average.probs[p][c], mean, &format!("place {p} class {c}"));
            differs |= (posterior.probs[p][c] - mean).abs() > 1e-3;
        }
    }
    assert!(
        differs,
        "the posterior weights should not all be equal here"
    );
}
