#!/usr/bin/env bash
# Runs a firmware ELF under QEMU with exact instruction counting (-icount shift=0):
# Cortex-M (ARM ELF) on the netduinoplus2 board with semihosting, RISC-V on `virt`
# with the UART on stdout. QEMU from scripts/setup-mcu.sh's cache, else from PATH.
# Usage: scripts/mcu-run.sh ELF   (also the cargo runner in firmware/.cargo/config.toml)
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
40) exec qemu-system-arm -M netduinoplus2 -nographic -monitor none -serial null \
    -semihosting-config enable=on,target=native -icount shift=0 -kernel "$elf" ;;
243) exec qemu-system-riscv32 -M virt -bios none -nographic -monitor none -serial stdio \
    -icount shift=0 -kernel "$elf" ;;
*)
    echo "mcu-run: $elf is neither an ARM nor a RISC-V ELF (e_machine $machine)" >&2
    exit 2
    ;;
esac
