//! Evidence simulation: the protocol's guarantees and the paper's Table 1.

use graphspn_compiler::experiments::evidence::{
    NoiseLevel, NoiseParams, WrongClassDraw, WrongEvidence, d_groundtruth, d_incorrect,
    format_table1, level_statistics, matches_paper, simulate_evidence,
};
use graphspn_compiler::map::ClassId;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const C: usize = 10;

fn random_truths(maps: usize, nodes: usize, seed: u64) -> Vec<Vec<ClassId>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..maps)
        .map(|_| {
            (0..nodes)
                .map(|_| rng.random_range(0..C as ClassId))
                .collect()
        })
        .collect()
}

#[test]
fn statistics_match_paper_table1() {
    let truths = random_truths(20, 100, 2018);
    let stats: Vec<_> = NoiseLevel::all()
        .into_iter()
        .map(|l| level_statistics(&truths, C, l, 5, 42, WrongClassDraw::Others).unwrap())
        .collect();
    println!("{}", format_table1(&stats));
    // The paper's effective noise (`reproduce --paper-noise`) gets statistics of its own
    // draws: a wrong class drawn among all 10 is sometimes the true one.
    let any: Vec<_> = NoiseLevel::all()
        .into_iter()
        .map(|l| level_statistics(&truths, C, l, 5, 42, WrongClassDraw::AnyClass).unwrap())
        .collect();
    assert!(
        stats
            .iter()
            .zip(&any)
            .any(|(o, a)| o.d_incorrect.mean != a.d_incorrect.mean),
        "{}",
        format_table1(&any)
    );
    for st in &stats {
        let (g, i) = matches_paper(st);
        assert!(
            g,
            "{}: D_groundtruth {:?} outside the paper's range",
            st.level, st.d_groundtruth
        );
        assert!(
            i,
            "{}: D_incorrect {:?} outside the paper's range",
            st.level, st.d_incorrect
        );
        // 20 maps × 5 rounds × exactly 20 wrong nodes of 100.
        assert_eq!(st.d_incorrect.n, 20 * 5 * 20);
        assert_eq!(st.d_groundtruth.n, 20 * 5 * 80);
    }
}

#[test]
fn argmax_is_wrong_exactly_for_the_chosen_places() {
    let truths = random_truths(5, 101, 7);
    for level in NoiseLevel::all() {
        for (m, truth) in truths.iter().enumerate() {
            let ev = simulate_evidence(
                truth,
                C,
                &vec![false; truth.len()],
                &level.params(),
                m as u64,
            )
            .unwrap();
            // round(0.2 * 101) = 20.
            assert_eq!(ev.wrong.iter().filter(|&&w| w).count(), 20);
            for (i, row) in ev.rows.iter().enumerate() {
                let s: f64 = row.iter().sum();
                assert!((s - 1.0).abs() < 1e-12);
                assert!(row.iter().all(|&x| x > 0.0));
                let t = truth[i] as usize;
                if !ev.wrong[i] {
                    assert!(d_groundtruth(row, t) > 0.0, "{level} map {m} place {i}");
                } else if level.get() == 1 {
                    assert!(row.iter().all(|&x| (x - 0.1).abs() < 1e-15));
                } else {
                    assert!(d_incorrect(row, t) > 0.0, "{level} map {m} place {i}");
                }
            }
        }
    }
}

#[test]
fn same_seed_same_evidence_and_placeholders_get_none() {
    let truth = random_truths(1, 50, 3).remove(0);
    let ph: Vec<bool> = (0..50).map(|i| i % 5 == 0).collect();
    let p = NoiseLevel::new(2).unwrap().params();
    let a = simulate_evidence(&truth, C, &ph, &p, 9).unwrap();
    let b = simulate_evidence(&truth, C, &ph, &p, 9).unwrap();
    let c = simulate_evidence(&truth, C, &ph, &p, 10).unwrap();
    assert_eq!(a, b);
    assert_ne!(a.rows, c.rows);
    for (i, &p) in ph.iter().enumerate() {
        if p {
            assert!(a.rows[i].iter().all(|&x| x == 0.1));
            assert!(!a.wrong[i]);
        }
    }
    // 20% of the 40 explored places.
    assert_eq!(a.wrong.iter().filter(|&&w| w).count(), 8);
}

#[test]
fn bad_parameters_and_inputs_are_rejected() {
    assert!(NoiseLevel::new(0).is_err() && NoiseLevel::new(7).is_err());
    let mut p = NoiseLevel::new(3).unwrap().params();
    p.loc = (0.1, 0.6); // overlaps hic
    assert!(p.validate().is_err());
    let p = NoiseParams {
        wrong: WrongEvidence::Ranges {
            hiic: (0.3, 0.7),
            loic: (0.2, 0.4),
        },
        ..NoiseLevel::new(2).unwrap().params()
    };
    assert!(p.validate().is_err());
    let ok = NoiseLevel::new(2).unwrap().params();
    assert!(simulate_evidence(&[0, 10], C, &[false, false], &ok, 1).is_err());
    assert!(simulate_evidence(&[0, 1], C, &[false], &ok, 1).is_err());
    assert!(simulate_evidence(&[0], 1, &[false], &ok, 1).is_err());
}
