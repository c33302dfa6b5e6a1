//! Source rules of the code generator (`compiler/src/codegen`), checked on its text:
//! - no Rust code is assembled as strings: every `format!` / `write!` / `writeln!` /
//!   `format_args!` / `push_str` is either an error message (`what: format!(..)`,
//!   `BadOption(format!(..))`, `Unsupported(format!(..))`) or marked `// lint: <why>` on the line above (the
//!   spelling of one numeric literal, the `@generated` comment line, a file name);
//! - the emitters use `quote!`;
//! - no function is longer than 100 lines.
//!
//! And of the module layout: `learn/` and `experiments/` import their modules
//! without a circle, and no file of `experiments/` is over 800 lines.

use std::path::{Path, PathBuf};

/// The `.rs` files below `dir`, sorted, with their text.
fn sources(dir: &Path) -> Vec<(PathBuf, String)> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir)
            .expect("source folder")
            .map(|e| e.expect("entry").path())
            .collect();
        entries.sort();
        for p in entries {
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|e| e == "rs") {
                out.push(p);
            }
        }
    }
    let mut paths = vec![];
    walk(dir, &mut paths);
    paths
        .into_iter()
        .map(|p| {
            let text = std::fs::read_to_string(&p).expect("read");
            (p, text)
        })
        .collect()
}

/// The generator's sources.
fn codegen_sources() -> Vec<(PathBuf, String)> {
    let out = sources(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src/codegen"));
    assert!(out.len() >= 8, "codegen sources not found");
    out
}

const TEXT_MACROS: [&str; 5] = [
    "format!(",
    "write!(",
    "writeln!(",
    "format_args!(",
    "push_str(",
];
const ERROR_MESSAGES: [&str; 4] = [
    "what: format!(",
    "BadOption(format!(",
    "Unsupported(format!(",
    "Internal(format!(",
];

#[test]
fn no_rust_code_assembled_as_strings() {
    let mut bad = vec![];
    for (path, text) in codegen_sources() {
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            if !TEXT_MACROS.iter().any(|m| code.contains(m)) {
                continue;
            }
            let marked = i > 0 && lines[i - 1].trim_start().starts_with("// lint:");
            let message = ERROR_MESSAGES.iter().any(|m| code.contains(m));
            if !marked && !message {
                bad.push(format!("{}:{}: {}", path.display(), i + 1, line.trim()));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "text assembly in compiler/src/codegen (build tokens with quote!, or mark a \
         non-code string with `// lint: why` on the line above):\n{}",
        bad.join("\n")
    );
}

#[test]
fn emitters_use_quote() {
    for name in [
        "sparse/mod.rs",
        "sparse/mpe.rs",
        "template.rs",
        "wiring/mod.rs",
        "wiring/api.rs",
        "wiring/state.rs",
        "surface.rs",
        "trees/mod.rs",
        "trees/api.rs",
    ] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("src/codegen")
            .join(name);
        let text = std::fs::read_to_string(&path).expect("read");
        assert!(text.contains("quote!"), "{name} does not use quote!");
        assert!(!text.contains("std::fmt::Write"), "{name} writes text");
    }
}

#[test]
fn no_function_over_100_lines() {
    let mut long = vec![];
    for (path, text) in codegen_sources() {
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            let t = line.trim_start();
            let is_fn = ["fn ", "pub fn ", "pub(super) fn ", "pub(crate) fn "]
                .iter()
                .any(|p| t.starts_with(p));
            if !is_fn {
                continue;
            }
            // The function ends at the first later line with its indentation that
            // closes a brace.
            let indent = line.len() - t.len();
            let end = lines[i + 1..].iter().position(|l| {
                l.len() > indent && l[..indent].trim().is_empty() && l[indent..].starts_with('}')
            });
            if let Some(end) = end
                && end + 2 > 100
            {
                long.push(format!("{}:{}: {} lines", path.display(), i + 1, end + 2));
            }
        }
    }
    assert!(
        long.is_empty(),
        "functions over 100 lines:\n{}",
        long.join("\n")
    );
}

