//! The firmware (`firmware/`) on emulated microcontrollers ([`MCUS`]): builds it
//! (release) for Cortex-M4F (`thumbv7em-none-eabihf`, QEMU `netduinoplus2`),
//! Cortex-M3 (`thumbv7m-none-eabi`, QEMU `netduino2`; no FPU: soft-float calls) and
//! RV32IMAC (`riscv32imac-unknown-none-elf`, QEMU `virt`; no FPU either), and for the
//! host at the x86-64 baseline (SSE2, no FMA); runs each (QEMU with `-icount
//! shift=0`, bounded time, the three side by side), parses the reports and checks, for
//! both maps compiled with both model families (GraphSPN and tree mixture) and all
//! four entry points:
//!
//! - every MCU build gives exactly the bits of the host's baseline build (same
//!   arithmetic: separate multiply and add, `libm` for exp/ln; hardware or
//!   soft-float, IEEE 754 single precision rounds alike);
//! - agreement with the host build of the same module in this process
//!   (`graphspn-generated`, built for x86-64-v3 by `.cargo/config.toml`: its `wide`
//!   vectors use fused multiply-adds, so its bits differ in the last places; the
//!   differences are printed) and with the interpreter, at the differential tests'
//!   tolerances (1e-4 relative for log-likelihoods and MPE values, 1e-4 absolute for
//!   marginals; the MPE labels must attain the interpreter's best value; tree
//!   mixtures against `TreeInstance`, the exact f64 reference);
//! - the streaming state's adversarial fusion sequence (hundreds of observations for one
//!   class, then more for another, then the first again) on the target: its
//!   log-likelihood is that of the product of every observation and the place's
//!   marginal that of an `f64` log-domain reference (no class underflows or locks);
//! - peak stack per call ≤ the bound below, statics + stack ≤ the 128 KiB of RAM;
//! - the tree mixture of the 230-place map: on every target every call ≤ 16 KiB of
//!   stack and `STATE_BYTES` ≤ 64 KiB; on Cortex-M4F `log_likelihood` ≤ 0.4 M
//!   instructions, `marginals` and `mpe` ≤ 1 M;
//! - the 230-place GraphSPN: on Cortex-M3 and RV32IMAC (the fixed-point kernel)
//!   `log_likelihood` ≤ 3 M instructions and `marginals` ≤ 10 M; on every target its
//!   streaming step with every marginal ≥ 10× cheaper than a stateless `marginals`;
//! - the instruction counter is exact to a few instructions on a loop of known size.
//!
//! The no-panic link check of `generated_no_std.rs` runs here for
//! `thumbv7em-none-eabihf`. Needs the Rust targets and QEMU: the tests run `bash
//! scripts/setup-mcu.sh` themselves, once per test process (idempotent and quiet;
//! it installs them on a fresh machine), and fail with its message if it fails. The
//! firmware builds into `target/firmware/`.

#[allow(dead_code)]
#[path = "../../firmware/src/evidence.rs"]
mod evidence;
#[path = "../no_panic_probe/mod.rs"]
mod no_panic_probe;

use std::io::Read;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use graphspn::codegen::{AnyInputs, Arithmetic, Builder};
use graphspn::instance::Instance;
use graphspn::interpreter::{Evaluator, Evidence};
use graphspn::treemix::TreeInstance;
use graphspn_generated::{
    demo_floor, demo_floor_trees, saarbrucken_seq2_night1, saarbrucken_seq2_night1_trees,
};
use graphspn_runtime::CompiledMap;

#[macro_use]
mod checks;
mod firmware;
mod report;

use checks::*;
use firmware::*;
use report::*;

/// RAM of the firmware's linker scripts, bytes: `memory.x` (the STM32F205's SRAM as
/// QEMU's `netduino2` models it, and the STM32F405's main SRAM, of which
/// `netduinoplus2` models 192 KiB) and `rv32.x`.
pub const RAM_BYTES: usize = 128 * 1024;
/// Longest a firmware run may take under QEMU (RISC-V and Cortex-M3 take about
/// 10 s, Cortex-M4F 2 s).
pub const QEMU_TIMEOUT: Duration = Duration::from_secs(300);
/// Relative tolerance of log-likelihoods and MPE values, absolute of marginals.
pub const TOL: f64 = 1e-4;

