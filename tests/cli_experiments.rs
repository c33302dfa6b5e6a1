//! The experiment commands end to end on the shipped data (tiny grids): `validate`,
//! `reproduce --settings` and `evaluate` on a building the data folder does not hold,
//! with and without a saved validation.

mod cli_support;

use std::path::PathBuf;

use cli_support::{bin, run_ok, run_refused};

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
    // The report names the settings file and says how large the search behind it
    // was: a --tiny-grid validation is a reduced search, also when reused.
    assert_eq!(json["sample"]["rounds"], 1, "{json}");
    for want in [
        "Every setting below was given: `--settings ",
        "on 1 map × NL2 × 1 round per validation building — **a reduced search**",
    ] {
        assert!(report.contains(want), "REPORT.md lacks {want:?}:\n{report}");
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
        let msg = run_refused(cmd.arg("--out").arg(dir.path().join("bad_name")));
        assert!(msg.contains("--maps") && msg.contains(want), "{msg}");
        assert!(!dir.path().join("bad_name").exists());
    }

    // The same maps as test and training set: refused (a distinct name would hide
    // that the test maps are trained on), naming both arguments.
    let msg = run_refused(
        bin()
            .args(["evaluate", "--maps"])
            .arg(&stockholm)
            .arg("--train")
            .arg(&stockholm)
            .arg("--train")
            .arg(&building)
            .arg("--out")
            .arg(dir.path().join("bad")),
    );
    assert!(
        msg.contains("--maps") && msg.contains("--train") && msg.contains("given twice"),
        "{msg}"
    );

    // Bad input: one training building is not enough for the validation.
    let msg = run_refused(
        bin()
            .args(["evaluate", "--maps"])
            .arg(&building)
            .arg("--train")
            .arg(&building)
            .arg("--out")
            .arg(dir.path().join("bad")),
    );
    assert!(
        msg.contains("--train") && msg.contains("at least two"),
        "{msg}"
    );
    assert!(!dir.path().join("bad").exists());
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
    // A GraphSPN trained for 2 epochs (fewer than the default): the report says so.
    let mut graphspn = GraphSpnSetting::paper();
    graphspn.training.epochs = 2;
    let chosen = ModelSettings {
        graphspn,
        mrf2: MrfSetting::paper(BpOptions::default()),
        mrf3: MrfSetting::paper(BpOptions::default()),
        trees,
    };
    let settings = dir.path().join("validation.json");
    let file = serde_json::json!({"settings": {"Stockholm": chosen, "Freiburg": chosen}});
    std::fs::write(&settings, file.to_string()).unwrap();
    let eval = |extra: &[&str], out: &str| {
        let mut cmd = bin();
        cmd.args(["evaluate", "--maps"])
            .arg(&held)
            .arg("--train")
            .arg(data.join("Freiburg"))
            .arg("--train")
            .arg(data.join("Saarbrucken"))
            .arg("--settings")
            .arg(&settings)
            .args(["--levels", "2", "--rounds", "1", "--no-novelty", "--out"])
            .arg(dir.path().join(out))
            .args(extra);
        cmd
    };
    let msg = run_refused(&mut eval(&[], "e0"));
    assert!(
        msg.contains("--settings-of") && msg.contains("Freiburg, Stockholm"),
        "{msg}"
    );
    run_ok(&mut eval(&["--settings-of", "Stockholm"], "e1"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("e1/results.json")).unwrap())
            .unwrap();
    assert!(
        json["validation"].as_array().unwrap().is_empty(),
        "no validation run"
    );
    assert_eq!(json["buildings"][0]["settings"]["trees"]["trees"], 2);
    assert_eq!(json["given_settings"]["entry"], "Stockholm");
    let report = std::fs::read_to_string(dir.path().join("e1/REPORT.md")).unwrap();
    for want in [
        "# Evaluation of the semantic-map models on your maps: Stockholm",
        "Every setting below was given: `--settings ",
        "validation.json` (entry Stockholm)",
        "The file does not record how large its validation's search was",
        "| Stockholm | Freiburg, Saarbrucken |",
        "; training: epochs = 2 |",
        "all maps (2 in all) × 1 round per building and level",
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
