//! Leave-one-training-building-out validation: chooses every model's settings
//! (GraphSPN's template structure and evidence exponent; each MRF's potential
//! form, coupling, evidence exponent and BP schedule) for one test building
//! using only the other buildings.
//!
//! For test building `T` with training buildings `{X, Y}` there are two folds:
//! train on `X`, validate on maps of `Y`, and the reverse. Each candidate
//! setting of a model is scored by its mean accuracy over the validation
//! graphs (classification over all places and placeholders without evidence,
//! pooled), averaged over the two folds; the best score wins (ties: the first
//! in grid order). MRF potentials and evidence exponent are searched jointly,
//! then the BP schedule at the chosen potential. No test-building map is read.

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::evidence::{NoiseLevel, derive_seed, map_truth, simulate_map_evidence_with};
use super::reproduce::{
    ReproduceConfig, ReproduceError, TAG_VALIDATE, accuracy, build_instance, graphspn_marginals,
    mrf_marginals, pick_maps,
};
use crate::interpreter::Evaluator;
use crate::learn::structure::SplitChoice;
use crate::learn::{Progress, TrainingSettings, train_model};
use crate::map::{ClassId, TopoMap, cold};
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

    /// Short description, e.g. `normalised^0.3, ev^1, sequential`.
    pub fn label(&self) -> String {
        format!(
            "{}^{}, ev^{}, {}{}",
            self.potentials.normalisation.name(),
            self.potentials.coupling,
            self.evidence_exponent,
            match self.bp.schedule {
                Schedule::Sequential => "sequential",
                Schedule::Parallel => "flooding",
            },
            if self.bp.damping > 0.0 {
                format!(" d={}", self.bp.damping)
            } else {
                String::new()
            }
        )
    }
}

/// Settings of GraphSPN.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GraphSpnSetting {
    /// Name of the training variant (template structure).
    pub variant: String,
    /// Training settings (the seed is replaced per building).
    pub training: TrainingSettings,
    /// Each evidence row is raised to this power and renormalised before inference.
    pub evidence_exponent: f64,
}

impl GraphSpnSetting {
    /// Short description, e.g. `most_images, ev^2`.
    pub fn label(&self) -> String {
        format!("{}, ev^{}", self.variant, self.evidence_exponent)
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
    /// The grid of `graphspn reproduce` / `graphspn validate`: 2 GraphSPN
    /// structures × 3 evidence exponents; 4 potential forms × 3 couplings × 2
    /// evidence exponents per MRF, then 2 BP schedules (at most 200 sweeps);
    /// 2 maps × NL2 and NL5 × 1 round per validation building. Kept small so the
    /// whole search takes minutes on 2 cores.
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
            graphspn_exponents: vec![1.0, 2.0, 3.0],
            normalisations: Normalisation::ALL.to_vec(),
            couplings: vec![0.3, 0.6, 1.0],
            mrf_exponents: vec![1.0, 2.0],
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

    /// A tiny grid for smoke tests: 2 GraphSPN exponents, 2 forms × 2 couplings,
    /// 1 map at NL2 per validation building.
    pub fn tiny() -> Self {
        let bp = BpOptions {
            max_iterations: 200,
            ..BpOptions::default()
        };
        ValidationGrid {
            graphspn_variants: vec![variant("most_images", SplitChoice::MostImages)],
            graphspn_exponents: vec![1.0, 2.0],
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

fn candidate(model: &str, setting: String, per_fold: Vec<f64>) -> CandidateScore {
    let score = per_fold.iter().sum::<f64>() / per_fold.len().max(1) as f64;
    CandidateScore {
        model: model.into(),
        setting,
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
            Ok((s.clone(), candidate(name, s.label(), pf)))
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
                Ok((s.clone(), candidate(name, s.label(), pf)))
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

fn building_key(b: &str) -> u64 {
    cold::BUILDINGS
        .iter()
        .position(|x| *x == b)
        .unwrap_or(cold::BUILDINGS.len()) as u64
}

/// Validates every model's settings for `test_building` on the other buildings
/// of `all` (see the module docs). Needs at least two other buildings.
pub fn validate_for(
    all: &BTreeMap<String, Vec<TopoMap>>,
    test_building: &str,
    cfg: &ReproduceConfig,
) -> Result<Validation, ReproduceError> {
    let grid = &cfg.grid;
    let others: Vec<&String> = all.keys().filter(|k| *k != test_building).collect();
    if others.len() < 2 {
        return Err(ReproduceError::Config(format!(
            "validation for {test_building} needs two other buildings, found {}",
            others.len()
        )));
    }
    if grid.levels.is_empty() || grid.rounds == 0 {
        return Err(ReproduceError::Config(
            "validation needs at least one level and one round".into(),
        ));
    }
    let tb = building_key(test_building);
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
            key: tb * 16 + vb,
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

    // GraphSPN: train each variant on each fold, then score every exponent.
    let jobs: Vec<(usize, usize)> = (0..grid.graphspn_variants.len())
        .flat_map(|v| (0..folds.len()).map(move |f| (v, f)))
        .collect();
    let trained = jobs
        .par_iter()
        .map(|&(v, f)| {
            let fold = &folds[f];
            let settings = TrainingSettings {
                seed: derive_seed(cfg.seed, &[TAG_VALIDATE, fold.key, v as u64]),
                ..grid.graphspn_variants[v].1.clone()
            };
            let (model, _) = train_model(
                &fold.train,
                &Template::paper_set(),
                &settings,
                Progress::Hidden,
            )
            .map_err(|source| ReproduceError::Train {
                building: format!("validation fold {}", fold.name),
                source,
            })?;
            let inst = fold
                .val
                .iter()
                .enumerate()
                .map(|(m, map)| build_instance(&model, map, cfg, 100 + fold.key, m as u64))
                .collect::<Result<Vec<_>, _>>()?;
            Ok(inst.into_iter().map(|(_, e)| e).collect::<Vec<Evaluator>>())
        })
        .collect::<Result<Vec<_>, ReproduceError>>()?;
    let mut g_scored = Vec::new();
    for (v, (vname, vsettings)) in grid.graphspn_variants.iter().enumerate() {
        for &e in &grid.graphspn_exponents {
            let acc = graphs
                .par_iter()
                .map(|g| {
                    let ev = &trained[v * folds.len() + g.fold][g.map];
                    let map = &folds[g.fold].val[g.map];
                    let p = graphspn_marginals(ev, map, &g.rows, e)?;
                    Ok(accuracy(&p, &g.truth, &g.scored))
                })
                .collect::<Result<Vec<_>, ReproduceError>>()?;
            let s = GraphSpnSetting {
                variant: vname.clone(),
                training: vsettings.clone(),
                evidence_exponent: e,
            };
            let c = candidate(
                "GraphSPN",
                s.label(),
                fold_scores(&graphs, &acc, folds.len()),
            );
            g_scored.push((s, c));
        }
    }
    let graphspn = best(&g_scored)
        .ok_or_else(|| ReproduceError::Config("GraphSPN validation grid is empty".into()))?;
    candidates.extend(g_scored.into_iter().map(|(_, c)| c));

    let mrf2 = search_mrf(
        "MRF-2",
        Mrf2::train,
        grid,
        &cfg.cooccurrence,
        &folds,
        &graphs,
        &mut candidates,
    )?;
    let mrf3 = search_mrf(
        "MRF-3",
        Mrf3::train,
        grid,
        &cfg.cooccurrence,
        &folds,
        &graphs,
        &mut candidates,
    )?;
    Ok(Validation {
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
