//! The figures of REPORT.md's accuracy tables, computed once ([`summarise`]) and
//! written to results.json beside the per-graph results, so that a script reads the
//! same means, intervals and paired differences as the report without redoing the
//! bootstrap: per cell (a test building or all of them, an experiment, a noise level),
//! every model's mean accuracy over maps with its 95% bootstrap interval, and the
//! paired difference of each of our models to the better tuned MRF of the cell.

use serde::{Deserialize, Serialize};

use super::models::{MODELS, OUR_MODELS, Scores};
use super::results::{Experiment, Reproduction};
use super::stats::{best_baseline, bootstrap_ci, ci_seed, levels_of, per_map};

/// A mean over maps (each map's mean over its evidence rounds) with its 95% percentile
/// bootstrap interval over maps ([`bootstrap_ci`]); fractions, not %.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Interval {
    /// The mean over maps.
    pub mean: f64,
    /// Lower end of the interval.
    pub low: f64,
    /// Upper end of the interval.
    pub high: f64,
}

impl Interval {
    /// The interval of per-map values, seeded by `seed`; `None` when there is no
    /// finite value.
    fn of(per_map: &[f64], seed: u64) -> Option<Interval> {
        bootstrap_ci(per_map, seed).map(|(mean, low, high)| Interval { mean, low, high })
    }

    /// `mean [low, high]` in %.
    pub fn percent(&self) -> String {
        format!(
            "{:.1} [{:.1}, {:.1}]",
            100.0 * self.mean,
            100.0 * self.low,
            100.0 * self.high
        )
    }
}

/// `mean [low, high]` in %, or `–` when there is no value.
pub(crate) fn shown(i: Option<Interval>) -> String {
    i.map_or_else(|| "–".into(), |i| i.percent())
}

/// One of our models against the better tuned MRF of a cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairedDifference {
    /// Our model ([`MODELS`] name).
    pub model: String,
    /// The better tuned MRF of the cell it is compared with.
    pub baseline: String,
    /// Model − baseline per map, then the bootstrap over maps (fractions; an
    /// interval above 0 means the model wins); `None` when no map was scored.
    pub difference: Option<Interval>,
}

/// One cell of the report's accuracy and paired-difference tables.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SummaryCell {
    /// Test building; `None` (`null`) for all test buildings pooled.
    pub building: Option<String>,
    /// Which experiment.
    pub experiment: Experiment,
    /// Noise level (1..6).
    pub level: u8,
    /// Maps with at least one scored place (placeholders: maps that have one).
    pub maps: usize,
    /// Accuracy per model, by model name; `None` when no map was scored.
    pub accuracy: Scores<Option<Interval>>,
    /// Accuracy of the evidence's argmax alone.
    pub evidence_only: Option<Interval>,
    /// The better tuned MRF of the cell (higher mean accuracy); `None` when no map was
    /// scored.
    pub better_tuned_mrf: Option<String>,
    /// Each of our models ([`OUR_MODELS`]) against that MRF (empty when no map was
    /// scored).
    pub paired: Vec<PairedDifference>,
}

/// The building rows of the tables: every test building, then all of them pooled
/// (`None`) when there is more than one.
pub(crate) fn building_rows(rep: &Reproduction) -> Vec<Option<&str>> {
    let mut rows: Vec<Option<&str>> = rep
        .buildings
        .iter()
        .map(|b| Some(b.building.as_str()))
        .collect();
    if rep.buildings.len() > 1 {
        rows.push(None);
    }
    rows
}

/// Every cell of a run: buildings (then all) × experiments × levels, in that order.
/// The seeds are the report's, so results.json and REPORT.md give the same figures.
pub fn summarise(rep: &Reproduction) -> Vec<SummaryCell> {
    let levels = levels_of(rep);
    let mut cells = Vec::new();
    for b in building_rows(rep) {
        for e in [Experiment::Classification, Experiment::Placeholders] {
            for &l in &levels {
                let series = |k: Option<usize>| {
                    let v = per_map(rep, b, e, l, |g| match k {
                        Some(k) => g.accuracy[k],
                        None => g.evidence_only,
                    });
                    let seed = ci_seed(rep, b, e, l, k.map_or(0, |k| k as u64 + 1));
                    (v.len(), Interval::of(&v, seed))
                };
                let (maps, evidence_only) = series(None);
                let best = best_baseline(rep, b, e, l);
                let scored = maps > 0;
                let paired = OUR_MODELS
                    .iter()
                    .filter(|_| scored)
                    .map(|&k| {
                        let v = per_map(rep, b, e, l, |g| g.accuracy[k] - g.accuracy[best]);
                        PairedDifference {
                            model: MODELS[k].into(),
                            baseline: MODELS[best].into(),
                            difference: Interval::of(&v, ci_seed(rep, b, e, l, 50 + k as u64)),
                        }
                    })
                    .collect();
                cells.push(SummaryCell {
                    building: b.map(str::to_string),
                    experiment: e,
                    level: l,
                    maps,
                    accuracy: Scores::from_fn(|k| series(Some(k)).1),
                    evidence_only,
                    better_tuned_mrf: scored.then(|| MODELS[best].into()),
                    paired,
                });
            }
        }
    }
    cells
}

/// The cell of one building (or all, `None`), experiment and level, if the run has it.
pub(crate) fn find_cell<'a>(
    cells: &'a [SummaryCell],
    building: Option<&str>,
    e: Experiment,
    level: u8,
) -> Option<&'a SummaryCell> {
    cells
        .iter()
        .find(|c| c.building.as_deref() == building && c.experiment == e && c.level == level)
}

/// [`find_cell`] for a building row and level of the run.
///
/// # Panics
/// If [`summarise`] made no such cell (a level or building the run does not have).
pub(crate) fn cell<'a>(
    cells: &'a [SummaryCell],
    building: Option<&str>,
    e: Experiment,
    level: u8,
) -> &'a SummaryCell {
    find_cell(cells, building, e, level)
        .expect("summarise makes a cell for every building row, experiment and level")
}

impl SummaryCell {
    /// The accuracy of model `k`, or of the cell's better tuned MRF when `k` is `None`.
    pub(crate) fn accuracy_of(&self, k: Option<usize>) -> Option<Interval> {
        let k = k.or_else(|| {
            let best = self.better_tuned_mrf.as_deref()?;
            MODELS.iter().position(|m| *m == best)
        })?;
        self.accuracy[k]
    }
}
