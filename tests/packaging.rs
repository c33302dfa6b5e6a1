//! What a user gets from the published crates, and what a firmware crate set up as
//! the README says builds with:
//!
//! - `cargo package` of graphspn-runtime and graphspn-compiler (offline, no
//!   verification build: a fraction of a second) holds the sources, every
//!   repository document the sources link (`docs/*.md`) and every file they
//!   `include_str!`, the README and both licence texts, and nothing else: no tests,
//!   benchmarks or data, which need the repository;
//! - the licence files the workspace declares exist with the standard texts, and no
//!   placeholder repository URL is declared;
//! - `firmware/Cargo.toml` keeps the build-script profile the README recommends
//!   (none: Cargo's defaults), and the README still recommends it.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn read(p: &str) -> String {
    std::fs::read_to_string(repo(p)).unwrap_or_else(|e| panic!("{p}: {e}"))
}

/// Every `.rs` file under `dir`.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Packages `crates` into a temporary folder; returns it and each crate's file.
fn package(crates: &[&str]) -> (tempfile::TempDir, Vec<PathBuf>) {
    let target = tempfile::tempdir().unwrap();
    let mut cmd = Command::new(env!("CARGO"));
    cmd.current_dir(repo(""))
        .args([
            "package",
            "--offline",
            "--no-verify",
            "--allow-dirty",
            "--quiet",
        ])
        .arg("--target-dir")
        .arg(target.path());
    for c in crates {
        cmd.args(["-p", c]);
    }
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "cargo package failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let files = crates
        .iter()
        .map(|c| {
            let version = env!("CARGO_PKG_VERSION");
            target.path().join(format!("package/{c}-{version}.crate"))
        })
        .collect();
    (target, files)
}

/// The files of a `.crate` (paths inside the crate's folder).
fn listing(krate: &Path) -> BTreeSet<String> {
    let out = Command::new("tar").arg("tzf").arg(krate).output().unwrap();
    assert!(out.status.success(), "tar tzf {}", krate.display());
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .filter(|l| !l.ends_with('/'))
        .map(|l| {
            l.split_once('/')
                .expect("crate-version/ prefix")
                .1
                .to_string()
        })
        .collect()
}

