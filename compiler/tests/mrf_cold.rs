//! MRF baselines on the real COLD maps (needs `GRAPHSPN_DATA`; skipped when the
//! variable is unset, fails when it is set but the folder is missing).
//!
//! Carries a minimal COLD loader of its own (filtering per REFERENCE-FACTS.md
//! §1) so the baselines can be checked before the shared loader lands.

use graphspn_compiler::experiments::evidence::{NoiseLevel, simulate_map_evidence};
use graphspn_compiler::map::{ClassId, ClassSet, Place, TopoMap};
use graphspn_compiler::mrf::{BpOptions, CooccurrenceParams, Mrf2, Mrf3, MrfModel, Normalisation};
use petgraph::graph::UnGraph;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn class_of(raw: &str) -> Option<ClassId> {
    Some(match raw {
        "DW" => 0,
        "CR" | "AT" | "ST" | "EV" => 1,
        "1PO" => 2,
        "2PO" | "PRO" => 3,
        "LO" | "MPO" => 4,
        "LAB" | "RL" | "LR" | "TR" => 5,
        "BA" => 6,
        "KT" => 7,
        "MR" | "LMR" | "CF" => 8,
        "UT" | "WS" | "PT" | "PA" => 9,
        _ => return None,
    })
}

fn load(dir: &Path) -> TopoMap {
    let nodes = std::fs::read_to_string(dir.join("nodes.dat")).unwrap();
    let rooms = std::fs::read_to_string(dir.join("rooms.dat")).unwrap_or_default();
    let relabel: BTreeSet<i64> = rooms
        .lines()
        .filter_map(|l| {
            let mut it = l.split_whitespace();
            let id: i64 = it.next()?.parse().ok()?;
            (it.next()? == "7-2PO-1").then_some(id)
        })
        .collect();
    let mut places: BTreeMap<i64, (Place, Vec<i64>)> = BTreeMap::new();
    for l in nodes.lines().filter(|l| !l.trim().is_empty()) {
        let f: Vec<&str> = l.split_whitespace().collect();
        let id: i64 = f[0].parse().unwrap();
        let class = if relabel.contains(&id) {
            Some(2)
        } else {
            class_of(f[8])
        };
        let Some(class) = class else { continue };
        let nb: Vec<i64> = (0..8)
            .map(|k| f[10 + 3 * k].parse::<i64>().unwrap())
            .filter(|&n| n >= 0)
            .collect();
        let p = Place {
            id: id as u32,
            class: Some(class),
            placeholder: f[1] == "1",
            x: f[2].parse().unwrap(),
            y: f[3].parse().unwrap(),
        };
        places.insert(id, (p, nb));
    }
    let mut edges = BTreeSet::new();
    for (&a, (_, nb)) in &places {
        for &b in nb {
            if b != a && places.contains_key(&b) {
                edges.insert((a.min(b), a.max(b)));
            }
        }
    }
    // Largest connected component (drops isolated nodes too).
    let mut comp: BTreeMap<i64, usize> = BTreeMap::new();
    let mut sizes = Vec::new();
    for &s in places.keys() {
        if comp.contains_key(&s) {
            continue;
        }
        let k = sizes.len();
        let mut stack = vec![s];
        comp.insert(s, k);
        let mut size = 0;
        while let Some(u) = stack.pop() {
            size += 1;
            for &(a, b) in &edges {
                let v = if a == u {
                    b
                } else if b == u {
                    a
                } else {
                    continue;
                };
                if let std::collections::btree_map::Entry::Vacant(e) = comp.entry(v) {
                    e.insert(k);
                    stack.push(v);
                }
            }
        }
        sizes.push(size);
    }
    let best = (0..sizes.len()).max_by_key(|&k| sizes[k]).unwrap();
    let mut g = UnGraph::new_undirected();
    let mut index = BTreeMap::new();
    for (&id, (p, _)) in &places {
        if comp[&id] == best {
            index.insert(id, g.add_node(p.clone()));
        }
    }
    for &(a, b) in &edges {
        if let (Some(&x), Some(&y)) = (index.get(&a), index.get(&b)) {
            g.add_edge(x, y, ());
        }
    }
    TopoMap {
        name: dir.display().to_string(),
        classes: ClassSet::paper(),
        graph: g,
    }
}

fn building(root: &Path, b: &str) -> Vec<TopoMap> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(root.join(b))
        .unwrap_or_else(|e| panic!("{}: {e}", root.join(b).display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("nodes.dat").exists())
        .collect();
    dirs.sort();
    dirs.iter().map(|d| load(d)).collect()
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

#[test]
fn mrf_baselines_on_cold() {
    let Ok(root) = std::env::var("GRAPHSPN_DATA") else {
        eprintln!("GRAPHSPN_DATA unset: skipping");
        return;
    };
    let root = PathBuf::from(root);
    assert!(
        root.is_dir(),
        "GRAPHSPN_DATA={} is not a folder",
        root.display()
    );
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
        let params = CooccurrenceParams {
            normalisation: norm,
            ..CooccurrenceParams::default()
        };
        let m2 = Mrf2::train(&train, &params).unwrap();
        let m3 = Mrf3::train(&train, &params).unwrap();
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
    let Ok(root) = std::env::var("GRAPHSPN_DATA") else {
        eprintln!("GRAPHSPN_DATA unset: skipping");
        return;
    };
    let root = PathBuf::from(root);
    assert!(
        root.is_dir(),
        "GRAPHSPN_DATA={} is not a folder",
        root.display()
    );
    let mut train = building(&root, "Saarbrucken");
    train.extend(building(&root, "Stockholm"));
    let test = building(&root, "Freiburg");
    let opts = BpOptions::default();
    for norm in [Normalisation::Joint, Normalisation::Pmi] {
        let params = CooccurrenceParams {
            normalisation: norm,
            ..CooccurrenceParams::default()
        };
        let m2 = Mrf2::train(&train, &params).unwrap();
        let m3 = Mrf3::train(&train, &params).unwrap();
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
