//! A firmware that runs every generated entry point of the compiled demo maps on
//! fixed evidence ([`evidence`]) and prints, per call, the result's exact bits, the
//! instructions it executed and its peak stack (stack painting).
//!
//! Targets (see `../README.md`, "Firmware"):
//! - `thumbv7em-none-eabihf`: Cortex-M4F on QEMU's `netduinoplus2` (STM32F405,
//!   1 MiB flash, 128 KiB RAM), cortex-m-rt, output through semihosting,
//!   instructions from SysTick under `-icount shift=0`;
//! - `riscv32imac-unknown-none-elf`: QEMU `virt`, a hand-written start (`rv32.rs`),
//!   output on the 16550 UART, instructions from `minstret`;
//! - the host (a plain `std` program, no counts): the reference for bit-for-bit
//!   comparisons with other builds of the same code.
//!
//! Output, one record per line (parsed by `tests/mcu_qemu.rs`):
//! ```text
//! firmware <target>
//! calibration loop_instructions=<n> measured=<n> overhead=<n>
//! ram static=<bytes of .data + .bss>
//! map <name> places=<n> classes=<n>
//! call <entry point> instructions=<n> stack=<bytes> value=<f32 bits, hex>|error=<e>
//! marginals <place> <f32 bits, hex> ...
//! mpe <label> ...
//! done
//! ```
#![cfg_attr(target_os = "none", no_std, no_main)]

mod calls;
#[allow(dead_code)]
mod evidence;

#[cfg(all(target_arch = "arm", target_os = "none"))]
mod cortex_m4;
#[cfg(all(target_arch = "arm", target_os = "none"))]
use cortex_m4 as platform;
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

use calls::{CallResult, Compiled, DemoFloor, Saarbrucken};

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
    writeln!(out, "done")
}

fn run_map<M: Compiled>(out: &mut impl Write, seed: u64) -> core::fmt::Result {
    M::with_views(|v| evidence::fill(seed, M::CLASSES, v.evidence, v.labels, M::UNKNOWN));
    writeln!(
        out,
        "map {} places={} classes={}",
        M::NAME,
        M::PLACES,
        M::CLASSES
    )?;
    let calls: [(&str, fn() -> CallResult); 4] = [
        ("log_likelihood", M::log_likelihood),
        ("marginals", M::marginals),
        ("mpe", M::mpe),
        ("labelled_log_likelihood", M::labelled_log_likelihood),
    ];
    for (name, f) in calls {
        let m = platform::measure(f);
        write!(
            out,
            "call {name} instructions={} stack={} ",
            m.instructions, m.stack
        )?;
        match m.result {
            Ok(v) => writeln!(out, "value={:08x}", v.to_bits())?,
            Err(e) => writeln!(out, "error={e:?}")?,
        }
    }
    M::with_views(|v| {
        for (p, row) in v.marginals.chunks(M::CLASSES).enumerate() {
            write!(out, "marginals {p}")?;
            for x in row {
                write!(out, " {:08x}", x.to_bits())?;
            }
            writeln!(out)?;
        }
        write!(out, "mpe")?;
        for l in v.mpe.iter() {
            write!(out, " {l}")?;
        }
        writeln!(out)
    })
}
