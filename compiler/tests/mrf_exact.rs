//! Loopy BP against exact inference (variable elimination) for the tuned MRF
//! baselines on small connected sub-maps cut from the shipped COLD maps, and
//! variable elimination against brute-force enumeration.

use std::collections::VecDeque;

use graphspn_compiler::experiments::evidence::{NoiseLevel, simulate_map_evidence};
use graphspn_compiler::experiments::models::temper_rows;
use graphspn_compiler::map::{TopoMap, cold};
use graphspn_compiler::mrf::{
    BpOptions, CooccurrenceParams, FactorGraph, Mrf2, Mrf3, MrfError, MrfModel, Normalisation,
    Schedule, exact_inference, loopy_bp, variable_elimination,
};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

#[test]
fn variable_elimination_matches_enumeration() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for _ in 0..5 {
        let mut fg = FactorGraph::new(vec![3, 2, 3, 2, 3, 2]).unwrap();
        for a in 0..6usize {
            fg.add_factor(
                vec![a],
                (0..fg.cards()[a]).map(|_| rng.random::<f64>()).collect(),
            )
            .unwrap();
        }
        for vars in [
            vec![0, 1],
            vec![3, 1, 2],
            vec![2, 4],
            vec![4, 0],
            vec![5, 3, 0],
        ] {
            let size: usize = vars.iter().map(|&v| fg.cards()[v]).product();
            let t = (0..size).map(|_| rng.random::<f64>() + 0.01).collect();
            fg.add_factor(vars, t).unwrap();
        }
        let e = exact_inference(&fg, 1 << 20).unwrap();
        let v = variable_elimination(&fg, 1 << 20).unwrap();
        assert!(
            (e.log_z - v.log_z).abs() < 1e-10,
            "{} vs {}",
            e.log_z,
            v.log_z
        );
        for (a, b) in e.marginals.iter().zip(&v.marginals) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() < 1e-12);
            }
        }
    }
}

/// `ln Z` of a one-variable graph (`Z` = the sum of its factors' products) and of
/// a variable in no factor (`Z` = its cardinality): the first elimination run is
/// the one that sets `ln Z`, and with one variable it is the only run.
#[test]
fn variable_elimination_gives_ln_z_of_one_variable() {
    let mut fg = FactorGraph::new(vec![3]).unwrap();
    fg.add_factor(vec![0], vec![1.0, 3.0, 0.5]).unwrap();
    fg.add_factor(vec![0], vec![2.0, 1.0, 4.0]).unwrap();
    let v = variable_elimination(&fg, 1 << 10).unwrap();
    assert!((v.log_z - 7f64.ln()).abs() < 1e-12, "ln Z {}", v.log_z);
    for (m, want) in v.marginals[0].iter().zip([2.0 / 7.0, 3.0 / 7.0, 2.0 / 7.0]) {
        assert!((m - want).abs() < 1e-12, "marginal {m} vs {want}");
    }
    let free = FactorGraph::new(vec![4]).unwrap();
    let v = variable_elimination(&free, 1 << 10).unwrap();
    assert!((v.log_z - 4f64.ln()).abs() < 1e-12, "ln Z {}", v.log_z);
}

/// A graph whose every assignment scores 0 has no distribution: variable
/// elimination (an all-zero table is left as it is, not divided by its maximum 0) and
/// enumeration both report it as inconsistent, on one variable and on a chain whose
/// contradiction sits in a summed-out table.
#[test]
fn variable_elimination_reports_a_contradiction_not_nan() {
    let mut one = FactorGraph::new(vec![2]).unwrap();
    one.add_factor(vec![0], vec![1.0, 0.0]).unwrap();
    one.add_factor(vec![0], vec![0.0, 2.0]).unwrap();
    let mut chain = FactorGraph::new(vec![2, 2, 2]).unwrap();
    chain
        .add_factor(vec![0, 1], vec![1.0, 0.0, 0.0, 1.0])
        .unwrap();
    chain
        .add_factor(vec![1, 2], vec![0.5, 0.5, 0.5, 0.5])
        .unwrap();
    chain.add_factor(vec![0], vec![0.0, 3.0]).unwrap();
    chain.add_factor(vec![1], vec![2.0, 0.0]).unwrap();
    for fg in [&one, &chain] {
        assert!(matches!(
            variable_elimination(fg, 1 << 10),
            Err(MrfError::Inconsistent)
        ));
        assert!(matches!(
            exact_inference(fg, 1 << 10),
            Err(MrfError::Inconsistent)
        ));
    }
}

