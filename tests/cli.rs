//! The command-line tool end to end on the committed demo inputs (no data set needed):
//! `infer` (marginals, MPE, evidence errors naming the file line and place id),
//! `instance` export, `compile`, and `validate` + `reproduce --settings`.

use std::path::PathBuf;
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_graphspn"))
}

fn demo(file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("generated/demo")
        .join(file)
}

/// `graphspn compile` of the demo floor into `out`.
fn compile_demo(out: &std::path::Path) -> Command {
    let mut cmd = bin();
    cmd.args(["compile", "--module", "floor", "--model"])
        .arg(demo("model.json"))
        .arg("--map")
        .arg(demo("floor.json"))
        .arg("--out")
        .arg(out);
    cmd
}

fn run_ok(cmd: &mut Command) -> String {
    let out = cmd.output().expect("graphspn runs");
    assert!(
        out.status.success(),
        "graphspn failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8 output")
}

#[test]
fn infer_gives_normalised_marginals_and_the_likelihood_of_the_evidence() {
    let dir = tempfile::tempdir().unwrap();
    // Certain evidence on place 0 (class CR) and nothing elsewhere: the marginal of place 0
    // is one-hot, every row sums to 1, and ln P(evidence) = ln P(Y_0 = CR) < 0.
    let ev = dir.path().join("ev.json");
    std::fs::write(
        &ev,
        r#"{"format": 1, "evidence": {"0": [0, 1, 0, 0, 0, 0, 0, 0, 0, 0]}}"#,
    )
    .unwrap();
    let text = run_ok(
        bin()
            .args(["infer", "--model"])
            .arg(demo("model.json"))
            .arg("--map")
            .arg(demo("floor.json"))
            .arg("--evidence")
            .arg(&ev)
            .arg("--mpe"),
    );
    let v: serde_json::Value = serde_json::from_str(&text).expect("infer writes JSON");
    let ll = v["log_likelihood"].as_f64().expect("log_likelihood");
    assert!(ll < 0.0 && ll > -5.0, "ln P(Y_0 = CR) = {ll}");
    let places = v["places"].as_array().expect("places");
    assert_eq!(places.len(), 80);
    for p in places {
        let probs: Vec<f64> = p["probs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert!((probs.iter().sum::<f64>() - 1.0).abs() < 1e-9, "{p}");
    }
    let first = places.iter().find(|p| p["id"] == 0).expect("place 0");
    assert_eq!(first["argmax"], "CR");
    assert_eq!(v["mpe"]["labels"]["0"], "CR");
}

#[test]
fn infer_names_the_line_and_place_of_bad_evidence() {
    let dir = tempfile::tempdir().unwrap();
    let ev = dir.path().join("bad.json");
    std::fs::write(
        &ev,
        "{\"format\": 1, \"evidence\": {\n\"99999\": [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]}}",
    )
    .unwrap();
    let out = bin()
        .args(["infer", "--model"])
        .arg(demo("model.json"))
        .arg("--map")
        .arg(demo("floor.json"))
        .arg("--evidence")
        .arg(&ev)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.json:2") && err.contains("99999"), "{err}");
}

#[test]
fn instance_exports_dot_and_compile_writes_generated_source() {
    let dot = run_ok(
        bin()
            .args(["instance", "--format", "dot", "--model"])
            .arg(demo("model.json"))
            .arg("--map")
            .arg(demo("floor.json")),
    );
    assert!(dot.starts_with("digraph instance {") && dot.trim_end().ends_with('}'));
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("floor.rs");
    run_ok(&mut compile_demo(&out));
    let src = std::fs::read_to_string(&out).unwrap();
    assert!(src.starts_with("// @generated"), "{}", &src[..80]);
    assert!(src.contains("pub const NUM_PLACES: usize = 80;"));
    // A hand-written file is not overwritten without --force.
    std::fs::write(&out, "// mine\n").unwrap();
    let status = compile_demo(&out).status().unwrap();
    assert!(!status.success());
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "// mine\n");
    // Nor is an existing --export-map file with other content.
    let exported = dir.path().join("map.json");
    std::fs::write(&exported, "{}").unwrap();
    let status = compile_demo(&dir.path().join("other.rs"))
        .arg("--export-map")
        .arg(&exported)
        .status()
        .unwrap();
    assert!(!status.success());
    assert_eq!(std::fs::read_to_string(&exported).unwrap(), "{}");
}

