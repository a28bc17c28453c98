#!/usr/bin/env bash
# The project's test command: installs what a fresh machine lacks (scripts/setup.sh), then runs
# every test of the workspace (unit, golden-byte, property, snapshot, fuzz-regression, engine,
# DDS interop) with cargo-nextest and the doc tests with `cargo test --doc`, then builds the protocol fuzz targets on
# stable and runs each briefly. What does not fit CI's time budget (PhysX, the other gap-effect cases, the engine
# fuzz target) runs in scripts/nightly.sh.
#   ULAB_FUZZ_SECONDS=0 skips the fuzz smoke run (default 10 s per target; the nightly run fuzzes for longer).
set -euo pipefail
cd "$(dirname "$0")/.."
# Wall time of each phase, printed so that a CI log shows where its time budget goes.
phase() { echo "test.sh: $1 done after ${SECONDS} s"; }
bash scripts/setup.sh
phase setup
source scripts/env.sh
export CARGO_TERM_COLOR=never
# A clean clone compiles everything once: incremental compilation's bookkeeping only costs time there. CI also
# builds the workspace's crates without debug info (dependencies have none anyway, Cargo.toml): a failing test still
# names its file and line, which the panic carries, and only a backtrace loses line numbers; rustc spends about a
# sixth less CPU on a workspace crate (gap-diagnosis, library and tests: 25.5 vs 30.1 CPU s) and the build scripts
# compile the engines' C++ glue without -g (DART's: 15.8 vs 23.5 s, 0.8 vs 25 MB linked into every binary using it).
if [ "${CI:-}" = true ]; then export CARGO_INCREMENTAL=0 CARGO_PROFILE_DEV_DEBUG=0; fi
# Snapshot tests must fail on a mismatch, never write new snapshots.
export INSTA_UPDATE=no
# Hygiene gate (issue 18), before the tests: formatting; no dependency its sources never name (scripts/unused_deps.py);
# no import cycle between the top-level modules of a crate (scripts/module_cycles.py); clippy with the workspace lints
# and warnings denied over every target (libraries, binaries, tests, benches); the docs of the crates meant for
# publication without a broken link or any other rustdoc warning (the other crates' docs are read in their sources).
cargo fmt --all --check
python3 scripts/unused_deps.py
python3 scripts/module_cycles.py
phase "hygiene gate (sources)"
# Clippy runs inside the test build instead of before it: `cargo clippy` is cargo with clippy-driver as the workspace
# crates' compiler and its arguments in CLIPPY_ARGS, so this one build lints every target as `cargo clippy
# --workspace --all-targets -- -D warnings` does and compiles the test binaries in the same rustc run, where a
# separate clippy pass analysed the whole workspace a second time (issue 58). The two variables stay exported: the
# test binaries' fingerprints include them, so nextest and the doc tests reuse this build instead of redoing it.
# Dependencies are not workspace crates and are compiled by plain rustc, as under `cargo clippy`.
RUSTC_WORKSPACE_WRAPPER="$(rustc --print sysroot)/bin/clippy-driver"
export RUSTC_WORKSPACE_WRAPPER
export CLIPPY_ARGS="-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__"
# --timings writes target/cargo-timings/cargo-timing.html: which crates the build waits on, for the CI time budget.
cargo test --workspace --all-targets --locked --no-run --timings
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --locked --quiet -p unitree-idl -p lowlevel-codec -p dds-transport -p recording
phase "clippy, docs and test build"
# A failing test does not skip the doc tests or the fuzz smoke run: one CI log reports all; the exit status keeps the
# failure. nextest runs each test in its own process, two at a time on two cores (.config/nextest.toml: the slow-test
# report, no retries, real-time tests one at a time); it does not run doc tests, `cargo test --doc` does.
logs=target/test-logs
mkdir -p "$logs"
status=0
cargo nextest run --workspace --locked --profile ci 2>&1 | tee "$logs/nextest.log" || status=$?
phase "nextest (exit $status)"
cargo test --doc --workspace --locked 2>&1 | tee "$logs/doctest.log" || status=$?
phase "doc tests (exit $status)"
# The CI demo's videos (crates/ulab/tests/it/deploy_sim.rs): one MP4 per engine and policy, kept in the test output.
if compgen -G "target/tmp/ci-demo/*.mp4" > /dev/null; then
  echo "test.sh: CI demo videos:"
  ls -l target/tmp/ci-demo/*.mp4
fi
if [ "${ULAB_FUZZ_SECONDS:-10}" != 0 ]; then
  # The fuzz crate is its own workspace, built on other flags: plain rustc, as `cargo fuzz` would.
  env -u RUSTC_WORKSPACE_WRAPPER -u CLIPPY_ARGS bash scripts/fuzz.sh smoke "${ULAB_FUZZ_SECONDS:-10}" || status=$?
  phase "fuzz smoke"
fi
# The number of tests run, last: nextest's summary line plus the doc tests' result lines.
python3 - "$logs/nextest.log" "$logs/doctest.log" <<'PY'
import re, sys
def count(pattern, text, word):
    return sum(int(n) for line in re.findall(pattern, text, re.M) for n in re.findall(r"(\d+) " + word, line))
nextest = open(sys.argv[1], encoding="utf-8", errors="replace").read()
summary = re.findall(r"^\s*Summary \[.*\] (\d+) tests? run: (.*)$", nextest, re.M)
doc = open(sys.argv[2], encoding="utf-8", errors="replace").read()
results = r"^test result: .*$"
d = {w: count(results, doc, w) for w in ("passed", "failed", "ignored")}
if summary:
    line = summary[-1][1]
    n = {w: sum(int(x) for x in re.findall(r"(\d+) " + w, line)) for w in ("passed", "failed", "timed out", "skipped")}
    failed = n["failed"] + n["timed out"]
    print(f"test.sh: nextest ran {summary[-1][0]} tests: {n['passed']} passed, {failed} failed, {n['skipped']} skipped")
print(f"test.sh: doc tests: {d['passed']} passed, {d['failed']} failed, {d['ignored']} ignored")
if summary:
    print(f"tests: {n['passed'] + d['passed']} passed, {failed + d['failed']} failed, {n['skipped'] + d['ignored']} skipped")
else:
    print("test.sh: no nextest summary (its run did not finish), so no total")
PY
exit "$status"
