//! REPORT.md and results.json of a run — a reproduction of the paper on the COLD
//! buildings, or an evaluation of a user's own map sets (`graphspn evaluate`) — and
//! the figures ([`super::figures`]) they link to.

use std::fmt::Write as _;
use std::path::Path;

use super::config::ReproduceConfig;
use super::evidence::{NoiseLevel, PAPER_TABLE1};
use super::figures::{fig8_panel, pie_panel};
use super::models::{MODELS, NUM_MODELS};
use super::novelty::{LOCAL_REGIONS, NoveltySet};
use super::reproduce::{BuildingSetup, ReproduceError, run_graph};
use super::result_tables::{accuracy_table, bp_convergence, ceiling_section, paired_tables};
use super::results::{Experiment, Reproduction, SetScores, set_score};
use super::sets::{Evaluation, SetRole};
use super::stats::levels_of;
use super::summary::{SummaryCell, summarise};
use super::validation_report::{
    counted, option_summary, search_summary, settings_table, validation_tables,
};
use crate::noise::MeanStd;
use serde::Serialize;

pub use super::figures::{accuracy_plot, compose_side_by_side, roc_plot};
pub use super::stats::{
    BOOTSTRAP_RESAMPLES, best_baseline, bootstrap_ci, mean_std, per_map, select,
};

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

/// results.json: the run's record with the report's summary figures beside it.
#[derive(Serialize)]
struct ResultsFile<'a> {
    #[serde(flatten)]
    run: &'a Reproduction,
    /// Means, intervals and paired differences per building, experiment and level.
    summary: &'a [SummaryCell],
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
    let cells = summarise(rep);
    let results = ResultsFile {
        run: rep,
        summary: &cells,
    };
    // Serialising cannot fail on these types; were it to, the error names the file
    // rather than leaving an empty one.
    let json = serde_json::to_string_pretty(&results)
        .map_err(|e| io(&out.join("results.json"))(e.into()))?;
    write("results.json", &json)?;
    let mut figures = Vec::new();
    for b in &rep.buildings {
        let name = format!("accuracy_{}.svg", b.building);
        write(&name, &accuracy_plot(rep, &cells, &b.building))?;
        figures.push(name);
    }
    for SetScores { set, .. } in &rep.auc {
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
        // The first test map with a placeholder (none: no placeholder figure; its
        // accuracies would be over no place).
        if let Some(m) = setup
            .maps
            .iter()
            .position(|m| m.places().any(|p| p.placeholder))
        {
            let o = run_graph(setup, m, pie_level, 0, Experiment::Placeholders, cfg)?;
            let name = format!("placeholders_{}.svg", setup.building);
            write(&name, &pie_panel(&setup.maps[m], &o, pie_level))?;
            figures.push(name);
        }
    }
    write(
        "REPORT.md",
        &report_markdown(
            rep,
            &cells,
            cfg,
            &figures,
            (fig_level, pie_level, labels),
            extra,
        ),
    )?;
    Ok(())
}

