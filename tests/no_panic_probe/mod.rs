#![allow(dead_code)]
//! The no-panic link check shared by `generated_no_std.rs` (host) and
//! `tests/mcu_qemu/` (Cortex-M4F): see [`link_check`].

use std::path::PathBuf;
use std::process::Command;

use graphspn::codegen::{Arithmetic, Builder, Precision, Vectorisation};

fn demo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("generated/demo")
}

/// The demo floor's module, generated with the inputs of `generated/build.rs` (SIMD
/// lane groups, the host's form).
pub fn demo_source(precision: Precision) -> String {
    demo_source_for(precision, Vectorisation::Simd)
}

/// [`demo_source`] in the given form (scalar: the microcontroller form).
pub fn demo_source_for(precision: Precision, v: Vectorisation) -> String {
    demo_model_source("model.json", precision, v)
}

/// The demo floor's tree-mixture module (`tree_model.json`, as `generated/build.rs`
/// compiles it) in the given form.
pub fn demo_tree_source_for(precision: Precision, v: Vectorisation) -> String {
    demo_model_source("tree_model.json", precision, v)
}

/// The demo floor compiled with the model file `model` in the given form.
fn demo_model_source(model: &str, precision: Precision, v: Vectorisation) -> String {
    demo_builder(model, precision, v).generate().unwrap()
}

fn demo_builder(model: &str, precision: Precision, v: Vectorisation) -> Builder {
    Builder::new(demo().join(model), demo().join("floor.json"))
        .seed(0)
        .count(5)
        .precision(precision)
        .vectorisation(v)
}

/// The demo floor's GraphSPN with the fixed-point kernel (targets without an FPU).
pub fn demo_fixed_source() -> String {
    demo_builder("model.json", Precision::F32, Vectorisation::Scalar)
        .arithmetic(Arithmetic::Fixed)
        .generate()
        .unwrap()
}

/// A `#![no_std]`, `#![no_main]` binary without an allocator, linked with `panic =
/// "abort"` and fat LTO, that calls every entry point of the generated demo modules of
/// both model families (GraphSPN and tree mixture; f32 and f64, SIMD and scalar, the
/// GraphSPN also with the fixed-point kernel: checked, unchecked, through
/// `CompiledMap` and the streaming state) on opaque inputs. Its panic
/// handler calls a symbol that is defined nowhere, so the binary links only if the
/// optimiser removed every path to a panic: this proves that the generated code and
/// the runtime helpers it calls cannot panic, need neither `std` nor `alloc` (either
/// would bring a second `panic_impl` or an allocator the binary lacks), and build
/// for a bare-metal-style target. `target`: a Rust target triple to build for (a
/// bare-metal one such as `thumbv7em-none-eabihf`), or `None` for the host (Linux).
pub fn link_check(target: Option<&str>) {
    let dir = tempfile::tempdir().unwrap();
    for (module, precision, v, trees) in [
        ("m32", Precision::F32, Vectorisation::Simd, false),
        ("m64", Precision::F64, Vectorisation::Simd, false),
        ("s32", Precision::F32, Vectorisation::Scalar, false),
        ("t32", Precision::F32, Vectorisation::Simd, true),
        ("t64", Precision::F64, Vectorisation::Simd, true),
        ("v32", Precision::F32, Vectorisation::Scalar, true),
    ] {
        let src = if trees {
            demo_tree_source_for(precision, v)
        } else {
            demo_source_for(precision, v)
        };
        std::fs::create_dir_all(dir.path().join("src")).unwrap();
        std::fs::write(dir.path().join(format!("src/{module}.rs")), src).unwrap();
    }
    std::fs::write(dir.path().join("src/x32.rs"), demo_fixed_source()).unwrap();
    let runtime = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("runtime");
    std::fs::write(
        dir.path().join("Cargo.toml"),
        format!(
            "[package]\nname = \"no_panic_probe\"\nversion = \"0.0.0\"\nedition = \"2024\"\n\n\
             [dependencies]\ngraphspn-runtime = {{ path = {:?} }}\n\n\
             [profile.release]\npanic = \"abort\"\nlto = \"fat\"\ncodegen-units = 1\n\n\
             [lints.rust]\nunexpected_cfgs = {{ level = \"warn\", check-cfg = [\"cfg(panic_control)\"] }}\n\n\
             [workspace]\n",
            runtime.display().to_string()
        ),
    )
    .unwrap();
    std::fs::write(dir.path().join("src/main.rs"), NO_PANIC_PROBE).unwrap();
    let link = |extra_cfg: Option<&str>| {
        let mut cmd = Command::new(env!("CARGO"));
        cmd.args(["rustc", "--release", "--offline", "--quiet"]);
        if let Some(t) = target {
            cmd.args(["--target", t, "--"]);
        } else {
            // No C start files (the probe has its own `_start`); libc only for the
            // `memcpy`/`memset` that bare-metal targets get from `compiler_builtins`.
            cmd.args(["--", "-C", "link-arg=-nostartfiles", "-C", "link-arg=-lc"]);
        }
        cmd.env(
            "CARGO_TARGET_DIR",
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/no-panic-probe"),
        )
        .current_dir(dir.path());
        if let Some(cfg) = extra_cfg {
            cmd.args(["--cfg", cfg]);
        }
        cmd.output().unwrap()
    };
    // Control: a deliberate out-of-bounds index must make the link fail on the
    // handler's symbol, or the probe proves nothing on this toolchain.
    let control = link(Some("panic_control"));
    let stderr = String::from_utf8_lossy(&control.stderr);
    assert!(
        !control.status.success() && stderr.contains(UNDEFINED_ON_PANIC),
        "the control build with a panic path did not fail to link on {UNDEFINED_ON_PANIC}:\n{stderr}"
    );
    let probe = link(None);
    let stderr = String::from_utf8_lossy(&probe.stderr);
    assert!(
        probe.status.success(),
        "the generated code keeps a path to a panic, or needs std/alloc:\n{stderr}"
    );
}

