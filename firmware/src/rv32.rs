//! RV32IMAC on QEMU `virt`: a hand-written start (stack, `.bss`, trap vector),
//! output on the 16550 UART, exit through the SiFive test device, instruction counts
//! from the `minstret` CSR (exact under `-icount`).
//!
//! Memory (`rv32.x`): code and read-only data in the first 2 MiB of DRAM
//! ("flash"), data, `.bss` and the stack in a 128 KiB region above it. QEMU's ELF
//! loader places `.data` directly at its run address.

use core::arch::{asm, global_asm};
use core::sync::atomic::{AtomicU32, Ordering};

use crate::Measured;
use crate::calls::CallResult;

/// Name printed in the report's first line.
pub const TARGET: &str = "riscv32imac-unknown-none-elf";

/// Transmit register of the `virt` board's 16550 UART.
const UART_THR: usize = 0x1000_0000;
/// The `virt` board's SiFive test device: writing 0x5555 ends QEMU with status 0,
/// `(code << 16) | 0x3333` with status `code`.
const TEST_DEVICE: usize = 0x0010_0000;

global_asm!(
    r#"
    .section .text.start, "ax"
    .global _start
_start:
    .option push
    .option norelax
    la gp, __global_pointer$
    .option pop
    la sp, _stack_top
    la t0, _sbss
    la t1, _ebss
1:  bgeu t0, t1, 2f
    sw zero, 0(t0)
    addi t0, t0, 4
    j 1b
2:  la t0, rv32_trap
    csrw mtvec, t0
    call rv32_main
3:  j 3b

    .align 4
rv32_trap:
    li t0, 0x100000
    li t1, 0x23333
    sw t1, 0(t0)
4:  j 4b
"#
);

/// Instructions retired since reset.
#[inline(always)]
fn instret() -> u64 {
    loop {
        let (hi, lo, hi2): (u32, u32, u32);
        // SAFETY: reads of the machine-mode counters.
        unsafe {
            asm!("csrr {0}, minstreth", "csrr {1}, minstret", "csrr {2}, minstreth",
                 out(reg) hi, out(reg) lo, out(reg) hi2, options(nomem, nostack));
        }
        if hi == hi2 {
            return (u64::from(hi) << 32) | u64::from(lo);
        }
    }
}

/// Instructions of an empty measurement, subtracted from every measurement.
static OVERHEAD: AtomicU32 = AtomicU32::new(0);

/// Runs a loop of exactly 2²¹ instructions (2²⁰ × `addi`, `bnez`) and returns
/// `(2²¹, instructions measured, overhead instructions)`.
pub fn calibrate() -> (u64, u64, u64) {
    const N: u32 = 1 << 20;
    let t0 = instret();
    let t1 = instret();
    let overhead = t1 - t0;
    OVERHEAD.store(overhead as u32, Ordering::SeqCst);
    let t0 = instret();
    // SAFETY: a register-only countdown loop.
    unsafe {
        asm!("1:", "addi {n}, {n}, -1", "bnez {n}, 1b", n = inout(reg) N => _, options(nomem, nostack));
    }
    let t1 = instret();
    (2 * u64::from(N), t1 - t0 - overhead, overhead)
}

unsafe extern "C" {
    /// End of `.bss` (from `rv32.x`): the stack's floor.
    static _ebss: u32;
    /// Start of `.data`, the first section in RAM (from `rv32.x`).
    static _sdata: u32;
}

/// Bytes of RAM taken by statics (`.data`, `.bss`).
pub fn static_ram() -> usize {
    &raw const _ebss as usize - &raw const _sdata as usize
}

/// Bytes left unpainted below this frame (room for the painting function's own).
const GAP: usize = 256;

/// Runs `f`, counting instructions and painting the stack to find its peak.
#[inline(never)]
pub fn measure(f: fn() -> CallResult) -> Measured {
    let sp: usize;
    // SAFETY: reads the stack pointer.
    unsafe { asm!("mv {}, sp", out(reg) sp, options(nomem, nostack)) };
    let lo = (&raw const _ebss as usize + 3) & !3;
    let hi = (sp - GAP) & !3;
    // SAFETY: [lo, hi) lies between the end of .bss and the live frames; nothing
    // else runs (no interrupts are enabled).
    unsafe { crate::stack::paint(lo, hi) };
    let t0 = instret();
    let result = core::hint::black_box(f)();
    let t1 = instret();
    // SAFETY: as above.
    let used = unsafe { crate::stack::used(lo, hi) };
    Measured {
        result,
        instructions: (t1 - t0).saturating_sub(u64::from(OVERHEAD.load(Ordering::SeqCst))),
        stack: if used == 0 { 0 } else { used + (sp - hi) },
    }
}

/// `core::fmt::Write` to the UART.
struct Uart;

impl core::fmt::Write for Uart {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for &b in s.as_bytes() {
            // SAFETY: the UART's transmit register (QEMU never reports it full).
            unsafe { core::ptr::write_volatile(UART_THR as *mut u8, b) };
        }
        Ok(())
    }
}

/// Ends QEMU with exit status `code` (0: success).
fn exit(code: u32) -> ! {
    let v = if code == 0 {
        0x5555
    } else {
        (code << 16) | 0x3333
    };
    // SAFETY: the test device's register.
    unsafe { core::ptr::write_volatile(TEST_DEVICE as *mut u32, v) };
    loop {
        core::hint::spin_loop();
    }
}

#[unsafe(no_mangle)]
extern "C" fn rv32_main() -> ! {
    let ok = crate::run(&mut Uart).is_ok();
    exit(if ok { 0 } else { 1 })
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    use core::fmt::Write;
    let _ = writeln!(Uart, "panic: {info}");
    exit(3)
}
