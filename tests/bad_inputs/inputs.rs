//! Malformed COLD sequences, evidence files and decompositions files.

use super::*;

/// Adds the malformed COLD, evidence and decompositions cases (files under `root`);
/// returns the demo floor's decompositions file, which [`super::limits`] enlarges.
pub fn cold_evidence_decompositions(root: &Path, cases: &mut Vec<Case>) -> Value {
    // Malformed COLD sequences (line 3 of nodes.dat is node 2).
    type ColdEdit = (
        &'static str,
        fn(&mut Vec<String>, &mut Vec<String>),
        &'static [&'static str],
    );
    let cold_edits: Vec<ColdEdit> = vec![
        (
            "columns",
            |n, _| {
                n[2] = n[2].rsplit_once(' ').unwrap().0.to_string();
            },
            &["nodes.dat:3", "expected 34 columns, found 33"],
        ),
        (
            "bad_x",
            |n, _| set_col(&mut n[2], 2, "abc"),
            &["nodes.dat:3", "column 2", "\"abc\""],
        ),
        (
            "nan_x",
            |n, _| set_col(&mut n[2], 2, "NaN"),
            &["nodes.dat:3", "column 2"],
        ),
        (
            "label",
            |n, _| set_col(&mut n[2], 8, "ZZ"),
            &["nodes.dat:3", "\"ZZ\""],
        ),
        (
            "neighbour",
            |n, _| set_col(&mut n[2], 10, "99999"),
            &["nodes.dat:3", "99999"],
        ),
        (
            "dup_line",
            |n, _| {
                let l = n[2].clone();
                n.push(l);
            },
            &["nodes.dat:89", "defined twice", "line 3"],
        ),
        (
            "placeholder_flag",
            |n, _| set_col(&mut n[2], 1, "7"),
            &["nodes.dat:3", "column 1"],
        ),
        (
            "node_id",
            |n, _| set_col(&mut n[2], 0, "-5"),
            &["nodes.dat:3", "-5"],
        ),
        (
            "room_missing",
            |_, r| {
                r.remove(2);
            },
            &["rooms.dat", "no room for node 2"],
        ),
        (
            "room_id",
            |_, r| r[0] = "0 garbage".into(),
            &["rooms.dat:1", "\"garbage\""],
        ),
        (
            "room_columns",
            |_, r| r[4] = "4".into(),
            &["rooms.dat:5", "expected 2 columns"],
        ),
        (
            "room_label",
            |_, r| r[2] = "2 1-KT-1".into(),
            &["nodes.dat:3", "node 2"],
        ),
        (
            "room_stray",
            |_, r| r.push("999 1-CR-1".into()),
            &["rooms.dat:89", "node 999 is not in nodes.dat"],
        ),
    ];
    for (stem, edit, expect) in cold_edits {
        let dir = root.join("cold").join(stem);
        cold_copy(&dir, edit);
        let map = format!("{{root}}/cold/{stem}");
        let e: Vec<&str> = expect.to_vec();
        cases.push(case(
            &format!("render cold {stem}"),
            &["render", "--map", &map, "--out", "{root}/o.svg"],
            1,
            &e,
        ));
        cases.push(case(
            &format!("infer cold {stem}"),
            &["infer", "--model", "{root}/model.json", "--map", &map],
            1,
            &e,
        ));
        cases.push(case(
            &format!("decompose cold {stem}"),
            &[
                "decompose",
                "--model",
                "{root}/model.json",
                "--map",
                &map,
                "--out",
                "{root}/o.json",
            ],
            1,
            &e,
        ));
    }
    cold_copy(&root.join("cold/good"), |_, _| {});
    std::fs::create_dir_all(root.join("cold/no_rooms")).unwrap();
    std::fs::copy(
        repo("data/cold-topomaps/Freiburg/seq1_cloudy1/nodes.dat"),
        root.join("cold/no_rooms/nodes.dat"),
    )
    .unwrap();
    cases.push(case(
        "render cold no_rooms",
        &[
            "render",
            "--map",
            "{root}/cold/no_rooms",
            "--out",
            "{root}/o.svg",
        ],
        1,
        &["no_rooms/rooms.dat"],
    ));

    // Malformed evidence (the bad row is on line 3).
    let ok_row = "[1, 1, 1, 1, 1, 1, 1, 1, 1, 1]";
    let evidence: Vec<(&str, String, Vec<&str>)> = vec![
        (
            "key_text",
            format!("{{\"format\": 1, \"evidence\": {{\n\"0\": {ok_row},\n\"abc\": {ok_row}\n}}}}"),
            vec![":3", "\"abc\" is not a place id"],
        ),
        (
            "key_missing_place",
            format!(
                "{{\"format\": 1, \"evidence\": {{\n\"0\": {ok_row},\n\"99999\": {ok_row}\n}}}}"
            ),
            vec![":3", "place id 99999 is not in map"],
        ),
        (
            "short_row",
            format!("{{\"format\": 1, \"evidence\": {{\n\"0\": {ok_row},\n\"1\": [1, 2, 3]\n}}}}"),
            vec![":3", "place id 1 has 3 likelihoods"],
        ),
        (
            "negative",
            format!(
                "{{\"format\": 1, \"evidence\": {{\n\"0\": {ok_row},\n\"1\": [1, 1, -2, 1, 1, 1, 1, 1, 1, 1]\n}}}}"
            ),
            vec![":3", "place id 1", "class 1PO is -2"],
        ),
        (
            "all_zero",
            format!(
                "{{\"format\": 1, \"evidence\": {{\n\"0\": {ok_row},\n\"1\": [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]\n}}}}"
            ),
            vec![":3", "place id 1: every likelihood is 0"],
        ),
        (
            "duplicate_key",
            format!(
                "{{\"format\": 1, \"evidence\": {{\n\"0\": {ok_row},\n\"0\": [0, 1, 0, 0, 0, 0, 0, 0, 0, 0]\n}}}}"
            ),
            vec![":3", "place id 0 is listed twice"],
        ),
        (
            "duplicate_id",
            format!("{{\"format\": 1, \"evidence\": {{\n\"7\": {ok_row},\n\"07\": {ok_row}\n}}}}"),
            vec![":3", "place id 7 is listed twice"],
        ),
        (
            "format_2",
            format!("{{\"format\": 2, \"evidence\": {{\n\"0\": {ok_row}\n}}}}"),
            vec!["evidence format 2"],
        ),
        ("not_json", "evidence!".to_string(), vec![":1:"]),
        (
            "unknown_field",
            "{\"format\": 1, \"evidence\": {},\n\"extra\": 3}".to_string(),
            vec![":2:", "extra"],
        ),
        ("list", "[1, 2, 3]".to_string(), vec![":1:"]),
        (
            "inf",
            format!(
                "{{\"format\": 1, \"evidence\": {{\n\"0\": {ok_row},\n\"1\": [1e999, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n}}}}"
            ),
            vec![":3:"],
        ),
        (
            "null",
            format!(
                "{{\"format\": 1, \"evidence\": {{\n\"0\": {ok_row},\n\"1\": [null, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n}}}}"
            ),
            vec![":3:"],
        ),
        ("empty", String::new(), vec![":1:"]),
        (
            "row_object",
            format!(
                "{{\"format\": 1, \"evidence\": {{\n\"0\": {ok_row},\n\"1\": {{\"CR\": 1}}\n}}}}"
            ),
            vec![":3:"],
        ),
    ];
    for (stem, text, expect) in &evidence {
        let file = format!("ev_{stem}.json");
        std::fs::write(root.join(&file), text).unwrap();
        let mut e: Vec<&str> = vec!["--evidence", file.as_str()];
        e.extend(expect.iter().copied());
        cases.push(case(
            &format!("infer evidence {stem}"),
            &[
                "infer",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/floor.json",
                "--evidence",
                &format!("{{root}}/{file}"),
                "--out",
                "{root}/o.json",
            ],
            1,
            &e,
        ));
    }
    cases.push(case(
        "infer evidence missing",
        &[
            "infer",
            "--model",
            "{root}/model.json",
            "--map",
            "{root}/floor.json",
            "--evidence",
            "{root}/nope.json",
        ],
        1,
        &["--evidence", "nope.json"],
    ));
    // A folder where a file is expected: one message for every file input.
    std::fs::create_dir_all(root.join("a_folder")).unwrap();
    for (flag, args) in [
        (
            "--model",
            ["--model", "{root}/a_folder", "--map", "{root}/floor.json"],
        ),
        (
            "--evidence",
            [
                "--model",
                "{root}/model.json",
                "--evidence",
                "{root}/a_folder",
            ],
        ),
        (
            "--decompositions-file",
            [
                "--model",
                "{root}/model.json",
                "--decompositions-file",
                "{root}/a_folder",
            ],
        ),
    ] {
        let mut argv = vec!["infer"];
        argv.extend(args);
        if !argv.contains(&"--map") {
            argv.extend(["--map", "{root}/floor.json"]);
        }
        cases.push(case(
            &format!("infer {flag} is a folder"),
            &argv,
            1,
            &[flag, "a_folder: is a folder, not a file"],
        ));
    }

    // Malformed decompositions files for `compile --decompositions` and `infer --decompositions-file`.
    let decs = demo_decompositions(root);
    std::fs::remove_file(root.join("decs.json")).unwrap();
    type DecMutation = (&'static str, fn(&mut Value), &'static [&'static str]);
    let dec_mutations: Vec<DecMutation> = vec![
        (
            "other_map",
            |d| d["map"] = json!("Elsewhere/seq9"),
            &["\"Elsewhere/seq9\""],
        ),
        ("format_3", |d| d["format"] = json!(3), &["format 3"]),
        (
            "unknown_template",
            |d| d["decompositions"][0]["components"][0]["template"] = json!("hexagon"),
            &["\"hexagon\""],
        ),
        (
            "missing_place",
            |d| d["decompositions"][0]["components"][0]["places"][0] = json!(4242),
            &["4242"],
        ),
        (
            "empty",
            |d| d["decompositions"] = json!([]),
            &["holds no decompositions"],
        ),
        (
            "dropped_component",
            |d| {
                d["decompositions"][0]["components"]
                    .as_array_mut()
                    .unwrap()
                    .pop();
            },
            &["decomposition 0"],
        ),
    ];
    for (stem, mutate, expect) in dec_mutations {
        let mut d = decs.clone();
        mutate(&mut d);
        let file = format!("dec_{stem}.json");
        write_json(&root.join(&file), &d);
        let mut e: Vec<&str> = vec![file.as_str()];
        e.extend(expect.iter().copied());
        let f = format!("{{root}}/{file}");
        cases.push(case(
            &format!("compile {file}"),
            &[
                "compile",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/floor.json",
                "--decompositions",
                &f,
                "--out",
                "{root}/o.rs",
            ],
            1,
            &e,
        ));
        cases.push(case(
            &format!("infer {file}"),
            &[
                "infer",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/floor.json",
                "--decompositions-file",
                &f,
                "--out",
                "{root}/o.json",
            ],
            1,
            &e,
        ));
    }
    std::fs::write(root.join("dec_syntax.json"), "{\"format\": 1,\n\"map\": }").unwrap();
    cases.push(case(
        "compile dec_syntax",
        &[
            "compile",
            "--model",
            "{root}/model.json",
            "--map",
            "{root}/floor.json",
            "--decompositions",
            "{root}/dec_syntax.json",
            "--out",
            "{root}/o.rs",
        ],
        1,
        &["dec_syntax.json", "line 2"],
    ));
    cases.push(case(
        "infer dec_syntax",
        &[
            "infer",
            "--model",
            "{root}/model.json",
            "--map",
            "{root}/floor.json",
            "--decompositions-file",
            "{root}/dec_syntax.json",
        ],
        1,
        &["dec_syntax.json", "line 2"],
    ));
    decs
}
