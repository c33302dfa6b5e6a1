//! The result tables of REPORT.md: accuracy per model, test building and noise level
//! (beside the paper's Table 2, [`PAPER_TABLE2`]), paired differences with the better
//! tuned MRF, the placeholder ceiling, and loopy BP's convergence.

use std::fmt::Write as _;

use super::ceiling::CeilingMap;
use super::models::{GRAPHSPN, MODELS, MRF_MODELS, OUR_MODELS, TREES};
use super::results::{Experiment, Reproduction};
use super::stats::levels_of;
use super::summary::{SummaryCell, building_rows, cell, find_cell, shown};

/// The paper's Table 2 (placeholder accuracy, %): `(model, level, [Freiburg, Saarbrucken, Stockholm])`.
pub const PAPER_TABLE2: [(&str, u8, [f64; 3]); 6] = [
    ("GraphSPN", 2, [67.58, 78.15, 67.57]),
    ("GraphSPN", 5, [40.59, 55.18, 37.56]),
    ("MRF-2", 2, [28.32, 39.85, 12.44]),
    ("MRF-2", 5, [24.23, 30.58, 10.04]),
    ("MRF-3", 2, [28.71, 31.94, 10.11]),
    ("MRF-3", 5, [18.02, 28.86, 8.96]),
];

fn paper_table2(model: &str, level: u8, building: &str) -> Option<f64> {
    let bi = crate::map::cold::BUILDINGS
        .iter()
        .position(|b| *b == building)?;
    PAPER_TABLE2
        .iter()
        .find(|(m, l, _)| *m == model && *l == level)
        .map(|(_, _, v)| v[bi])
}

pub(crate) fn accuracy_table(
    rep: &Reproduction,
    cells: &[SummaryCell],
    e: Experiment,
    with_paper: bool,
) -> String {
    let levels = levels_of(rep);
    let mut s = String::new();
    let mut head = "| Test building | Model |".to_string();
    let mut rule = "|---|---|".to_string();
    for l in &levels {
        let _ = write!(head, " NL{l} |");
        rule.push_str("---|");
        if with_paper && (*l == 2 || *l == 5) {
            let _ = write!(head, " paper NL{l} |");
            rule.push_str("---|");
        }
    }
    let _ = writeln!(s, "{head}\n{rule}");
    for b in building_rows(rep) {
        let mut rows: Vec<(&str, Option<usize>)> = MODELS
            .iter()
            .enumerate()
            .map(|(k, m)| (*m, Some(k)))
            .collect();
        rows.push(("evidence only", None));
        for (name, k) in rows {
            let _ = write!(s, "| {} | {name} |", b.unwrap_or("**all**"));
            for &l in &levels {
                let c = cell(cells, b, e, l);
                let _ = write!(
                    s,
                    " {} |",
                    shown(k.map_or(c.evidence_only, |k| c.accuracy[k]))
                );
                if with_paper && (l == 2 || l == 5) {
                    let paper_name = match name {
                        "MRF-2 paper" => "MRF-2",
                        "MRF-3 paper" => "MRF-3",
                        "GraphSPN paper" => "GraphSPN",
                        _ => "",
                    };
                    let p = b.and_then(|b| paper_table2(paper_name, l, b));
                    let _ = write!(
                        s,
                        " {} |",
                        p.map(|v| format!("{v:.1}")).unwrap_or_else(|| "–".into())
                    );
                }
            }
            s.push('\n');
        }
    }
    s
}

/// Paired differences model `ours` (its index in [`OUR_MODELS`]) − the better tuned
/// MRF (per map, then bootstrap over maps).
fn paired_table(rep: &Reproduction, cells: &[SummaryCell], e: Experiment, ours: usize) -> String {
    let levels = levels_of(rep);
    let mut s = String::new();
    let mut head = "| Test building |".to_string();
    let mut rule = "|---|".to_string();
    for l in &levels {
        let _ = write!(head, " NL{l} |");
        rule.push_str("---|");
    }
    let _ = writeln!(s, "{head}\n{rule}");
    for b in building_rows(rep) {
        let _ = write!(s, "| {} |", b.unwrap_or("**all**"));
        for &l in &levels {
            match cell(cells, b, e, l).paired.get(ours) {
                Some(p) => {
                    let _ = write!(s, " {} vs {} |", shown(p.difference), p.baseline);
                }
                None => s.push_str(" – |"),
            }
        }
        s.push('\n');
    }
    s
}

