#!/usr/bin/env bash
# Repeatability of `ulab conform` (issue 60): the same peer judged N times in a row, by default while `yes` holds one
# core, and per check how often each verdict came out. A check whose verdict changes between runs of the same peer
# is a defect of the check, whatever the peer does.
#
#   bench/conform-repeat/run.sh ours [N]             our bridge (`ulab sim`, MuJoCo), as CI's defect matrix runs it
#   bench/conform-repeat/run.sh unitree_mujoco [N]   Unitree's Python bridge from $UNITREE_MUJOCO_DIR, a local clone
#                                                    of unitreerobotics/unitree_mujoco (never committed); without it
#                                                    the run is skipped with a message
#
# N defaults to 10. ULAB_REPEAT_LOAD is how many cores `yes` holds throughout: 0 quiet, 1 (default) core 1, 2 both
# cores (the tester and the peer then share the machine with two busy processes, as beside a CI build).
# ULAB_BIN overrides the binary (default target/release/ulab, built if missing). Domain 57 unless ULAB_REPEAT_DOMAIN.
# Output: out/conform-repeat/<peer>/run_NN/report.{json,md} and agreement.{md,json}.
set -euo pipefail
cd "$(dirname "$0")/../.."
source scripts/env.sh
peer=${1:?usage: run.sh ours|unitree_mujoco [N]}
n=${2:-10}
BIN=${ULAB_BIN:-target/release/ulab}
domain=${ULAB_REPEAT_DOMAIN:-57}
case "$peer" in
  ours) conform_args=() ;;
  unitree_mujoco)
    if [ -z "${UNITREE_MUJOCO_DIR:-}" ] || [ ! -d "$UNITREE_MUJOCO_DIR/simulate_python" ]; then
      echo "run.sh: skipped: set UNITREE_MUJOCO_DIR to a local clone of unitreerobotics/unitree_mujoco" >&2
      exit 0
    fi
    # Their publish thread runs every SIMULATE_DT = 5 ms: judged against its own rate, as docs/conform says.
    conform_args=(--state-rate 200) ;;
  *) echo "usage: run.sh ours|unitree_mujoco [N]" >&2; exit 2 ;;
esac
[ -x "$BIN" ] || cargo build --release --locked -p ulab
out=out/conform-repeat/$peer
rm -rf "$out"
mkdir -p "$out"
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done; }
trap cleanup EXIT
load=${ULAB_REPEAT_LOAD:-1}
for ((core = 1; core >= 2 - load && core >= 0; core--)); do
  taskset -c "$core" yes > /dev/null &
  pids+=($!)
done
for ((k = 1; k <= n; k++)); do
  run=$(printf "%s/run_%02d" "$out" "$k")
  mkdir -p "$run"
  if [ "$peer" = ours ]; then
    "$BIN" sim --engine mujoco --domain "$domain" --duration 150 --quiet > "$run/peer.log" 2>&1 &
  else
    "$ULAB_PYTHON" bench/conform-repeat/headless_unitree_mujoco.py --repo "$UNITREE_MUJOCO_DIR" --domain "$domain" \
      --seconds 150 > "$run/peer.log" 2>&1 &
  fi
  peer_pid=$!
  pids+=("$peer_pid")
  status=0
  "$BIN" conform --domain "$domain" "${conform_args[@]}" --out "$run" --format json --quiet > /dev/null || status=$?
  kill "$peer_pid" 2> /dev/null || true
  wait "$peer_pid" 2> /dev/null || true
  echo "run.sh: $peer run $k of $n: exit $status"
  # The next peer must not meet this one's DDS participants.
  sleep 2
done
"$ULAB_PYTHON" - "$out" "$n" "$load" <<'PY'
import collections, glob, json, os, sys
out, n, load = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
runs = sorted(glob.glob(os.path.join(out, "run_*", "report.json")))
verdicts, probes, margins = {}, {}, {}
for path in runs:
    for r in json.load(open(path))["results"]:
        verdicts.setdefault(r["id"], []).append(r["status"])
        probes.setdefault(r["id"], []).append(r.get("probes", 1))
        m = (r.get("margin") or {}).get("relative")
        if isinstance(m, (int, float)):
            margins.setdefault(r["id"], []).append(m)
rows = [{"check": c, "counts": dict(collections.Counter(vs)), "repeats": len(set(vs)) == 1 and len(vs) == len(runs),
         "probes": [min(probes[c]), max(probes[c])], "closest_margin": min(margins[c]) if c in margins else None}
        for c, vs in verdicts.items()]
json.dump({"runs": len(runs), "of": n, "load": load, "checks": rows}, open(os.path.join(out, "agreement.json"), "w"), indent=1)
held = {0: "quiet", 1: "one core held by yes", 2: "both cores held by yes"}.get(load, f"{load} yes processes")
lines = [f"{len(runs)} reports of {n} runs, {held}; "
         f"{sum(r['repeats'] for r in rows)} of {len(rows)} checks gave the same verdict every time",
         "", "| check | verdicts | repeats | probes | closest margin |", "|---|---|---|---|---|"]
span = lambda p: str(p[0]) if p[0] == p[1] else f"{p[0]}-{p[1]}"
lines += [f"| `{r['check']}` | {', '.join(f'{k} {v}' for k, v in sorted(r['counts'].items()))} | "
          f"{'yes' if r['repeats'] else 'NO'} | {span(r['probes'])} | "
          f"{'-' if r['closest_margin'] is None else format(r['closest_margin'] * 100, '+.0f') + ' %'} |" for r in rows]
table = "\n".join(lines) + "\n"
open(os.path.join(out, "agreement.md"), "w").write(table)
print(table)
PY
