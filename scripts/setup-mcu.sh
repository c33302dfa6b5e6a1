#!/usr/bin/env bash
# Installs what the firmware test (tests/mcu_qemu/) and the instruction-count
# benchmark (scripts/mcu-bench.sh) need, from the project's own files:
#
# - the Rust targets thumbv7em-none-eabihf (Cortex-M4F), thumbv7m-none-eabi
#   (Cortex-M3) and riscv32imac-unknown-none-elf (rustup); checked on every run,
#   before and independently of QEMU's cache, so a target added here reaches
#   machines that set up an older list;
# - QEMU 7.2 (qemu-system-arm for the netduinoplus2 and netduino2 boards,
#   qemu-system-riscv32 for `virt`) from Debian's packages, unpacked into a cache
#   folder without installing: `apt-get install qemu-system-arm` fails on machines
#   whose preinstalled qemu-utils 10.0 conflicts with Debian's 7.2, so the packages
#   and the shared libraries missing on this machine are fetched with `apt-get
#   download` and unpacked with `dpkg -x`.
#
# Idempotent and quiet when everything is already there. Prints nothing else on
# success. The cache folder is $GRAPHSPN_MCU_TOOLS, default
# ~/.cache/graphspn/mcu-tools; QEMU lands in $GRAPHSPN_MCU_TOOLS/qemu/usr/bin, and
# its libraries in .../qemu/usr/lib/x86_64-linux-gnu and .../qemu/lib/x86_64-linux-gnu
# (tests/mcu_qemu/ and scripts/mcu-bench.sh set LD_LIBRARY_PATH themselves).
set -euo pipefail

TARGETS=(thumbv7em-none-eabihf thumbv7m-none-eabi riscv32imac-unknown-none-elf)
TOOLS="${GRAPHSPN_MCU_TOOLS:-$HOME/.cache/graphspn/mcu-tools}"
QEMU="$TOOLS/qemu"
# Written last: its presence means the unpacked QEMU is complete and runs.
STAMP="$QEMU/.complete"

# 1. Rust targets.
installed="$(rustup target list --installed 2>/dev/null || true)"
for t in "${TARGETS[@]}"; do
    if ! grep -qx "$t" <<<"$installed"; then
        rustup target add "$t" >/dev/null 2>&1 || {
            echo "setup-mcu: rustup target add $t failed" >&2
            exit 1
        }
    fi
done

# 2. QEMU from Debian's packages (or a system-wide install, if one exists).
if [ -e "$STAMP" ]; then
    exit 0
fi
if command -v qemu-system-arm >/dev/null && command -v qemu-system-riscv32 >/dev/null; then
    exit 0
fi
for tool in apt-get apt-cache dpkg dpkg-query; do
    command -v "$tool" >/dev/null || {
        echo "setup-mcu: QEMU is missing and '$tool' is not available; install qemu-system-arm and qemu-system-misc (7.x or later) by hand" >&2
        exit 1
    }
done

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
chmod 755 "$work" # apt's sandbox user must be able to write the downloads

installed_pkg() {
    dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"
}

# Direct dependencies (first alternative of each) of the named packages.
direct_deps() {
    apt-cache depends --no-recommends --no-suggests --no-conflicts --no-breaks \
        --no-replaces --no-enhances "$@" 2>/dev/null |
        awk '/Depends:/ { if (!alt) print $2; alt = ($1 ~ /^\|/) }' | grep -v '^<' | sort -u
}

# The two emulator packages and, transitively, their dependencies that this
# machine lacks. qemu-system-common/-data (helpers, firmware images, keymaps) are
# not needed: both machines boot the ELF directly with `-bios none` / `-kernel`.
closure() {
    local want=(qemu-system-arm qemu-system-misc) seen=" " next
    while [ "${#want[@]}" -gt 0 ]; do
        next=()
        for p in "${want[@]}"; do
            case "$seen" in *" $p "*) continue ;; esac
            seen="$seen$p "
            echo "$p"
            while read -r d; do
                case "$d" in qemu-system-common | qemu-system-data) continue ;; esac
                installed_pkg "$d" || next+=("$d")
            done < <(direct_deps "$p")
        done
        want=("${next[@]+"${next[@]}"}")
    done
}

fetch() {
    local pkgs
    mapfile -t pkgs < <(closure | sort -u)
    (cd "$work" && apt-get download "${pkgs[@]}" >/dev/null 2>&1)
}

if ! fetch; then
    # Package lists may be missing or stale on a fresh machine.
    apt-get update -qq >/dev/null 2>&1 || true
    fetch || {
        echo "setup-mcu: apt-get download of QEMU's packages failed (no Debian mirror?)" >&2
        exit 1
    }
fi

rm -rf "$QEMU"
mkdir -p "$QEMU"
for deb in "$work"/*.deb; do
    dpkg -x "$deb" "$QEMU"
done
# qemu-system-misc ships ~20 emulators; keep the two the project uses (saves ~200 MB).
find "$QEMU/usr/bin" -name 'qemu-system-*' ! -name qemu-system-arm ! -name qemu-system-riscv32 -delete
rm -rf "$QEMU/usr/share/doc" "$QEMU/usr/share/man"

export LD_LIBRARY_PATH="$QEMU/usr/lib/x86_64-linux-gnu:$QEMU/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
for bin in qemu-system-arm qemu-system-riscv32; do
    "$QEMU/usr/bin/$bin" --version >/dev/null 2>&1 || {
        echo "setup-mcu: $QEMU/usr/bin/$bin does not run:" >&2
        "$QEMU/usr/bin/$bin" --version >&2 || true
        exit 1
    }
done
touch "$STAMP"