/// An MCU target of the firmware and how QEMU runs it (the board
/// `scripts/mcu-run.sh` chooses).
pub struct Mcu {
    pub target: &'static str,
    /// The emulator and its machine (`-M`).
    pub qemu: &'static str,
    pub machine: &'static str,
    /// Further arguments: firmware loading and where the output goes.
    pub args: &'static [&'static str],
}

/// Cortex-M output: semihosting to QEMU's stdout.
pub const SEMIHOSTING: &[&str] = &[
    "-semihosting-config",
    "enable=on,target=native",
    "-serial",
    "null",
];
/// Cortex-M4F: STM32F405 with FPU.
pub const M4F: Mcu = Mcu {
    target: "thumbv7em-none-eabihf",
    qemu: "qemu-system-arm",
    machine: "netduinoplus2",
    args: SEMIHOSTING,
};
/// Cortex-M3: STM32F205 without FPU (soft-float calls).
pub const M3: Mcu = Mcu {
    target: "thumbv7m-none-eabi",
    qemu: "qemu-system-arm",
    machine: "netduino2",
    args: SEMIHOSTING,
};
/// RV32IMAC (no FPU either): output on the UART.
pub const RV32: Mcu = Mcu {
    target: "riscv32imac-unknown-none-elf",
    qemu: "qemu-system-riscv32",
    machine: "virt",
    args: &["-bios", "none", "-serial", "stdio"],
};
/// Every MCU target the firmware is built for and checked on.
pub const MCUS: [&Mcu; 3] = [&M4F, &M3, &RV32];

pub const HOST: &str = "x86_64-unknown-linux-gnu";
pub const SETUP: &str = "bash scripts/setup-mcu.sh";

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Where the firmware is built (shared with `scripts/mcu-bench.sh`).
pub fn target_dir() -> PathBuf {
    root().join("target/firmware")
}

