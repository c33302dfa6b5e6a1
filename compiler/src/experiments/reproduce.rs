//! The paper's experiments end to end (the `graphspn reproduce` command):
//! for each test building, train every model ([`super::models::MODELS`]: the tree
//! mixture, GraphSPN, MRF-2 and MRF-3, validated, and the paper-style ones) on the
//! other buildings, then on `maps_per_building` seeded test maps × `rounds` evidence
//! rounds × every noise level measure
//! - classification accuracy over all places (the paper's Fig. 5),
//! - accuracy on placeholders given no evidence (Table 2),
//!
//! and, with certain labels and no evidence, the per-variable log-likelihood of
//! original / consistent-swap / novel-swap labellings (novelty detection, Fig. 7).
//!
//! Every random step's seed is derived from `(seed, building, map, level, round,
//! experiment)` with [`derive_seed`], and parallel work is collected in a fixed
//! order, so results do not depend on the number of threads.

use std::collections::BTreeMap;
use std::path::Path;

use rayon::prelude::*;

use super::ceiling::placeholder_ceiling;
use super::config::{ReproduceConfig, check_settings};
pub use super::error::ReproduceError;
use super::evidence::{
    LevelStats, NoiseLevel, SimulatedEvidence, WrongClassDraw, derive_seed, level_statistics,
    map_truth, simulate_map_evidence_with,
};
use super::models::{
    MODELS, MRF_MODELS, NUM_MODELS, Scores, graphspn_marginals, mrf_marginals, tree_marginals,
};
use super::novelty::{
    NoveltyResult, NoveltySet, auc, novelty_labellings, novelty_points, within_map_auc,
};
use super::protocol::{
    TAG_EVIDENCE, TAG_NOVELTY, TAG_PICK, TAG_TRAIN, accuracy, build_instance, building_key,
    pick_maps, train_trees, training_buildings, tree_instance,
};
use super::results::{BuildingInfo, Experiment, GraphResult, Reproduction, SetScores, Table1Row};
use super::settings::{GraphSpnSetting, ModelSettings, MrfSetting};
use super::validate::{Validation, validate_for};
use crate::instance::ComponentInstance;
use crate::learn::{Model, Progress, TrainingSettings, train_model};
pub use crate::map::stats::class_prior;
use crate::map::{ClassId, TopoMap, cold};
use crate::mrf::{Mrf2, Mrf3, MrfModel};
use crate::template::Template;
use crate::treemix::{TreeInstance, TreeMixture};

/// A trained test setup for one building.
pub struct BuildingSetup {
    /// Test building.
    pub building: String,
    /// The GraphSPN model with validated settings.
    pub model: Model,
    /// The paper-style GraphSPN model.
    pub model_paper: Model,
    /// The tree mixture with validated settings.
    pub trees: TreeMixture,
    /// Class shares of the training maps ([`class_prior`]).
    pub class_prior: Vec<f64>,
    /// MRF-2 with validated settings.
    pub mrf2: Mrf2,
    /// MRF-3 with validated settings.
    pub mrf3: Mrf3,
    /// Paper-style MRF-2 (raw joint frequencies).
    pub mrf2_paper: Mrf2,
    /// Paper-style MRF-3.
    pub mrf3_paper: Mrf3,
    /// Settings of every model.
    pub settings: ModelSettings,
    /// Test maps.
    pub maps: Vec<TopoMap>,
    /// Per test map: the validated GraphSPN's instance (no evidence set).
    pub instances: Vec<ComponentInstance>,
    /// Per test map: the paper-style GraphSPN's instance.
    pub instances_paper: Vec<ComponentInstance>,
    /// Per test map: the tree mixture's instance (no evidence set).
    pub tree_instances: Vec<TreeInstance>,
    /// Facts for the report.
    pub info: BuildingInfo,
}

