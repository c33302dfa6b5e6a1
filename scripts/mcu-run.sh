#!/usr/bin/env bash
# Runs a firmware ELF under QEMU with exact instruction counting (-icount shift=0):
# Cortex-M (ARM ELF) with semihosting, on the netduinoplus2 board (Cortex-M4F) if the
# ELF uses the hard-float ABI (thumbv7em-none-eabihf), else on netduino2 (Cortex-M3,
# no FPU: thumbv7m-none-eabi); RISC-V on `virt` with the UART on stdout. QEMU from
# scripts/setup-mcu.sh's cache, else from PATH.
# Usage: scripts/mcu-run.sh ELF   (also the cargo runner in firmware/.cargo/config.toml,
# and what scripts/mcu-bench.sh runs)
set -euo pipefail
elf="$1"
QEMU="${GRAPHSPN_MCU_TOOLS:-$HOME/.cache/graphspn/mcu-tools}/qemu"
if [ -e "$QEMU/.complete" ]; then
    export PATH="$QEMU/usr/bin:$PATH"
    export LD_LIBRARY_PATH="$QEMU/usr/lib/x86_64-linux-gnu:$QEMU/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
fi
# e_machine (ELF header offset 18): 40 = ARM, 243 = RISC-V.
machine="$(od -An -t u2 -j 18 -N 2 "$elf" | tr -d ' ')"
case "$machine" in
40)
    # e_flags (offset 36 of an ELF32 header): EF_ARM_ABI_FLOAT_HARD = 0x400 (rustc
    # sets it for thumbv7em-none-eabihf, EF_ARM_ABI_FLOAT_SOFT = 0x200 for
    # thumbv7m-none-eabi; `readelf -h`). A soft-float ELF for a Cortex-M4 or M7
    # (thumbv7em-none-eabi) would need netduinoplus2 too: not a target of this project.
    flags="$(od -An -t u4 -j 36 -N 4 "$elf" | tr -d ' ')"
    if [ $((flags & 0x400)) -ne 0 ]; then board=netduinoplus2; else board=netduino2; fi
    exec qemu-system-arm -M "$board" -nographic -monitor none -serial null \
        -semihosting-config enable=on,target=native -icount shift=0 -kernel "$elf"
    ;;
243) exec qemu-system-riscv32 -M virt -bios none -nographic -monitor none -serial stdio \
    -icount shift=0 -kernel "$elf" ;;
*)
    echo "mcu-run: $elf is neither an ARM nor a RISC-V ELF (e_machine $machine)" >&2
    exit 2
    ;;
esac
