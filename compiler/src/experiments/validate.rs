//! Leave-one-training-building-out validation: chooses every model's settings
//! for one test building using only its training buildings:
//! - GraphSPN: Star structure, template temperature, evidence exponent,
//!   class-prior correction, decompositions (strategy and number) and how the
//!   decompositions' marginals are mixed (searched jointly);
//! - each MRF: potential form, coupling and evidence exponent (jointly), then the
//!   BP schedule at the winner;
//! - the tree mixture: potential form, coupling, prior exponent, evidence exponent,
//!   number of trees and mixing (jointly, counted potentials), then the noise-aware
//!   fit of the potentials at the winner (none or each penalty of the grid).
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

use super::config::ReproduceConfig;
use super::error::ReproduceError;
use super::evidence::{derive_seed, map_truth, simulate_map_evidence_with};
use super::grid::ValidationGrid;
use super::models::{graphspn_rows, mrf_marginals};
use super::protocol::{
    TAG_VALIDATE, accuracy, build_instance, building_key, pick_maps, train_trees,
    training_buildings,
};
pub use super::settings::{DecompositionChoice, GraphSpnSetting, ModelSettings, MrfSetting};
use crate::learn::{Progress, TrainingSettings, train_model};
use crate::map::stats::class_prior;
use crate::map::{ClassId, TopoMap};
use crate::mrf::{CooccurrenceParams, Mrf2, Mrf3, MrfModel};
use crate::progress::Bar;
use crate::template::Template;
use crate::treemix::{NoiseFit, SpanningTrees, TreeInstance, TreeTraining};

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

/// The name of a fold trained on `train` and validated on `validate`:
/// `A+B → C` ([`Validation::folds`]; [`fold_buildings`] reads it back).
pub fn fold_name(train: &[&str], validate: &str) -> String {
    format!("{} → {validate}", train.join("+"))
}

