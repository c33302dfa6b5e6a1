//! Leave-one-training-building-out validation: chooses every model's settings
//! for one test building using only its training buildings:
//! - GraphSPN: Star structure, template temperature, evidence exponent,
//!   class-prior correction, decompositions (strategy and number) and how the
//!   decompositions' marginals are mixed (searched jointly);
//! - each MRF: potential form, coupling and evidence exponent (jointly), then the
//!   BP schedule at the winner.
//!
//! For test building `T` with training buildings `{X, Y}` there are two folds:
//! train on `X`, validate on maps of `Y`, and the reverse (with more training
//! buildings, one fold per building: validate on it, train on the others). Each
//! candidate setting is scored by its mean accuracy over the validation graphs
//! (classification over all places and placeholders without evidence, pooled),
//! averaged over the folds; the best score wins (ties: the first in grid order).
//! Every candidate of every model sees the same validation graphs (maps, noise
//! levels, evidence). No test-building map is read.

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::evidence::{NoiseLevel, derive_seed, map_truth, simulate_map_evidence_with};
use super::reproduce::{
    ReproduceConfig, ReproduceError, TAG_VALIDATE, accuracy, build_instance, building_key,
    class_prior, graphspn_rows, mrf_marginals, pick_maps, training_buildings,
};
use crate::decompose::{DecompositionParams, DecompositionStrategy};
use crate::instance::Mixing;
use crate::learn::structure::SplitChoice;
use crate::learn::{Progress, TrainingSettings, train_model};
use crate::map::{ClassId, TopoMap};
use crate::mrf::{BpOptions, CooccurrenceParams, Mrf2, Mrf3, MrfModel, Normalisation, Schedule};
use crate::template::Template;

/// Settings of one MRF baseline.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MrfSetting {
    /// How potentials are made from the training counts.
    pub potentials: CooccurrenceParams,
    /// Each evidence row is raised to this power and renormalised before inference.
    pub evidence_exponent: f64,
    /// Loopy BP options.
    pub bp: BpOptions,
}

impl MrfSetting {
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
pub struct DecompositionChoice {
    /// How candidates are drawn and ranked.
    pub strategy: DecompositionStrategy,
    /// Decompositions kept (the instance's D).
    pub count: usize,
    /// Candidates drawn.
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
pub struct GraphSpnSetting {
    /// Name of the training variant (template structure).
    pub variant: String,
    /// Training settings (the seed is replaced per building); `training.temperature`
    /// is the template temperature.
    pub training: TrainingSettings,
    /// Each evidence row is raised to this power and renormalised before inference.
    pub evidence_exponent: f64,
    /// The decompositions of each test map's instance.
    #[serde(default)]
    pub decompositions: DecompositionChoice,
    /// How the decompositions' marginals are combined.
    #[serde(default)]
    pub mixing: Mixing,
    /// Class-prior correction β: evidence rows are multiplied by `prior^-β` (the
    /// training maps' class shares; see [`super::reproduce::graphspn_rows`]). 0 = none.
    #[serde(default)]
    pub prior_correction: f64,
}

impl GraphSpnSetting {
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

    /// Short description, e.g. `most_images, τ=0.8, ev^2, β=0.25, cover 20/60, average`.
    pub fn label(&self) -> String {
        format!(
            "{}, τ={}, ev^{}, β={}, {}, {}",
            self.variant,
            self.training.temperature,
            self.evidence_exponent,
            self.prior_correction,
            self.decompositions.label(),
            self.mixing.name()
        )
    }
}

/// The settings of every model for one test building.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelSettings {
    /// GraphSPN.
    pub graphspn: GraphSpnSetting,
    /// The tuned MRF-2.
    pub mrf2: MrfSetting,
    /// The tuned MRF-3.
    pub mrf3: MrfSetting,
}

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
    /// Validation maps per validation building (chosen at random, seeded).
    pub maps_per_building: usize,
    /// Noise levels of the validation graphs.
    pub levels: Vec<NoiseLevel>,
    /// Evidence rounds per map and level.
    pub rounds: usize,
}

fn variant(name: &str, split: SplitChoice) -> (String, TrainingSettings) {
    let mut t = TrainingSettings::default();
    t.structure.split_choice = split;
    (name.to_string(), t)
}

