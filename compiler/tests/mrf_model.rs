//! MRF-2 / MRF-3 construction on small hand-made maps, checked by hand and
//! against brute-force enumeration.

use graphspn_compiler::map::{ClassId, ClassSet, Place, TopoMap};
use graphspn_compiler::mrf::model::connected_triples;
use graphspn_compiler::mrf::{
    BpOptions, CooccurrenceParams, Mrf2, Mrf3, MrfModel, Normalisation, exact_inference,
};
use petgraph::graph::UnGraph;

fn map(classes: &[ClassId], edges: &[(u32, u32)]) -> TopoMap {
    let mut g = UnGraph::new_undirected();
    for (i, &c) in classes.iter().enumerate() {
        g.add_node(Place {
            id: 100 + i as u32,
            class: Some(c),
            placeholder: false,
            x: i as f64,
            y: 0.0,
        });
    }
    for &(a, b) in edges {
        g.add_edge(a.into(), b.into(), ());
    }
    TopoMap {
        name: "hand".into(),
        classes: ClassSet::new(vec!["A".into(), "B".into(), "C".into()]).unwrap(),
        graph: g,
    }
}

/// Classes [A, B, B, C]; edges 0-1, 1-2, 2-3, 1-3 (a triangle 1-2-3).
fn hand_map() -> TopoMap {
    map(&[0, 1, 1, 2], &[(0, 1), (1, 2), (2, 3), (1, 3)])
}

#[test]
fn pair_counts_match_hand_count() {
    let joint0 = CooccurrenceParams {
        pseudo_count: 0.0,
        normalisation: Normalisation::Joint,
        coupling: 1.0,
    };
    let m = Mrf2::train(&[hand_map()], &joint0).unwrap();
    // Edges (A,B), (B,B), (B,C), (B,C), each in both orientations.
    let expected = [0.0, 1.0, 0.0, 1.0, 2.0, 2.0, 0.0, 2.0, 0.0];
    assert_eq!(m.counts(), &expected);
    let p: Vec<f64> = expected.iter().map(|n| n / 8.0).collect();
    assert_eq!(m.potential(), p.as_slice());
    // Pseudo-count 1 and PMI: p(a,b) = (n+1)/17, marginals of that table.
    let pmi_params = CooccurrenceParams {
        pseudo_count: 1.0,
        normalisation: Normalisation::Pmi,
        coupling: 1.0,
    };
    let pmi = Mrf2::train(&[hand_map()], &pmi_params).unwrap();
    let q: Vec<f64> = expected.iter().map(|n| (n + 1.0) / 17.0).collect();
    let marg: Vec<f64> = (0..3).map(|a| (0..3).map(|b| q[a * 3 + b]).sum()).collect();
    for a in 0..3 {
        for b in 0..3 {
            let want = q[a * 3 + b] / (marg[a] * marg[b]);
            assert!((pmi.potential()[a * 3 + b] - want).abs() < 1e-15);
        }
    }
}

#[test]
fn triple_counts_match_hand_count() {
    let t = connected_triples(&hand_map());
    assert_eq!(
        t,
        vec![[0, 1, 2], [0, 1, 3], [2, 1, 3], [1, 2, 3], [1, 3, 2]]
    );
    let joint0 = CooccurrenceParams {
        pseudo_count: 0.0,
        normalisation: Normalisation::Joint,
        coupling: 1.0,
    };
    let m = Mrf3::train(&[hand_map()], &joint0).unwrap();
    let idx = |a: usize, p: usize, b: usize| (a * 3 + p) * 3 + b;
    let mut expected = vec![0.0; 27];
    // Pivot 1 (B): (A,B,B), (A,B,C), (B,B,C); pivot 2 (B): (B,B,C); pivot 3 (C): (B,C,B).
    for (a, p, b) in [(0, 1, 1), (0, 1, 2), (1, 1, 2), (1, 1, 2), (1, 2, 1)] {
        expected[idx(a, p, b)] += 1.0;
        expected[idx(b, p, a)] += 1.0;
    }
    assert_eq!(m.counts(), expected.as_slice());
    assert_eq!(m.counts().iter().sum::<f64>(), 10.0);
    // Symmetric in the two ends.
    for a in 0..3 {
        for p in 0..3 {
            for b in 0..3 {
                assert_eq!(m.potential()[idx(a, p, b)], m.potential()[idx(b, p, a)]);
            }
        }
    }
}

