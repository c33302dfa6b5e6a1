//! A firmware that runs every generated entry point of the compiled demo maps (each
//! with both model families: GraphSPN and tree mixture) on fixed evidence
//! ([`evidence`]) and prints, per call, the result's exact bits, the instructions it
//! executed and its peak stack (stack painting).
//!
//! Targets (see `../README.md`, "Firmware"):
//! - `thumbv7em-none-eabihf`: Cortex-M4F on QEMU's `netduinoplus2` (STM32F405,
//!   1 MiB flash, 128 KiB RAM), cortex-m-rt, output through semihosting,
//!   instructions from SysTick under `-icount shift=0` (`armv7m.rs`);
//! - `thumbv7m-none-eabi`: Cortex-M3 (no FPU: soft-float calls) on QEMU's
//!   `netduino2` (STM32F205, same memory map), otherwise as the Cortex-M4F;
//! - `riscv32imac-unknown-none-elf`: QEMU `virt`, a hand-written start (`rv32.rs`),
//!   output on the 16550 UART, instructions from `minstret`;
//! - the host (a plain `std` program, no counts): the reference for bit-for-bit
//!   comparisons with other builds of the same code.
//!
//! Output, one record per line (parsed by `tests/mcu_qemu/`):
//! ```text
//! firmware <target>
//! calibration loop_instructions=<n> measured=<n> overhead=<n>
//! ram static=<bytes of .data + .bss>
//! map <name> places=<n> classes=<n> buffers=<bytes> state=<bytes>
//! call <entry point> instructions=<n> stack=<bytes> value=<f32 bits, hex>|error=<e>
//! marginals <place> <f32 bits, hex> ...
//! mpe <label> ...
//! stream set_all instructions=<n> stack=<bytes> value=<f32 bits, hex>|error=<e>
//! step <i> <observe_marginals|observe_marginal> place=<p> instructions=<n> stack=<bytes> value=...
//! state_marginals <place> <f32 bits, hex> ...
//! state_call <mpe|labelled_log_likelihood> instructions=<n> stack=<bytes> value=...
//! fusion <phase> observe_marginal place=<p> instructions=<n> stack=<bytes> value=...
//! fusion_state <phase> <log-likelihood bits> <the place's marginal: f32 bits> ...
//! done
//! ```
#![cfg_attr(target_os = "none", no_std, no_main)]

mod calls;
#[allow(dead_code)]
mod evidence;

#[cfg(all(target_arch = "arm", target_os = "none"))]
mod armv7m;
#[cfg(all(target_arch = "arm", target_os = "none"))]
use armv7m as platform;
#[cfg(not(target_os = "none"))]
mod host;
#[cfg(not(target_os = "none"))]
use host as platform;
#[cfg(all(target_arch = "riscv32", target_os = "none"))]
mod rv32;
#[cfg(all(target_arch = "riscv32", target_os = "none"))]
use rv32 as platform;

#[cfg(target_os = "none")]
mod stack;

use core::fmt::Write;

use calls::{CallResult, Compiled, DemoFloor, DemoFloorTrees, Saarbrucken, SaarbruckenTrees};

#[cfg(not(target_os = "none"))]
fn main() {
    host::main();
}

/// Result, instructions and peak stack bytes of one call.
pub struct Measured {
    /// What the call returned.
    pub result: CallResult,
    /// Instructions executed by the call (0 on the host).
    pub instructions: u64,
    /// Peak stack below the caller's stack pointer, bytes (0 on the host).
    pub stack: usize,
}

/// Runs everything and writes the report to `out`.
pub fn run(out: &mut impl Write) -> core::fmt::Result {
    writeln!(out, "firmware {}", platform::TARGET)?;
    let (loop_instructions, measured, overhead) = platform::calibrate();
    writeln!(
        out,
        "calibration loop_instructions={loop_instructions} measured={measured} overhead={overhead}"
    )?;
    writeln!(out, "ram static={}", platform::static_ram())?;
    run_map::<DemoFloor>(out, evidence::SEED)?;
    run_map::<Saarbrucken>(out, evidence::SEED + 1)?;
    run_map::<DemoFloorTrees>(out, evidence::SEED + 2)?;
    run_map::<SaarbruckenTrees>(out, evidence::SEED + 3)?;
    writeln!(out, "done")
}

