//! Summary statistics of maps (degree distribution, class mix, placeholder
//! share, edges per place) and a side-by-side comparison table, used to check
//! that synthetic maps resemble COLD.

use std::fmt::Write as _;

use super::TopoMap;

/// Pooled statistics of one or more maps.
#[derive(Clone, Debug, PartialEq)]
pub struct MapStats {
    /// Number of maps pooled.
    pub maps: usize,
    /// Total places.
    pub places: usize,
    /// Total undirected edges.
    pub edges: usize,
    /// Total placeholders.
    pub placeholders: usize,
    /// `degree_hist[d]` = number of places with degree `d` (length ≥ 9).
    pub degree_hist: Vec<usize>,
    /// Class names (from the first map).
    pub class_names: Vec<String>,
    /// Places per class index; unannotated places are not counted.
    pub class_counts: Vec<usize>,
}

impl MapStats {
    /// Pool the statistics of `maps` (class names from the first map; classes
    /// beyond its class set are ignored).
    pub fn of_maps<'a>(maps: impl IntoIterator<Item = &'a TopoMap>) -> MapStats {
        let mut s = MapStats {
            maps: 0,
            places: 0,
            edges: 0,
            placeholders: 0,
            degree_hist: vec![0; 9],
            class_names: Vec::new(),
            class_counts: Vec::new(),
        };
        for m in maps {
            if s.maps == 0 {
                s.class_names = m.classes.names().to_vec();
                s.class_counts = vec![0; m.classes.len()];
            }
            s.maps += 1;
            s.places += m.num_places();
            s.edges += m.num_edges();
            for i in 0..m.num_places() {
                let d = m.degree(i);
                if d >= s.degree_hist.len() {
                    s.degree_hist.resize(d + 1, 0);
                }
                s.degree_hist[d] += 1;
                let p = m.place(i);
                s.placeholders += usize::from(p.placeholder);
                if let Some(c) = p.class
                    && let Some(n) = s.class_counts.get_mut(c as usize)
                {
                    *n += 1;
                }
            }
        }
        s
    }

    /// Statistics of one map.
    pub fn of_map(map: &TopoMap) -> MapStats {
        MapStats::of_maps([map])
    }

    /// Share of places with each degree (sums to 1 for a non-empty map).
    pub fn degree_distribution(&self) -> Vec<f64> {
        shares(&self.degree_hist)
    }

    /// Share of annotated places in each class.
    pub fn class_shares(&self) -> Vec<f64> {
        shares(&self.class_counts)
    }

    /// Share of places that are placeholders.
    pub fn placeholder_share(&self) -> f64 {
        ratio(self.placeholders, self.places)
    }

    /// Undirected edges per place (half the mean degree).
    pub fn edges_per_place(&self) -> f64 {
        ratio(self.edges, self.places)
    }

    /// Largest degree present.
    pub fn max_degree(&self) -> usize {
        self.degree_hist.iter().rposition(|&n| n > 0).unwrap_or(0)
    }

    /// Total-variation distance between the degree distributions of two pools
    /// (½ Σ |p − q|, in [0, 1]).
    pub fn degree_tv_distance(&self, other: &MapStats) -> f64 {
        tv_distance(&self.degree_distribution(), &other.degree_distribution())
    }

    /// Total-variation distance between the class mixes of two pools.
    pub fn class_tv_distance(&self, other: &MapStats) -> f64 {
        tv_distance(&self.class_shares(), &other.class_shares())
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 { 0.0 } else { a as f64 / b as f64 }
}

fn shares(counts: &[usize]) -> Vec<f64> {
    let total: usize = counts.iter().sum();
    counts.iter().map(|&c| ratio(c, total)).collect()
}

/// Total-variation distance ½ Σ |p_i − q_i| between two distributions (the
/// shorter one padded with zeros).
pub fn tv_distance(p: &[f64], q: &[f64]) -> f64 {
    let n = p.len().max(q.len());
    (0..n)
        .map(|i| (p.get(i).copied().unwrap_or(0.0) - q.get(i).copied().unwrap_or(0.0)).abs())
        .sum::<f64>()
        / 2.0
}

