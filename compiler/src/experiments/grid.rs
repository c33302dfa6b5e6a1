//! The validation grid ([`ValidationGrid`]): every model's candidate settings that
//! the validation searches, and the data it scores them on (maps, noise levels,
//! rounds); the standard and tiny grids, and the check of every candidate against the
//! domain of the setting it becomes.

use super::evidence::NoiseLevel;
use super::settings::{DecompositionChoice, GraphSpnSetting, MrfSetting};
use crate::decompose::DecompositionStrategy;
use crate::learn::TrainingSettings;
use crate::learn::structure::SplitChoice;
use crate::mrf::{BpOptions, Normalisation, Schedule};
use crate::spn::Mixing;
use crate::treemix::{NoiseFit, TreeTraining};

/// What the validation searches, and on how much data.
#[derive(Clone, Debug)]
pub struct ValidationGrid {
    /// GraphSPN training variants `(name, settings)`.
    pub graphspn_variants: Vec<(String, TrainingSettings)>,
    /// GraphSPN evidence exponents.
    pub graphspn_exponents: Vec<f64>,
    /// GraphSPN template temperatures.
    pub graphspn_temperatures: Vec<f64>,
    /// GraphSPN decompositions.
    pub graphspn_decompositions: Vec<DecompositionChoice>,
    /// GraphSPN mixings.
    pub graphspn_mixings: Vec<Mixing>,
    /// GraphSPN class-prior corrections β.
    pub graphspn_prior_corrections: Vec<f64>,
    /// MRF potential forms.
    pub normalisations: Vec<Normalisation>,
    /// MRF coupling exponents.
    pub couplings: Vec<f64>,
    /// MRF evidence exponents.
    pub mrf_exponents: Vec<f64>,
    /// BP options tried at the chosen potential (the first is used during the potential search).
    pub schedules: Vec<BpOptions>,
    /// Tree mixture: potential forms (symmetric ones: joint, normalised, PMI).
    pub tree_forms: Vec<Normalisation>,
    /// Tree mixture: coupling exponents.
    pub tree_couplings: Vec<f64>,
    /// Tree mixture: prior exponents ρ of the unary potential.
    pub tree_prior_exponents: Vec<f64>,
    /// Tree mixture: evidence exponents γ.
    pub tree_exponents: Vec<u32>,
    /// Tree mixture: trees per map.
    pub tree_counts: Vec<usize>,
    /// Tree mixture: mixings.
    pub tree_mixings: Vec<Mixing>,
    /// Tree mixture: noise-aware fits tried at the winner (penalties `λ`; the
    /// counted potentials are always a candidate).
    pub tree_fit_penalties: Vec<f64>,
    /// Validation maps per validation building (chosen at random, seeded).
    pub maps_per_building: usize,
    /// Noise levels of the validation graphs.
    pub levels: Vec<NoiseLevel>,
    /// Evidence rounds per map and level.
    pub rounds: usize,
}

fn variant(split: SplitChoice) -> (String, TrainingSettings) {
    let mut t = TrainingSettings::default();
    t.structure.split_choice = split;
    (split.name().to_string(), t)
}

/// How much data a validation scored each candidate on, per validation building:
/// recorded in validation.json, so that a run reusing its settings (`--settings`) can
/// say how large the search behind them was.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValidationSample {
    /// Maps per validation building.
    pub maps_per_building: usize,
    /// Noise levels (1..6).
    pub levels: Vec<u8>,
    /// Evidence rounds per map and level.
    pub rounds: usize,
}

impl ValidationGrid {
    /// The sample this grid scores candidates on.
    pub fn sample(&self) -> ValidationSample {
        ValidationSample {
            maps_per_building: self.maps_per_building,
            levels: self.levels.iter().map(|l| l.get()).collect(),
            rounds: self.rounds,
        }
    }