fn run_map<M: Compiled>(out: &mut impl Write, seed: u64) -> core::fmt::Result {
    M::start();
    M::with_views(|v| evidence::fill(seed, M::CLASSES, v.evidence, v.labels, M::UNKNOWN));
    writeln!(
        out,
        "map {} places={} classes={} buffers={} state={}",
        M::NAME,
        M::PLACES,
        M::CLASSES,
        M::BUFFER_BYTES,
        M::STATE_BYTES
    )?;
    let calls: [(&str, fn() -> CallResult); 4] = [
        ("log_likelihood", M::log_likelihood),
        ("marginals", M::marginals),
        ("mpe", M::mpe),
        ("labelled_log_likelihood", M::labelled_log_likelihood),
    ];
    for (name, f) in calls {
        write!(out, "call {name} ")?;
        measured(out, f)?;
    }
    M::with_views(|v| {
        rows(out, "marginals", v.marginals, M::CLASSES)?;
        write!(out, "mpe")?;
        for l in v.mpe.iter() {
            write!(out, " {l}")?;
        }
        writeln!(out)
    })?;
    stream::<M>(out, seed)
}

/// The streaming state on the same evidence: `set_all`, then [`evidence::STEPS`]
/// observations (alternately followed by `marginals` of all places and by
/// `marginal` of the observed place), then the state's marginals of every place.
fn stream<M: Compiled>(out: &mut impl Write, seed: u64) -> core::fmt::Result {
    write!(out, "stream set_all ")?;
    measured(out, M::state_set_all)?;
    for i in 0..evidence::STEPS {
        let place = M::with_views(|v| {
            let p = evidence::step(seed, i, M::PLACES, v.step_row);
            *v.step_place = p;
            p
        });
        let (kind, f): (&str, fn() -> CallResult) = if i % 2 == 0 {
            ("observe_marginals", M::observe_marginals)
        } else {
            ("observe_marginal", M::observe_marginal)
        };
        write!(out, "step {i} {kind} place={place} ")?;
        measured(out, f)?;
    }
    // The final state's marginals (not timed).
    match M::state_marginals() {
        Ok(_) => M::with_views(|v| rows(out, "state_marginals", v.marginals, M::CLASSES))?,
        Err(e) => writeln!(out, "state_marginals error={e:?}")?,
    }
    // The state's full passes, measured for their stack (`STACK_BYTES_STATE` bounds
    // every state call).
    let full: [(&str, fn() -> CallResult); 2] = [
        ("mpe", M::state_mpe),
        ("labelled_log_likelihood", M::state_labelled_log_likelihood),
    ];
    for (name, f) in full {
        write!(out, "state_call {name} ")?;
        measured(out, f)?;
    }
    fusion::<M>(out)
}

/// The adversarial fusion sequence ([`evidence::FUSION`]) on a new state: per phase
/// its last `observe` + `marginal` timed, then the state's log-likelihood (of the
/// product of every observation) and the place's marginal.
fn fusion<M: Compiled>(out: &mut impl Write) -> core::fmt::Result {
    M::start();
    let p = evidence::FUSION_PLACE;
    for (phase, &(class, other, count)) in evidence::FUSION.iter().enumerate() {
        M::with_views(|v| {
            evidence::favouring(class, other, v.step_row);
            *v.step_place = p;
        });
        for _ in 1..count {
            if let Err(e) = M::observe_marginal() {
                return writeln!(out, "fusion {phase} error={e:?}");
            }
        }
        write!(out, "fusion {phase} observe_marginal place={p} ")?;
        measured(out, M::observe_marginal)?;
        match M::state_marginals() {
            Ok(ll) => M::with_views(|v| {
                write!(out, "fusion_state {phase} {:08x}", ll.to_bits())?;
                let row = v.marginals.chunks(M::CLASSES).nth(p).unwrap_or(&[]);
                for x in row {
                    write!(out, " {:08x}", x.to_bits())?;
                }
                writeln!(out)
            })?,
            Err(e) => writeln!(out, "fusion_state {phase} error={e:?}")?,
        }
    }
    Ok(())
}

/// Runs `f`, writes `instructions=<n> stack=<bytes> value=<bits>|error=<e>` and a
/// line end.
fn measured(out: &mut impl Write, f: fn() -> CallResult) -> core::fmt::Result {
    let m = platform::measure(f);
    write!(out, "instructions={} stack={} ", m.instructions, m.stack)?;
    match m.result {
        Ok(v) => writeln!(out, "value={:08x}", v.to_bits()),
        Err(e) => writeln!(out, "error={e:?}"),
    }
}

/// Writes one `<tag> <place> <f32 bits>...` line per place of `values`.
fn rows(out: &mut impl Write, tag: &str, values: &[f32], classes: usize) -> core::fmt::Result {
    for (p, row) in values.chunks(classes).enumerate() {
        write!(out, "{tag} {p}")?;
        for x in row {
            write!(out, " {:08x}", x.to_bits())?;
        }
        writeln!(out)?;
    }
    Ok(())
}
