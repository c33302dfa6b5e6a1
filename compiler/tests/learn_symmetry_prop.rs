//! Property: a template SPN trained with `Symmetry::Tied` is invariant under the
//! template's automorphisms for every full assignment, whatever the data and
//! seeds; with `Symmetry::Augment` the full tables (Pair, Three) are too.

mod harness;

use graphspn_compiler::learn::{Progress, Symmetry, TrainingSettings, learn_template_spn};
use harness::learn::*;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    #[test]
    fn tied_star_is_invariant(
        data_seed in 0u64..1000,
        structure_seed in 0u64..1000,
        x in proptest::collection::vec(0u16..3, 5),
        g in 0usize..24,
        epochs in 1usize..4,
    ) {
        let table = mixture_table(5, 3, 3, data_seed);
        let samples = sample_table(&table, 5, 3, 400, data_seed);
        let settings = TrainingSettings {
            epochs,
            symmetry: Symmetry::Tied,
            ..TrainingSettings::default()
        };
        let (spn, _) = learn_template_spn(
            5, 3, &star_group(), &samples, &settings, structure_seed, Progress::Hidden,
        ).unwrap();
        let perm = &star_group()[g];
        let y: Vec<u16> = perm.iter().map(|&i| x[i]).collect();
        let (a, b) = (value(&spn, &x), value(&spn, &y));
        prop_assert!((a - b).abs() <= 1e-13 * a, "{x:?} {a} vs {y:?} {b}");
    }

    #[test]
    fn augmented_tables_are_invariant(
        data_seed in 0u64..1000,
        x in proptest::collection::vec(0u16..6, 3),
        three in any::<bool>(),
    ) {
        let (n, group) = if three { (3, three_group()) } else { (2, pair_group()) };
        let table = mixture_table(n, 6, 2, data_seed);
        let samples = sample_table(&table, n, 6, 300, data_seed);
        let settings = TrainingSettings {
            symmetry: Symmetry::Augment,
            ..TrainingSettings::default()
        };
        let (spn, _) = learn_template_spn(
            n, 6, &group, &samples, &settings, data_seed, Progress::Hidden,
        ).unwrap();
        for perm in &group {
            let y: Vec<u16> = perm.iter().map(|&i| x[i]).collect();
            prop_assert_eq!(value(&spn, &x[..n]), value(&spn, &y));
        }
    }
}
