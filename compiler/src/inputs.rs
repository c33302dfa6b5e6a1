//! The one check that a GraphSPN model, a map and decompositions fit together. The
//! instance GraphSPN (explicit and component by component) and the code generator
//! both run it, so an input that one of them refuses the other refuses too, with the
//! same message. (A tree mixture's counterpart is [`crate::treemix::check_inputs`].)

use thiserror::Error;

use crate::decompose::{DecomposeError, Decomposition};
use crate::learn::{Model, check_template_spn};
use crate::map::{MapFitError, TopoMap};

/// Why a model, a map and decompositions do not fit together.
#[derive(Debug, Error)]
pub enum InputsError {
    /// The model cannot label the map (other classes, or no places).
    #[error(transparent)]
    Map(#[from] MapFitError),
    /// The model has a different number of templates and SPNs.
    #[error("the model has {templates} templates but {spns} SPNs")]
    ModelShape {
        /// Number of templates.
        templates: usize,
        /// Number of SPNs.
        spns: usize,
    },
    /// A template's SPN is malformed or does not fit the template.
    #[error("template {template} ({name:?}){}: {what}", node.map_or(String::new(), |n| format!(", SPN node {n}")))]
    BadTemplateSpn {
        /// Template index.
        template: usize,
        /// Template name.
        name: String,
        /// The SPN node at fault, when one is.
        node: Option<u32>,
        /// What is wrong.
        what: String,
    },
    /// No decomposition was given.
    #[error("an instance needs at least one decomposition")]
    NoDecompositions,
    /// A decomposition is not a partition of the map into matches of the model's
    /// templates ([`Decomposition::validate`]).
    #[error("decomposition {decomposition}: {source}")]
    BadDecomposition {
        /// Decomposition index.
        decomposition: usize,
        /// What is wrong with it.
        source: DecomposeError,
    },
}

/// Checks that `map` can be labelled by `model`: the model's class names, in order,
/// and at least one place. The first part of [`check_inputs`], for commands that read
/// a map before they decompose it.
pub fn check_map(model: &Model, map: &TopoMap) -> Result<(), InputsError> {
    Ok(map.check_labellable(&model.classes)?)
}

/// Checks that `model`, `map` and `decompositions` fit together: the same class names,
/// one valid SPN per template ([`check_template_spn`]), a map with places, at least one
/// decomposition, and each decomposition a partition of the map's places into matches
/// of the model's templates.
pub fn check_inputs(
    model: &Model,
    map: &TopoMap,
    decompositions: &[Decomposition],
) -> Result<(), InputsError> {
    check_map(model, map)?;
    if model.templates.len() != model.spns.len() {
        return Err(InputsError::ModelShape {
            templates: model.templates.len(),
            spns: model.spns.len(),
        });
    }
    let c = model.classes.len();
    for (t, (tpl, spn)) in model.templates.iter().zip(&model.spns).enumerate() {
        check_template_spn(spn, tpl.num_nodes, c).map_err(|e| InputsError::BadTemplateSpn {
            template: t,
            name: tpl.name.clone(),
            node: e.node(),
            what: e.to_string(),
        })?;
    }
    if decompositions.is_empty() {
        return Err(InputsError::NoDecompositions);
    }
    for (d, dec) in decompositions.iter().enumerate() {
        dec.validate(map, &model.templates)
            .map_err(|source| InputsError::BadDecomposition {
                decomposition: d,
                source,
            })?;
    }
    Ok(())
}
