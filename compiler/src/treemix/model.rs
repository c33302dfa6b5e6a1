//! The tree-mixture model file: classes, the shared pairwise and unary potentials,
//! the evidence exponent, the number of trees and how their marginals are mixed.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::learn::ModelFileError;
use crate::learn::model::MODEL_FORMAT;
use crate::map::ClassSet;
use crate::model_file::{ModelFamily, family_of, read};
use crate::spn::Mixing;

/// Largest evidence exponent a model may hold.
pub const MAX_EVIDENCE_EXPONENT: u32 = 8;

/// Largest number of trees a model may ask for per map.
pub const MAX_TREES: usize = 64;

/// Largest ratio between the largest and the smallest entry of the pairwise
/// potential (and of the unary potential). Within it, every message of the f32
/// generated code stays far inside the normal range (see `treemix` module docs).
pub const MAX_POTENTIAL_RATIO: f64 = 1e6;

/// A learned tree mixture (see the [`crate::treemix`] module docs for the model).
///
/// Potentials are relative: scaling `potential` or `unary` by a positive constant
/// leaves every probability unchanged (each tree is normalised by its own `Z_t`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TreeMixture {
    /// Format version, [`MODEL_FORMAT`].
    pub format: u32,
    /// Always [`ModelFamily::TreeMixture`].
    pub family: ModelFamily,
    /// The class names (`C` classes).
    pub classes: ClassSet,
    /// The pairwise potential `ψ(a, b)` at `a · C + b`: `C × C`, symmetric, every
    /// entry finite and > 0.
    pub potential: Vec<f64>,
    /// The unary potential `u(c)` of every place (a class prior factor): `C`
    /// entries, finite and > 0.
    pub unary: Vec<f64>,
    /// Evidence rows enter as `α^γ` with this integer `γ` (1..=[`MAX_EVIDENCE_EXPONENT`]).
    pub evidence_exponent: u32,
    /// Spanning trees per map (1..=[`MAX_TREES`]), unless the caller asks for another count.
    pub trees: usize,
    /// How the trees' marginals are combined (`posterior`: the exact mixture;
    /// `average`: the mean of the trees' exact marginals).
    pub mixing: Mixing,
    /// How the model was trained (free-form, for provenance).
    pub settings: serde_json::Value,
    /// Names of the maps the model was trained on.
    pub trained_on: Vec<String>,
}

impl TreeMixture {
    /// Number of classes `C`.
    pub fn num_classes(&self) -> usize {
        self.classes.len()
    }

    /// `ψ(a, b)`.
    pub fn psi(&self, a: usize, b: usize) -> f64 {
        self.potential[a * self.num_classes() + b]
    }

    /// The one check every path applies (loading, training, inference, code
    /// generation): format and family, unique class names, a symmetric `C × C`
    /// potential and a `C`-entry unary potential with finite entries > 0 whose
    /// largest/smallest ratio is at most [`MAX_POTENTIAL_RATIO`], an evidence exponent
    /// in 1..=[`MAX_EVIDENCE_EXPONENT`], 1..=[`MAX_TREES`] trees. Errors name
    /// `source_name` and the entry.
    pub fn check(&self, source_name: &str) -> Result<(), ModelFileError> {
        let invalid = |message: String| ModelFileError::Invalid {
            source_name: source_name.to_string(),
            message,
        };
        if self.format != MODEL_FORMAT {
            return Err(ModelFileError::UnsupportedFormat {
                source_name: source_name.to_string(),
                found: self.format.to_string(),
                expected: MODEL_FORMAT,
            });
        }
        if self.family != ModelFamily::TreeMixture {
            return Err(invalid(format!(
                "a tree mixture must say \"family\": \"tree_mixture\", this one says {:?}",
                self.family.name()
            )));
        }
        ClassSet::new(self.classes.names().to_vec())
            .map_err(|e| invalid(format!("classes: {e}")))?;
        let c = self.num_classes();
        check_entries("potential", &self.potential, c * c).map_err(&invalid)?;
        check_entries("unary", &self.unary, c).map_err(&invalid)?;
        for a in 0..c {
            for b in a + 1..c {
                let (x, y) = (self.psi(a, b), self.psi(b, a));
                if (x - y).abs() > 1e-9 * x.max(y) {
                    return Err(invalid(format!(
                        "potential is not symmetric: entry ({a}, {b}) is {x}, entry ({b}, {a}) is {y}"
                    )));
                }
            }
        }
        // The same domains as the training settings' ([`crate::domain`]).
        crate::domain::count(
            "evidence_exponent",
            u64::from(self.evidence_exponent),
            1,
            u64::from(MAX_EVIDENCE_EXPONENT),
        )
        .map_err(|e| invalid(e.to_string()))?;
        crate::domain::trees("trees", self.trees).map_err(|e| invalid(e.to_string()))?;
        Ok(())
    }

    /// The model as pretty-printed JSON (ends with a newline). Deterministic.
    pub fn to_json(&self) -> Result<String, ModelFileError> {
        self.check("<model>")?;
        let mut s = serde_json::to_string_pretty(self).map_err(|e| ModelFileError::Invalid {
            source_name: "<model>".into(),
            message: e.to_string(),
        })?;
        s.push('\n');
        Ok(s)
    }

    /// Parses a tree-mixture model file and checks it ([`TreeMixture::check`]);
    /// `source_name` names the input in error messages.
    pub fn from_json_named(text: &str, source_name: &str) -> Result<Self, ModelFileError> {
        let family = family_of(text, source_name)?;
        if family != ModelFamily::TreeMixture {
            return Err(ModelFileError::Invalid {
                source_name: source_name.to_string(),
                message: format!("this is a {} model, not a tree mixture", family.name()),
            });
        }
        let model: TreeMixture = serde_json::from_str(text)
            .map_err(|e| crate::model_file::parse_error(source_name, e))?;
        model.check(source_name)?;
        Ok(model)
    }

    /// Writes the model to `path` as JSON.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), ModelFileError> {
        let path = path.as_ref();
        let text = self.to_json().map_err(|e| match e {
            ModelFileError::Invalid { message, .. } => ModelFileError::Invalid {
                source_name: path.display().to_string(),
                message,
            },
            other => other,
        })?;
        std::fs::write(path, text).map_err(|source| ModelFileError::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Reads a tree-mixture model from `path`.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ModelFileError> {
        let path = path.as_ref();
        Self::from_json_named(&read(path)?, &path.display().to_string())
    }
}

/// `values` has `len` entries, each finite and > 0, largest/smallest ≤ [`MAX_POTENTIAL_RATIO`].
fn check_entries(what: &str, values: &[f64], len: usize) -> Result<(), String> {
    if values.len() != len {
        return Err(format!(
            "{what} has {} entries, expected {len}",
            values.len()
        ));
    }
    if let Some((i, v)) = values
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && **v > 0.0))
    {
        return Err(format!(
            "{what} entry {i} is {v}; entries must be finite and > 0"
        ));
    }
    let max = values.iter().cloned().fold(0.0, f64::max);
    let min = values.iter().cloned().fold(f64::INFINITY, f64::min);
    if max / min > MAX_POTENTIAL_RATIO {
        return Err(format!(
            "{what}: largest entry {max} / smallest {min} exceeds {MAX_POTENTIAL_RATIO:e}"
        ));
    }
    Ok(())
}
