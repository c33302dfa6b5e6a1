//! Malformed models and maps through every command that reads them, and a map whose
//! classes are not the model's.

use super::*;

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
        (
            "no_templates",
            |m| {
                m["templates"] = json!([]);
                m["spns"] = json!([]);
            },
            &["the model has no templates"],
        ),
        // Unknown fields at every level are refused, not ignored (a misspelt field
        // would otherwise be a silent default).
        (
            "unknown_field",
            |m| m["temperature"] = json!(0.5),
            &["unknown field `temperature`"],
        ),
        (
            "unknown_template_field",
            |m| m["templates"][0]["nodes"] = json!(3),
            &["unknown field `nodes`"],
        ),
        (
            "unknown_spn_field",
            |m| m["spns"][3]["roots"] = json!([10]),
            &["unknown field `roots`"],
        ),
        (
            "unknown_node_field",
            |m| m["spns"][3]["nodes"][10]["weight"] = json!(1),
            &["unknown field `weight`"],
        ),
        (
            "unknown_class_field",
            |m| m["classes"]["colours"] = json!([]),
            &["unknown field `colours`"],
        ),
    ]
}

/// Adds the malformed-model and malformed-map cases (their files written under `root`).
pub fn models_and_maps(root: &Path, cases: &mut Vec<Case>) {
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
            "classes_65537",
            |m| m["classes"] = json!((0..65537).map(|i| format!("c{i}")).collect::<Vec<_>>()),
            &["65537 classes: at most 65536"],
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
            &[
                "line ",
                "invalid length 3, expected an edge: a pair of place ids [a, b]",
            ],
        ),
        (
            "edge_single",
            |m| m["edges"][0] = json!([0]),
            &["invalid length 1, expected an edge"],
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
    // A map with many classes: the message lists the first ten and the count.
    let mut twenty = floor.clone();
    twenty["classes"] = json!((0..20).map(|i| format!("c{i}")).collect::<Vec<_>>());
    for p in twenty["places"].as_array_mut().unwrap() {
        p["class"] = json!("c0");
    }
    write_json(&root.join("map_twenty_classes.json"), &twenty);
    cases.push(case(
        "infer map_twenty_classes",
        &[
            "infer",
            "--model",
            "{root}/model.json",
            "--map",
            "{root}/map_twenty_classes.json",
        ],
        1,
        &["\"c9\", … (20 classes)]", "but the model has [\"DW\""],
    ));
    // A map with no place to label.
    let mut empty = floor.clone();
    empty["places"] = json!([]);
    empty["edges"] = json!([]);
    write_json(&root.join("map_empty.json"), &empty);
    // Refused by every command that reads a map for a model, of either family, with
    // both files named, before any work (decompose used to write a file for them).
    for (map, what) in [("map_three_classes", "classes"), ("map_empty", "no places")] {
        for model in ["model", "trees"] {
            for cmd in ["infer", "instance", "compile", "decompose"] {
                if cmd == "decompose" && model == "trees" {
                    continue;
                }
                let (map_arg, model_arg) = (
                    format!("{{root}}/{map}.json"),
                    format!("{{root}}/{model}.json"),
                );
                cases.push(case(
                    &format!("{cmd} {model} {map}"),
                    &[
                        cmd,
                        "--model",
                        &model_arg,
                        "--map",
                        &map_arg,
                        "--out",
                        "{root}/o.rs",
                    ],
                    1,
                    &["--map", &format!("{map}.json does not fit --model"), what],
                ));
            }
        }
    }
}
