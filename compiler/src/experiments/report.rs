//! REPORT.md, results.json and the SVG figures of a reproduction run.

use std::fmt::Write as _;
use std::path::Path;

use super::evidence::derive_seed;
use super::evidence::{NoiseLevel, PAPER_TABLE1};
use super::models::{
    FIRST_PAPER_MODEL, GRAPHSPN, MODELS, MRF_MODELS, MRF2, MRF3, NUM_MODELS, OUR_MODELS, Scores,
    TREES,
};
use super::novelty::{LOCAL_REGIONS, NoveltySet, novelty_points, roc_curve};
use super::reproduce::{
    BuildingSetup, Experiment, GraphResult, ReproduceConfig, ReproduceError, Reproduction,
    run_graph,
};
use crate::map::TopoMap;
use crate::render::{RenderOptions, escape_xml, render_svg};
use crate::template::Template;

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

/// Accuracies of `model` (index into [`MODELS`], or `None` = evidence only) for
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

fn levels_of(rep: &Reproduction) -> Vec<u8> {
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

/// Index (into [`MODELS`]) of the better tuned MRF in a cell (higher mean accuracy).
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

fn ci_seed(rep: &Reproduction, building: Option<&str>, e: Experiment, level: u8, k: u64) -> u64 {
    let b = building
        .and_then(|b| crate::map::cold::BUILDINGS.iter().position(|x| *x == b))
        .map(|i| i as u64 + 1)
        .unwrap_or(0);
    derive_seed(rep.seed, &[99, b, e as u64, level as u64, k])
}

fn fmt_ci(ci: Option<(f64, f64, f64)>) -> String {
    match ci {
        Some((m, lo, hi)) => format!("{:.1} [{:.1}, {:.1}]", 100.0 * m, 100.0 * lo, 100.0 * hi),
        None => "–".into(),
    }
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
    let mut s = format!(
        "\nHow far can placeholders go? An oracle that knows the true class of every \
         explored place and labels each placeholder with the class most often found \
         there in the training buildings, given the classes of its explored neighbours \
         (one hop) or also their neighbours' (two hops) — mean over maps, in %, beside \
         the models at NL{lo} and NL{hi}:\n\n\
         | Test building | placeholders | oracle, one hop | oracle, two hops | {} NL{lo} | {} NL{lo} | better tuned MRF NL{lo} | {} NL{hi} | better tuned MRF NL{hi} |\n\
         |---|---|---|---|---|---|---|---|---|\n",
        MODELS[TREES], MODELS[GRAPHSPN], MODELS[TREES]
    );
    let mean = |b: Option<&str>, l: u8, k: usize| {
        let v = per_map(rep, b, Experiment::Placeholders, l, |g| g.accuracy[k]);
        100.0 * v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    let best = |b: Option<&str>, l: u8| {
        let k = best_baseline(rep, b, Experiment::Placeholders, l);
        mean(b, l, k)
    };
    for c in &rep.ceiling {
        let b = Some(c.building.as_str());
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
            c.building,
            c.placeholders,
            100.0 * c.one_hop,
            100.0 * c.two_hop,
            mean(b, lo, TREES),
            mean(b, lo, GRAPHSPN),
            best(b, lo),
            mean(b, hi, TREES),
            best(b, hi),
        );
    }
    if rep.ceiling.len() > 1 {
        let maps: Vec<&(String, f64, f64)> = rep.ceiling.iter().flat_map(|c| &c.per_map).collect();
        let k = maps.len().max(1) as f64;
        let _ = writeln!(
            s,
            "| **all** | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
            rep.ceiling.iter().map(|c| c.placeholders).sum::<usize>(),
            100.0 * maps.iter().map(|m| m.1).sum::<f64>() / k,
            100.0 * maps.iter().map(|m| m.2).sum::<f64>() / k,
            mean(None, lo, TREES),
            mean(None, lo, GRAPHSPN),
            best(None, lo),
            mean(None, hi, TREES),
            best(None, hi),
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
    s.push_str(&validation_tables(vals, usize::MAX));
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

fn validation_tables(vals: &[super::validate::Validation], keep: usize) -> String {
    let mut s = String::new();
    for v in vals {
        let _ = writeln!(
            s,
            "\nValidation for test building {} (folds: {}); mean accuracy in %, \
             classification and placeholders pooled, per fold and mean; best first:\n",
            v.test_building,
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
    s.push_str(&validation_tables(&rep.validation, 5));
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
    // Fig. 8- and Fig. 6-style panels for the first test map of each building.
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
        let name = format!("fig8_{}.svg", setup.building);
        write(&name, &fig8_panel(setup, &o, fig_level))?;
        figures.push(name);
        let o = run_graph(setup, 0, pie_level, 0, Experiment::Placeholders, cfg)?;
        let name = format!("placeholders_{}.svg", setup.building);
        write(&name, &pie_panel(&setup.maps[0], &o, pie_level))?;
        figures.push(name);
    }
    write(
        "REPORT.md",
        &report_markdown(rep, cfg, &figures, fig_level, pie_level, extra),
    )?;
    Ok(())
}

fn report_markdown(
    rep: &Reproduction,
    cfg: &ReproduceConfig,
    figures: &[String],
    fig_level: NoiseLevel,
    pie_level: NoiseLevel,
    extra: &str,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Semantic-map models on the COLD maps: results\n");
    let _ = writeln!(
        s,
        "Seed {}; {} test building(s); {} maps × {} rounds per building and level; \
         evidence noise: {}. Run time {:.1} s.\n",
        rep.seed,
        rep.buildings.len(),
        if cfg.maps_per_building == usize::MAX {
            "all".to_string()
        } else {
            cfg.maps_per_building.to_string()
        },
        cfg.rounds,
        if rep.paper_noise {
            "**paper-effective** (wrong class drawn among all 10 classes, `--paper-noise`)"
        } else {
            "protocol as written (wrong class drawn among the 9 others)"
        },
        rep.seconds
    );
    let _ = writeln!(
        s,
        "## Models and their settings\n\n\
         Every setting below was chosen by leave-one-training-building-out validation \
         on the test building's two training buildings only (`graphspn validate`). \
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
        "\n## Classification accuracy over all places (paper Fig. 5)\n\n\
         Mean over the test maps (each map's mean over its evidence rounds) with a \
         map-level bootstrap 95% interval, in %. Paper: GraphSPN above 80% at every \
         noise level and test building (read from Fig. 5; the text gives no exact \
         values); MRF-2 good at low noise and deteriorating quickly; MRF-3 worse than MRF-2.\n"
    );
    s.push_str(&accuracy_table(rep, Experiment::Classification, false));
    s.push_str(&paired_tables(rep, Experiment::Classification));
    s.push('\n');
    s.push_str(&bp_convergence(rep));
    let _ = writeln!(
        s,
        "\n## Placeholders without evidence (paper Table 2)\n\n\
         Accuracy over placeholders only (they get a uniform evidence row), mean over \
         the test maps with at least one placeholder and bootstrap 95% interval, in %; \
         the paper's numbers (NL2 and NL5 only) beside ours (its MRFs beside our paper-style MRFs).\n"
    );
    s.push_str(&accuracy_table(rep, Experiment::Placeholders, true));
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
            "\n## Novelty detection (paper Fig. 7)\n\n\
             Per-variable log-likelihood of the labelled test maps (no evidence); a low \
             score flags novelty. Two sets of labellings, each scored with the original \
             labellings ({} maps):\n\n\
             - the paper's: {} novel (CR↔DW and CR↔1PO over the whole map) and {} not \
             (1PO↔2PO), plus the originals;\n\
             - local (harder): the same swaps inside one connected region of a quarter of \
             the places, {} regions per swap and map: {} novel and {} not, plus the originals.\n\n\
             The paper reports ROC curves only (all three models good, MRFs slightly better \
             than GraphSPN).\n",
            originals,
            count(NoveltySet::Paper, true),
            count(NoveltySet::Paper, false) - originals,
            LOCAL_REGIONS,
            count(NoveltySet::Local, true),
            count(NoveltySet::Local, false),
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
    if !rep.table1.is_empty() {
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
    }
    let _ = writeln!(s, "\n## Figures\n");
    let _ = writeln!(
        s,
        "`accuracy_*.svg`: accuracy vs noise level per test building (lines: models, \
         dashed: paper-style; grey dashed: evidence only; bars: map-level bootstrap 95% \
         intervals). `roc.svg`, `roc_local.svg`: novelty-detection ROC of the paper's \
         and of the local swaps. \
         `fig8_*.svg`: first test map at {fig_level} (ground truth; places whose \
         evidence argmax is wrong in black; the tree mixture's, GraphSPN's and MRF-2's \
         labels). `placeholders_*.svg`: the tree mixture's and GraphSPN's marginals of \
         the placeholders (pies) at {pie_level}, explored places in their true class, \
         wrong-evidence places in black.\n"
    );
    for f in figures {
        let _ = writeln!(s, "- [{f}]({f})");
    }
    let _ = writeln!(
        s,
        "\n## Generated code check\n\n\
         GraphSPN marginals above come from the instance GraphSPN evaluated component by \
         component on the host (`ComponentInstance`, tested against the interpreter to \
         1e-9), the tree mixture's from its exact host evaluator (`TreeInstance`, tested \
         against brute force and the interpreter on its explicit SPN): each test map gets a model trained on the other buildings, so no \
         test map is a fixed, compiled one. The generated code applies to a map known at \
         build time; the check below (written by `graphspn reproduce`, empty when the \
         library is called directly) compares it with the interpreter on such a map.\n"
    );
    s.push_str(extra);
    s
}

// ---------------------------------------------------------------- figures

const MODEL_COLOURS: [&str; NUM_MODELS] = [
    "#9467bd", "#d62728", "#1f77b4", "#2ca02c", "#ff9896", "#9ecae1", "#a1d99b",
];

/// An SVG line chart frame: returns (svg prefix, x→px, y→px) for data in [x0,x1]×[0,1].
struct Frame {
    w: f64,
    h: f64,
    left: f64,
    top: f64,
    pw: f64,
    ph: f64,
    x0: f64,
    x1: f64,
}

impl Frame {
    fn px(&self, x: f64) -> f64 {
        self.left + (x - self.x0) / (self.x1 - self.x0) * self.pw
    }
    fn py(&self, y: f64) -> f64 {
        self.top + (1.0 - y) * self.ph
    }
    fn start(&self, title: &str, xlabel: &str, ylabel: &str) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"#,
            w = self.w,
            h = self.h
        );
        let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
        let _ = writeln!(
            s,
            r#"<text x="{}" y="20" font-size="15" text-anchor="middle">{}</text>"#,
            self.w / 2.0,
            escape_xml(title)
        );
        let _ = writeln!(
            s,
            r##"<rect x="{}" y="{}" width="{}" height="{}" fill="none" stroke="#333"/>"##,
            self.left, self.top, self.pw, self.ph
        );
        for k in 0..=10 {
            let y = k as f64 / 10.0;
            let _ = writeln!(
                s,
                r##"<line x1="{l}" x2="{r}" y1="{y}" y2="{y}" stroke="#ddd"/><text x="{tx}" y="{ty}" text-anchor="end">{lab}</text>"##,
                l = self.left,
                r = self.left + self.pw,
                y = self.py(y),
                tx = self.left - 5.0,
                ty = self.py(y) + 4.0,
                lab = if self.x1 > 1.5 {
                    format!("{}", k * 10)
                } else {
                    format!("{y:.1}")
                }
            );
        }
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
            self.left + self.pw / 2.0,
            self.h - 8.0,
            escape_xml(xlabel)
        );
        let _ = writeln!(
            s,
            r#"<text transform="translate(14,{}) rotate(-90)" text-anchor="middle">{}</text>"#,
            self.top + self.ph / 2.0,
            escape_xml(ylabel)
        );
        s
    }
}

fn polyline(pts: &[(f64, f64)], colour: &str, dash: bool) -> String {
    let p: Vec<String> = pts.iter().map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
    format!(
        r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="2"{}/>"#,
        p.join(" "),
        if dash {
            r#" stroke-dasharray="6 4""#
        } else {
            ""
        }
    ) + "\n"
}

fn legend(s: &mut String, x: f64, y: f64, items: &[(&str, &str)]) {
    for (i, (name, col)) in items.iter().enumerate() {
        let yy = y + 16.0 * i as f64;
        let _ = writeln!(
            s,
            r#"<line x1="{x}" x2="{}" y1="{yy}" y2="{yy}" stroke="{col}" stroke-width="3"/><text x="{}" y="{}">{}</text>"#,
            x + 20.0,
            x + 25.0,
            yy + 4.0,
            escape_xml(name)
        );
    }
}

/// Accuracy (%) vs noise level for one building: one line per model, bars = map-level bootstrap 95% intervals.
pub fn accuracy_plot(rep: &Reproduction, building: &str) -> String {
    let levels = levels_of(rep);
    let (lo, hi) = (
        *levels.first().unwrap_or(&1) as f64,
        *levels.last().unwrap_or(&6) as f64,
    );
    let fr = Frame {
        w: 520.0,
        h: 360.0,
        left: 55.0,
        top: 35.0,
        pw: 330.0,
        ph: 280.0,
        x0: lo - 0.3,
        x1: hi + 0.3,
    };
    let mut s = fr.start(
        &format!("Classification accuracy, test building {building}"),
        "noise level",
        "accuracy (%)",
    );
    for &l in &levels {
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">NL{l}</text>"#,
            fr.px(l as f64),
            fr.top + fr.ph + 16.0
        );
    }
    let mut items = Vec::new();
    let mut all_models: Vec<Option<usize>> = (0..NUM_MODELS).map(Some).collect();
    all_models.push(None);
    for (k, model) in all_models.into_iter().enumerate() {
        let (col, name, dash) = match model {
            Some(m) => (MODEL_COLOURS[m], MODELS[m], m >= FIRST_PAPER_MODEL),
            None => ("#888888", "evidence only", true),
        };
        let mut pts = Vec::new();
        for &l in &levels {
            let v = per_map(
                rep,
                Some(building),
                Experiment::Classification,
                l,
                |g| match model {
                    Some(m) => g.accuracy[m],
                    None => g.evidence_only,
                },
            );
            let seed = ci_seed(
                rep,
                Some(building),
                Experiment::Classification,
                l,
                model.map(|m| m as u64 + 1).unwrap_or(0),
            );
            if let Some((m, lo, hi)) = bootstrap_ci(&v, seed) {
                let x = fr.px(l as f64) + (k as f64 - 3.0) * 3.0;
                pts.push((x, fr.py(m)));
                let _ = writeln!(
                    s,
                    r#"<line x1="{x:.1}" x2="{x:.1}" y1="{:.1}" y2="{:.1}" stroke="{col}"/>"#,
                    fr.py(lo),
                    fr.py(hi)
                );
            }
        }
        s.push_str(&polyline(&pts, col, dash));
        items.push((name, col));
    }
    legend(&mut s, fr.left + fr.pw + 15.0, fr.top + 20.0, &items);
    s.push_str("</svg>\n");
    s
}

/// ROC curves of one novelty set, one per model, with AUC in the legend.
pub fn roc_plot(rep: &Reproduction, set: NoveltySet) -> String {
    let fr = Frame {
        w: 520.0,
        h: 380.0,
        left: 55.0,
        top: 35.0,
        pw: 300.0,
        ph: 300.0,
        x0: 0.0,
        x1: 1.0,
    };
    let mut s = fr.start(
        match set {
            NoveltySet::Paper => "Novelty detection ROC (paper's swaps)",
            NoveltySet::Local => "Novelty detection ROC (local swaps)",
        },
        "false-positive rate",
        "true-positive rate",
    );
    for k in 0..=10 {
        let x = k as f64 / 10.0;
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{x:.1}</text>"#,
            fr.px(x),
            fr.top + fr.ph + 16.0
        );
    }
    s.push_str(&polyline(
        &[(fr.px(0.0), fr.py(0.0)), (fr.px(1.0), fr.py(1.0))],
        "#bbbbbb",
        true,
    ));
    let mut names = Vec::new();
    for k in 0..NUM_MODELS {
        let pts = novelty_points(&rep.novelty, set, k);
        let curve: Vec<(f64, f64)> = roc_curve(&pts)
            .into_iter()
            .map(|(x, y)| (fr.px(x), fr.py(y)))
            .collect();
        s.push_str(&polyline(&curve, MODEL_COLOURS[k], false));
        let a = rep
            .auc
            .iter()
            .find(|(s, _)| *s == set)
            .map(|(_, a)| a[k])
            .unwrap_or(f64::NAN);
        names.push(format!("{} (AUC {a:.3})", MODELS[k]));
    }
    let items: Vec<(&str, &str)> = names
        .iter()
        .zip(MODEL_COLOURS)
        .map(|(n, c)| (n.as_str(), c))
        .collect();
    legend(&mut s, fr.left + fr.pw + 15.0, fr.top + 20.0, &items);
    s.push_str("</svg>\n");
    s
}

