#!/usr/bin/env bash
# The checks that do not fit CI's time budget (issue 21), kept alive here rather than deleted:
#   - PhysX (the `physx` feature: its vendored SDK takes ~7 min of two cores to build): the engine's own tests
#     against the reference and MuJoCo, `ulab model check/inspect`, and Unitree's SDK clients (Python SDK on
#     Cyclone 11, C on Cyclone 0.10.2) driving `ulab sim --engine physx`;
#   - Newton (the `newton` feature, `setup.sh --newton`: ~575 MB and 30–70 s of Warp kernel compilation per solver on
#     a cold cache): its engines against the reference and MuJoCo, the server's own unit tests, and
#     `ulab model check` on Featherstone and Steel (docs/newton.md);
#   - PhysX's and Newton's bit-for-bit repetition against the determinism table (docs/diff/determinism.md);
#   - the gap diagnosis on every single effect and every stored benchmark trial (`effects_found`, 1–4 min a case;
#     CI runs the no-effect control and one benchmark trial), and the Python plant's single-joint and load-friction
#     logs (CI runs its control, pair and ceiling);
#   - a policy-driven benchmark trial whose saturation the logged torque contradicts (`policy_trials`) and the
#     walking plant's contact stiffness (`floating_diagnose`; CI runs its leg damping, control and fallen windows);
#   - the control of the planted cheat (a gait optimised in MuJoCo transfers; CI runs the cheat itself);
#   - every fuzz target, `engine_divergence` included (a release build of three engines with coverage);
#   - a campaign of each shardable kind (diff, diff fuzz, validate, gap bench) sharded over a local Ray cluster
#     (head + 2 workers), merged and compared with the unsharded run (tests/campaign/ray_local.py; Ray is ~285 MB, installed by setup.sh --ray).
# Run after scripts/test.sh on the same checkout (it reuses its set-up); ~60–90 min on 2 cores.
#   ULAB_FUZZ_SECONDS (default 60) per fuzz target.
set -euo pipefail
cd "$(dirname "$0")/.."
phase() { echo "nightly.sh: $1 done after ${SECONDS} s"; }
bash scripts/setup.sh
source scripts/env.sh
export CARGO_TERM_COLOR=never INSTA_UPDATE=no
status=0
cargo test --locked -p diff-physics --features diff-physics/physx --test it -- physx_engine:: || status=$?
phase "physx engine"
# The PhysX experiments on the campaign's candidate bugs (issue 16): friction offset, contact offset.
cargo test --locked -p engine-diff --features engine-diff/physx --test it -- campaign_triage::physx:: || status=$?
phase "physx campaign triage"
cargo test --locked -p ulab --features ulab/physx --test it -- model_cli::check_and_inspect_physx \
  sim_sdk_client::python_sdk_drives_physx sim_c010_client::cyclone_0_10_2_client_drives_physx || status=$?
phase "physx through ulab"
bash scripts/setup.sh --newton
cargo test --locked -p diff-physics --features diff-physics/newton --test it -- newton_engine:: || status=$?
"$ULAB_NEWTON_PYTHON" -m unittest crates/diff-physics/python/test_newton_server.py || status=$?
cargo test --locked -p ulab --features ulab/newton --test it -- model_cli::check_newton_solvers || status=$?
phase "newton engines"
# PhysX's and Newton's entries in the determinism table of this machine class (CI's build lacks both engines).
cargo test --locked -p engine-diff --features engine-diff/physx,engine-diff/newton --test it -- determinism:: \
  || status=$?
phase "physx and newton determinism"
cargo test --locked -p gap-bench --test it -- --include-ignored effects_found:: || status=$?
phase "effects_found"
cargo test --locked -p gap-diagnosis --test it -- --include-ignored python_plant:: || status=$?
phase "python plant"
cargo test --locked -p gap-bench --test it -- --include-ignored policy_trials:: floating_diagnose:: \
  || status=$?
phase "policy trials, floating diagnosis"
cargo test --locked -p engine-diff --test it -- --ignored planted_cheat::a_gait_optimised_in_mujoco_transfers \
  || status=$?
phase "planted cheat control"
bash scripts/setup.sh --ray
cargo build --locked -p ulab
"$ULAB_RAY_PYTHON" tests/campaign/ray_local.py --ulab target/debug/ulab || status=$?
phase "Ray campaign"
bash scripts/fuzz.sh smoke-all "${ULAB_FUZZ_SECONDS:-60}" || status=$?
phase "fuzz smoke-all"
exit "$status"