#[test]
fn firmware_on_qemu_matches_host_and_interpreter_within_stack_bounds() {
    let start = Instant::now();
    // Fail early, naming the setup script, if QEMU is missing.
    for mcu in MCUS {
        drop(qemu(mcu.qemu));
    }
    // With the host build of the same scalar float code (Rust never fuses a multiply
    // and an add, so the workspace's x86-64-v3 flags change no result bit); targets
    // without an FPU get the fixed-point kernel (`Builder`'s default for them) and are
    // compared with each other instead. One cargo run for all four: the build-time
    // crates are resolved once (cortex-m-rt's macros add a `syn` feature, so a host
    // build on its own compiled syn, serde and graphspn-compiler a second time).
    let [m4f, m3, rv32] = MCUS.map(|m| m.target);
    build_firmware(&[m4f, m3, rv32, HOST], "release", None);
    let built = start.elapsed();
    let baseline = parse(&run_bounded(
        Command::new(elf(HOST, "release")),
        "host baseline firmware",
    ));
    for target in MCUS.map(|m| m.target) {
        let data = section_bytes(&elf(target, "release"), ".data");
        assert!(
            data <= 1024,
            "{target}: {data} bytes of .data: the firmware's states and buffers (all zero at start) belong in .bss"
        );
    }
    // Side by side: each run is single-threaded, and `-icount` counts are exact
    // whatever else the machine runs.
    let reports = std::thread::scope(|s| {
        MCUS.map(|mcu| s.spawn(move || (mcu.target, run_qemu(mcu, "release"))))
            .map(|run| run.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
    });
    for (target, r) in &reports {
        let smallest = r
            .maps
            .iter()
            .filter_map(|m| m.state_bytes)
            .min()
            .unwrap_or(0);
        assert_no_state_image(&elf(target, "release"), smallest, target);
        check_state_bytes(target, r);
    }
    let hosts = [
        host_answers!(demo_floor, 0),
        host_answers!(saarbrucken_seq2_night1, 1),
        host_answers!(demo_floor_trees, 2),
        host_answers!(saarbrucken_seq2_night1_trees, 3),
    ];
    let fusions = [
        fusion_reference::<demo_floor::Map>(),
        fusion_reference::<saarbrucken_seq2_night1::Map>(),
        fusion_reference::<demo_floor_trees::Map>(),
        fusion_reference::<saarbrucken_seq2_night1_trees::Map>(),
    ];
    let streams = [
        host_stream!(demo_floor, 0),
        host_stream!(saarbrucken_seq2_night1, 1),
        host_stream!(demo_floor_trees, 2),
        host_stream!(saarbrucken_seq2_night1_trees, 3),
    ];
    let bounds = [
        "demo_floor",
        "saarbrucken_seq2_night1",
        "demo_floor_trees",
        "saarbrucken_seq2_night1_trees",
    ]
    .map(stack_bounds);
    let fixed_reference = reports.iter().find(|(t, _)| is_fixed(t));
    for (target, r) in &reports {
        let (loop_n, measured, _) = r.calibration;
        assert!(
            measured.abs_diff(loop_n) <= 16,
            "{target}: the counter gives {measured} instructions for a loop of {loop_n}"
        );
        assert_eq!(r.maps.len(), 4, "{target}: maps");
        match fixed_reference {
            Some((first, reference)) if is_fixed(target) => assert_eq!(
                results(r),
                results(reference),
                "{target}: results differ from {first}'s (both use the fixed-point kernel)"
            ),
            _ => assert_eq!(
                results(r),
                results(&baseline),
                "{target}: results differ from the host's x86-64 baseline build"
            ),
        }
        let mut peak = 0;
        for (i, (m, host)) in r.maps.iter().zip(&hosts).enumerate() {
            let differ = check_map(target, m, i as u64, host);
            let numbers = 4 + m.places * m.classes + m.places;
            eprintln!(
                "{target} {}: {differ} of {numbers} numbers differ in bits from the x86-64-v3 host build (FMA)",
                m.name
            );
            check_stream(target, m, &streams[i]);
            check_fusion(target, m, &fusions[i]);
            let full = m.calls[1].instructions;
            let (all, one) = (
                median_instructions(m, "observe_marginals"),
                median_instructions(m, "observe_marginal"),
            );
            eprintln!(
                "{target} {}: streaming step (median) observe + marginals {all} instructions ({:.1}x fewer than stateless marginals, {full}), observe + marginal(place) {one} ({:.1}x)",
                m.name,
                full as f64 / all as f64,
                full as f64 / one as f64
            );
            // The 230-place GraphSPN's streaming step with every marginal costs at least
            // 10x less than a stateless `marginals` on every target: without an FPU its
            // mix of the cached rows runs in Q1.31 integers (in soft-float it was
            // 4.5-7.1x). The 80-place demo floor gains less (9-14x: a smaller map
            // leaves less for the cache to save).
            if m.name == "saarbrucken_seq2_night1" {
                assert!(
                    all * 10 <= full,
                    "{target} {}: streaming step {all} vs stateless marginals {full}",
                    m.name
                );
            }
            // The state's full passes run the stateless ones on the fused evidence:
            // their stack counts against the state's bound too.
            let names: Vec<&str> = m.state_calls.iter().map(|c| c.name.as_str()).collect();
            assert_eq!(
                names,
                ["mpe", "labelled_log_likelihood"],
                "{target} {}",
                m.name
            );
            for c in &m.state_calls {
                assert!(c.value.is_ok(), "{target} {} state {c:?}", m.name);
            }
            let stream = m.stream.iter().map(|(c, _)| c);
            let stream = stream.chain(&m.fusion).chain(&m.state_calls);
            let stream = stream.map(|c| (c, bounds[i][4]));
            for (call, bound) in m.calls.iter().zip(bounds[i]).chain(stream) {
                eprintln!(
                    "{target} {} {}: {} instructions, {} bytes of stack (bound {bound})",
                    m.name, call.name, call.instructions, call.stack
                );
                assert!(call.instructions > 0 && call.stack > 0, "{target} {call:?}");
                assert!(
                    call.stack <= bound,
                    "{target} {} {}: peak stack {} > bound {bound}",
                    m.name,
                    call.name,
                    call.stack
                );
                peak = peak.max(call.stack);
            }
        }
        assert!(
            r.static_ram + peak <= RAM_BYTES,
            "{target}: statics {} + peak stack {peak} exceed {RAM_BYTES} bytes of RAM",
            r.static_ram
        );
        check_tree_acceptance(target, r);
        check_fixed_point_goals(target, r);
    }
    eprintln!(
        "firmware builds {:.1} s, all runs and checks {:.1} s",
        built.as_secs_f64(),
        (start.elapsed() - built).as_secs_f64()
    );
}

/// Crates a firmware's build must not compile: host-only parts of graphspn-compiler
/// (parallelism, progress bars) and the command-line tool's and tests' crates.
const HOST_ONLY_CRATES: &[&str] = &[
    "rayon",
    "rayon-core",
    "indicatif",
    "console",
    "clap",
    "anyhow",
    "criterion",
    "proptest",
    "roxmltree",
    "tempfile",
    "insta",
];

/// The firmware's dependency tree (normal and build dependencies, Cortex-M4F) has
/// none of [`HOST_ONLY_CRATES`]: its build.rs uses graphspn-compiler with only the
/// `codegen` feature.
#[test]
fn firmware_build_dependencies_have_no_host_only_crates() {
    let out = Command::new(env!("CARGO"))
        .current_dir(root().join("firmware"))
        .args(["tree", "--quiet", "--target", M4F.target])
        .args(["-e", "normal,build"])
        .args(["--prefix", "none", "--format", "{p} {f}"])
        .output()
        .unwrap();
    let tree = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && tree.contains("graphspn-compiler"),
        "cargo tree failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for line in tree.lines() {
        let name = line.split_whitespace().next().unwrap_or("");
        assert!(
            !HOST_ONLY_CRATES.contains(&name),
            "the firmware's build compiles the host-only crate {line:?}"
        );
        if name == "graphspn-compiler" {
            assert!(
                !line.contains("host"),
                "graphspn-compiler with its `host` feature: {line:?}"
            );
        }
    }
}

