//! The model families a model file can hold, and the one loader that reads either.
//!
//! - [`ModelFamily::Graphspn`]: the paper's GraphSPN ([`crate::learn::Model`]: template
//!   SPNs mixed over decompositions of the map);
//! - [`ModelFamily::TreeMixture`]: a mixture of spanning trees of the map with one
//!   shared pairwise potential ([`crate::treemix::TreeMixture`]).
//!
//! Every model file carries a `"family"` field; a file without one is a GraphSPN
//! model (files written before tree mixtures existed).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::learn::{Model, ModelFileError};
use crate::map::ClassSet;
use crate::treemix::TreeMixture;

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
        serde_json::from_str(text).map_err(|e| crate::learn::file::parse_error(source_name, e))?;
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

/// A model of either family, as read from a model file.
#[derive(Clone, Debug, PartialEq)]
pub enum AnyModel {
    /// The paper's GraphSPN.
    Graphspn(Model),
    /// A tree mixture.
    TreeMixture(TreeMixture),
}

impl AnyModel {
    /// Parses a model file of either family (the `family` field decides; absent =
    /// GraphSPN) with that family's checks; errors name `source_name`.
    pub fn from_json_named(text: &str, source_name: &str) -> Result<Self, ModelFileError> {
        Ok(match family_of(text, source_name)? {
            ModelFamily::Graphspn => AnyModel::Graphspn(Model::from_json_named(text, source_name)?),
            ModelFamily::TreeMixture => {
                AnyModel::TreeMixture(TreeMixture::from_json_named(text, source_name)?)
            }
        })
    }

    /// Reads a model file of either family.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ModelFileError> {
        let path = path.as_ref();
        let text = read(path)?;
        Self::from_json_named(&text, &path.display().to_string())
    }

    /// The family of the model.
    pub fn family(&self) -> ModelFamily {
        match self {
            AnyModel::Graphspn(_) => ModelFamily::Graphspn,
            AnyModel::TreeMixture(_) => ModelFamily::TreeMixture,
        }
    }

    /// The model's classes.
    pub fn classes(&self) -> &ClassSet {
        match self {
            AnyModel::Graphspn(m) => &m.classes,
            AnyModel::TreeMixture(m) => &m.classes,
        }
    }

    /// Names of the maps the model was trained on.
    pub fn trained_on(&self) -> &[String] {
        match self {
            AnyModel::Graphspn(m) => &m.trained_on,
            AnyModel::TreeMixture(m) => &m.trained_on,
        }
    }

    /// Writes the model to `path` as JSON (deterministic, pretty-printed).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), ModelFileError> {
        match self {
            AnyModel::Graphspn(m) => m.save(path),
            AnyModel::TreeMixture(m) => m.save(path),
        }
    }
}

/// The text of a model file.
pub(crate) fn read(path: &Path) -> Result<String, ModelFileError> {
    std::fs::read_to_string(path).map_err(|source| ModelFileError::Io {
        path: PathBuf::from(path),
        source,
    })
}