impl ValidationGrid {
    /// The grid of `graphspn reproduce` / `graphspn validate`:
    /// - GraphSPN (768 candidates): 2 Star structures × template temperature
    ///   {1, 0.8, 0.6} × evidence exponent {1, 2, 3, 4} × class-prior correction
    ///   {0, 0.25, 0.5, 0.75} × decompositions {paper, cover} × {5 of 15, 20 of 60} ×
    ///   mixing {posterior, average};
    /// - each MRF (112 candidates, then 2 BP schedules at the winner): 4 potential
    ///   forms × coupling {0.05, 0.1, 0.2, 0.3, 0.45, 0.6, 1} × evidence exponent
    ///   {1, 2, 3, 4}; BP at most 200 sweeps;
    ///
    /// on 3 maps × NL2, NL4, NL6 × 1 round per validation building,
    /// classification and placeholders.
    pub fn standard() -> Self {
        let bp = BpOptions {
            max_iterations: 200,
            ..BpOptions::default()
        };
        ValidationGrid {
            graphspn_variants: vec![
                variant("most_images", SplitChoice::MostImages),
                variant("fewest_images", SplitChoice::FewestImages),
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
            maps_per_building: 3,
            levels: [2, 4, 6]
                .map(|l| NoiseLevel::new(l).expect("level exists"))
                .to_vec(),
            rounds: 1,
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
            graphspn_variants: vec![variant("most_images", SplitChoice::MostImages)],
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
            maps_per_building: 1,
            levels: vec![NoiseLevel::new(2).expect("level exists")],
            rounds: 1,
        }
    }
}

/// The score of one candidate setting.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CandidateScore {
    /// `GraphSPN`, `MRF-2` or `MRF-3`.
    pub model: String,
    /// The setting ([`MrfSetting::label`] / [`GraphSpnSetting::label`]).
    pub setting: String,
    /// The setting as `(option, value)` pairs ([`MrfSetting::options`] /
    /// [`GraphSpnSetting::options`]), for the per-option summary.
    #[serde(default)]
    pub options: Vec<(String, String)>,
    /// Mean accuracy per fold (classification and placeholders pooled), in [0, 1].
    pub per_fold: Vec<f64>,
    /// Mean of `per_fold`.
    pub score: f64,
}

/// The validation of one test building.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Validation {
    /// The test building (never read).
    pub test_building: String,
    /// The folds, e.g. `Freiburg → Saarbrucken` (train → validate).
    pub folds: Vec<String>,
    /// Every candidate's score.
    pub candidates: Vec<CandidateScore>,
    /// The winners.
    pub chosen: ModelSettings,
    /// Wall-clock seconds of each model's search (`GraphSPN`, `MRF-2`, `MRF-3`).
    #[serde(default)]
    pub seconds: Vec<(String, f64)>,
}

/// One validation graph.
struct VGraph {
    fold: usize,
    map: usize,
    rows: Vec<Vec<f64>>,
    truth: Vec<ClassId>,
    scored: Vec<usize>,
}

struct Fold {
    name: String,
    train: Vec<TopoMap>,
    val: Vec<TopoMap>,
    /// Seed index of the fold.
    key: u64,
}

fn mean(v: &[f64]) -> f64 {
    let f: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    f.iter().sum::<f64>() / f.len().max(1) as f64
}

/// Per-fold mean accuracy from per-graph accuracies.
fn fold_scores(graphs: &[VGraph], acc: &[f64], folds: usize) -> Vec<f64> {
    (0..folds)
        .map(|f| {
            let v: Vec<f64> = graphs
                .iter()
                .zip(acc)
                .filter(|(g, _)| g.fold == f)
                .map(|(_, &a)| a)
                .collect();
            mean(&v)
        })
        .collect()
}

fn candidate(
    model: &str,
    (setting, options): (String, Vec<(String, String)>),
    per_fold: Vec<f64>,
) -> CandidateScore {
    let score = per_fold.iter().sum::<f64>() / per_fold.len().max(1) as f64;
    CandidateScore {
        model: model.into(),
        setting,
        options,
        per_fold,
        score,
    }
}

