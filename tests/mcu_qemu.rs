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
//! - the instruction counter is exact to a few instructions on a loop of known size.
//!
//! The no-panic link check of `generated_no_std.rs` runs here for
//! `thumbv7em-none-eabihf`. Needs the Rust targets and QEMU: the tests run `bash
//! scripts/setup-mcu.sh` themselves, once per test process (idempotent and quiet;
//! it installs them on a fresh machine), and fail with its message if it fails. The
//! firmware builds into `target/firmware/`.

#[allow(dead_code)]
#[path = "../firmware/src/evidence.rs"]
mod evidence;
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

/// The firmware's `Builder` of module `name` (as its build script has it): the
/// GraphSPN of the demo model with 5 decompositions, or (`*_trees`) the demo tree
/// mixture; scalar code, seed 0.
fn firmware_builder(name: &str) -> Builder {
    let demo = root().join("generated/demo");
    let map = demo.join(map_file(name));
    if name.ends_with("_trees") {
        Builder::new(demo.join("tree_model.json"), map)
    } else {
        Builder::new(demo.join("model.json"), map).count(5)
    }
    .vectorisation(graphspn::codegen::Vectorisation::Scalar)
    .seed(0)
}

/// The generator's stack bounds of the firmware's scalar module `name`
/// (`STACK_BYTES_*` of the module: log-likelihood, marginals, MPE, labelled
/// log-likelihood, and last the streaming state's calls), computed by the same
/// `Builder` the firmware's build script uses.
fn stack_bounds(name: &str) -> [usize; 5] {
    let b = firmware_builder(name);
    let (_, r) = b.report_from_any(&b.load_any().unwrap()).unwrap();
    let file = map_file(name);
    assert!(
        r.stack_marginals <= 16 * 1024,
        "{file}: bound {} > 16 KiB",
        r.stack_marginals
    );
    [
        r.stack_log_likelihood,
        r.stack_marginals,
        r.stack_mpe,
        r.stack_log_likelihood,
        r.stack_state,
    ]
}

/// RAM of the firmware's linker scripts, bytes: `memory.x` (the STM32F205's SRAM as
/// QEMU's `netduino2` models it, and the STM32F405's main SRAM, of which
/// `netduinoplus2` models 192 KiB) and `rv32.x`.
const RAM_BYTES: usize = 128 * 1024;
/// Longest a firmware run may take under QEMU (RISC-V and Cortex-M3 take about
/// 10 s, Cortex-M4F 2 s).
const QEMU_TIMEOUT: Duration = Duration::from_secs(300);
/// Relative tolerance of log-likelihoods and MPE values, absolute of marginals.
const TOL: f64 = 1e-4;

/// An MCU target of the firmware and how QEMU runs it (the board
/// `scripts/mcu-run.sh` chooses).
struct Mcu {
    target: &'static str,
    /// The emulator and its machine (`-M`).
    qemu: &'static str,
    machine: &'static str,
    /// Further arguments: firmware loading and where the output goes.
    args: &'static [&'static str],
}

/// Cortex-M output: semihosting to QEMU's stdout.
const SEMIHOSTING: &[&str] = &[
    "-semihosting-config",
    "enable=on,target=native",
    "-serial",
    "null",
];
/// Cortex-M4F: STM32F405 with FPU.
const M4F: Mcu = Mcu {
    target: "thumbv7em-none-eabihf",
    qemu: "qemu-system-arm",
    machine: "netduinoplus2",
    args: SEMIHOSTING,
};
/// Cortex-M3: STM32F205 without FPU (soft-float calls).
const M3: Mcu = Mcu {
    target: "thumbv7m-none-eabi",
    qemu: "qemu-system-arm",
    machine: "netduino2",
    args: SEMIHOSTING,
};
/// RV32IMAC (no FPU either): output on the UART.
const RV32: Mcu = Mcu {
    target: "riscv32imac-unknown-none-elf",
    qemu: "qemu-system-riscv32",
    machine: "virt",
    args: &["-bios", "none", "-serial", "stdio"],
};
/// Every MCU target the firmware is built for and checked on.
const MCUS: [&Mcu; 3] = [&M4F, &M3, &RV32];

const HOST: &str = "x86_64-unknown-linux-gnu";
const SETUP: &str = "bash scripts/setup-mcu.sh";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Where the firmware is built (shared with `scripts/mcu-bench.sh`).
fn target_dir() -> PathBuf {
    root().join("target/firmware")
}

/// One call's line of a report.
#[derive(Clone, Debug, PartialEq)]
struct Call {
    name: String,
    instructions: u64,
    stack: usize,
    /// `f32` bits of the value, or the error's text.
    value: Result<u32, String>,
}

/// One map's part of a report.
#[derive(Clone, Debug, PartialEq)]
struct MapReport {
    name: String,
    places: usize,
    classes: usize,
    calls: Vec<Call>,
    /// `f32` bits, one row per place.
    marginals: Vec<Vec<u32>>,
    mpe: Vec<u16>,
    /// The streaming state's calls: `set_all`, then one per step (named
    /// `observe_marginals` or `observe_marginal`), with the step's place.
    stream: Vec<(Call, Option<usize>)>,
    /// The state's marginals after the last step (`f32` bits, one row per place).
    state_marginals: Vec<Vec<u32>>,
    /// `STATE_BYTES` of the module (`state=` of the `map` line).
    state_bytes: Option<usize>,
    /// The adversarial fusion sequence: per phase its last `observe_marginal` call.
    fusion: Vec<Call>,
    /// Per phase the state's log-likelihood and the place's marginal (`f32` bits).
    fusion_state: Vec<Vec<u32>>,
}