/// The symbol the probe's panic handler calls; defined nowhere.
const UNDEFINED_ON_PANIC: &str = "graphspn_generated_code_reaches_a_panic";

/// `src/main.rs` of the probe binary (modules `m32`, `m64`, `s32`: the demo floor's
/// GraphSPN in f32 and f64 SIMD form and f32 scalar form; `t32`, `t64`, `v32`: its tree
/// mixture in the same forms; `x32`: the GraphSPN with the fixed-point kernel).
const NO_PANIC_PROBE: &str = r#"
#![no_std]
#![no_main]

use core::hint::black_box;
use graphspn_runtime::CompiledMap;

#[cfg(not(panic_control))]
mod m32 { include!("m32.rs"); }
#[cfg(not(panic_control))]
mod m64 { include!("m64.rs"); }
#[cfg(not(panic_control))]
mod s32 { include!("s32.rs"); }
#[cfg(not(panic_control))]
mod t32 { include!("t32.rs"); }
#[cfg(not(panic_control))]
mod t64 { include!("t64.rs"); }
#[cfg(not(panic_control))]
mod v32 { include!("v32.rs"); }
#[cfg(not(panic_control))]
mod x32 { include!("x32.rs"); }

unsafe extern "C" {
    /// Defined nowhere: the binary links only if no path reaches the panic handler.
    fn graphspn_generated_code_reaches_a_panic() -> !;
}

#[panic_handler]
fn on_panic(_: &core::panic::PanicInfo) -> ! {
    // SAFETY: never runs; the symbol does not exist, so a reachable call fails to link.
    unsafe { graphspn_generated_code_reaches_a_panic() }
}

/// Calls every entry point on opaque inputs (the optimiser knows neither the values
/// nor the slice lengths) and keeps every result alive.
macro_rules! exercise {
    ($m:ident) => {{
        use $m::{Evidence, Labels, Marginals, NUM_CLASSES, NUM_PLACES};
        static EVIDENCE: Evidence = [[0.5; NUM_CLASSES]; NUM_PLACES];
        static LABELS: Labels = [$m::UNKNOWN; NUM_PLACES];
        let e: &Evidence = black_box(&EVIDENCE);
        let mut labels: Labels = *black_box(&LABELS);
        let mut out: Marginals = [[0.0; NUM_CLASSES]; NUM_PLACES];
        let _ = black_box($m::log_likelihood(e));
        let _ = black_box($m::log_likelihood_unchecked(e));
        let _ = black_box($m::marginals(e, &mut out));
        let _ = black_box($m::marginals_unchecked(e, &mut out));
        let _ = black_box($m::mpe(e, &mut labels));
        let _ = black_box($m::mpe_unchecked(e, &mut labels));
        let _ = black_box($m::labelled_log_likelihood(&labels, e));
        let _ = black_box($m::labelled_log_likelihood_unchecked(&labels, e));
        let n = black_box(NUM_PLACES);
        let es = e.get(..n).unwrap_or(&[]);
        let _ = black_box(<$m::Map as CompiledMap>::log_likelihood(es));
        let _ = black_box(<$m::Map as CompiledMap>::marginals(es, out.get_mut(..n).unwrap_or(&mut [])));
        let _ = black_box(<$m::Map as CompiledMap>::mpe(es, labels.get_mut(..n).unwrap_or(&mut [])));
        let _ = black_box(<$m::Map as CompiledMap>::labelled_log_likelihood(labels.get(..n).unwrap_or(&[]), es));
        // The streaming state: every update and query, at an opaque place.
        let mut s = $m::State::new();
        let p = black_box(3usize);
        let row = black_box(EVIDENCE[0]);
        let _ = black_box(s.set_evidence(p, &row));
        let _ = black_box(s.observe(p, &row));
        let _ = black_box(s.clear_evidence(p));
        let _ = black_box(s.set_all(e));
        let _ = black_box(s.log_likelihood());
        let _ = black_box(s.marginals(&mut out));
        let mut one = [0.0; NUM_CLASSES];
        let _ = black_box(s.marginal(p, &mut one));
        let _ = black_box(s.mpe(&mut labels));
        let _ = black_box(s.labelled_log_likelihood(&labels));
        let _ = black_box(<$m::Map as CompiledMap>::set_evidence(&mut s, p, &row));
        let _ = black_box(<$m::Map as CompiledMap>::state_marginals(&mut s, out.get_mut(..n).unwrap_or(&mut [])));
        black_box((&out, &labels, &one, &s));
    }};
}

#[unsafe(no_mangle)]
pub extern "C" fn _start() -> ! {
    #[cfg(not(panic_control))]
    {
        exercise!(m32);
        exercise!(m64);
        exercise!(s32);
        exercise!(t32);
        exercise!(t64);
        exercise!(v32);
        exercise!(x32);
    }
    #[cfg(panic_control)]
    {
        let a = black_box([1u8; 4]);
        black_box(a[black_box(7usize)]);
    }
    loop {
        core::hint::spin_loop();
    }
}
"#;
