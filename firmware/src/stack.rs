//! Peak stack by painting: fill the free stack below the current stack pointer with
//! a pattern, run the call, and find the lowest word the call overwrote.

/// The paint: a word no real frame is likely to hold in its deepest slot.
const PAINT: u32 = 0xC0FF_EE5A;

/// Paints `[lo, hi)` (word-aligned addresses of free stack below the live frames).
///
/// # Safety
/// The range must be unused memory: below the stack pointer of the caller and above
/// every static (the linker's end of `.bss`), with no interrupt handler running on it.
#[inline(never)]
pub unsafe fn paint(lo: usize, hi: usize) {
    let mut a = lo;
    while a < hi {
        // SAFETY: per the function's contract, `a` is unused, aligned memory.
        unsafe { core::ptr::write_volatile(a as *mut u32, PAINT) };
        a += 4;
    }
}

/// Bytes of `[lo, hi)` in use since [`paint`]: `hi` minus the lowest address whose
/// word no longer holds the paint (0 if none changed).
///
/// # Safety
/// `[lo, hi)` must be readable, word-aligned memory.
#[inline(never)]
pub unsafe fn used(lo: usize, hi: usize) -> usize {
    let mut a = lo;
    while a < hi {
        // SAFETY: per the function's contract.
        if unsafe { core::ptr::read_volatile(a as *const u32) } != PAINT {
            return hi - a;
        }
        a += 4;
    }
    0
}
