//! The command-line tool end to end on the committed demo inputs (no data set needed):
//! `infer` (marginals, MPE, evidence errors naming the file line and place id),
//! `instance` export, `compile`, `train` with its options and the tree mixture.
//! `validate`, `reproduce` and `evaluate`: `cli_experiments.rs`.

mod cli_support;

use std::path::Path;
use std::process::Command;

use cli_support::{bin, demo, run_ok, run_refused};

/// `graphspn CMD --model <demo model> --map <demo floor>` (the rest to be added).
fn on_demo(cmd: &str) -> Command {
    let mut c = bin();
    c.args([cmd, "--model"])
        .arg(demo("model.json"))
        .arg("--map")
        .arg(demo("floor.json"));
    c
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
    let text = run_ok(on_demo("infer").arg("--evidence").arg(&ev).arg("--mpe"));
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
    assert_eq!(v["seed"], 0);
    // Decompositions read from a file (made with seed 9): the output names the file
    // and records no seed, which would not reproduce it.
    let decs = dir.path().join("d9.json");
    run_ok(
        on_demo("decompose")
            .args(["--count", "3", "--seed", "9", "--out"])
            .arg(&decs),
    );
    let text = run_ok(on_demo("infer").arg("--decompositions-file").arg(&decs));
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(v.get("seed").is_none(), "{}", v["seed"]);
    assert_eq!(v["model"]["decompositions"], 3);
    assert_eq!(
        v["model"]["decompositions_file"],
        decs.display().to_string()
    );
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
    let err = run_refused(
        bin()
            .args(["infer", "--model"])
            .arg(demo("model.json"))
            .arg("--map")
            .arg(demo("floor.json"))
            .arg("--evidence")
            .arg(&ev)
            .env("RUST_BACKTRACE", "0"),
    );
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
    assert!(src.contains("(absolute error about 1e-6 in `f32`)"));
    // A relative --out: the printed `include!` names it from the crate's root (an
    // `include!` path is relative to the file it is in); SIMD stack figures are
    // estimates, and the multiply-adds lane-vector operations.
    std::fs::create_dir(dir.path().join("src")).unwrap();
    let run = compile_demo(Path::new("src/floor.rs"))
        .current_dir(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    assert!(
        err.contains(
            r#"pub mod floor { include!(concat!(env!("CARGO_MANIFEST_DIR"), "/src/floor.rs")); }"#
        ),
        "{err}"
    );
    assert!(
        err.contains("stack per call (bytes, estimate")
            && err.contains("multiply-adds per call (lane-vector operations)"),
        "{err}"
    );
    // The fixed-point kernel's module states its own bound, not the float one.
    let fixed = dir.path().join("fixed.rs");
    let run = compile_demo(&fixed).arg("--fixed-point").output().unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    assert!(err.contains("stack per call (bytes, upper bound)"), "{err}");
    let src = std::fs::read_to_string(&fixed).unwrap();
    assert!(
        src.contains("fixed-point kernel: each entry within `2^-10 + 2K·2^-13 + 3D·2^-31`")
            && src.contains("within `K·2^-13` =")
            && !src.contains("about 1e-6"),
        "the fixed-point module's accuracy"
    );
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
    assert!(
        src.contains("Messages `ψ·b` in fixed point: each entry within `η` = 4.7e-5 of itself"),
        "the fixed-point module's accuracy"
    );
    // A flag that does not apply to the family is refused as such, before its value
    // or file is looked at (this file does not exist).
    let decs = dir.path().join("missing.json");
    let decs = decs.to_str().unwrap();
    for flags in [["--strategy", "cover"], ["--decompositions", decs]] {
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

/// `compile --map` takes a sequence name under the data folder, as `infer` does, and
/// names the map `building/sequence` whichever way its folder was given.
#[test]
fn compile_resolves_a_sequence_name_under_the_data_folder() {
    let dir = tempfile::tempdir().unwrap();
    let data = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/cold-topomaps");
    let compile = |map: &std::path::Path, out: &str| {
        run_ok(
            bin()
                .args(["compile", "--count", "1", "--model"])
                .arg(demo("model.json"))
                .arg("--data")
                .arg(&data)
                .arg("--map")
                .arg(map)
                .arg("--out")
                .arg(dir.path().join(out)),
        );
        std::fs::read_to_string(dir.path().join(out)).unwrap()
    };
    let by_name = compile(std::path::Path::new("Freiburg/seq1_cloudy1"), "a.rs");
    let by_path = compile(&data.join("Freiburg/seq1_cloudy1/."), "b.rs");
    assert!(by_name.contains("Freiburg/seq1_cloudy1"));
    assert_eq!(by_name, by_path);
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
    // GraphSPN-only flags are refused as such before their value or file is looked at.
    for (cmd, flag, value) in [
        ("infer", "--decompositions", "0"),
        ("instance", "--decompositions", "0"),
        ("infer", "--decompositions-file", "missing.json"),
        ("instance", "--decompositions-file", "missing.json"),
    ] {
        let err = run_refused(
            bin()
                .args([cmd, "--model"])
                .arg(&model)
                .arg("--map")
                .arg(demo("floor.json"))
                .args([flag, value]),
        );
        assert!(
            err.contains(&format!(
                "{flag} applies to GraphSPN models; --model holds a tree mixture"
            )),
            "{cmd} {flag}: {err}"
        );
    }
    // `render` of the model's trees on `map` with `flags`.
    let svg = dir.path().join("t.svg");
    let render = |map: &Path, flags: &[&str]| {
        let mut cmd = bin();
        cmd.args(["render", "--force", "--map"])
            .arg(map)
            .arg("--model")
            .arg(&model)
            .args(flags)
            .arg("--out")
            .arg(&svg);
        cmd
    };
    run_ok(&mut render(&demo("floor.json"), &["--tree", "3"]));
    let text = std::fs::read_to_string(&svg).unwrap();
    roxmltree::Document::parse(&text).unwrap();
    assert_eq!(
        text.matches("tree-edge").count(),
        79,
        "a spanning tree of 80 places"
    );
    // `render` and `instance` take `--trees` as `infer` does (each draws the trees
    // with `SpanningTrees::covering(map, count, seed)`).
    run_ok(&mut render(
        &demo("floor.json"),
        &["--trees", "5", "--tree", "5"],
    ));
    let err = run_refused(&mut render(&demo("floor.json"), &["--tree", "5"]));
    assert!(
        err.contains("the model mixes 3 trees (give 1 to 3)"),
        "{err}"
    );
    let exported = run_ok(
        bin()
            .args(["instance", "--model"])
            .arg(&model)
            .arg("--map")
            .arg(demo("floor.json"))
            .args(["--trees", "5"]),
    );
    let exported: serde_json::Value = serde_json::from_str(&exported).unwrap();
    assert_eq!(exported["trees"].as_array().unwrap().len(), 5);
    // Those are the trees `SpanningTrees::covering(map, 5, seed 0)` draws, as parent
    // and child place ids.
    let map = graphspn::map::TopoMap::load(demo("floor.json")).unwrap();
    let drawn = graphspn::treemix::SpanningTrees::covering(&map, 5, 0).unwrap();
    for (k, forest) in drawn.forests.iter().enumerate() {
        let ids: Vec<[u32; 2]> = forest
            .edges()
            .into_iter()
            .map(|(p, c)| [map.place(p as usize).id, map.place(c as usize).id])
            .collect();
        assert_eq!(exported["trees"][k], serde_json::json!(ids), "tree {k}");
    }
    // A map whose classes are not the model's is refused by render as by infer.
    let other = dir.path().join("other.json");
    std::fs::write(
        &other,
        r#"{"format": 1, "name": "abc", "classes": ["A", "B", "C"], "places": [{"id": 1, "class": "A", "placeholder": false, "x": 0, "y": 0}, {"id": 2, "class": "B", "placeholder": false, "x": 1, "y": 0}], "edges": [[1, 2]]}"#,
    )
    .unwrap();
    let err = run_refused(&mut render(&other, &[]));
    assert!(err.contains("does not fit --model"), "{err}");
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

/// A user's own data folder, with a building of its own name: `train` and `stats`
/// take the buildings the folder holds (they knew only COLD's three names), a map
/// that lost places to disconnection is named in a warning, and a building's
/// sub-folder that is not a sequence is an error naming it (it was skipped).
#[test]
fn train_and_stats_take_a_building_of_your_own() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("my-data/MyLab/seq1");
    std::fs::create_dir_all(&seq).unwrap();
    let shipped = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("data/cold-topomaps/Freiburg/seq1_cloudy1");
    for f in ["nodes.dat", "rooms.dat"] {
        std::fs::copy(shipped.join(f), seq.join(f)).unwrap();
    }
    let data = dir.path().join("my-data");
    let model = dir.path().join("mylab.json");
    let train = |building: &str| {
        let mut cmd = bin();
        cmd.args(["train", "--family", "tree-mixture", "--force", "--data"])
            .arg(&data)
            .args(["--buildings", building, "--out"])
            .arg(&model);
        cmd
    };
    run_ok(&mut train("MyLab"));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    assert_eq!(m["trained_on"], serde_json::json!(["MyLab/seq1"]));
    let stats = run_ok(bin().arg("stats").arg("--data").arg(&data));
    assert!(stats.contains("MyLab") && stats.contains("all"), "{stats}");
    let err = run_refused(&mut train("Freiburg"));
    assert!(
        err.contains("unknown building \"Freiburg\": the data folder")
            && err.contains("holds MyLab"),
        "{err}"
    );
    // A disconnected map: two places far from the rest, joined to each other only.
    let seq2 = dir.path().join("my-data/MyLab/seq2");
    std::fs::create_dir_all(&seq2).unwrap();
    let mut nodes = std::fs::read_to_string(seq.join("nodes.dat")).unwrap();
    let mut rooms = std::fs::read_to_string(seq.join("rooms.dat")).unwrap();
    for (id, other) in [(9001, 9002), (9002, 9001)] {
        nodes.push_str(&format!(
            "{id} 0 50.0 50.0 50.0 50.0 50.0 50.0 CR 1.0 {other} 0.5 0 -1 -1.0 1 -1 -1.0 2 -1 -1.0 3 -1 -1.0 4 -1 -1.0 5 -1 -1.0 6 -1 -1.0 7\n"
        ));
        rooms.push_str(&format!("{id} 9-CR-1\n"));
    }
    std::fs::write(seq2.join("nodes.dat"), nodes).unwrap();
    std::fs::write(seq2.join("rooms.dat"), rooms).unwrap();
    let out = train("MyLab").output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("seq2: the map is not connected; 2 places outside its largest connected component were dropped (ids 9001, 9002)"),
        "{err}"
    );
    // `infer` lists what the map lost, by reason (Freiburg seq1_cloudy1's own `UN`
    // and edgeless nodes, and the two places cut off).
    let out = run_ok(
        bin()
            .args(["infer", "--model"])
            .arg(&model)
            .arg("--map")
            .arg(&seq2),
    );
    let out: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(
        out["dropped"],
        serde_json::json!({"unknown": [7, 8, 28, 55], "isolated": [47], "disconnected": [9001, 9002]})
    );
    std::fs::create_dir(dir.path().join("my-data/MyLab/notes")).unwrap();
    let err = run_refused(&mut train("MyLab"));
    assert!(err.contains("notes: not a map"), "{err}");
}
