//! Training settings, stored in [`super::Model::settings`].

use serde::{Deserialize, Serialize};

use super::structure::DenseParams;

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
    /// Random decompositions of each training map per template (authors: 10).
    pub decompositions_per_map: usize,
    /// Also add each component's sample with its nodes reversed, as the authors
    /// did (redundant when `symmetry` is `augment` or `tied`).
    pub add_reversed: bool,
    /// Dense structure parameters.
    pub structure: DenseParams,
    /// EM epochs (authors: 10).
    pub epochs: usize,
    /// Additive smoothing (pseudo-count per sum edge) in the first epoch (authors: 30).
    pub smoothing_start: f64,
    /// Additive smoothing in the last epoch; it decays linearly in between (authors: ~5).
    pub smoothing_end: f64,
    /// Distinct samples per work chunk of the E-step (authors: 2,000). Weights are
    /// updated once per epoch (full-batch EM), so this affects speed, not results.
    pub batch_size: usize,
    /// Hard or soft EM.
    pub em: EmKind,
    /// After training, remove sum edges whose weight is below this (0 = off).
    pub prune_threshold: f64,
    /// How template symmetries are handled.
    pub symmetry: Symmetry,
    /// Master seed: structure, initial weights and decompositions derive from it.
    pub seed: u64,
    /// Temperature applied to every template SPN after training (sum weights
    /// raised to this power and renormalised; see [`super::temperature`]). 1 = none
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

    /// From a JSON value (missing fields take their defaults; unknown fields are an error).
    pub fn from_value(v: &serde_json::Value) -> Result<Self, serde_json::Error> {
        TrainingSettings::deserialize(v)
    }
}