/// The `[dependencies]` entries of a manifest, as crate names (`-` → `_`).
fn dependencies(manifest: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(manifest).expect("Cargo.toml");
    text.split("\n[")
        .find(|s| s.starts_with("dependencies]"))
        .map(|s| {
            s.lines()
                .skip(1)
                .filter_map(|l| l.split(['=', '.']).next())
                .map(|n| n.trim().replace('-', "_"))
                .filter(|n| !n.is_empty() && !n.starts_with('#'))
                .collect()
        })
        .unwrap_or_default()
}

/// A `cargo machete`-style check of the workspace: every `[dependencies]` entry of
/// the compiler, the runtime and the command-line crate is named in its sources
/// (`name::` or `use name`). (`graphspn-generated`'s one dependency, the runtime, is
/// named only by the code its build script generates.)
#[test]
fn no_unused_dependency() {
    let compiler = Path::new(env!("CARGO_MANIFEST_DIR"));
    let workspace = compiler.parent().expect("workspace folder");
    let mut checked = 0;
    for (krate, dirs) in [
        (compiler.to_path_buf(), vec!["src"]),
        (workspace.join("runtime"), vec!["src"]),
        (workspace.to_path_buf(), vec!["src"]),
    ] {
        let deps = dependencies(&krate.join("Cargo.toml"));
        assert!(
            !deps.is_empty(),
            "{}: no dependencies read",
            krate.display()
        );
        let sources: String = dirs
            .iter()
            .flat_map(|d| sources(&krate.join(d)))
            .map(|(_, text)| text)
            .collect();
        let unused: Vec<&String> = deps
            .iter()
            .filter(|d| {
                !sources.contains(&format!("{d}::")) && !sources.contains(&format!("use {d}"))
            })
            .collect();
        assert!(
            unused.is_empty(),
            "{}: unused dependencies {unused:?}",
            krate.display()
        );
        checked += deps.len();
    }
    assert!(checked >= 20, "only {checked} dependencies checked");
}

/// The graph of `super::<module>` references between the modules of `src/<folder>`
/// (comments aside; names re-exported by the folder's `mod.rs`, and the `extra`
/// `(name, module)` pairs, resolved to their module): `(modules, edges)`.
fn import_graph(folder: &str, extra: &[(&str, &str)]) -> (Vec<String>, Vec<(String, String)>) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("src")
        .join(folder);
    let files = sources(&dir);
    let module = |p: &Path| p.file_stem().unwrap().to_string_lossy().into_owned();
    let modules: Vec<String> = files
        .iter()
        .map(|(p, _)| module(p))
        .filter(|m| m != "mod")
        .collect();
    // Names `mod.rs` re-exports: `pub use <module>::{a, b}` / `pub use <module>::a`.
    let mod_rs = &files
        .iter()
        .find(|(p, _)| module(p) == "mod")
        .expect("mod.rs")
        .1;
    let mut owner: std::collections::BTreeMap<String, String> = Default::default();
    for stmt in mod_rs.split(';') {
        let stmt = stmt.trim();
        let Some(rest) = stmt.strip_prefix("pub use ") else {
            continue;
        };
        let Some((m, names)) = rest.split_once("::") else {
            continue;
        };
        for n in names.trim_matches(['{', '}']).split(',') {
            let n = n.trim();
            if !n.is_empty() {
                owner.insert(n.to_string(), m.trim().to_string());
            }
        }
    }
    for &(name, m) in extra {
        owner.entry(name.to_string()).or_insert(m.to_string());
    }
    let mut edges: Vec<(String, String)> = Vec::new();
    for (p, text) in &files {
        let from = module(p);
        if from == "mod" {
            continue;
        }
        for line in text.lines() {
            let code = line.split("//").next().unwrap_or("");
            for (i, _) in code.match_indices("super::") {
                let rest = &code[i + "super::".len()..];
                let names: Vec<&str> = if let Some(group) = rest.strip_prefix('{') {
                    group.split('}').next().unwrap_or("").split(',').collect()
                } else {
                    vec![rest]
                };
                for n in names {
                    let ident: String = n
                        .trim()
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    let target = if modules.contains(&ident) {
                        ident
                    } else if let Some(m) = owner.get(&ident) {
                        m.clone()
                    } else {
                        continue;
                    };
                    if target != from && target != "mod" {
                        edges.push((from.clone(), target));
                    }
                }
            }
        }
    }
    (modules, edges)
}

