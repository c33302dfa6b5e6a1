#!/usr/bin/env bash
# Mutation testing through the root crate's tests, for code that only generated
# modules exercise (the runtime engine, the tree-mixture driver, the generator's tree
# code). cargo-mutants limits its test targets per package, so for these it cannot run
# the root crate's generated-module tests alone; this runner applies each mutant that
# `cargo mutants --list --json --diff` lists to a scratch clone and runs the given
# test command itself.
#
# Usage:
#   cargo mutants -p graphspn-runtime -f 'runtime/src/__private/engine/*.rs' \
#     --shard 0/16 --sharding round-robin --list --json --diff > list.json
#   scripts/mutants-runner.sh list.json OUT_DIR -- cargo test --test generated_state
#
# OUT_DIR gets results.txt (one line per mutant: index, verdict (see `judge` below),
# place, what changed, seconds) and each mutant's test log; a test command still
# running after MUTANTS_TIMEOUT seconds (default 3000) is stopped; a re-run skips the
# mutants already in results.txt. With MUTANTS_RECORD=FILE (a file kept in the
# repository, e.g. docs/mutants/generator.tsv) every verdict is also appended to FILE
# as `VERDICT<tab>file<tab>mutation @+line:column` (the place counted from the
# mutated function's first line, so the record outlives edits elsewhere in the file),
# and a mutant already recorded there is skipped: a run spread over many sessions and
# scratch folders never repeats a mutant. The scratch clone is OUT_DIR/tree (from
# the current commit of this checkout; its target directory is reused between
# mutants).
# Needs git, jq and patch.
set -euo pipefail

