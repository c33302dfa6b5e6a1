//! The statistics behind the report's tables and figures: per-map means, bootstrap
//! intervals over maps and the better tuned MRF of a cell.

use super::evidence::derive_seed;
use super::models::{MRF2, MRF3};
use super::results::{Experiment, GraphResult, Reproduction};

/// Mean and (population) standard deviation of the finite values, or `None`.
pub fn mean_std(v: &[f64]) -> Option<(f64, f64)> {
    let v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let s = (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n).sqrt();
    Some((m, s))
}

/// Accuracies of `model` (index into [`MODELS`](super::models::MODELS), or `None` = evidence only) for
/// one building (or all when `building` is `None`), experiment and level.
pub fn select(
    rep: &Reproduction,
    model: Option<usize>,
    building: Option<&str>,
    e: Experiment,
    level: u8,
) -> Vec<f64> {
    rep.graphs
        .iter()
        .filter(|g| {
            g.experiment == e && g.level == level && building.is_none_or(|b| g.building == b)
        })
        .map(|g| match model {
            Some(k) => g.accuracy[k],
            None => g.evidence_only,
        })
        .collect()
}

/// The noise levels of the run's test graphs, ascending.
pub(crate) fn levels_of(rep: &Reproduction) -> Vec<u8> {
    let mut l: Vec<u8> = rep.graphs.iter().map(|g| g.level).collect();
    l.sort_unstable();
    l.dedup();
    l
}

/// Number of bootstrap resamples behind every interval.
pub const BOOTSTRAP_RESAMPLES: usize = 2000;

/// Mean of `per_map` and its 95% percentile bootstrap interval over maps
/// (resampling maps with replacement, `BOOTSTRAP_RESAMPLES` times, seeded by
/// `seed`): `(mean, low, high)`, or `None` when empty.
pub fn bootstrap_ci(per_map: &[f64], seed: u64) -> Option<(f64, f64, f64)> {
    use rand::{Rng, SeedableRng};
    let v: Vec<f64> = per_map.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    let n = v.len();
    let m = v.iter().sum::<f64>() / n as f64;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut means: Vec<f64> = (0..BOOTSTRAP_RESAMPLES)
        .map(|_| (0..n).map(|_| v[rng.random_range(0..n)]).sum::<f64>() / n as f64)
        .collect();
    means.sort_by(f64::total_cmp);
    let q = |p: f64| means[((p * (means.len() - 1) as f64).round() as usize).min(means.len() - 1)];
    Some((m, q(0.025), q(0.975)))
}

/// Per-map means (over rounds) of `value` for the graphs of one building (or
/// all), experiment and level, in map order.
pub fn per_map(
    rep: &Reproduction,
    building: Option<&str>,
    e: Experiment,
    level: u8,
    value: impl Fn(&GraphResult) -> f64,
) -> Vec<f64> {
    let mut maps: std::collections::BTreeMap<(&str, &str), Vec<f64>> = Default::default();
    for g in &rep.graphs {
        if g.experiment == e && g.level == level && building.is_none_or(|b| g.building == b) {
            let v = value(g);
            if v.is_finite() {
                maps.entry((g.building.as_str(), g.map.as_str()))
                    .or_default()
                    .push(v);
            }
        }
    }
    maps.values()
        .map(|v| v.iter().sum::<f64>() / v.len() as f64)
        .collect()
}

/// Index (into [`MODELS`](super::models::MODELS)) of the better tuned MRF in a cell (higher mean accuracy).
pub fn best_baseline(
    rep: &Reproduction,
    building: Option<&str>,
    e: Experiment,
    level: u8,
) -> usize {
    let m = |k: usize| {
        let v = per_map(rep, building, e, level, |g| g.accuracy[k]);
        v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    if m(MRF3) > m(MRF2) { MRF3 } else { MRF2 }
}

/// The seed of one cell's bootstrap interval (building, experiment, level, series `k`).
pub(crate) fn ci_seed(
    rep: &Reproduction,
    building: Option<&str>,
    e: Experiment,
    level: u8,
    k: u64,
) -> u64 {
    let b = building
        .and_then(|b| crate::map::cold::BUILDINGS.iter().position(|x| *x == b))
        .map(|i| i as u64 + 1)
        .unwrap_or(0);
    derive_seed(rep.seed, &[99, b, e as u64, level as u64, k])
}
