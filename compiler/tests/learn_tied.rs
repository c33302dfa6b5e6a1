//! Symmetry in training: augmentation with every automorphic image gives exactly
//! symmetric tables, tied weights stay bit-identical, and tied EM equals untied EM on
//! the augmented data (its closed-form reference).

mod harness;

use graphspn_compiler::learn::{
    DenseParams, EmKind, Progress, Symmetry, TrainingSettings, augment_with_automorphisms,
    dense_structure, edge_orbits, learn_template_spn, symmetric_dense_structure, train, train_tied,
};
use graphspn_compiler::spn::Node;
use harness::learn::*;

#[test]
fn augmentation_makes_tables_exactly_symmetric() {
    for (n, group) in [(2usize, pair_group()), (3, three_group())] {
        let table = mixture_table(n, 10, 3, 77);
        let samples = sample_table(&table, n, 10, 5_000, 3);
        let aug = augment_with_automorphisms(&samples, &group).unwrap();
        assert_eq!(aug.len(), samples.len() * group.len());
        let mut spn = dense_structure(n, 10, &DenseParams::default(), 2).unwrap();
        train(
            &mut spn,
            &aug,
            &TrainingSettings::default(),
            Progress::Hidden,
        )
        .unwrap();
        for x in all_labellings(n, 10) {
            for g in &group {
                let y: Vec<u16> = g.iter().map(|&i| x[i]).collect();
                assert_eq!(value(&spn, &x), value(&spn, &y), "{x:?} vs {y:?}");
            }
        }
    }
}

/// Largest |log p(x) − log p(g·x)| over all assignments and automorphisms.
fn asymmetry(spn: &graphspn_compiler::spn::Spn, c: u16) -> f64 {
    let mut worst = 0.0f64;
    for x in all_labellings(5, c) {
        let v = value(spn, &x).ln();
        for g in star_group() {
            let y: Vec<u16> = g.iter().map(|&i| x[i]).collect();
            worst = worst.max((value(spn, &y).ln() - v).abs());
        }
    }
    worst
}

#[test]
fn star_symmetry_augmented_vs_tied() {
    let table = mixture_table(5, 4, 3, 5);
    let samples = sample_table(&table, 5, 4, 3_000, 4);
    let settings = TrainingSettings {
        symmetry: Symmetry::Augment,
        ..TrainingSettings::default()
    };
    let (aug, _) = learn_template_spn(
        5,
        4,
        &star_group(),
        &samples,
        &settings,
        1,
        Progress::Hidden,
    )
    .unwrap();
    let tied_settings = TrainingSettings {
        symmetry: Symmetry::Tied,
        ..settings.clone()
    };
    let (tied, rep) = learn_template_spn(
        5,
        4,
        &star_group(),
        &samples,
        &tied_settings,
        1,
        Progress::Hidden,
    )
    .unwrap();
    let a = asymmetry(&aug, 4);
    let t = asymmetry(&tied, 4);
    eprintln!("star asymmetry max |Δ log p|: augmented {a:.3e}, tied {t:.3e}");
    assert!(t < 1e-12, "tied: {t}");
    assert!(a > t);
    let rep = rep.unwrap();
    assert_eq!(rep.num_samples, samples.len() * 24);
    assert!(rep.num_distinct < rep.num_samples);
}

#[test]
fn tied_weights_stay_bit_identical() {
    let table = mixture_table(3, 5, 2, 8);
    let samples = sample_table(&table, 3, 5, 2_000, 8);
    let mut spn =
        symmetric_dense_structure(3, 5, &DenseParams::default(), &three_group(), 3).unwrap();
    let orbits = edge_orbits(&spn, &three_group()).unwrap();
    // No augmentation: the data are asymmetric, tying alone must symmetrise.
    train_tied(
        &mut spn,
        &samples,
        &TrainingSettings::default(),
        &orbits,
        Progress::Hidden,
    )
    .unwrap();
    let flat: Vec<f64> = spn
        .nodes
        .iter()
        .filter_map(|n| match n {
            Node::Sum { weights, .. } => Some(weights.clone()),
            _ => None,
        })
        .flatten()
        .collect();
    for orbit in &orbits.orbits {
        for &e in orbit {
            assert_eq!(
                flat[e as usize].to_bits(),
                flat[orbit[0] as usize].to_bits()
            );
        }
    }
}

/// Tied EM has a closed-form reference: with the structure invariant under the group
/// and tied initial weights, tied soft EM on the data equals untied soft EM on the data
/// augmented with every automorphic image (`|G|` times the samples, `|G|` times the
/// smoothing): an edge's augmented count is `|G|` times its orbit's mean count. Checked
/// on the Star template (24 automorphisms) after several epochs; a tied M-step that
/// summed instead of averaging, or smoothed per orbit, would fail. (Hard EM breaks
/// symmetric ties in its max-product paths, so only soft EM has this identity.)
#[test]
fn tied_em_equals_untied_em_on_the_augmented_data() {
    let (vars, classes) = (5usize, 3u32);
    let group = star_group();
    let table = mixture_table(vars, classes as u16, 2, 17);
    let samples = sample_table(&table, vars, classes as u16, 400, 17);
    let p = DenseParams {
        split_choice: graphspn_compiler::learn::SplitChoice::FewestImages,
        ..DenseParams::default()
    };
    let start = symmetric_dense_structure(vars, classes, &p, &group, 5).unwrap();
    let orbits = edge_orbits(&start, &group).unwrap();
    assert!(!orbits.is_trivial());
    let settings = TrainingSettings {
        epochs: 4,
        em: EmKind::Soft,
        smoothing_start: 3.0,
        smoothing_end: 0.5,
        ..TrainingSettings::default()
    };
    let mut tied = start.clone();
    train_tied(&mut tied, &samples, &settings, &orbits, Progress::Hidden).unwrap();
    let images: Vec<Vec<u16>> = samples
        .iter()
        .flat_map(|x| group.iter().map(|g| g.iter().map(|&i| x[i]).collect()))
        .collect();
    let k = group.len() as f64;
    let scaled = TrainingSettings {
        smoothing_start: settings.smoothing_start * k,
        smoothing_end: settings.smoothing_end * k,
        ..settings.clone()
    };
    let mut untied = start.clone();
    train(&mut untied, &images, &scaled, Progress::Hidden).unwrap();
    let (mut worst, mut moved) = (0.0f64, 0.0f64);
    for ((a, b), s) in tied.nodes.iter().zip(&untied.nodes).zip(&start.nodes) {
        if let (
            Node::Sum { weights: wa, .. },
            Node::Sum { weights: wb, .. },
            Node::Sum { weights: ws, .. },
        ) = (a, b, s)
        {
            for ((x, y), z) in wa.iter().zip(wb).zip(ws) {
                worst = worst.max((x - y).abs());
                moved = moved.max((x - z).abs());
            }
        }
    }
    assert!(moved > 1e-3, "training moved no weight ({moved})");
    assert!(worst < 1e-10, "tied vs untied on augmented data: {worst}");
}
