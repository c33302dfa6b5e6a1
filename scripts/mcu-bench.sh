#!/usr/bin/env bash
# Instruction-count benchmark of the generated code on emulated microcontrollers:
# builds firmware/ for Cortex-M4F (thumbv7em-none-eabihf, QEMU netduinoplus2),
# Cortex-M3 without FPU (thumbv7m-none-eabi, QEMU netduino2) and RV32IMAC
# (riscv32imac-unknown-none-elf, QEMU virt) in three profiles, runs each under QEMU
# with -icount shift=0 (exact instruction counts; scripts/mcu-run.sh, which picks
# the board) and prints one table per map:
#
#   release   opt-level 3 everywhere
#   size      opt-level "s", the generated maps crate and its numerics at 3
#   size-all  opt-level "s" everywhere (no override)
#
# Four modules: both demo maps, each compiled with the GraphSPN model and with the
# tree mixture (`*_trees`).
#
# flash: bytes of machine code and tables of the map's generated module (symbol
# sizes, `nm`), and in brackets the whole firmware's .text + .rodata (`size`); a tree
# mixture's machine code is mostly the runtime's generic tree driver, whose
# monomorphisations (all tree modules together) are printed below the tables;
# RAM: the map's buffers (evidence, marginals, two label arrays, the streaming state;
# the firmware's `buffers=`, one module's share of the .bss arena) + the largest peak
# stack of its calls. Stack and instructions per call:
# log_likelihood / marginals / mpe / labelled_log_likelihood. Streaming step: median
# instructions of one `State::observe` + `marginals` (all places) and of one
# `observe` + `marginal(place)`, with how many times fewer than one stateless
# `marginals` call.
#
# Usage: scripts/mcu-bench.sh [PROFILE...]   (default: release size size-all)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup-mcu.sh
export CARGO_TARGET_DIR="$PWD/target/firmware"
PROFILES=("$@")
[ "${#PROFILES[@]}" -gt 0 ] || PROFILES=(release size size-all)
TARGETS=(thumbv7em-none-eabihf thumbv7m-none-eabi riscv32imac-unknown-none-elf)
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT

for p in "${PROFILES[@]}"; do
    (cd firmware && cargo build --quiet --profile "$p" "${TARGETS[@]/#/--target=}")
    for t in "${TARGETS[@]}"; do
        elf="$CARGO_TARGET_DIR/$t/$p/graphspn-firmware"
        timeout 600 bash scripts/mcu-run.sh "$elf" | tr -d '\r' >"$out/$t.$p.txt"
        size -A "$elf" | awk '$1 == ".text" || $1 == ".rodata" { s += $2 } END { print "total", s }' >"$out/$t.$p.size"
        # Bytes per map module: code (t/T) and tables (r/R/d/D) of its symbols; the tree driver.
        nm -S -t d -C "$elf" | awk '
            NF >= 4 && $4 ~ /^graphspn_firmware_maps::/ && $3 !~ /^[bB]$/ {
                name = $4; sub(/^graphspn_firmware_maps::/, "", name); sub(/::.*/, "", name)
                flash[name] += $2 + 0
            }
            NF >= 4 && $4 ~ /^graphspn_runtime::__private::(tree|soft_float)::/ { tree += $2 + 0 }
            NF >= 4 && $4 == "<graphspn_runtime::__private::soft_float::SoftF32" { tree += $2 + 0 }
            END { for (m in flash) print m, flash[m]; print "tree_driver", tree + 0 }' >>"$out/$t.$p.size"
    done
done

for map in demo_floor saarbrucken_seq2_night1 demo_floor_trees saarbrucken_seq2_night1_trees; do
    echo
    echo "### $map"
    echo
    echo "| target | profile | flash: map (firmware) | RAM: buffers + peak stack | stack per call (B) | instructions per call | streaming step: observe + marginals / observe + marginal |"
    echo "|---|---|---|---|---|---|---|"
    for t in "${TARGETS[@]}"; do
        for p in "${PROFILES[@]}"; do
            awk -v map="$map" -v t="${t%%-*}" -v p="$p" -v sizes="$out/$t.$p.size" '
                BEGIN {
                    while ((getline l < sizes) > 0) {
                        split(l, f, " ")
                        if (f[1] == "total") total = f[2]
                        else if (f[1] == map) flash = f[2]
                    }
                }
                function median(a, n,    i, j, x) {
                    for (i = 2; i <= n; i++) {
                        x = a[i]
                        for (j = i - 1; j >= 1 && a[j] > x; j--) a[j + 1] = a[j]
                        a[j + 1] = x
                    }
                    return a[int(n / 2) + 1]
                }
                $1 == "map" {
                    on = ($2 == map)
                    if (on) for (q = 3; q <= NF; q++) if ($q ~ /^buffers=/) buffers = substr($q, 9) + 0
                }
                on && $1 == "call" {
                    split($3, i, "="); split($4, s, "=")
                    ins = ins sep i[2]; st = st sep s[2]; sep = " / "
                    if (s[2] + 0 > peak) peak = s[2] + 0
                    if ($2 == "marginals") full = i[2]
                }
                on && $1 == "stream" { split($4, s, "="); if (s[2] + 0 > peak) peak = s[2] + 0 }
                on && $1 == "step" {
                    split($5, i, "="); split($6, s, "=")
                    if (s[2] + 0 > peak) peak = s[2] + 0
                    if ($3 == "observe_marginals") all[++na] = i[2] + 0
                    else one[++no] = i[2] + 0
                }
                END {
                    ma = median(all, na); mo = median(one, no)
                    printf "| %s | %s | %d (%d) | %d + %d = %d | %s | %s | %d (%.1fx) / %d (%.1fx) |\n",
                        t, p, flash, total, buffers, peak, buffers + peak, st, ins,
                        ma, full / ma, mo, full / mo
                }' "$out/$t.$p.txt"
        done
    done
done
echo
echo "### tree-mixture driver (graphspn_runtime::__private::tree and SoftF32's out-of-line row operations, every tree module's monomorphisations)"
echo
for t in "${TARGETS[@]}"; do
    for p in "${PROFILES[@]}"; do
        awk -v t="${t%%-*}" -v p="$p" '$1 == "tree_driver" { printf "- %s %s: %d bytes of machine code\n", t, p, $2 }' "$out/$t.$p.size"
    done
done
