#!/usr/bin/env bash
# Reproduces the rediscovery table of BENCHMARKS.md: builds the MuJoCo reference and one adapter per
# pinned rapier version (each its own workspace and Cargo.lock), runs the same scenes and oracles on
# each, and prints the tables. Not part of scripts/test.sh: it compiles seven rapier versions.
#   bash bench/rediscovery/run.sh            # from the repository root
# Environment: CARGO_TARGET_DIR (default target-rediscovery), REDISCOVERY_NICE (default 0).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
# shellcheck source=/dev/null
source "$root/scripts/env.sh"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target-rediscovery}"
out="$CARGO_TARGET_DIR/rediscovery-out"
mkdir -p "$out"
nice_cmd=(nice -n "${REDISCOVERY_NICE:-0}")
adapters=(rapier-0_17_2 rapier-0_18_0 rapier-0_20_0 rapier-0_34_0 rapier-0_35_0_beta_0 rapier-0_35_0 rapier-0_36_1)

build_and_run() { # manifest, package, output file
    local t0 t1
    t0=$(date +%s)
    "${nice_cmd[@]}" cargo build --quiet --locked --manifest-path "$1" -p "$2" --bins
    t1=$(date +%s)
    "${nice_cmd[@]}" cargo run --quiet --locked --manifest-path "$1" -p "$2" > "$3"
    echo "$2: build $((t1 - t0)) s, run $(( $(date +%s) - t1 )) s" >&2
}

build_and_run "$here/Cargo.toml" rediscovery-reference "$out/reference.jsonl"
files=("$out/reference.jsonl")
for a in "${adapters[@]}"; do
    pkg=$(sed -n 's/^name = "\(.*\)"/\1/p' "$here/adapters/$a/Cargo.toml" | head -1)
    build_and_run "$here/adapters/$a/Cargo.toml" "$pkg" "$out/$a.jsonl"
    files+=("$out/$a.jsonl")
done
"${nice_cmd[@]}" cargo run --quiet --locked --manifest-path "$here/Cargo.toml" -p rediscovery-harness --bin report -- "${files[@]}"
