//! What the command-line tests share: the binary, the demo inputs, a run that must
//! succeed.

use std::path::PathBuf;
use std::process::Command;

/// The `graphspn` binary of this build.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_graphspn"))
}

/// A file of the committed demo inputs (`generated/demo/`).
#[allow(dead_code)] // not every test crate reads the demo inputs
pub fn demo(file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("generated/demo")
        .join(file)
}

/// Runs `cmd`, fails the test with its standard error unless it succeeds, and returns
/// its standard output.
pub fn run_ok(cmd: &mut Command) -> String {
    let out = cmd.output().expect("graphspn runs");
    assert!(
        out.status.success(),
        "graphspn failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8 output")
}

/// Runs `cmd`, fails the test unless it fails, and returns its standard error (the
/// message to check).
#[allow(dead_code)] // not every test crate checks refusals
pub fn run_refused(cmd: &mut Command) -> String {
    let out = cmd.output().expect("graphspn runs");
    assert!(
        !out.status.success(),
        "graphspn succeeded where it should refuse: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}
