//! Evidence validation through the generated demo modules of both model families (the
//! GraphSPN `demo_floor` and the tree mixture `demo_floor_trees`): NaN, negative,
//! infinite and all-zero rows give the right `EvidenceError`, naming the place by index
//! and by its `PLACE_IDS` id, through every entry point — the stateless functions, the
//! streaming `State` (`set_evidence`, `observe`, `set_all`; a rejected row changes
//! nothing) and the `CompiledMap` trait, which also rejects wrong shapes.

use graphspn_runtime::{CompiledMap, EvidenceError};

/// The tests, for one generated module `$m`.
macro_rules! evidence_errors {
    ($m:ident) => {
        use graphspn_generated::$m::{
            self as m, Evidence, Labels, Marginals, NUM_CLASSES, NUM_PLACES, PLACE_IDS,
        };

        use super::*;

        fn ones() -> Evidence {
            [[1.0; NUM_CLASSES]; NUM_PLACES]
        }

        /// Runs every checked entry point on `e` (and the state on the bad row) and
        /// asserts they return `want`.
        fn all_queries_fail(e: &Evidence, want: EvidenceError) {
            let mut out: Marginals = [[0.0; NUM_CLASSES]; NUM_PLACES];
            let mut labels: Labels = [0; NUM_PLACES];
            let unknown: Labels = [m::UNKNOWN; NUM_PLACES];
            assert_eq!(m::log_likelihood(e), Err(want));
            assert_eq!(m::marginals(e, &mut out), Err(want));
            assert_eq!(m::mpe(e, &mut labels), Err(want));
            assert_eq!(m::labelled_log_likelihood(&unknown, e), Err(want));
            assert_eq!(<m::Map as CompiledMap>::marginals(e, &mut out), Err(want));
            // The streaming state: whole evidence, and the bad row alone.
            let mut s = m::State::new();
            s.set_evidence(1, &[0.5; NUM_CLASSES]).unwrap();
            let before = (*s.evidence(), s.log_likelihood().unwrap());
            assert_eq!(s.set_all(e), Err(want));
            if let EvidenceError::NotFinite { place, .. }
            | EvidenceError::Negative { place, .. }
            | EvidenceError::NoMass { place, .. } = want
            {
                assert_eq!(s.set_evidence(place, &e[place]), Err(want));
                assert_eq!(s.observe(place, &e[place]), Err(want));
                let msg = want.to_string();
                let id = PLACE_IDS[place];
                assert!(
                    msg.contains(&format!("place {id} (index {place})")),
                    "{msg}"
                );
            }
            assert_eq!(*s.evidence(), before.0, "a rejected row changed the state");
            assert_eq!(s.log_likelihood().unwrap(), before.1);
        }

        #[test]
        fn valid_evidence_is_accepted() {
            let e = ones();
            let ll = m::log_likelihood(&e).unwrap();
            // All-ones evidence sums the normalised model out: ln S = 0 (f32 rounding).
            assert!(ll.abs() < 1e-4, "{ll}");
        }

        #[test]
        fn nan_is_rejected_naming_the_place() {
            let p = 17;
            let mut e = ones();
            e[p][3] = f32::NAN;
            all_queries_fail(
                &e,
                EvidenceError::NotFinite {
                    place: p,
                    place_id: u64::from(PLACE_IDS[p]),
                    class: 3,
                },
            );
        }

        #[test]
        fn infinity_is_rejected_naming_the_place() {
            for (p, v) in [(0, f32::INFINITY), (NUM_PLACES - 1, f32::NEG_INFINITY)] {
                let mut e = ones();
                e[p][NUM_CLASSES - 1] = v;
                all_queries_fail(
                    &e,
                    EvidenceError::NotFinite {
                        place: p,
                        place_id: u64::from(PLACE_IDS[p]),
                        class: NUM_CLASSES - 1,
                    },
                );
            }
        }

        #[test]
        fn negative_is_rejected_naming_the_place() {
            let p = 41;
            let mut e = ones();
            e[p][0] = -1e-3;
            all_queries_fail(
                &e,
                EvidenceError::Negative {
                    place: p,
                    place_id: u64::from(PLACE_IDS[p]),
                    class: 0,
                },
            );
        }

        #[test]
        fn all_zero_row_is_rejected_naming_the_place() {
            let p = 5;
            let mut e = ones();
            e[p] = [0.0; NUM_CLASSES];
            all_queries_fail(
                &e,
                EvidenceError::NoMass {
                    place: p,
                    place_id: u64::from(PLACE_IDS[p]),
                },
            );
        }

        #[test]
        fn an_observation_leaving_no_class_is_rejected() {
            let p = 7;
            let mut s = m::State::new();
            let mut row = [0.0; NUM_CLASSES];
            row[0] = 1.0;
            s.set_evidence(p, &row).unwrap();
            let mut other = [0.0; NUM_CLASSES];
            other[1] = 1.0;
            let before = *s.evidence();
            assert_eq!(
                s.observe(p, &other),
                Err(EvidenceError::NoMass {
                    place: p,
                    place_id: u64::from(PLACE_IDS[p]),
                })
            );
            assert_eq!(*s.evidence(), before);
        }

        #[test]
        fn out_of_range_label_and_place_are_rejected() {
            let mut labels: Labels = [m::UNKNOWN; NUM_PLACES];
            labels[9] = NUM_CLASSES as u16;
            let bad_label = Err(EvidenceError::LabelOutOfRange {
                place: 9,
                label: NUM_CLASSES as u16,
                classes: NUM_CLASSES,
            });
            assert_eq!(m::labelled_log_likelihood(&labels, &ones()), bad_label);
            let mut s = m::State::new();
            assert_eq!(s.labelled_log_likelihood(&labels), bad_label);
            let wrong = EvidenceError::PlaceOutOfRange {
                place: NUM_PLACES,
                places: NUM_PLACES,
            };
            assert_eq!(s.set_evidence(NUM_PLACES, &[1.0; NUM_CLASSES]), Err(wrong));
            assert_eq!(s.observe(NUM_PLACES, &[1.0; NUM_CLASSES]), Err(wrong));
            assert_eq!(s.clear_evidence(NUM_PLACES), Err(wrong));
            let mut row = [0.0; NUM_CLASSES];
            assert_eq!(s.marginal(NUM_PLACES, &mut row), Err(wrong));
        }

        #[test]
        fn trait_rejects_wrong_number_of_rows() {
            let rows = vec![[1.0f32; NUM_CLASSES]; NUM_PLACES - 1];
            assert_eq!(
                <m::Map as CompiledMap>::log_likelihood(&rows),
                Err(EvidenceError::WrongLength {
                    expected: NUM_PLACES,
                    found: NUM_PLACES - 1,
                })
            );
            // The output and the labels are checked the same way, and the message
            // names no place (the evidence was right).
            let rows = vec![[1.0f32; NUM_CLASSES]; NUM_PLACES];
            let mut out = vec![[0.0f32; NUM_CLASSES]; NUM_PLACES + 1];
            let err = <m::Map as CompiledMap>::marginals(&rows, &mut out).unwrap_err();
            assert_eq!(
                err,
                EvidenceError::WrongLength {
                    expected: NUM_PLACES,
                    found: NUM_PLACES + 1,
                }
            );
            let mut labels = vec![0u16; 2];
            assert_eq!(
                <m::Map as CompiledMap>::mpe(&rows, &mut labels),
                Err(EvidenceError::WrongLength {
                    expected: NUM_PLACES,
                    found: 2,
                })
            );
        }
    };
}

mod graphspn {
    evidence_errors!(demo_floor);
}

mod tree_mixture {
    evidence_errors!(demo_floor_trees);
}