/// One file of a `.crate`.
fn extract(krate: &Path, name: &str) -> String {
    let stem = krate.file_stem().unwrap().to_string_lossy();
    let out = Command::new("tar")
        .arg("xzf")
        .arg(krate)
        .arg("-O")
        .arg(format!("{stem}/{name}"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{name} in {}", krate.display());
    String::from_utf8(out.stdout).unwrap()
}

/// The repository documents `docs/NAME.md` the crate's sources mention, and the
/// files they include (crate-relative paths).
fn linked(crate_dir: &str) -> BTreeSet<String> {
    let dir = repo(crate_dir);
    let mut out = BTreeSet::new();
    for f in sources(&dir.join("src")) {
        let text = std::fs::read_to_string(&f).unwrap();
        let mut rest = text.as_str();
        while let Some(i) = rest.find("docs/") {
            let tail = &rest[i..];
            let end = tail
                .find(|c: char| !(c.is_ascii_alphanumeric() || "/._-".contains(c)))
                .unwrap_or(tail.len());
            let name = tail[..end].trim_end_matches('.');
            if name.ends_with(".md") {
                out.insert(name.to_string());
            }
            rest = &tail[end.max(1)..];
        }
        for mac in ["include_str!(\"", "include_bytes!(\""] {
            for (i, _) in text.match_indices(mac) {
                let arg = &text[i + mac.len()..];
                let arg = &arg[..arg.find('"').unwrap()];
                let path = f.parent().unwrap().join(arg);
                let path = std::fs::canonicalize(&path)
                    .unwrap_or_else(|e| panic!("{}: {arg}: {e}", f.display()));
                let rel = path
                    .strip_prefix(std::fs::canonicalize(&dir).unwrap())
                    .unwrap_or_else(|_| {
                        panic!("{}: includes {arg}, outside the crate", f.display())
                    });
                out.insert(rel.to_string_lossy().into_owned());
            }
        }
    }
    out
}

#[test]
fn the_published_crates_hold_their_docs_and_licences_and_no_test_data() {
    let crates = [
        ("graphspn-runtime", "runtime"),
        ("graphspn-compiler", "compiler"),
    ];
    let (_dir, files) = package(&crates.map(|c| c.0));
    for ((name, dir), krate) in crates.iter().zip(&files) {
        let list = listing(krate);
        for want in [
            "Cargo.toml",
            "README.md",
            "LICENSE-MIT",
            "LICENSE-APACHE",
            "src/lib.rs",
        ] {
            assert!(
                list.contains(want),
                "{name}: the package lacks {want}: {list:?}"
            );
        }
        let links = linked(dir);
        if *name == "graphspn-compiler" {
            assert!(links.contains("docs/FORMATS.md"), "{links:?}");
        }
        for l in &links {
            assert!(
                list.contains(l),
                "{name}: its sources link {l}, not packaged"
            );
        }
        for f in &list {
            let allowed = f.starts_with("src/")
                || links.contains(f)
                || [
                    "Cargo.toml",
                    "Cargo.toml.orig",
                    "Cargo.lock",
                    ".cargo_vcs_info.json",
                    "README.md",
                    "LICENSE-MIT",
                    "LICENSE-APACHE",
                ]
                .contains(&f.as_str());
            assert!(
                allowed,
                "{name}: the package holds {f}, which its users do not need"
            );
        }
        for licence in ["LICENSE-MIT", "LICENSE-APACHE"] {
            assert_eq!(
                extract(krate, licence),
                read(licence),
                "{name}: {licence} is not the repository's"
            );
        }
        let size = std::fs::metadata(krate).unwrap().len();
        assert!(size < 2 << 20, "{name}: {size} bytes compressed");
        let manifest = extract(krate, "Cargo.toml");
        assert!(
            manifest.contains("license = \"MIT OR Apache-2.0\""),
            "{name}: {manifest}"
        );
        assert!(
            !manifest.contains("example.invalid"),
            "{name}: placeholder URL"
        );
    }
}

#[test]
fn the_declared_licences_ship_and_no_placeholder_url_is_declared() {
    let workspace = read("Cargo.toml");
    assert!(workspace.contains("license = \"MIT OR Apache-2.0\""));
    for manifest in [
        "Cargo.toml",
        "compiler/Cargo.toml",
        "runtime/Cargo.toml",
        "generated/Cargo.toml",
        "firmware/Cargo.toml",
    ] {
        let text = read(manifest);
        for bad in ["example.invalid", "example.com", "example.org"] {
            assert!(!text.contains(bad), "{manifest}: placeholder URL {bad}");
        }
    }
    let mit = read("LICENSE-MIT");
    assert!(mit.starts_with("MIT License") && mit.contains("Copyright (c) the graphspn authors"));
    assert!(mit.contains("THE SOFTWARE IS PROVIDED \"AS IS\""));
    let apache = read("LICENSE-APACHE");
    assert!(apache.contains("Apache License") && apache.contains("Version 2.0, January 2004"));
    assert!(apache.contains("END OF TERMS AND CONDITIONS"));
}

/// The `[section]` headers of a TOML file.
fn toml_sections(text: &str) -> Vec<String> {
    text.lines()
        .map(|l| l.split('#').next().unwrap().trim())
        .filter(|l| l.starts_with('['))
        .map(str::to_string)
        .collect()
}

/// A firmware crate gives its build script no profile of its own (README,
/// "Firmware", measured by `scripts/firmware-build-time.sh`): no build-override,
/// which optimises every build-time crate (syn, serde_derive, ...: 2.9x the clean
/// build's CPU time), and no override on the generator either (19-25 s more per
/// clean build for 0.5-3 s less code generation).
#[test]
fn the_firmware_keeps_the_recommended_build_script_profile() {
    for manifest in ["firmware/Cargo.toml", "firmware/maps/Cargo.toml"] {
        for s in toml_sections(&read(manifest)) {
            assert!(
                !s.contains("build-override") && !s.contains("package.graphspn-compiler"),
                "{manifest}: {s}: the README's Firmware section recommends no profile for the build script"
            );
        }
    }
    let readme = read("README.md");
    let firmware = readme
        .split("\n## Firmware\n")
        .nth(1)
        .expect("README has a Firmware section");
    let firmware = firmware.split("\n## ").next().unwrap();
    assert!(
        firmware.contains("Give the build script no profile of its own")
            && firmware.contains("| **none** (recommended) |"),
        "README's Firmware section no longer recommends building without a build-script profile"
    );
    // No TOML block of the README sets one.
    for block in readme.split("```toml\n").skip(1) {
        let block = block.split("```").next().unwrap();
        for s in toml_sections(block) {
            assert!(
                !s.contains("build-override") && !s.contains("package.graphspn-compiler"),
                "README shows {s} in a TOML block"
            );
        }
    }
}