/// A plain-text table of several pools side by side (one column per pool),
/// followed by the degree and class total-variation distances of every pool
/// from the first one.
pub fn comparison_table(columns: &[(&str, &MapStats)]) -> String {
    let mut out = String::new();
    let width = 14;
    let row = |out: &mut String, label: &str, cells: Vec<String>| {
        let _ = write!(out, "{label:<22}");
        for c in cells {
            let _ = write!(out, "{c:>width$}");
        }
        out.push('\n');
    };
    row(
        &mut out,
        "",
        columns.iter().map(|c| c.0.to_string()).collect(),
    );
    let each = |f: &dyn Fn(&MapStats) -> String| columns.iter().map(|c| f(c.1)).collect();
    row(&mut out, "maps", each(&|s| s.maps.to_string()));
    row(&mut out, "places", each(&|s| s.places.to_string()));
    row(&mut out, "edges", each(&|s| s.edges.to_string()));
    row(
        &mut out,
        "edges/place",
        each(&|s| format!("{:.3}", s.edges_per_place())),
    );
    row(
        &mut out,
        "placeholder share",
        each(&|s| pct(s.placeholder_share())),
    );
    row(
        &mut out,
        "max degree",
        each(&|s| s.max_degree().to_string()),
    );
    let max_d = columns
        .iter()
        .map(|c| c.1.max_degree())
        .max()
        .unwrap_or(0)
        .max(8);
    for d in 0..=max_d {
        row(
            &mut out,
            &format!("degree {d}"),
            each(&|s| pct(s.degree_distribution().get(d).copied().unwrap_or(0.0))),
        );
    }
    if let Some((_, first)) = columns.first() {
        for (c, name) in first.class_names.iter().enumerate() {
            row(
                &mut out,
                &format!("class {name}"),
                each(&|s| pct(s.class_shares().get(c).copied().unwrap_or(0.0))),
            );
        }
        row(
            &mut out,
            "degree TV vs first",
            each(&|s| format!("{:.3}", s.degree_tv_distance(first))),
        );
        row(
            &mut out,
            "class TV vs first",
            each(&|s| format!("{:.3}", s.class_tv_distance(first))),
        );
    }
    out
}

fn pct(x: f64) -> String {
    format!("{:.1}%", 100.0 * x)
}

/// Degree histogram of the 90 filtered COLD maps pooled (index = degree 0..=8),
/// as measured by [`crate::map::cold::load_all`]; checked against the data by
/// the `map_cold` tests.
pub const COLD_DEGREE_COUNTS: [usize; 9] = [0, 1397, 1472, 2036, 2367, 1871, 1073, 404, 77];

/// Places per class (paper class order) in the 90 filtered COLD maps.
pub const COLD_CLASS_COUNTS: [usize; 10] = [566, 3628, 1168, 1248, 409, 1091, 528, 585, 547, 927];

/// Placeholders in the 90 filtered COLD maps.
pub const COLD_PLACEHOLDERS: usize = 2736;

/// Undirected edges in the 90 filtered COLD maps.
pub const COLD_EDGES: usize = 19_577;

impl MapStats {
    /// The pooled statistics of the 90 filtered COLD maps, from the constants
    /// above (for comparisons when the data set is not at hand).
    pub fn cold_reference() -> MapStats {
        MapStats {
            maps: 90,
            places: COLD_DEGREE_COUNTS.iter().sum(),
            edges: COLD_EDGES,
            placeholders: COLD_PLACEHOLDERS,
            degree_hist: COLD_DEGREE_COUNTS.to_vec(),
            class_names: super::PAPER_CLASSES.iter().map(|s| s.to_string()).collect(),
            class_counts: COLD_CLASS_COUNTS.to_vec(),
        }
    }
}

/// Share of each class among the places of `maps` (`classes` classes), smoothed
/// towards uniform: `(n_c + α·N/C) / (N·(1 + α))` with `α = 0.1`, so a class never
/// seen in training gets 1% of the mass (with 10 classes) rather than 0.
pub fn class_prior(maps: &[TopoMap], classes: usize) -> Vec<f64> {
    const ALPHA: f64 = 0.1;
    let mut counts = vec![0.0; classes];
    for m in maps {
        for p in m.places() {
            if let Some(c) = p.class.filter(|&c| (c as usize) < classes) {
                counts[c as usize] += 1.0;
            }
        }
    }
    let n: f64 = counts.iter().sum();
    let add = if n > 0.0 {
        ALPHA * n / classes as f64
    } else {
        1.0
    };
    let total: f64 = counts.iter().map(|c| c + add).sum();
    counts.iter().map(|c| (c + add) / total).collect()
}
