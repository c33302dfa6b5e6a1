//! The host build: the same report on stdout, without instruction counts or stack.

use crate::Measured;
use crate::calls::CallResult;

/// Name printed in the report's first line.
pub const TARGET: &str = "host";

/// No counter on the host: all zero.
pub fn calibrate() -> (u64, u64, u64) {
    (0, 0, 0)
}

/// Not measured on the host: 0.
pub fn static_ram() -> usize {
    0
}

/// Runs `f` (no counts).
pub fn measure(f: fn() -> CallResult) -> Measured {
    Measured {
        result: std::hint::black_box(f)(),
        instructions: 0,
        stack: 0,
    }
}

/// `core::fmt::Write` on stdout.
struct Stdout(String);

impl core::fmt::Write for Stdout {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.0.push_str(s);
        Ok(())
    }
}

/// Prints the report.
pub fn main() {
    let mut out = Stdout(String::new());
    crate::run(&mut out).expect("formatting into a String cannot fail");
    print!("{}", out.0);
}