#[test]
fn factor_graphs_have_the_documented_factors() {
    let m2 = Mrf2::train(&[hand_map()], &CooccurrenceParams::default()).unwrap();
    let m3 = Mrf3::train(&[hand_map()], &CooccurrenceParams::default()).unwrap();
    let ev: Vec<Vec<f64>> = (0..4)
        .map(|i| vec![0.2, 0.3 + 0.1 * i as f64, 0.5])
        .collect();
    let fg2 = m2.factor_graph(&hand_map(), Some(&ev)).unwrap();
    let vars2: Vec<&[usize]> = fg2.factors().iter().map(|f| f.vars()).collect();
    assert_eq!(
        vars2,
        vec![
            &[0, 1][..],
            &[1, 2],
            &[1, 3],
            &[2, 3],
            &[0],
            &[1],
            &[2],
            &[3]
        ]
    );
    let fg3 = m3.factor_graph(&hand_map(), Some(&ev)).unwrap();
    assert_eq!(fg3.factors().len(), 5 + 4);
    assert_eq!(fg3.factors()[8].table(), ev[3].as_slice());
    // Bad evidence is refused with the place id in the message.
    let mut bad = ev.clone();
    bad[2] = vec![0.0; 3];
    let err = m2
        .infer(&hand_map(), &bad, &BpOptions::default())
        .unwrap_err();
    assert!(err.to_string().contains("place 102"), "{err}");
}

