//! Extreme but valid inputs, and the policies the corpus relies on.

use super::*;

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
        err.contains("warning:")
            && err.contains("2 places outside its largest connected component were dropped (ids 3, 4), 3 are kept"),
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
