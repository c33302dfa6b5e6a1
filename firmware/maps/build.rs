//! Compiles the repository's demo maps with the demo models, exactly as
//! `generated/build.rs` does (the GraphSPN: f32, seed 0, 5 decompositions; the tree
//! mixture: f32, trees seeded with 0): the firmware's results can then be compared
//! with the host build of `graphspn-generated`.

use std::path::PathBuf;

use graphspn_compiler::codegen::{Builder, Vectorisation};

/// `(module name, map file under ../../generated/demo/)`; each map is compiled with
/// both models (the tree mixture's module is `<name>_trees`).
const MAPS: &[(&str, &str)] = &[
    ("demo_floor", "floor.json"),
    ("saarbrucken_seq2_night1", "saarbrucken_seq2_night1.json"),
];

fn main() {
    let dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let demo = dir.join("../../generated/demo");
    for &(module, file) in MAPS {
        // `run()` writes $OUT_DIR/<module>.rs (only if changed) and prints the
        // rerun-if-changed lines for the model and the map.
        // Scalar code (one component per call) on every target, the host build
        // included: the MCUs get it anyway (`Builder` picks it for targets without
        // float SIMD), and the host build the tests compare with then runs exactly the
        // same operations (Rust never fuses a multiply and an add on its own). Targets
        // without an FPU (Cortex-M3, RV32IMAC) get `Builder`'s default for them, the
        // fixed-point kernel.
        if let Err(e) = Builder::new(demo.join("model.json"), demo.join(file))
            .vectorisation(Vectorisation::Scalar)
            .seed(0)
            .count(5)
            .module_name(module)
            .run()
        {
            panic!("graphspn-firmware-maps: {e}");
        }
        // The tree mixture: its number of trees comes from the model file.
        if let Err(e) = Builder::new(demo.join("tree_model.json"), demo.join(file))
            .vectorisation(Vectorisation::Scalar)
            .seed(0)
            .module_name(format!("{module}_trees"))
            .run()
        {
            panic!("graphspn-firmware-maps: {e}");
        }
    }
}
