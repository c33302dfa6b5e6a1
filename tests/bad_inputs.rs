//! The bad-input corpus: malformed files and argument sets through every sub-command.
//!
//! Every case runs the real binary in a folder of fixtures (generated here from the
//! demo model, the demo floor and one shipped COLD map) and asserts: the expected exit
//! status (1 for a refused input, 2 for a command-line usage error), that standard
//! error names what is wrong (the file or flag, and the line, node or place), that
//! nothing panicked, and that no file in the folder was created, changed or removed.
//!
//! Further tests check extreme but valid inputs (coordinates near ±1e308, a one-place
//! map, evidence rows of 1e-300, relative template weights) and the policies the
//! corpus relies on (the shipped data found with no set-up, one-line errors).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use graphspn_compiler::experiments::settings::{GraphSpnSetting, ModelSettings, MrfSetting};
use graphspn_compiler::map::PAPER_CLASSES;
use graphspn_compiler::mrf::BpOptions;
use graphspn_compiler::treemix::TreeTraining;
use serde_json::{Value, json};

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// The binary, with no data variable (the shipped maps are found by default).
fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_graphspn"));
    c.env_remove("GRAPHSPN_DATA").env("RUST_BACKTRACE", "0");
    c
}

/// Every file under `dir` with its content and modification time.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, (Vec<u8>, std::time::SystemTime)> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                out.insert(p.clone(), (Vec::new(), std::time::UNIX_EPOCH));
                stack.push(p);
            } else {
                let m = std::fs::metadata(&p).unwrap().modified().unwrap();
                out.insert(p.clone(), (std::fs::read(&p).unwrap(), m));
            }
        }
    }
    out
}

/// One malformed input: arguments (`{root}` stands for the fixture folder), the exit
/// status expected and fragments the error message must hold.
struct Case {
    name: String,
    args: Vec<String>,
    code: i32,
    expect: Vec<String>,
}

fn case(name: &str, args: &[&str], code: i32, expect: &[&str]) -> Case {
    Case {
        name: name.to_string(),
        args: args.iter().map(|s| s.to_string()).collect(),
        code,
        expect: expect.iter().map(|s| s.to_string()).collect(),
    }
}

fn write_json(path: &Path, v: &Value) {
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap() + "\n").unwrap();
}

fn demo_model() -> Value {
    serde_json::from_str(&std::fs::read_to_string(repo("generated/demo/model.json")).unwrap())
        .unwrap()
}

fn leaf(var: u32, class: u32) -> Value {
    json!({"kind": "leaf", "var": var, "class": class})
}

/// A small valid SPN for the two-node `pair` template: two 10-class sums under a product.
/// Nodes 0-9: var 0 leaves; 10-19: var 1 leaves; 20, 21: sums; 22: product (root).
fn tiny_pair() -> Value {
    let mut nodes: Vec<Value> = Vec::new();
    for v in 0..2 {
        for k in 0..10 {
            nodes.push(leaf(v, k));
        }
    }
    for v in 0..2u32 {
        let children: Vec<u32> = (v * 10..v * 10 + 10).collect();
        nodes.push(json!({"kind": "sum", "children": children, "weights": vec![0.1; 10]}));
    }
    nodes.push(json!({"kind": "product", "children": [20, 21]}));
    json!({"classes": [10, 10], "nodes": nodes, "root": 22})
}