/// Variable elimination rescales every intermediate table (its documented guard
/// against underflow): a chain of 60 variables whose pairwise factors are all
/// scaled by `1e-10` has `Z` near `1e-590`, far below `f64`'s range, yet its `ln Z`
/// must be the unscaled chain's plus `59 · ln 1e-10`, with the same marginals.
#[test]
fn variable_elimination_keeps_tiny_factor_products_from_underflowing() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let n = 60;
    let scale = 1e-10f64;
    let mut plain = FactorGraph::new(vec![2; n]).unwrap();
    let mut tiny = plain.clone();
    for a in 0..n - 1 {
        let t: Vec<f64> = (0..4).map(|_| rng.random::<f64>() + 0.1).collect();
        plain.add_factor(vec![a, a + 1], t.clone()).unwrap();
        tiny.add_factor(vec![a, a + 1], t.iter().map(|x| x * scale).collect())
            .unwrap();
    }
    let p = variable_elimination(&plain, 1 << 20).unwrap();
    let t = variable_elimination(&tiny, 1 << 20).unwrap();
    let expected = p.log_z + (n - 1) as f64 * scale.ln();
    assert!(
        (t.log_z - expected).abs() < 1e-9 * expected.abs(),
        "ln Z {} vs {expected}",
        t.log_z
    );
    for (a, b) in p.marginals.iter().zip(&t.marginals) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() < 1e-12, "marginal {y} vs {x}");
        }
    }
}

/// A connected sub-map of `n` places: breadth-first from place `start`.
fn bfs_submap(map: &TopoMap, start: usize, n: usize) -> TopoMap {
    let mut seen = vec![false; map.num_places()];
    let mut order = Vec::new();
    let mut q = VecDeque::from([start]);
    seen[start] = true;
    while let Some(i) = q.pop_front() {
        if order.len() == n {
            break;
        }
        order.push(i);
        for j in map.neighbors(i) {
            if !seen[j] {
                seen[j] = true;
                q.push_back(j);
            }
        }
    }
    map.induced_submap(&order)
}

/// The tuned settings an earlier `graphspn validate` run chose (they include every
/// potential and exponent of the run docs/REPRODUCTION.md reports): potentials,
/// coupling, evidence exponent; BP flooding with damping 0.5, at most 200 sweeps.
const TUNED: [(&str, Normalisation, f64, f64); 6] = [
    ("MRF-2", Normalisation::Normalised, 0.45, 3.0),
    ("MRF-2", Normalisation::Normalised, 0.6, 3.0),
    ("MRF-2", Normalisation::Normalised, 0.6, 4.0),
    ("MRF-3", Normalisation::Normalised, 0.1, 3.0),
    ("MRF-3", Normalisation::Normalised, 0.1, 4.0),
    ("MRF-3", Normalisation::Normalised, 0.2, 4.0),
];

