//! REPORT.md and results.json of a run — a reproduction of the paper on the COLD
//! buildings, or an evaluation of a user's own map sets (`graphspn evaluate`) — and
//! the figures ([`super::figures`]) they link to.

use std::fmt::Write as _;
use std::path::Path;

use super::config::ReproduceConfig;
use super::evidence::{NoiseLevel, PAPER_TABLE1};
use super::figures::{fig8_panel, pie_panel};
use super::models::{GRAPHSPN, MODELS, MRF_MODELS, NUM_MODELS, OUR_MODELS, Scores, TREES};
use super::novelty::{LOCAL_REGIONS, NoveltySet};
use super::reproduce::{BuildingSetup, ReproduceError, run_graph};
use super::results::{Experiment, Reproduction};
use super::sets::{Evaluation, SetRole};
use super::stats::{ci_seed, fmt_ci, levels_of};

pub use super::figures::{accuracy_plot, compose_side_by_side, roc_plot};
pub use super::stats::{
    BOOTSTRAP_RESAMPLES, best_baseline, bootstrap_ci, mean_std, per_map, select,
};

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

/// `a`, `a and b`, `a, b and c`.
fn and_list(v: &[&str]) -> String {
    match v {
        [] => String::new(),
        [a] => a.to_string(),
        [rest @ .., last] => format!("{} and {last}", rest.join(", ")),
    }
}

/// A count in words up to ten.
fn count_words(n: usize) -> String {
    const W: [&str; 11] = [
        "no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten",
    ];
    W.get(n).map_or_else(|| n.to_string(), |w| w.to_string())
}

/// What the models were trained and validated on, from the run's own record: e.g.
/// "the three training buildings Freiburg, Saarbrucken and Stockholm", or, when test
/// buildings had different ones, each test building's.
fn training_wording(rep: &Reproduction) -> String {
    let mut lists: Vec<&Vec<String>> = rep.buildings.iter().map(|b| &b.trained_on).collect();
    lists.dedup();
    let one = |l: &Vec<String>| {
        let names: Vec<&str> = l.iter().map(String::as_str).collect();
        format!(
            "the {} training building{} {}",
            count_words(l.len()),
            if l.len() == 1 { "" } else { "s" },
            and_list(&names)
        )
    };
    match lists.as_slice() {
        [l] => one(l),
        _ => {
            let per: Vec<String> = rep
                .buildings
                .iter()
                .map(|b| format!("{} for {}", one(&b.trained_on), b.building))
                .collect();
            per.join("; ")
        }
    }
}

/// Which map set is which in an evaluation: the name each is reported under, its role,
/// where it was read from, and why a name differs from its folder's.
fn map_sets_section(ev: &Evaluation) -> String {
    let mut s = String::from(
        "## Map sets\n\n\
         Your test maps and the training buildings, as named in this report. Every model \
         is trained on the training sets only; the test sets are read for testing only.\n\n\
         | Name in this report | Role | Read from | Maps | Note |\n|---|---|---|---|---|\n",
    );
    for m in &ev.sets {
        let _ = writeln!(
            s,
            "| {} | {} | {}`{}` | {} | {} |",
            m.name,
            match m.role {
                SetRole::Test => "test",
                SetRole::Training => "training",
            },
            if m.bundled {
                "bundled COLD building, "
            } else {
                ""
            },
            m.source,
            m.maps,
            m.note.as_deref().unwrap_or("")
        );
    }
    s.push('\n');
    s
}

fn building_rows(rep: &Reproduction) -> Vec<Option<&str>> {
    let mut buildings: Vec<Option<&str>> = rep
        .buildings
        .iter()
        .map(|b| Some(b.building.as_str()))
        .collect();
    if rep.buildings.len() > 1 {
        buildings.push(None);
    }
    buildings
}

