//! MRF baselines on the real COLD maps (the shipped copy, or `$GRAPHSPN_DATA`; fails
//! if the folder is missing).

use graphspn_compiler::experiments::evidence::{NoiseLevel, simulate_map_evidence};
use graphspn_compiler::map::{ClassId, TopoMap, cold};
use graphspn_compiler::mrf::{BpOptions, CooccurrenceParams, Mrf2, Mrf3, MrfModel, Normalisation};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn building(root: &Path, b: &str) -> Vec<TopoMap> {
    cold::load_building(root, b)
        .unwrap_or_else(|e| panic!("{b} must load from {}: {e}", root.display()))
}

fn accuracy(marg: &[Vec<f64>], map: &TopoMap, only: impl Fn(usize) -> bool) -> f64 {
    let mut ok = 0;
    let mut n = 0;
    for (i, m) in marg.iter().enumerate() {
        if !only(i) {
            continue;
        }
        let best = (0..m.len()).fold(0, |b, k| if m[k] > m[b] { k } else { b });
        n += 1;
        if Some(best as ClassId) == map.place(i).class {
            ok += 1;
        }
    }
    ok as f64 / n.max(1) as f64
}

/// The COLD maps folder ([`cold::data_dir`]); a missing folder fails the test.
fn data_root() -> PathBuf {
    let root = cold::data_dir(None);
    assert!(root.is_dir(), "{} is not a folder", root.display());
    root
}

/// MRF-2 and MRF-3 trained on `train` with the given normalisation.
fn models(train: &[TopoMap], norm: Normalisation) -> (Mrf2, Mrf3) {
    let params = CooccurrenceParams {
        normalisation: norm,
        ..CooccurrenceParams::default()
    };
    (
        Mrf2::train(train, &params).unwrap(),
        Mrf3::train(train, &params).unwrap(),
    )
}

#[test]
fn mrf_baselines_on_cold() {
    let root = data_root();
    let fr = building(&root, "Freiburg");
    let sa = building(&root, "Saarbrucken");
    let st = building(&root, "Stockholm");
    assert_eq!((fr.len(), sa.len(), st.len()), (26, 32, 32));
    let n: usize = fr
        .iter()
        .chain(&sa)
        .chain(&st)
        .map(|m| m.num_places())
        .sum();
    assert_eq!(n, 10_697, "node count after filtering");
    let mut train = sa;
    train.extend(st);
    let opts = BpOptions::default();
    for norm in [Normalisation::Joint, Normalisation::Pmi] {
        let (m2, m3) = models(&train, norm);
        for (name, model, levels, maps) in
            [("MRF-2", &m2 as &dyn MrfModel, 6, 3), ("MRF-3", &m3, 2, 1)]
        {
            for level in NoiseLevel::all().into_iter().take(levels) {
                let t0 = Instant::now();
                let mut accs = Vec::new();
                for (k, map) in fr.iter().take(maps).enumerate() {
                    let ev = simulate_map_evidence(map, level, false, k as u64).unwrap();
                    let r = model.infer(map, &ev.rows, &opts).unwrap();
                    assert!(r.converged, "{norm:?} {name} {level} map {k}");
                    let a = accuracy(&r.marginals, map, |_| true);
                    let a0 = accuracy(&ev.rows, map, |_| true);
                    // With nearly certain evidence (NL1), the spatial model must
                    // repair most of the 20% wrong places.
                    if level.get() == 1 && name == "MRF-2" {
                        assert!(
                            a > a0 + 0.1,
                            "{norm:?} {name} NL1 map {k}: {a} vs evidence {a0}"
                        );
                    }
                    accs.push(format!("{a:.3} (evidence {a0:.3})"));
                }
                println!("{norm:?} {name} {level}: {accs:?} in {:.2?}", t0.elapsed());
            }
        }
    }
}

/// Novelty detection needs `log Z_Bethe`: per-variable log-likelihood of the
/// true labelling must beat the same map with corridor ↔ doorway swapped.
#[test]
fn mrf_likelihood_prefers_true_labels_on_cold() {
    let root = data_root();
    let mut train = building(&root, "Saarbrucken");
    train.extend(building(&root, "Stockholm"));
    let test = building(&root, "Freiburg");
    let opts = BpOptions::default();
    for norm in [Normalisation::Joint, Normalisation::Pmi] {
        let (m2, m3) = models(&train, norm);
        for (name, model) in [("MRF-2", &m2 as &dyn MrfModel), ("MRF-3", &m3)] {
            let mut wins = 0;
            let mut conv = 0;
            let maps = 4;
            for map in test.iter().take(maps) {
                let truth: Vec<ClassId> = map.places().map(|p| p.class.unwrap()).collect();
                let swapped: Vec<ClassId> = truth
                    .iter()
                    .map(|&c| match c {
                        0 => 1,
                        1 => 0,
                        c => c,
                    })
                    .collect();
                let n = truth.len() as f64;
                let a = model.log_likelihood_labelled(map, &truth, &opts).unwrap();
                let b = model.log_likelihood_labelled(map, &swapped, &opts).unwrap();
                conv += a.bp.converged as usize;
                println!(
                    "{norm:?} {name} {}: true {:.3} / var, CR<->DW {:.3} / var (BP sweeps {})",
                    map.name,
                    a.log_likelihood / n,
                    b.log_likelihood / n,
                    a.bp.iterations
                );
                wins += (a.log_likelihood > b.log_likelihood) as usize;
            }
            assert_eq!(
                conv, maps,
                "{norm:?} {name}: BP without evidence did not converge"
            );
            assert_eq!(
                wins, maps,
                "{norm:?} {name}: a swapped map looked more likely"
            );
        }
    }
}
