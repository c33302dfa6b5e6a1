//! Compiles the demo maps shipped in `demo/` into `$OUT_DIR` (filled in by the compiler issue).
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
}
