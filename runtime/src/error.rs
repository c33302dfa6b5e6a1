//! The error returned when local evidence cannot be used.

use core::fmt;

/// Why a place's row of local evidence (one non-negative likelihood per class) was rejected.
///
/// `place` is the place's index in the model's place order (the SPN variable index);
/// `place_id` is the id the user knows the place by (equal to `place` for bare SPNs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EvidenceError {
    /// A value is NaN or infinite.
    NotFinite {
        /// Index of the place (variable) in model order.
        place: usize,
        /// The place's user-facing id.
        place_id: u64,
        /// Class index of the offending value.
        class: usize,
    },
    /// A value is negative.
    Negative {
        /// Index of the place (variable) in model order.
        place: usize,
        /// The place's user-facing id.
        place_id: u64,
        /// Class index of the offending value.
        class: usize,
    },
    /// Every value of the row is zero: the place can take no class at all.
    NoMass {
        /// Index of the place (variable) in model order.
        place: usize,
        /// The place's user-facing id.
        place_id: u64,
    },
    /// The evidence is valid but has probability zero under the model (a model whose
    /// weights exclude every class combination the evidence allows); no marginal exists.
    ZeroLikelihood,
    /// The evidence has the wrong number of places or classes.
    WrongShape {
        /// Index of the first place whose row has the wrong length.
        place: usize,
        /// Classes per row.
        expected: usize,
        /// The row's length.
        found: usize,
    },
    /// A slice that should hold one entry per place (evidence rows, marginals, labels)
    /// has another length.
    WrongLength {
        /// Number of places of the map.
        expected: usize,
        /// The slice's length.
        found: usize,
    },
    /// A place index outside the map (`place >= places`), given to a `State` call.
    PlaceOutOfRange {
        /// The index given.
        place: usize,
        /// Number of places of the map.
        places: usize,
    },
    /// A label that is neither a class index (`< classes`) nor `UNKNOWN` (`u16::MAX`).
    LabelOutOfRange {
        /// Index of the place (variable) in model order.
        place: usize,
        /// The label given.
        label: u16,
        /// Number of classes.
        classes: usize,
    },
}

impl fmt::Display for EvidenceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            EvidenceError::NotFinite {
                place,
                place_id,
                class,
            } => write!(
                f,
                "evidence for place {place_id} (index {place}), class {class} is not finite (NaN or infinite)"
            ),
            EvidenceError::Negative {
                place,
                place_id,
                class,
            } => write!(
                f,
                "evidence for place {place_id} (index {place}), class {class} is negative"
            ),
            EvidenceError::NoMass { place, place_id } => write!(
                f,
                "evidence for place {place_id} (index {place}) is zero for every class"
            ),
            EvidenceError::ZeroLikelihood => {
                write!(f, "the evidence has probability zero under the model")
            }
            EvidenceError::WrongShape {
                place,
                expected,
                found,
            } => write!(
                f,
                "evidence has the wrong shape at place index {place}: expected {expected}, found {found}"
            ),
            EvidenceError::WrongLength { expected, found } => write!(
                f,
                "a slice of {found} entries where the map has {expected} places (evidence rows, marginals and labels take one entry per place)"
            ),
            EvidenceError::PlaceOutOfRange { place, places } => write!(
                f,
                "place index {place} is out of range: the map has {places} places (indices 0 to {})",
                places.saturating_sub(1)
            ),
            EvidenceError::LabelOutOfRange {
                place,
                label,
                classes,
            } => write!(
                f,
                "label {label} at place index {place} is not a class: the model has {classes} classes (labels 0 to {}, or u16::MAX for unknown)",
                classes.saturating_sub(1)
            ),
        }
    }
}

impl core::error::Error for EvidenceError {}
