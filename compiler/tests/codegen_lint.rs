//! Source rules of the code generator (`compiler/src/codegen`), checked on its text:
//! - no Rust code is assembled as strings: every `format!` / `write!` / `writeln!` /
//!   `format_args!` / `push_str` is either an error message (`what: format!(..)`,
//!   `BadOption(format!(..))`) or marked `// lint: <why>` on the line above (the
//!   spelling of one numeric literal, the `@generated` comment line, a file name);
//! - the emitters use `quote!`;
//! - no function is longer than 100 lines.

use std::path::{Path, PathBuf};

fn codegen_files() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir)
            .expect("codegen folder")
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
    let mut out = vec![];
    walk(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("src/codegen"),
        &mut out,
    );
    assert!(out.len() >= 8, "codegen sources not found: {out:?}");
    out
}

const TEXT_MACROS: [&str; 5] = [
    "format!(",
    "write!(",
    "writeln!(",
    "format_args!(",
    "push_str(",
];
const ERROR_MESSAGES: [&str; 3] = ["what: format!(", "BadOption(format!(", "Internal(format!("];

#[test]
fn no_rust_code_assembled_as_strings() {
    let mut bad = vec![];
    for path in codegen_files() {
        let text = std::fs::read_to_string(&path).expect("read");
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
        "sparse.rs",
        "template.rs",
        "wiring/mod.rs",
        "wiring/api.rs",
        "wiring/state.rs",
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
    for path in codegen_files() {
        let text = std::fs::read_to_string(&path).expect("read");
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