/// A parsed firmware report.
#[derive(Debug)]
struct Report {
    calibration: (u64, u64, u64),
    static_ram: usize,
    maps: Vec<MapReport>,
}

fn field<T: std::str::FromStr>(line: &str, key: &str) -> T {
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no {key}= in report line {line:?}"))
}

/// A call record named `name`: `instructions=<n> stack=<b> value=<bits>|error=<e>`.
fn call(name: &str, line: &str) -> Call {
    let value = match line.split_once(" value=") {
        Some((_, v)) => Ok(u32::from_str_radix(v.trim(), 16).unwrap()),
        None => Err(line.split_once(" error=").map_or("?", |x| x.1).to_string()),
    };
    Call {
        name: name.to_string(),
        instructions: field(line, "instructions"),
        stack: field(line, "stack"),
        value,
    }
}

fn parse(text: &str) -> Report {
    let mut calibration = None;
    let mut static_ram = None;
    let mut maps: Vec<MapReport> = vec![];
    let mut done = false;
    for line in text.lines().map(str::trim_end) {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("calibration") => {
                calibration = Some((
                    field(line, "loop_instructions"),
                    field(line, "measured"),
                    field(line, "overhead"),
                ))
            }
            Some("ram") => static_ram = Some(field(line, "static")),
            Some("map") => maps.push(MapReport {
                name: words.next().unwrap().to_string(),
                places: field(line, "places"),
                classes: field(line, "classes"),
                calls: vec![],
                marginals: vec![],
                mpe: vec![],
                stream: vec![],
                state_marginals: vec![],
                state_bytes: line
                    .split_whitespace()
                    .find_map(|w| w.strip_prefix("state=")?.parse().ok()),
                fusion: vec![],
                fusion_state: vec![],
            }),
            Some("fusion") => {
                let m = maps.last_mut().expect("a map line first");
                let phase: usize = words.next().unwrap().parse().unwrap();
                assert_eq!(phase, m.fusion.len(), "fusion phases in order: {line}");
                m.fusion.push(call(words.next().unwrap_or("?"), line));
            }
            Some("fusion_state") => {
                let m = maps.last_mut().expect("a map line first");
                let phase: usize = words.next().unwrap().parse().unwrap();
                assert_eq!(
                    phase,
                    m.fusion_state.len(),
                    "fusion states in order: {line}"
                );
                let bits = words.map(|w| u32::from_str_radix(w, 16));
                let bits: Result<Vec<u32>, _> = bits.collect();
                m.fusion_state
                    .push(bits.unwrap_or_else(|_| panic!("fusion state: {line}")));
            }
            Some("call") => {
                let call = call(words.next().unwrap(), line);
                maps.last_mut().expect("a map line first").calls.push(call);
            }
            Some("stream") => {
                let call = call(words.next().unwrap(), line);
                maps.last_mut()
                    .expect("a map line first")
                    .stream
                    .push((call, None));
            }
            Some("step") => {
                let m = maps.last_mut().expect("a map line first");
                let i: usize = words.next().unwrap().parse().unwrap();
                assert_eq!(i + 1, m.stream.len(), "steps in order, after set_all");
                let call = call(words.next().unwrap(), line);
                m.stream.push((call, Some(field(line, "place"))));
            }
            Some(tag @ ("marginals" | "state_marginals")) => {
                let m = maps.last_mut().expect("a map line first");
                let rows = if tag == "marginals" {
                    &mut m.marginals
                } else {
                    &mut m.state_marginals
                };
                let p: usize = words.next().unwrap().parse().unwrap();
                assert_eq!(p, rows.len(), "{tag} rows in order");
                rows.push(words.map(|w| u32::from_str_radix(w, 16).unwrap()).collect());
            }
            Some("mpe") => {
                maps.last_mut().expect("a map line first").mpe =
                    words.map(|w| w.parse().unwrap()).collect()
            }
            Some("done") => done = true,
            _ => {}
        }
    }
    assert!(done, "the report does not end with `done`:\n{text}");
    Report {
        calibration: calibration.expect("calibration line"),
        static_ram: static_ram.expect("ram line"),
        maps,
    }
}

