//! Cortex-M on QEMU: Cortex-M4F (`thumbv7em-none-eabihf`) on `netduinoplus2`,
//! Cortex-M3 (`thumbv7m-none-eabi`, no FPU: every float operation is a soft-float
//! call) on `netduino2`. cortex-m-rt start, semihosting output, instruction counts
//! from SysTick.
//!
//! Under `-icount shift=0` QEMU advances its virtual clock by exactly 1 ns per
//! executed instruction, and SysTick (clock source: the core clock, [`CORE_HZ`])
//! counts `CORE_HZ` / 10⁹ ticks per ns: instructions = ticks · 10⁹ / `CORE_HZ`
//! (125 / 21 at 168 MHz, 25 / 3 at 120 MHz), to within a tick (±6 and ±9
//! instructions). [`calibrate`] checks that relation on a loop of known length.

use core::arch::asm;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::{debug, hio};

use crate::Measured;
use crate::calls::CallResult;

/// Name printed in the report's first line.
#[cfg(target_abi = "eabihf")]
pub const TARGET: &str = "thumbv7em-none-eabihf";
/// Name printed in the report's first line.
#[cfg(not(target_abi = "eabihf"))]
pub const TARGET: &str = "thumbv7m-none-eabi";

/// Core clock of the board QEMU models (its fixed SYSCLK), Hz: the STM32F405 of
/// `netduinoplus2` (hard-float ABI, chosen by `scripts/mcu-run.sh`).
#[cfg(target_abi = "eabihf")]
const CORE_HZ: u64 = 168_000_000;
/// Core clock of the board QEMU models (its fixed SYSCLK), Hz: the STM32F205 of
/// `netduino2` (soft-float ABI, chosen by `scripts/mcu-run.sh`).
#[cfg(not(target_abi = "eabihf"))]
const CORE_HZ: u64 = 120_000_000;

const fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// Instructions per tick as the fraction `NS_PER_TICK.0 / NS_PER_TICK.1` (1 ns per
/// instruction), reduced so that `ticks · numerator` cannot overflow.
const NS_PER_TICK: (u64, u64) = {
    let g = gcd(1_000_000_000, CORE_HZ);
    (1_000_000_000 / g, CORE_HZ / g)
};

/// SysTick reload value (24 bits); every wrap raises the SysTick exception.
const RELOAD: u32 = 0x00FF_FFFF;
/// SysTick wraps so far.
static WRAPS: AtomicU32 = AtomicU32::new(0);
/// Ticks of an empty measurement, subtracted from every measurement.
static OVERHEAD: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    WRAPS.fetch_add(1, Ordering::SeqCst);
}

/// SysTick ticks since start (64 bits, counting the wraps).
#[inline(always)]
fn ticks() -> u64 {
    loop {
        let w = WRAPS.load(Ordering::SeqCst);
        let v = SYST::get_current();
        if WRAPS.load(Ordering::SeqCst) == w {
            return u64::from(w) * (u64::from(RELOAD) + 1) + u64::from(RELOAD - v);
        }
    }
}

/// Instructions executed in `ticks` SysTick ticks, rounded (see the module doc).
fn instructions(ticks: u64) -> u64 {
    let (num, den) = NS_PER_TICK;
    (ticks * num + den / 2) / den
}

/// Runs a loop of exactly 2²¹ instructions (2²⁰ × `subs`, `bne`) and returns
/// `(2²¹, instructions measured, overhead instructions)`.
pub fn calibrate() -> (u64, u64, u64) {
    const N: u32 = 1 << 20;
    let t0 = ticks();
    let t1 = ticks();
    OVERHEAD.store((t1 - t0) as u32, Ordering::SeqCst);
    let t0 = ticks();
    // SAFETY: a register-only countdown loop.
    unsafe {
        asm!("1:", "subs {n}, {n}, #1", "bne 1b", n = inout(reg) N => _, options(nomem, nostack));
    }
    let t1 = ticks();
    let overhead = u64::from(OVERHEAD.load(Ordering::SeqCst));
    (
        2 * u64::from(N),
        instructions(t1 - t0 - overhead),
        instructions(overhead),
    )
}

unsafe extern "C" {
    /// End of `.bss` (cortex-m-rt's start of the heap region): the stack's floor.
    static __sheap: u32;
    /// Start of `.data`, the first section in RAM (cortex-m-rt's `link.x`).
    static __sdata: u32;
}

/// Bytes of RAM taken by statics (`.data`, `.bss`, `.uninit`).
pub fn static_ram() -> usize {
    &raw const __sheap as usize - &raw const __sdata as usize
}

/// Bytes left unpainted below this frame (room for the painting function's own).
const GAP: usize = 256;

/// Runs `f`, counting instructions and painting the stack to find its peak.
#[inline(never)]
pub fn measure(f: fn() -> CallResult) -> Measured {
    let sp: usize;
    // SAFETY: reads the stack pointer.
    unsafe { asm!("mov {}, sp", out(reg) sp, options(nomem, nostack)) };
    let lo = (&raw const __sheap as usize + 3) & !3;
    let hi = (sp - GAP) & !3;
    // SAFETY: [lo, hi) lies between the end of .bss and the live frames; the
    // SysTick handler runs on this stack but only below the stack pointer.
    unsafe { crate::stack::paint(lo, hi) };
    let t0 = ticks();
    let result = core::hint::black_box(f)();
    let t1 = ticks();
    // SAFETY: as above.
    let used = unsafe { crate::stack::used(lo, hi) };
    let overhead = u64::from(OVERHEAD.load(Ordering::SeqCst));
    Measured {
        result,
        instructions: instructions((t1 - t0).saturating_sub(overhead)),
        stack: if used == 0 { 0 } else { used + (sp - hi) },
    }
}

/// `core::fmt::Write` to the host's stdout by semihosting, a line at a time.
struct Semihosting {
    stream: hio::HostStream,
    buf: [u8; 256],
    len: usize,
}

impl Semihosting {
    fn flush(&mut self) {
        let _ = self.stream.write_all(&self.buf[..self.len]);
        self.len = 0;
    }
}

impl core::fmt::Write for Semihosting {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for &b in s.as_bytes() {
            if self.len == self.buf.len() {
                self.flush();
            }
            self.buf[self.len] = b;
            self.len += 1;
            if b == b'\n' {
                self.flush();
            }
        }
        Ok(())
    }
}

#[entry]
fn main() -> ! {
    let Some(mut cp) = cortex_m::Peripherals::take() else {
        debug::exit(debug::EXIT_FAILURE);
        loop {}
    };
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(RELOAD);
    cp.SYST.clear_current();
    cp.SYST.enable_interrupt();
    cp.SYST.enable_counter();
    let ok = match hio::hstdout() {
        Ok(stream) => {
            let mut out = Semihosting {
                stream,
                buf: [0; 256],
                len: 0,
            };
            let ok = crate::run(&mut out).is_ok();
            out.flush();
            ok
        }
        Err(()) => false,
    };
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {}
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m_semihosting::hprintln!("panic: {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {}
}