/// The paired-difference table of each of our models ([`OUR_MODELS`]).
pub(crate) fn paired_tables(rep: &Reproduction, cells: &[SummaryCell], e: Experiment) -> String {
    let mut s = String::new();
    for (ours, k) in OUR_MODELS.into_iter().enumerate() {
        let _ = writeln!(
            s,
            "\nPaired difference {m} − the better tuned MRF of the cell (percentage points, \
             per map then bootstrap over maps); an interval above 0 means {m} wins:\n",
            m = MODELS[k]
        );
        s.push_str(&paired_table(rep, cells, e, ours));
    }
    s
}

/// The placeholder ceiling ([`super::ceiling`]) beside the models' placeholder accuracy
/// at the lowest and highest noise level.
pub(crate) fn ceiling_section(rep: &Reproduction, cells: &[SummaryCell]) -> String {
    if rep.ceiling.is_empty() {
        return String::new();
    }
    let levels = levels_of(rep);
    let (lo, hi) = (levels[0], levels[levels.len() - 1]);
    // Columns: the tree mixture, GraphSPN and the better tuned MRF at the lowest level,
    // the tree mixture and the better tuned MRF at the highest (when it differs).
    let mut columns: Vec<(u8, Option<usize>, String)> = vec![
        (lo, Some(TREES), format!("{} NL{lo}", MODELS[TREES])),
        (lo, Some(GRAPHSPN), format!("{} NL{lo}", MODELS[GRAPHSPN])),
        (lo, None, format!("better tuned MRF NL{lo}")),
    ];
    if hi != lo {
        columns.push((hi, Some(TREES), format!("{} NL{hi}", MODELS[TREES])));
        columns.push((hi, None, format!("better tuned MRF NL{hi}")));
    }
    let at = if hi == lo {
        format!("NL{lo}")
    } else {
        format!("NL{lo} and NL{hi}")
    };
    let heads: Vec<&str> = columns.iter().map(|c| c.2.as_str()).collect();
    let mut s = format!(
        "\nHow far can placeholders go? An oracle that knows the true class of every \
         explored place and labels each placeholder with the class most often found \
         there in the training buildings, given the classes of its explored neighbours \
         (one hop) or also their neighbours' (two hops) — mean over maps, in %, beside \
         the models at {at}:\n\n\
         | Test building | placeholders | oracle, one hop | oracle, two hops | {} |\n\
         |---|---|---|---|{}\n",
        heads.join(" | "),
        "---|".repeat(columns.len())
    );
    // A percentage, or a dash where nothing was measured (no placeholder).
    let pct = |x: Option<f64>| x.map_or("–".to_string(), |x| format!("{:.1}", 100.0 * x));
    let mean = |v: &[f64]| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    // The models' means from the report's cells (the better tuned MRF is the cell's).
    let models = |b: Option<&str>| -> String {
        columns
            .iter()
            .map(|&(l, k, _)| {
                let c = find_cell(cells, b, Experiment::Placeholders, l);
                pct(c.and_then(|c| c.accuracy_of(k)).map(|i| i.mean))
            })
            .collect::<Vec<_>>()
            .join(" | ")
    };
    for c in &rep.ceiling {
        let b = Some(c.building.as_str());
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            c.building,
            c.placeholders,
            pct(c.one_hop),
            pct(c.two_hop),
            models(b),
        );
    }
    if rep.ceiling.len() > 1 {
        let maps: Vec<&CeilingMap> = rep.ceiling.iter().flat_map(|c| &c.per_map).collect();
        let hop = |f: fn(&CeilingMap) -> f64| mean(&maps.iter().map(|m| f(m)).collect::<Vec<_>>());
        let _ = writeln!(
            s,
            "| **all** | {} | {} | {} | {} |",
            rep.ceiling.iter().map(|c| c.placeholders).sum::<usize>(),
            pct(hop(|m| m.one_hop)),
            pct(hop(|m| m.two_hop)),
            models(None),
        );
    }
    s
}

pub(crate) fn bp_convergence(rep: &Reproduction) -> String {
    let n = rep.graphs.len().max(1) as f64;
    let parts: Vec<String> = MRF_MODELS
        .iter()
        .map(|&k| {
            let c = rep
                .graphs
                .iter()
                .filter(|g| g.bp_converged.get(MODELS[k]).copied().unwrap_or(false))
                .count() as f64;
            format!("{:.1}% ({})", 100.0 * c / n, MODELS[k])
        })
        .collect();
    format!(
        "Loopy BP converged on {} of the test graphs.\n",
        parts.join(", ")
    )
}