fn report_markdown(
    rep: &Reproduction,
    cells: &[SummaryCell],
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
        "Seed {}; {}; {} × {} per building and level; \
         evidence noise: {}. Run time {:.1} s.\n",
        rep.seed,
        counted(rep.buildings.len(), "test building"),
        maps_run(rep, cfg.maps_per_building),
        counted(cfg.rounds, "round"),
        if rep.paper_noise {
            "**paper-effective** (wrong class drawn among all the classes, `--paper-noise`)"
        } else {
            "protocol as written (wrong class drawn among the other classes)"
        },
        rep.seconds
    );
    if let Some(ev) = &rep.evaluation {
        s.push_str(&map_sets_section(ev));
    }
    let chosen = match &rep.given_settings {
        Some(g) => format!(
            "Every setting below was given: `--settings {}`{}, the settings a \
             leave-one-training-building-out validation chose (`graphspn validate`); no \
             validation was run here. {}",
            g.file,
            g.entry
                .as_ref()
                .map_or(String::new(), |e| format!(" (entry {e})")),
            match &g.sample {
                Some(sample) => search_summary(&g.validation, sample),
                None => "The file does not record how large its validation's search was \
                         (it was written before validation.json recorded it)."
                    .to_string(),
            }
        ),
        None if rep.validation.is_empty() => "Every setting below was given (a saved \
             validation, `graphspn validate`); no validation was run."
            .to_string(),
        None => format!(
            "Every setting below was chosen by leave-one-training-building-out validation \
             on {} only; the test maps are never read by it (`graphspn validate`). {}",
            training_wording(rep),
            search_summary(&rep.validation, &cfg.grid.sample())
        ),
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
    s.push_str(&accuracy_table(
        rep,
        cells,
        Experiment::Classification,
        false,
    ));
    s.push_str(&paired_tables(rep, cells, Experiment::Classification));
    s.push('\n');
    s.push_str(&bp_convergence(rep));
    let _ = writeln!(
        s,
        "\n## Placeholders without evidence{}\n\n\
         Accuracy over placeholders only (they get a uniform evidence row), mean over \
         the test maps with at least one placeholder and bootstrap 95% interval, in %{}.\n",
        if paper { " (paper Table 2)" } else { "" },
        if paper && levels_of(rep).iter().any(|l| *l == 2 || *l == 5) {
            "; the paper's numbers (NL2 and NL5 only) beside ours (its MRFs beside our \
             paper-style MRFs)"
        } else {
            ""
        }
    );
    s.push_str(&accuracy_table(rep, cells, Experiment::Placeholders, paper));
    s.push_str(&paired_tables(rep, cells, Experiment::Placeholders));
    s.push_str(&ceiling_section(rep, cells));
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
        for (k, m) in MODELS.iter().enumerate() {
            let _ = writeln!(
                s,
                "| {m} | {:.3} | {:.3} | {:.3} | {:.3} |",
                set_score(&rep.auc, NoveltySet::Paper, k),
                set_score(&rep.within_map, NoveltySet::Paper, k),
                set_score(&rep.auc, NoveltySet::Local, k),
                set_score(&rep.within_map, NoveltySet::Local, k),
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
            "\nMean per-variable log-likelihood by variant (mean ± population standard \
             deviation over the variant's labellings; the MRFs' are Bethe approximations, \
             which can exceed 0 where a true log-likelihood cannot):\n\n| Variant | {} |\n|---|{}",
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
             Evidence drawn on the test maps' ground truth for these statistics alone \
             (seeded by level, map and round), {} per map; mean ± standard deviation \
             over places.\n\n\
             | NL | D_groundtruth ours | paper | D_incorrect ours | paper |\n|---|---|---|---|---|",
            counted(cfg.rounds, "round")
        );
        for r in &rep.table1 {
            let l = r.level;
            let p = PAPER_TABLE1[(l - 1) as usize];
            // The paper lists NL1's D_incorrect as 0.0 with no spread.
            let paper_incorrect = if l == 1 {
                format!("{:.1}", p.2.0)
            } else {
                format!("{:.3} ± {:.3}", p.2.0, p.2.1)
            };
            let _ = writeln!(
                s,
                "| {l} | {} | {:.3} ± {:.3} | {} | {paper_incorrect} |",
                shown_mean_std(r.d_groundtruth),
                p.1.0,
                p.1.1,
                shown_mean_std(r.d_incorrect),
            );
        }
    } else if !rep.table1.is_empty() {
        let _ = writeln!(
            s,
            "\n## Evidence statistics\n\n\
             Evidence drawn on the test maps' ground truth for these statistics alone \
             (seeded by level, map and round), {} per map (mean ± standard deviation \
             over places): D_groundtruth, over the places with correct \
             evidence, the true class's value minus the highest other one; D_incorrect, \
             over the places with wrong evidence, the highest value minus the true \
             class's.\n\n\
             | NL | D_groundtruth | D_incorrect |\n|---|---|---|",
            counted(cfg.rounds, "round")
        );
        for r in &rep.table1 {
            let _ = writeln!(
                s,
                "| {} | {} | {} |",
                r.level,
                shown_mean_std(r.d_groundtruth),
                shown_mean_std(r.d_incorrect)
            );
        }
    }
    let _ = writeln!(s, "\n## Figures\n");
    let roc = if rep.auc.is_empty() {
        "Novelty detection was not run (`--no-novelty`): no ROC figure. "
    } else {
        "`roc.svg`, `roc_local.svg`: novelty-detection ROC of the paper's and of the \
         local swaps. "
    };
    let _ = writeln!(
        s,
        "`accuracy_*.svg`: accuracy vs noise level per test building (lines: models, \
         dashed: paper-style; grey dashed: evidence only; bars: map-level bootstrap 95% \
         intervals). {roc}\
         `{labels}_*.svg`: first test map at {fig_level} (ground truth; places whose \
         evidence argmax is wrong in black; the tree mixture's, GraphSPN's and MRF-2's \
         labels). `placeholders_*.svg`: the tree mixture's and GraphSPN's marginals of \
         the placeholders (pies) at {pie_level} on the first test map that has any, \
         explored places in their true class, wrong-evidence places in black.\n"
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

/// How many test maps each building ran: the count asked for when every building had
/// that many, else what ran (a building with fewer maps runs them all).
fn maps_run(rep: &Reproduction, asked: usize) -> String {
    let counts: Vec<usize> = rep.buildings.iter().map(|b| b.test_maps.len()).collect();
    let total: usize = counts.iter().sum();
    if asked == usize::MAX {
        format!("all maps ({total} in all)")
    } else if counts.iter().all(|&n| n == asked) {
        counted(asked, "map")
    } else {
        format!("up to {asked} maps ({total} in all: a building with fewer runs them all)")
    }
}

/// `mean ± std` to three decimals, or `–` when no place was counted (the mean is
/// not a number: e.g. no place got wrong evidence).
fn shown_mean_std(MeanStd { mean, std, .. }: MeanStd) -> String {
    if mean.is_finite() {
        format!("{mean:.3} ± {std:.3}")
    } else {
        "–".to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::shown_mean_std;
    use crate::noise::MeanStd;

    /// A statistic over no place (e.g. D_incorrect when no evidence was wrong) is shown
    /// as a dash, not as `NaN ± 0.000`.
    #[test]
    fn a_mean_over_no_place_is_a_dash() {
        let of = |mean, std| MeanStd { mean, std, n: 2 };
        assert_eq!(shown_mean_std(of(0.25, 0.125)), "0.250 ± 0.125");
        assert_eq!(shown_mean_std(of(f64::NAN, 0.0)), "–");
    }
}
