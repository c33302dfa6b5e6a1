//! Evidence validation through the generated demo module: NaN, negative, infinite
//! and all-zero rows give the right `EvidenceError`, naming the place by index and
//! by its `PLACE_IDS` id; the `CompiledMap` trait rejects wrong shapes.

use graphspn_generated::demo_floor::{self, Evidence, Labels, Marginals, NUM_CLASSES, PLACE_IDS};
use graphspn_runtime::{CompiledMap, EvidenceError};

fn ones() -> Evidence {
    [[1.0; NUM_CLASSES]; demo_floor::NUM_PLACES]
}

/// Runs all four checked queries and asserts they return `want`.
fn all_queries_fail(e: &Evidence, want: EvidenceError) {
    let mut out: Marginals = [[0.0; NUM_CLASSES]; demo_floor::NUM_PLACES];
    let mut labels: Labels = [0; demo_floor::NUM_PLACES];
    let unknown: Labels = [demo_floor::UNKNOWN; demo_floor::NUM_PLACES];
    assert_eq!(demo_floor::log_likelihood(e), Err(want));
    assert_eq!(demo_floor::marginals(e, &mut out), Err(want));
    assert_eq!(demo_floor::mpe(e, &mut labels), Err(want));
    assert_eq!(demo_floor::labelled_log_likelihood(&unknown, e), Err(want));
    let msg = want.to_string();
    if let EvidenceError::NotFinite {
        place, place_id, ..
    }
    | EvidenceError::Negative {
        place, place_id, ..
    }
    | EvidenceError::NoMass { place, place_id } = want
    {
        assert!(
            msg.contains(&format!("place {place_id} (index {place})")),
            "{msg}"
        );
    }
}

#[test]
fn valid_evidence_is_accepted() {
    let e = ones();
    let ll = demo_floor::log_likelihood(&e).unwrap();
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
    for (p, v) in [
        (0, f32::INFINITY),
        (demo_floor::NUM_PLACES - 1, f32::NEG_INFINITY),
    ] {
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
fn out_of_range_label_is_rejected() {
    let mut labels: Labels = [demo_floor::UNKNOWN; demo_floor::NUM_PLACES];
    labels[9] = NUM_CLASSES as u16;
    assert!(matches!(
        demo_floor::labelled_log_likelihood(&labels, &ones()),
        Err(EvidenceError::WrongShape { place: 9, .. })
    ));
}

#[test]
fn trait_rejects_wrong_number_of_rows() {
    let rows = vec![[1.0f32; NUM_CLASSES]; demo_floor::NUM_PLACES - 1];
    assert_eq!(
        <demo_floor::Map as CompiledMap>::log_likelihood(&rows),
        Err(EvidenceError::WrongShape {
            place: demo_floor::NUM_PLACES,
            expected: demo_floor::NUM_PLACES,
            found: demo_floor::NUM_PLACES - 1,
        })
    );
}
