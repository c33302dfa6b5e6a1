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
# OUT_DIR gets results.txt (one line per mutant: index, CAUGHT / MISSED / UNVIABLE (the
# mutated crate does not compile; generated code that does not compile is CAUGHT),
# place, what changed, seconds) and each mutant's test log; a re-run skips the
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

run() { (cd "$tree" && timeout "$timeout_s" "$@"); }

# The package of a source file: its folder's Cargo.toml name (the root crate's for src/).
package_of() {
    local dir=${1%%/*}
    [[ $dir == src ]] && dir=.
    sed -n 's/^name = "\(.*\)"/\1/p' "$tree/$dir/Cargo.toml" | head -1
}

if ! grep -q '^baseline ' "$results"; then
    start=$SECONDS
    if ! run "$@" >"$out/baseline.log" 2>&1; then
        echo "baseline fails: see $out/baseline.log" >&2
        exit 1
    fi
    echo "baseline ok $((SECONDS - start))s" >>"$results"
fi

count=$(jq length "$list")
for ((i = 0; i < count; i++)); do
    grep -q "^$i " "$results" && continue
    file=$(jq -r ".[$i].file" "$list")
    line=$(jq -r ".[$i].span.start.line" "$list")
    what=$(jq -r ".[$i].name" "$list" | sed 's/^[^ ]* //')
    # Where in its function (absolute when it is in none): tells apart the same
    # mutation twice in one function.
    at=$(jq -r ".[$i] | \"@+\(.span.start.line - (.function.span.start.line // 0)):\(.span.start.column)\"" "$list")
    if [[ -n $record ]] && cut -f2,3 "$record" | grep -qxF "$file"$'\t'"$what $at"; then
        continue
    fi
    start=$SECONDS
    git -C "$tree" checkout -q -- .
    if ! jq -r ".[$i].diff" "$list" | (cd "$tree" && patch -s "$file"); then
        verdict=NOPATCH
    elif run "$@" >"$out/$i.log" 2>&1; then
        verdict=MISSED
    elif grep -q "^error: could not compile \`$(package_of "$file")\` (lib" "$out/$i.log"; then
        # The mutated crate itself does not compile. Generated code that does not
        # compile (a fixture, graphspn-generated) is a caught mutant.
        verdict=UNVIABLE
    else
        verdict=CAUGHT
    fi
    git -C "$tree" checkout -q -- .
    echo "$i $verdict $file:$line $what $((SECONDS - start))s" >>"$results"
    # A diff that does not apply says the list and the clone differ, nothing of the
    # mutant: it is not recorded, so it runs again from a list that fits.
    if [[ -n $record && $verdict != NOPATCH ]]; then
        printf '%s\t%s\t%s\n' "$verdict" "$file" "$what $at" >>"$record"
    fi
done
echo "done: $(grep -c ' CAUGHT ' "$results") caught, $(grep -c ' MISSED ' "$results") missed, $(grep -c ' UNVIABLE ' "$results") unviable"
