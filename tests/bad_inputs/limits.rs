//! Work that cannot fit (refused before it is attempted), settings out of their
//! domain, and a stray folder among `evaluate --maps`.

use super::*;

/// Adds the cases of work that cannot fit (`decs`: the demo floor's decompositions
/// file) and of settings out of their domain.
pub fn limits_and_settings(root: &Path, decs: &Value, cases: &mut Vec<Case>) {
    // Work that cannot fit, refused before it is attempted (issue 23 §2): a map over the
    // generated code's 65,535 places (JSON and COLD, counted while read), decompositions
    // and explicit SPNs whose memory estimate is over the limit on it, an evidence file
    // larger than any evidence of its map, a decompositions file with too many entries.
    let big = 65_536;
    let places: Vec<String> = (0..big)
        .map(|i| {
            format!(
                "{{\"id\": {i}, \"class\": \"CR\", \"placeholder\": false, \"x\": 0, \"y\": 0}}"
            )
        })
        .collect();
    std::fs::write(
        root.join("big.json"),
        format!(
            "{{\"format\": 1, \"name\": \"big\", \"classes\": {}, \"places\": [\n{}\n], \"edges\": []}}\n",
            json!(PAPER_CLASSES),
            places.join(",\n")
        ),
    )
    .unwrap();
    std::fs::create_dir(root.join("big_cold")).unwrap();
    let nodes: Vec<String> = (0..big)
        .map(|i| cold_line(i as u32, i as f64, "CR", &[(i as u32 + 1) % big as u32]))
        .collect();
    std::fs::write(root.join("big_cold/nodes.dat"), nodes.join("\n") + "\n").unwrap();
    std::fs::write(root.join("big_cold/rooms.dat"), "").unwrap();
    let refused_work: Vec<(&str, Vec<&str>, Vec<&str>)> = vec![
        (
            "compile json map over 65535 places",
            vec![
                "compile",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/big.json",
                "--out",
                "{root}/o.rs",
            ],
            vec!["--map", "big.json", "65536 places", "at most 65535"],
        ),
        (
            "compile cold map over 65535 places",
            vec![
                "compile",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/big_cold",
                "--out",
                "{root}/o.rs",
            ],
            vec!["--map", "big_cold", "65536 places", "at most 65535"],
        ),
        (
            "decompose count 1000 on a large map",
            vec![
                "decompose",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/big.json",
                "--count",
                "1000",
                "--out",
                "{root}/o.json",
            ],
            vec!["--map", "65536 places", "--count 1000", "GB (limit 4.3 GB)"],
        ),
        (
            "instance decompositions 1000 on a large map",
            vec![
                "instance",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/big.json",
                "--decompositions",
                "1000",
                "--out",
                "{root}/o.json",
            ],
            vec!["--decompositions 1000", "GB (limit 4.3 GB)"],
        ),
        (
            "infer decompositions 1000 on a large map",
            vec![
                "infer",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/big.json",
                "--decompositions",
                "1000",
            ],
            vec!["--decompositions 1000", "GB (limit 4.3 GB)"],
        ),
        (
            "instance tree spn on a large map",
            vec![
                "instance",
                "--model",
                "{root}/trees.json",
                "--map",
                "{root}/big.json",
                "--out",
                "{root}/o.json",
            ],
            vec!["explicit SPN of", "GB (limit 4.3 GB)"],
        ),
    ];
    for (name, args, expect) in &refused_work {
        cases.push(case(name, args, 1, expect));
    }
    // Larger than any evidence file of the 80-place demo floor can be (blank padding).
    std::fs::write(
        root.join("ev_huge.json"),
        format!(
            "{{\"format\": 1, \"evidence\": {{}}{}}}",
            " ".repeat(200_000)
        ),
    )
    .unwrap();
    cases.push(case(
        "infer evidence file too large",
        &[
            "infer",
            "--model",
            "{root}/model.json",
            "--map",
            "{root}/floor.json",
            "--evidence",
            "{root}/ev_huge.json",
        ],
        1,
        &[
            "--evidence",
            "ev_huge.json",
            "0.2 MB",
            "more than an evidence file",
            "80 places",
        ],
    ));
    let mut many = decs.clone();
    let one = many["decompositions"][0].clone();
    many["decompositions"] = Value::Array(vec![one; 1001]);
    write_json(&root.join("dec_1001.json"), &many);
    for (cmd, flag) in [
        ("infer", "--decompositions-file"),
        ("compile", "--decompositions"),
    ] {
        cases.push(case(
            &format!("{cmd} decompositions file of 1001"),
            &[
                cmd,
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/floor.json",
                flag,
                "{root}/dec_1001.json",
                "--out",
                "{root}/o.x",
            ],
            1,
            &[
                flag,
                "dec_1001.json",
                "holds 1001 decompositions",
                "at most 1000",
            ],
        ));
    }

    // Settings out of their domain (issue 23 §3): every numeric setting of a settings
    // file (`--settings`, as `graphspn validate` writes it), of `--training` and of the
    // flags is checked against its documented domain before any work, for GraphSPN, the
    // MRFs and the tree mixture alike; unknown keys are errors. The error names the file
    // or flag, the setting, the value and the domain.
    let chosen = serde_json::to_value(ModelSettings {
        graphspn: GraphSpnSetting::paper(),
        mrf2: MrfSetting::paper(BpOptions::default()),
        mrf3: MrfSetting::paper(BpOptions::default()),
        trees: TreeTraining::default(),
    })
    .unwrap();
    type Edit = fn(&mut Value);
    let bad_settings: Vec<(&str, Edit, Vec<&str>)> = vec![
        (
            "s_gspn_exponent",
            |s| s["graphspn"]["evidence_exponent"] = json!(-2.0),
            vec!["graphspn.evidence_exponent = -2", "(0, 16]"],
        ),
        (
            "s_prior_correction",
            |s| s["graphspn"]["prior_correction"] = json!(-0.5),
            vec!["graphspn.prior_correction = -0.5", "[0, 1]"],
        ),
        (
            "s_temperature",
            |s| s["graphspn"]["training"]["temperature"] = json!(1e6),
            vec!["graphspn.training.temperature = 1000000", "(0, 10]"],
        ),
        (
            "s_smoothing",
            |s| s["graphspn"]["training"]["smoothing_end"] = json!(-1.0),
            vec!["graphspn.training.smoothing_end = -1", "(0, 1000000]"],
        ),
        (
            "s_decompositions",
            |s| s["graphspn"]["decompositions"]["count"] = json!(0),
            vec!["graphspn.decompositions.count = 0", "from 1 to 1000"],
        ),
        (
            "s_mrf_exponent",
            |s| s["mrf2"]["evidence_exponent"] = json!(-1.0),
            vec!["mrf2.evidence_exponent = -1", "(0, 16]"],
        ),
        (
            "s_mrf_coupling",
            |s| s["mrf3"]["potentials"]["coupling"] = json!(-1.0),
            vec!["mrf3.potentials.coupling = -1", "[0, 10]"],
        ),
        (
            "s_bp_damping",
            |s| s["mrf2"]["bp"]["damping"] = json!(1.0),
            vec!["mrf2.bp.damping = 1", "[0, 1)"],
        ),
        (
            "s_tree_prior",
            |s| s["trees"]["prior_exponent"] = json!(-5.0),
            vec!["trees.prior_exponent = -5", "[-2, 2]"],
        ),
        (
            "s_tree_count",
            |s| s["trees"]["trees"] = json!(0),
            vec!["trees.trees = 0", "from 1 to 64"],
        ),
        (
            "s_tree_form",
            |s| s["trees"]["potentials"]["normalisation"] = json!("conditional"),
            vec!["trees.potentials.normalisation = conditional", "symmetric"],
        ),
        (
            "s_unknown_key",
            |s| s["graphspn"]["evidence_exponnet"] = json!(2.0),
            vec!["unknown field `evidence_exponnet`"],
        ),
        (
            "s_unknown_tree_key",
            |s| s["trees"]["tres"] = json!(4),
            vec!["unknown field `tres`"],
        ),
    ];
    for (stem, edit, expect) in &bad_settings {
        let mut s = chosen.clone();
        edit(&mut s);
        let file = format!("{stem}.json");
        write_json(&root.join(&file), &json!({"settings": {"Stockholm": s}}));
        let mut expect = expect.clone();
        expect.extend(["--settings", file.as_str()]);
        cases.push(case(
            &format!("reproduce settings file {stem}"),
            &[
                "reproduce",
                "--out",
                "{root}/r",
                "--settings",
                &format!("{{root}}/{file}"),
            ],
            1,
            &expect,
        ));
    }
    cases.push(case(
        "evaluate settings file out of domain",
        &[
            "evaluate",
            "--maps",
            "{root}/floor.json",
            "--settings",
            "{root}/s_prior_correction.json",
            "--out",
            "{root}/r",
        ],
        1,
        &[
            "--settings",
            "s_prior_correction.json",
            "graphspn.prior_correction = -0.5",
        ],
    ));
    // A settings file inside the output folder is an input: --force may not replace
    // the folder that holds it (it used to be deleted with the old output).
    std::fs::create_dir(root.join("val")).unwrap();
    std::fs::write(root.join("val/.graphspn-output"), "graphspn\n").unwrap();
    write_json(
        &root.join("val/validation.json"),
        &json!({"settings": {"Stockholm": chosen}}),
    );
    for cmd in ["reproduce", "evaluate"] {
        let mut args = vec![cmd];
        if cmd == "evaluate" {
            args.extend(["--maps", "{root}/floor.json"]);
        }
        args.extend([
            "--settings",
            "{root}/val/validation.json",
            "--out",
            "{root}/val",
            "--force",
        ]);
        cases.push(case(
            &format!("{cmd} settings inside the output folder"),
            &args,
            1,
            &["--out", "overlaps the input --settings"],
        ));
    }
    // Settings validated on other training buildings than the run's: refused, naming
    // both sets (the folds say which buildings a validation used).
    write_json(
        &root.join("s_other_training.json"),
        &json!({
            "settings": {"Stockholm": chosen},
            "validation": [{
                "test_building": "Stockholm",
                "folds": ["Saarbrucken → Freiburg", "Freiburg → Saarbrucken"],
            }],
        }),
    );
    cases.push(case(
        "evaluate settings validated on other buildings",
        &[
            "evaluate",
            "--maps",
            "{root}/floor.json",
            "--settings",
            "{root}/s_other_training.json",
            "--out",
            "{root}/r",
        ],
        1,
        &[
            "s_other_training.json",
            "validated on Freiburg, Saarbrucken",
            "trains on Freiburg, Saarbrucken, Stockholm",
        ],
    ));
    write_json(
        &root.join("s_odd_training.json"),
        &json!({
            "settings": {"Stockholm": chosen},
            "validation": [{
                "test_building": "Stockholm",
                "folds": ["Elsewhere → Freiburg", "Freiburg → Elsewhere"],
            }],
        }),
    );
    cases.push(case(
        "reproduce settings validated on other buildings",
        &[
            "reproduce",
            "--buildings",
            "Stockholm",
            "--settings",
            "{root}/s_odd_training.json",
            "--out",
            "{root}/r",
        ],
        1,
        &[
            "s_odd_training.json",
            "validated on Elsewhere, Freiburg",
            "trains on Freiburg, Saarbrucken",
        ],
    ));
    cases.push(case(
        "reproduce settings without the test building",
        &[
            "reproduce",
            "--buildings",
            "Freiburg",
            "--settings",
            "{root}/s_odd_training.json",
            "--out",
            "{root}/r",
        ],
        1,
        &[
            "--settings",
            "s_odd_training.json",
            "no settings for test building Freiburg",
        ],
    ));
    // A test map with no places: refused before the validation runs.
    cases.push(case(
        "evaluate empty test map",
        &[
            "evaluate",
            "--maps",
            "{root}/map_empty.json",
            "--out",
            "{root}/r",
        ],
        1,
        &["--maps", "map_empty.json", "has no places"],
    ));
    write_json(
        &root.join("s_unknown_top.json"),
        &json!({"settings": {"Stockholm": chosen}, "setings": {}}),
    );
    cases.push(case(
        "reproduce settings file unknown top-level key",
        &[
            "reproduce",
            "--out",
            "{root}/r",
            "--settings",
            "{root}/s_unknown_top.json",
        ],
        1,
        &["s_unknown_top.json", "unknown field `setings`"],
    ));
    for (name, training, expect) in [
        (
            "epochs 0",
            r#"{"epochs": 0}"#,
            vec!["--training", "epochs = 0", "from 1 to 10000"],
        ),
        (
            "misspelled key",
            r#"{"epoch": 5}"#,
            vec!["--training", "unknown field `epoch`"],
        ),
        (
            "negative smoothing",
            r#"{"smoothing_start": -3}"#,
            vec!["--training", "smoothing_start = -3"],
        ),
        (
            "nested structure",
            r#"{"structure": {"sums": 0}}"#,
            vec!["--training", "structure.sums = 0", "from 1 to 64"],
        ),
        (
            "split choice",
            r#"{"structure": {"split_choice": "fewest_images"}}"#,
            vec!["--training", "structure.split_choice cannot be set here"],
        ),
        (
            "prune threshold",
            r#"{"prune_threshold": 1.5}"#,
            vec!["--training", "prune_threshold = 1.5", "[0, 1)"],
        ),
        (
            "temperature",
            r#"{"temperature": 0.5}"#,
            vec!["--training", "temperature cannot be set here"],
        ),
    ] {
        cases.push(case(
            &format!("reproduce training {name}"),
            &["reproduce", "--out", "{root}/r", "--training", training],
            1,
            &expect,
        ));
    }
    let out = "{root}/t3.json";
    for (name, args, expect) in [
        (
            "train temperature too large to apply",
            vec!["train", "--temperature", "1e6", "--out", out],
            vec!["--temperature 1000000", "must be finite and in (0, 10]"],
        ),
        (
            "train trees prior exponent",
            vec![
                "train",
                "--family",
                "tree-mixture",
                "--prior-exponent",
                "-5",
                "--out",
                out,
            ],
            vec!["--prior-exponent -5", "[-2, 2]"],
        ),
        (
            "train trees 65",
            vec![
                "train",
                "--family",
                "tree-mixture",
                "--trees",
                "65",
                "--out",
                out,
            ],
            vec!["--trees 65", "must be from 1 to 64"],
        ),
        (
            "infer trees 0",
            vec![
                "infer",
                "--model",
                "{root}/trees.json",
                "--map",
                "{root}/floor.json",
                "--trees",
                "0",
            ],
            vec!["--trees 0", "must be from 1 to 64"],
        ),
        (
            "compile tree mixture count 65",
            vec![
                "compile",
                "--model",
                "{root}/trees.json",
                "--map",
                "{root}/floor.json",
                "--count",
                "65",
                "--out",
                "{root}/o.rs",
            ],
            vec!["--count 65", "must be from 1 to 64"],
        ),
        (
            "reproduce rounds 1001",
            vec!["reproduce", "--out", "{root}/r", "--rounds", "1001"],
            vec!["--rounds 1001", "must be from 1 to 1000"],
        ),
        (
            "compile module keyword",
            vec![
                "compile",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/floor.json",
                "--module",
                "fn",
                "--out",
                "{root}/o.rs",
            ],
            vec!["--module", "\"fn\"", "keyword"],
        ),
        (
            "compile module gen",
            vec![
                "compile",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/floor.json",
                "--module",
                "gen",
                "--out",
                "{root}/o.rs",
            ],
            vec!["--module", "\"gen\"", "keyword"],
        ),
    ] {
        cases.push(case(name, &args, 1, &expect));
    }
    // A folder among `evaluate --maps` that is not a COLD sequence (no nodes.dat): an
    // error naming it (it was skipped without a word).
    std::fs::create_dir_all(root.join("maps_with_stray/notes")).unwrap();
    std::fs::copy(
        repo("generated/demo/floor.json"),
        root.join("maps_with_stray/floor.json"),
    )
    .unwrap();
    cases.push(case(
        "evaluate maps folder holding a folder without nodes.dat",
        &[
            "evaluate",
            "--maps",
            "{root}/maps_with_stray",
            "--out",
            "{root}/r",
        ],
        1,
        &["--maps", "maps_with_stray/notes", "not a map", "nodes.dat"],
    ));
}
