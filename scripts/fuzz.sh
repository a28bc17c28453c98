#!/usr/bin/env bash
# Builds and runs the fuzz targets on stable Rust without cargo-fuzz: the same sanitizer-coverage
# instrumentation cargo-fuzz asks rustc for (`-s none`: no address sanitizer, which needs nightly).
#   scripts/fuzz.sh build               build every target
#   scripts/fuzz.sh build-protocol      build the protocol targets only (no physics engine; .clusterfuzzlite/build.sh)
#   scripts/fuzz.sh run TARGET SECONDS  fuzz TARGET from its seed corpus for SECONDS
#   scripts/fuzz.sh smoke SECONDS       run the protocol targets for SECONDS each (CI), with a fixed libFuzzer
#                                       seed so that a red smoke run replays the same inputs on the same commit
#   scripts/fuzz.sh smoke-all SECONDS   the same for every target, engine_divergence included (nightly: its
#                                       release build of three engines with coverage takes minutes)
# Seeds: fuzz/corpus/TARGET/{seeds,regressions} (fuzz/corpus/README.md). New crashes land in fuzz/artifacts/TARGET/;
# copy minimized ones to fuzz/corpus/TARGET/regressions/. With cargo-fuzz and nightly (address sanitizer):
# `cargo +nightly fuzz run TARGET` (scripts/setup.sh --fuzz installs cargo-fuzz).
set -euo pipefail
cd "$(dirname "$0")/.."
PROTOCOL_TARGETS=(decode_any crc roundtrip)
TARGETS=("${PROTOCOL_TARGETS[@]}" engine_divergence)
export RUSTFLAGS="--cfg fuzzing -Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares -Cdebug-assertions -Coverflow-checks"
BIN=fuzz/target/x86_64-unknown-linux-gnu/release

# build [TARGET...]: the named targets (default: every target; engine_divergence needs the fuzz crate's `engine`
# feature, which pulls in the physics engines).
build() {
  local bins=(--bins --features engine)
  if [ $# -gt 0 ]; then bins=(); for t in "$@"; do bins+=(--bin "$t"); [ "$t" = engine_divergence ] && bins+=(--features engine); done; fi
  cargo build --quiet --release --manifest-path fuzz/Cargo.toml --target x86_64-unknown-linux-gnu "${bins[@]}"
}

run() {
  local target=$1 seconds=$2 seed=${3:-0} work
  work=$(mktemp -d)
  mkdir -p "fuzz/artifacts/$target"
  # Work corpus in a temp dir: the committed seeds and regressions are only read, and the inputs a local
  # `cargo fuzz run` left beside them are not (a CI run starts from what is committed). Only folders that exist:
  # git does not keep empty ones, and libFuzzer refuses a missing one.
  local dirs=("$work")
  for d in "fuzz/corpus/$target/seeds" "fuzz/corpus/$target/regressions"; do [ -d "$d" ] && dirs+=("$d"); done
  local status=0
  # -seed=0 asks libFuzzer for a random seed.
  "$BIN/$target" -seed="$seed" -max_total_time="$seconds" -print_final_stats=1 -artifact_prefix="fuzz/artifacts/$target/" \
    "${dirs[@]}" > "$work.log" 2>&1 || status=$?
  grep -E "^(#[0-9]+.*DONE|stat::number_of_executed_units|==[0-9]+==|SUMMARY|ERROR)" "$work.log" || true
  if [ "$status" != 0 ]; then tail -n 30 "$work.log"; echo "fuzz: $target failed (exit $status)" >&2; fi
  rm -f "$work.log"
  rm -rf "$work"
  return "$status"
}

case "${1:-}" in
  build) build ;;
  build-protocol) build "${PROTOCOL_TARGETS[@]}" ;;
  run) build "$2"; run "$2" "$3" ;;
  smoke)
    build "${PROTOCOL_TARGETS[@]}"
    for t in "${PROTOCOL_TARGETS[@]}"; do echo "fuzz: $t for ${2}s"; run "$t" "$2" 1; done ;;
  smoke-all)
    build
    for t in "${TARGETS[@]}"; do echo "fuzz: $t for ${2}s"; run "$t" "$2" 1; done ;;
  *) echo "usage: $0 build | build-protocol | run TARGET SECONDS | smoke SECONDS | smoke-all SECONDS" >&2; exit 2 ;;
esac