/// Runs `scripts/setup-mcu.sh` (the Rust targets and QEMU) once per test process;
/// panics with its output if it fails.
fn setup() {
    static DONE: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    let result = DONE.get_or_init(|| {
        let out = Command::new("bash")
            .arg(root().join("scripts/setup-mcu.sh"))
            .stdin(Stdio::null())
            .output()
            .map_err(|e| format!("cannot run bash: {e}"))?;
        if out.status.success() {
            Ok(())
        } else {
            Err(format!(
                "{}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            ))
        }
    });
    if let Err(e) = result {
        panic!("`{SETUP}` (the Rust targets and QEMU these tests need) failed:\n{e}");
    }
}

/// `cargo build --release` of the firmware for `targets` (one cargo run).
fn build_firmware(targets: &[&str], profile: &str, rustflags: Option<&str>) {
    setup();
    let mut cmd = Command::new(env!("CARGO"));
    cmd.current_dir(root().join("firmware"))
        .args(["build", "--quiet", "--profile", profile])
        .env("CARGO_TARGET_DIR", target_dir())
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS");
    for t in targets {
        cmd.args(["--target", t]);
    }
    if let Some(f) = rustflags {
        cmd.env("RUSTFLAGS", f);
    }
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "building the firmware for {targets:?} failed (missing Rust targets? run `{SETUP}`):\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn elf(target: &str, profile: &str) -> PathBuf {
    let dir = if profile == "dev" { "debug" } else { profile };
    target_dir()
        .join(target)
        .join(dir)
        .join("graphspn-firmware")
}

/// QEMU's folder as `scripts/setup-mcu.sh` unpacks it.
fn qemu_dir() -> PathBuf {
    std::env::var_os("GRAPHSPN_MCU_TOOLS")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(std::env::var_os("HOME").expect("HOME is set"))
                .join(".cache/graphspn/mcu-tools")
        })
        .join("qemu")
}

/// A command running QEMU binary `name`: from the setup script's cache, else from
/// `PATH`; fails naming the setup script if neither has it.
fn qemu(name: &str) -> Command {
    setup();
    let dir = qemu_dir();
    if dir.join(".complete").exists() {
        let mut cmd = Command::new(dir.join("usr/bin").join(name));
        let mut libs = format!(
            "{}:{}",
            dir.join("usr/lib/x86_64-linux-gnu").display(),
            dir.join("lib/x86_64-linux-gnu").display()
        );
        if let Some(old) = std::env::var_os("LD_LIBRARY_PATH") {
            libs = format!("{libs}:{}", old.to_string_lossy());
        }
        cmd.env("LD_LIBRARY_PATH", libs);
        return cmd;
    }
    let on_path = std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(name).is_file()));
    assert!(
        on_path,
        "QEMU ({name}) is neither in {} nor on PATH, though `{SETUP}` succeeded",
        dir.display()
    );
    Command::new(name)
}

/// Runs `cmd` to completion within [`QEMU_TIMEOUT`]; returns stdout.
fn run_bounded(mut cmd: Command, what: &str) -> String {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{what}: cannot start ({e}); run `{SETUP}`"));
    let mut stdout = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        stdout.read_to_string(&mut s).map(|_| s)
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > QEMU_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what}: still running after {QEMU_TIMEOUT:?}; killed");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let out = reader.join().unwrap().unwrap();
    let mut err = String::new();
    let _ = child.stderr.take().unwrap().read_to_string(&mut err);
    assert!(
        status.success(),
        "{what}: exit status {status}\nstdout:\n{out}\nstderr:\n{err}"
    );
    out
}

/// Runs the firmware built for `mcu` (profile `profile`) under QEMU.
fn run_qemu(mcu: &Mcu, profile: &str) -> Report {
    let kernel = elf(mcu.target, profile);
    let mut cmd = qemu(mcu.qemu);
    cmd.args(["-M", mcu.machine]).args(mcu.args);
    cmd.args(["-nographic", "-monitor", "none", "-icount", "shift=0"])
        .arg("-kernel")
        .arg(&kernel);
    parse(&run_bounded(
        cmd,
        &format!("QEMU {} {}", mcu.target, kernel.display()),
    ))
}

/// Size in bytes of section `name` of ELF `elf` (`size -A` from binutils; 0 when
/// the section is absent).
fn section_bytes(elf: &std::path::Path, name: &str) -> u64 {
    let out = Command::new("size")
        .arg("-A")
        .arg(elf)
        .output()
        .expect("running `size` (binutils)");
    assert!(out.status.success(), "size -A {}", elf.display());
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .find_map(|l| {
            let mut w = l.split_whitespace();
            (w.next() == Some(name)).then(|| w.next()?.parse().ok())?
        })
        .unwrap_or(0)
}

/// `State::new()` is all zeros, so the firmware's buffers start as a `memset` of
/// `.bss`: no object in the ELF is as large as the smallest map's `State`
/// (`smallest` bytes), as a constant initial image of a state would be (a non-zero
/// field in `new` once put an 88 KB image of the buffers in flash).
fn assert_no_state_image(elf: &std::path::Path, smallest: usize, target: &str) {
    let out = Command::new("nm")
        .args(["-S", "-t", "d", "--size-sort"])
        .arg(elf)
        .output()
        .expect("running `nm` (binutils)");
    assert!(out.status.success(), "nm -S {}", elf.display());
    let text = String::from_utf8_lossy(&out.stdout);
    let largest = text
        .lines()
        .filter_map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            let data = matches!(w.get(2).copied(), Some("r" | "R" | "d" | "D"));
            data.then(|| Some((w.get(1)?.parse::<usize>().ok()?, w.get(3)?.to_string())))?
        })
        .max();
    if let Some((size, name)) = largest {
        assert!(
            size < smallest,
            "{target}: {name} holds {size} bytes of initialised data, at least a whole \
             State ({smallest} B): State::new() must stay all zeros"
        );
    }
}

/// Answers of the in-process host build (`graphspn-generated`) of one map.
struct HostAnswers {
    values: [Result<f32, String>; 4],
    marginals: Vec<Vec<f32>>,
    mpe: Vec<u16>,
}

