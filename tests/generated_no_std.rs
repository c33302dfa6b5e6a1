//! The generated crate is `no_std` without `alloc`, and the generated code has no
//! `unsafe` and no panicking path. `graphspn-generated` is `#![no_std]` and
//! `#![forbid(unsafe_code)]`, so std or alloc could only come in through an
//! `extern crate` in the included, generated text: one test regenerates that text
//! (same inputs as `generated/build.rs`, f32 and f64, GraphSPN and tree mixture) and
//! scans it; another links it into a `no_std` binary whose panic handler calls an
//! undefined symbol.

mod no_panic_probe;

use std::path::PathBuf;

use graphspn::codegen::Vectorisation;
use graphspn::codegen::{Builder, Precision, is_generated_file};
use no_panic_probe::{demo_source, demo_tree_source_for};

fn demo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("generated/demo")
}

#[test]
fn generated_crate_is_no_std_without_alloc_unsafe_or_panics() {
    let lib = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("generated/src/lib.rs"),
    )
    .unwrap();
    assert!(lib.contains("#![no_std]") && lib.contains("#![forbid(unsafe_code)]"));
    assert!(!lib.contains("extern crate"));
    let forms = [Precision::F32, Precision::F64].into_iter().flat_map(|p| {
        [
            (p, demo_source(p)),
            (p, demo_tree_source_for(p, Vectorisation::Simd)),
            (p, demo_tree_source_for(p, Vectorisation::Scalar)),
        ]
    });
    for (precision, src) in forms {
        assert!(is_generated_file(&src));
        let scalar = match precision {
            Precision::F32 => "pub type Evidence = [[f32; NUM_CLASSES]; NUM_PLACES];",
            Precision::F64 => "pub type Evidence = [[f64; NUM_CLASSES]; NUM_PLACES];",
        };
        assert!(src.contains(scalar), "{precision:?} evidence type");
        for banned in [
            "extern crate",
            "std::",
            "alloc::",
            "Vec<",
            "Box<",
            "unsafe",
            "panic!",
            "unwrap(",
            "expect(",
            "unreachable!",
            "todo!",
            "assert",
        ] {
            assert!(
                !src.contains(banned),
                "{precision:?}: generated code contains {banned:?}"
            );
        }
    }
}

#[test]
fn same_inputs_give_byte_identical_output() {
    let b = Builder::new(demo().join("model.json"), demo().join("floor.json"))
        .seed(3)
        .count(4);
    assert_eq!(b.generate().unwrap(), b.clone().generate().unwrap());
    let t = Builder::new(demo().join("tree_model.json"), demo().join("floor.json"))
        .seed(3)
        .count(3);
    assert_eq!(t.generate().unwrap(), t.clone().generate().unwrap());
}

/// See [`no_panic_probe::link_check`], here with every form (SIMD included); the
/// Cortex-M4F build of the probe, with the forms a microcontroller gets, runs in
/// `tests/mcu_qemu/`.
#[cfg(all(target_os = "linux", target_arch = "x86_64"))]
#[test]
fn generated_code_links_without_std_alloc_or_any_panic_path() {
    no_panic_probe::link_check(None, no_panic_probe::HOST_FORMS);
}
