//! VALIDATION.md of `graphspn validate`, and the validation tables REPORT.md shares
//! with it: the chosen settings per test building, what each option value gives, and
//! every candidate's score.

use std::fmt::Write as _;

use super::grid::{ValidationGrid, ValidationSample};

/// `n` and the noun, plural unless `n` is 1: `1 round`, `3 rounds`.
pub fn counted(n: usize, noun: &str) -> String {
    format!("{n} {noun}{}", if n == 1 { "" } else { "s" })
}

/// What a validation searched: candidates per model (from `vals`, the first test
/// building's) and the sample of each validation building (`grid`), saying so when
/// that sample is smaller than the standard grid's (a smoke run such as `--tiny-grid`
/// or `reproduce --quick`, not the protocol's search). Empty without a validation.
pub fn search_summary(vals: &[super::validate::Validation], sample: &ValidationSample) -> String {
    let Some(first) = vals.first() else {
        return String::new();
    };
    let counts: Vec<String> = VALIDATED
        .iter()
        .map(|m| {
            let n = first.candidates.iter().filter(|c| c.model == *m).count();
            format!("{n} {m}")
        })
        .collect();
    let levels: Vec<String> = sample.levels.iter().map(|l| format!("NL{l}")).collect();
    let standard = ValidationGrid::standard();
    let smaller = sample.maps_per_building < standard.maps_per_building
        || sample.levels.len() < standard.levels.len()
        || sample.rounds < standard.rounds;
    format!(
        "The search: {} candidates, on {} × {} × {} per validation building{}.",
        counts.join(", "),
        counted(sample.maps_per_building, "map"),
        levels.join(", "),
        counted(sample.rounds, "round"),
        if smaller {
            format!(
                " — **a reduced search** (a smoke run such as `--tiny-grid` or `reproduce --quick`), not \
                 the protocol's ({} maps × {} levels × {} rounds)",
                standard.maps_per_building,
                standard.levels.len(),
                standard.rounds
            )
        } else {
            String::new()
        }
    )
}

/// VALIDATION.md of `graphspn validate`: the chosen settings and every candidate's score.
pub fn validation_markdown(
    vals: &[super::validate::Validation],
    grid: &ValidationGrid,
    seconds: f64,
) -> String {
    let mut s = format!(
        "# Validation of every model's settings\n\nLeave-one-training-building-out, per \
         test building; the test building is never read. {} Run time {seconds:.1} s.\n\n",
        search_summary(vals, &grid.sample())
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
pub(crate) fn validation_tables(
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
pub(crate) fn settings_table<'a>(
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
