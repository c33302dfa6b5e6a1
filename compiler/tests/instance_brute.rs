//! The instance GraphSPN against brute-force enumeration on tiny maps: marginals,
//! log-likelihood of partial labellings and MPE equal what the definition
//! P(y) = mean_d Π_components T(y_component) gives over all labellings.

mod harness;

use graphspn_compiler::decompose::Decomposition;
use graphspn_compiler::instance::{Instance, InstanceModel, InstanceParams};
use graphspn_compiler::interpreter::Evidence;
use graphspn_compiler::learn::Model;
use graphspn_compiler::map::ClassId;
use harness::instance::{all_labellings, random_model, random_rows, tiny_map, value};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The value of decomposition `d`'s product for labelling `y` (no evidence).
fn term(model: &Model, d: &Decomposition, y: &[ClassId]) -> f64 {
    d.components
        .iter()
        .map(|comp| {
            let x: Vec<ClassId> = comp.places.iter().map(|&p| y[p]).collect();
            value(&model.spns[comp.template], &x)
        })
        .product()
}

fn evidence_weight(rows: &[Vec<f64>], y: &[ClassId]) -> f64 {
    y.iter()
        .enumerate()
        .map(|(p, &c)| rows[p][c as usize])
        .product()
}

struct Case {
    model: Model,
    im: InstanceModel,
    n: usize,
    c: usize,
}

fn case(seed: u64, selective: bool) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = rng.random_range(2..=7usize);
    let c = rng.random_range(2..=3usize);
    let map = tiny_map(n, c, seed);
    let model = random_model(c, selective, seed ^ 0xABCD);
    let params = InstanceParams {
        decompositions: 3,
        candidates: 6,
        seed,
        ..InstanceParams::default()
    };
    let inst = Instance::for_map(&model, &map, &params).unwrap();
    assert_eq!(inst.decompositions.len(), 3);
    let im = InstanceModel::new(inst).unwrap();
    Case { model, im, n, c }
}

#[test]
fn marginals_and_likelihood_match_enumeration() {
    for seed in 0..12u64 {
        let Case {
            model,
            mut im,
            n,
            c,
        } = case(seed, seed % 2 == 0);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 100);
        let rows = random_rows(n, c, &mut rng);
        let ev = Evidence::from_rows(rows.clone());
        let decs = im.instance.decompositions.clone();
        let ys = all_labellings(n, c as u16);
        let joint: Vec<f64> = ys
            .iter()
            .map(|y| {
                decs.iter().map(|d| term(&model, d, y)).sum::<f64>() / decs.len() as f64
                    * evidence_weight(&rows, y)
            })
            .collect();
        let total: f64 = joint.iter().sum();
        // The prior sums to one over all labellings.
        let prior: f64 = ys
            .iter()
            .map(|y| decs.iter().map(|d| term(&model, d, y)).sum::<f64>() / decs.len() as f64)
            .sum();
        assert!(
            (prior - 1.0).abs() < 1e-9,
            "seed {seed}: prior sums to {prior}"
        );

        let m = im.marginals(&ev).unwrap();
        assert!(
            (m.log_likelihood - total.ln()).abs() < 1e-9,
            "seed {seed}: ln P(e) {} vs brute force {}",
            m.log_likelihood,
            total.ln()
        );
        for p in 0..n {
            for k in 0..c {
                let brute: f64 = ys
                    .iter()
                    .zip(&joint)
                    .filter(|(y, _)| y[p] as usize == k)
                    .map(|(_, j)| j)
                    .sum::<f64>()
                    / total;
                assert!(
                    (m.probs[p][k] - brute).abs() < 1e-9,
                    "seed {seed}: P(Y_{p} = {k}) = {} vs brute force {brute}",
                    m.probs[p][k]
                );
            }
        }

        // Partial labellings: unlabelled places summed out.
        for _ in 0..4 {
            let labels: Vec<Option<ClassId>> = (0..n)
                .map(|_| rng.random_bool(0.5).then(|| rng.random_range(0..c as u16)))
                .collect();
            let brute: f64 = ys
                .iter()
                .zip(&joint)
                .filter(|(y, _)| {
                    labels
                        .iter()
                        .zip(y.iter())
                        .all(|(l, &v)| l.is_none_or(|l| l == v))
                })
                .map(|(_, j)| j)
                .sum();
            let ll = im.log_likelihood_labelled(&labels, &ev).unwrap();
            assert!(
                (ll - brute.ln()).abs() < 1e-9,
                "seed {seed}: labels {labels:?}: {ll} vs brute force {}",
                brute.ln()
            );
        }
    }
}

