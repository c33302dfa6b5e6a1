//! The novelty-detection experiment's labellings and scores: the paper's swaps and
//! the harder local swaps, ROC curves, pooled and within-map AUC.

use std::collections::BTreeMap;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::evidence::derive_seed;
use super::models::Scores;
use crate::map::{ClassId, TopoMap};
use crate::template::Adjacency;

/// One labelled map of the novelty experiment.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct NoveltyResult {
    /// Test building.
    pub building: String,
    /// Map name.
    pub map: String,
    /// `original`, `1PO<->2PO`, `CR<->DW` or `CR<->1PO`, with ` local k` for the
    /// local set.
    pub variant: String,
    /// The labelling set.
    pub set: NoveltySet,
    /// Whether the labelling counts as novel (the CR swaps).
    pub novel: bool,
    /// Number of variables (places).
    pub variables: usize,
    /// Log-likelihood per variable (natural log), in `MODELS` order.
    pub score: Scores<f64>,
}

impl NoveltyResult {
    /// Whether this labelling is the map's original one.
    pub fn is_original(&self) -> bool {
        self.variant == ORIGINAL
    }

    /// Whether the labelling is scored in `set` (its own set; the original
    /// labelling in both).
    pub fn in_set(&self, set: NoveltySet) -> bool {
        self.set == set || self.is_original()
    }
}

/// The two labelling sets of the novelty experiment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NoveltySet {
    /// The paper's: the original labelling and 1PO↔2PO (not novel), CR↔DW and
    /// CR↔1PO over the whole map (novel).
    Paper,
    /// Harder: the same swaps inside one connected region covering a quarter of
    /// the places ([`LOCAL_REGION_SHARE`]), [`LOCAL_REGIONS`] regions per swap;
    /// scored together with the original labelling.
    Local,
}

/// Name of the unswapped labelling, which belongs to both novelty sets.
pub const ORIGINAL: &str = "original";

/// Share of a map's places a local swap region covers.
pub const LOCAL_REGION_SHARE: f64 = 0.25;

/// Random regions per local swap and map.
pub const LOCAL_REGIONS: usize = 3;

/// The class swaps of the novelty experiment: `(name, novel, class a, class b)`.
pub const NOVELTY_SWAPS: [(&str, bool, &str, &str); 3] = [
    ("1PO<->2PO", false, "1PO", "2PO"),
    ("CR<->DW", true, "CR", "DW"),
    ("CR<->1PO", true, "CR", "1PO"),
];

/// One labelling of the novelty experiment.
#[derive(Clone, Debug, PartialEq)]
pub struct NoveltyLabelling {
    /// E.g. `original`, `CR<->DW`, `CR<->DW local 2`.
    pub name: String,
    /// Its set.
    pub set: NoveltySet,
    /// Whether it counts as novel.
    pub novel: bool,
    /// A class per place.
    pub labels: Vec<ClassId>,
}

/// `truth` with classes `a` and `b` exchanged at the places where `inside` holds.
fn swap_where(
    truth: &[ClassId],
    a: ClassId,
    b: ClassId,
    inside: impl Fn(usize) -> bool,
) -> Vec<ClassId> {
    truth
        .iter()
        .enumerate()
        .map(|(i, &t)| match t {
            _ if !inside(i) => t,
            t if t == a => b,
            t if t == b => a,
            t => t,
        })
        .collect()
}

/// A connected region grown breadth-first from `start` over `adj` until it holds
/// `size` places (or its whole component).
fn region_from(adj: &Adjacency, start: usize, size: usize) -> Vec<bool> {
    let mut inside = vec![false; adj.num_places()];
    let mut queue = std::collections::VecDeque::from([start]);
    inside[start] = true;
    let mut count = 1;
    while let Some(u) = queue.pop_front() {
        for &v in adj.neighbors(u) {
            if count >= size {
                return inside;
            }
            if !inside[v] {
                inside[v] = true;
                count += 1;
                queue.push_back(v);
            }
        }
    }
    inside
}