fn best<T: Clone>(scored: &[(T, CandidateScore)]) -> Option<T> {
    let mut out: Option<(&T, f64)> = None;
    for (t, c) in scored {
        if out.is_none_or(|(_, s)| c.score > s) {
            out = Some((t, c.score));
        }
    }
    out.map(|(t, _)| t.clone())
}

/// Scores an MRF setting on every validation graph.
fn score_mrf<M: MrfModel + Sync>(
    models: &[M],
    setting: &MrfSetting,
    folds: &[Fold],
    graphs: &[VGraph],
) -> Result<Vec<f64>, ReproduceError> {
    let acc = graphs
        .iter()
        .map(|g| {
            let map = &folds[g.fold].val[g.map];
            let r = mrf_marginals(&models[g.fold], setting, map, &g.rows)?;
            Ok(accuracy(&r.marginals, &g.truth, &g.scored))
        })
        .collect::<Result<Vec<_>, ReproduceError>>()?;
    Ok(fold_scores(graphs, &acc, folds.len()))
}

/// Searches one MRF's settings (potentials × evidence exponent, then schedule).
fn search_mrf<M: MrfModel + Sync + Send>(
    name: &str,
    train: impl Fn(&[TopoMap], &CooccurrenceParams) -> Result<M, crate::mrf::MrfError> + Sync,
    grid: &ValidationGrid,
    base: &CooccurrenceParams,
    folds: &[Fold],
    graphs: &[VGraph],
    out: &mut Vec<CandidateScore>,
) -> Result<MrfSetting, ReproduceError> {
    let mut cands = Vec::new();
    for &normalisation in &grid.normalisations {
        for &coupling in &grid.couplings {
            for &e in &grid.mrf_exponents {
                cands.push(MrfSetting {
                    potentials: CooccurrenceParams {
                        normalisation,
                        coupling,
                        ..*base
                    },
                    evidence_exponent: e,
                    bp: grid.schedules[0],
                });
            }
        }
    }
    let mrf_err = |source| ReproduceError::Mrf {
        what: format!("validation of {name}"),
        source,
    };
    let scored = cands
        .par_iter()
        .map(|s| {
            let models = folds
                .iter()
                .map(|f| train(&f.train, &s.potentials))
                .collect::<Result<Vec<_>, _>>()
                .map_err(mrf_err)?;
            let pf = score_mrf(&models, s, folds, graphs)?;
            Ok((s.clone(), candidate(name, (s.label(), s.options()), pf)))
        })
        .collect::<Result<Vec<_>, ReproduceError>>()?;
    let mut chosen = best(&scored)
        .ok_or_else(|| ReproduceError::Config(format!("validation grid of {name} is empty")))?;
    out.extend(scored.into_iter().map(|(_, c)| c));
    if grid.schedules.len() > 1 {
        let models = folds
            .iter()
            .map(|f| train(&f.train, &chosen.potentials))
            .collect::<Result<Vec<_>, _>>()
            .map_err(mrf_err)?;
        let scored = grid.schedules[1..]
            .par_iter()
            .map(|&bp| {
                let s = MrfSetting {
                    bp,
                    ..chosen.clone()
                };
                let pf = score_mrf(&models, &s, folds, graphs)?;
                Ok((s.clone(), candidate(name, (s.label(), s.options()), pf)))
            })
            .collect::<Result<Vec<_>, ReproduceError>>()?;
        let first_score = out
            .iter()
            .rev()
            .find(|c| c.model == name && c.setting == chosen.label())
            .map(|c| c.score)
            .unwrap_or(f64::NEG_INFINITY);
        for (s, c) in &scored {
            if c.score > first_score {
                chosen = s.clone();
            }
        }
        out.extend(scored.into_iter().map(|(_, c)| c));
    }
    Ok(chosen)
}

