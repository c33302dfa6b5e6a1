//! What the model files of both families share: the `"family"` field that says which
//! family a file holds ([`family_of`]), the one error type of both readers
//! ([`ModelFileError`]), and the parse error at a position that all of them report the
//! same way.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::spn::{NodeId, SpnError};

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
        /// [`crate::learn::model::MODEL_FORMAT`].
        expected: u32,
    },
    /// A template SPN is malformed (see [`crate::learn::check_template_spn`]).
    #[error("{source_name}: template {template:?} (SPN {index}): {source}")]
    TemplateSpn {
        /// File name (or `<string>`).
        source_name: String,
        /// The template's name.
        template: String,
        /// Position of the template (and its SPN) in the model.
        index: usize,
        /// What is wrong, naming the node (boxed: keeps the error small).
        source: Box<TemplateSpnError>,
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

/// A model file that is not valid JSON of the expected shape, at its position.
pub(crate) fn parse_error(source_name: &str, e: serde_json::Error) -> ModelFileError {
    ModelFileError::Parse {
        source_name: source_name.to_string(),
        line: e.line(),
        column: e.column(),
        message: crate::json_error::json_message(&e),
    }
}

/// What is wrong with one template SPN of a model ([`crate::learn::check_template_spn`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TemplateSpnError {
    /// The SPN's variables do not match the template's nodes.
    #[error("the SPN has {found} variables, the template has {expected} nodes")]
    VariableCount {
        /// Variables of the SPN.
        found: usize,
        /// Nodes of the template.
        expected: usize,
    },
    /// A variable has another number of classes than the model.
    #[error("variable {var} has {found} classes, the model has {expected}")]
    ClassCount {
        /// The variable.
        var: usize,
        /// Its classes.
        found: u32,
        /// Classes of the model.
        expected: usize,
    },
    /// A structural error: ids, order, weights, completeness, decomposability.
    #[error(transparent)]
    Structure(#[from] SpnError),
}

impl TemplateSpnError {
    /// The SPN node the error is about, when there is one.
    pub fn node(&self) -> Option<NodeId> {
        match self {
            TemplateSpnError::Structure(e) => e.node(),
            _ => None,
        }
    }
}

/// Which model family a model file holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ModelFamily {
    /// The paper's GraphSPN (template SPNs over decompositions).
    #[default]
    Graphspn,
    /// A mixture of edge-covering spanning trees with a shared pairwise potential.
    TreeMixture,
}

impl ModelFamily {
    /// Both families, in a fixed order.
    pub const ALL: [ModelFamily; 2] = [ModelFamily::Graphspn, ModelFamily::TreeMixture];

    /// The name used in model files and on the command line (`graphspn`,
    /// `tree_mixture`).
    pub fn name(self) -> &'static str {
        match self {
            ModelFamily::Graphspn => "graphspn",
            ModelFamily::TreeMixture => "tree_mixture",
        }
    }

    /// The family called `name` ([`ModelFamily::name`]; `tree-mixture` is accepted too).
    pub fn from_name(name: &str) -> Option<Self> {
        let name = name.replace('-', "_");
        Self::ALL.into_iter().find(|f| f.name() == name)
    }
}

#[derive(Deserialize)]
struct FamilyProbe {
    family: Option<serde_json::Value>,
}

/// The family named by a model file's text (`Graphspn` when the field is absent).
/// Errors name `source_name` and say what is wrong; the rest of the file is not
/// looked at.
pub fn family_of(text: &str, source_name: &str) -> Result<ModelFamily, ModelFileError> {
    let probe: FamilyProbe =
        serde_json::from_str(text).map_err(|e| crate::model_file::parse_error(source_name, e))?;
    match probe.family {
        None => Ok(ModelFamily::Graphspn),
        Some(v) => v
            .as_str()
            .and_then(ModelFamily::from_name)
            .ok_or_else(|| ModelFileError::Invalid {
                source_name: source_name.to_string(),
                message: format!(
                    "unknown model family {v}; this version of graphspn reads \"graphspn\" and \"tree_mixture\""
                ),
            }),
    }
}

/// The text of a model file.
pub(crate) fn read(path: &Path) -> Result<String, ModelFileError> {
    std::fs::read_to_string(path).map_err(|source| ModelFileError::Io {
        path: PathBuf::from(path),
        source,
    })
}
