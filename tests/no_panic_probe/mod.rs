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

/// One module of the no-panic probe: the demo floor compiled by one model family in
/// one form.
pub struct Form {
    /// The module's name in the probe.
    pub name: &'static str,
    /// The tree mixture (`tree_model.json`) instead of the GraphSPN (`model.json`).
    pub trees: bool,
    /// `f32` or `f64` code.
    pub precision: Precision,
    /// SIMD lane groups or scalar code.
    pub vectorisation: Vectorisation,
    /// Floats, or the fixed-point kernel (scalar `f32` only).
    pub arithmetic: Arithmetic,
}

/// A [`Form`], for the lists below.
const fn form(
    name: &'static str,
    trees: bool,
    precision: Precision,
    vectorisation: Vectorisation,
    arithmetic: Arithmetic,
) -> Form {
    Form {
        name,
        trees,
        precision,
        vectorisation,
        arithmetic,
    }
}

use Arithmetic::{Fixed, Float};
use Precision::{F32, F64};
use Vectorisation::{Scalar, Simd};

/// The forms checked on the host: SIMD lane groups (the form `Builder` picks for
/// x86-64 and AArch64) and scalar code, `f32` and `f64`, both families, and the
/// fixed-point kernels of both.
pub const HOST_FORMS: &[Form] = &[
    form("m32", false, F32, Simd, Float),
    form("m64", false, F64, Simd, Float),
    form("s32", false, F32, Scalar, Float),
    form("t32", true, F32, Simd, Float),
    form("t64", true, F64, Simd, Float),
    form("v32", true, F32, Scalar, Float),
    form("x32", false, F32, Scalar, Fixed),
    form("y32", true, F32, Scalar, Fixed),
];

/// The forms checked for a 32-bit microcontroller: what `Builder` emits for one
/// (scalar code; the fixed-point kernels on parts without an FPU), in `f32` and `f64`,
/// both families. SIMD forms, which no microcontroller target gets unless asked for,
/// are left to the host check: built for Cortex-M4F, the four SIMD forms took about
/// 270 s of the 298 s this check took with them (these six: 51 s).
pub const MCU_FORMS: &[Form] = &[
    form("s32", false, F32, Scalar, Float),
    form("s64", false, F64, Scalar, Float),
    form("v32", true, F32, Scalar, Float),
    form("v64", true, F64, Scalar, Float),
    form("x32", false, F32, Scalar, Fixed),
    form("y32", true, F32, Scalar, Fixed),
];

/// A `#![no_std]`, `#![no_main]` binary without an allocator, linked with `panic =
/// "abort"` and fat LTO, that calls every entry point of the demo floor's modules in
/// the given `forms` (checked, unchecked, through `CompiledMap` and the streaming
/// state) on opaque inputs. Its panic handler calls a symbol that is defined nowhere,
/// so the binary links only if the optimiser removed every path to a panic: this
/// proves that the generated code and the runtime helpers it calls cannot panic, need
/// neither `std` nor `alloc` (either would bring a second `panic_impl` or an allocator
/// the binary lacks), and build for a bare-metal-style target. `target`: a Rust target
/// triple to build for (a bare-metal one such as `thumbv7em-none-eabihf`), or `None`
/// for the host (Linux).
pub fn link_check(target: Option<&str>, forms: &[Form]) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("src")).unwrap();
    let (mut mods, mut calls) = (String::new(), String::new());
    for f in forms {
        let model = if f.trees {
            "tree_model.json"
        } else {
            "model.json"
        };
        let src = demo_builder(model, f.precision, f.vectorisation)
            .arithmetic(f.arithmetic)
            .generate()
            .unwrap();
        std::fs::write(dir.path().join(format!("src/{}.rs", f.name)), src).unwrap();
        mods += &format!(
            "#[cfg(not(panic_control))]\nmod {0} {{ include!(\"{0}.rs\"); }}\n",
            f.name
        );
        calls += &format!("        exercise!({});\n", f.name);
    }
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
    let main = NO_PANIC_PROBE
        .replace("MODULES\n", &mods)
        .replace("        CALLS\n", &calls);
    std::fs::write(dir.path().join("src/main.rs"), main).unwrap();
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

/// `src/main.rs` of the probe binary: `MODULES` becomes one `mod` line per form (left
/// out by the control build), `CALLS` one `exercise!` line per form.
const NO_PANIC_PROBE: &str = r#"
#![no_std]
#![no_main]

use core::hint::black_box;
use graphspn_runtime::CompiledMap;

MODULES

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
        CALLS
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