fn accuracy_table(rep: &Reproduction, e: Experiment, with_paper: bool) -> String {
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
                let v = per_map(rep, b, e, l, |g| match k {
                    Some(k) => g.accuracy[k],
                    None => g.evidence_only,
                });
                let seed = ci_seed(rep, b, e, l, k.map(|k| k as u64 + 1).unwrap_or(0));
                let _ = write!(s, " {} |", fmt_ci(bootstrap_ci(&v, seed)));
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

/// Paired differences model `ours` − the better tuned MRF (per map, then bootstrap
/// over maps).
fn paired_table(rep: &Reproduction, e: Experiment, ours: usize) -> String {
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
            let k = best_baseline(rep, b, e, l);
            let v = per_map(rep, b, e, l, |g| g.accuracy[ours] - g.accuracy[k]);
            let ci = bootstrap_ci(&v, ci_seed(rep, b, e, l, 50 + ours as u64));
            let _ = write!(s, " {} vs {} |", fmt_ci(ci), MODELS[k]);
        }
        s.push('\n');
    }
    s
}

/// The paired-difference table of each of our models ([`OUR_MODELS`]).
fn paired_tables(rep: &Reproduction, e: Experiment) -> String {
    let mut s = String::new();
    for k in OUR_MODELS {
        let _ = writeln!(
            s,
            "\nPaired difference {m} − the better tuned MRF of the cell (percentage points, \
             per map then bootstrap over maps); an interval above 0 means {m} wins:\n",
            m = MODELS[k]
        );
        s.push_str(&paired_table(rep, e, k));
    }
    s
}

/// The placeholder ceiling ([`super::ceiling`]) beside the models' placeholder accuracy
/// at the lowest and highest noise level.
fn ceiling_section(rep: &Reproduction) -> String {
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
    let mean = |b: Option<&str>, l: u8, k: usize| {
        let v = per_map(rep, b, Experiment::Placeholders, l, |g| g.accuracy[k]);
        100.0 * v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    let cells = |b: Option<&str>| -> String {
        columns
            .iter()
            .map(|&(l, k, _)| {
                let k = k.unwrap_or_else(|| best_baseline(rep, b, Experiment::Placeholders, l));
                format!("{:.1}", mean(b, l, k))
            })
            .collect::<Vec<_>>()
            .join(" | ")
    };
    for c in &rep.ceiling {
        let b = Some(c.building.as_str());
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {} |",
            c.building,
            c.placeholders,
            100.0 * c.one_hop,
            100.0 * c.two_hop,
            cells(b),
        );
    }
    if rep.ceiling.len() > 1 {
        let maps: Vec<&(String, f64, f64)> = rep.ceiling.iter().flat_map(|c| &c.per_map).collect();
        let k = maps.len().max(1) as f64;
        let _ = writeln!(
            s,
            "| **all** | {} | {:.1} | {:.1} | {} |",
            rep.ceiling.iter().map(|c| c.placeholders).sum::<usize>(),
            100.0 * maps.iter().map(|m| m.1).sum::<f64>() / k,
            100.0 * maps.iter().map(|m| m.2).sum::<f64>() / k,
            cells(None),
        );
    }
    s
}

