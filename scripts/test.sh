#!/usr/bin/env bash
# The project's test command: installs what a fresh machine lacks (scripts/setup.sh), then runs
# every test of the workspace (unit, golden-byte, property, snapshot, fuzz-regression, engine,
# DDS interop), then builds the protocol fuzz targets on stable and runs each briefly. What does not fit CI's
# time budget (PhysX, the other gap-effect cases, the engine fuzz target) runs in scripts/nightly.sh.
#   ULAB_FUZZ_SECONDS=0 skips the fuzz smoke run (default 10 s per target; the nightly run fuzzes for longer).
set -euo pipefail
cd "$(dirname "$0")/.."
# Wall time of each phase, printed so that a CI log shows where its time budget goes.
phase() { echo "test.sh: $1 done after ${SECONDS} s"; }
bash scripts/setup.sh
phase setup
source scripts/env.sh
export CARGO_TERM_COLOR=never
# Snapshot tests must fail on a mismatch, never write new snapshots.
export INSTA_UPDATE=no
# Hygiene gate (issue 18), before the tests: formatting, clippy with the workspace lints and warnings denied, and
# the docs of every crate without a broken link; no dependency its sources never name (scripts/unused_deps.py); no import cycle
# between the top-level modules of a crate (scripts/module_cycles.py).
cargo fmt --all --check
python3 scripts/unused_deps.py
python3 scripts/module_cycles.py
cargo clippy --workspace --all-targets --locked -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked --quiet
phase "hygiene gate"
cargo test --workspace --locked --no-run
phase build
# A failing test does not skip the fuzz smoke run: one CI log reports both; the exit status keeps the failure.
status=0
cargo test --workspace --locked --no-fail-fast || status=$?
phase "cargo test (exit $status)"
# The CI demo's videos (crates/ulab/tests/deploy_sim.rs): one MP4 per engine and policy, kept in the test output.
if compgen -G "target/tmp/ci-demo/*.mp4" > /dev/null; then
  echo "test.sh: CI demo videos:"
  ls -l target/tmp/ci-demo/*.mp4
fi
if [ "${ULAB_FUZZ_SECONDS:-10}" != 0 ]; then
  bash scripts/fuzz.sh smoke "${ULAB_FUZZ_SECONDS:-10}" || status=$?
  phase "fuzz smoke"
fi
exit "$status"