/// Validates every model's settings for `test_building` on its training buildings
/// ([`training_buildings`]: the other buildings of `all`, or `cfg.train_buildings`;
/// see the module docs). Needs at least two training buildings.
pub fn validate_for(
    all: &BTreeMap<String, Vec<TopoMap>>,
    test_building: &str,
    cfg: &ReproduceConfig,
) -> Result<Validation, ReproduceError> {
    let grid = &cfg.grid;
    let others = training_buildings(all, test_building, cfg)?;
    if others.len() < 2 {
        return Err(ReproduceError::Config(format!(
            "validation for {test_building} needs two training buildings (one to train on, one to validate on), found {}",
            others.len()
        )));
    }
    if grid.levels.is_empty() || grid.rounds == 0 {
        return Err(ReproduceError::Config(
            "validation needs at least one level and one round".into(),
        ));
    }
    let tb = building_key(test_building);
    let others: Vec<&String> = others.iter().collect();
    // Folds: validate on each other building, train on the rest (never the test building).
    let mut folds = Vec::new();
    for v in &others {
        let train: Vec<TopoMap> = others
            .iter()
            .filter(|k| *k != v)
            .flat_map(|k| all[*k].iter().cloned())
            .collect();
        let vb = building_key(v);
        let val = pick_maps(&all[*v], grid.maps_per_building, cfg.seed, vb, TAG_VALIDATE)
            .map_err(|e| ReproduceError::Config(format!("validation maps of {v}: {e}")))?;
        let names: Vec<&str> = others
            .iter()
            .filter(|k| *k != v)
            .map(|k| k.as_str())
            .collect();
        folds.push(Fold {
            name: format!("{} → {v}", names.join("+")),
            train,
            val,
            key: tb.wrapping_mul(16).wrapping_add(vb),
        });
    }
    // Validation graphs (evidence shared by every candidate).
    let mut graphs = Vec::new();
    for (f, fold) in folds.iter().enumerate() {
        for (m, map) in fold.val.iter().enumerate() {
            for &level in &grid.levels {
                for round in 0..grid.rounds {
                    for placeholders in [false, true] {
                        let seed = derive_seed(
                            cfg.seed,
                            &[
                                TAG_VALIDATE,
                                fold.key,
                                m as u64,
                                level.get() as u64,
                                round as u64,
                                placeholders as u64,
                            ],
                        );
                        let evi = |source| ReproduceError::Evidence {
                            map: map.name.clone(),
                            source,
                        };
                        let ev = simulate_map_evidence_with(
                            map,
                            level,
                            placeholders,
                            seed,
                            cfg.wrong_draw,
                        )
                        .map_err(evi)?;
                        let truth = map_truth(map).map_err(evi)?;
                        let scored: Vec<usize> = (0..map.num_places())
                            .filter(|&i| !placeholders || map.place(i).placeholder)
                            .collect();
                        if scored.is_empty() {
                            continue;
                        }
                        graphs.push(VGraph {
                            fold: f,
                            map: m,
                            rows: ev.rows,
                            truth,
                            scored,
                        });
                    }
                }
            }
        }
    }
    let mut candidates = Vec::new();
    let mut seconds = Vec::new();
    let clock = std::time::Instant::now();

    // GraphSPN: train each structure variant on each fold (temperature 1), then
    // temper, decompose and score every setting; evidence shared by every candidate.
    let jobs: Vec<(usize, usize)> = (0..grid.graphspn_variants.len())
        .flat_map(|v| (0..folds.len()).map(move |f| (v, f)))
        .collect();
    let trained = jobs
        .par_iter()
        .map(|&(v, f)| {
            let fold = &folds[f];
            let settings = TrainingSettings {
                seed: derive_seed(cfg.seed, &[TAG_VALIDATE, fold.key, v as u64]),
                temperature: 1.0,
                ..grid.graphspn_variants[v].1.clone()
            };
            train_model(
                &fold.train,
                &Template::paper_set(),
                &settings,
                Progress::Hidden,
            )
            .map(|(model, _)| model)
            .map_err(|source| ReproduceError::Train {
                building: format!("validation fold {}", fold.name),
                source,
            })
        })
        .collect::<Result<Vec<_>, ReproduceError>>()?;
    let priors: Vec<Vec<f64>> = folds
        .iter()
        .map(|f| class_prior(&f.train, trained[0].classes.len()))
        .collect();
    let mut g_scored = Vec::new();
    for (v, (vname, vsettings)) in grid.graphspn_variants.iter().enumerate() {
        for &tau in &grid.graphspn_temperatures {
            let models = (0..folds.len())
                .map(|f| trained[v * folds.len() + f].tempered(tau))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| ReproduceError::Config(e.to_string()))?;
            for dc in &grid.graphspn_decompositions {
                // One instance per validation map (decomposition seeds as before).
                let instances = folds
                    .iter()
                    .enumerate()
                    .map(|(f, fold)| {
                        fold.val
                            .iter()
                            .enumerate()
                            .map(|(m, map)| {
                                build_instance(
                                    &models[f],
                                    map,
                                    dc,
                                    cfg.seed,
                                    100 + fold.key,
                                    m as u64,
                                )
                            })
                            .collect::<Result<Vec<_>, _>>()
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                // Per graph, one copy of its instance: one evaluation per (exponent,
                // prior correction), read out with every mixing. acc[graph][row kind][mixing].
                let row_kinds: Vec<(f64, f64)> = grid
                    .graphspn_exponents
                    .iter()
                    .flat_map(|&e| grid.graphspn_prior_corrections.iter().map(move |&b| (e, b)))
                    .collect();
                let acc = graphs
                    .par_iter()
                    .map(|g| {
                        let map = &folds[g.fold].val[g.map];
                        let err = |source| ReproduceError::Inference {
                            map: map.name.clone(),
                            source,
                        };
                        let mut inst = instances[g.fold][g.map].clone();
                        row_kinds
                            .iter()
                            .map(|&(e, beta)| {
                                let rows = graphspn_rows(&g.rows, e, &priors[g.fold], beta);
                                inst.set_all_evidence(&rows).map_err(err)?;
                                grid.graphspn_mixings
                                    .iter()
                                    .map(|&mx| {
                                        let p = inst.marginals_mixed(mx).map_err(err)?.probs;
                                        Ok(accuracy(&p, &g.truth, &g.scored))
                                    })
                                    .collect::<Result<Vec<f64>, ReproduceError>>()
                            })
                            .collect::<Result<Vec<_>, ReproduceError>>()
                    })
                    .collect::<Result<Vec<_>, ReproduceError>>()?;
                for (ri, &(e, beta)) in row_kinds.iter().enumerate() {
                    for (mi, &mixing) in grid.graphspn_mixings.iter().enumerate() {
                        let s = GraphSpnSetting {
                            variant: vname.clone(),
                            training: TrainingSettings {
                                temperature: tau,
                                ..vsettings.clone()
                            },
                            evidence_exponent: e,
                            decompositions: *dc,
                            mixing,
                            prior_correction: beta,
                        };
                        let a: Vec<f64> = acc.iter().map(|per| per[ri][mi]).collect();
                        let c = candidate(
                            "GraphSPN",
                            (s.label(), s.options()),
                            fold_scores(&graphs, &a, folds.len()),
                        );
                        g_scored.push((s, c));
                    }
                }
            }
        }
    }
    let graphspn = best(&g_scored)
        .ok_or_else(|| ReproduceError::Config("GraphSPN validation grid is empty".into()))?;
    candidates.extend(g_scored.into_iter().map(|(_, c)| c));
    seconds.push(("GraphSPN".to_string(), clock.elapsed().as_secs_f64()));
    let mut timed =
        |name: &str,
         search: &dyn Fn(&mut Vec<CandidateScore>) -> Result<MrfSetting, ReproduceError>| {
            let clock = std::time::Instant::now();
            let chosen = search(&mut candidates);
            seconds.push((name.to_string(), clock.elapsed().as_secs_f64()));
            chosen
        };
    let base = &cfg.cooccurrence;
    let mrf2 = timed("MRF-2", &|c| {
        search_mrf("MRF-2", Mrf2::train, grid, base, &folds, &graphs, c)
    })?;
    let mrf3 = timed("MRF-3", &|c| {
        search_mrf("MRF-3", Mrf3::train, grid, base, &folds, &graphs, c)
    })?;
    Ok(Validation {
        seconds,
        test_building: test_building.into(),
        folds: folds.iter().map(|f| f.name.clone()).collect(),
        candidates,
        chosen: ModelSettings {
            graphspn,
            mrf2,
            mrf3,
        },
    })
}
