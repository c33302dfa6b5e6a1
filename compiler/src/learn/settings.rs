//! Training settings, stored in [`super::Model::settings`], and the types every
//! learning algorithm shares (the dense structure's parameters, `TrainError`).
//!
//! This module is the bottom of `learn`: it imports no other module of it, and the
//! algorithms (`structure`, `symmetry`, `train`, `from_maps`) import it.

use serde::{Deserialize, Serialize};

use crate::domain::{self, DomainError, End};

#[cfg(feature = "host")]
use crate::map::ClassId;
#[cfg(feature = "host")]
use crate::spn::NodeId;

/// How sum weights are re-estimated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum EmKind {
    /// Hard (Viterbi) EM: count the sum children on each sample's max-product
    /// (MPE) path. The authors' choice.
    #[default]
    Hard,
    /// Soft EM: expected counts from an upward and a downward pass (log space).
    Soft,
}

/// How training respects the template's automorphisms.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Symmetry {
    /// Train on the samples as given.
    None,
    /// Train on every sample under every automorphism (the paper's structure and
    /// size; exactly symmetric for full tables, but NOT for the Star: on
    /// COLD-like data its `log p` changes by 0.95 nats on average (up to 6.6)
    /// when the four leaves are permuted).
    Augment,
    /// Augment, build a structure closed under the automorphisms and tie the
    /// weights along their orbits: exactly symmetric (to ~1e-15), and a slightly
    /// better fit, but larger (Star: 8,000 or 3,750 weights, see `SplitChoice`, instead of 1,250 with 10
    /// classes; Pair and Three unchanged). The default: the instance model must
    /// not depend on the arbitrary order a match lists the Star's leaves in.
    #[default]
    Tied,
}

/// Everything that determines a trained model besides the data. Defaults are the
/// authors' settings (from their published code) plus our symmetry fix
/// ([`Symmetry::Tied`]; set [`Symmetry::Augment`] for the paper's 1,250-weight
/// Star).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainingSettings {
    /// Random decompositions of each training map per template (authors: 10; 1 to
    /// 1,000).
    pub decompositions_per_map: usize,
    /// Also add each component's sample with its nodes reversed, as the authors
    /// did (redundant when `symmetry` is `augment` or `tied`).
    pub add_reversed: bool,
    /// Dense structure parameters.
    pub structure: DenseParams,
    /// EM epochs (authors: 10; 1 to 10,000).
    pub epochs: usize,
    /// Additive smoothing (pseudo-count per sum edge) in the first epoch (authors: 30;
    /// finite, in (0, 1e6]: it keeps every weight positive).
    pub smoothing_start: f64,
    /// Additive smoothing in the last epoch; it decays linearly in between (authors: ~5;
    /// same domain).
    pub smoothing_end: f64,
    /// Distinct samples per work chunk of the E-step (authors: 2,000; at least 1).
    /// Weights are updated once per epoch (full-batch EM), so this affects speed, not
    /// results.
    pub batch_size: usize,
    /// Hard or soft EM.
    pub em: EmKind,
    /// After training, remove sum edges whose weight is below this (0 = off; in [0, 1)).
    pub prune_threshold: f64,
    /// How template symmetries are handled.
    pub symmetry: Symmetry,
    /// Master seed: structure, initial weights and decompositions derive from it.
    pub seed: u64,
    /// Temperature applied to every template SPN after training (sum weights
    /// raised to this power and renormalised; see [`super::temperature`]; in
    /// (0, [`MAX_TEMPERATURE`](super::temperature::MAX_TEMPERATURE)]). 1 = none
    /// (and then not written, so model files of untempered models are unchanged).
    #[serde(skip_serializing_if = "is_one")]
    pub temperature: f64,
}

fn is_one(x: &f64) -> bool {
    *x == 1.0
}

impl Default for TrainingSettings {
    fn default() -> Self {
        TrainingSettings {
            decompositions_per_map: 10,
            add_reversed: false,
            structure: DenseParams::default(),
            epochs: 10,
            smoothing_start: 30.0,
            smoothing_end: 5.0,
            batch_size: 2000,
            em: EmKind::Hard,
            prune_threshold: 0.0,
            symmetry: Symmetry::Tied,
            seed: 0,
            temperature: 1.0,
        }
    }
}

impl TrainingSettings {
    /// Smoothing of epoch `e` (0-based): linear from `smoothing_start` to
    /// `smoothing_end` over `epochs` epochs.
    pub fn smoothing(&self, e: usize) -> f64 {
        if self.epochs <= 1 {
            return self.smoothing_start;
        }
        let t = e.min(self.epochs - 1) as f64 / (self.epochs - 1) as f64;
        self.smoothing_start + (self.smoothing_end - self.smoothing_start) * t
    }

    /// As a JSON value, for [`super::Model::settings`].
    pub fn to_value(&self) -> serde_json::Value {
        // Serialising a plain struct of numbers, bools and enums cannot fail.
        serde_json::to_value(self).unwrap_or(serde_json::Value::Null)
    }

    /// From a JSON value (missing fields take their defaults; unknown fields are an
    /// error). [`TrainingSettings::check`] checks the values.
    pub fn from_value(v: &serde_json::Value) -> Result<Self, serde_json::Error> {
        TrainingSettings::deserialize(v)
    }