/// Model mutations: (file stem, what to do to the demo model, message fragments).
type Mutation = (&'static str, fn(&mut Value), &'static [&'static str]);

fn model_mutations() -> Vec<Mutation> {
    // spns[3] is the singleton SPN: leaves 0-9 (var 0, class k), sum 10 (root).
    // spns[2] is the pair SPN (replaced by `tiny_pair` for the pair cases).
    vec![
        (
            "root_out_of_range",
            |m| m["spns"][3]["root"] = json!(11),
            &["singleton", "root node 11"],
        ),
        (
            "child_out_of_range",
            |m| m["spns"][3]["nodes"][10]["children"][9] = json!(99),
            &["singleton", "node 10", "child 99"],
        ),
        (
            "leaf_var_out_of_range",
            |m| m["spns"][3]["nodes"][0]["var"] = json!(3),
            &["singleton", "leaf node 0", "variable 3"],
        ),
        (
            "leaf_class_out_of_range",
            |m| m["spns"][3]["nodes"][3]["class"] = json!(12),
            &["singleton", "leaf node 3", "class 12"],
        ),
        (
            "forward_child",
            |m| {
                m["spns"][3]["nodes"]
                    .as_array_mut()
                    .unwrap()
                    .push(leaf(0, 0));
                m["spns"][3]["nodes"][10]["children"][0] = json!(11);
            },
            &["singleton", "node 10", "child 11"],
        ),
        (
            "cycle",
            |m| m["spns"][3]["nodes"][10]["children"][0] = json!(10),
            &["singleton", "cycle", "[10]"],
        ),
        (
            "weight_count",
            |m| {
                m["spns"][3]["nodes"][10]["weights"]
                    .as_array_mut()
                    .unwrap()
                    .pop();
            },
            &["singleton", "sum node 10", "9 weights"],
        ),
        (
            "negative_weight",
            |m| m["spns"][3]["nodes"][10]["weights"][2] = json!(-0.1),
            &["singleton", "sum node 10", "weight 2 is negative"],
        ),
        (
            "zero_weights",
            |m| m["spns"][3]["nodes"][10]["weights"] = json!(vec![0.0; 10]),
            &["singleton", "sum node 10", "all weights are zero"],
        ),
        (
            "empty_sum",
            |m| m["spns"][3]["nodes"][10] = json!({"kind": "sum", "children": [], "weights": []}),
            &["singleton", "sum node 10", "no children"],
        ),
        (
            "empty_product",
            |m| m["spns"][3]["nodes"][10] = json!({"kind": "product", "children": []}),
            &["singleton", "product node 10"],
        ),
        (
            "spn_classes",
            |m| m["spns"][3]["classes"] = json!([9]),
            &["singleton", "variable 0 has 9 classes"],
        ),
        (
            "spn_vars",
            |m| m["spns"][3]["classes"] = json!([10, 10]),
            &["singleton", "2 variables", "1 nodes"],
        ),
        (
            "unreachable",
            |m| {
                m["spns"][3]["nodes"]
                    .as_array_mut()
                    .unwrap()
                    .push(leaf(0, 1));
            },
            &["singleton", "node 11 is unreachable"],
        ),
        (
            "unknown_kind",
            |m| m["spns"][3]["nodes"][0]["kind"] = json!("leafy"),
            &["unknown variant", "leafy"],
        ),
        (
            "not_decomposable",
            |m| {
                let mut p = tiny_pair();
                p["nodes"][22]["children"] = json!([20, 21, 0]);
                m["spns"][2] = p;
            },
            &["pair", "product node 22 is not decomposable", "variable 0"],
        ),
        (
            "incomplete",
            |m| {
                let mut p = tiny_pair();
                p["nodes"]
                    .as_array_mut()
                    .unwrap()
                    .push(json!({"kind": "sum", "children": [22, 20], "weights": [0.5, 0.5]}));
                p["root"] = json!(23);
                m["spns"][2] = p;
            },
            &["pair", "sum node 23 is not complete"],
        ),
        (
            "variable_not_in_scope",
            |m| {
                let mut nodes: Vec<Value> = (0..10).map(|k| leaf(0, k)).collect();
                nodes.push(json!({"kind": "sum", "children": (0..10).collect::<Vec<u32>>(), "weights": vec![0.1; 10]}));
                m["spns"][2] = json!({"classes": [10, 10], "nodes": nodes, "root": 10});
            },
            &["pair", "variable 1 does not occur"],
        ),
        (
            "pair_leaf_class",
            |m| {
                let mut p = tiny_pair();
                p["nodes"][15]["class"] = json!(10);
                m["spns"][2] = p;
            },
            &["pair", "leaf node 15", "class 10"],
        ),
        (
            "pair_child_range",
            |m| {
                let mut p = tiny_pair();
                p["nodes"][22]["children"][1] = json!(4_000_000_000u32);
                m["spns"][2] = p;
            },
            &["pair", "node 22", "child 4000000000"],
        ),
        (
            "format_missing",
            |m| {
                m.as_object_mut().unwrap().remove("format");
            },
            &["unsupported model format missing"],
        ),
        (
            "format_2",
            |m| m["format"] = json!(2),
            &["unsupported model format 2"],
        ),
        (
            "spn_count",
            |m| {
                m["spns"].as_array_mut().unwrap().pop();
            },
            &["4 templates but 3 SPNs"],
        ),
        (
            "duplicate_template",
            |m| m["templates"][3]["name"] = json!("pair"),
            &["template 3", "\"pair\""],
        ),
        (
            "template_edge",
            |m| m["templates"][2]["edges"] = json!([[0, 5]]),
            &["template 2"],
        ),
        (
            "no_classes",
            |m| m["classes"] = json!([]),
            &[":2:15", "ClassSet"],
        ),
        ("spns_not_list", |m| m["spns"] = json!(3), &["invalid type"]),
    ]
}

/// The decompositions file of the demo floor written by `graphspn decompose`.
fn demo_decompositions(root: &Path) -> Value {
    let out = root.join("decs.json");
    assert!(
        bin()
            .args(["decompose", "--count", "2", "--model"])
            .arg(root.join("model.json"))
            .arg("--map")
            .arg(root.join("floor.json"))
            .arg("--out")
            .arg(&out)
            .status()
            .unwrap()
            .success()
    );
    serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap()
}

/// A COLD sequence copied from the shipped Freiburg/seq1_cloudy1, with `edit` applied
/// to the lines of its nodes.dat and rooms.dat.
fn cold_copy(dir: &Path, edit: impl Fn(&mut Vec<String>, &mut Vec<String>)) {
    let src = repo("data/cold-topomaps/Freiburg/seq1_cloudy1");
    let lines = |f: &str| -> Vec<String> {
        std::fs::read_to_string(src.join(f))
            .unwrap()
            .lines()
            .map(String::from)
            .collect()
    };
    let (mut nodes, mut rooms) = (lines("nodes.dat"), lines("rooms.dat"));
    edit(&mut nodes, &mut rooms);
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("nodes.dat"), nodes.join("\n") + "\n").unwrap();
    std::fs::write(dir.join("rooms.dat"), rooms.join("\n") + "\n").unwrap();
}

fn set_col(line: &mut String, col: usize, value: &str) {
    let mut cols: Vec<&str> = line.split_whitespace().collect();
    cols[col] = value;
    *line = cols.join(" ");
}

/// Builds the fixture folder and the corpus.
fn corpus(root: &Path) -> Vec<Case> {
    std::fs::copy(repo("generated/demo/model.json"), root.join("model.json")).unwrap();
    std::fs::copy(
        repo("generated/demo/tree_model.json"),
        root.join("trees.json"),
    )
    .unwrap();
    let mut bad_trees: Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("trees.json")).unwrap()).unwrap();
    bad_trees["potential"][1] = json!(123.0);
    write_json(&root.join("trees_asymmetric.json"), &bad_trees);
    std::fs::copy(repo("generated/demo/floor.json"), root.join("floor.json")).unwrap();
    std::fs::write(root.join("hand.rs"), "// mine\n").unwrap();
    std::fs::write(root.join("existing.json"), "{}\n").unwrap();
    std::fs::create_dir(root.join("full")).unwrap();
    std::fs::write(root.join("full/REPORT.md"), "mine\n").unwrap();
    let mut cases = Vec::new();

    // Malformed models through every command that reads one.
    let mut models: Vec<(String, Vec<&str>)> = Vec::new();
    for (stem, mutate, expect) in model_mutations() {
        let mut m = demo_model();
        mutate(&mut m);
        let file = format!("m_{stem}.json");
        write_json(&root.join(&file), &m);
        models.push((file, expect.to_vec()));
    }
    std::fs::write(root.join("m_truncated.json"), {
        let t = std::fs::read_to_string(repo("generated/demo/model.json")).unwrap();
        t[..t.len() / 2].to_string()
    })
    .unwrap();
    models.push(("m_truncated.json".into(), vec!["EOF"]));
    std::fs::write(root.join("m_empty.json"), "").unwrap();
    models.push(("m_empty.json".into(), vec!["m_empty.json:1:"]));
    std::fs::write(root.join("m_list.json"), "[1, 2]\n").unwrap();
    models.push(("m_list.json".into(), vec!["m_list.json:1:"]));
    std::fs::write(root.join("m_inf.json"), {
        let t = std::fs::read_to_string(root.join("model.json")).unwrap();
        t.replacen("0.1", "1e999", 1)
    })
    .unwrap();
    models.push(("m_inf.json".into(), vec!["m_inf.json:", "out of range"]));
    models.push(("m_missing.json".into(), vec!["--model", "no such file"]));
    for (file, expect) in &models {
        let model = format!("{{root}}/{file}");
        let mut e: Vec<&str> = vec![file.as_str()];
        e.extend(expect.iter().copied());
        let stem = file.trim_end_matches(".json");
        cases.push(case(
            &format!("infer {stem}"),
            &[
                "infer",
                "--model",
                &model,
                "--map",
                "{root}/floor.json",
                "--out",
                "{root}/o.json",
            ],
            1,
            &e,
        ));
        cases.push(case(
            &format!("instance {stem}"),
            &[
                "instance",
                "--model",
                &model,
                "--map",
                "{root}/floor.json",
                "--out",
                "{root}/o.json",
            ],
            1,
            &e,
        ));
        cases.push(case(
            &format!("compile {stem}"),
            &[
                "compile",
                "--model",
                &model,
                "--map",
                "{root}/floor.json",
                "--out",
                "{root}/o.rs",
            ],
            1,
            &e,
        ));
        cases.push(case(
            &format!("decompose {stem}"),
            &[
                "decompose",
                "--model",
                &model,
                "--map",
                "{root}/floor.json",
                "--out",
                "{root}/o.json",
            ],
            1,
            &e,
        ));
    }

    // Malformed JSON maps through every command that reads a map.
    let floor: Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("floor.json")).unwrap()).unwrap();
    type MapMutation = (&'static str, fn(&mut Value), &'static [&'static str]);
    let map_mutations: Vec<MapMutation> = vec![
        (
            "dup_place",
            |m| m["places"][1]["id"] = json!(0),
            &["place id 0 appears twice"],
        ),
        (
            "edge_missing_place",
            |m| m["edges"].as_array_mut().unwrap().push(json!([0, 9999])),
            &["9999"],
        ),
        (
            "self_loop",
            |m| m["edges"].as_array_mut().unwrap().push(json!([3, 3])),
            &["place 3 to itself"],
        ),
        (
            "unknown_class",
            |m| m["places"][0]["class"] = json!("XX"),
            &["place 0", "\"XX\""],
        ),
        ("format_9", |m| m["format"] = json!(9), &["format 9"]),
        (
            "dup_class",
            |m| m["classes"][1] = json!("DW"),
            &["\"DW\" appears twice"],
        ),
        (
            "no_classes",
            |m| m["classes"] = json!([]),
            &["at least one class"],
        ),
        (
            "negative_id",
            |m| m["places"][2]["id"] = json!(-1),
            &["line "],
        ),
        (
            "id_too_big",
            |m| m["places"][2]["id"] = json!(5_000_000_000u64),
            &["line "],
        ),
        (
            "pose_string",
            |m| m["places"][2]["x"] = json!("east"),
            &["line "],
        ),
        (
            "edge_triple",
            |m| m["edges"][0] = json!([0, 1, 2]),
            &["line "],
        ),
        (
            "places_missing",
            |m| {
                m.as_object_mut().unwrap().remove("places");
            },
            &["places"],
        ),
    ];
    let mut maps: Vec<(String, Vec<&str>)> = Vec::new();
    for (stem, mutate, expect) in map_mutations {
        let mut m = floor.clone();
        mutate(&mut m);
        let file = format!("map_{stem}.json");
        write_json(&root.join(&file), &m);
        maps.push((file, expect.to_vec()));
    }
    std::fs::write(root.join("map_truncated.json"), {
        let t = std::fs::read_to_string(root.join("floor.json")).unwrap();
        t[..t.len() / 3].to_string()
    })
    .unwrap();
    maps.push(("map_truncated.json".into(), vec!["line "]));
    std::fs::write(root.join("map_text.json"), "hello\n").unwrap();
    maps.push(("map_text.json".into(), vec!["line 1"]));
    std::fs::write(root.join("map_inf.json"), {
        let t = std::fs::read_to_string(root.join("floor.json")).unwrap();
        t.replacen("-1.676", "1e999", 1)
    })
    .unwrap();
    maps.push(("map_inf.json".into(), vec!["line 17"]));
    for (file, expect) in &maps {
        let map = format!("{{root}}/{file}");
        let mut e: Vec<&str> = vec![file.as_str()];
        e.extend(expect.iter().copied());
        let stem = file.trim_end_matches(".json");
        cases.push(case(
            &format!("infer {stem}"),
            &[
                "infer",
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
        cases.push(case(
            &format!("instance {stem}"),
            &["instance", "--model", "{root}/model.json", "--map", &map],
            1,
            &e,
        ));
        cases.push(case(
            &format!("compile {stem}"),
            &[
                "compile",
                "--model",
                "{root}/model.json",
                "--map",
                &map,
                "--out",
                "{root}/o.rs",
            ],
            1,
            &e,
        ));
        cases.push(case(
            &format!("decompose {stem}"),
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
        cases.push(case(
            &format!("render {stem}"),
            &["render", "--map", &map, "--out", "{root}/o.svg"],
            1,
            &e,
        ));
    }
    // A map whose classes are not the model's: refused by the model commands.
    let mut three = floor.clone();
    three["classes"] = json!(["CR", "DW", "XX"]);
    for p in three["places"].as_array_mut().unwrap() {
        p["class"] = json!("CR");
    }
    write_json(&root.join("map_three_classes.json"), &three);
    for cmd in ["infer", "instance", "compile"] {
        cases.push(case(
            &format!("{cmd} map_three_classes"),
            &[
                cmd,
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/map_three_classes.json",
                "--out",
                "{root}/o.rs",
            ],
            1,
            &["classes"],
        ));
    }

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

    // Argument sets: flags out of range, outputs that may not be written.
    let m = "{root}/model.json";
    let f = "{root}/floor.json";
    let t = "{root}/trees.json";
    let args: Vec<Case> = vec![
        // tree mixtures
        case(
            "infer trees with decompositions",
            &["infer", "--model", t, "--map", f, "--decompositions", "3"],
            1,
            &["--decompositions", "tree mixture"],
        ),
        case(
            "infer trees 0",
            &["infer", "--model", t, "--map", f, "--trees", "0"],
            1,
            &["--trees 0"],
        ),
        case(
            "infer trees 65",
            &["infer", "--model", t, "--map", f, "--trees", "65"],
            1,
            &["--trees 65"],
        ),
        case(
            "infer graphspn with trees",
            &["infer", "--model", m, "--map", f, "--trees", "2"],
            1,
            &["--trees", "GraphSPN"],
        ),
        case(
            "infer asymmetric potential",
            &[
                "infer",
                "--model",
                "{root}/trees_asymmetric.json",
                "--map",
                f,
            ],
            1,
            &["trees_asymmetric.json", "not symmetric", "(0, 1)"],
        ),
        case(
            "decompose tree mixture",
            &[
                "decompose",
                "--model",
                t,
                "--map",
                f,
                "--out",
                "{root}/d.json",
            ],
            1,
            &["trees.json", "tree_mixture", "not a GraphSPN"],
        ),
        case(
            "train trees with epochs",
            &[
                "train",
                "--family",
                "tree-mixture",
                "--epochs",
                "3",
                "--out",
                "{root}/t2.json",
            ],
            1,
            &["--epochs", "graphspn"],
        ),
        case(
            "train graphspn with coupling",
            &["train", "--coupling", "0.5", "--out", "{root}/t2.json"],
            1,
            &["--coupling", "tree-mixture"],
        ),
        case(
            "train unknown family",
            &["train", "--family", "forest", "--out", "{root}/t2.json"],
            2,
            &["--family", "forest"],
        ),
        case(
            "train trees evidence exponent 0",
            &[
                "train",
                "--family",
                "tree-mixture",
                "--evidence-exponent",
                "0",
                "--out",
                "{root}/t2.json",
            ],
            1,
            &["--evidence-exponent 0", "must be from 1 to 8"],
        ),
        case(
            "train trees negative coupling",
            &[
                "train",
                "--family",
                "tree-mixture",
                "--coupling",
                "-1",
                "--out",
                "{root}/t2.json",
            ],
            1,
            &["coupling", "-1"],
        ),
        case(
            "render graphspn model",
            &["render", "--map", f, "--model", m, "--out", "{root}/r.svg"],
            1,
            &["--model", "GraphSPN"],
        ),
        case(
            "render tree out of range",
            &[
                "render",
                "--map",
                f,
                "--model",
                t,
                "--tree",
                "9",
                "--out",
                "{root}/r.svg",
            ],
            1,
            &["--tree 9"],
        ),
        // infer
        case(
            "infer decompositions 0",
            &["infer", "--model", m, "--map", f, "--decompositions", "0"],
            1,
            &["--decompositions 0"],
        ),
        case(
            "infer decompositions huge",
            &[
                "infer",
                "--model",
                m,
                "--map",
                f,
                "--decompositions",
                "10000",
            ],
            1,
            &["--decompositions 10000", "must be from 1 to 1000"],
        ),
        case(
            "infer decompositions negative",
            &["infer", "--model", m, "--map", f, "--decompositions", "-3"],
            2,
            &["--decompositions", "-3"],
        ),
        case(
            "infer seed negative",
            &["infer", "--model", m, "--map", f, "--seed", "-1"],
            2,
            &["--seed", "-1"],
        ),
        case(
            "infer out exists",
            &[
                "infer",
                "--model",
                m,
                "--map",
                f,
                "--out",
                "{root}/existing.json",
            ],
            1,
            &["--out", "existing.json", "--force"],
        ),
        case(
            "infer out is map",
            &["infer", "--model", m, "--map", f, "--out", f, "--force"],
            1,
            &["--out", "floor.json", "input --map"],
        ),
        case(
            "infer out is model",
            &["infer", "--model", m, "--map", f, "--out", m, "--force"],
            1,
            &["--out", "model.json", "input --model"],
        ),
        case(
            "infer svg is map",
            &[
                "infer",
                "--model",
                m,
                "--map",
                f,
                "--out",
                "{root}/o.json",
                "--svg",
                f,
                "--force",
            ],
            1,
            &["--svg", "floor.json", "input --map"],
        ),
        case(
            "infer svg equals out",
            &[
                "infer",
                "--model",
                m,
                "--map",
                f,
                "--out",
                "{root}/o.json",
                "--svg",
                "{root}/o.json",
            ],
            1,
            &["--svg", "o.json", "--out"],
        ),
        case(
            "infer svg exists",
            &[
                "infer",
                "--model",
                m,
                "--map",
                f,
                "--out",
                "{root}/o.json",
                "--svg",
                "{root}/existing.json",
            ],
            1,
            &["--svg", "existing.json", "--force"],
        ),
        case(
            "infer svg folder missing",
            &[
                "infer",
                "--model",
                m,
                "--map",
                f,
                "--out",
                "{root}/o.json",
                "--svg",
                "{root}/nowhere/o.svg",
            ],
            1,
            &["--svg", "nowhere", "does not exist"],
        ),
        case(
            "infer out is folder",
            &["infer", "--model", m, "--map", f, "--out", "{root}/full"],
            1,
            &["--out", "full", "folder"],
        ),
        case(
            "infer evidence is out",
            &[
                "infer",
                "--model",
                m,
                "--map",
                f,
                "--evidence",
                "{root}/existing.json",
                "--out",
                "{root}/existing.json",
                "--force",
            ],
            1,
            &["--out", "input --evidence"],
        ),
        case(
            "infer map missing",
            &["infer", "--model", m, "--map", "{root}/nope.json"],
            1,
            &["--map", "nope.json"],
        ),
        case(
            "infer map name missing",
            &["infer", "--model", m, "--map", "Freiburg/seq99"],
            1,
            &["--map", "Freiburg/seq99"],
        ),
        case(
            "infer cold out in map folder",
            &[
                "infer",
                "--model",
                m,
                "--map",
                "{root}/cold/good",
                "--out",
                "{root}/cold/good/nodes.dat",
                "--force",
            ],
            1,
            &["--out", "nodes.dat", "input --map"],
        ),
        case(
            "infer unknown flag",
            &["infer", "--model", m, "--map", f, "--bogus"],
            2,
            &["--bogus"],
        ),
        case(
            "infer missing model flag",
            &["infer", "--map", f],
            2,
            &["--model"],
        ),
        case(
            "infer both decompositions",
            &[
                "infer",
                "--model",
                m,
                "--map",
                f,
                "--decompositions",
                "3",
                "--decompositions-file",
                "{root}/existing.json",
            ],
            2,
            &["--decompositions"],
        ),
        // instance
        case(
            "instance format",
            &["instance", "--model", m, "--map", f, "--format", "xml"],
            2,
            &["--format", "xml"],
        ),
        case(
            "instance out exists",
            &[
                "instance",
                "--model",
                m,
                "--map",
                f,
                "--out",
                "{root}/existing.json",
            ],
            1,
            &["--out", "existing.json", "--force"],
        ),
        case(
            "instance out is model",
            &["instance", "--model", m, "--map", f, "--out", m, "--force"],
            1,
            &["--out", "input --model"],
        ),
        case(
            "instance decompositions 0",
            &[
                "instance",
                "--model",
                m,
                "--map",
                f,
                "--decompositions",
                "0",
            ],
            1,
            &["--decompositions 0"],
        ),
        case(
            "instance out folder missing",
            &[
                "instance",
                "--model",
                m,
                "--map",
                f,
                "--out",
                "{root}/nowhere/i.json",
            ],
            1,
            &["--out", "does not exist"],
        ),
        // render
        case(
            "render nothing",
            &["render", "--out", "{root}/o.svg"],
            2,
            &["--map"],
        ),
        case(
            "render both",
            &[
                "render",
                "--map",
                f,
                "--synthetic",
                "50",
                "--out",
                "{root}/o.svg",
            ],
            2,
            &["--synthetic"],
        ),
        case(
            "render synthetic small",
            &["render", "--synthetic", "5", "--out", "{root}/o.svg"],
            1,
            &["--synthetic 5"],
        ),
        case(
            "render synthetic huge",
            &["render", "--synthetic", "200000", "--out", "{root}/o.svg"],
            1,
            &["--synthetic 200000"],
        ),
        case(
            "render out exists",
            &["render", "--map", f, "--out", "{root}/existing.json"],
            1,
            &["--out", "existing.json", "--force"],
        ),
        case(
            "render out is map",
            &["render", "--map", f, "--out", f, "--force"],
            1,
            &["--out", "input --map"],
        ),
        case(
            "render map missing",
            &[
                "render",
                "--map",
                "{root}/nope.json",
                "--out",
                "{root}/o.svg",
            ],
            1,
            &["--map", "nope.json"],
        ),
        case(
            "render seed negative",
            &[
                "render",
                "--synthetic",
                "50",
                "--seed",
                "-2",
                "--out",
                "{root}/o.svg",
            ],
            2,
            &["--seed", "-2"],
        ),
        // generate
        case(
            "generate places small",
            &["generate", "--places", "5", "--out", "{root}/g.json"],
            1,
            &["--places 5"],
        ),
        case(
            "generate places huge",
            &["generate", "--places", "1000000", "--out", "{root}/g.json"],
            1,
            &["--places 1000000"],
        ),
        case(
            "generate places negative",
            &["generate", "--places", "-1", "--out", "{root}/g.json"],
            2,
            &["--places", "-1"],
        ),
        case(
            "generate places text",
            &["generate", "--places", "many", "--out", "{root}/g.json"],
            2,
            &["--places", "many"],
        ),
        case(
            "generate out exists",
            &[
                "generate",
                "--places",
                "20",
                "--out",
                "{root}/existing.json",
            ],
            1,
            &["--out", "existing.json", "--force"],
        ),
        case(
            "generate out folder",
            &["generate", "--places", "20", "--out", "{root}/full"],
            1,
            &["--out", "folder"],
        ),
        case(
            "generate out folder missing",
            &[
                "generate",
                "--places",
                "20",
                "--out",
                "{root}/nowhere/g.json",
            ],
            1,
            &["--out", "does not exist"],
        ),
        // train
        case(
            "train duplicate building",
            &[
                "train",
                "--buildings",
                "Freiburg,Freiburg",
                "--out",
                "{root}/t.json",
            ],
            1,
            &["--buildings", "Freiburg is listed twice"],
        ),
        case(
            "train unknown building",
            &["train", "--buildings", "Atlantis", "--out", "{root}/t.json"],
            1,
            &["--buildings", "\"Atlantis\""],
        ),
        case(
            "train epochs 0",
            &["train", "--epochs", "0", "--out", "{root}/t.json"],
            1,
            &["--epochs 0", "must be from 1 to 10000"],
        ),
        case(
            "train epochs negative",
            &["train", "--epochs", "-4", "--out", "{root}/t.json"],
            2,
            &["--epochs", "-4"],
        ),
        case(
            "train decompositions per map 0",
            &[
                "train",
                "--decompositions-per-map",
                "0",
                "--out",
                "{root}/t.json",
            ],
            1,
            &["--decompositions-per-map 0", "must be from 1 to 1000"],
        ),
        case(
            "train out exists",
            &["train", "--out", "{root}/existing.json"],
            1,
            &["--out", "existing.json", "--force"],
        ),
        case(
            "train data missing",
            &[
                "train",
                "--data",
                "{root}/nowhere",
                "--out",
                "{root}/t.json",
            ],
            1,
            &["--data", "nowhere"],
        ),
        case(
            "train out in data",
            &[
                "train",
                "--data",
                "{root}/cold",
                "--buildings",
                "Freiburg",
                "--out",
                "{root}/cold/no_rooms/nodes.dat",
                "--force",
            ],
            1,
            &["--out", "nodes.dat", "input --data"],
        ),
        // reproduce
        case(
            "reproduce out is file",
            &["reproduce", "--out", "{root}/existing.json"],
            1,
            &["--out", "existing.json", "not a folder"],
        ),
        case(
            "reproduce out not empty",
            &["reproduce", "--out", "{root}/full"],
            1,
            &["--out", "full", "not empty", "--force"],
        ),
        case(
            "reproduce level 9",
            &["reproduce", "--out", "{root}/r", "--levels", "9"],
            1,
            &["--levels 9"],
        ),
        case(
            "reproduce level 0",
            &["reproduce", "--out", "{root}/r", "--levels", "0"],
            1,
            &["--levels 0"],
        ),
        case(
            "reproduce level negative",
            &["reproduce", "--out", "{root}/r", "--levels", "-1"],
            2,
            &["--levels", "-1"],
        ),
        case(
            "reproduce maps 0",
            &["reproduce", "--out", "{root}/r", "--maps", "0"],
            1,
            &["--maps 0"],
        ),
        case(
            "reproduce rounds 0",
            &["reproduce", "--out", "{root}/r", "--rounds", "0"],
            1,
            &["--rounds 0"],
        ),
        case(
            "reproduce decompositions 0",
            &["reproduce", "--out", "{root}/r", "--decompositions", "0"],
            1,
            &["--decompositions 0"],
        ),
        case(
            "reproduce candidates",
            &[
                "reproduce",
                "--out",
                "{root}/r",
                "--decompositions",
                "5",
                "--candidates",
                "2",
            ],
            1,
            &["--candidates 2"],
        ),
        case(
            "reproduce exclude unknown",
            &["reproduce", "--out", "{root}/r", "--exclude", "Atlantis"],
            1,
            &["--exclude", "\"Atlantis\""],
        ),
        case(
            "reproduce buildings twice",
            &[
                "reproduce",
                "--out",
                "{root}/r",
                "--buildings",
                "Stockholm,Stockholm",
            ],
            1,
            &["--buildings", "Stockholm is listed twice"],
        ),
        case(
            "reproduce buildings excluded",
            &[
                "reproduce",
                "--out",
                "{root}/r",
                "--buildings",
                "Stockholm",
                "--exclude",
                "Stockholm",
            ],
            1,
            &["--buildings", "--exclude"],
        ),
        case(
            "reproduce training list",
            &["reproduce", "--out", "{root}/r", "--training", "[1]"],
            1,
            &["--training"],
        ),
        case(
            "reproduce training syntax",
            &["reproduce", "--out", "{root}/r", "--training", "{bad"],
            1,
            &["--training"],
        ),
        case(
            "reproduce training field",
            &[
                "reproduce",
                "--out",
                "{root}/r",
                "--training",
                "{\"epochs\": \"many\"}",
            ],
            1,
            &["--training"],
        ),
        case(
            "reproduce settings missing",
            &[
                "reproduce",
                "--out",
                "{root}/r",
                "--settings",
                "{root}/nope.json",
            ],
            1,
            &["nope.json"],
        ),
        case(
            "reproduce settings without a settings object",
            &[
                "reproduce",
                "--out",
                "{root}/r",
                "--settings",
                "{root}/model.json",
            ],
            1,
            &["model.json", "settings"],
        ),
        case(
            "infer unknown strategy",
            &[
                "infer",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/floor.json",
                "--strategy",
                "greedy",
            ],
            2,
            &["--strategy", "greedy", "paper or cover"],
        ),
        case(
            "infer unknown mixing",
            &[
                "infer",
                "--model",
                "{root}/model.json",
                "--map",
                "{root}/floor.json",
                "--mixing",
                "vote",
            ],
            2,
            &["--mixing", "vote", "posterior or average"],
        ),
        case(
            "train temperature 0",
            &["train", "--out", "{root}/o.json", "--temperature", "0"],
            1,
            &["--temperature 0", "must be finite and in (0, 10]"],
        ),
        // evaluate
        case(
            "evaluate maps missing",
            &["evaluate", "--maps", "{root}/nope", "--out", "{root}/r"],
            1,
            &["--maps", "nope", "no such"],
        ),
        case(
            "evaluate out not empty",
            &[
                "evaluate",
                "--maps",
                "{root}/floor.json",
                "--out",
                "{root}/full",
            ],
            1,
            &["--out", "full", "not empty", "--force"],
        ),
        case(
            "evaluate one training building",
            &[
                "evaluate",
                "--maps",
                "{root}/floor.json",
                "--train",
                "{root}/floor.json",
                "--out",
                "{root}/r",
            ],
            1,
            &["--train", "at least two"],
        ),
        case(
            "evaluate other classes",
            &[
                "evaluate",
                "--maps",
                "{root}/map_three_classes.json",
                "--out",
                "{root}/r",
            ],
            1,
            &["--maps", "classes"],
        ),
        case(
            "evaluate COLD folder without rooms.dat",
            &[
                "evaluate",
                "--maps",
                "{root}/cold/no_rooms",
                "--out",
                "{root}/r",
            ],
            1,
            &["--maps", "rooms.dat"],
        ),
        case(
            "evaluate level 9",
            &[
                "evaluate",
                "--maps",
                "{root}/floor.json",
                "--out",
                "{root}/r",
                "--levels",
                "9",
            ],
            1,
            &["--levels 9"],
        ),
        case(
            "evaluate rounds 0",
            &[
                "evaluate",
                "--maps",
                "{root}/floor.json",
                "--out",
                "{root}/r",
                "--rounds",
                "0",
            ],
            1,
            &["--rounds 0"],
        ),
        case(
            "validate building unknown",
            &["validate", "--out", "{root}/r", "--buildings", "Atlantis"],
            1,
            &["--buildings", "Atlantis"],
        ),
        case(
            "validate data missing",
            &["validate", "--data", "{root}/nowhere", "--out", "{root}/r"],
            1,
            &["--data", "nowhere"],
        ),
        case(
            "reproduce data missing",
            &["reproduce", "--data", "{root}/nowhere", "--out", "{root}/r"],
            1,
            &["--data", "nowhere"],
        ),
        case(
            "reproduce out in data",
            &[
                "reproduce",
                "--data",
                "{root}/cold",
                "--out",
                "{root}/cold/r",
                "--force",
            ],
            1,
            &["--out", "input --data"],
        ),
        // compile
        case(
            "compile module",
            &[
                "compile",
                "--model",
                m,
                "--map",
                f,
                "--module",
                "1bad",
                "--out",
                "{root}/o.rs",
            ],
            1,
            &["--module", "\"1bad\""],
        ),
        case(
            "compile count 0",
            &[
                "compile",
                "--model",
                m,
                "--map",
                f,
                "--count",
                "0",
                "--out",
                "{root}/o.rs",
            ],
            1,
            &["--count 0"],
        ),
        case(
            "compile count huge",
            &[
                "compile",
                "--model",
                m,
                "--map",
                f,
                "--count",
                "100000",
                "--out",
                "{root}/o.rs",
            ],
            1,
            &["--count 100000"],
        ),
        case(
            "compile count negative",
            &[
                "compile",
                "--model",
                m,
                "--map",
                f,
                "--count",
                "-1",
                "--out",
                "{root}/o.rs",
            ],
            2,
            &["--count", "-1"],
        ),
        case(
            "compile out hand-written",
            &[
                "compile",
                "--model",
                m,
                "--map",
                f,
                "--out",
                "{root}/hand.rs",
            ],
            1,
            &["--out", "hand.rs", "--force"],
        ),
        case(
            "compile out is model",
            &["compile", "--model", m, "--map", f, "--out", m, "--force"],
            1,
            &["--out", "input --model"],
        ),
        case(
            "compile out is map",
            &["compile", "--model", m, "--map", f, "--out", f, "--force"],
            1,
            &["--out", "input --map"],
        ),
        case(
            "compile export map exists",
            &[
                "compile",
                "--model",
                m,
                "--map",
                f,
                "--export-map",
                "{root}/existing.json",
                "--out",
                "{root}/o.rs",
            ],
            1,
            &["--export-map", "existing.json", "--force"],
        ),
        case(
            "compile export map is model",
            &[
                "compile",
                "--model",
                m,
                "--map",
                f,
                "--export-map",
                m,
                "--out",
                "{root}/o.rs",
                "--force",
            ],
            1,
            &["--export-map", "input --model"],
        ),
        case(
            "compile export map equals out",
            &[
                "compile",
                "--model",
                m,
                "--map",
                f,
                "--export-map",
                "{root}/o.rs",
                "--out",
                "{root}/o.rs",
            ],
            1,
            &["--export-map", "--out"],
        ),
        case(
            "compile decompositions missing",
            &[
                "compile",
                "--model",
                m,
                "--map",
                f,
                "--decompositions",
                "{root}/nope.json",
                "--out",
                "{root}/o.rs",
            ],
            1,
            &["nope.json"],
        ),
        case(
            "compile stack text",
            &[
                "compile",
                "--model",
                m,
                "--map",
                f,
                "--max-stack-bytes",
                "lots",
                "--out",
                "{root}/o.rs",
            ],
            2,
            &["--max-stack-bytes", "lots"],
        ),
        // decompose
        case(
            "decompose count 0",
            &[
                "decompose",
                "--model",
                m,
                "--map",
                f,
                "--count",
                "0",
                "--out",
                "{root}/o.json",
            ],
            1,
            &["--count 0"],
        ),
        case(
            "decompose count huge",
            &[
                "decompose",
                "--model",
                m,
                "--map",
                f,
                "--count",
                "5000",
                "--out",
                "{root}/o.json",
            ],
            1,
            &["--count 5000"],
        ),
        case(
            "decompose out exists",
            &[
                "decompose",
                "--model",
                m,
                "--map",
                f,
                "--out",
                "{root}/existing.json",
            ],
            1,
            &["--out", "existing.json", "--force"],
        ),
        case(
            "decompose out is map",
            &["decompose", "--model", m, "--map", f, "--out", f, "--force"],
            1,
            &["--out", "input --map"],
        ),
        // stats
        case(
            "stats synthetic small",
            &["stats", "--synthetic", "3"],
            1,
            &["--synthetic 3"],
        ),
        case(
            "stats data missing",
            &["stats", "--data", "{root}/nowhere"],
            1,
            &["--data", "nowhere"],
        ),
        case(
            "stats seed negative",
            &["stats", "--synthetic", "50", "--seed", "-5"],
            2,
            &["--seed", "-5"],
        ),
        case("no subcommand", &[], 2, &["Usage"]),
        case("unknown subcommand", &["frobnicate"], 2, &["frobnicate"]),
    ];
    cases.extend(args);
    cases
}

#[test]
fn every_bad_input_is_refused_clearly_without_panic_or_side_effect() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let cases = corpus(root);
    assert!(cases.len() >= 150, "only {} cases", cases.len());
    let root_s = root.to_str().unwrap();
    let before = snapshot(root);
    let mut failures = Vec::new();
    for c in &cases {
        let args: Vec<String> = c.args.iter().map(|a| a.replace("{root}", root_s)).collect();
        let out: Output = bin().args(&args).current_dir(root).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        let mut problems = Vec::new();
        if out.status.code() != Some(c.code) {
            problems.push(format!("exit {:?}, expected {}", out.status.code(), c.code));
        }
        if err.contains("panicked") || out.status.code() == Some(101) {
            problems.push("panicked".to_string());
        }
        for e in &c.expect {
            if !err.contains(e.as_str()) {
                problems.push(format!("message lacks {e:?}"));
            }
        }
        if err.contains("Caused by") {
            problems.push("error chain printed twice".to_string());
        }
        if c.code == 1 && err.lines().filter(|l| l.starts_with("error:")).count() != 1 {
            problems.push("not exactly one error line".to_string());
        }
        let after = snapshot(root);
        if after != before {
            let changed: Vec<_> = after
                .keys()
                .chain(before.keys())
                .filter(|k| after.get(*k) != before.get(*k))
                .collect();
            problems.push(format!("files created or changed: {changed:?}"));
            // Restore for the next cases.
            for k in after.keys() {
                if !before.contains_key(k) {
                    let _ = std::fs::remove_file(k).or_else(|_| std::fs::remove_dir_all(k));
                }
            }
        }
        if !problems.is_empty() {
            failures.push(format!(
                "{}: {}\n  stderr: {}",
                c.name,
                problems.join("; "),
                err.trim()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
    eprintln!("{} bad inputs refused cleanly", cases.len());
}

/// Runs a command that must succeed; returns (stdout, stderr).
fn ok(cmd: &mut Command) -> (String, String) {
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "failed: {err}");
    (String::from_utf8(out.stdout).unwrap(), err)
}

fn infer_json(model: &Path, map: &Path, evidence: Option<&Path>) -> Value {
    let mut c = bin();
    c.args(["infer", "--model"])
        .arg(model)
        .arg("--map")
        .arg(map);
    if let Some(e) = evidence {
        c.arg("--evidence").arg(e);
    }
    serde_json::from_str(&ok(&mut c).0).unwrap()
}

fn probs(v: &Value, place: usize) -> Vec<f64> {
    v["places"][place]["probs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn coordinates_near_the_float_limit_give_a_finite_drawing() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("far.json");
    let classes = [
        "DW", "CR", "1PO", "2PO", "LO", "LAB", "BA", "KT", "MR", "UT",
    ];
    write_json(
        &map,
        &json!({"format": 1, "name": "far", "classes": classes, "places": [
            {"id": 0, "class": "CR", "placeholder": false, "x": 1e308, "y": 1e308},
            {"id": 1, "class": "DW", "placeholder": false, "x": -1e308, "y": -1e308},
            {"id": 2, "class": "KT", "placeholder": true, "x": 0.0, "y": 0.0}
        ], "edges": [[0, 2], [1, 2]]}),
    );
    let svg = dir.path().join("far.svg");
    ok(bin()
        .arg("render")
        .arg("--map")
        .arg(&map)
        .arg("--out")
        .arg(&svg));
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(!text.contains("inf") && !text.contains("NaN"), "{text}");
    let doc = roxmltree::Document::parse(&text).unwrap();
    let root = doc.root_element();
    for attr in ["width", "height"] {
        let v: f64 = root.attribute(attr).unwrap().parse().unwrap();
        assert!(v.is_finite() && v > 0.0 && v < 2.1e6, "{attr} = {v}");
    }
    // The three places are drawn at distinct finite positions, place 2 in the middle.
    let xs: Vec<f64> = doc
        .descendants()
        .filter(|n| n.has_tag_name("circle") && n.attribute("cx").is_some())
        .map(|n| n.attribute("cx").unwrap().parse::<f64>().unwrap())
        .collect();
    assert!(xs.iter().all(|x| x.is_finite()), "{xs:?}");
    // infer on the same map works too (coordinates only matter for drawing).
    let v = infer_json(&repo("generated/demo/model.json"), &map, None);
    assert_eq!(v["places"].as_array().unwrap().len(), 3);
}

#[test]
fn a_one_place_map_gets_the_singleton_distribution() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("one.json");
    let classes = [
        "DW", "CR", "1PO", "2PO", "LO", "LAB", "BA", "KT", "MR", "UT",
    ];
    write_json(
        &map,
        &json!({"format": 1, "name": "one", "classes": classes, "places": [
            {"id": 5, "class": "CR", "placeholder": false, "x": 0.0, "y": 0.0}
        ], "edges": []}),
    );
    let model = demo_model();
    let singleton: Vec<f64> = model["spns"][3]["nodes"][10]["weights"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let v = infer_json(&repo("generated/demo/model.json"), &map, None);
    assert_eq!(v["places"][0]["id"], 5);
    let p = probs(&v, 0);
    let total: f64 = singleton.iter().sum();
    for (a, b) in p.iter().zip(&singleton) {
        assert!((a - b / total).abs() < 1e-12, "{p:?} vs {singleton:?}");
    }
    assert!(v["log_likelihood"].as_f64().unwrap().abs() < 1e-12);
    // Every other command accepts it too.
    let d = dir.path();
    ok(bin()
        .arg("render")
        .arg("--map")
        .arg(&map)
        .arg("--out")
        .arg(d.join("one.svg")));
    ok(bin()
        .args(["instance", "--model"])
        .arg(repo("generated/demo/model.json"))
        .arg("--map")
        .arg(&map)
        .arg("--out")
        .arg(d.join("one.instance.json")));
    ok(bin()
        .args(["decompose", "--model"])
        .arg(repo("generated/demo/model.json"))
        .arg("--map")
        .arg(&map)
        .arg("--out")
        .arg(d.join("one.dec.json")));
    ok(bin()
        .args(["compile", "--model"])
        .arg(repo("generated/demo/model.json"))
        .arg("--map")
        .arg(&map)
        .arg("--decompositions")
        .arg(d.join("one.dec.json"))
        .arg("--out")
        .arg(d.join("one.rs")));
    assert!(
        std::fs::read_to_string(d.join("one.rs"))
            .unwrap()
            .contains("NUM_PLACES: usize = 1;")
    );
}

#[test]
fn evidence_rows_of_1e_300_give_the_same_marginals() {
    let dir = tempfile::tempdir().unwrap();
    let row = [0.05, 0.6, 0.1, 0.05, 0.05, 0.05, 0.02, 0.03, 0.03, 0.02];
    let tiny: Vec<f64> = row.iter().map(|x| x * 1e-300).collect();
    let write = |name: &str, r: &[f64]| {
        let p = dir.path().join(name);
        write_json(&p, &json!({"format": 1, "evidence": {"3": r, "40": r}}));
        p
    };
    let plain = write("plain.json", &row);
    let small = write("small.json", &tiny);
    let m = repo("generated/demo/model.json");
    let f = repo("generated/demo/floor.json");
    let a = infer_json(&m, &f, Some(&plain));
    let b = infer_json(&m, &f, Some(&small));
    for i in 0..80 {
        for (x, y) in probs(&a, i).iter().zip(probs(&b, i)) {
            assert!((x - y).abs() < 1e-9, "place {i}: {x} vs {y}");
        }
    }
    // Two rows scaled by 1e-300 each: ln P drops by 2 · 300 · ln 10.
    let (la, lb) = (
        a["log_likelihood"].as_f64().unwrap(),
        b["log_likelihood"].as_f64().unwrap(),
    );
    let want = la - 600.0 * std::f64::consts::LN_10;
    assert!((lb - want).abs() < 1e-6 * want.abs(), "{lb} vs {want}");
}

#[test]
fn template_weights_are_relative_on_every_path() {
    // The singleton's weights times 20 (not summing to 1) mean the same model: infer,
    // instance and compile all give exactly what the original model gives.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut m = demo_model();
    let w: Vec<f64> = m["spns"][3]["nodes"][10]["weights"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap() * 20.0)
        .collect();
    m["spns"][3]["nodes"][10]["weights"] = json!(w);
    let scaled = d.join("scaled.json");
    write_json(&scaled, &m);
    let orig = repo("generated/demo/model.json");
    let f = repo("generated/demo/floor.json");
    assert_eq!(infer_json(&orig, &f, None), infer_json(&scaled, &f, None));
    let instance = |model: &Path| {
        ok(bin()
            .args(["instance", "--model"])
            .arg(model)
            .arg("--map")
            .arg(&f))
        .0
    };
    assert_eq!(instance(&orig), instance(&scaled));
    let compile = |model: &Path, out: &str| {
        ok(bin()
            .args(["compile", "--model"])
            .arg(model)
            .arg("--map")
            .arg(&f)
            .arg("--out")
            .arg(d.join(out)));
        // The first line names the model file; the code must be identical.
        let text = std::fs::read_to_string(d.join(out)).unwrap();
        text.split_once('\n').unwrap().1.to_string()
    };
    assert_eq!(compile(&orig, "a.rs"), compile(&scaled, "b.rs"));
}

/// One `nodes.dat` line: id, not a placeholder, pose (x, 0), label, neighbours.
fn cold_line(id: u32, x: f64, label: &str, nbs: &[u32]) -> String {
    let mut cols = vec![
        id.to_string(),
        "0".into(),
        x.to_string(),
        "0".into(),
        "0".into(),
        "0".into(),
        x.to_string(),
        "0".into(),
        label.into(),
        "1.0".into(),
    ];
    for t in 0..8 {
        match nbs.get(t) {
            Some(n) => cols.extend([n.to_string(), "0.5".into(), "0".into()]),
            None => cols.extend(["-1".into(), "-1.0".into(), "0".into()]),
        }
    }
    cols.join(" ")
}

#[test]
fn a_disconnected_cold_map_warns_and_explains_its_dropped_places() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("Lab/seq1");
    std::fs::create_dir_all(&seq).unwrap();
    // Places 0-1-2 and 3-4: two components; 3 and 4 are dropped.
    let nodes = [
        cold_line(0, 0.0, "CR", &[1]),
        cold_line(1, 1.0, "CR", &[0, 2]),
        cold_line(2, 2.0, "DW", &[1]),
        cold_line(3, 5.0, "KT", &[4]),
        cold_line(4, 6.0, "KT", &[3]),
    ];
    std::fs::write(seq.join("nodes.dat"), nodes.join("\n") + "\n").unwrap();
    let rooms = "0 1-CR-1\n1 1-CR-1\n2 1-DW-1\n3 1-KT-1\n4 1-KT-1\n";
    std::fs::write(seq.join("rooms.dat"), rooms).unwrap();
    let ev = dir.path().join("ev.json");
    std::fs::write(
        &ev,
        "{\"format\": 1, \"evidence\": {\n\"4\": [0, 0, 0, 0, 0, 0, 0, 1, 0, 0]\n}}",
    )
    .unwrap();
    let out = bin()
        .args(["infer", "--model"])
        .arg(repo("generated/demo/model.json"))
        .arg("--map")
        .arg(&seq)
        .arg("--evidence")
        .arg(&ev)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("warning:") && err.contains("2 of its 5 places") && err.contains("ids 3, 4"),
        "{err}"
    );
    assert!(
        err.contains("ev.json:2")
            && err.contains("place id 4 was dropped")
            && err.contains("not in the largest connected component"),
        "{err}"
    );
}

#[test]
fn the_shipped_maps_are_found_with_no_set_up() {
    let (table, _) = ok(bin().arg("stats"));
    for b in ["Freiburg", "Saarbrucken", "Stockholm"] {
        assert!(table.contains(b), "{table}");
    }
    let v: Value = serde_json::from_str(
        &ok(bin()
            .args(["infer", "--model"])
            .arg(repo("generated/demo/model.json"))
            .args(["--map", "Freiburg/seq1_cloudy1"]))
        .0,
    )
    .unwrap();
    assert_eq!(v["map"], "Freiburg/seq1_cloudy1");
}

#[test]
fn reproduce_needs_only_out_and_refuses_a_non_empty_folder_before_computing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    ok(bin().args(["reproduce", "--quick", "--out"]).arg(&out));
    let report = std::fs::read_to_string(out.join("REPORT.md")).unwrap();
    assert!(report.contains('#'));
    // No temporary folder is left next to the output.
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 1);
    // Again without --force: refused at once, the report untouched.
    let t = std::time::SystemTime::now();
    let again = bin()
        .args(["reproduce", "--quick", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(again.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));
    assert!(
        std::fs::metadata(out.join("REPORT.md"))
            .unwrap()
            .modified()
            .unwrap()
            < t
    );
}

#[test]
fn force_replaces_an_existing_output_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("floor.json");
    std::fs::write(&out, "old\n").unwrap();
    ok(bin()
        .args(["generate", "--places", "30", "--force", "--out"])
        .arg(&out));
    assert!(
        std::fs::read_to_string(&out)
            .unwrap()
            .contains("\"places\"")
    );
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 1, "no temporary file left behind");
}

#[test]
fn the_examples_of_docs_formats_are_accepted() {
    let text = std::fs::read_to_string(repo("docs/FORMATS.md")).unwrap();
    let blocks: Vec<&str> = text
        .split("```json\n")
        .skip(1)
        .map(|b| b.split("```").next().unwrap())
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let file = |name: &str, k: usize| {
        let p = dir.path().join(name);
        std::fs::write(&p, blocks[k]).unwrap();
        p
    };
    let (map, model, trees, ev, decs) = (
        file("map.json", 0),
        file("model.json", 1),
        file("trees.json", 2),
        file("ev.json", 3),
        file("decs.json", 4),
    );
    // The example model (relative weights 1 and 4) on the example map.
    let v = infer_json(&model, &map, None);
    assert!((probs(&v, 0)[1] - 4.0 / 13.0).abs() < 1e-12, "{v}");
    // The example tree mixture on the example map (two places, one edge): exactly
    // P(y) ∝ u(y1) u(y2) ψ(y1, y2).
    let v = infer_json(&trees, &map, None);
    assert_eq!(v["model"]["family"], "tree_mixture");
    let u = [1.0, 2.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0];
    let psi = |a: usize, b: usize| match (a, b) {
        (0, 0) => 2.0,
        (1, 1) => 4.0,
        (a, b) if a == b => 3.0,
        _ => 1.0,
    };
    let z: f64 = (0..10)
        .flat_map(|a| (0..10).map(move |b| (a, b)))
        .map(|(a, b)| u[a] * u[b] * psi(a, b))
        .sum();
    let p_cr: f64 = (0..10).map(|b| u[1] * u[b] * psi(1, b)).sum::<f64>() / z;
    assert!((probs(&v, 0)[1] - p_cr).abs() < 1e-12, "{v}");
    // The example evidence and decompositions with the demo model.
    let (out, _) = ok(bin()
        .args(["infer", "--model"])
        .arg(repo("generated/demo/model.json"))
        .arg("--map")
        .arg(&map)
        .arg("--evidence")
        .arg(&ev)
        .arg("--decompositions-file")
        .arg(&decs));
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["places"][1]["argmax"], "CR");
}

#[test]
fn every_subcommand_help_has_an_example() {
    let commands = [
        "stats",
        "render",
        "train",
        "infer",
        "instance",
        "reproduce",
        "validate",
        "evaluate",
        "compile",
        "decompose",
        "generate",
    ];
    for c in commands {
        let (help, _) = ok(bin().args([c, "--help"]));
        assert!(
            help.contains("Example") && help.contains(&format!("graphspn {c} ")),
            "{c} --help has no example:\n{help}"
        );
    }
    // infer's help describes the evidence format itself.
    let (help, _) = ok(bin().args(["infer", "--help"]));
    assert!(
        help.contains("\"evidence\"") && help.contains("likelihood"),
        "{help}"
    );
}

/// A setting out of its domain in a settings file is named with the file's line, the
/// setting's path, the value and the domain (issue 23 §3: what and where).
#[test]
fn a_settings_file_value_out_of_its_domain_is_named_with_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = serde_json::to_value(ModelSettings {
        graphspn: GraphSpnSetting::paper(),
        mrf2: MrfSetting::paper(BpOptions::default()),
        mrf3: MrfSetting::paper(BpOptions::default()),
        trees: TreeTraining::default(),
    })
    .unwrap();
    // The same key under another model before it: the line is the one of mrf3's.
    s["mrf3"]["evidence_exponent"] = json!(-3.5);
    let path = dir.path().join("validation.json");
    write_json(
        &path,
        &json!({"settings": {"Freiburg": s.clone(), "Stockholm": s}}),
    );
    let text = std::fs::read_to_string(&path).unwrap();
    let line = text
        .lines()
        .position(|l| l.contains("\"evidence_exponent\": -3.5"))
        .unwrap()
        + 1;
    let out = bin()
        .args(["reproduce", "--out"])
        .arg(dir.path().join("r"))
        .arg("--settings")
        .arg(&path)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(&format!(
            "validation.json:{line}: settings of Freiburg: mrf3.evidence_exponent = -3.5: must be finite and in (0, 16]"
        )),
        "line {line}: {err}"
    );
    assert!(!dir.path().join("r").exists());
}
