//! Training a tree mixture from annotated maps: the pairwise potential from edge
//! co-occurrence counts (the MRF-2 baseline's counting, [`crate::mrf::Mrf2::train`]),
//! the unary potential from the training maps' class shares.

use serde::{Deserialize, Serialize};

use super::TreeMixError;
use super::fit::{FitGraph, FitOptions, fit_potentials};
use super::model::{MAX_EVIDENCE_EXPONENT, TreeMixture};
use super::trees::SpanningTrees;
use crate::domain::{self, DomainError};
use crate::learn::model::MODEL_FORMAT;
use crate::map::ClassId;
use crate::map::TopoMap;
use crate::map::stats::class_prior;
use crate::model_file::ModelFamily;
use crate::mrf::{CooccurrenceParams, Mrf2, Normalisation};
use crate::noise::{NoiseLevel, derive_seed, map_truth, simulate_map_evidence};
use crate::spn::Mixing;

/// How a tree mixture is trained; stored in the model file's `settings`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TreeTraining {
    /// The pairwise potential: edge co-occurrence counts (both orientations, plus a
    /// pseudo-count per cell) → potential form → raised to the coupling exponent.
    pub potentials: CooccurrenceParams,
    /// `ρ`: the unary potential is `prior^ρ`, the training maps' smoothed class shares
    /// ([`class_prior`]) to this power (0 = uniform; finite, in [-2, 2]).
    pub prior_exponent: f64,
    /// Evidence exponent `γ` (rows enter as `α^γ`; 1 to [`MAX_EVIDENCE_EXPONENT`]).
    pub evidence_exponent: u32,
    /// Spanning trees per map (1 to [`MAX_TREES`](super::MAX_TREES)).
    pub trees: usize,
    /// How the trees' marginals are combined.
    pub mixing: Mixing,
    /// Noise-aware fitting of the counted potentials (none: the counted ones).
    pub fit: Option<NoiseFit>,
}

/// Noise-aware fitting of a tree mixture's potentials on the training maps
/// ([`super::fit`]): every training map with evidence simulated by the paper's noise
/// model ([`crate::noise`]) at every noise level, with and without evidence on
/// placeholders, `rounds` times each.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseFit {
    /// Penalty weight `λ` ([`FitOptions::penalty`]; finite, in (0, 1e6]).
    pub penalty: f64,
    /// Evidence rounds per map, level and placeholder setting (1 to 100).
    pub rounds: usize,
    /// Seed of the simulated evidence and the training maps' forests.
    pub seed: u64,
}

impl Default for TreeTraining {
    /// Normalised potentials `p(a,b)/√(p(a)p(b))` with coupling 1 and pseudo-count 1,
    /// uniform unary, `γ = 2`, 4 trees, averaged marginals.
    fn default() -> Self {
        TreeTraining {
            potentials: CooccurrenceParams {
                pseudo_count: 1.0,
                normalisation: Normalisation::Normalised,
                coupling: 1.0,
            },
            prior_exponent: 0.0,
            evidence_exponent: 2,
            trees: 4,
            mixing: Mixing::Average,
            fit: None,
        }
    }
}

impl TreeTraining {
    /// Every setting against its documented domain (the one check: training, the
    /// command line and settings files call it). The potential form must be a
    /// symmetric one (`joint`, `normalised` or `pmi`): the model's `ψ` is symmetric.
    pub fn check(&self) -> Result<(), DomainError> {
        self.potentials.check().map_err(|e| e.under("potentials"))?;
        if self.potentials.normalisation == Normalisation::Conditional {
            return Err(DomainError {
                setting: "potentials.normalisation".into(),
                value: "conditional".into(),
                domain:
                    "must be joint, normalised or pmi (a tree mixture's potential is symmetric)"
                        .into(),
            });
        }
        domain::closed("prior_exponent", self.prior_exponent, -2.0, 2.0)?;
        domain::count(
            "evidence_exponent",
            u64::from(self.evidence_exponent),
            1,
            u64::from(MAX_EVIDENCE_EXPONENT),
        )?;
        domain::trees("trees", self.trees)?;
        if let Some(fit) = &self.fit {
            domain::left_open("fit.penalty", fit.penalty, 0.0, 1e6)?;
            domain::count("fit.rounds", fit.rounds as u64, 1, 100)?;
        }
        Ok(())
    }

