//! The quick reproduction on the real COLD data (the shipped copy, or
//! `$GRAPHSPN_DATA`; fails if missing): outputs exist and parse, accuracies are
//! probabilities, GraphSPN beats the evidence alone at NL2, and results do not
//! depend on the number of threads.

use std::path::PathBuf;

use graphspn_compiler::experiments::config::ReproduceConfig;
use graphspn_compiler::experiments::report::write_outputs;
use graphspn_compiler::experiments::reproduce::{load_data, run};
use graphspn_compiler::experiments::results::{Experiment, Reproduction, Table1Row};
use graphspn_compiler::experiments::summary::{SummaryCell, summarise};
use graphspn_compiler::learn::Progress;
use graphspn_compiler::noise::MeanStd;

fn data() -> PathBuf {
    let d = graphspn_compiler::map::cold::data_dir(None);
    assert!(d.is_dir(), "{} is not a folder", d.display());
    d
}

#[test]
fn quick_reproduction_on_cold() {
    let dir = data();
    let all = load_data(&dir).expect("load COLD maps");
    let mut cfg = ReproduceConfig::quick(7);
    cfg.progress = Progress::Hidden;
    let (mut rep, setups) = run(&all, &cfg).expect("quick run");

    // Same seed, one thread: identical results.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let (mut rep1, _) = pool.install(|| run(&all, &cfg)).expect("single-thread run");
    // Timings are the only thing allowed to differ.
    for b in rep.buildings.iter_mut().chain(rep1.buildings.iter_mut()) {
        b.train_seconds = 0.0;
        b.train_seconds_trees = 0.0;
    }
    for v in rep.validation.iter_mut().chain(rep1.validation.iter_mut()) {
        v.seconds.clear();
    }
    assert_eq!(
        serde_json::to_string(&rep).unwrap(),
        serde_json::to_string(&rep1).unwrap(),
        "results depend on the thread count"
    );

    let out = tempfile::tempdir().unwrap();
    write_outputs(&rep, &setups, &cfg, out.path(), "").expect("write outputs");
    let report = std::fs::read_to_string(out.path().join("REPORT.md")).unwrap();
    assert!(report.contains("Placeholders without evidence"));
    // A reproduction compares with the paper; the generated-code check is the CLI's
    // (none given here), and a section with nothing to say is left out.
    assert!(report.contains("# Semantic-map models on the COLD maps"));
    assert!(report.contains("paper NL2") && report.contains("(paper Table 1)"));
    assert!(!report.contains("Generated code check"));
    assert!(
        !report.contains("Map sets"),
        "no evaluation record in a reproduction"
    );
    // The ceiling table has one column per model and level, also with one level (it
    // repeated its columns then: "NL2 ... NL2").
    let head = |report: &str| -> String {
        let at = report
            .find("| Test building | placeholders | oracle")
            .expect("ceiling table");
        report[at..].lines().next().unwrap().to_string()
    };
    assert_eq!(head(&report).matches(" | ").count(), 8, "{}", head(&report));
    let mut single = rep.clone();
    let lowest = single.graphs.iter().map(|g| g.level).min().unwrap();
    single.graphs.retain(|g| g.level == lowest);
    let one = tempfile::tempdir().unwrap();
    write_outputs(&single, &setups, &cfg, one.path(), "").expect("write outputs");
    let report1 = std::fs::read_to_string(one.path().join("REPORT.md")).unwrap();
    let h = head(&report1);
    // A set without placeholders: its placeholder cells have no figure, no baseline
    // and no paired difference (they read "– vs MRF-2"), and no placeholder panel.
    let mut none = single.clone();
    for g in none
        .graphs
        .iter_mut()
        .filter(|g| g.experiment == Experiment::Placeholders)
    {
        g.scored = 0;
        g.evidence_only = f64::NAN;
        g.accuracy.0.iter_mut().for_each(|a| *a = f64::NAN);
    }
    for c in summarise(&none)
        .iter()
        .filter(|c| c.experiment == Experiment::Placeholders)
    {
        assert!(
            c.maps == 0 && c.better_tuned_mrf.is_none() && c.paired.is_empty(),
            "{c:?}"
        );
    }
    // A building with fewer maps than asked: the header says what ran.
    none.buildings[0].test_maps.truncate(1);
    let nothing = tempfile::tempdir().unwrap();
    write_outputs(&none, &setups, &cfg, nothing.path(), "").expect("write outputs");
    let report3 = std::fs::read_to_string(nothing.path().join("REPORT.md")).unwrap();
    assert!(!report3.contains("– vs"), "{report3}");
    assert!(
        report3.contains("up to 2 maps (1 in all: a building with fewer runs them all)"),
        "{report3}"
    );
    assert_eq!(h.matches(" | ").count(), 6, "{h}");
    // Without novelty detection (`--no-novelty`) the report names no ROC figure and
    // says it was not run.
    assert!(report.contains("`roc.svg`"));
    let mut plain = rep.clone();
    // The paper gives NL1's D_incorrect as 0.0 without a spread: shown so.
    let stat = |mean, std| MeanStd { mean, std, n: 10 };
    plain.table1.insert(
        0,
        Table1Row {
            level: 1,
            d_groundtruth: stat(0.99, 0.001),
            d_incorrect: stat(f64::NAN, 0.0),
        },
    );
    // A graph with no place scored (a map without placeholders) has NaN accuracies,
    // written as null.
    let last = plain.graphs.len() - 1;
    plain.graphs[last].scored = 0;
    plain.graphs[last].evidence_only = f64::NAN;
    plain.graphs[last].accuracy.0[1] = f64::NAN;
    plain.auc.clear();
    plain.within_map.clear();
    plain.novelty.clear();
    let no_novelty = tempfile::tempdir().unwrap();
    write_outputs(&plain, &setups, &cfg, no_novelty.path(), "").expect("write outputs");
    let report2 = std::fs::read_to_string(no_novelty.path().join("REPORT.md")).unwrap();
    assert!(
        !report2.contains("roc.svg") && report2.contains("Novelty detection was not run"),
        "{report2}"
    );
    let nl1 = report2
        .lines()
        .find(|l| l.starts_with("| 1 | "))
        .expect("NL1 row");
    assert!(nl1.ends_with("| – | 0.0 |"), "{nl1}");
    // A statistic over no place is written as null and read back as NaN.
    let json2 = std::fs::read_to_string(no_novelty.path().join("results.json")).unwrap();
    let back: Reproduction = serde_json::from_str(&json2).expect("results.json parses");
    assert!(back.table1[0].d_incorrect.mean.is_nan());
    let g = &back.graphs[last];
    assert!(g.evidence_only.is_nan() && g.accuracy[1].is_nan() && g.accuracy[0].is_finite());
    assert_eq!(back.table1[1..], plain.table1[1..]);
    assert!(report.contains("1 round per map") && !report.contains("1 rounds"));
    // The quick run's validation is a reduced search, and the report says so.
    assert!(
        report.contains("The search: ") && report.contains("**a reduced search**"),
        "{report}"
    );
    assert_eq!(h.matches(&format!("NL{lowest}")).count(), 3, "{h}");
    let json = std::fs::read_to_string(out.path().join("results.json")).unwrap();
    let parsed: Reproduction = serde_json::from_str(&json).expect("results.json parses");
    // 1 building × 2 maps × 2 levels × 1 round × 2 experiments.
    assert_eq!(parsed.graphs.len(), 8);
    assert_eq!(parsed.buildings[0].test_maps.len(), 2);
    for f in [
        "accuracy_Stockholm.svg",
        "roc.svg",
        "fig8_Stockholm.svg",
        "placeholders_Stockholm.svg",
    ] {
        let svg = std::fs::read_to_string(out.path().join(f)).unwrap();
        roxmltree::Document::parse(&svg).unwrap_or_else(|e| panic!("{f} is not XML: {e}"));
    }
    for g in &parsed.graphs {
        for a in g.accuracy.0.iter().chain([&g.evidence_only]) {
            assert!(
                a.is_nan() && g.scored == 0 || (0.0..=1.0).contains(a),
                "{g:?}"
            );
        }
    }
    let nl2: Vec<_> = parsed
        .graphs
        .iter()
        .filter(|g| g.level == 2 && g.experiment == Experiment::Classification)
        .collect();
    assert_eq!(nl2.len(), 2);
    for g in nl2 {
        for (name, a) in g.accuracy.named().take(2) {
            assert!(
                *a > g.evidence_only,
                "{name} {a} does not beat the evidence {} on {}",
                g.evidence_only,
                g.map
            );
        }
    }
    // results.json names every model beside its figures.
    let raw: serde_json::Value = serde_json::from_str(&json).unwrap();
    for g in raw["graphs"].as_array().unwrap() {
        for m in graphspn_compiler::experiments::models::MODELS {
            assert!(g["accuracy"][m].is_number(), "{m} missing in {g}");
        }
        assert!(g["bp_converged"]["MRF-2"].is_boolean());
    }
    for n in raw["novelty"].as_array().unwrap() {
        assert!(n["score"]["Tree mixture"].is_number());
    }
    assert_eq!(parsed.auc.len(), 2, "both novelty sets scored");
    for auc in &parsed.auc {
        assert!(auc.scores.0.iter().all(|a| (0.0..=1.0).contains(a)));
    }
    assert_eq!(raw["auc"][0]["set"], "paper");
    assert!(raw["table1"][0]["d_groundtruth"]["mean"].is_number());
    // results.json carries the report's summary figures: every cell, with the same
    // interval REPORT.md prints.
    let summary = raw["summary"].as_array().expect("summary");
    assert_eq!(
        summary.len(),
        2 * 2,
        "1 building × 2 experiments × 2 levels"
    );
    for c in summary {
        let cell: SummaryCell = serde_json::from_value(c.clone()).expect("a summary cell");
        let acc = cell.accuracy.0[0].expect("tree mixture scored");
        assert!(acc.low <= acc.mean && acc.mean <= acc.high, "{cell:?}");
        assert_eq!(cell.paired.len(), 2);
        assert_eq!(cell.paired[0].model, "Tree mixture");
        assert!(["MRF-2", "MRF-3"].contains(&cell.better_tuned_mrf.as_deref().unwrap()));
        let row = "| Stockholm | Tree mixture | ";
        let line = report
            .lines()
            .filter(|l| l.starts_with(row))
            .nth(cell.experiment as usize)
            .expect("accuracy row");
        assert!(
            line.contains(&acc.percent()),
            "{line} lacks {}",
            acc.percent()
        );
        let d = cell.paired[0].difference.expect("paired difference");
        let shown = format!("{} vs {}", d.percent(), cell.paired[0].baseline);
        assert!(report.contains(&shown), "REPORT.md lacks {shown}");
    }
}

