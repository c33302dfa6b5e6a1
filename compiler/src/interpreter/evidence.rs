//! Local evidence: one row of non-negative class likelihoods `α` per variable.

use graphspn_runtime::EvidenceError;

use crate::spn::Spn;

/// Local evidence `α_v^c ≥ 0` for every variable `v` and class `c` of an SPN.
/// `α = 1` everywhere means "no evidence"; rows may have different lengths
/// (the class count of their variable). Rows need not be normalised.
#[derive(Clone, Debug, PartialEq)]
pub struct Evidence {
    rows: Vec<Vec<f64>>,
}

impl Evidence {
    /// No evidence: every `α` is 1.
    pub fn uniform(spn: &Spn) -> Self {
        Evidence {
            rows: spn.classes.iter().map(|&k| vec![1.0; k as usize]).collect(),
        }
    }

    /// Evidence from explicit rows (checked later by [`Evidence::validate`]).
    pub fn from_rows(rows: Vec<Vec<f64>>) -> Self {
        Evidence { rows }
    }

    /// The rows, one per variable.
    pub fn rows(&self) -> &[Vec<f64>] {
        &self.rows
    }

    /// Checks the shape against `classes` (classes per variable) and every value:
    /// finite, non-negative, and some positive value per row. `place_id` in the error
    /// is the variable index.
    pub fn validate(&self, classes: &[u32]) -> Result<(), EvidenceError> {
        if self.rows.len() != classes.len() {
            return Err(EvidenceError::WrongLength {
                expected: classes.len(),
                found: self.rows.len(),
            });
        }
        for (place, (row, &k)) in self.rows.iter().zip(classes).enumerate() {
            if row.len() != k as usize {
                return Err(EvidenceError::WrongShape {
                    place,
                    expected: k as usize,
                    found: row.len(),
                });
            }
            check_row(place, place as u64, row, k as usize)?;
        }
        Ok(())
    }
}

/// The one check of a row of local evidence, shared by every evaluator (the
/// interpreter, `instance::ComponentInstance`, `treemix::TreeInstance`): `classes`
/// values, each finite and ≥ 0, not all zero. `place` is the place's index, `place_id`
/// its user-facing id (both reported in the error).
pub fn check_row(
    place: usize,
    place_id: u64,
    row: &[f64],
    classes: usize,
) -> Result<(), EvidenceError> {
    if row.len() != classes {
        return Err(EvidenceError::WrongShape {
            place,
            expected: classes,
            found: row.len(),
        });
    }
    for (class, &a) in row.iter().enumerate() {
        if !a.is_finite() {
            return Err(EvidenceError::NotFinite {
                place,
                place_id,
                class,
            });
        }
        if a < 0.0 {
            return Err(EvidenceError::Negative {
                place,
                place_id,
                class,
            });
        }
    }
    if row.iter().all(|&a| a == 0.0) {
        return Err(EvidenceError::NoMass { place, place_id });
    }
    Ok(())
}
