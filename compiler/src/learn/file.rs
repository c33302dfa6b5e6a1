//! Reading and writing the model file (JSON, versioned, pretty-printed).
//!
//! Output is deterministic: struct fields in declaration order, map keys sorted
//! (serde_json's default map), floats in shortest round-trip form; parsing uses
//! serde_json's exact float parser (`float_roundtrip`), so every `f64` survives a
//! save/load cycle bit for bit.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::model::{MODEL_FORMAT, Model};
use super::settings::TrainingSettings;
use crate::spn::Node;

/// Why a model file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum ModelFileError {
    /// Reading or writing the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// Not valid JSON, or not a model.
    #[error("{source_name}:{line}:{column}: {message}")]
    Parse {
        /// File name (or `<string>`).
        source_name: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// The `format` field is missing or not one this version reads.
    #[error(
        "{source_name}: unsupported model format {found}; this version of graphspn reads format {expected} (re-train or convert the model)"
    )]
    UnsupportedFormat {
        /// File name (or `<string>`).
        source_name: String,
        /// The `format` value found (`missing` if absent).
        found: String,
        /// [`MODEL_FORMAT`].
        expected: u32,
    },
    /// The model is inconsistent or holds a value JSON cannot represent.
    #[error("{source_name}: {message}")]
    Invalid {
        /// File name (or `<string>`).
        source_name: String,
        /// What is wrong, naming the SPN and node.
        message: String,
    },
}

#[derive(Deserialize)]
struct Probe {
    format: Option<serde_json::Value>,
}

fn parse_error(source_name: &str, e: serde_json::Error) -> ModelFileError {
    ModelFileError::Parse {
        source_name: source_name.to_string(),
        line: e.line(),
        column: e.column(),
        message: e.to_string(),
    }
}

impl Model {
    /// Checks what the file format relies on: one SPN per template, each SPN's
    /// variable count equal to its template's node count and every variable with
    /// `classes.len()` classes, finite weights.
    pub fn check(&self, source_name: &str) -> Result<(), ModelFileError> {
        let invalid = |message: String| ModelFileError::Invalid {
            source_name: source_name.to_string(),
            message,
        };
        if self.spns.len() != self.templates.len() {
            return Err(invalid(format!(
                "{} templates but {} SPNs",
                self.templates.len(),
                self.spns.len()
            )));
        }
        for (t, spn) in self.templates.iter().zip(&self.spns) {
            if spn.num_vars() != t.num_nodes {
                return Err(invalid(format!(
                    "SPN of template {:?} has {} variables, the template has {} nodes",
                    t.name,
                    spn.num_vars(),
                    t.num_nodes
                )));
            }
            if let Some(v) = spn
                .classes
                .iter()
                .position(|&c| c as usize != self.classes.len())
            {
                return Err(invalid(format!(
                    "SPN of template {:?}: variable {v} has {} classes, the model has {}",
                    t.name,
                    spn.classes[v],
                    self.classes.len()
                )));
            }
            for (id, n) in spn.nodes.iter().enumerate() {
                if let Node::Sum { weights, .. } = n
                    && let Some(w) = weights.iter().find(|w| !w.is_finite() || **w < 0.0)
                {
                    return Err(invalid(format!(
                        "SPN of template {:?}, node {id}: weight {w} is not finite and ≥ 0",
                        t.name
                    )));
                }
            }
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
    /// other format versions before looking at the rest.
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
        let model: Model = serde_json::from_str(text).map_err(|e| parse_error(source_name, e))?;
        model.check(source_name)?;
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
