//! The settings of every compared model (what validation chooses and
//! `graphspn validate` saves): GraphSPN's, each tuned MRF's and the tree mixture's.
//!
//! Read from a file (`--settings`), unknown fields are errors, and
//! [`ModelSettings::check`] tests every numeric setting against the domain documented
//! on its field before any work ([`crate::domain`]).

use serde::{Deserialize, Serialize};

use crate::decompose::{DecompositionParams, DecompositionStrategy, MAX_CANDIDATES};
use crate::domain::{self, DomainError};
use crate::learn::TrainingSettings;
use crate::mrf::{BpOptions, CooccurrenceParams, Schedule};
use crate::spn::Mixing;
use crate::treemix::TreeTraining;

/// Largest evidence exponent of GraphSPN and the MRFs (rows are raised to it).
pub const MAX_ROW_EXPONENT: f64 = 16.0;

/// Settings of one MRF baseline.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MrfSetting {
    /// How potentials are made from the training counts.
    pub potentials: CooccurrenceParams,
    /// Each evidence row is raised to this power and renormalised before inference
    /// (finite, in (0, [`MAX_ROW_EXPONENT`]]).
    pub evidence_exponent: f64,
    /// Loopy BP options.
    pub bp: BpOptions,
}

/// The evidence exponent of a GraphSPN or MRF setting: finite, in `(0, MAX_ROW_EXPONENT]`.
fn evidence_exponent_in_domain(x: f64) -> Result<(), DomainError> {
    domain::left_open("evidence_exponent", x, 0.0, MAX_ROW_EXPONENT)
}

impl MrfSetting {
    /// Every numeric setting against its documented domain.
    pub fn check(&self) -> Result<(), DomainError> {
        self.potentials.check().map_err(|e| e.under("potentials"))?;
        evidence_exponent_in_domain(self.evidence_exponent)?;
        self.bp.check().map_err(|e| e.under("bp"))
    }

    /// The paper-style MRF: raw joint frequencies, coupling 1, raw evidence.
    pub fn paper(bp: BpOptions) -> Self {
        MrfSetting {
            potentials: CooccurrenceParams::default(),
            evidence_exponent: 1.0,
            bp,
        }
    }

    /// The BP schedule, e.g. `sequential` or `flooding d=0.5`.
    fn bp_label(&self) -> String {
        let schedule = match self.bp.schedule {
            Schedule::Sequential => "sequential",
            Schedule::Parallel => "flooding",
        };
        if self.bp.damping > 0.0 {
            format!("{schedule} d={}", self.bp.damping)
        } else {
            schedule.to_string()
        }
    }

    /// The setting as `(option, value)` pairs: potentials, coupling, evidence, BP.
    pub fn options(&self) -> Vec<(String, String)> {
        vec![
            (
                "potentials".into(),
                self.potentials.normalisation.name().into(),
            ),
            ("coupling".into(), self.potentials.coupling.to_string()),
            (
                "evidence exponent".into(),
                self.evidence_exponent.to_string(),
            ),
            ("BP".into(), self.bp_label()),
        ]
    }

    /// Short description, e.g. `normalised^0.3, ev^1, sequential`.
    pub fn label(&self) -> String {
        format!(
            "{}^{}, ev^{}, {}",
            self.potentials.normalisation.name(),
            self.potentials.coupling,
            self.evidence_exponent,
            self.bp_label()
        )
    }
}

/// Which decompositions an instance GraphSPN mixes: how they are drawn, how many
/// are kept and of how many candidates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DecompositionChoice {
    /// How candidates are drawn and ranked.
    pub strategy: DecompositionStrategy,
    /// Decompositions kept (the instance's D; 1 to
    /// [`MAX_DECOMPOSITIONS`](crate::decompose::MAX_DECOMPOSITIONS)).
    pub count: usize,
    /// Candidates drawn (`count` to [`MAX_CANDIDATES`]).
    pub candidates: usize,
}

