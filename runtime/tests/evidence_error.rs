//! What an [`EvidenceError`] says: what is wrong and where (place id, index, class).

use graphspn_runtime::EvidenceError;

#[test]
fn every_error_says_what_and_where() {
    let cases = [
        (
            EvidenceError::NotFinite {
                place: 3,
                place_id: 17,
                class: 2,
            },
            "evidence for place 17 (index 3), class 2 is not finite (NaN or infinite)",
        ),
        (
            EvidenceError::Negative {
                place: 4,
                place_id: 40,
                class: 1,
            },
            "evidence for place 40 (index 4), class 1 is negative",
        ),
        (
            EvidenceError::NoMass {
                place: 0,
                place_id: 9,
            },
            "evidence for place 9 (index 0) is zero for every class",
        ),
        (
            EvidenceError::ZeroLikelihood,
            "the evidence has probability zero under the model",
        ),
        (
            EvidenceError::WrongShape {
                place: 5,
                expected: 10,
                found: 9,
            },
            "evidence has the wrong shape at place index 5: expected 10, found 9",
        ),
        (
            EvidenceError::WrongLength {
                expected: 80,
                found: 79,
            },
            "a slice of 79 entries where the map has 80 places (evidence rows, marginals and labels take one entry per place)",
        ),
        (
            EvidenceError::PlaceOutOfRange {
                place: 80,
                places: 80,
            },
            "place index 80 is out of range: the map has 80 places (indices 0 to 79)",
        ),
        (
            EvidenceError::LabelOutOfRange {
                place: 3,
                label: 12,
                classes: 10,
            },
            "label 12 at place index 3 is not a class: the model has 10 classes (labels 0 to 9, or u16::MAX for unknown)",
        ),
    ];
    for (e, want) in cases {
        assert_eq!(e.to_string(), want);
    }
}