/// The buildings of a fold named by [`fold_name`]: those trained on and the one
/// validated on; `None` for a name of another form.
pub fn fold_buildings(name: &str) -> Option<(Vec<&str>, &str)> {
    let (train, validate) = name.split_once(" → ")?;
    Some((train.split('+').collect(), validate))
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
    cfg: &ReproduceConfig,
    folds: &[Fold],
    graphs: &[VGraph],
    out: &mut Vec<CandidateScore>,
) -> Result<MrfSetting, ReproduceError> {
    let (grid, base) = (&cfg.grid, &cfg.cooccurrence);
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
    let bar = cfg
        .progress
        .bar(cands.len() as u64, &format!("{name} settings"));
    let scored = cands
        .par_iter()
        .map(|s| {
            let models = folds
                .iter()
                .map(|f| train(&f.train, &s.potentials))
                .collect::<Result<Vec<_>, _>>()
                .map_err(mrf_err)?;
            let pf = score_mrf(&models, s, folds, graphs)?;
            bar.inc(1);
            Ok((s.clone(), candidate(name, (s.label(), s.options()), pf)))
        })
        .collect::<Result<Vec<_>, ReproduceError>>()?;
    bar.finish_and_clear();
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

/// Scores tree-mixture settings on every validation graph: `acc[candidate][graph]`.
fn score_trees(
    settings: &[TreeTraining],
    seed: u64,
    folds: &[Fold],
    graphs: &[VGraph],
    bar: &Bar,
) -> Result<Vec<Vec<f64>>, ReproduceError> {
    let err = |what: &str| {
        let what = what.to_string();
        move |source| ReproduceError::Trees { what, source }
    };
    // One set of forests per (count, fold, map): every candidate sees the same ones.
    let mut counts: Vec<usize> = settings.iter().map(|s| s.trees).collect();
    counts.sort_unstable();
    counts.dedup();
    let mut forests: BTreeMap<(usize, usize, usize), SpanningTrees> = BTreeMap::new();
    for &t in &counts {
        for (f, fold) in folds.iter().enumerate() {
            for (m, map) in fold.val.iter().enumerate() {
                let s = derive_seed(seed, &[TAG_VALIDATE, fold.key, m as u64, 7]);
                let trees = SpanningTrees::covering(map, t, s).map_err(err(&map.name))?;
                forests.insert((t, f, m), trees);
            }
        }
    }
    settings
        .par_iter()
        .enumerate()
        .map(|(i, st)| {
            let models = folds
                .iter()
                .map(|f| train_trees(&f.train, st, seed, 200 + f.key + i as u64, &f.name))
                .collect::<Result<Vec<_>, _>>()?;
            let acc = graphs
                .iter()
                .map(|g| {
                    let map = &folds[g.fold].val[g.map];
                    let trees = forests[&(st.trees, g.fold, g.map)].clone();
                    let mut inst =
                        TreeInstance::build(&models[g.fold], map, trees).map_err(err(&map.name))?;
                    inst.set_all_evidence(&g.rows).map_err(err(&map.name))?;
                    let p = inst.marginals().map_err(err(&map.name))?.mixed.probs;
                    Ok(accuracy(&p, &g.truth, &g.scored))
                })
                .collect::<Result<Vec<f64>, ReproduceError>>();
            bar.inc(1);
            acc
        })
        .collect()
}

/// Searches the tree mixture's settings: the counted-potential grid jointly, then
/// the noise-aware fits at the winner.
fn search_trees(
    grid: &ValidationGrid,
    seed: u64,
    folds: &[Fold],
    graphs: &[VGraph],
    progress: Progress,
    out: &mut Vec<CandidateScore>,
) -> Result<TreeTraining, ReproduceError> {
    let mut cands = Vec::new();
    for &normalisation in &grid.tree_forms {
        for &coupling in &grid.tree_couplings {
            for &rho in &grid.tree_prior_exponents {
                for &gamma in &grid.tree_exponents {
                    for &trees in &grid.tree_counts {
                        for &mixing in &grid.tree_mixings {
                            let mut t = TreeTraining::default();
                            t.potentials.normalisation = normalisation;
                            t.potentials.coupling = coupling;
                            t.prior_exponent = rho;
                            t.evidence_exponent = gamma;
                            t.trees = trees;
                            t.mixing = mixing;
                            cands.push(t);
                        }
                    }
                }
            }
        }
    }
    let name = "Tree mixture";
    let scored_of =
        |cands: &[TreeTraining]| -> Result<Vec<(TreeTraining, CandidateScore)>, ReproduceError> {
            let bar = progress.bar(cands.len() as u64, "tree-mixture settings");
            let acc = score_trees(cands, seed, folds, graphs, &bar)?;
            bar.finish_and_clear();
            Ok(cands
                .iter()
                .zip(acc)
                .map(|(s, a)| {
                    let c = candidate(
                        name,
                        (s.label(), s.options()),
                        fold_scores(graphs, &a, folds.len()),
                    );
                    (s.clone(), c)
                })
                .collect())
        };
    let scored = scored_of(&cands)?;
    let mut chosen = best(&scored)
        .ok_or_else(|| ReproduceError::Config("tree-mixture validation grid is empty".into()))?;
    let mut chosen_score = scored
        .iter()
        .find(|(s, _)| *s == chosen)
        .map(|(_, c)| c.score)
        .unwrap_or(f64::NEG_INFINITY);
    out.extend(scored.into_iter().map(|(_, c)| c));
    let fits: Vec<TreeTraining> = grid
        .tree_fit_penalties
        .iter()
        .map(|&penalty| TreeTraining {
            fit: Some(NoiseFit {
                penalty,
                rounds: 1,
                seed: 0,
            }),
            ..chosen.clone()
        })
        .collect();
    if !fits.is_empty() {
        for (s, c) in scored_of(&fits)? {
            if c.score > chosen_score {
                chosen_score = c.score;
                chosen = s;
            }
            out.push(c);
        }
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
    grid.check()
        .map_err(|e| ReproduceError::Config(format!("validation grid: {e}")))?;
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
            name: fold_name(&names, v),
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
    let bar = cfg.progress.bar(
        (grid.graphspn_variants.len()
            * grid.graphspn_temperatures.len()
            * grid.graphspn_decompositions.len()) as u64,
        "GraphSPN settings",
    );
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
                bar.inc(1);
            }
        }
    }
    bar.finish_and_clear();
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
    let mrf2 = timed("MRF-2", &|c| {
        search_mrf("MRF-2", Mrf2::train, cfg, &folds, &graphs, c)
    })?;
    let mrf3 = timed("MRF-3", &|c| {
        search_mrf("MRF-3", Mrf3::train, cfg, &folds, &graphs, c)
    })?;
    let clock = std::time::Instant::now();
    let trees = search_trees(
        grid,
        cfg.seed,
        &folds,
        &graphs,
        cfg.progress,
        &mut candidates,
    )?;
    seconds.push(("Tree mixture".to_string(), clock.elapsed().as_secs_f64()));
    Ok(Validation {
        seconds,
        test_building: test_building.into(),
        folds: folds.iter().map(|f| f.name.clone()).collect(),
        candidates,
        chosen: ModelSettings {
            graphspn,
            mrf2,
            mrf3,
            trees,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::{fold_buildings, fold_name};

    /// A fold's name gives back its buildings (what `--settings` checks a run's
    /// training buildings against).
    #[test]
    fn a_fold_name_reads_back_as_its_buildings() {
        let name = fold_name(&["Freiburg", "Saarbrucken"], "Stockholm");
        assert_eq!(name, "Freiburg+Saarbrucken → Stockholm");
        assert_eq!(
            fold_buildings(&name),
            Some((vec!["Freiburg", "Saarbrucken"], "Stockholm"))
        );
        assert_eq!(fold_buildings("Freiburg to Stockholm"), None);
    }
}