/// Trains the three models for `test_building` on the other buildings' maps in
/// `all` (building name → maps), picks the test maps and builds their instances.
pub fn setup_building(
    all: &BTreeMap<String, Vec<TopoMap>>,
    test_building: &str,
    cfg: &ReproduceConfig,
    settings: ModelSettings,
) -> Result<BuildingSetup, ReproduceError> {
    let b = building_key(test_building);
    let trained_on = training_buildings(all, test_building, cfg)?;
    let train_maps: Vec<TopoMap> = trained_on
        .iter()
        .flat_map(|k| all[k].iter().cloned())
        .collect();
    let candidates = all
        .get(test_building)
        .ok_or_else(|| ReproduceError::Config(format!("no maps for {test_building}")))?;
    let maps = pick_maps(candidates, cfg.maps_per_building, cfg.seed, b, TAG_PICK)
        .map_err(|e| ReproduceError::Config(format!("{test_building}: {e}")))?;
    let train = |g: &GraphSpnSetting| {
        let settings_g = TrainingSettings {
            seed: derive_seed(cfg.seed, &[TAG_TRAIN, b]),
            ..g.training.clone()
        };
        train_model(
            &train_maps,
            &Template::paper_set(),
            &settings_g,
            Progress::Hidden,
        )
        .map(|(model, _)| model)
        .map_err(|source| ReproduceError::Train {
            building: test_building.into(),
            source,
        })
    };
    let t0 = std::time::Instant::now();
    let model = train(&settings.graphspn)?;
    let class_prior = class_prior(&train_maps, model.classes.len());
    let train_seconds = t0.elapsed().as_secs_f64();
    let model_paper = train(&cfg.graphspn_paper)?;
    let t1 = std::time::Instant::now();
    let trees = train_trees(&train_maps, &settings.trees, cfg.seed, b, test_building)?;
    let train_seconds_trees = t1.elapsed().as_secs_f64();
    let mrf = |source| ReproduceError::Mrf {
        what: format!("training for {test_building}"),
        source,
    };
    let mrf2 = Mrf2::train(&train_maps, &settings.mrf2.potentials).map_err(mrf)?;
    let mrf3 = Mrf3::train(&train_maps, &settings.mrf3.potentials).map_err(mrf)?;
    let mrf2_paper = Mrf2::train(&train_maps, &cfg.cooccurrence).map_err(mrf)?;
    let mrf3_paper = Mrf3::train(&train_maps, &cfg.cooccurrence).map_err(mrf)?;
    let instances_of = |model: &Model, g: &GraphSpnSetting| {
        maps.par_iter()
            .enumerate()
            .map(|(m, map)| build_instance(model, map, &g.decompositions, cfg.seed, b, m as u64))
            .collect::<Result<Vec<_>, _>>()
    };
    let instances = instances_of(&model, &settings.graphspn)?;
    let instances_paper = instances_of(&model_paper, &cfg.graphspn_paper)?;
    let tree_instances = maps
        .iter()
        .enumerate()
        .map(|(m, map)| tree_instance(&trees, map, cfg.seed, b, m as u64))
        .collect::<Result<Vec<_>, _>>()?;
    let info = BuildingInfo {
        building: test_building.into(),
        trained_on,
        test_maps: maps.iter().map(|m| m.name.clone()).collect(),
        train_seconds,
        train_seconds_trees,
        settings: settings.clone(),
    };
    Ok(BuildingSetup {
        building: test_building.into(),
        model,
        model_paper,
        trees,
        class_prior,
        mrf2,
        mrf3,
        mrf2_paper,
        mrf3_paper,
        settings,
        maps,
        instances,
        instances_paper,
        tree_instances,
        info,
    })
}

/// The full outcome of one test graph (kept for figures).
pub struct GraphOutcome {
    /// Scores.
    pub result: GraphResult,
    /// The simulated evidence.
    pub evidence: SimulatedEvidence,
    /// Marginals per model.
    pub marginals: Scores<Vec<Vec<f64>>>,
}

/// Runs the three models on map `m` of `setup` at `level`, round `round`.
pub fn run_graph(
    setup: &BuildingSetup,
    m: usize,
    level: NoiseLevel,
    round: usize,
    experiment: Experiment,
    cfg: &ReproduceConfig,
) -> Result<GraphOutcome, ReproduceError> {
    let map = &setup.maps[m];
    let b = building_key(&setup.building);
    let seed = derive_seed(
        cfg.seed,
        &[
            TAG_EVIDENCE,
            b,
            m as u64,
            level.get() as u64,
            round as u64,
            experiment as u64,
        ],
    );
    let placeholders = experiment == Experiment::Placeholders;
    let evi = |source| ReproduceError::Evidence {
        map: map.name.clone(),
        source,
    };
    let ev =
        simulate_map_evidence_with(map, level, placeholders, seed, cfg.wrong_draw).map_err(evi)?;
    let truth = map_truth(map).map_err(evi)?;
    let scored: Vec<usize> = (0..map.num_places())
        .filter(|&i| !placeholders || map.place(i).placeholder)
        .collect();
    let t = tree_marginals(&setup.tree_instances[m], map, &ev.rows)?;
    let g = graphspn_marginals(
        &setup.instances[m],
        map,
        &ev.rows,
        &setup.settings.graphspn,
        &setup.class_prior,
    )?;
    let gp = graphspn_marginals(
        &setup.instances_paper[m],
        map,
        &ev.rows,
        &cfg.graphspn_paper,
        &setup.class_prior,
    )?;
    let r2 = mrf_marginals(&setup.mrf2, &setup.settings.mrf2, map, &ev.rows)?;
    let r3 = mrf_marginals(&setup.mrf3, &setup.settings.mrf3, map, &ev.rows)?;
    let paper = MrfSetting::paper(cfg.bp);
    let p2 = mrf_marginals(&setup.mrf2_paper, &paper, map, &ev.rows)?;
    let p3 = mrf_marginals(&setup.mrf3_paper, &paper, map, &ev.rows)?;
    let converged = [r2.converged, r3.converged, p2.converged, p3.converged];
    // In MODELS order.
    let marginals = Scores([
        t,
        g,
        r2.marginals,
        r3.marginals,
        gp,
        p2.marginals,
        p3.marginals,
    ]);
    let result = GraphResult {
        building: setup.building.clone(),
        map: map.name.clone(),
        level: level.get(),
        round,
        experiment,
        scored: scored.len(),
        evidence_only: accuracy(&ev.rows, &truth, &scored),
        accuracy: Scores::from_fn(|k| accuracy(&marginals[k], &truth, &scored)),
        bp_converged: MRF_MODELS
            .iter()
            .zip(converged)
            .map(|(&k, c)| (MODELS[k].to_string(), c))
            .collect(),
    };
    Ok(GraphOutcome {
        result,
        evidence: ev,
        marginals,
    })
}