impl Default for DecompositionChoice {
    /// The paper's: the best 5 of 15 random partitions.
    fn default() -> Self {
        DecompositionChoice {
            strategy: DecompositionStrategy::Paper,
            count: 5,
            candidates: 15,
        }
    }
}

impl DecompositionChoice {
    /// Every count against its documented domain.
    pub fn check(&self) -> Result<(), DomainError> {
        domain::decompositions("count", self.count)?;
        domain::count(
            "candidates",
            self.candidates as u64,
            self.count as u64,
            MAX_CANDIDATES as u64,
        )
    }

    /// `strategy`, `count` of `candidates`.
    pub fn new(strategy: DecompositionStrategy, count: usize, candidates: usize) -> Self {
        DecompositionChoice {
            strategy,
            count,
            candidates,
        }
    }

    /// The parameters of [`crate::decompose::decompose_best`] with `seed`.
    pub fn params(&self, seed: u64) -> DecompositionParams {
        DecompositionParams {
            count: self.count,
            candidates: self.candidates,
            seed,
            strategy: self.strategy,
        }
    }

    /// Short description, e.g. `cover 20/60`.
    pub fn label(&self) -> String {
        format!(
            "{} {}/{}",
            self.strategy.name(),
            self.count,
            self.candidates
        )
    }
}

/// Settings of GraphSPN.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraphSpnSetting {
    /// Name of the training variant (template structure).
    pub variant: String,
    /// Training settings (the seed is replaced per building); `training.temperature`
    /// is the template temperature.
    pub training: TrainingSettings,
    /// Each evidence row is raised to this power and renormalised before inference
    /// (finite, in (0, [`MAX_ROW_EXPONENT`]]).
    pub evidence_exponent: f64,
    /// The decompositions of each test map's instance.
    #[serde(default)]
    pub decompositions: DecompositionChoice,
    /// How the decompositions' marginals are combined.
    #[serde(default)]
    pub mixing: Mixing,
    /// Class-prior correction β: evidence rows are multiplied by `prior^-β` (the
    /// training maps' class shares; see `graphspn_rows` in `reproduce.rs`). 0 = none,
    /// 1 = divided by the prior entirely (finite, in [0, 1]).
    #[serde(default)]
    pub prior_correction: f64,
}

impl GraphSpnSetting {
    /// Every numeric setting against its documented domain.
    pub fn check(&self) -> Result<(), DomainError> {
        self.training.check().map_err(|e| e.under("training"))?;
        evidence_exponent_in_domain(self.evidence_exponent)?;
        self.decompositions
            .check()
            .map_err(|e| e.under("decompositions"))?;
        domain::closed("prior_correction", self.prior_correction, 0.0, 1.0)
    }

    /// The paper's GraphSPN: default training (our symmetric Star), raw evidence,
    /// the best 5 of 15 decompositions, the exact mixture's marginals.
    pub fn paper() -> Self {
        GraphSpnSetting {
            variant: "most_images".into(),
            training: TrainingSettings::default(),
            evidence_exponent: 1.0,
            decompositions: DecompositionChoice::default(),
            mixing: Mixing::Posterior,
            prior_correction: 0.0,
        }
    }

    /// The setting as `(option, value)` pairs: structure, temperature, evidence
    /// exponent, decompositions, mixing.
    pub fn options(&self) -> Vec<(String, String)> {
        vec![
            ("structure".into(), self.variant.clone()),
            ("temperature".into(), self.training.temperature.to_string()),
            (
                "evidence exponent".into(),
                self.evidence_exponent.to_string(),
            ),
            ("prior correction".into(), self.prior_correction.to_string()),
            ("decompositions".into(), self.decompositions.label()),
            ("mixing".into(), self.mixing.name().into()),
        ]
    }

