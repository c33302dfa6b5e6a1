//! The model families a model file can hold ([`ModelFamily`], kept with what both
//! families' files share in [`crate::model_file`]), and the one loader that reads
//! either ([`AnyModel`]).
//!
//! - [`ModelFamily::Graphspn`]: the paper's GraphSPN ([`crate::learn::Model`]: template
//!   SPNs mixed over decompositions of the map);
//! - [`ModelFamily::TreeMixture`]: a mixture of spanning trees of the map with one
//!   shared pairwise potential ([`crate::treemix::TreeMixture`]).
//!
//! Every model file carries a `"family"` field; a file without one is a GraphSPN
//! model (files written before tree mixtures existed).

use std::path::Path;

use crate::learn::model::Model;
use crate::map::ClassSet;
pub use crate::model_file::{ModelFamily, family_of};
use crate::model_file::{ModelFileError, read};
use crate::treemix::TreeMixture;

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
