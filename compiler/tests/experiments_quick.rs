//! The quick reproduction on the real COLD data (the shipped copy, or
//! `$GRAPHSPN_DATA`; fails if missing): outputs exist and parse, accuracies are
//! probabilities, GraphSPN beats the evidence alone at NL2, and results do not
//! depend on the number of threads.

use std::path::PathBuf;

use graphspn_compiler::experiments::report::write_outputs;
use graphspn_compiler::experiments::reproduce::{
    Experiment, ReproduceConfig, Reproduction, load_data, run,
};
use graphspn_compiler::learn::Progress;

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
    assert!(report.contains("Generated code check"));
    let parsed: Reproduction =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("results.json")).unwrap())
            .expect("results.json parses");
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
        for a in g.accuracy.iter().chain([&g.evidence_only]) {
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
        assert!(
            g.accuracy[0] > g.evidence_only,
            "GraphSPN {} does not beat the evidence {} on {}",
            g.accuracy[0],
            g.evidence_only,
            g.map
        );
    }
    let auc = parsed.auc.expect("novelty ran");
    assert!(auc.iter().all(|a| (0.0..=1.0).contains(a)));
}