/// `graphspn compile` of a tree mixture: the same module API, the report on standard
/// error, `--count` overriding the model's trees; GraphSPN-only options refused naming
/// the model file.
#[test]
fn compile_writes_a_tree_mixture_module_and_reports_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("floor_trees.rs");
    let run = bin()
        .args([
            "compile",
            "--module",
            "floor_trees",
            "--scalar",
            "--count",
            "3",
            "--model",
        ])
        .arg(demo("tree_model.json"))
        .arg("--map")
        .arg(demo("floor.json"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    assert!(
        err.contains("tree mixture: 3 trees") && err.contains("stack per call"),
        "{err}"
    );
    assert!(err.contains("3 spanning trees"), "{err}");
    let src = std::fs::read_to_string(&out).unwrap();
    assert!(src.contains("pub const MODEL_FAMILY: &str = \"tree_mixture\";"));
    assert!(src.contains("pub const NUM_TREES: usize = 3;"));
    assert!(
        !err.contains("fixed point") && src.contains("fixed: None"),
        "{err}"
    );
    // For a target without an FPU: fixed-point messages, with their bound reported.
    let run = bin()
        .args(["compile", "--fixed-point", "--count", "3", "--model"])
        .arg(demo("tree_model.json"))
        .arg("--map")
        .arg(demo("floor.json"))
        .arg("--out")
        .arg(dir.path().join("fixed.rs"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    assert!(
        err.contains("messages in fixed point, each entry within 4.71e-5"),
        "{err}"
    );
    let src = std::fs::read_to_string(dir.path().join("fixed.rs")).unwrap();
    assert!(src.contains("FixedMatrices {") && src.contains("SoftF32"));
    for flags in [["--strategy", "cover"], ["--decompositions", "d.json"]] {
        let run = bin()
            .args(["compile", "--model"])
            .arg(demo("tree_model.json"))
            .arg("--map")
            .arg(demo("floor.json"))
            .args(flags)
            .arg("--out")
            .arg(dir.path().join("x.rs"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success(), "{flags:?}");
        assert!(
            err.contains("tree_model.json") && err.contains("tree mixture"),
            "{flags:?}: {err}"
        );
    }
}

/// `graphspn validate` (tiny grid, one test building, shipped data) writes its table
/// and settings, and `reproduce --settings` reuses them: the report names the
/// validated settings and carries the tuned and paper-style baselines with intervals.
#[test]
fn validate_then_reproduce_with_the_saved_settings() {
    let dir = tempfile::tempdir().unwrap();
    let val = dir.path().join("val");
    run_ok(
        bin()
            .args([
                "validate",
                "--buildings",
                "Stockholm",
                "--tiny-grid",
                "--out",
            ])
            .arg(&val),
    );
    let md = std::fs::read_to_string(val.join("VALIDATION.md")).unwrap();
    assert!(md.contains("| Stockholm |") && md.contains("MRF-2"), "{md}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(val.join("validation.json")).unwrap())
            .unwrap();
    assert!(json["settings"]["Stockholm"].is_object(), "{json}");
    let out = dir.path().join("out");
    run_ok(
        bin()
            .args(["reproduce", "--quick", "--no-novelty", "--settings"])
            .arg(val.join("validation.json"))
            .arg("--out")
            .arg(&out),
    );
    let report = std::fs::read_to_string(out.join("REPORT.md")).unwrap();
    for want in ["MRF-2 paper", "evidence only", "Paired difference", "["] {
        assert!(report.contains(want), "REPORT.md lacks {want:?}");
    }
}

#[test]
fn evaluate_runs_the_protocol_on_a_building_the_data_folder_does_not_hold() {
    // A user's building: two synthetic floors from our generator and a COLD sequence
    // copied under another name, in a folder outside the data folder.
    let dir = tempfile::tempdir().unwrap();
    let building = dir.path().join("my_office");
    std::fs::create_dir(&building).unwrap();
    for seed in ["1", "2"] {
        run_ok(
            bin()
                .args(["generate", "--places", "90", "--seed", seed, "--out"])
                .arg(building.join(format!("floor_{seed}.json"))),
        );
    }
    let cold =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/cold-topomaps/Freiburg/seq1_cloudy1");
    let copy = building.join("annex_level_2");
    std::fs::create_dir(&copy).unwrap();
    for f in ["nodes.dat", "rooms.dat"] {
        std::fs::copy(cold.join(f), copy.join(f)).unwrap();
    }
    // A second test set in a folder named like a default training building (a new set
    // of Stockholm maps): accepted, reported under a distinct name.
    let stockholm = dir.path().join("Stockholm");
    std::fs::create_dir(&stockholm).unwrap();
    run_ok(
        bin()
            .args(["generate", "--places", "60", "--seed", "3", "--out"])
            .arg(stockholm.join("floor_3.json")),
    );
    let out = dir.path().join("eval");
    let stderr = bin()
        .args(["evaluate", "--maps"])
        .arg(&building)
        .arg("--maps")
        .arg(&stockholm)
        .args(["--tiny-grid", "--levels", "2", "--rounds", "1", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        stderr.status.success(),
        "{}",
        String::from_utf8_lossy(&stderr.stderr)
    );
    assert!(
        String::from_utf8_lossy(&stderr.stderr).contains("Stockholm-test"),
        "the renamed set is announced"
    );
    let report = std::fs::read_to_string(out.join("REPORT.md")).unwrap();
    for want in [
        "# Evaluation of the semantic-map models on your maps: my_office and Stockholm-test",
        "on the three training buildings Freiburg, Saarbrucken and Stockholm only",
        "| my_office | Freiburg, Saarbrucken, Stockholm |",
        "| my_office | GraphSPN |",
        "| my_office | MRF-2 |",
        "| Stockholm-test | Freiburg, Saarbrucken, Stockholm |",
        "| Stockholm-test | GraphSPN paper |",
        "| Stockholm | training | bundled COLD building",
        "| Stockholm-test | test |",
        "is also the name of training building \"Stockholm\"",
        "Paired difference",
        "pooled AUC, local set",
        "## Evidence statistics",
        "labels_my_office.svg",
    ] {
        assert!(report.contains(want), "REPORT.md lacks {want:?}:\n{report}");
    }
    // An evaluation speaks about the user's maps: no paper figures or wording, no
    // section with nothing to say.
    for unwanted in [
        "COLD maps: results",
        "two training buildings",
        "paper NL",
        "paper Fig",
        "paper Table",
        "Fig. 5",
        "| paper |",
        "Generated code check",
        "fig8_",
    ] {
        assert!(
            !report.contains(unwanted),
            "REPORT.md has {unwanted:?}:\n{report}"
        );
    }
    let headings: Vec<&str> = report.lines().filter(|l| l.starts_with('#')).collect();
    let body_after = |h: &str| {
        let rest = &report[report.find(h).unwrap() + h.len()..];
        rest[..rest.find("\n#").unwrap_or(rest.len())].trim().len()
    };
    for h in headings {
        assert!(body_after(h) > 0, "section {h:?} is empty:\n{report}");
    }
    assert!(out.join("labels_Stockholm-test.svg").exists());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let maps: std::collections::BTreeSet<&str> = json["graphs"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|g| g["building"] == "my_office")
        .map(|g| g["map"].as_str().unwrap())
        .collect();
    assert_eq!(maps.len(), 3, "every map of the folder is tested: {maps:?}");
    let sets = json["evaluation"]["sets"].as_array().unwrap();
    assert_eq!(sets.len(), 5, "two test sets, three training buildings");
    assert_eq!(sets[1]["name"], "Stockholm-test");
    assert_eq!(sets[1]["role"], "test");
    assert!(maps.contains("my_office/annex_level_2"), "{maps:?}");
    // One validation on the three COLD buildings (three folds), none on the test maps.
    let folds = json["validation"][0]["folds"].as_array().unwrap();
    assert_eq!(folds.len(), 3);
    assert!(!json["validation"].to_string().contains("my_office/"));

    // NAME=PATH: a name the user gives is checked before anything runs, and two sets
    // given one name are refused with what to do.
    for (args, want) in [
        (vec!["a/b=".to_string()], "'/'"),
        (
            vec![
                format!("x={}", building.display()),
                format!("x={}", stockholm.display()),
            ],
            "NAME=PATH",
        ),
    ] {
        let mut cmd = bin();
        cmd.arg("evaluate");
        for a in &args {
            let a = if a.ends_with('=') {
                format!("{a}{}", building.display())
            } else {
                a.clone()
            };
            cmd.arg("--maps").arg(a);
        }
        let bad = cmd
            .arg("--out")
            .arg(dir.path().join("bad_name"))
            .output()
            .unwrap();
        assert!(!bad.status.success());
        let msg = String::from_utf8_lossy(&bad.stderr);
        assert!(msg.contains("--maps") && msg.contains(want), "{msg}");
        assert!(!dir.path().join("bad_name").exists());
    }

    // The same maps as test and training set: refused (a distinct name would hide
    // that the test maps are trained on), naming both arguments.
    let twice = bin()
        .args(["evaluate", "--maps"])
        .arg(&stockholm)
        .arg("--train")
        .arg(&stockholm)
        .arg("--train")
        .arg(&building)
        .arg("--out")
        .arg(dir.path().join("bad"))
        .output()
        .unwrap();
    assert!(!twice.status.success());
    let msg = String::from_utf8_lossy(&twice.stderr);
    assert!(
        msg.contains("--maps") && msg.contains("--train") && msg.contains("given twice"),
        "{msg}"
    );

    // Bad input: one training building is not enough for the validation.
    let bad = bin()
        .args(["evaluate", "--maps"])
        .arg(&building)
        .arg("--train")
        .arg(&building)
        .arg("--out")
        .arg(dir.path().join("bad"))
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let msg = String::from_utf8_lossy(&bad.stderr);
    assert!(
        msg.contains("--train") && msg.contains("at least two"),
        "{msg}"
    );
    assert!(!dir.path().join("bad").exists());
}

#[test]
fn the_validated_graphspn_options_are_on_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    // train --temperature: recorded in the model's settings.
    let model = dir.path().join("model.json");
    run_ok(
        bin()
            .args([
                "train",
                "--buildings",
                "Freiburg,Stockholm",
                "--epochs",
                "2",
            ])
            .args(["--temperature", "0.8", "--out"])
            .arg(&model),
    );
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    assert_eq!(m["settings"]["temperature"], 0.8);
    // train --star-split fewest_images: the smaller Star (3,750 sum weights with 10
    // classes, against 8,000 for the default most_images).
    let small = dir.path().join("small.json");
    run_ok(
        bin()
            .args([
                "train",
                "--buildings",
                "Freiburg,Stockholm",
                "--epochs",
                "1",
            ])
            .args(["--star-split", "fewest_images", "--out"])
            .arg(&small),
    );
    let weights = |m: &serde_json::Value| -> usize {
        m["spns"][0]["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|n| n["weights"].as_array().map(Vec::len))
            .sum()
    };
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&small).unwrap()).unwrap();
    assert_eq!(s["settings"]["structure"]["split_choice"], "fewest_images");
    assert_eq!(m["settings"]["structure"]["split_choice"], "most_images");
    assert_eq!((weights(&s), weights(&m)), (3750, 8000));
    // infer --strategy cover --mixing average: normalised rows, and not the posterior
    // mix (with evidence, the decompositions' posterior weights differ).
    let ev = dir.path().join("ev.json");
    let rows: Vec<String> = (0..40)
        .map(|i| {
            let mut r = ["0.02"; 10];
            r[i % 10] = "0.8";
            format!("\"{i}\": [{}]", r.join(", "))
        })
        .collect();
    std::fs::write(
        &ev,
        format!("{{\"format\": 1, \"evidence\": {{{}}}}}", rows.join(", ")),
    )
    .unwrap();
    let infer = |mixing: &str| -> serde_json::Value {
        let text = run_ok(
            bin()
                .args(["infer", "--model"])
                .arg(&model)
                .arg("--map")
                .arg(demo("floor.json"))
                .arg("--evidence")
                .arg(&ev)
                .args(["--decompositions", "4"])
                .args(["--strategy", "cover", "--mixing", mixing]),
        );
        serde_json::from_str(&text).unwrap()
    };
    let (avg, post) = (infer("average"), infer("posterior"));
    assert_eq!(avg["model"]["mixing"], "average");
    assert_eq!(avg["log_likelihood"], post["log_likelihood"]);
    let rows = |v: &serde_json::Value| -> Vec<Vec<f64>> {
        v["places"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| serde_json::from_value(p["probs"].clone()).unwrap())
            .collect()
    };
    let (a, p) = (rows(&avg), rows(&post));
    assert!(a.iter().all(|r| (r.iter().sum::<f64>() - 1.0).abs() < 1e-9));
    assert!(
        a.iter()
            .zip(&p)
            .any(|(x, y)| x.iter().zip(y).any(|(u, v)| (u - v).abs() > 1e-6))
    );
    // decompose --strategy cover writes decompositions compile accepts.
    let decs = dir.path().join("d.json");
    run_ok(
        bin()
            .args(["decompose", "--model"])
            .arg(&model)
            .args(["--map", "Saarbrucken/seq1_cloudy1", "--count", "2"])
            .args(["--strategy", "cover", "--out"])
            .arg(&decs),
    );
    assert!(
        std::fs::read_to_string(&decs)
            .unwrap()
            .contains("\"components\"")
    );
}

/// A tree mixture through the command line: train it, infer with both mixings, the
/// MPE labelling, another tree count, and draw one of its spanning trees.
#[test]
fn a_tree_mixture_trains_infers_and_renders() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("trees.json");
    run_ok(
        bin()
            .args([
                "train",
                "--family",
                "tree-mixture",
                "--buildings",
                "Freiburg",
            ])
            .args([
                "--coupling",
                "0.8",
                "--evidence-exponent",
                "3",
                "--trees",
                "3",
            ])
            .args(["--mixing", "posterior", "--out"])
            .arg(&model),
    );
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    assert_eq!(m["family"], "tree_mixture");
    assert_eq!(m["trees"], 3);
    assert_eq!(m["evidence_exponent"], 3);
    assert_eq!(m["settings"]["potentials"]["coupling"], 0.8);
    let ev = dir.path().join("ev.json");
    std::fs::write(
        &ev,
        r#"{"format": 1, "evidence": {"1": [0.1, 0.9, 0, 0, 0, 0, 0, 0, 0, 0], "7": [1, 0.2, 0.2, 0.2, 0.2, 0.2, 0.2, 0.2, 0.2, 0.2]}}"#,
    )
    .unwrap();
    let infer = |extra: &[&str]| -> serde_json::Value {
        let text = run_ok(
            bin()
                .args(["infer", "--model"])
                .arg(&model)
                .arg("--map")
                .arg(demo("floor.json"))
                .arg("--evidence")
                .arg(&ev)
                .args(extra),
        );
        serde_json::from_str(&text).unwrap()
    };
    let post = infer(&["--mpe"]);
    let avg = infer(&["--mixing", "average"]);
    assert_eq!(post["model"]["family"], "tree_mixture");
    assert_eq!(post["model"]["trees"], 3);
    assert_eq!(post["model"]["mixing"], "posterior");
    assert_eq!(avg["model"]["mixing"], "average");
    assert_eq!(post["model"]["edges_covered"], post["model"]["edges"]);
    assert_eq!(post["log_likelihood"], avg["log_likelihood"]);
    assert!(post["log_likelihood"].as_f64().unwrap() < 0.0);
    for v in [&post, &avg] {
        for p in v["places"].as_array().unwrap() {
            let row: Vec<f64> = serde_json::from_value(p["probs"].clone()).unwrap();
            assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        }
    }
    let mpe = &post["mpe"];
    assert!(mpe["log_probability"].as_f64().unwrap() >= mpe["log_max_product"].as_f64().unwrap());
    assert_eq!(infer(&["--trees", "1"])["model"]["trees"], 1);
    let svg = dir.path().join("t.svg");
    run_ok(
        bin()
            .args(["render", "--map"])
            .arg(demo("floor.json"))
            .arg("--model")
            .arg(&model)
            .args(["--tree", "3", "--out"])
            .arg(&svg),
    );
    let text = std::fs::read_to_string(&svg).unwrap();
    roxmltree::Document::parse(&text).unwrap();
    assert_eq!(
        text.matches("tree-edge").count(),
        79,
        "a spanning tree of 80 places"
    );
}

/// `evaluate --settings`: a held-out building (a COLD building's maps copied into a
/// folder of the same name, as a user's new Stockholm maps would be) tested with the settings of a saved validation on the other two
/// buildings, with no validation run; `--settings-of` picks the entry.
#[test]
fn evaluate_reuses_a_saved_validation() {
    use graphspn_compiler::experiments::settings::{GraphSpnSetting, ModelSettings, MrfSetting};
    use graphspn_compiler::mrf::BpOptions;
    use graphspn_compiler::treemix::TreeTraining;
    let dir = tempfile::tempdir().unwrap();
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/cold-topomaps");
    // Named like the paper's building: the report must still not print the paper's
    // figures for it (they belong to the paper's test maps, not to these).
    let held = dir.path().join("Stockholm");
    std::fs::create_dir(&held).unwrap();
    for seq in ["floor4_cloudy_a1", "floor4_cloudy_b"] {
        let to = held.join(seq);
        std::fs::create_dir(&to).unwrap();
        for f in ["nodes.dat", "rooms.dat"] {
            std::fs::copy(data.join("Stockholm").join(seq).join(f), to.join(f)).unwrap();
        }
    }
    let trees = TreeTraining {
        trees: 2,
        ..TreeTraining::default()
    };
    let chosen = ModelSettings {
        graphspn: GraphSpnSetting::paper(),
        mrf2: MrfSetting::paper(BpOptions::default()),
        mrf3: MrfSetting::paper(BpOptions::default()),
        trees,
    };
    let settings = dir.path().join("validation.json");
    let file = serde_json::json!({"settings": {"Stockholm": chosen, "Freiburg": chosen}});
    std::fs::write(&settings, file.to_string()).unwrap();
    let eval = |extra: &[&str], out: &str| {
        bin()
            .args(["evaluate", "--maps"])
            .arg(&held)
            .arg("--train")
            .arg(data.join("Freiburg"))
            .arg("--train")
            .arg(data.join("Saarbrucken"))
            .arg("--settings")
            .arg(&settings)
            .args(["--levels", "2", "--rounds", "1", "--no-novelty", "--out"])
            .arg(dir.path().join(out))
            .args(extra)
            .output()
            .unwrap()
    };
    let refused = eval(&[], "e0");
    assert!(!refused.status.success());
    let msg = String::from_utf8_lossy(&refused.stderr);
    assert!(
        msg.contains("--settings-of") && msg.contains("Freiburg, Stockholm"),
        "{msg}"
    );
    let ok = eval(&["--settings-of", "Stockholm"], "e1");
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("e1/results.json")).unwrap())
            .unwrap();
    assert!(
        json["validation"].as_array().unwrap().is_empty(),
        "no validation run"
    );
    assert_eq!(json["buildings"][0]["settings"]["trees"]["trees"], 2);
    let report = std::fs::read_to_string(dir.path().join("e1/REPORT.md")).unwrap();
    for want in [
        "# Evaluation of the semantic-map models on your maps: Stockholm",
        "Every setting below was given (`--settings`",
        "| Stockholm | Freiburg, Saarbrucken |",
    ] {
        assert!(report.contains(want), "REPORT.md lacks {want:?}:\n{report}");
    }
    for unwanted in [
        "paper NL",
        "paper Table",
        "chosen by leave-one-training-building-out",
        "Generated code check",
    ] {
        assert!(
            !report.contains(unwanted),
            "REPORT.md has {unwanted:?}:\n{report}"
        );
    }
    for g in json["graphs"].as_array().unwrap() {
        assert_eq!(g["building"], "Stockholm");
        assert!(g["accuracy"]["Tree mixture"].as_f64().unwrap() > 0.5);
    }
}

/// `infer` reads evidence on every place of a 20,000-place map in one pass (it used to
/// look every key's line up by rescanning the file: about 30 s at this size, against
/// about 1 s), and an error deep in the file still names its line.
#[test]
fn infer_reads_evidence_on_every_place_of_a_large_map_in_one_pass() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("floor.json");
    run_ok(
        bin()
            .args(["generate", "--places", "20000", "--seed", "3", "--out"])
            .arg(&map),
    );
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&map).unwrap()).unwrap();
    let ids: Vec<u64> = m["places"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["id"].as_u64().unwrap())
        .collect();
    let rows: Vec<String> = ids
        .iter()
        .enumerate()
        .map(|(i, id)| {
            let mut r = ["0.05"; 10];
            r[i % 10] = "0.7";
            format!("    \"{id}\": [{}]", r.join(", "))
        })
        .collect();
    let write = |rows: &[String], path: &std::path::Path| {
        std::fs::write(
            path,
            format!(
                "{{\n  \"format\": 1,\n  \"evidence\": {{\n{}\n  }}\n}}\n",
                rows.join(",\n")
            ),
        )
        .unwrap()
    };
    let ev = dir.path().join("ev.json");
    write(&rows, &ev);
    let infer = |ev: &std::path::Path| {
        bin()
            .args(["infer", "--model"])
            .arg(demo("model.json"))
            .arg("--map")
            .arg(&map)
            .arg("--evidence")
            .arg(ev)
            .args(["--decompositions", "1"])
            .output()
            .unwrap()
    };
    let start = std::time::Instant::now();
    let out = infer(&ev);
    let secs = start.elapsed().as_secs_f64();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["places"].as_array().unwrap().len(), ids.len());
    assert!(secs < 15.0, "infer took {secs:.1} s");
    // A negative likelihood on the last row but one: line 4 + its index.
    let k = ids.len() - 2;
    let mut bad = rows.clone();
    bad[k] = format!("    \"{}\": [1, 1, -1, 1, 1, 1, 1, 1, 1, 1]", ids[k]);
    let bad_ev = dir.path().join("bad.json");
    write(&bad, &bad_ev);
    let out = infer(&bad_ev);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains(&format!("bad.json:{}: place id {}", k + 4, ids[k])),
        "{err}"
    );
}