/// The firmware's evidence and labels for map `index` (see `firmware/src/evidence.rs`).
fn inputs(index: u64, places: usize, classes: usize, unknown: u16) -> (Vec<f32>, Vec<u16>) {
    let mut rows = vec![0.0f32; places * classes];
    let mut labels = vec![0u16; places];
    evidence::fill(
        evidence::SEED + index,
        classes,
        &mut rows,
        &mut labels,
        unknown,
    );
    (rows, labels)
}

macro_rules! host_answers {
    ($m:ident, $index:expr) => {{
        let (rows, labels) = inputs($index, $m::NUM_PLACES, $m::NUM_CLASSES, $m::UNKNOWN);
        let mut e: $m::Evidence = [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES];
        e.as_flattened_mut().copy_from_slice(&rows);
        let l: $m::Labels = labels.try_into().unwrap();
        let mut marg: $m::Marginals = [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES];
        let mut mpe: $m::Labels = [0; $m::NUM_PLACES];
        let s = |r: Result<f32, graphspn::runtime::EvidenceError>| r.map_err(|e| format!("{e:?}"));
        let values = [
            s($m::log_likelihood(&e)),
            s($m::marginals(&e, &mut marg)),
            s($m::mpe(&e, &mut mpe)),
            s($m::labelled_log_likelihood(&l, &e)),
        ];
        HostAnswers {
            values,
            marginals: marg.iter().map(|r| r.to_vec()).collect(),
            mpe: mpe.to_vec(),
        }
    }};
}

fn close(a: f64, b: f64) -> bool {
    a == b || (a - b).abs() <= TOL * b.abs().max(1.0)
}

fn map_file(name: &str) -> &'static str {
    match name.trim_end_matches("_trees") {
        "demo_floor" => "floor.json",
        "saarbrucken_seq2_night1" => "saarbrucken_seq2_night1.json",
        _ => panic!("unknown map {name}"),
    }
}

/// The tree mixture's reference (`TreeInstance`) of firmware module `name` with
/// evidence `rows` (`f32` rows, widened).
fn tree_reference(name: &str, rows: &[Vec<f32>]) -> TreeInstance {
    let AnyInputs::TreeMixture(i) = firmware_builder(name).load_any().unwrap() else {
        panic!("{name} is not a tree mixture");
    };
    let mut inst = TreeInstance::build(&i.model, &i.map, i.trees).unwrap();
    let wide: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| r.iter().map(|&x| f64::from(x)).collect())
        .collect();
    inst.set_all_evidence(&wide).unwrap();
    inst
}

/// The value call `i` of map `m` returned (panics naming the call on an error).
fn call_value(target: &str, m: &MapReport, i: usize) -> f64 {
    let call = &m.calls[i];
    f64::from(f32::from_bits(*call.value.as_ref().unwrap_or_else(|e| {
        panic!("{target} {} {}: error {e}", m.name, call.name)
    })))
}

/// The largest absolute difference between the firmware's marginals (`f32` bits) and
/// a reference's.
fn largest_marginal_error(got: &[Vec<u32>], want: &[Vec<f64>]) -> f64 {
    got.iter()
        .flatten()
        .zip(want.iter().flatten())
        .map(|(&g, &w)| (f64::from(f32::from_bits(g)) - w).abs())
        .fold(0.0, f64::max)
}

/// [`check_map`] for a tree-mixture module: every call against `TreeInstance` (the
/// interpreter's instance SPN is checked against it in `generated_trees.rs`).
fn check_tree_map(target: &str, m: &MapReport, index: u64) {
    let (n, c) = (m.places, m.classes);
    let (rows, labels) = inputs(index, n, c, u16::MAX);
    let rows: Vec<Vec<f32>> = rows.chunks(c).map(<[f32]>::to_vec).collect();
    let inst = tree_reference(&m.name, &rows);
    let ctx = |what: &str| format!("{target} {} {what}", m.name);
    let value = |i: usize| call_value(target, m, i);
    let want = inst.marginals().unwrap();
    let best = inst.mpe(&vec![None; n]).unwrap().log_max_product;
    if is_fixed(target) {
        // Fixed-point messages: each entry within η of itself, so the log-likelihood
        // within n·η, a marginal within 4n·η, beside f32's roundings (TOL).
        let b = firmware_builder(&m.name).arithmetic(Arithmetic::Fixed);
        let (_, report) = b.report_from_any(&b.load_any().unwrap()).unwrap();
        let eta = report
            .message_error
            .expect("the demo tree model gets fixed-point messages");
        let (ll_bound, marginal_bound) = (TOL + n as f64 * eta, TOL + 4.0 * n as f64 * eta);
        let ll_err = (value(0) - want.mixed.log_likelihood).abs();
        let marginal_err = largest_marginal_error(&m.marginals, &want.mixed.probs);
        // mpe: max-product messages in fixed point too, its value within n·η.
        let mpe_err = (value(2) - best).abs();
        eprintln!(
            "{target} {}: fixed-point messages (η = {eta:.2e}), largest errors against TreeInstance: log-likelihood {ll_err:.2e} (bound {ll_bound:.2e}), marginals {marginal_err:.2e} (bound {marginal_bound:.2e}), mpe value {mpe_err:.2e} (bound {ll_bound:.2e})",
            m.name
        );
        assert!(
            ll_err <= ll_bound && marginal_err <= marginal_bound && mpe_err <= ll_bound,
            "{}",
            ctx("fixed-point error bound")
        );
    }
    for i in [0, 1] {
        let w = want.mixed.log_likelihood;
        assert!(close(value(i), w), "{}: {} vs {w}", ctx("ll"), value(i));
    }
    for (p, row) in m.marginals.iter().enumerate() {
        for (k, &bits) in row.iter().enumerate() {
            let (got, w) = (f64::from(f32::from_bits(bits)), want.mixed.probs[p][k]);
            assert!(
                (got - w).abs() <= TOL,
                "{}: {p}/{k}: {got} vs {w}",
                ctx("marginals")
            );
        }
    }
    assert!(
        close(value(2), best),
        "{}: {} vs {best}",
        ctx("mpe"),
        value(2)
    );
    let fixed: Vec<Option<u16>> = m.mpe.iter().map(|&l| Some(l)).collect();
    let attained = inst.mpe(&fixed).unwrap().log_max_product;
    assert!(
        close(attained, best),
        "{}: labels attain {attained}",
        ctx("mpe")
    );
    let probe: Vec<Option<u16>> = labels
        .iter()
        .map(|&l| (l != u16::MAX).then_some(l))
        .collect();
    let want_l = inst.log_likelihood_labelled(&probe).unwrap();
    assert!(
        close(value(3), want_l),
        "{}: {} vs {want_l}",
        ctx("labelled"),
        value(3)
    );
}