fn bp_convergence(rep: &Reproduction) -> String {
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

/// VALIDATION.md of `graphspn validate`: the chosen settings and every candidate's score.
pub fn validation_markdown(vals: &[super::validate::Validation], seconds: f64) -> String {
    let mut s = format!(
        "# Validation of every model's settings\n\nLeave-one-training-building-out, per \
         test building; the test building is never read. Run time {seconds:.1} s.\n\n"
    );
    s.push_str(&settings_table(
        vals.iter().map(|v| (v.test_building.as_str(), &v.chosen)),
    ));
    let _ = writeln!(
        s,
        "\nWhat each option gives (validation score, %, averaged over the test buildings' \
         validations): the best setting having that value, and the mean of all settings \
         having it.\n"
    );
    s.push_str(&option_summary(vals));
    s.push_str(&validation_tables(vals, usize::MAX, None));
    s
}

/// The models whose settings validation chooses, in report order.
const VALIDATED: [&str; 4] = ["Tree mixture", "GraphSPN", "MRF-2", "MRF-3"];

/// Per validation: best score, sum of scores and number of settings with one option value.
type OptionCell = (f64, f64, usize);

/// What each option value gives in validation: per model, option and value, the
/// best candidate score among the settings with that value and the mean of all of
/// them, each averaged over the test buildings' validations (in %).
pub fn option_summary(vals: &[super::validate::Validation]) -> String {
    use std::collections::BTreeMap;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| Model | Option | Value | best setting with it | mean of all settings with it |\n|---|---|---|---|---|"
    );
    for model in VALIDATED {
        // option -> value -> per validation (best, sum, count)
        let mut order: Vec<String> = Vec::new();
        let mut table: BTreeMap<(String, String), Vec<OptionCell>> = BTreeMap::new();
        let mut value_order: Vec<(String, String)> = Vec::new();
        for (vi, v) in vals.iter().enumerate() {
            for c in v.candidates.iter().filter(|c| c.model == model) {
                for (o, x) in &c.options {
                    if !order.contains(o) {
                        order.push(o.clone());
                    }
                    let key = (o.clone(), x.clone());
                    if !value_order.contains(&key) {
                        value_order.push(key.clone());
                    }
                    let e = table.entry(key).or_default();
                    e.resize(vals.len(), (f64::NEG_INFINITY, 0.0, 0));
                    let cell = &mut e[vi];
                    cell.0 = cell.0.max(c.score);
                    cell.1 += c.score;
                    cell.2 += 1;
                }
            }
        }
        for o in &order {
            for key in value_order.iter().filter(|k| &k.0 == o) {
                let cells: Vec<&(f64, f64, usize)> =
                    table[key].iter().filter(|c| c.2 > 0).collect();
                let n = cells.len().max(1) as f64;
                let best = cells.iter().map(|c| c.0).sum::<f64>() / n;
                let mean = cells.iter().map(|c| c.1 / c.2 as f64).sum::<f64>() / n;
                let _ = writeln!(
                    s,
                    "| {model} | {o} | {} | {:.1} | {:.1} |",
                    key.1,
                    100.0 * best,
                    100.0 * mean
                );
            }
        }
    }
    s
}

/// Every validation's candidates, best first (`keep` per model, and the worst).
/// `shared`: the test sets one validation on fixed training buildings serves (an
/// evaluation), named in its heading instead of the one it was run for.
fn validation_tables(
    vals: &[super::validate::Validation],
    keep: usize,
    shared: Option<&str>,
) -> String {
    let mut s = String::new();
    for v in vals {
        let _ = writeln!(
            s,
            "\nValidation for {} (folds: {}); mean accuracy in %, \
             classification and placeholders pooled, per fold and mean; best first:\n",
            match shared {
                Some(names) => format!("every test set ({names})"),
                None => format!("test building {}", v.test_building),
            },
            v.folds.join("; ")
        );
        let _ = writeln!(
            s,
            "| Model | Setting | per fold | mean |\n|---|---|---|---|"
        );
        for model in VALIDATED {
            let mut c: Vec<_> = v.candidates.iter().filter(|c| c.model == model).collect();
            c.sort_by(|a, b| b.score.total_cmp(&a.score));
            let n = c.len();
            for (i, c) in c.iter().enumerate() {
                if i < keep || i + 1 == n {
                    let pf: Vec<String> = c
                        .per_fold
                        .iter()
                        .map(|x| format!("{:.1}", 100.0 * x))
                        .collect();
                    let _ = writeln!(
                        s,
                        "| {} | {}{} | {} | {:.1} |",
                        c.model,
                        c.setting,
                        if i + 1 == n && n > keep {
                            " (worst)"
                        } else {
                            ""
                        },
                        pf.join(" / "),
                        100.0 * c.score
                    );
                }
            }
        }
    }
    s
}

