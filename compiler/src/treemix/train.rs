//! Training a tree mixture from annotated maps: the pairwise potential from edge
//! co-occurrence counts (the MRF-2 baseline's counting, [`crate::mrf::Mrf2::train`]),
//! the unary potential from the training maps' class shares.

use serde::{Deserialize, Serialize};

use super::TreeMixError;
use super::model::TreeMixture;
use crate::family::ModelFamily;
use crate::learn::model::MODEL_FORMAT;
use crate::map::TopoMap;
use crate::map::stats::class_prior;
use crate::mrf::{CooccurrenceParams, Mrf2, Normalisation};
use crate::spn::Mixing;

/// How a tree mixture is trained; stored in the model file's `settings`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TreeTraining {
    /// The pairwise potential: edge co-occurrence counts (both orientations, plus a
    /// pseudo-count per cell) → potential form → raised to the coupling exponent.
    pub potentials: CooccurrenceParams,
    /// `ρ`: the unary potential is `prior^ρ`, the training maps' smoothed class shares
    /// ([`class_prior`]) to this power (0 = uniform; finite).
    pub prior_exponent: f64,
    /// Evidence exponent `γ` (rows enter as `α^γ`).
    pub evidence_exponent: u32,
    /// Spanning trees per map.
    pub trees: usize,
    /// How the trees' marginals are combined.
    pub mixing: Mixing,
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
        }
    }
}

impl TreeTraining {
    /// Short description, e.g. `normalised^1, ρ=0, ev^2, 4 trees, average`.
    pub fn label(&self) -> String {
        format!(
            "{}^{}, ρ={}, ev^{}, {} trees, {}",
            self.potentials.normalisation.name(),
            self.potentials.coupling,
            self.prior_exponent,
            self.evidence_exponent,
            self.trees,
            self.mixing.name()
        )
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
        ]
    }
}

/// Trains a tree mixture on `maps` (every map must use the same classes; places
/// without a class are skipped when counting). The result passes
/// [`TreeMixture::check`]; errors say what is wrong.
pub fn train_tree_mixture(
    maps: &[TopoMap],
    settings: &TreeTraining,
) -> Result<TreeMixture, TreeMixError> {
    if !settings.prior_exponent.is_finite() {
        return Err(TreeMixError::Model(format!(
            "prior_exponent must be finite, got {}",
            settings.prior_exponent
        )));
    }
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
    Ok(model)
}