/// Whether `Builder` gives `target` the fixed-point kernel (no FPU).
fn is_fixed(target: &str) -> bool {
    Arithmetic::for_target(target) == Arithmetic::Fixed
}

/// Checks one map of an MCU report against the interpreter (tolerances) and returns
/// how many of its numbers differ in bits from `host` (the x86-64-v3 build). On a
/// fixed-point target it also prints the largest errors and checks them against the
/// kernel's documented bound (`fixed_bounds`).
fn check_map(target: &str, m: &MapReport, index: u64, host: &HostAnswers) -> usize {
    if m.name.ends_with("_trees") {
        check_tree_map(target, m, index);
        return compare_with_host(target, m, host);
    }
    let demo = root().join("generated/demo");
    let inputs_ = Builder::new(demo.join("model.json"), demo.join(map_file(&m.name)))
        .seed(0)
        .count(5)
        .load()
        .unwrap();
    let inst = Instance::build(&inputs_.model, &inputs_.map, inputs_.decompositions).unwrap();
    let mut ev = Evaluator::new(&inst.spn).unwrap();
    let (n, c) = (m.places, m.classes);
    let unknown = u16::MAX;
    let (rows, labels) = inputs(index, n, c, unknown);
    let evidence = Evidence::from_rows(
        rows.chunks(c)
            .map(|r| r.iter().map(|&x| f64::from(x)).collect())
            .collect(),
    );
    let free = vec![None; n];
    let ctx = |what: &str| format!("{target} {} {what}", m.name);
    let value = |i: usize| call_value(target, m, i);
    let names: Vec<&str> = m.calls.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "log_likelihood",
            "marginals",
            "mpe",
            "labelled_log_likelihood"
        ],
        "{}",
        ctx("calls")
    );
    // Interpreter.
    let want = ev.marginals(&free, &evidence).unwrap();
    if is_fixed(target) {
        let (ll_bound, marginal_bound) = fixed_bounds(&inst);
        let ll_err = (value(1) - want.log_likelihood).abs();
        let marginal_err = largest_marginal_error(&m.marginals, &want.probs);
        eprintln!(
            "{target} {}: fixed-point kernel, largest errors against the interpreter: log-likelihood {ll_err:.2e} (bound {ll_bound:.2e}), marginals {marginal_err:.2e} (bound {marginal_bound:.2e})",
            m.name
        );
        assert!(
            ll_err <= ll_bound && marginal_err <= marginal_bound,
            "{}",
            ctx("fixed-point error bound")
        );
    }
    for i in [0, 1] {
        assert!(
            close(value(i), want.log_likelihood),
            "{}: {} vs interpreter {}",
            ctx(names[i]),
            value(i),
            want.log_likelihood
        );
    }
    for (p, row) in m.marginals.iter().enumerate() {
        for (k, &bits) in row.iter().enumerate() {
            let got = f64::from(f32::from_bits(bits));
            assert!(
                (got - want.probs[p][k]).abs() <= TOL,
                "{}: place {p} class {k}: {got} vs interpreter {}",
                ctx("marginals"),
                want.probs[p][k]
            );
        }
    }
    let best = ev.log_max_product(&free, &evidence).unwrap();
    assert!(
        close(value(2), best),
        "{}: {} vs interpreter {best}",
        ctx("mpe"),
        value(2)
    );
    let fixed: Vec<Option<u32>> = m.mpe.iter().map(|&l| Some(u32::from(l))).collect();
    let attained = ev.log_max_product(&fixed, &evidence).unwrap();
    assert!(
        close(attained, best),
        "{}: labels attain {attained} not {best}",
        ctx("mpe")
    );
    let probe: Vec<Option<u32>> = labels
        .iter()
        .map(|&l| (l != unknown).then_some(u32::from(l)))
        .collect();
    let want_l = ev.log_likelihood(&probe, &evidence).unwrap();
    assert!(
        close(value(3), want_l),
        "{}: {} vs interpreter {want_l}",
        ctx("labelled_log_likelihood"),
        value(3)
    );
    // The x86-64-v3 host build: same tolerances, and count differing bits.
    compare_with_host(target, m, host)
}