    /// Every numeric setting against the domain its documentation states (the one
    /// check: training, the command line and settings files call it). Errors name the
    /// setting by its JSON path.
    pub fn check(&self) -> Result<(), DomainError> {
        domain::count(
            "decompositions_per_map",
            self.decompositions_per_map as u64,
            1,
            1000,
        )?;
        self.structure.check().map_err(|e| e.under("structure"))?;
        domain::count("epochs", self.epochs as u64, 1, 10_000)?;
        domain::left_open("smoothing_start", self.smoothing_start, 0.0, 1e6)?;
        domain::left_open("smoothing_end", self.smoothing_end, 0.0, 1e6)?;
        domain::count("batch_size", self.batch_size as u64, 1, u64::MAX)?;
        domain::real(
            "prune_threshold",
            self.prune_threshold,
            (0.0, End::Closed),
            (1.0, End::Open),
        )?;
        super::temperature::check_temperature(self.temperature).map_err(|e| DomainError {
            setting: "temperature".into(),
            value: e.0.to_string(),
            domain: e.domain(),
        })
    }
}

/// Parameters of the dense random structure.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DenseParams {
    /// Random splits per multi-variable region (authors: 1; 1 to 16).
    pub decompositions: usize,
    /// Subsets per split, at most the region size (authors: 3; 2 to 8).
    pub subsets: usize,
    /// Sums per non-root multi-variable region (authors: 5; 1 to 64); the root has one.
    pub sums: usize,
    /// Balanced subset sizes (sizes differ by at most one; authors: true).
    pub balanced: bool,
    /// Which random split a symmetric structure keeps (see [`SplitChoice`]);
    /// ignored by [`dense_structure`](super::structure::dense_structure).
    pub split_choice: SplitChoice,
}

/// How [`symmetric_dense_structure`](super::structure::symmetric_dense_structure) picks a region's split among
/// [`SPLIT_CANDIDATES`](super::structure::SPLIT_CANDIDATES) random draws before closing it under the template's
/// automorphisms. Among draws with equally many images the first one drawn is kept
/// (so under the identity alone both choices keep every region's first draw).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SplitChoice {
    /// The split with the fewest images under the group: the smallest closed
    /// structure (Star: `{P},{x,y},{z,w}`, 3 images, 3,750 weights with 10 classes).
    /// The pivot then shares no subset with a neighbour, so its dependence on
    /// the leaves is carried by the mixture only.
    FewestImages,
    /// The split with the most images: every way of grouping variables appears
    /// (Star: `{P,x},{y,z},{w}`, 12 images, 8,000 weights): the pivot gets a full
    /// joint table with each neighbour, at about twice the evaluation cost.
    /// The default. `graphspn validate` searches both per test building; with the
    /// other options validated too they score alike (86.0% vs 86.1% for the best
    /// setting of each, `docs/REPRODUCTION.md`).
    #[default]
    MostImages,
}

impl SplitChoice {
    /// Both choices, the default last.
    pub const ALL: [SplitChoice; 2] = [SplitChoice::FewestImages, SplitChoice::MostImages];

    /// The name in model files, reports and on the command line (`fewest_images`,
    /// `most_images`).
    pub fn name(self) -> &'static str {
        match self {
            SplitChoice::FewestImages => "fewest_images",
            SplitChoice::MostImages => "most_images",
        }
    }

    /// The choice named `name` ([`SplitChoice::name`]), if any.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == name)
    }
}

impl DenseParams {
    /// Every count against its documented domain.
    pub fn check(&self) -> Result<(), DomainError> {
        domain::count("decompositions", self.decompositions as u64, 1, 16)?;
        domain::count("subsets", self.subsets as u64, 2, 8)?;
        domain::count("sums", self.sums as u64, 1, 64)
    }
}

impl Default for DenseParams {
    fn default() -> Self {
        DenseParams {
            decompositions: 1,
            subsets: 3,
            sums: 5,
            balanced: true,
            split_choice: SplitChoice::MostImages,
        }
    }
}

/// Why training failed.
#[cfg(feature = "host")]
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TrainError {
    /// No samples.
    #[error("no training samples")]
    NoSamples,
    /// A sample has the wrong number of classes.
    #[error("sample {index} has {len} classes, the SPN has {num_vars} variables")]
    SampleLength {
        /// Index of the sample.
        index: usize,
        /// Its length.
        len: usize,
        /// Variables of the SPN.
        num_vars: usize,
    },
    /// A class is out of range.
    #[error(
        "sample {index}: class {class} of variable {var} is out of range (variable has {classes} classes)"
    )]
    ClassOutOfRange {
        /// Index of the sample.
        index: usize,
        /// Variable.
        var: usize,
        /// The class given.
        class: ClassId,
        /// Classes of the variable.
        classes: u32,
    },
    /// The SPN is not usable for training.
    #[error("invalid SPN for training: node {node}: {what}")]
    BadSpn {
        /// Offending node.
        node: NodeId,
        /// What is wrong.
        what: String,
    },
    /// A sample has probability zero under the SPN (e.g. after pruning).
    #[error("sample {index} {sample:?} has probability zero under the SPN")]
    ZeroProbability {
        /// Index of a sample with that tuple.
        index: usize,
        /// The tuple.
        sample: Vec<ClassId>,
    },
    /// Settings out of range.
    #[error("invalid training settings: {0}")]
    BadSettings(String),
    /// Tying information does not fit the SPN.
    #[error("edge orbits list {given} edges, the SPN has {actual} sum edges")]
    OrbitMismatch {
        /// Edges in the orbits.
        given: usize,
        /// Sum edges of the SPN.
        actual: usize,
    },
}