    /// Short description, e.g. `normalised^1, ρ=0, ev^2, 4 trees, average, fit λ=0.001`.
    pub fn label(&self) -> String {
        format!(
            "{}^{}, ρ={}, ev^{}, {} trees, {}, {}",
            self.potentials.normalisation.name(),
            self.potentials.coupling,
            self.prior_exponent,
            self.evidence_exponent,
            self.trees,
            self.mixing.name(),
            self.fit_label()
        )
    }

    fn fit_label(&self) -> String {
        match &self.fit {
            Some(f) => format!("fit λ={}", f.penalty),
            None => "counted".into(),
        }
    }

    /// The settings as `(option, value)` pairs.
    pub fn options(&self) -> Vec<(String, String)> {
        vec![
            (
                "potentials".into(),
                self.potentials.normalisation.name().into(),
            ),
            ("coupling".into(), self.potentials.coupling.to_string()),
            ("prior exponent".into(), self.prior_exponent.to_string()),
            (
                "evidence exponent".into(),
                self.evidence_exponent.to_string(),
            ),
            ("trees".into(), self.trees.to_string()),
            ("mixing".into(), self.mixing.name().into()),
            ("potentials fitted".into(), self.fit_label()),
        ]
    }
}

/// Trains a tree mixture on `maps` (every map must use the same classes; places
/// without a class are skipped when counting; with `fit`, maps with an unannotated
/// place are left out of the fit). The result passes [`TreeMixture::check`]; errors
/// say what is wrong.
pub fn train_tree_mixture(
    maps: &[TopoMap],
    settings: &TreeTraining,
) -> Result<TreeMixture, TreeMixError> {
    settings
        .check()
        .map_err(|e| TreeMixError::Model(format!("training settings: {e}")))?;
    let mrf = Mrf2::train(maps, &settings.potentials)
        .map_err(|e| TreeMixError::Model(format!("counting edge classes: {e}")))?;
    let classes = maps[0].classes.clone();
    let prior = class_prior(maps, classes.len());
    let model = TreeMixture {
        format: MODEL_FORMAT,
        family: ModelFamily::TreeMixture,
        classes,
        potential: mrf.potential().to_vec(),
        unary: prior
            .iter()
            .map(|p| p.powf(settings.prior_exponent))
            .collect(),
        evidence_exponent: settings.evidence_exponent,
        trees: settings.trees,
        mixing: settings.mixing,
        settings: serde_json::to_value(settings).map_err(|e| TreeMixError::Model(e.to_string()))?,
        trained_on: maps.iter().map(|m| m.name.clone()).collect(),
    };
    model
        .check("<trained model>")
        .map_err(|e| TreeMixError::Model(e.to_string()))?;
    match &settings.fit {
        None => Ok(model),
        Some(fit) => fit_on_simulated_evidence(model, maps, fit),
    }
}

/// [`fit_potentials`] on every annotated map of `maps` with simulated evidence.
fn fit_on_simulated_evidence(
    model: TreeMixture,
    maps: &[TopoMap],
    fit: &NoiseFit,
) -> Result<TreeMixture, TreeMixError> {
    if fit.rounds == 0 {
        return Err(TreeMixError::Model("fit rounds must be at least 1".into()));
    }
    let annotated: Vec<(usize, &TopoMap, Vec<ClassId>)> = maps
        .iter()
        .enumerate()
        .filter_map(|(i, m)| map_truth(m).ok().map(|t| (i, m, t)))
        .collect();
    let trees = annotated
        .iter()
        .map(|(i, m, _)| {
            SpanningTrees::covering(m, model.trees, derive_seed(fit.seed, &[*i as u64]))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut graphs = Vec::new();
    for ((i, map, truth), trees) in annotated.iter().zip(&trees) {
        let has_placeholders = map.places().any(|p| p.placeholder);
        for level in NoiseLevel::all() {
            for placeholders in [false, true] {
                if placeholders && !has_placeholders {
                    continue;
                }
                for r in 0..fit.rounds {
                    let seed = derive_seed(
                        fit.seed,
                        &[
                            *i as u64,
                            u64::from(level.get()),
                            placeholders as u64,
                            r as u64,
                        ],
                    );
                    let ev = simulate_map_evidence(map, level, placeholders, seed)
                        .map_err(|e| TreeMixError::Model(format!("simulating evidence: {e}")))?;
                    graphs.push(FitGraph {
                        map,
                        trees,
                        rows: ev.rows,
                        truth: truth.clone(),
                    });
                }
            }
        }
    }
    let opts = FitOptions {
        penalty: fit.penalty,
        ..FitOptions::default()
    };
    Ok(fit_potentials(&model, &graphs, &opts)?.0)
}