/// The fixed-point kernel's documented error bound for an instance (see the
/// generator's `codegen::fixed` module): each template value off by at most `2^-13` of
/// itself and each local posterior by `2^-10`, so with `K` components in the largest
/// decomposition the log-likelihood is off by at most `K·2^-13` (plus `f32` rounding
/// of the sum, 1e-3 here) and a marginal by `2^-10 + 2K·2^-13` (the decomposition
/// weights' relative error).
fn fixed_bounds(inst: &Instance) -> (f64, f64) {
    let k = inst
        .decompositions
        .iter()
        .map(|d| d.components.len())
        .max()
        .unwrap_or(0) as f64;
    let unit = 2f64.powi(-13);
    (k * unit + 1e-3, 8.0 * unit + 2.0 * k * unit)
}

/// How many of a map's numbers differ in bits from the x86-64-v3 host build `host`
/// (all within the tolerances).
fn compare_with_host(target: &str, m: &MapReport, host: &HostAnswers) -> usize {
    let ctx = |what: &str| format!("{target} {} {what}", m.name);
    let names = [
        "log_likelihood",
        "marginals",
        "mpe",
        "labelled_log_likelihood",
    ];
    let value = |i: usize| f64::from(f32::from_bits(*m.calls[i].value.as_ref().unwrap()));
    let mut differ = 0;
    for (i, h) in host.values.iter().enumerate() {
        let h = h
            .as_ref()
            .unwrap_or_else(|e| panic!("host {}: {e}", ctx(names[i])));
        assert!(
            close(value(i), f64::from(*h)),
            "{}: {} vs host {h}",
            ctx(names[i]),
            value(i)
        );
        differ += usize::from(m.calls[i].value != Ok(h.to_bits()));
    }
    for (got, h) in m
        .marginals
        .iter()
        .flatten()
        .zip(host.marginals.iter().flatten())
    {
        assert!((f64::from(f32::from_bits(*got)) - f64::from(*h)).abs() <= TOL);
        differ += usize::from(*got != h.to_bits());
    }
    differ += m.mpe.iter().zip(&host.mpe).filter(|(a, b)| a != b).count();
    differ
}

/// One map's results: everything but instruction counts and stack, which must
/// agree bit for bit between builds of the same code.
#[derive(Debug, PartialEq)]
struct MapResults {
    name: String,
    values: Vec<Result<u32, String>>,
    marginals: Vec<Vec<u32>>,
    mpe: Vec<u16>,
    stream: Vec<(Result<u32, String>, Option<usize>)>,
    state_marginals: Vec<Vec<u32>>,
    fusion: Vec<Result<u32, String>>,
    fusion_state: Vec<Vec<u32>>,
}

fn results(r: &Report) -> Vec<MapResults> {
    r.maps
        .iter()
        .map(|m| MapResults {
            name: m.name.clone(),
            values: m.calls.iter().map(|c| c.value.clone()).collect(),
            marginals: m.marginals.clone(),
            mpe: m.mpe.clone(),
            stream: m
                .stream
                .iter()
                .map(|(c, p)| (c.value.clone(), *p))
                .collect(),
            state_marginals: m.state_marginals.clone(),
            fusion: m.fusion.iter().map(|c| c.value.clone()).collect(),
            fusion_state: m.fusion_state.clone(),
        })
        .collect()
}

/// The adversarial fusion sequence's exact outcome on module `M`, per phase: the
/// log-likelihood of the product of every observation (the stateless log-likelihood of
/// the `f64` log-domain reference rows, largest entry 1, plus `γ · max_c ln Π α`) and
/// the place's marginal (stateless `marginals` of the reference rows).
fn fusion_reference<M: CompiledMap<Scalar = f32>>() -> Vec<(f64, Vec<f64>)> {
    let (n, c, p) = (M::NUM_PLACES, M::NUM_CLASSES, evidence::FUSION_PLACE);
    let mut logs = vec![0.0f64; c];
    let mut row = vec![0.0f32; c];
    let mut out = vec![];
    for &(class, other, count) in &evidence::FUSION {
        evidence::favouring(class, other, &mut row);
        for (l, &a) in logs.iter_mut().zip(&row) {
            *l += f64::from(count) * f64::from(a).ln();
        }
        let best = logs.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let mut e = vec![M::ZERO_ROW; n];
        for (q, r) in e.iter_mut().enumerate() {
            for (k, x) in r.as_mut().iter_mut().enumerate() {
                *x = if q == p {
                    (logs[k] - best).exp() as f32
                } else {
                    1.0
                };
            }
        }
        let mut marg = vec![M::ZERO_ROW; n];
        let ll = f64::from(M::marginals(&e, &mut marg).unwrap());
        let ll = ll + f64::from(M::EVIDENCE_EXPONENT) * best;
        out.push((ll, marg[p].as_ref().iter().map(|&x| f64::from(x)).collect()));
    }
    out
}