/// The no-panic link check of `generated_no_std.rs`, built for Cortex-M4F with the
/// forms a microcontroller gets (scalar `f32` and `f64`, the fixed-point kernels).
#[test]
fn generated_code_links_for_cortex_m4f_without_any_panic_path() {
    setup();
    no_panic_probe::link_check(Some(M4F.target), no_panic_probe::MCU_FORMS);
}

#[test]
fn report_parser_reads_every_record() {
    let text = "firmware x\ncalibration loop_instructions=8 measured=9 overhead=1\nram static=100\n\
                map m places=2 classes=2 buffers=64 state=32\ncall log_likelihood instructions=5 stack=64 value=3f800000\n\
                call mpe instructions=6 stack=32 error=ZeroLikelihood\n\
                marginals 0 3f000000 3f000000\nmarginals 1 3f800000 00000000\nmpe 1 0\n\
                stream set_all instructions=7 stack=16 value=3f800000\n\
                step 0 observe_marginals place=1 instructions=3 stack=8 value=3f000000\n\
                state_marginals 0 3f800000 00000000\nstate_marginals 1 3f000000 3f000000\n\
                state_call mpe instructions=9 stack=40 value=3f800000\ndone\n";
    let r = parse(text);
    assert_eq!(r.calibration, (8, 9, 1));
    assert_eq!(r.static_ram, 100);
    let m = &r.maps[0];
    assert_eq!((m.places, m.classes, m.state_bytes), (2, 2, Some(32)));
    assert_eq!(m.calls[0].value, Ok(0x3f80_0000));
    assert_eq!(m.calls[1].value, Err("ZeroLikelihood".into()));
    assert_eq!(m.marginals[1], [0x3f80_0000, 0]);
    assert_eq!(m.mpe, [1, 0]);
    assert_eq!(m.stream.len(), 2);
    assert_eq!(
        (m.stream[0].0.name.as_str(), m.stream[0].1),
        ("set_all", None)
    );
    assert_eq!(m.stream[1].0.name, "observe_marginals");
    assert_eq!((m.stream[1].0.instructions, m.stream[1].1), (3, Some(1)));
    assert_eq!(m.state_marginals[1], [0x3f00_0000, 0x3f00_0000]);
    assert_eq!(m.state_calls.len(), 1);
    assert_eq!(
        (m.state_calls[0].name.as_str(), m.state_calls[0].stack),
        ("mpe", 40)
    );
}