#[test]
fn mpe_matches_enumeration_for_selective_templates() {
    for seed in 20..32u64 {
        let Case {
            model,
            mut im,
            n,
            c,
        } = case(seed, true);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 100);
        let rows = random_rows(n, c, &mut rng);
        let ev = Evidence::from_rows(rows.clone());
        let decs = im.instance.decompositions.clone();
        let dn = decs.len() as f64;
        let ys = all_labellings(n, c as u16);
        // Max over (decomposition, labelling) of that decomposition's weighted term.
        let mut best = 0.0f64;
        for y in &ys {
            for d in &decs {
                best = best.max(term(&model, d, y) / dn * evidence_weight(&rows, y));
            }
        }
        let mpe = im.mpe(&[], &ev).unwrap();
        assert!(
            (mpe.log_max_product - best.ln()).abs() < 1e-9,
            "seed {seed}: max-product {} vs brute force {}",
            mpe.log_max_product,
            best.ln()
        );
        let y: Vec<ClassId> = mpe.assignment.iter().map(|&k| k as ClassId).collect();
        let joint_y =
            decs.iter().map(|d| term(&model, d, &y)).sum::<f64>() / dn * evidence_weight(&rows, &y);
        assert!(
            (mpe.log_probability - joint_y.ln()).abs() < 1e-9,
            "seed {seed}: ln P(mpe) {} vs brute force {}",
            mpe.log_probability,
            joint_y.ln()
        );
        // The labelling attains the max for some decomposition.
        let attained = decs
            .iter()
            .map(|d| term(&model, d, &y) / dn * evidence_weight(&rows, &y))
            .fold(0.0, f64::max);
        assert!((attained.ln() - best.ln()).abs() < 1e-9, "seed {seed}");
        // And the bounds of a non-selective max-product hold against the true max.
        let true_max = ys
            .iter()
            .map(|y| {
                decs.iter().map(|d| term(&model, d, y)).sum::<f64>() / dn
                    * evidence_weight(&rows, y)
            })
            .fold(0.0, f64::max);
        assert!(mpe.log_max_product <= mpe.log_probability + 1e-12);
        assert!(mpe.log_probability <= true_max.ln() + 1e-12);

        // Clamping a place keeps its class and maximises over the rest.
        let p = rng.random_range(0..n);
        let k = rng.random_range(0..c as u16);
        let mut labels = vec![None; n];
        labels[p] = Some(k);
        let clamped = im.mpe(&labels, &ev).unwrap();
        assert_eq!(clamped.assignment[p], u32::from(k));
        let mut best_c = 0.0f64;
        for y in ys.iter().filter(|y| y[p] == k) {
            for d in &decs {
                best_c = best_c.max(term(&model, d, y) / dn * evidence_weight(&rows, y));
            }
        }
        assert!(
            (clamped.log_max_product - best_c.ln()).abs() < 1e-9,
            "seed {seed}"
        );
    }
}

#[test]
fn bad_labellings_are_rejected() {
    let Case { mut im, n, c, .. } = case(1, true);
    let ev = im.uniform_evidence();
    assert!(im.log_likelihood_labelled(&vec![None; n + 1], &ev).is_err());
    let mut labels = vec![None; n];
    labels[0] = Some(c as ClassId);
    let err = im.log_likelihood_labelled(&labels, &ev).unwrap_err();
    assert!(err.to_string().contains("place index 0"), "{err}");
}