/// Panics naming the first import circle among `modules` of `src/<folder>`.
fn assert_no_import_circle(folder: &str, modules: &[String], edges: &[(String, String)]) {
    // Depth-first search for a cycle.
    fn visit(
        folder: &str,
        m: &str,
        edges: &[(String, String)],
        state: &mut std::collections::BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) {
        match state.get(m) {
            Some(2) => return,
            Some(1) => panic!("import circle in {folder}/: {} -> {m}", path.join(" -> ")),
            _ => {}
        }
        state.insert(m.to_string(), 1);
        path.push(m.to_string());
        for (_, b) in edges.iter().filter(|(a, _)| a == m) {
            visit(folder, b, edges, state, path);
        }
        path.pop();
        state.insert(m.to_string(), 2);
    }
    let mut state = Default::default();
    for m in modules {
        visit(folder, m, edges, &mut state, &mut Vec::new());
    }
}

/// `learn/`'s modules import each other without a circle (settings and shared types
/// at the bottom, algorithms above): the graph of `super::<module>` references in
/// code (comments aside; names re-exported by `learn/mod.rs` resolved to their
/// module) has no cycle.
#[test]
fn learn_modules_import_without_a_circle() {
    let (modules, edges) = import_graph("learn", &[("Model", "model"), ("LearnError", "mod")]);
    assert!(
        edges.iter().any(|(a, b)| a == "train" && b == "settings"),
        "the scan should see train -> settings: {edges:?}"
    );
    assert_no_import_circle("learn", &modules, &edges);
}

/// `experiments/`'s modules import each other without a circle (configuration,
/// results and shared protocol steps at the bottom; validation, reproduction and
/// the report above), by the same scan as `learn/`'s.
#[test]
fn experiments_modules_import_without_a_circle() {
    let (modules, edges) = import_graph("experiments", &[]);
    assert!(
        edges.iter().any(|(a, b)| a == "report" && b == "figures"),
        "the scan should see report -> figures: {edges:?}"
    );
    assert_no_import_circle("experiments", &modules, &edges);
}

/// The longest a source file may be: past it, a file is split by concern.
const MAX_FILE_LINES: usize = 800;

/// No Rust file of the project — sources, tests, benches, examples, build scripts and
/// the firmware — is longer than [`MAX_FILE_LINES`]. Generated code (the runtime's test
/// fixtures, whose first line is the generator's `@generated` header) is not written
/// by hand and is exempt.
#[test]
fn no_source_file_over_800_lines() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = Vec::new();
    for dir in [
        "compiler/src",
        "compiler/tests",
        "compiler/benches",
        "src",
        "tests",
        "benches",
        "examples",
        "runtime/src",
        "runtime/tests",
        "generated/src",
        "firmware/src",
        "firmware/maps",
    ] {
        files.extend(sources(&root.join(dir)));
    }
    for script in ["generated/build.rs", "firmware/build.rs"] {
        let p = root.join(script);
        let text = std::fs::read_to_string(&p).expect("build script");
        files.push((p, text));
    }
    assert!(
        files.len() >= 150,
        "only {} source files found",
        files.len()
    );
    for part in [
        "src/experiments",
        "src/instance",
        "__private/engine",
        "tests/bad_inputs",
        "tests/mcu_qemu",
    ] {
        assert!(
            files
                .iter()
                .any(|(p, _)| p.to_string_lossy().contains(part)),
            "no sources found under {part}"
        );
    }
    let long: Vec<String> = files
        .iter()
        .filter(|(_, text)| !text.starts_with("// @generated"))
        .filter(|(_, text)| text.lines().count() > MAX_FILE_LINES)
        .map(|(p, text)| format!("{} ({} lines)", p.display(), text.lines().count()))
        .collect();
    assert!(
        long.is_empty(),
        "over {MAX_FILE_LINES} lines (split by concern): {long:?}"
    );
}