/// Checks one map's adversarial fusion sequence (run on the target) against its exact
/// outcome: the log-likelihood of the product of the observations, and the place's
/// marginal on the class the net evidence favours.
fn check_fusion(target: &str, m: &MapReport, want: &[(f64, Vec<f64>)]) {
    let ctx = |phase: usize| format!("{target} {} fusion phase {phase}", m.name);
    assert_eq!(m.fusion.len(), evidence::FUSION.len(), "{}", ctx(0));
    assert_eq!(m.fusion_state.len(), want.len(), "{}", ctx(0));
    for (phase, (bits, (ll, row))) in m.fusion_state.iter().zip(want).enumerate() {
        let got: Vec<f64> = bits.iter().map(|&b| f64::from(f32::from_bits(b))).collect();
        assert!(
            (got[0] - ll).abs() <= 1e-5 * ll.abs().max(1.0),
            "{}: log-likelihood {} vs the product's {ll}",
            ctx(phase),
            got[0]
        );
        for (k, (g, w)) in got[1..].iter().zip(row).enumerate() {
            assert!(
                (g - w).abs() <= TOL,
                "{}: class {k}: {g} vs {w}",
                ctx(phase)
            );
        }
        let class = evidence::FUSION[phase].0;
        assert!(got[1 + class] > 0.999, "{}: {got:?}", ctx(phase));
    }
}

/// The firmware's streaming steps replayed on the in-process host build of a map:
/// the value of `set_all` + `log_likelihood` and of every step, the steps' places,
/// and the state's final marginals and evidence rows.
struct HostStream {
    values: Vec<f32>,
    places: Vec<usize>,
    marginals: Vec<Vec<f32>>,
    evidence: Vec<Vec<f32>>,
}

macro_rules! host_stream {
    ($m:ident, $index:expr) => {{
        let (rows, _) = inputs($index, $m::NUM_PLACES, $m::NUM_CLASSES, $m::UNKNOWN);
        let mut e: $m::Evidence = [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES];
        e.as_flattened_mut().copy_from_slice(&rows);
        let mut st = $m::State::new();
        st.set_all(&e).unwrap();
        let mut values = vec![st.log_likelihood().unwrap()];
        let mut places = vec![];
        let mut marg: $m::Marginals = [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES];
        let mut one = [0.0f32; $m::NUM_CLASSES];
        for i in 0..evidence::STEPS {
            let mut row = [0.0f32; $m::NUM_CLASSES];
            let p = evidence::step(evidence::SEED + $index, i, $m::NUM_PLACES, &mut row);
            places.push(p);
            st.observe(p, &row).unwrap();
            values.push(if i % 2 == 0 {
                st.marginals(&mut marg).unwrap()
            } else {
                st.marginal(p, &mut one).unwrap();
                one[0]
            });
        }
        st.marginals(&mut marg).unwrap();
        HostStream {
            values,
            places,
            marginals: marg.iter().map(|r| r.to_vec()).collect(),
            evidence: st.evidence().iter().map(|r| r.to_vec()).collect(),
        }
    }};
}

/// Checks one map's streaming steps against the host build's replay (values within
/// the tolerances, same places) and the state's final marginals against the
/// interpreter on the state's final evidence (`TreeInstance` for a tree mixture).
fn check_stream(target: &str, m: &MapReport, host: &HostStream) {
    let ctx = |what: &str| format!("{target} {} stream {what}", m.name);
    assert_eq!(m.stream.len(), host.values.len(), "{}", ctx("steps"));
    for (i, ((call, place), &want)) in m.stream.iter().zip(&host.values).enumerate() {
        let expected = match i {
            0 => "set_all",
            i if i % 2 == 1 => "observe_marginals",
            _ => "observe_marginal",
        };
        assert_eq!(call.name, expected, "{}", ctx("call order"));
        assert_eq!(
            *place,
            i.checked_sub(1).map(|s| host.places[s]),
            "{}",
            ctx("places")
        );
        let bits = call
            .value
            .as_ref()
            .unwrap_or_else(|e| panic!("{}: error {e}", ctx(&call.name)));
        let got = f64::from(f32::from_bits(*bits));
        let ok = if expected == "observe_marginal" {
            (got - f64::from(want)).abs() <= TOL
        } else {
            close(got, f64::from(want))
        };
        assert!(ok, "{}: step {i}: {got} vs host {want}", ctx(&call.name));
    }
    if m.name.ends_with("_trees") {
        let want = tree_reference(&m.name, &host.evidence).marginals().unwrap();
        for (p, row) in m.state_marginals.iter().enumerate() {
            for (k, &bits) in row.iter().enumerate() {
                let got = f64::from(f32::from_bits(bits));
                let (w, h) = (want.mixed.probs[p][k], f64::from(host.marginals[p][k]));
                assert!(
                    (got - w).abs() <= TOL && (got - h).abs() <= TOL,
                    "{}: place {p} class {k}: {got} vs TreeInstance {w} and host {h}",
                    ctx("final marginals")
                );
            }
        }
        return;
    }
    let demo = root().join("generated/demo");
    let inputs_ = Builder::new(demo.join("model.json"), demo.join(map_file(&m.name)))
        .seed(0)
        .count(5)
        .load()
        .unwrap();
    let inst = Instance::build(&inputs_.model, &inputs_.map, inputs_.decompositions).unwrap();
    let mut ev = Evaluator::new(&inst.spn).unwrap();
    let evidence = Evidence::from_rows(
        host.evidence
            .iter()
            .map(|r| r.iter().map(|&x| f64::from(x)).collect())
            .collect(),
    );
    let want = ev.marginals(&vec![None; m.places], &evidence).unwrap();
    for (p, row) in m.state_marginals.iter().enumerate() {
        for (k, &bits) in row.iter().enumerate() {
            let got = f64::from(f32::from_bits(bits));
            assert!(
                (got - want.probs[p][k]).abs() <= TOL
                    && (got - f64::from(host.marginals[p][k])).abs() <= TOL,
                "{}: place {p} class {k}: {got} vs interpreter {} and host {}",
                ctx("final marginals"),
                want.probs[p][k],
                host.marginals[p][k]
            );
        }
    }
}

