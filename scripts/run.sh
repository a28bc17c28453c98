#!/usr/bin/env bash
# The main job on the built-in default: installs what a fresh machine lacks, builds ulab, and runs the
# differential engine test of the built-in H1-2 under the built-in excitation input (standing PD with
# randomized targets, pushes and command sequences) in every engine of the build: MuJoCo, Rapier multibody,
# Rapier impulse joints, Bullet (btMultiBody), DART and PhysX (the `physx` feature, on here).
# The report (report.md, report.json, SVG plots, reproducers) goes to out/diff; extra arguments are passed
# on (e.g. --policy robots/h1_2/policies/unitree_rl_gym_lstm.toml --episodes 8).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
source scripts/env.sh
cargo build --release --locked -p ulab --features physx
exec target/release/ulab diff --robot h1_2 --out out/diff "$@"
