//! Temporary crates of generated code, built by the differential tests.

use std::path::Path;

/// Copies the workspace's `.cargo/config.toml` (at `workspace/.cargo/`: x86-64-v3
/// code on x86-64 hosts) into the temporary crate at `dir`, which lives outside the
/// workspace, so its generated modules build as the workspace's own do. Without it
/// they build for the SSE2 baseline, whose `wide` vectors LLVM takes about 3x longer
/// to optimise (the demo floor's SIMD module: 79 s against 26 s at opt-level 1).
/// Nothing is copied when the workspace has no such file (a user who deleted it for
/// an older CPU).
pub fn use_workspace_cargo_config(workspace: &Path, dir: &Path) {
    let config = workspace.join(".cargo/config.toml");
    if config.is_file() {
        std::fs::create_dir_all(dir.join(".cargo")).unwrap();
        std::fs::copy(&config, dir.join(".cargo/config.toml")).unwrap();
    }
}