/// Per-variable log-likelihoods of the novelty labellings of map `m`
/// ([`novelty_labellings`]).
pub fn run_novelty(
    setup: &BuildingSetup,
    m: usize,
    cfg: &ReproduceConfig,
) -> Result<Vec<NoveltyResult>, ReproduceError> {
    let map = &setup.maps[m];
    let truth = map_truth(map).map_err(|source| ReproduceError::Evidence {
        map: map.name.clone(),
        source,
    })?;
    let b = building_key(&setup.building);
    let labellings = novelty_labellings(
        map,
        &truth,
        derive_seed(cfg.seed, &[TAG_NOVELTY, b, m as u64]),
    );
    let n = map.num_places() as f64;
    let gerr = |source| ReproduceError::Inference {
        map: map.name.clone(),
        source,
    };
    let graphspn = |inst: &ComponentInstance| {
        let mut inst = inst.clone();
        labellings
            .iter()
            .map(|l| {
                let fixed: Vec<Option<ClassId>> = l.labels.iter().map(|&c| Some(c)).collect();
                inst.log_likelihood_labelled(&fixed).map_err(gerr)
            })
            .collect::<Result<Vec<f64>, _>>()
    };
    let mrf_err = |source| ReproduceError::Mrf {
        what: map.name.clone(),
        source,
    };
    let all: Vec<Vec<ClassId>> = labellings.iter().map(|l| l.labels.clone()).collect();
    let trees = labellings
        .iter()
        .map(|l| {
            let fixed: Vec<Option<ClassId>> = l.labels.iter().map(|&c| Some(c)).collect();
            setup.tree_instances[m]
                .log_likelihood_labelled(&fixed)
                .map_err(|source| ReproduceError::Trees {
                    what: map.name.clone(),
                    source,
                })
        })
        .collect::<Result<Vec<f64>, _>>()?;
    let st = &setup.settings;
    // In MODELS order.
    let scores: [Vec<f64>; NUM_MODELS] = [
        trees,
        graphspn(&setup.instances[m])?,
        setup
            .mrf2
            .log_likelihoods_labelled(map, &all, &st.mrf2.bp)
            .map_err(mrf_err)?
            .0,
        setup
            .mrf3
            .log_likelihoods_labelled(map, &all, &st.mrf3.bp)
            .map_err(mrf_err)?
            .0,
        graphspn(&setup.instances_paper[m])?,
        setup
            .mrf2_paper
            .log_likelihoods_labelled(map, &all, &cfg.bp)
            .map_err(mrf_err)?
            .0,
        setup
            .mrf3_paper
            .log_likelihoods_labelled(map, &all, &cfg.bp)
            .map_err(mrf_err)?
            .0,
    ];
    Ok(labellings
        .iter()
        .enumerate()
        .map(|(i, l)| NoveltyResult {
            building: setup.building.clone(),
            map: map.name.clone(),
            variant: l.name.clone(),
            set: l.set,
            novel: l.novel,
            variables: map.num_places(),
            score: Scores::from_fn(|k| scores[k][i] / n),
        })
        .collect())
}

/// Loads every building's maps.
pub fn load_data(data: &Path) -> Result<BTreeMap<String, Vec<TopoMap>>, ReproduceError> {
    cold::BUILDINGS
        .iter()
        .map(|b| {
            cold::load_building(data, b)
                .map(|m| (b.to_string(), m))
                .map_err(|source| ReproduceError::Load {
                    building: b.to_string(),
                    source,
                })
        })
        .collect()
}