    /// The training settings that differ from the defaults (e.g. set by `reproduce
    /// --training`), as `path = value` in JSON terms, e.g. `["em = \"soft\"",
    /// "structure.sums = 3"]`; the seed (replaced per building), the temperature and
    /// the structure's split choice (both in [`label`](Self::label)) are left out.
    pub fn training_changes(&self) -> Vec<String> {
        let mut base = TrainingSettings {
            seed: self.training.seed,
            temperature: self.training.temperature,
            ..TrainingSettings::default()
        };
        base.structure.split_choice = self.training.structure.split_choice;
        let mut changes = Vec::new();
        json_changes(
            "",
            &base.to_value(),
            &self.training.to_value(),
            &mut changes,
        );
        changes
    }

    /// Short description, e.g. `most_images, τ=0.8, ev^2, β=0.25, cover 20/60,
    /// average`, followed by `; training: …` with the
    /// [`training_changes`](Self::training_changes) when there are any.
    pub fn label(&self) -> String {
        let mut label = format!(
            "{}, τ={}, ev^{}, β={}, {}, {}",
            self.variant,
            self.training.temperature,
            self.evidence_exponent,
            self.prior_correction,
            self.decompositions.label(),
            self.mixing.name()
        );
        let changes = self.training_changes();
        if !changes.is_empty() {
            label += "; training: ";
            label += &changes.join(", ");
        }
        label
    }
}

/// Appends to `out` every leaf of `new` that differs from `old`, as `path = value`
/// (objects are followed key by key; paths are dotted).
fn json_changes(
    path: &str,
    old: &serde_json::Value,
    new: &serde_json::Value,
    out: &mut Vec<String>,
) {
    match (old, new) {
        (serde_json::Value::Object(o), serde_json::Value::Object(n)) => {
            for (k, v) in n {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                json_changes(&p, o.get(k).unwrap_or(&serde_json::Value::Null), v, out);
            }
        }
        _ if old != new => out.push(format!("{path} = {new}")),
        _ => {}
    }
}

/// The settings of every model for one test building.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSettings {
    /// GraphSPN.
    pub graphspn: GraphSpnSetting,
    /// The tuned MRF-2.
    pub mrf2: MrfSetting,
    /// The tuned MRF-3.
    pub mrf3: MrfSetting,
    /// The tree mixture (its training settings; the fit's seed is replaced per
    /// building).
    pub trees: TreeTraining,
}

impl ModelSettings {
    /// Every model's settings against their documented domains (the one check:
    /// experiments and the command line call it on settings from a file). Errors name
    /// the setting by its JSON path, e.g. `graphspn.prior_correction`.
    pub fn check(&self) -> Result<(), DomainError> {
        self.graphspn.check().map_err(|e| e.under("graphspn"))?;
        self.mrf2.check().map_err(|e| e.under("mrf2"))?;
        self.mrf3.check().map_err(|e| e.under("mrf3"))?;
        self.trees.check().map_err(|e| e.under("trees"))
    }
}

#[cfg(test)]
mod tests {
    use super::GraphSpnSetting;
    use crate::learn::SplitChoice;

    /// A training setting changed from its default (as `reproduce --training` does)
    /// shows in the label that REPORT.md prints; what the label already says (split,
    /// temperature) and the per-building seed do not.
    #[test]
    fn changed_training_settings_show_in_the_label() {
        let mut s = GraphSpnSetting::paper();
        s.training.seed = 17;
        s.training.temperature = 0.8;
        s.training.structure.split_choice = SplitChoice::FewestImages;
        assert!(s.training_changes().is_empty());
        assert!(!s.label().contains("training"), "{}", s.label());
        s.training.epochs = 3;
        s.training.structure.sums = 4;
        assert_eq!(s.training_changes(), ["epochs = 3", "structure.sums = 4"]);
        assert!(
            s.label()
                .ends_with("; training: epochs = 3, structure.sums = 4"),
            "{}",
            s.label()
        );
    }
}
