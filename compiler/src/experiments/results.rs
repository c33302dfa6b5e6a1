//! What a run measured, as written to results.json ([`Reproduction`]): one
//! [`GraphResult`] per test graph and [`Experiment`], the facts of each test building
//! ([`BuildingInfo`]), and the validation, novelty, ceiling and evidence statistics.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::ceiling::CeilingRow;
use super::grid::ValidationSample;
use super::models::Scores;
use super::novelty::{NoveltyResult, NoveltySet};
use super::settings::ModelSettings;
use super::validate::Validation;
use crate::noise::MeanStd;

/// The two inference experiments.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Experiment {
    /// Every place has evidence; accuracy over all places (Fig. 5).
    Classification,
    /// Placeholders get no evidence; accuracy over placeholders only (Table 2).
    Placeholders,
}

/// One test graph's result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct GraphResult {
    /// Test building.
    pub building: String,
    /// Map name.
    pub map: String,
    /// Noise level (1..6).
    pub level: u8,
    /// Evidence round.
    pub round: usize,
    /// Which experiment.
    pub experiment: Experiment,
    /// Places scored (all places, or the placeholders).
    pub scored: usize,
    /// Accuracy of the evidence's argmax alone (ties split evenly); NaN (`null` in
    /// JSON) when no place was scored.
    #[serde(deserialize_with = "crate::noise::nan_if_null")]
    pub evidence_only: f64,
    /// Accuracy per model, by model name (ties split evenly); NaN (`null`) when no
    /// place was scored.
    #[serde(deserialize_with = "super::models::scores_nan_if_null")]
    pub accuracy: Scores<f64>,
    /// Whether loopy BP converged, by MRF name ([`MRF_MODELS`](super::models::MRF_MODELS)).
    pub bp_converged: BTreeMap<String, bool>,
}

/// Settings taken from a saved validation (`--settings FILE`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct GivenSettings {
    /// The validation.json they were read from, as given.
    pub file: String,
    /// The file's entry used for every test set (`evaluate --settings-of`), if one
    /// entry served them all.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub entry: Option<String>,
    /// The sample the file's validation scored candidates on; `None` for a file
    /// written before validation.json recorded it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample: Option<ValidationSample>,
    /// The file's validation records of the entries used (what was searched and
    /// chosen); empty when the file holds none.
    #[serde(default)]
    pub validation: Vec<Validation>,
}

/// One novelty set's figure per model (the area under the ROC curve, or the
/// within-map ranking).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SetScores {
    /// Which novelty labellings.
    pub set: NoveltySet,
    /// The figure per model, by model name.
    pub scores: Scores<f64>,
}

/// The figure of `set` for model `k`, NaN when the set was not scored.
pub(crate) fn set_score(v: &[SetScores], set: NoveltySet, k: usize) -> f64 {
    v.iter()
        .find(|s| s.set == set)
        .map_or(f64::NAN, |s| s.scores[k])
}

/// Table 1 statistics of one noise level (paper Table 1), over the places of the
/// evidence simulated on the test maps' ground truth.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Table1Row {
    /// Noise level (1..6).
    pub level: u8,
    /// Over places with correct evidence: the true class's value minus the highest
    /// other one.
    pub d_groundtruth: MeanStd,
    /// Over places with wrong evidence: the highest value minus the true class's.
    pub d_incorrect: MeanStd,
}

/// Per-building facts.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BuildingInfo {
    /// Test building.
    pub building: String,
    /// Training buildings.
    pub trained_on: Vec<String>,
    /// Test maps chosen (names, sorted).
    pub test_maps: Vec<String>,
    /// Seconds spent training GraphSPN.
    pub train_seconds: f64,
    /// Seconds spent training the tree mixture (noise-aware fit included).
    #[serde(default)]
    pub train_seconds_trees: f64,
    /// The settings used (chosen by validation on the training buildings).
    pub settings: ModelSettings,
}

/// Everything a run measured (written as results.json).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Reproduction {
    /// Master seed.
    pub seed: u64,
    /// Whether the paper's effective noise (wrong class drawn among all classes) was used.
    pub paper_noise: bool,
    /// The validation behind every building's settings (empty when settings were given).
    pub validation: Vec<Validation>,
    /// Per building.
    pub buildings: Vec<BuildingInfo>,
    /// Per test graph.
    pub graphs: Vec<GraphResult>,
    /// Novelty experiment.
    pub novelty: Vec<NoveltyResult>,
    /// Per novelty set: the area under the ROC curve per model
    /// ([`MODELS`](super::models::MODELS) order), pooled over maps and buildings (empty
    /// when novelty was not run).
    pub auc: Vec<SetScores>,
    /// Per novelty set, the within-map ranking: per model, the share of (novel,
    /// non-novel) labelling pairs of the same map that the model ranks correctly
    /// (ties ½), averaged over maps.
    pub within_map: Vec<SetScores>,
    /// Per test building: how well an oracle knowing every explored place's true class
    /// labels the placeholders from their neighbourhood ([`super::ceiling`]).
    #[serde(default)]
    pub ceiling: Vec<CeilingRow>,
    /// Table 1 statistics of the evidence simulated on the test maps, per level.
    pub table1: Vec<Table1Row>,
    /// Wall-clock seconds of the whole run (filled by the caller).
    pub seconds: f64,
    /// Where the settings came from when they were given (`--settings`, filled by the
    /// caller); `None` when this run validated them (or a library caller gave them
    /// without saying).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub given_settings: Option<GivenSettings>,
    /// For an evaluation of a user's map sets (`graphspn evaluate`, filled by the
    /// caller): which set is which. `None` for a reproduction on the COLD buildings;
    /// the report then compares with the paper.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub evaluation: Option<super::sets::Evaluation>,
}
