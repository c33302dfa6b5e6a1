//! The steps of the protocol that validation and reproduction share: seed tags and
//! building keys, which buildings a test building's models are trained on, the seeded
//! choice of maps, training the tree mixture, each map's GraphSPN and tree-mixture
//! instances, and the tie-aware accuracy every graph is scored by.

use std::collections::BTreeMap;

use rand::SeedableRng;
use rand::seq::index::sample;
use rand_chacha::ChaCha8Rng;

use super::config::ReproduceConfig;
use super::error::ReproduceError;
use super::evidence::derive_seed;
use super::settings::DecompositionChoice;
use crate::decompose::decompose_best;
use crate::instance::ComponentInstance;
use crate::learn::Model;
use crate::map::{ClassId, TopoMap, cold};
use crate::treemix::{NoiseFit, TreeInstance, TreeMixture, train_tree_mixture};

/// The seed key of a building (a named group of maps): its index in
/// [`cold::BUILDINGS`] for the COLD buildings, else a stable hash of its name
/// (FNV-1a, above 1,000), so every random step of a run is reproducible whatever
/// the buildings are called.
pub fn building_key(name: &str) -> u64 {
    if let Some(i) = cold::BUILDINGS.iter().position(|x| *x == name) {
        return i as u64;
    }
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in name.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    1000 + (h >> 24)
}

/// The buildings `test_building`'s models are trained on: `cfg.train_buildings`
/// when given, else every other building of `all`. Errors when one is missing from
/// `all` or is the test building itself.
pub fn training_buildings(
    all: &BTreeMap<String, Vec<TopoMap>>,
    test_building: &str,
    cfg: &ReproduceConfig,
) -> Result<Vec<String>, ReproduceError> {
    let names: Vec<String> = match &cfg.train_buildings {
        Some(t) => t.clone(),
        None => all
            .keys()
            .filter(|k| k.as_str() != test_building)
            .cloned()
            .collect(),
    };
    for n in &names {
        if n == test_building {
            return Err(ReproduceError::Config(format!(
                "building {n:?} is both a training and the test building"
            )));
        }
        if !all.contains_key(n) {
            return Err(ReproduceError::Config(format!(
                "no maps for training building {n:?}"
            )));
        }
    }
    if names.is_empty() {
        return Err(ReproduceError::Config(format!(
            "no training building for test building {test_building:?}"
        )));
    }
    Ok(names)
}

/// Seed tags, so different kinds of random steps never share a seed.
pub(crate) const TAG_PICK: u64 = 1;
pub(crate) const TAG_TRAIN: u64 = 2;
const TAG_DECOMPOSE: u64 = 3;
pub(crate) const TAG_EVIDENCE: u64 = 4;
pub(crate) const TAG_NOVELTY: u64 = 6;
const TAG_TREES: u64 = 7;
/// Seed tag of the validation's random steps.
pub(crate) const TAG_VALIDATE: u64 = 5;

/// The tree mixture of `settings` trained on `maps`, its noise-aware fit (if any)
/// seeded by `(seed, TAG_TREES, b)`.
pub(crate) fn train_trees(
    maps: &[TopoMap],
    settings: &crate::treemix::TreeTraining,
    seed: u64,
    b: u64,
    what: &str,
) -> Result<TreeMixture, ReproduceError> {
    let mut s = settings.clone();
    if let Some(fit) = &mut s.fit {
        *fit = NoiseFit {
            seed: derive_seed(seed, &[TAG_TREES, b]),
            ..*fit
        };
    }
    train_tree_mixture(maps, &s).map_err(|source| ReproduceError::Trees {
        what: format!("training for {what}"),
        source,
    })
}

/// The tree-mixture instance of `map` (no evidence), its forests seeded by
/// `(seed, TAG_DECOMPOSE, b, m)` like GraphSPN's decompositions.
pub(crate) fn tree_instance(
    model: &TreeMixture,
    map: &TopoMap,
    seed: u64,
    b: u64,
    m: u64,
) -> Result<TreeInstance, ReproduceError> {
    TreeInstance::with_covering_trees(model, map, derive_seed(seed, &[TAG_DECOMPOSE, b, m]))
        .map_err(|source| ReproduceError::Trees {
            what: map.name.clone(),
            source,
        })
}

/// `count` maps of `candidates` chosen at random (seeded by `(seed, tag, b)`),
/// in their original order; all of them when `count ≥ candidates.len()`.
pub(crate) fn pick_maps(
    candidates: &[TopoMap],
    count: usize,
    seed: u64,
    b: u64,
    tag: u64,
) -> Result<Vec<TopoMap>, String> {
    if count == 0 || candidates.is_empty() {
        return Err(format!(
            "{} maps available, {count} requested",
            candidates.len()
        ));
    }
    if count >= candidates.len() {
        return Ok(candidates.to_vec());
    }
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(seed, &[tag, b]));
    let mut picked = sample(&mut rng, candidates.len(), count).into_vec();
    picked.sort_unstable();
    Ok(picked.iter().map(|&i| candidates[i].clone()).collect())
}

/// The instance GraphSPN of `map` (component-wise evaluator, no evidence) mixing
/// the decompositions `dc` asks for, seeded by `(seed, TAG_DECOMPOSE, b, m)`.
pub(crate) fn build_instance(
    model: &Model,
    map: &TopoMap,
    dc: &DecompositionChoice,
    seed: u64,
    b: u64,
    m: u64,
) -> Result<ComponentInstance, ReproduceError> {
    let params = dc.params(derive_seed(seed, &[TAG_DECOMPOSE, b, m]));
    let decs = decompose_best(map, &model.templates, &params).map_err(|source| {
        ReproduceError::Decompose {
            map: map.name.clone(),
            source,
        }
    })?;
    ComponentInstance::build(model, map, decs).map_err(|source| ReproduceError::Inference {
        map: map.name.clone(),
        source,
    })
}

/// Accuracy of `probs` against `truth` over the places in `scored`; a place
/// whose maximum is shared by `k` classes counts `1/k` if the truth is among them.
pub fn accuracy(probs: &[Vec<f64>], truth: &[ClassId], scored: &[usize]) -> f64 {
    if scored.is_empty() {
        return f64::NAN;
    }
    let mut hits = 0.0;
    for &i in scored {
        let row = &probs[i];
        let max = row.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let ties = row.iter().filter(|&&v| v == max).count();
        if row[truth[i] as usize] == max {
            hits += 1.0 / ties as f64;
        }
    }
    hits / scored.len() as f64
}
