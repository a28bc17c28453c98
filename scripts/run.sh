#!/usr/bin/env bash
# The main job on the built-in default: installs what a fresh machine lacks, builds ulab, and runs
# every model oracle on every engine for the built-in H1-2 (exit 1 if any check fails).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
source scripts/env.sh
cargo build --release --locked -p ulab
exec target/release/ulab model check --robot h1_2 "$@"