/// The chosen settings of every model, one row per test building.
fn settings_table<'a>(
    rows: impl Iterator<Item = (&'a str, &'a super::settings::ModelSettings)>,
) -> String {
    let mut s = String::from(
        "| Test building | Tree mixture | GraphSPN | MRF-2 (tuned) | MRF-3 (tuned) |\n|---|---|---|---|---|\n",
    );
    for (b, st) in rows {
        let _ = writeln!(
            s,
            "| {b} | {} | {} | {} | {} |",
            st.trees.label(),
            st.graphspn.label(),
            st.mrf2.label(),
            st.mrf3.label()
        );
    }
    s
}

fn settings_section(rep: &Reproduction) -> String {
    let mut s = String::new();
    s.push_str(&settings_table(
        rep.buildings
            .iter()
            .map(|b| (b.building.as_str(), &b.settings)),
    ));
    if !rep.validation.is_empty() {
        let _ = writeln!(
            s,
            "\nWhat each option gives in validation (score in %, averaged over the test \
             buildings' validations): the best setting having that value, and the mean of \
             all settings having it.\n"
        );
        s.push_str(&option_summary(&rep.validation));
    }
    let tests: Option<String> = rep
        .evaluation
        .as_ref()
        .map(|ev| and_list(&ev.names(SetRole::Test)));
    s.push_str(&validation_tables(&rep.validation, 5, tests.as_deref()));
    s
}

/// Writes REPORT.md, results.json and the figures into `out`.
/// `extra` is appended to the report (e.g. the CLI's notes).
pub fn write_outputs(
    rep: &Reproduction,
    setups: &[BuildingSetup],
    cfg: &ReproduceConfig,
    out: &Path,
    extra: &str,
) -> Result<(), ReproduceError> {
    let io = |path: &Path| {
        let p = path.display().to_string();
        move |source| ReproduceError::Io { path: p, source }
    };
    std::fs::create_dir_all(out).map_err(io(out))?;
    let write = |name: &str, text: &str| -> Result<(), ReproduceError> {
        let p = out.join(name);
        std::fs::write(&p, text).map_err(io(&p))
    };
    write(
        "results.json",
        &serde_json::to_string_pretty(rep).unwrap_or_default(),
    )?;
    let mut figures = Vec::new();
    for b in &rep.buildings {
        let name = format!("accuracy_{}.svg", b.building);
        write(&name, &accuracy_plot(rep, &b.building))?;
        figures.push(name);
    }
    for (set, _) in &rep.auc {
        let name = match set {
            NoveltySet::Paper => "roc.svg",
            NoveltySet::Local => "roc_local.svg",
        };
        write(name, &roc_plot(rep, *set))?;
        figures.push(name.into());
    }
    // Fig. 8- and Fig. 6-style panels for the first test map of each building (an
    // evaluation names them after what they show, not after the paper's figures).
    let labels = if rep.evaluation.is_some() {
        "labels"
    } else {
        "fig8"
    };
    let fig_level = *cfg
        .levels
        .iter()
        .filter(|l| l.get() <= 4)
        .max()
        .unwrap_or(&cfg.levels[0]);
    let pie_level = cfg
        .levels
        .iter()
        .copied()
        .find(|l| l.get() == 2)
        .unwrap_or(cfg.levels[0]);
    for setup in setups {
        let o = run_graph(setup, 0, fig_level, 0, Experiment::Classification, cfg)?;
        let name = format!("{labels}_{}.svg", setup.building);
        write(&name, &fig8_panel(setup, &o, fig_level))?;
        figures.push(name);
        let o = run_graph(setup, 0, pie_level, 0, Experiment::Placeholders, cfg)?;
        let name = format!("placeholders_{}.svg", setup.building);
        write(&name, &pie_panel(&setup.maps[0], &o, pie_level))?;
        figures.push(name);
    }
    write(
        "REPORT.md",
        &report_markdown(rep, cfg, &figures, (fig_level, pie_level, labels), extra),
    )?;
    Ok(())
}

