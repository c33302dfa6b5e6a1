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

mod args_queries;
mod args_runs;
mod extremes;
mod fixtures;
mod inputs;
mod limits;
mod models_maps;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use graphspn_compiler::experiments::settings::{GraphSpnSetting, ModelSettings, MrfSetting};
use graphspn_compiler::map::PAPER_CLASSES;
use graphspn_compiler::mrf::BpOptions;
use graphspn_compiler::treemix::TreeTraining;
use serde_json::{Value, json};

pub use fixtures::*;

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
    // A file graphspn generated, and a link to it: compile replaces the file without
    // --force, never the link.
    std::fs::write(
        root.join("gen.rs"),
        format!("{}\n", graphspn_compiler::codegen::GENERATED_MARKER),
    )
    .unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink("gen.rs", root.join("link.rs")).unwrap();
    std::fs::write(root.join("existing.json"), "{}\n").unwrap();
    std::fs::create_dir(root.join("full")).unwrap();
    std::fs::write(root.join("full/REPORT.md"), "mine\n").unwrap();
    let mut cases = Vec::new();

    models_maps::models_and_maps(root, &mut cases);
    let decs = inputs::cold_evidence_decompositions(root, &mut cases);
    limits::limits_and_settings(root, &decs, &mut cases);
    // Argument sets: flags out of range, outputs that may not be written.
    let m = "{root}/model.json";
    let f = "{root}/floor.json";
    let t = "{root}/trees.json";
    cases.extend(args_queries::query_args(m, f, t));
    cases.extend(args_runs::run_args(m, f));
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