#[test]
fn loopy_bp_is_close_to_exact_on_cold_sub_maps_for_the_tuned_mrfs() {
    let root = cold::data_dir(None);
    let load = |b| cold::load_building(&root, b).unwrap();
    let (fr, sa, st) = (load("Freiburg"), load("Saarbrucken"), load("Stockholm"));
    let train: Vec<TopoMap> = sa.iter().chain(&st).cloned().collect();
    let bp = BpOptions {
        schedule: Schedule::Parallel,
        damping: 0.5,
        max_iterations: 200,
        ..BpOptions::default()
    };
    // 8-place connected sub-maps of real maps of all three buildings: the first
    // start place (from a fixed one on) whose MRF-3 exact inference fits in 4M
    // table entries (the triple factors over a sub-map's triangles can make
    // variable elimination too wide).
    let probe = Mrf3::train(&train, &CooccurrenceParams::default()).unwrap();
    let maps = [
        &fr[0], &fr[5], &fr[11], &sa[3], &sa[20], &st[2], &st[9], &st[25],
    ];
    let subs: Vec<TopoMap> = maps
        .par_iter()
        .enumerate()
        .map(|(k, m)| {
            (0..m.num_places())
                .map(|j| bfs_submap(m, (17 * k + 5 + j) % m.num_places(), 8))
                .find(|sub| {
                    let fg = probe.factor_graph(sub, None).unwrap();
                    variable_elimination(&fg, 1 << 22).is_ok()
                })
                .unwrap_or_else(|| panic!("no feasible sub-map in {}", m.name))
        })
        .collect();
    let models: Vec<(Mrf2, Mrf3)> = TUNED
        .iter()
        .map(|&(_, form, coupling, _)| {
            let p = CooccurrenceParams {
                normalisation: form,
                coupling,
                ..CooccurrenceParams::default()
            };
            (
                Mrf2::train(&train, &p).unwrap(),
                Mrf3::train(&train, &p).unwrap(),
            )
        })
        .collect();
    // Every (setting, sub-map, noise level) on its own: side by side (exact inference
    // of the MRF-3s takes most of this test's time), reported in this order.
    let cases: Vec<(usize, usize, u8)> = (0..TUNED.len())
        .flat_map(|t| (0..subs.len()).flat_map(move |s| [2, 4, 6].map(move |level| (t, s, level))))
        .collect();
    let results: Vec<(usize, f64, String)> = cases
        .par_iter()
        .map(|&(t, s, level)| {
            let (name, form, coupling, exponent) = TUNED[t];
            let sub = &subs[s];
            let ev =
                simulate_map_evidence(sub, NoiseLevel::new(level).unwrap(), s % 2 == 1, s as u64)
                    .unwrap();
            let rows = temper_rows(&ev.rows, exponent);
            let (k, fg) = if name == "MRF-2" {
                (0, models[t].0.factor_graph(sub, Some(&rows)).unwrap())
            } else {
                (1, models[t].1.factor_graph(sub, Some(&rows)).unwrap())
            };
            let exact = variable_elimination(&fg, 1 << 22).unwrap_or_else(|e| {
                panic!("{name} on {}: exact inference refused ({e})", sub.name)
            });
            let r = loopy_bp(&fg, &bp).unwrap();
            assert!(r.converged, "{name} BP did not converge on {}", sub.name);
            let err = exact
                .marginals
                .iter()
                .zip(&r.marginals)
                .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
                .fold(0.0, f64::max);
            let dz = (exact.log_z - r.log_z_bethe).abs() / sub.num_places() as f64;
            let line = format!(
                "{name} {}^{coupling} ev^{exponent} NL{level} on {} ({} places, {} edges): \
                 max |marginal error| {err:.2e}, |log Z − Bethe| per place {dz:.2e}",
                form.name(),
                sub.name,
                sub.num_places(),
                sub.num_edges(),
            );
            (k, err, line)
        })
        .collect();
    let mut checked = [0usize; 2];
    let mut worst = [0.0f64; 2];
    for (k, err, line) in results {
        eprintln!("{line}");
        checked[k] += 1;
        worst[k] = worst[k].max(err);
    }
    eprintln!(
        "worst BP marginal error over {} MRF-2 and {} MRF-3 checks: {:.2e}, {:.2e}",
        checked[0], checked[1], worst[0], worst[1]
    );
    assert_eq!(checked, [72, 72]);
    // The tuned MRFs' numbers reflect the models, not the approximation.
    assert!(
        worst[0] < BP_TOLERANCE,
        "MRF-2: loopy BP off by {}",
        worst[0]
    );
    assert!(
        worst[1] < BP_TOLERANCE,
        "MRF-3: loopy BP off by {}",
        worst[1]
    );
}

/// Largest marginal error of loopy BP accepted for a tuned MRF.
const BP_TOLERANCE: f64 = 0.05;
