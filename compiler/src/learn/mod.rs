//! Template SPN structure generation, EM training and the model file.
//!
//! - [`structure`]: the dense random structure of the paper (and a symmetric
//!   variant), the uniform Singleton SPN;
//! - [`train`](mod@train): hard / soft EM on complete samples, pruning;
//! - [`symmetry`]: augmentation with template automorphisms and weight tying;
//! - [`settings`]: [`TrainingSettings`], stored in the model file;
//! - [`temperature`]: a temperature on the template SPNs (sum weights `w^τ`, renormalised);
//! - [`file`](mod@file): reading and writing [`Model`] files.

pub mod file;
#[cfg(feature = "host")]
pub mod from_maps;
pub mod model;
pub mod settings;
pub mod structure;
pub mod symmetry;
pub mod temperature;
#[cfg(feature = "host")]
pub mod train;

pub use file::{ModelFileError, TemplateSpnError, check_template_spn, normalise_weights};
#[cfg(feature = "host")]
pub use from_maps::{TemplateTraining, TrainModelError, template_samples, train_model};
pub use model::Model;
pub use settings::{EmKind, Symmetry, TrainingSettings};
pub use structure::{
    DenseParams, SplitChoice, dense_structure, symmetric_dense_structure, uniform_spn,
};
#[cfg(feature = "host")]
pub use symmetry::augment_with_automorphisms;
pub use symmetry::{EdgeOrbits, edge_orbits};
pub use temperature::{BadTemperature, check_temperature, temper_spn};
#[cfg(feature = "host")]
pub use train::{Progress, TrainError, TrainingReport, train, train_tied};

use crate::map::ClassId;
use crate::spn::Spn;

/// Why a template SPN could not be learned.
#[cfg(feature = "host")]
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LearnError {
    /// Building the structure failed.
    #[error(transparent)]
    Structure(#[from] structure::StructureError),
    /// The symmetric structure's orbits could not be computed.
    #[error(transparent)]
    Symmetry(#[from] symmetry::SymmetryError),
    /// Training failed.
    #[error(transparent)]
    Train(#[from] TrainError),
}

#[cfg(feature = "host")]
/// Learns one template SPN: a single variable gets [`uniform_spn`]; otherwise the
/// samples are augmented with `automorphisms` (unless `settings.symmetry` is
/// `none`), a dense structure is generated (symmetric and tied for
/// `Symmetry::Tied`) from `seed`, and trained with `settings`.
/// `automorphisms` are the template's (including the identity), each mapping
/// template node `v` to `perm[v]`.
pub fn learn_template_spn(
    num_vars: usize,
    num_classes: u32,
    automorphisms: &[Vec<usize>],
    samples: &[Vec<ClassId>],
    settings: &TrainingSettings,
    seed: u64,
    progress: Progress,
) -> Result<(Spn, Option<TrainingReport>), LearnError> {
    if num_vars == 1 {
        return Ok((uniform_spn(1, num_classes)?, None));
    }
    let augmented;
    let data: &[Vec<ClassId>] = if settings.symmetry == Symmetry::None || automorphisms.is_empty() {
        samples
    } else {
        augmented = augment_with_automorphisms(samples, automorphisms)?;
        &augmented
    };
    let (mut spn, orbits) = if settings.symmetry == Symmetry::Tied {
        let spn = symmetric_dense_structure(
            num_vars,
            num_classes,
            &settings.structure,
            automorphisms,
            seed,
        )?;
        let orbits = edge_orbits(&spn, automorphisms)?;
        (spn, orbits)
    } else {
        let spn = dense_structure(num_vars, num_classes, &settings.structure, seed)?;
        let edges = structure::num_weights(&spn);
        (spn, EdgeOrbits::trivial(edges))
    };
    let report = train_tied(&mut spn, data, settings, &orbits, progress)?;
    Ok((spn, Some(report)))
}
