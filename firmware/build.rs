//! Linker scripts: cortex-m-rt's `link.x` with the boards' `memory.x` on
//! Cortex-M (M4F and M3), the firmware's own `rv32.x` on RISC-V; nothing on the
//! host.

use std::path::PathBuf;

fn main() {
    let target = std::env::var("TARGET").expect("set by cargo");
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("set by cargo"));
    let dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    println!("cargo:rerun-if-changed=build.rs");
    let script = if target.starts_with("thumbv") {
        "memory.x"
    } else if target.starts_with("riscv32") {
        "rv32.x"
    } else {
        return;
    };
    println!("cargo:rerun-if-changed={script}");
    std::fs::copy(dir.join(script), out.join(script)).expect("copy the linker script");
    println!("cargo:rustc-link-search={}", out.display());
    if script == "memory.x" {
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=--nmagic");
    } else {
        println!("cargo:rustc-link-arg-bins=-Trv32.x");
    }
}