fn report_markdown(
    rep: &Reproduction,
    cfg: &ReproduceConfig,
    figures: &[String],
    (fig_level, pie_level, labels): (NoiseLevel, NoiseLevel, &str),
    extra: &str,
) -> String {
    let mut s = String::new();
    // An evaluation speaks about the user's map sets: no comparison with the paper's
    // figures, which belong to the paper's own COLD buildings.
    let paper = rep.evaluation.is_none();
    match &rep.evaluation {
        None => {
            let _ = writeln!(s, "# Semantic-map models on the COLD maps: results\n");
        }
        Some(ev) => {
            let _ = writeln!(
                s,
                "# Evaluation of the semantic-map models on your maps: {}\n",
                and_list(&ev.names(SetRole::Test))
            );
        }
    }
    let _ = writeln!(
        s,
        "Seed {}; {} test building{}; {} maps × {} round{} per building and level; \
         evidence noise: {}. Run time {:.1} s.\n",
        rep.seed,
        rep.buildings.len(),
        if rep.buildings.len() == 1 { "" } else { "s" },
        if cfg.maps_per_building == usize::MAX {
            "all".to_string()
        } else {
            cfg.maps_per_building.to_string()
        },
        cfg.rounds,
        if cfg.rounds == 1 { "" } else { "s" },
        if rep.paper_noise {
            "**paper-effective** (wrong class drawn among all 10 classes, `--paper-noise`)"
        } else {
            "protocol as written (wrong class drawn among the 9 others)"
        },
        rep.seconds
    );
    if let Some(ev) = &rep.evaluation {
        s.push_str(&map_sets_section(ev));
    }
    let chosen = if rep.validation.is_empty() {
        "Every setting below was given (`--settings`: a saved validation, `graphspn \
         validate`); no validation was run."
            .to_string()
    } else {
        format!(
            "Every setting below was chosen by leave-one-training-building-out validation \
             on {} only; the test maps are never read by it (`graphspn validate`).",
            training_wording(rep)
        )
    };
    let _ = writeln!(
        s,
        "## Models and their settings\n\n\
         {chosen} \
         The tree mixture is a mixture of edge-covering spanning trees of the map with \
         one learned pairwise potential, evaluated exactly (`treemix`). \
         The paper-style models are \"GraphSPN paper\" (`{}`: the paper's best 5 of 15 \
         decompositions, raw evidence, no temperature, the exact mixture's marginals) and \
         \"MRF-2 paper\" / \"MRF-3 paper\" (raw joint co-occurrence frequencies, raw evidence).\n",
        cfg.graphspn_paper.label()
    );
    s.push_str(&settings_section(rep));
    s.push('\n');
    let _ = writeln!(s, "## Test maps\n");
    let _ = writeln!(
        s,
        "| Test building | Trained on | Test maps | GraphSPN training (s) | tree-mixture training (s) |\n|---|---|---|---|---|"
    );
    for b in &rep.buildings {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {:.2} |",
            b.building,
            b.trained_on.join(", "),
            b.test_maps.join(", "),
            b.train_seconds,
            b.train_seconds_trees
        );
    }
    let _ = writeln!(
        s,
        "\n## Classification accuracy over all places{}\n\n\
         Mean over the test maps (each map's mean over its evidence rounds) with a \
         map-level bootstrap 95% interval, in %.{}\n",
        if paper { " (paper Fig. 5)" } else { "" },
        if paper {
            " Paper: GraphSPN above 80% at every \
             noise level and test building (read from Fig. 5; the text gives no exact \
             values); MRF-2 good at low noise and deteriorating quickly; MRF-3 worse than MRF-2."
        } else {
            ""
        }
    );
    s.push_str(&accuracy_table(rep, Experiment::Classification, false));
    s.push_str(&paired_tables(rep, Experiment::Classification));
    s.push('\n');
    s.push_str(&bp_convergence(rep));
    let _ = writeln!(
        s,
        "\n## Placeholders without evidence{}\n\n\
         Accuracy over placeholders only (they get a uniform evidence row), mean over \
         the test maps with at least one placeholder and bootstrap 95% interval, in %{}.\n",
        if paper { " (paper Table 2)" } else { "" },
        if paper {
            "; the paper's numbers (NL2 and NL5 only) beside ours (its MRFs beside our \
             paper-style MRFs)"
        } else {
            ""
        }
    );
    s.push_str(&accuracy_table(rep, Experiment::Placeholders, paper));
    s.push_str(&paired_tables(rep, Experiment::Placeholders));
    s.push_str(&ceiling_section(rep));
    if !rep.auc.is_empty() {
        let count = |set: NoveltySet, novel: bool| {
            rep.novelty
                .iter()
                .filter(|n| n.set == set && n.novel == novel)
                .count()
        };
        let originals = rep.novelty.iter().filter(|n| n.is_original()).count();
        let _ = writeln!(
            s,
            "\n## Novelty detection{}\n\n\
             Per-variable log-likelihood of the labelled test maps (no evidence); a low \
             score flags novelty. Two sets of labellings, each scored with the original \
             labellings ({}):\n\n\
             - the paper's: {} novel (CR↔DW and CR↔1PO over the whole map) and {} not \
             (1PO↔2PO), plus the originals;\n\
             - local (harder): the same swaps inside one connected region of a quarter of \
             the places, {} regions per swap and map: {} novel and {} not, plus the originals.\n{}",
            if paper { " (paper Fig. 7)" } else { "" },
            if originals == 1 {
                "1 map".to_string()
            } else {
                format!("{originals} maps")
            },
            count(NoveltySet::Paper, true),
            count(NoveltySet::Paper, false) - originals,
            LOCAL_REGIONS,
            count(NoveltySet::Local, true),
            count(NoveltySet::Local, false),
            if paper {
                "\nThe paper reports ROC curves only (all three models good, MRFs slightly \
                 better than GraphSPN).\n"
            } else {
                ""
            }
        );
        let _ = writeln!(
            s,
            "Pooled AUC ranks all labellings of all maps together (it also measures how \
             comparable the scores are across maps); within-map AUC ranks each map's own \
             labellings only, averaged over maps. MRF scores use the Bethe approximation of log Z.\n"
        );
        let _ = writeln!(
            s,
            "| Model | pooled AUC, paper set | within-map, paper set | pooled AUC, local set | within-map, local set |\n|---|---|---|---|---|"
        );
        let get = |v: &[(NoveltySet, Scores<f64>)], set: NoveltySet, k: usize| {
            v.iter()
                .find(|(s, _)| *s == set)
                .map(|(_, a)| a[k])
                .unwrap_or(f64::NAN)
        };
        for (k, m) in MODELS.iter().enumerate() {
            let _ = writeln!(
                s,
                "| {m} | {:.3} | {:.3} | {:.3} | {:.3} |",
                get(&rep.auc, NoveltySet::Paper, k),
                get(&rep.within_map, NoveltySet::Paper, k),
                get(&rep.auc, NoveltySet::Local, k),
                get(&rep.within_map, NoveltySet::Local, k),
            );
        }
        let mut variants: Vec<String> = Vec::new();
        for n in &rep.novelty {
            // Local variants pooled over their regions.
            let v = n
                .variant
                .split(" local")
                .next()
                .unwrap_or(&n.variant)
                .to_string()
                + if n.set == NoveltySet::Local {
                    " (local)"
                } else {
                    ""
                };
            if !variants.contains(&v) {
                variants.push(v);
            }
        }
        let _ = writeln!(
            s,
            "\nMean per-variable log-likelihood by variant:\n\n| Variant | {} |\n|---|{}",
            MODELS.join(" | "),
            "---|".repeat(NUM_MODELS)
        );
        for v in variants {
            let _ = write!(s, "| {v} |");
            for k in 0..NUM_MODELS {
                let vals: Vec<f64> = rep
                    .novelty
                    .iter()
                    .filter(|n| {
                        let base = n.variant.split(" local").next().unwrap_or(&n.variant);
                        let name = base.to_string()
                            + if n.set == NoveltySet::Local {
                                " (local)"
                            } else {
                                ""
                            };
                        name == v
                    })
                    .map(|n| n.score[k])
                    .collect();
                match mean_std(&vals) {
                    Some((m, sd)) => {
                        let _ = write!(s, " {m:.3} ± {sd:.3} |");
                    }
                    None => s.push_str(" – |"),
                }
            }
            s.push('\n');
        }
    }
    if !rep.table1.is_empty() && paper {
        let _ = writeln!(
            s,
            "\n## Evidence statistics (paper Table 1)\n\n\
             On the test maps' ground truth, {} rounds per map.\n\n\
             | NL | D_groundtruth ours | paper | D_incorrect ours | paper |\n|---|---|---|---|---|",
            cfg.rounds
        );
        for &(l, gm, gs, im, is) in &rep.table1 {
            let p = PAPER_TABLE1[(l - 1) as usize];
            let _ = writeln!(
                s,
                "| {l} | {gm:.3} ± {gs:.3} | {:.3} ± {:.3} | {im:.3} ± {is:.3} | {:.3} ± {:.3} |",
                p.1.0, p.1.1, p.2.0, p.2.1
            );
        }
    } else if !rep.table1.is_empty() {
        let _ = writeln!(
            s,
            "\n## Evidence statistics\n\n\
             The evidence simulated on the test maps' ground truth, {} rounds per map \
             (mean ± standard deviation): D_groundtruth, over the places with correct \
             evidence, the true class's value minus the highest other one; D_incorrect, \
             over the places with wrong evidence, the highest value minus the true \
             class's.\n\n\
             | NL | D_groundtruth | D_incorrect |\n|---|---|---|",
            cfg.rounds
        );
        for &(l, gm, gs, im, is) in &rep.table1 {
            let _ = writeln!(s, "| {l} | {gm:.3} ± {gs:.3} | {im:.3} ± {is:.3} |");
        }
    }
    let _ = writeln!(s, "\n## Figures\n");
    let _ = writeln!(
        s,
        "`accuracy_*.svg`: accuracy vs noise level per test building (lines: models, \
         dashed: paper-style; grey dashed: evidence only; bars: map-level bootstrap 95% \
         intervals). `roc.svg`, `roc_local.svg`: novelty-detection ROC of the paper's \
         and of the local swaps. \
         `{labels}_*.svg`: first test map at {fig_level} (ground truth; places whose \
         evidence argmax is wrong in black; the tree mixture's, GraphSPN's and MRF-2's \
         labels). `placeholders_*.svg`: the tree mixture's and GraphSPN's marginals of \
         the placeholders (pies) at {pie_level}, explored places in their true class, \
         wrong-evidence places in black.\n"
    );
    for f in figures {
        let _ = writeln!(s, "- [{f}]({f})");
    }
    // The check of the generated code (`graphspn reproduce` passes it in `extra`);
    // without it the section would have nothing to say, so it is left out.
    if extra.trim().is_empty() {
        return s;
    }
    let _ = writeln!(
        s,
        "\n## Generated code check\n\n\
         GraphSPN marginals above come from the instance GraphSPN evaluated component by \
         component on the host (`ComponentInstance`, tested against the interpreter to \
         1e-9), the tree mixture's from its exact host evaluator (`TreeInstance`, tested \
         against brute force and the interpreter on its explicit SPN): each test map gets a model trained on the other buildings, so no \
         test map is a fixed, compiled one. The generated code applies to a map known at \
         build time; the check below compares it with the interpreter on such a map.\n"
    );
    s.push_str(extra);
    s
}