if [[ $# -lt 4 || $3 != "--" ]]; then
    echo "usage: $0 LIST.json OUT_DIR -- TEST COMMAND..." >&2
    exit 2
fi
list=$(realpath "$1")
out=$(realpath -m "$2")
shift 3
repo=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
timeout_s=${MUTANTS_TIMEOUT:-3000}
record=${MUTANTS_RECORD:+$(realpath -m "$MUTANTS_RECORD")}
if [[ -n $record ]]; then touch "$record"; fi

mkdir -p "$out"
tree="$out/tree"
if [[ ! -d $tree ]]; then
    git clone -q "$repo" "$tree"
    git -C "$tree" checkout -q "$(git -C "$repo" rev-parse HEAD)"
fi
results="$out/results.txt"
touch "$results"

run() { (cd "$tree" && timeout -k 30 "$timeout_s" "$@"); }

# The package of a source file: its folder's Cargo.toml name (the root crate's for src/).
package_of() {
    local dir=${1%%/*}
    [[ $dir == src ]] && dir=.
    sed -n 's/^name = "\(.*\)"/\1/p' "$tree/$dir/Cargo.toml" | head -1
}

# Drops what a build stopped midway (a killed or paused runner) can leave stale, the
# workspace's own compiled crates and rustc's incremental caches: an object of the
# earlier build can refer to a symbol that a recompiled unit no longer exports, and
# the next link fails (`undefined hidden symbol … .llvm.…`). Dependencies stay built.
fresh_build() {
    rm -rf "$tree"/target/*/incremental
    local packages
    mapfile -t packages < <(cd "$tree" && cargo metadata -q --no-deps --format-version 1 |
        jq -r '.packages[].name | "-p", .')
    (cd "$tree" && cargo clean -q "${packages[@]}")
}

if ! grep -q '^baseline ' "$results"; then
    start=$SECONDS
    if ! run "$@" >"$out/baseline.log" 2>&1; then
        if ! grep -q "^error: linking with" "$out/baseline.log"; then
            echo "baseline fails: see $out/baseline.log" >&2
            exit 1
        fi
        echo "baseline: the build broke (stale objects), retried from scratch" >&2
        fresh_build
        if ! run "$@" >"$out/baseline.log" 2>&1; then
            echo "baseline fails: see $out/baseline.log" >&2
            exit 1
        fi
    fi
    echo "baseline ok $((SECONDS - start))s" >>"$results"
fi

# The verdict of the mutant now in the tree, its test log in $2: MISSED (the tests
# pass), UNVIABLE (the mutated crate does not compile; generated code that does not
# compile, a fixture or graphspn-generated, is CAUGHT), TIMEOUT (still running after
# MUTANTS_TIMEOUT seconds: a mutant that hangs or blows up the generated code, which
# counts as caught, as cargo-mutants counts it), PAUSED (stopped by the timer long
# after it was due: the runner was paused, so the mutant runs again), BROKEN (the link
# failed: the build, not the mutant) or CAUGHT.
judge() {
    local file=$1 log=$2 status=0 start=$SECONDS
    shift 2
    run "$@" >"$log" 2>&1 || status=$?
    if ((status == 0)); then
        echo MISSED
    elif ((status == 124 || status == 137)) && ((SECONDS - start > timeout_s + 60)); then
        # Stopped far past the limit: the runner was paused (`kill -STOP`), and the
        # timer fired when it went on. Not a verdict: the caller runs it again.
        echo PAUSED
    elif ((status == 124 || status == 137)); then
        echo TIMEOUT
    elif grep -q "^error: could not compile \`$(package_of "$file")\` (lib" "$log"; then
        echo UNVIABLE
    elif grep -q "^error: linking with" "$log"; then
        echo BROKEN
    else
        echo CAUGHT
    fi
}

count=$(jq length "$list")
for ((i = 0; i < count; i++)); do
    grep -qE "^$i (CAUGHT|MISSED|UNVIABLE|TIMEOUT) " "$results" && continue
    file=$(jq -r ".[$i].file" "$list")
    line=$(jq -r ".[$i].span.start.line" "$list")
    what=$(jq -r ".[$i].name" "$list" | sed 's/^[^ ]* //')
    # Where in its function (absolute when it is in none): tells apart the same
    # mutation twice in one function.
    at=$(jq -r ".[$i] | \"@+\(.span.start.line - (.function.span.start.line // 0)):\(.span.start.column)\"" "$list")
    # Read to the end (no `grep -q` on a pipe: under `pipefail` its early exit fails
    # the pipeline with SIGPIPE, and a mutant recorded early in the file ran again).
    if [[ -n $record ]] && key="$file"$'\t'"$what $at" awk -F'\t' \
        '$2 "\t" $3 == ENVIRON["key"] { found = 1 } END { exit !found }' "$record"; then
        continue
    fi
    start=$SECONDS
    git -C "$tree" checkout -q -- .
    if ! jq -r ".[$i].diff" "$list" | (cd "$tree" && patch -s "$file"); then
        verdict=NOPATCH
    else
        verdict=$(judge "$file" "$out/$i.log" "$@")
        if [[ $verdict == BROKEN ]]; then
            # The linker failed on objects of an earlier build (see `fresh_build`).
            # Not a verdict on the mutant: rebuild the workspace's crates and run it
            # once more.
            echo "$i: the build broke (stale objects), retried from scratch" >&2
            fresh_build
            verdict=$(judge "$file" "$out/$i.log" "$@")
        fi
        while [[ $verdict == PAUSED ]]; do
            echo "$i: the runner was paused past the time limit, run again" >&2
            verdict=$(judge "$file" "$out/$i.log" "$@")
        done
    fi
    git -C "$tree" checkout -q -- .
    echo "$i $verdict $file:$line $what $((SECONDS - start))s" >>"$results"
    # A diff that does not apply says the list and the clone differ, and a build that
    # broke twice says nothing of the mutant either: neither is recorded, so the
    # mutant runs again (from a list that fits).
    if [[ -n $record && $verdict != NOPATCH && $verdict != BROKEN ]]; then
        printf '%s\t%s\t%s\n' "$verdict" "$file" "$what $at" >>"$record"
    fi
done
echo "done: $(grep -c ' CAUGHT ' "$results") caught, $(grep -c ' TIMEOUT ' "$results") timeouts, $(grep -c ' MISSED ' "$results") missed, $(grep -c ' UNVIABLE ' "$results") unviable"