#[test]
fn novelty_labellings_swap_whole_maps_and_connected_quarter_regions() {
    use graphspn_compiler::experiments::novelty::{
        LOCAL_REGION_SHARE, LOCAL_REGIONS, NoveltySet, novelty_labellings,
    };
    use graphspn_compiler::template::Adjacency;
    let all = load_data(&data()).unwrap();
    let map = &all["Stockholm"][0];
    let truth: Vec<_> = map.places().map(|p| p.class.unwrap()).collect();
    let ls = novelty_labellings(map, &truth, 3);
    assert_eq!(ls, novelty_labellings(map, &truth, 3), "seeded");
    assert_eq!(ls[0].name, "original");
    assert_eq!(ls[0].labels, truth);
    let (cr, dw) = (
        map.classes.index_of("CR").unwrap(),
        map.classes.index_of("DW").unwrap(),
    );
    let whole = ls.iter().find(|l| l.name == "CR<->DW").unwrap();
    assert!(whole.novel && whole.set == NoveltySet::Paper);
    for (i, (&t, &l)) in truth.iter().zip(&whole.labels).enumerate() {
        let want = if t == cr {
            dw
        } else if t == dw {
            cr
        } else {
            t
        };
        assert_eq!(l, want, "place index {i}");
    }
    let adj = Adjacency::new(map);
    let local: Vec<_> = ls.iter().filter(|l| l.set == NoveltySet::Local).collect();
    assert_eq!(local.len(), 3 * LOCAL_REGIONS);
    let quarter = (LOCAL_REGION_SHARE * truth.len() as f64).ceil() as usize;
    for l in local {
        // Changed places: some, all swapped classes of one pair, within a connected
        // region of a quarter of the map (so fewer than the whole-map swap changes).
        let changed: Vec<usize> = (0..truth.len())
            .filter(|&i| l.labels[i] != truth[i])
            .collect();
        assert!(
            !changed.is_empty() && changed.len() <= quarter,
            "{}",
            l.name
        );
        let base = l.name.split(" local").next().unwrap();
        let full = ls.iter().find(|x| x.name == base).unwrap();
        assert_eq!(l.novel, full.novel);
        for &i in &changed {
            assert_eq!(l.labels[i], full.labels[i], "{} place {i}", l.name);
        }
        // The region grows breadth-first from one place, so (loosely) every changed
        // place is within `quarter` hops of the first one.
        let mut dist = vec![usize::MAX; truth.len()];
        let mut queue = std::collections::VecDeque::from([changed[0]]);
        dist[changed[0]] = 0;
        while let Some(u) = queue.pop_front() {
            for &v in adj.neighbors(u) {
                if dist[v] == usize::MAX {
                    dist[v] = dist[u] + 1;
                    queue.push_back(v);
                }
            }
        }
        assert!(changed.iter().all(|&i| dist[i] <= quarter), "{}", l.name);
    }
}

