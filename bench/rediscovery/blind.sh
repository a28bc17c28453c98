#!/usr/bin/env bash
# Blind mode of the cross-engine set (issue 63): for each pinned wheel version, the harness's `blind campaign`
# runs randomly generated scenes (seeded, the same for every version) through the engine's adapter for a fixed
# CPU budget, with no knowledge of which bug the version has; a finding is a scene that violates an invariant
# (the first one per invariant is minimised). Then each known bug of `cross.rs` is matched by flipping versions:
# every scene flagged on its last bad version is replayed on the last bad and the first good version; a scene
# flagged on the first and quiet on the second rediscovers the bug.
#   bash bench/rediscovery/blind.sh          # from the repository root
# Environment: BLIND_BUDGET (CPU seconds per version, this process and its children; default 1800),
# BLIND_SEED (default 1), BLIND_WHEELS (default: every wheel of the cross set, as PKG:VER; `rapier:VER` runs the Rust
# adapter of a pinned rapier version, adapters/rapier-VER/src/blind.rs, built here), CARGO_TARGET_DIR
# (default target-rediscovery), REDISCOVERY_NICE (default 10), REDISCOVERY_VENVS, REDISCOVERY_VENV_PREFIX (see
# run.sh). Output: $CARGO_TARGET_DIR/blind-out/PKG-VER/{findings.jsonl,summary.json,scenes/} and a table on stdout.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
# shellcheck source=/dev/null
source "$root/scripts/env.sh"
# shellcheck source=bench/rediscovery/venv.sh
source "$here/venv.sh"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target-rediscovery}"
out="$CARGO_TARGET_DIR/blind-out"
mkdir -p "$out"
nice_cmd=(nice -n "${REDISCOVERY_NICE:-10}")
budget="${BLIND_BUDGET:-1800}"
seed="${BLIND_SEED:-1}"
read -r -a wheels <<< "${BLIND_WHEELS:-mujoco:3.1.0 mujoco:3.1.1 mujoco:3.1.5 mujoco:3.1.6 mujoco:3.2.6 mujoco:3.2.7 mujoco:3.11.0 mujoco:3.12.0 mujoco:3.17.0 pybullet:3.2.6 pybullet:3.2.7 dartpy:6.16.4 dartpy:6.16.5 dartpy:6.16.6}"

"${nice_cmd[@]}" cargo build --quiet --locked --manifest-path "$here/Cargo.toml" -p rediscovery-harness --bin blind
blind="$CARGO_TARGET_DIR/debug/blind"

# engine_of PKG VER: sets eng_py and eng_adapter, the PYTHON ADAPTER pair of `blind` for that version: a wheel's venv
# interpreter and Python adapter, or (PKG rapier) the Rust adapter's executable and `-`.
engine_of() {
    if [ "$1" = rapier ]; then
        local crate="rapier-${2//[.-]/_}"
        if [ ! -f "$here/adapters/$crate/src/blind.rs" ]; then
            echo "no blind adapter for rapier $2 (adapters/$crate/src/blind.rs)" >&2
            return 1
        fi
        "${nice_cmd[@]}" cargo build --quiet --locked --manifest-path "$here/adapters/$crate/Cargo.toml" --bin "blind-$crate"
        eng_py="$CARGO_TARGET_DIR/debug/blind-$crate" eng_adapter=-
    else
        ensure_venv "$1" "$2"
        eng_py="$venv/bin/python" eng_adapter="$here/adapters/python/$adapter"
    fi
}

for w in "${wheels[@]}"; do
    pkg="${w%%:*}" ver="${w##*:}"
    engine_of "$pkg" "$ver"
    rm -rf "${out:?}/$pkg-$ver"
    "${nice_cmd[@]}" "$blind" campaign "$eng_py" "$eng_adapter" "$seed" "$budget" "$out/$pkg-$ver" > /dev/null
    python3 -c 'import json,sys; s=json.load(open(sys.argv[1])); print("{engine}: {scenes} scenes, {flagged} flagged, {unsupported} not run, {cpu_s:.0f} CPU s, first finding after {cpu_s_to_first_finding} CPU s".format(**s))' "$out/$pkg-$ver/summary.json" >&2
