//! How well can any model label a placeholder from its neighbourhood? An oracle that
//! knows the TRUE class of every explored place and predicts each placeholder's class
//! from the classes around it, with statistics counted on the training buildings.
//!
//! Two contexts: the set of classes of the placeholder's explored neighbours
//! (*one hop*), and for each explored neighbour its class with the set of classes of
//! its own other explored neighbours (*two hops*; backs off to one hop when the
//! training maps never saw that context, then to the most common placeholder class).
//! Each context predicts its most frequent placeholder class in the training maps
//! (ties: the smallest class index). Accuracy is averaged per map, then over maps,
//! like the placeholder experiment's tables. A model that sees only noisy evidence can
//! do no better on average than such an oracle given the same kind of statistics, so
//! the oracle bounds what a better dependency structure over classes can add.

use std::collections::{BTreeMap, BTreeSet};

use serde::{Deserialize, Serialize};

use crate::map::{ClassId, TopoMap};

/// The oracle's accuracy on one test building's placeholders.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CeilingRow {
    /// Test building.
    pub building: String,
    /// Placeholders scored.
    pub placeholders: usize,
    /// Per-map mean accuracy (mean over maps with placeholders) from the one-hop
    /// context; `None` when no test map has a placeholder.
    pub one_hop: Option<f64>,
    /// The same from the two-hop context.
    pub two_hop: Option<f64>,
    /// Per-map accuracies (maps with a placeholder).
    pub per_map: Vec<CeilingMap>,
}

/// The oracle's accuracy on one test map's placeholders.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CeilingMap {
    /// Map name.
    pub map: String,
    /// Accuracy from the one-hop context.
    pub one_hop: f64,
    /// Accuracy from the two-hop context.
    pub two_hop: f64,
}

/// Classes of the explored neighbours of `v` (except `skip`), as a set.
fn explored_classes(m: &TopoMap, v: usize, skip: usize) -> BTreeSet<ClassId> {
    m.neighbors(v)
        .into_iter()
        .filter(|&j| j != skip && !m.place(j).placeholder)
        .filter_map(|j| m.place(j).class)
        .collect()
}

fn one_hop(m: &TopoMap, v: usize) -> Vec<ClassId> {
    explored_classes(m, v, usize::MAX).into_iter().collect()
}

/// A two-hop context: each explored neighbour's class and its other neighbours' classes.
type TwoHops = Vec<(ClassId, Vec<ClassId>)>;

/// Placeholder classes counted per context.
type Counts<K> = BTreeMap<K, BTreeMap<ClassId, usize>>;

fn two_hops(m: &TopoMap, v: usize) -> TwoHops {
    let set: BTreeSet<(ClassId, Vec<ClassId>)> = m
        .neighbors(v)
        .into_iter()
        .filter(|&j| !m.place(j).placeholder)
        .filter_map(|j| {
            m.place(j)
                .class
                .map(|c| (c, explored_classes(m, j, v).into_iter().collect()))
        })
        .collect();
    set.into_iter().collect()
}

/// Most frequent class of a count table (ties: the smallest class).
fn argmax(t: &BTreeMap<ClassId, usize>) -> Option<ClassId> {
    let mut best: Option<(ClassId, usize)> = None;
    for (&c, &n) in t {
        if best.is_none_or(|b| n > b.1) {
            best = Some((c, n));
        }
    }
    best.map(|b| b.0)
}

/// The oracle's accuracy on the placeholders of `test` with statistics from `train`
/// (annotated places only; a placeholder without a class is not scored).
pub fn placeholder_ceiling(building: &str, train: &[TopoMap], test: &[TopoMap]) -> CeilingRow {
    let mut t1: Counts<Vec<ClassId>> = BTreeMap::new();
    let mut t2: Counts<TwoHops> = BTreeMap::new();
    let mut prior: BTreeMap<ClassId, usize> = BTreeMap::new();
    for m in train {
        for v in 0..m.num_places() {
            let p = m.place(v);
            if let (true, Some(y)) = (p.placeholder, p.class) {
                *t1.entry(one_hop(m, v)).or_default().entry(y).or_default() += 1;
                *t2.entry(two_hops(m, v)).or_default().entry(y).or_default() += 1;
                *prior.entry(y).or_default() += 1;
            }
        }
    }
    let fallback = argmax(&prior).unwrap_or(0);
    let mut per_map = Vec::new();
    let mut placeholders = 0;
    for m in test {
        let (mut n, mut h1, mut h2) = (0usize, 0usize, 0usize);
        for v in 0..m.num_places() {
            let p = m.place(v);
            let (true, Some(y)) = (p.placeholder, p.class) else {
                continue;
            };
            let a = t1.get(&one_hop(m, v)).and_then(argmax).unwrap_or(fallback);
            let b = t2.get(&two_hops(m, v)).and_then(argmax).unwrap_or(a);
            n += 1;
            h1 += usize::from(a == y);
            h2 += usize::from(b == y);
        }
        if n > 0 {
            placeholders += n;
            per_map.push(CeilingMap {
                map: m.name.clone(),
                one_hop: h1 as f64 / n as f64,
                two_hop: h2 as f64 / n as f64,
            });
        }
    }
    let k = per_map.len() as f64;
    let mean = |f: fn(&CeilingMap) -> f64| {
        (!per_map.is_empty()).then(|| per_map.iter().map(f).sum::<f64>() / k)
    };
    CeilingRow {
        building: building.to_string(),
        placeholders,
        one_hop: mean(|x| x.one_hop),
        two_hop: mean(|x| x.two_hop),
        per_map,
    }
}
