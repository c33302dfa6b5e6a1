//! Reading and writing the model file (JSON, versioned, pretty-printed).
//!
//! Output is deterministic: struct fields in declaration order, map keys sorted
//! (serde_json's default map), floats in shortest round-trip form; parsing uses
//! serde_json's exact float parser (`float_roundtrip`), so every `f64` survives a
//! save/load cycle bit for bit.

use std::path::Path;

use serde::Deserialize;

use super::model::{MODEL_FORMAT, Model};
use super::settings::TrainingSettings;
use crate::model_file::parse_error;
use crate::model_file::{ModelFamily, family_of};
pub use crate::model_file::{ModelFileError, TemplateSpnError};
use crate::spn::validate::WEIGHT_SUM_TOLERANCE;
use crate::spn::{Node, Spn};
use crate::template::Template;

#[derive(Deserialize)]
struct Probe {
    format: Option<serde_json::Value>,
}

/// The one check every path applies to a template SPN (`Model::load`, `infer`,
/// `instance`, `compile`): `num_vars` variables of `classes` classes each, and every
/// structural invariant of [`Spn::validate_unnormalised`] (ids in range and in
/// topological order, leaves in range, finite non-negative weights with one per child
/// and not all zero, completeness, decomposability, every node reachable, every
/// variable in the root's scope).
///
/// Weights need not add up to 1 here: a model file's weights are relative and
/// [`Model::from_json_named`] rescales each sum to total 1 (see [`normalise_weights`]).
pub fn check_template_spn(
    spn: &Spn,
    num_vars: usize,
    classes: usize,
) -> Result<(), TemplateSpnError> {
    if spn.num_vars() != num_vars {
        return Err(TemplateSpnError::VariableCount {
            found: spn.num_vars(),
            expected: num_vars,
        });
    }
    if let Some(var) = spn.classes.iter().position(|&c| c as usize != classes) {
        return Err(TemplateSpnError::ClassCount {
            var,
            found: spn.classes[var],
            expected: classes,
        });
    }
    spn.validate_unnormalised()?;
    Ok(())
}

/// Rescales every sum of `spn` whose weights do not add up to 1 within
/// [`WEIGHT_SUM_TOLERANCE`] so that they do; sums already within it are left bit for
/// bit. Weights are relative: `[2, 6]` means `[0.25, 0.75]`. Returns the number of
/// sums rescaled. Call on a checked SPN ([`check_template_spn`]): every sum then has
/// finite, non-negative weights that are not all zero. Weights whose sum is not a
/// normal number (it overflows, as `[1e308, 1e308]` does, or is subnormal) are first
/// divided by their largest, so any such weights keep their ratios.
pub fn normalise_weights(spn: &mut Spn) -> usize {
    let mut rescaled = 0;
    for node in &mut spn.nodes {
        if let Node::Sum { weights, .. } = node {
            let mut total: f64 = weights.iter().sum();
            let largest = weights.iter().copied().fold(0.0, f64::max);
            if !total.is_normal() && largest > 0.0 {
                for w in weights.iter_mut() {
                    *w /= largest;
                }
                total = weights.iter().sum();
            }
            if total > 0.0 && (total - 1.0).abs() > WEIGHT_SUM_TOLERANCE {
                for w in weights.iter_mut() {
                    *w /= total;
                }
                rescaled += 1;
            }
        }
    }
    rescaled
}

impl Model {
    /// Checks everything the file format and every consumer rely on: classes, one
    /// valid template per SPN (unique names, edges in range, connected), and each
    /// template SPN by [`check_template_spn`]. Errors name `source_name`, the
    /// template and the SPN node.
    pub fn check(&self, source_name: &str) -> Result<(), ModelFileError> {
        let invalid = |message: String| ModelFileError::Invalid {
            source_name: source_name.to_string(),
            message,
        };
        if self.family != ModelFamily::Graphspn {
            return Err(invalid(format!(
                "a GraphSPN model must say \"family\": \"graphspn\", this one says {:?}",
                self.family.name()
            )));
        }
        if self.classes.is_empty() {
            return Err(invalid("the model has no classes".into()));
        }
        if self.templates.is_empty() {
            return Err(invalid(
                "the model has no templates (a GraphSPN covers a map with template-shaped \
                 pieces; it needs at least the one-place template)"
                    .into(),
            ));
        }
        if self.spns.len() != self.templates.len() {
            return Err(invalid(format!(
                "{} templates but {} SPNs",
                self.templates.len(),
                self.spns.len()
            )));
        }
        for (i, t) in self.templates.iter().enumerate() {
            if self.templates[..i].iter().any(|o| o.name == t.name) {
                return Err(invalid(format!(
                    "template {i} is named {:?} like an earlier one",
                    t.name
                )));
            }
            match Template::custom(t.name.clone(), t.num_nodes, &t.edges) {
                Ok(c) if c.edges == t.edges => {}
                Ok(_) => {
                    return Err(invalid(format!(
                        "template {:?}: edges must be sorted (a, b) pairs with a < b",
                        t.name
                    )));
                }
                Err(e) => return Err(invalid(format!("template {i}: {e}"))),
            }
        }
        for (index, (t, spn)) in self.templates.iter().zip(&self.spns).enumerate() {
            check_template_spn(spn, t.num_nodes, self.classes.len()).map_err(|source| {
                ModelFileError::TemplateSpn {
                    source_name: source_name.to_string(),
                    template: t.name.clone(),
                    index,
                    source: Box::new(source),
                }
            })?;
        }
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

    /// Parses a model; `source_name` names the input in error messages. Rejects
    /// other format versions before looking at the rest, checks the model
    /// ([`Model::check`]), then rescales every sum whose weights do not add up to 1
    /// ([`normalise_weights`]): a model file's weights are relative.
    pub fn from_json_named(text: &str, source_name: &str) -> Result<Self, ModelFileError> {
        let probe: Probe = serde_json::from_str(text).map_err(|e| parse_error(source_name, e))?;
        let ok = matches!(&probe.format, Some(v) if v.as_u64() == Some(u64::from(MODEL_FORMAT)));
        if !ok {
            return Err(ModelFileError::UnsupportedFormat {
                source_name: source_name.to_string(),
                found: probe
                    .format
                    .map_or_else(|| "missing".to_string(), |v| v.to_string()),
                expected: MODEL_FORMAT,
            });
        }
        let family = family_of(text, source_name)?;
        if family != ModelFamily::Graphspn {
            return Err(ModelFileError::Invalid {
                source_name: source_name.to_string(),
                message: format!(
                    "this is a {} model, not a GraphSPN, where only a GraphSPN model is read",
                    family.name()
                ),
            });
        }
        let mut model: Model =
            serde_json::from_str(text).map_err(|e| parse_error(source_name, e))?;
        model.check(source_name)?;
        for spn in &mut model.spns {
            normalise_weights(spn);
        }
        Ok(model)
    }

    /// Parses a model from a string (errors name it `<string>`).
    pub fn from_json(text: &str) -> Result<Self, ModelFileError> {
        Self::from_json_named(text, "<string>")
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

    /// Reads a model from `path`.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ModelFileError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| ModelFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json_named(&text, &path.display().to_string())
    }

    /// The training settings stored in [`Model::settings`].
    pub fn training_settings(&self) -> Result<TrainingSettings, serde_json::Error> {
        TrainingSettings::from_value(&self.settings)
    }
}