#[test]
fn inference_and_likelihood_are_exact_on_a_tree_map() {
    // A star-shaped tree: MRF-2's factor graph is a tree, so BP is exact.
    let train = [
        hand_map(),
        map(&[0, 0, 1, 2, 2], &[(0, 1), (1, 2), (2, 3), (3, 4)]),
    ];
    let m2 = Mrf2::train(&train, &CooccurrenceParams::default()).unwrap();
    let test = map(&[1, 0, 1, 2, 1], &[(0, 1), (0, 2), (0, 3), (3, 4)]);
    let ev: Vec<Vec<f64>> = (0..5)
        .map(|i| vec![0.1 + 0.05 * i as f64, 0.6, 0.3 - 0.05 * i as f64])
        .collect();
    let bp = m2.infer(&test, &ev, &BpOptions::default()).unwrap();
    let exact = exact_inference(&m2.factor_graph(&test, Some(&ev)).unwrap(), 1 << 12).unwrap();
    for (a, b) in bp.marginals.iter().zip(&exact.marginals) {
        for (p, q) in a.iter().zip(b) {
            assert!((p - q).abs() < 1e-10);
        }
    }
    let labels = [1, 0, 1, 2, 1];
    let ll = m2
        .log_likelihood_labelled(&test, &labels, &BpOptions::default())
        .unwrap();
    let fg = m2.factor_graph(&test, None).unwrap();
    let x: Vec<usize> = labels.iter().map(|&l| l as usize).collect();
    let want = fg.log_score(&x).unwrap() - exact_inference(&fg, 1 << 12).unwrap().log_z;
    assert!(ll.bp.converged);
    assert!(
        (ll.log_likelihood - want).abs() < 1e-10,
        "{} vs {want}",
        ll.log_likelihood
    );
    assert!(ll.log_likelihood < 0.0);
    // MRF-3 on the loopy hand map: a proper (approximate) distribution.
    let m3 = Mrf3::train(&train, &CooccurrenceParams::default()).unwrap();
    let r = m3
        .infer(&hand_map(), &ev[..4], &BpOptions::default())
        .unwrap();
    assert!(r.converged);
    for row in &r.marginals {
        assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
}

#[test]
fn normalised_conditional_and_coupling_follow_their_formulas() {
    let base = CooccurrenceParams {
        pseudo_count: 1.0,
        normalisation: Normalisation::Joint,
        coupling: 1.0,
    };
    let joint = Mrf2::train(&[hand_map()], &base).unwrap();
    let q = joint.potential().to_vec();
    let marg: Vec<f64> = (0..3).map(|a| (0..3).map(|b| q[a * 3 + b]).sum()).collect();
    let with = |normalisation, coupling| {
        Mrf2::train(
            &[hand_map()],
            &CooccurrenceParams {
                normalisation,
                coupling,
                ..base
            },
        )
        .unwrap()
    };
    let norm = with(Normalisation::Normalised, 0.3);
    let cond = with(Normalisation::Conditional, 1.0);
    for a in 0..3 {
        for b in 0..3 {
            let n = (q[a * 3 + b] / (marg[a] * marg[b]).sqrt()).powf(0.3);
            assert!((norm.potential()[a * 3 + b] - n).abs() < 1e-12);
            let c = q[a * 3 + b] / marg[a];
            assert!((cond.potential()[a * 3 + b] - c).abs() < 1e-12);
        }
    }
    // Coupling 0: every potential is 1 (independent places).
    assert!(
        with(Normalisation::Pmi, 0.0)
            .potential()
            .iter()
            .all(|&v| v == 1.0)
    );
    // MRF-3 conditional: p(a, b | pivot), so each pivot slice sums to 1.
    let m3 = Mrf3::train(
        &[hand_map()],
        &CooccurrenceParams {
            normalisation: Normalisation::Conditional,
            ..base
        },
    )
    .unwrap();
    for p in 0..3 {
        let s: f64 = (0..3)
            .flat_map(|a| (0..3).map(move |b| (a * 3 + p) * 3 + b))
            .map(|i| m3.potential()[i])
            .sum();
        assert!((s - 1.0).abs() < 1e-12, "pivot {p}: {s}");
    }
    assert!(
        Mrf2::train(
            &[hand_map()],
            &CooccurrenceParams {
                coupling: -1.0,
                ..base
            }
        )
        .is_err()
    );
}

/// The names that validation tables and reports print, one per normalisation.
#[test]
fn normalisations_have_their_documented_names() {
    let names: Vec<&str> = Normalisation::ALL.iter().map(|n| n.name()).collect();
    assert_eq!(names, ["joint", "conditional", "normalised", "pmi"]);
}

/// Evidence rows with zero entries are valid (only negative, non-finite and all-zero
/// rows are refused, naming the place), and a map whose class set is not the model's
/// is refused.
#[test]
fn evidence_and_class_checks_refuse_only_bad_input() {
    let m2 = Mrf2::train(&[hand_map()], &CooccurrenceParams::default()).unwrap();
    let mut ev = vec![vec![0.2, 0.3, 0.5]; 4];
    ev[1] = vec![0.0, 1.0, 0.0];
    let fg = m2.factor_graph(&hand_map(), Some(&ev)).unwrap();
    assert_eq!(fg.factors()[5].table(), [0.0, 1.0, 0.0]);
    for row in [
        vec![-0.1, 0.5, 0.6],
        vec![f64::NAN, 0.5, 0.5],
        vec![0.2, f64::INFINITY, 0.5],
    ] {
        let mut bad = ev.clone();
        bad[3] = row;
        let err = m2.factor_graph(&hand_map(), Some(&bad)).unwrap_err();
        assert!(err.to_string().contains("place 103"), "{err}");
    }
    let mut four = hand_map();
    four.classes = ClassSet::new(vec!["A".into(), "B".into(), "C".into(), "D".into()]).unwrap();
    let err = m2.factor_graph(&four, None).unwrap_err();
    assert!(err.to_string().contains("4 classes, the model 3"), "{err}");
    // A place labelled with class index 3 of 3 classes is refused by name, not counted.
    let out_of_range = map(&[0, 1, 1, 3], &[(0, 1), (1, 2), (2, 3)]);
    let err = Mrf2::train(&[out_of_range], &CooccurrenceParams::default()).unwrap_err();
    assert!(
        err.to_string().contains("place 103: class 3 out of range"),
        "{err}"
    );
}

/// Without pseudo-counts a class that never occurs has a zero marginal: every
/// potential involving it is 0 (its whole slice of the joint is 0), never `0/0`, under
/// every normalisation that divides by marginals.
#[test]
fn a_class_never_seen_without_pseudo_counts_gets_zero_potentials() {
    // Classes A and B only; C (index 2) never occurs.
    let m = map(&[0, 1, 0, 1], &[(0, 1), (1, 2), (2, 3)]);
    for normalisation in EVERY_NORMALISATION {
        let params = CooccurrenceParams {
            pseudo_count: 0.0,
            normalisation,
            coupling: 1.0,
        };
        let p = Mrf2::train(std::slice::from_ref(&m), &params).unwrap();
        for a in 0..3 {
            for b in 0..3 {
                let v = p.potential()[a * 3 + b];
                if a == 2 || b == 2 {
                    assert_eq!(v, 0.0, "{normalisation:?}: potential ({a}, {b})");
                } else {
                    assert!(
                        v.is_finite() && v >= 0.0,
                        "{normalisation:?}: ({a}, {b}) = {v}"
                    );
                }
            }
        }
    }
}

/// Training maps without one labelled edge and no pseudo-count: the joint frequencies
/// are 0/0, so the table falls back to uniform and every potential is one finite
/// value (no NaN), under each normalisation.
#[test]
fn no_labelled_edge_without_pseudo_counts_gives_uniform_potentials() {
    let m = map(&[0, 1, 2], &[]);
    for normalisation in EVERY_NORMALISATION {
        let params = CooccurrenceParams {
            pseudo_count: 0.0,
            normalisation,
            coupling: 1.0,
        };
        let p = Mrf2::train(std::slice::from_ref(&m), &params).unwrap();
        let first = p.potential()[0];
        assert!(
            first.is_finite() && first > 0.0,
            "{normalisation:?}: {first}"
        );
        assert!(
            p.potential().iter().all(|&v| v == first),
            "{normalisation:?}: {:?}",
            p.potential()
        );
    }
}

/// Every normalisation of co-occurrence potentials.
const EVERY_NORMALISATION: [Normalisation; 4] = [
    Normalisation::Joint,
    Normalisation::Pmi,
    Normalisation::Normalised,
    Normalisation::Conditional,
];
