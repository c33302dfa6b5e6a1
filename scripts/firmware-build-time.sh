#!/usr/bin/env bash
# Clean-build time of a user-style firmware (firmware/: two compiled maps, Cortex-M4F)
# under different profiles for the build script that generates the maps. Prints one
# line per variant: wall and CPU seconds of `cargo build --release --target
# thumbv7em-none-eabihf` from an empty target folder, and how long the maps' build
# script (the code generation) ran.
#
#   build-override  [profile.release.build-override] opt-level = 3: every build
#                   script, proc macro and their dependencies optimised (syn,
#                   serde_derive, thiserror-impl, prettyplease, ...)
#   none            no override: build scripts at opt-level 0 (Cargo's default)
#   compiler        [profile.release.package.graphspn-compiler] opt-level = 3: only
#                   the code generator optimised (what firmware/Cargo.toml and the
#                   README recommend)
#   compiler+print  graphspn-compiler, prettyplease and proc-macro2 at opt-level 3
#
# Each variant builds a copy of firmware/ whose profile section is replaced (the
# rest of the repository is linked in, so the paths resolve as in firmware/), in
# its own target folder under $TMPDIR, one variant after the other.
#
# Usage: scripts/firmware-build-time.sh [VARIANT...]   (default: all four)
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$PWD"
bash scripts/setup-mcu.sh
TARGET=thumbv7em-none-eabihf
VARIANTS=("$@")
[ "${#VARIANTS[@]}" -gt 0 ] || VARIANTS=(build-override none compiler compiler+print)
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

profile() {
    case "$1" in
    build-override) printf '[profile.release.build-override]\nopt-level = 3\n' ;;
    none) ;;
    compiler) printf '[profile.release.package.graphspn-compiler]\nopt-level = 3\n' ;;
    compiler+print)
        printf '[profile.release.package.graphspn-compiler]\nopt-level = 3\n'
        printf '[profile.release.package.prettyplease]\nopt-level = 3\n'
        printf '[profile.release.package.proc-macro2]\nopt-level = 3\n'
        ;;
    *)
        echo "unknown variant $1" >&2
        exit 2
        ;;
    esac
}

(cd firmware && cargo fetch --quiet)
printf '%-16s %8s %8s %10s\n' variant wall_s cpu_s codegen_s
for v in "${VARIANTS[@]}"; do
    tree="$work/$v"
    mkdir -p "$tree"
    for entry in "$ROOT"/*; do
        case "$(basename "$entry")" in firmware | target) ;; *) ln -s "$entry" "$tree/" ;; esac
    done
    ln -s "$ROOT/.cargo" "$tree/.cargo"
    mkdir "$tree/firmware"
    (cd firmware && tar --exclude=./target -cf - .) | (cd "$tree/firmware" && tar -xf -)
    # Drop the build script's profile sections, then add the variant's.
    awk '/^\[/ { skip = ($0 == "[profile.release.build-override]" || $0 ~ /^\[profile\.release\.package\.(graphspn-compiler|prettyplease|proc-macro2)\]$/) }
         !skip' firmware/Cargo.toml >"$tree/firmware/Cargo.toml"
    profile "$v" >>"$tree/firmware/Cargo.toml"
    times="$work/$v.time"
    (cd "$tree/firmware" &&
        CARGO_TARGET_DIR="$work/$v-target" /usr/bin/time -f '%e %U %S' -o "$times" \
            cargo build --quiet --offline --release --target "$TARGET" --timings 2>"$work/$v.log") || {
        cat "$work/$v.log" >&2
        exit 1
    }
    read -r wall user sys <"$times"
    # The timings report lists every unit; the maps crate's build-script run is the
    # code generation.
    html="$(ls "$work/$v-target"/cargo-timings/cargo-timing-*.html | head -n1)"
    codegen="$(awk -F': ' '/"name":/ { name = $2 } /"mode":/ { mode = $2 }
        /"duration":/ && name ~ /"graphspn-firmware-maps"/ && mode ~ /"run-custom-build"/ { sub(/,$/, "", $2); print $2; exit }' "$html")"
    printf '%-16s %8.1f %8.1f %10s\n' "$v" "$wall" "$(echo "$user + $sys" | bc)" "${codegen:-?}"
    [ -n "${KEEP:-}" ] && cp "$html" "$KEEP/$v.html"
    rm -rf "$work/$v-target"
done
