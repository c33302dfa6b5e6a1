//! The model file: classes, templates and one learned SPN per template.

use serde::{Deserialize, Serialize};

use crate::map::ClassSet;
use crate::model_file::ModelFamily;
use crate::spn::Spn;
use crate::template::Template;

/// Version of the model JSON format written by this crate.
pub const MODEL_FORMAT: u32 = 1;

/// A learned GraphSPN: one template SPN per sub-graph template.
///
/// `spns[k]` models the classes of the nodes of `templates[k]`: variable `i` of the
/// SPN is template node `i` (canonical order) and every variable has
/// `classes.len()` classes. Templates are listed largest first (the order the
/// decomposition tries them in).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Model {
    /// Format version, [`MODEL_FORMAT`].
    pub format: u32,
    /// Always [`ModelFamily::Graphspn`] (absent in files written before other
    /// families existed).
    #[serde(default)]
    pub family: ModelFamily,
    /// The class names.
    pub classes: ClassSet,
    /// The sub-graph templates, largest first.
    pub templates: Vec<Template>,
    /// One SPN per template, same order.
    pub spns: Vec<Spn>,
    /// How the model was trained (free-form, for provenance).
    pub settings: serde_json::Value,
    /// Names of the maps the model was trained on.
    pub trained_on: Vec<String>,
}