done

pkg_of() { case "$1" in MuJoCo) echo mujoco ;; pybullet) echo pybullet ;; dartpy) echo dartpy ;; rapier3d) echo rapier ;; esac; }
echo "| bug | last bad / first good | scenes flagged on last bad | of them quiet on first good | smallest such scene (bodies+geoms) | a flip (a rediscovery only once the flip is attributed to the bug: README) |"
echo "|---|---|---|---|---|---|"
# Bugs fixed by one release share a version pair (rapier #974 and #968): the flip cannot tell them apart, so the first
# row names every bug of its pair and the later ones point to it instead of replaying the same scenes again (README:
# how the flips were attributed).
mapfile -t bugs < <("$blind" bugs)
declare -A first_of_pair=() ids_of_pair=()
for line in "${bugs[@]}"; do
    IFS=$'\t' read -r engine bad good id <<< "$line"
    ids_of_pair["$engine $bad $good"]+="${ids_of_pair["$engine $bad $good"]:+ and }$id"
done
for line in "${bugs[@]}"; do
    IFS=$'\t' read -r engine bad good id <<< "$line"
    pair="$engine $bad $good"
    if [ -n "${first_of_pair[$pair]:-}" ]; then
        echo "| $id | $bad / $good | same pair as ${first_of_pair[$pair]}: the same scenes | | | see ${first_of_pair[$pair]} |"
        continue
    fi
    first_of_pair[$pair]="$id"
    pkg=$(pkg_of "$engine")
    dir="$out/$pkg-$bad"
    if [ ! -d "$dir/scenes" ]; then
        echo "| $id | $bad / $good | not run | | | |"
        continue
    fi
    mapfile -t files < <(find "$dir/scenes" -name '*.json' | sort)
    engine_of "$pkg" "$bad"
    bad_py="$eng_py" bad_adapter="$eng_adapter"
    engine_of "$pkg" "$good"
    good_py="$eng_py" good_adapter="$eng_adapter"
    if [ "${#files[@]}" -eq 0 ]; then
        echo "| $id | $bad / $good | 0 | | | no |"
        continue
    fi
    "${nice_cmd[@]}" "$blind" replay "$bad_py" "$bad_adapter" "${files[@]}" > "$dir/replay-$bad.jsonl"
    "${nice_cmd[@]}" "$blind" replay "$good_py" "$good_adapter" "${files[@]}" > "$dir/replay-$good.jsonl"
    python3 - "$dir" "$bad" "$good" "$id" "${ids_of_pair[$pair]}" <<'PY'
import json, os, sys
d, bad, good, bug, pair_bugs = sys.argv[1:6]
def load(v):
    return {r["verdict"]["scene"]: r for r in map(json.loads, open(os.path.join(d, "replay-%s.jsonl" % v)))}
b, g = load(bad), load(good)
flagged = [s for s, r in b.items() if r["verdict"]["flagged"]]
# Quiet on the good version means judged and not flagged (a scene the good version refuses to build is not quiet).
quiet = [s for s in flagged if s in g and not g[s]["verdict"]["flagged"] and g[s]["verdict"]["value"] is not None]
def size(s):
    w = json.load(open(os.path.join(d, "scenes", s + ".json")))
    return len(w["bodies"]) + sum(len(x["geoms"]) for x in w["bodies"])
best = min(quiet, key=size) if quiet else None
print("| {} | {} / {} | {} | {} | {} | {} |".format(bug, bad, good, len(flagged), len(quiet),
      "{} ({}; {})".format(best, size(best), b[best]["violation"]) if best else "-",
      ("yes" if pair_bugs == bug else "yes, for one of " + pair_bugs) if quiet else "no"))
PY
done