    /// Every candidate value against the domain of the setting it becomes: each is
    /// put into that model's settings and checked by their one check
    /// ([`ModelSettings::check`](super::settings::ModelSettings::check)), so the grid
    /// and a settings file are held to the same domains. Errors name the grid entry,
    /// e.g. `tree_couplings: potentials.coupling = -1: …`.
    pub fn check(&self) -> Result<(), crate::domain::DomainError> {
        let gspn = |name: &str, edit: &dyn Fn(&mut GraphSpnSetting)| {
            let mut s = GraphSpnSetting::paper();
            edit(&mut s);
            s.check().map_err(|e| e.under(name))
        };
        let mrf = |name: &str, edit: &dyn Fn(&mut MrfSetting)| {
            let mut s = MrfSetting::paper(BpOptions::default());
            edit(&mut s);
            s.check().map_err(|e| e.under(name))
        };
        let tree = |name: &str, edit: &dyn Fn(&mut TreeTraining)| {
            let mut s = TreeTraining::default();
            edit(&mut s);
            s.check().map_err(|e| e.under(name))
        };
        for (name, t) in &self.graphspn_variants {
            gspn(&format!("graphspn_variants.{name}"), &|s| {
                s.training = t.clone()
            })?;
        }
        for &x in &self.graphspn_exponents {
            gspn("graphspn_exponents", &|s| s.evidence_exponent = x)?;
        }
        for &x in &self.graphspn_temperatures {
            gspn("graphspn_temperatures", &|s| s.training.temperature = x)?;
        }
        for &d in &self.graphspn_decompositions {
            gspn("graphspn_decompositions", &|s| s.decompositions = d)?;
        }
        for &x in &self.graphspn_prior_corrections {
            gspn("graphspn_prior_corrections", &|s| s.prior_correction = x)?;
        }
        for &x in &self.couplings {
            mrf("couplings", &|s| s.potentials.coupling = x)?;
        }
        for &x in &self.mrf_exponents {
            mrf("mrf_exponents", &|s| s.evidence_exponent = x)?;
        }
        for bp in &self.schedules {
            mrf("schedules", &|s| s.bp = *bp)?;
        }
        for &x in &self.tree_forms {
            tree("tree_forms", &|s| s.potentials.normalisation = x)?;
        }
        for &x in &self.tree_couplings {
            tree("tree_couplings", &|s| s.potentials.coupling = x)?;
        }
        for &x in &self.tree_prior_exponents {
            tree("tree_prior_exponents", &|s| s.prior_exponent = x)?;
        }
        for &x in &self.tree_exponents {
            tree("tree_exponents", &|s| s.evidence_exponent = x)?;
        }
        for &x in &self.tree_counts {
            tree("tree_counts", &|s| s.trees = x)?;
        }
        for &x in &self.tree_fit_penalties {
            tree("tree_fit_penalties", &|s| {
                s.fit = Some(NoiseFit {
                    penalty: x,
                    rounds: 1,
                    seed: 0,
                })
            })?;
        }
        crate::domain::maps("maps_per_building", self.maps_per_building)
    }