/// The tree mixture of the 230-place map fits a small microcontroller: every call
/// takes at most 16 KiB of stack and the streaming state at most 64 KiB (the
/// generator's figure is the module's); on Cortex-M4F `log_likelihood` takes at most
/// 0.4 M instructions, `marginals` and `mpe` at most 1 M each; on the targets without
/// an FPU (Cortex-M3, RV32IMAC) `log_likelihood` at most 3 M and `marginals` 10 M.
fn check_tree_acceptance(target: &str, r: &Report) {
    let m = r
        .maps
        .iter()
        .find(|m| m.name == "saarbrucken_seq2_night1_trees")
        .expect("the 230-place tree mixture");
    let state = m.state_bytes.expect("state= in the map line");
    let b = firmware_builder(&m.name);
    let (_, report) = b.report_from_any(&b.load_any().unwrap()).unwrap();
    assert_eq!(
        report.state_bytes, state,
        "{target}: the report's state bytes"
    );
    assert!(state <= 64 * 1024, "{target}: STATE_BYTES {state} > 64 KiB");
    let calls = m.calls.iter().chain(m.stream.iter().map(|(c, _)| c));
    for c in calls {
        assert!(
            c.stack <= 16 * 1024,
            "{target} {}: {} bytes of stack",
            c.name,
            c.stack
        );
    }
    // log_likelihood, marginals, mpe: the kernels' goals on a Cortex-M4F, and
    // log_likelihood and marginals on the targets without an FPU, whose mpe has
    // fixed-point max-product messages (2.81 M / 3.35 M; 7.41 M / 7.25 M with f32 ones).
    let limits: &[u64] = if target == M4F.target {
        &[400_000, 1_000_000, 1_000_000]
    } else {
        &[3_000_000, 10_000_000, 4_000_000]
    };
    for (c, &limit) in m.calls.iter().zip(limits) {
        assert!(
            c.instructions <= limit,
            "{target}: {} of the 230-place tree mixture takes {} instructions (at most {limit})",
            c.name,
            c.instructions
        );
    }
}

/// Median instructions of the steps of kind `name`.
fn median_instructions(m: &MapReport, name: &str) -> u64 {
    let mut n: Vec<u64> = m
        .stream
        .iter()
        .filter(|(c, _)| c.name == name)
        .map(|(c, _)| c.instructions)
        .collect();
    n.sort_unstable();
    n[n.len() / 2]
}

#[test]
fn firmware_on_qemu_matches_host_and_interpreter_within_stack_bounds() {
    let start = Instant::now();
    // Fail early, naming the setup script, if QEMU is missing.
    for mcu in MCUS {
        drop(qemu(mcu.qemu));
    }
    build_firmware(&MCUS.map(|m| m.target), "release", None);
    // The host build of the same scalar float code (Rust never fuses a multiply and
    // an add, so the workspace's x86-64-v3 flags change no result bit); targets
    // without an FPU get the fixed-point kernel (`Builder`'s default for them) and are
    // compared with each other instead.
    build_firmware(&[HOST], "release", None);
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
            // A GraphSPN's streaming step with every marginal costs at least 10x less
            // than a stateless `marginals` on every target: without an FPU its mix of
            // the cached rows runs in Q1.31 integers (in soft-float it was 3.9-7.1x).
            if !m.name.ends_with("_trees") {
                assert!(
                    all * 10 <= full,
                    "{target} {}: streaming step {all} vs stateless marginals {full}",
                    m.name
                );
            }
            let stream = m.stream.iter().map(|(c, _)| c).chain(&m.fusion);
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

/// The no-panic link check of `generated_no_std.rs`, for Cortex-M4F (the fixed-point
/// kernel included).
#[test]
fn generated_code_links_for_cortex_m4f_without_any_panic_path() {
    setup();
    no_panic_probe::link_check(Some(M4F.target));
}

#[test]
fn report_parser_reads_every_record() {
    let text = "firmware x\ncalibration loop_instructions=8 measured=9 overhead=1\nram static=100\n\
                map m places=2 classes=2 buffers=64 state=32\ncall log_likelihood instructions=5 stack=64 value=3f800000\n\
                call mpe instructions=6 stack=32 error=ZeroLikelihood\n\
                marginals 0 3f000000 3f000000\nmarginals 1 3f800000 00000000\nmpe 1 0\n\
                stream set_all instructions=7 stack=16 value=3f800000\n\
                step 0 observe_marginals place=1 instructions=3 stack=8 value=3f000000\n\
                state_marginals 0 3f800000 00000000\nstate_marginals 1 3f000000 3f000000\ndone\n";
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
}