/// `map` with its classes replaced by the argmax of `probs`.
fn relabel(map: &TopoMap, probs: &[Vec<f64>]) -> TopoMap {
    let mut m = map.clone();
    for (i, w) in m.graph.node_weights_mut().enumerate() {
        let row = &probs[i];
        let best = (0..row.len())
            .max_by(|&a, &b| row[a].total_cmp(&row[b]).then(b.cmp(&a)))
            .unwrap_or(0);
        w.class = Some(best as crate::map::ClassId);
    }
    m
}

/// Width and height of a `render_svg` drawing (from its root element).
fn svg_size(svg: &str) -> (f64, f64) {
    let get = |key: &str| -> f64 {
        svg.find(&format!(" {key}=\""))
            .and_then(|i| {
                let rest = &svg[i + key.len() + 3..];
                rest.find('"').and_then(|j| rest[..j].parse().ok())
            })
            .unwrap_or(400.0)
    };
    (get("width"), get("height"))
}

/// Places the drawings side by side in one SVG (nested `<svg>` elements).
pub fn compose_side_by_side(drawings: &[String]) -> String {
    let sizes: Vec<(f64, f64)> = drawings.iter().map(|d| svg_size(d)).collect();
    let w: f64 = sizes.iter().map(|s| s.0).sum();
    let h = sizes.iter().map(|s| s.1).fold(0.0, f64::max);
    let mut s = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.0} {h:.0}">"#
    );
    s.push('\n');
    let mut x = 0.0;
    for (d, (dw, _)) in drawings.iter().zip(&sizes) {
        let body = d.replacen("<svg ", &format!(r#"<svg x="{x:.0}" y="0" "#), 1);
        s.push_str(&body);
        x += dw;
    }
    s.push_str("</svg>\n");
    s
}

fn wrong_places(o: &super::reproduce::GraphOutcome) -> Vec<usize> {
    (0..o.evidence.wrong.len())
        .filter(|&i| o.evidence.wrong[i])
        .collect()
}

fn fig8_panel(
    setup: &BuildingSetup,
    o: &super::reproduce::GraphOutcome,
    level: NoiseLevel,
) -> String {
    let map = &setup.maps[0];
    let wrong = wrong_places(o);
    let templates = Template::paper_set();
    let acc = &o.result.accuracy;
    let d = [
        render_svg(
            map,
            &RenderOptions {
                title: Some(format!("{} ground truth", map.name)),
                ..RenderOptions::default()
            },
        ),
        render_svg(
            map,
            &RenderOptions {
                title: Some(format!("{level}: wrong evidence (black), decomposition 1")),
                decomposition: setup.instances[0].decompositions().first(),
                templates: Some(&templates),
                highlight: &wrong,
                ..RenderOptions::default()
            },
        ),
        render_svg(
            &relabel(map, &o.marginals[TREES]),
            &RenderOptions {
                title: Some(format!("Tree mixture ({:.1}%)", 100.0 * acc[TREES])),
                ..RenderOptions::default()
            },
        ),
        render_svg(
            &relabel(map, &o.marginals[GRAPHSPN]),
            &RenderOptions {
                title: Some(format!("GraphSPN ({:.1}%)", 100.0 * acc[GRAPHSPN])),
                ..RenderOptions::default()
            },
        ),
        render_svg(
            &relabel(map, &o.marginals[MRF2]),
            &RenderOptions {
                title: Some(format!("MRF-2 tuned ({:.1}%)", 100.0 * acc[MRF2])),
                ..RenderOptions::default()
            },
        ),
    ];
    compose_side_by_side(&d)
}

fn pie_panel(map: &TopoMap, o: &super::reproduce::GraphOutcome, level: NoiseLevel) -> String {
    let wrong = wrong_places(o);
    let mut d = vec![render_svg(
        map,
        &RenderOptions {
            title: Some(format!("{} ground truth (placeholders dashed)", map.name)),
            ..RenderOptions::default()
        },
    )];
    for k in [TREES, GRAPHSPN] {
        let dists = placeholder_pies(map, &o.marginals[k]);
        d.push(render_svg(
            map,
            &RenderOptions {
                title: Some(format!(
                    "{level}: {} placeholder marginals ({:.1}% correct)",
                    MODELS[k],
                    100.0 * o.result.accuracy[k]
                )),
                distributions: Some(&dists),
                highlight: &wrong,
                ..RenderOptions::default()
            },
        ));
    }
    compose_side_by_side(&d)
}

/// A pie per place: a placeholder's marginals, an explored place's true class.
fn placeholder_pies(map: &TopoMap, marginals: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let c = map.classes.len();
    map.places()
        .enumerate()
        .map(|(i, p)| {
            if p.placeholder {
                marginals[i].clone()
            } else {
                let mut v = vec![0.0; c];
                if let Some(k) = p.class {
                    v[k as usize] = 1.0;
                }
                v
            }
        })
        .collect()
}