/// Runs every experiment of `cfg` on the maps in `all`; returns the results
/// and the per-building setups (for figures).
pub fn run(
    all: &BTreeMap<String, Vec<TopoMap>>,
    cfg: &ReproduceConfig,
) -> Result<(Reproduction, Vec<BuildingSetup>), ReproduceError> {
    if cfg.levels.is_empty() || cfg.rounds == 0 {
        return Err(ReproduceError::Config(
            "need at least one level and one round".into(),
        ));
    }
    check_settings(cfg)?;
    let mut validation: Vec<Validation> = Vec::new();
    let mut setups = Vec::new();
    for b in &cfg.test_buildings {
        let settings = match &cfg.settings {
            Some(given) => given.get(b).cloned().ok_or_else(|| {
                ReproduceError::Config(format!("no settings given for test building {b}"))
            })?,
            // Fixed training buildings: one validation serves every test building.
            None if cfg.train_buildings.is_some() && !validation.is_empty() => {
                validation[0].chosen.clone()
            }
            None => {
                let v = validate_for(all, b, cfg)?;
                let chosen = v.chosen.clone();
                validation.push(v);
                chosen
            }
        };
        setups.push(setup_building(all, b, cfg, settings)?);
    }
    // Every test graph: (setup, map, level, round, experiment).
    let mut jobs = Vec::new();
    for (s, setup) in setups.iter().enumerate() {
        for m in 0..setup.maps.len() {
            for &level in &cfg.levels {
                for round in 0..cfg.rounds {
                    for e in [Experiment::Classification, Experiment::Placeholders] {
                        jobs.push((s, m, level, round, e));
                    }
                }
            }
        }
    }
    let bar = cfg.progress.bar(jobs.len() as u64, "test graphs");
    let graphs = jobs
        .par_iter()
        .map(|&(s, m, level, round, e)| {
            let r = run_graph(&setups[s], m, level, round, e, cfg).map(|o| o.result);
            bar.inc(1);
            r
        })
        .collect::<Result<Vec<_>, _>>()?;
    bar.finish_and_clear();
    let mut novelty = Vec::new();
    let mut auc_v = Vec::new();
    let mut within = Vec::new();
    if cfg.novelty {
        let njobs: Vec<(usize, usize)> = setups
            .iter()
            .enumerate()
            .flat_map(|(s, st)| (0..st.maps.len()).map(move |m| (s, m)))
            .collect();
        let bar = cfg.progress.bar(njobs.len() as u64, "novelty maps");
        let per = njobs
            .par_iter()
            .map(|&(s, m)| {
                let r = run_novelty(&setups[s], m, cfg);
                bar.inc(1);
                r
            })
            .collect::<Result<Vec<_>, _>>()?;
        bar.finish_and_clear();
        novelty = per.into_iter().flatten().collect();
        for set in [NoveltySet::Paper, NoveltySet::Local] {
            let a = Scores::from_fn(|k| auc(&novelty_points(&novelty, set, k)));
            let w = Scores::from_fn(|k| within_map_auc(&novelty, set, k));
            auc_v.push(SetScores { set, scores: a });
            within.push(SetScores { set, scores: w });
        }
    }
    // Table 1 statistics on the test maps' ground truth.
    let truths: Vec<Vec<ClassId>> = setups
        .iter()
        .flat_map(|s| s.maps.iter())
        .map(map_truth)
        .collect::<Result<_, _>>()
        .map_err(|source| ReproduceError::Evidence {
            map: "test maps".into(),
            source,
        })?;
    let mut table1 = Vec::new();
    for &level in &cfg.levels {
        let st: LevelStats =
            level_statistics(&truths, 10, level, cfg.rounds, cfg.seed, cfg.wrong_draw).map_err(
                |source| ReproduceError::Evidence {
                    map: "test maps".into(),
                    source,
                },
            )?;
        table1.push(Table1Row {
            level: level.get(),
            d_groundtruth: st.d_groundtruth,
            d_incorrect: st.d_incorrect,
        });
    }
    let ceiling = setups
        .iter()
        .map(|s| {
            let train: Vec<TopoMap> = s
                .info
                .trained_on
                .iter()
                .flat_map(|k| all[k].iter().cloned())
                .collect();
            placeholder_ceiling(&s.building, &train, &s.maps)
        })
        .collect();
    let rep = Reproduction {
        seed: cfg.seed,
        ceiling,
        paper_noise: cfg.wrong_draw == WrongClassDraw::AnyClass,
        validation,
        buildings: setups.iter().map(|s| s.info.clone()).collect(),
        graphs,
        novelty,
        auc: auc_v,
        within_map: within,
        table1,
        seconds: 0.0,
        given_settings: None,
        evaluation: None,
    };
    Ok((rep, setups))
}