/// The labellings of the novelty experiment for a map with ground truth `truth`:
/// the paper's set, then the local set (regions seeded by `seed`). A swap whose
/// classes the map's class set lacks, or that changes no place, is left out.
pub fn novelty_labellings(map: &TopoMap, truth: &[ClassId], seed: u64) -> Vec<NoveltyLabelling> {
    let adj = Adjacency::new(map);
    let mut out = vec![NoveltyLabelling {
        name: ORIGINAL.into(),
        set: NoveltySet::Paper,
        novel: false,
        labels: truth.to_vec(),
    }];
    let size = ((LOCAL_REGION_SHARE * truth.len() as f64).ceil() as usize).max(1);
    for (k, (name, novel, a, b)) in NOVELTY_SWAPS.iter().enumerate() {
        let (Some(a), Some(b)) = (map.classes.index_of(a), map.classes.index_of(b)) else {
            continue;
        };
        let swapped: Vec<usize> = (0..truth.len())
            .filter(|&i| truth[i] == a || truth[i] == b)
            .collect();
        if swapped.is_empty() {
            continue;
        }
        out.push(NoveltyLabelling {
            name: name.to_string(),
            set: NoveltySet::Paper,
            novel: *novel,
            labels: swap_where(truth, a, b, |_| true),
        });
        let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(seed, &[k as u64]));
        for r in 0..LOCAL_REGIONS {
            // The region starts at a place the swap changes.
            let start = swapped[rand::Rng::random_range(&mut rng, 0..swapped.len())];
            let inside = region_from(&adj, start, size);
            out.push(NoveltyLabelling {
                name: format!("{name} local {}", r + 1),
                set: NoveltySet::Local,
                novel: *novel,
                labels: swap_where(truth, a, b, |i| inside[i]),
            });
        }
    }
    out
}

/// The `(score of model k, novel)` points of one novelty set: its labellings plus
/// the original labellings (which belong to both sets).
pub fn novelty_points(novelty: &[NoveltyResult], set: NoveltySet, k: usize) -> Vec<(f64, bool)> {
    novelty
        .iter()
        .filter(|n| n.in_set(set))
        .map(|n| (n.score[k], n.novel))
        .collect()
}

/// ROC curve `(false-positive rate, true-positive rate)` points, from
/// `(score, novel)` pairs where a LOW score means novel; starts at (0,0), ends at (1,1).
pub fn roc_curve(points: &[(f64, bool)]) -> Vec<(f64, f64)> {
    let pos = points.iter().filter(|p| p.1).count() as f64;
    let neg = points.len() as f64 - pos;
    let mut sorted: Vec<(f64, bool)> = points.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut curve = vec![(0.0, 0.0)];
    let (mut tp, mut fp) = (0.0, 0.0);
    let mut i = 0;
    while i < sorted.len() {
        let s = sorted[i].0;
        while i < sorted.len() && sorted[i].0 == s {
            if sorted[i].1 {
                tp += 1.0;
            } else {
                fp += 1.0;
            }
            i += 1;
        }
        curve.push((
            if neg > 0.0 { fp / neg } else { 0.0 },
            if pos > 0.0 { tp / pos } else { 0.0 },
        ));
    }
    curve
}

/// Area under the ROC curve (trapezoidal; equals the Mann–Whitney probability
/// that a novel map scores lower than a non-novel one, ties counting ½).
pub fn auc(points: &[(f64, bool)]) -> f64 {
    let c = roc_curve(points);
    c.windows(2)
        .map(|w| (w[1].0 - w[0].0) * (w[1].1 + w[0].1) / 2.0)
        .sum()
}

/// The within-map ranking measure of model `k` on one novelty set: for each map,
/// the AUC of its own labellings of that set (novel vs not, the original included),
/// averaged over the maps that have both kinds.
pub fn within_map_auc(novelty: &[NoveltyResult], set: NoveltySet, k: usize) -> f64 {
    let mut maps: BTreeMap<(&str, &str), Vec<(f64, bool)>> = BTreeMap::new();
    for n in novelty.iter().filter(|n| n.in_set(set)) {
        maps.entry((n.building.as_str(), n.map.as_str()))
            .or_default()
            .push((n.score[k], n.novel));
    }
    let per: Vec<f64> = maps
        .values()
        .filter(|p| p.iter().any(|x| x.1) && p.iter().any(|x| !x.1))
        .map(|p| auc(p))
        .collect();
    per.iter().sum::<f64>() / per.len().max(1) as f64
}