#[test]
fn class_prior_and_prior_corrected_rows() {
    use graphspn_compiler::experiments::models::graphspn_rows;
    use graphspn_compiler::experiments::reproduce::class_prior;
    let all = load_data(&data()).unwrap();
    // Freiburg has no LAB and no MR: smoothing keeps them at 1% (α = 0.1, 10 classes).
    let p = class_prior(&all["Freiburg"], 10);
    assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    let lab = all["Freiburg"][0].classes.index_of("LAB").unwrap() as usize;
    assert!((p[lab] - 0.01 / 1.1).abs() < 1e-12, "{}", p[lab]);
    let cr = all["Freiburg"][0].classes.index_of("CR").unwrap() as usize;
    assert!(p[cr] > 0.3);
    // β = 0 and exponent 1: the rows as given; a uniform row becomes prior^-β, normalised.
    let rows = vec![vec![0.1; 10], (1..=10).map(|k| k as f64 / 55.0).collect()];
    assert_eq!(graphspn_rows(&rows, 1.0, &p, 0.0), rows);
    let r = graphspn_rows(&rows, 2.0, &p, 0.5);
    let z: f64 = p.iter().map(|x| x.powf(-0.5)).sum();
    for k in 0..10 {
        assert!((r[0][k] - p[k].powf(-0.5) / z).abs() < 1e-12);
    }
    assert!((r[1].iter().sum::<f64>() - 1.0).abs() < 1e-12);
    assert!(
        r[0][lab] > r[0][cr],
        "a rare class gains against a common one"
    );
}