    /// The grid of `graphspn reproduce` / `graphspn validate`:
    /// - GraphSPN (768 candidates): 2 Star structures × template temperature
    ///   {1, 0.8, 0.6} × evidence exponent {1, 2, 3, 4} × class-prior correction
    ///   {0, 0.25, 0.5, 0.75} × decompositions {paper, cover} × {5 of 15, 20 of 60} ×
    ///   mixing {posterior, average};
    /// - each MRF (112 candidates, then 2 BP schedules at the winner): 4 potential
    ///   forms × coupling {0.05, 0.1, 0.2, 0.3, 0.45, 0.6, 1} × evidence exponent
    ///   {1, 2, 3, 4}; BP at most 200 sweeps;
    /// - the tree mixture (432 candidates, then 2 noise-aware fits at the winner):
    ///   potential form {joint, normalised, PMI} × coupling {0.6, 0.8, 1, 1.25} × prior
    ///   exponent {0, 0.25, 0.5} × evidence exponent {1, 2, 3} × trees {2, 4} (within
    ///   the microcontroller budget of the 230-place map) × mixing {posterior,
    ///   average}; fit penalty λ ∈ {1e-3, 1e-4}. The prior exponent stays ≥ 0: the
    ///   unary potential is part of the model's distribution of labelled maps, which
    ///   novelty detection scores; a negative exponent (favouring rare classes) would
    ///   turn it into a correction of the evidence at the cost of that distribution
    ///   (measured: see docs/REPRODUCTION.md);
    ///
    /// on 5 maps × NL2, NL4, NL6 × 2 rounds per validation building (60 graphs per
    /// fold: with 18, as before, settings within 0.2 points of each other were picked
    /// by the draw of the validation maps),
    /// classification and placeholders.
    pub fn standard() -> Self {
        let bp = BpOptions {
            max_iterations: 200,
            ..BpOptions::default()
        };
        ValidationGrid {
            graphspn_variants: vec![
                variant(SplitChoice::MostImages),
                variant(SplitChoice::FewestImages),
            ],
            graphspn_exponents: vec![1.0, 2.0, 3.0, 4.0],
            graphspn_temperatures: vec![1.0, 0.8, 0.6],
            graphspn_decompositions: DecompositionStrategy::ALL
                .iter()
                .flat_map(|&s| {
                    [
                        DecompositionChoice::new(s, 5, 15),
                        DecompositionChoice::new(s, 20, 60),
                    ]
                })
                .collect(),
            graphspn_mixings: Mixing::ALL.to_vec(),
            graphspn_prior_corrections: vec![0.0, 0.25, 0.5, 0.75],
            normalisations: Normalisation::ALL.to_vec(),
            couplings: vec![0.05, 0.1, 0.2, 0.3, 0.45, 0.6, 1.0],
            mrf_exponents: vec![1.0, 2.0, 3.0, 4.0],
            schedules: vec![
                bp,
                BpOptions {
                    schedule: Schedule::Parallel,
                    damping: 0.5,
                    ..bp
                },
            ],
            tree_forms: vec![
                Normalisation::Joint,
                Normalisation::Normalised,
                Normalisation::Pmi,
            ],
            tree_couplings: vec![0.6, 0.8, 1.0, 1.25],
            tree_prior_exponents: vec![0.0, 0.25, 0.5],
            tree_exponents: vec![1, 2, 3],
            tree_counts: vec![2, 4],
            tree_mixings: Mixing::ALL.to_vec(),
            tree_fit_penalties: vec![1e-3, 1e-4],
            maps_per_building: 5,
            levels: [2, 4, 6]
                .map(|l| NoiseLevel::new(l).expect("level exists"))
                .to_vec(),
            rounds: 2,
        }
    }

    /// A tiny grid for smoke tests: GraphSPN 2 exponents × 2 temperatures × 2
    /// decompositions × 2 mixings; MRFs 2 forms × 2 couplings; 1 map at NL2 per
    /// validation building.
    pub fn tiny() -> Self {
        let bp = BpOptions {
            max_iterations: 200,
            ..BpOptions::default()
        };
        ValidationGrid {
            graphspn_variants: vec![variant(SplitChoice::MostImages)],
            graphspn_exponents: vec![1.0, 2.0],
            graphspn_temperatures: vec![1.0, 0.8],
            graphspn_decompositions: vec![
                DecompositionChoice::default(),
                DecompositionChoice::new(DecompositionStrategy::Cover, 5, 15),
            ],
            graphspn_mixings: Mixing::ALL.to_vec(),
            graphspn_prior_corrections: vec![0.0, 0.25],
            normalisations: vec![Normalisation::Joint, Normalisation::Normalised],
            couplings: vec![0.3, 1.0],
            mrf_exponents: vec![1.0],
            schedules: vec![bp],
            tree_forms: vec![Normalisation::Normalised],
            tree_couplings: vec![0.8, 1.0],
            tree_prior_exponents: vec![0.0],
            tree_exponents: vec![2],
            tree_counts: vec![2],
            tree_mixings: Mixing::ALL.to_vec(),
            tree_fit_penalties: vec![],
            maps_per_building: 1,
            levels: vec![NoiseLevel::new(2).expect("level exists")],
            rounds: 1,
        }
    }
}
