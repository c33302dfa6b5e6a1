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
#   none            no override: build scripts at opt-level 0 (Cargo's default; what
#                   firmware/Cargo.toml and the README recommend)
#   compiler        [profile.release.package.graphspn-compiler] opt-level = 3: only
#                   the code generator optimised
#   compiler+print  graphspn-compiler, prettyplease and proc-macro2 at opt-level 3
#
# Each variant builds a copy of firmware/ whose profile section is replaced (the
# rest of the repository is linked in, so the paths resolve as in firmware/), in
# its own target folder under $TMPDIR, one variant after the other.
#
# With GRAPHSPN_BIG_MAP=FILE (a JSON map, e.g. from `graphspn generate --places
# 10000`), each variant's build script is also run once more on FILE in place of the
# demo floor (same model, 5 decompositions), and that code generation is timed too
# (median of three runs).
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
big="${GRAPHSPN_BIG_MAP:-}"
if [ -n "$big" ]; then
    # The maps' build script reads CARGO_MANIFEST_DIR/../../generated/demo.
    mkdir -p "$work/big/generated/demo" "$work/big/a/maps"
    cp generated/demo/model.json generated/demo/saarbrucken_seq2_night1.json "$work/big/generated/demo/"
    cp "$big" "$work/big/generated/demo/floor.json"
fi
printf '%-16s %8s %8s %10s %s\n' variant wall_s cpu_s codegen_s "${big:+big_map_codegen_s}"
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
    big_s=""
    if [ -n "$big" ]; then
        script="$(ls "$work/$v-target"/release/build/graphspn-firmware-maps-*/build-script-build | head -n1)"
        mkdir -p "$work/big/out"
        # The median of three runs.
        big_s="$(for _ in 1 2 3; do
            CARGO_MANIFEST_DIR="$work/big/a/maps" OUT_DIR="$work/big/out" TARGET="$TARGET" \
                /usr/bin/time -f '%e' "$script" 2>&1 >/dev/null | tail -n1
        done | sort -n | sed -n 2p)"
    fi
    printf '%-16s %8.1f %8.1f %10s %s\n' "$v" "$wall" "$(echo "$user + $sys" | bc)" "${codegen:-?}" "$big_s"
    [ -n "${KEEP:-}" ] && cp "$html" "$KEEP/$v.html"
    rm -rf "$work/$v-target"
done
