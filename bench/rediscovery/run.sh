#!/usr/bin/env bash
# Reproduces the rediscovery table of BENCHMARKS.md and the per-version tables of README.md.
#  - rapier set: builds the MuJoCo reference and one adapter per pinned rapier version (each its own workspace
#    and Cargo.lock), runs the same scenes and oracles on each;
#  - cross set: MuJoCo, Bullet and DART versions from their PyPI wheels (one venv per version, created on first
#    use), each scene in its own process through the engine's Python bindings (adapters/python), judged by the
#    project's invariants (crates/physics-invariants) in the harness's `judge` binary.
# Not part of scripts/test.sh: it compiles seven rapier versions and installs fourteen wheels.
#   bash bench/rediscovery/run.sh            # from the repository root
# Environment: CARGO_TARGET_DIR (default target-rediscovery), REDISCOVERY_NICE (default 0), REDISCOVERY_SETS
# (default "rapier cross"), REDISCOVERY_VENVS (default $CARGO_TARGET_DIR/venvs) and REDISCOVERY_VENV_PREFIX
# (default empty): the venv of wheel P==V is $REDISCOVERY_VENVS/$REDISCOVERY_VENV_PREFIX$P-$V.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
# shellcheck source=/dev/null
source "$root/scripts/env.sh"
# shellcheck source=bench/rediscovery/venv.sh
source "$here/venv.sh"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target-rediscovery}"
out="$CARGO_TARGET_DIR/rediscovery-out"
mkdir -p "$out"
nice_cmd=(nice -n "${REDISCOVERY_NICE:-0}")
sets="${REDISCOVERY_SETS:-rapier cross}"
adapters=(rapier-0_17_2 rapier-0_18_0 rapier-0_20_0 rapier-0_34_0 rapier-0_35_0_beta_0 rapier-0_35_0 rapier-0_36_1)
# Wheel versions of the cross set: each bug's last bad and first good version, and the current versions that
# serve as independent engines on the other engines' scenes (MuJoCo 3.17.0 is also the inverse-dynamics reference).
wheels=(mujoco:3.1.0 mujoco:3.1.1 mujoco:3.1.5 mujoco:3.1.6 mujoco:3.2.6 mujoco:3.2.7 mujoco:3.11.0 mujoco:3.12.0
    mujoco:3.17.0 pybullet:3.2.6 pybullet:3.2.7 dartpy:6.16.4 dartpy:6.16.5 dartpy:6.16.6)

build_and_run() { # manifest, package, output file
    local t0 t1
    t0=$(date +%s)
    "${nice_cmd[@]}" cargo build --quiet --locked --manifest-path "$1" -p "$2" --bins
    t1=$(date +%s)
    "${nice_cmd[@]}" cargo run --quiet --locked --manifest-path "$1" -p "$2" > "$3"
    echo "$2: build $((t1 - t0)) s, run $(( $(date +%s) - t1 )) s" >&2
}

files=()
if [[ " $sets " == *" rapier "* ]]; then
    build_and_run "$here/Cargo.toml" rediscovery-reference "$out/reference.jsonl"
    files+=("$out/reference.jsonl")
    for a in "${adapters[@]}"; do
        pkg=$(sed -n 's/^name = "\(.*\)"/\1/p' "$here/adapters/$a/Cargo.toml" | head -1)
        build_and_run "$here/adapters/$a/Cargo.toml" "$pkg" "$out/$a.jsonl"
        files+=("$out/$a.jsonl")
    done
fi

if [[ " $sets " == *" cross "* ]]; then
    "${nice_cmd[@]}" cargo build --quiet --locked --manifest-path "$here/Cargo.toml" -p rediscovery-harness --bins
    harness_bin="$CARGO_TARGET_DIR/debug"
    "$harness_bin/scenes" > "$out/scenes.json"
    mapfile -t scene_ids < <(python3 -c 'import json,sys; [print(s["id"]) for s in json.load(open(sys.argv[1]))]' "$out/scenes.json")
    obs=()
    for w in "${wheels[@]}"; do
        pkg="${w%%:*}" ver="${w##*:}"
        ensure_venv "$pkg" "$ver"
        file="$out/cross-$pkg-$ver.jsonl"
        : > "$file"
        t0=$(date +%s)
        for id in "${scene_ids[@]}"; do
            # One process per scene: a crash (abort, segfault) is a verdict about that scene, not the end of the run.
            set +e
            line=$(cd "$here/adapters/python" && timeout 600 "${nice_cmd[@]}" "$venv/bin/python" "$adapter" \
                "$out/scenes.json" "$id" 2> "$out/cross-$pkg-$ver-$id.stderr" | grep '"scene"')
            code=${PIPESTATUS[0]}
            set -e
            if [ -z "$line" ]; then
                line=$(python3 -c 'import json,sys; print(json.dumps({"engine": sys.argv[1], "scene": sys.argv[2], "status": "crashed", "detail": "process exited with status " + sys.argv[3] + " before reporting"}))' "$label" "$id" "$code")
            fi
            echo "$line" >> "$file"
        done
        echo "$label: ${#scene_ids[@]} scenes in $(( $(date +%s) - t0 )) s" >&2
        obs+=("$file")
    done
    "$harness_bin/judge" "${obs[@]}" > "$out/cross-verdicts.jsonl"
    files+=("$out/cross-verdicts.jsonl")
fi
"${nice_cmd[@]}" cargo run --quiet --locked --manifest-path "$here/Cargo.toml" -p rediscovery-harness --bin report -- "${files[@]}"
