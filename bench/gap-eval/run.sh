#!/usr/bin/env bash
# The gap diagnosis's development and evaluation sets (issue 57). An evaluation split is fixed here before the
# decision model it judges is designed, and is run only to report; the development sets are for looking at.
# `eval` judged the judge of 65e947d and has been read since; `eval2` (fixed at 2554d96) was first run on that same
# judge, unchanged, and has been read since; `eval3` (fixed before `eval2` was read) judged the change of 4ada592 (the
# candidates replayed exactly ranked by the decision's own measure) and has been read since; `eval4` (fixed when
# `eval3` was read) judged the change of 5f13a73 (test (a) over the windows where a candidate acts) and has been read
# since; `eval5` (fixed while `eval4` ran) judges the next change of the decision model, reported beside the others.
#
#   bench/gap-eval/run.sh dev|eval|eval2|eval3|eval4|eval5 [SET...]     generate the logs, diagnose them, score them strictly
#   bench/gap-eval/run.sh rediagnose dev|eval|eval2|eval3|eval4|eval5 [SET...]   diagnose the logs already there again
#       (with ULAB_EVAL_AS=NAME into out/gap-eval/<split>@NAME/, the logs linked, the split's own reports untouched:
#       two judges on the same logs)
#   bench/gap-eval/run.sh score dev|eval|eval2|eval3|eval4|eval5        score what is there
#   bench/gap-eval/run.sh visibility dev|eval|eval2|eval3|eval4|eval5 [SET...]   regenerate each trial's log beside the log
#       without each of its hidden effects (<set>/counterfactual/), measure what each effect shows in its log
#       (visibility.py -> <set>/visibility.json) and score again: score.py's second table (effects the log can show)
#
# Output: out/gap-eval/<split>/<set>/ (logs, labels, one report per trial) and out/gap-eval/<split>/score.{md,json}.
# Sets: four of `ulab gap bench` (reference plants Rapier multibody and DART, each under the excitation plan and
# under gentle chirps: 12 trials single/single/pair/control and 2 out-of-library) and one of a plant outside ulab
# (`mujoco_trials.py`: Unitree's MJCF in MuJoCo's Python bindings, 1 ms steps, PD at 1 kHz, 16 trials plan/chirp
# and 2 out-of-library). ULAB_BIN overrides the binary (default target/release/ulab, built if missing);
# ULAB_EVAL_JOBS (default 1) runs that many diagnoses at once. The binary is copied into the split's directory first
# (with `git describe` beside it), so that a rebuild during a run changes nothing.
set -euo pipefail
cd "$(dirname "$0")/../.."
source scripts/env.sh
split=${1:?usage: run.sh dev|eval|eval2|eval3|eval4|eval5 [SET...] | run.sh score dev|eval|eval2|eval3|eval4|eval5}
shift
BIN=${ULAB_BIN:-target/release/ulab}
JOBS=${ULAB_EVAL_JOBS:-1}
DURATION=20

# name  kind  seed  arguments
EVAL_SETS=(
  "rapier-plan bench 9001 --reference-engine rapier_multibody --trials 12 --out-of-library 2"
  "rapier-chirp bench 9002 --reference-engine rapier_multibody --trials 12 --out-of-library 2 --gentle-chirp"
  "dart-plan bench 9003 --reference-engine dart --trials 12 --out-of-library 2"
  "dart-chirp bench 9004 --reference-engine dart --trials 12 --out-of-library 2 --gentle-chirp"
  "mujoco-py mujoco 9005 --trials 16 --out-of-library 2"
)
EVAL2_SETS=(
  "rapier-plan bench 9101 --reference-engine rapier_multibody --trials 12 --out-of-library 2"
  "rapier-chirp bench 9102 --reference-engine rapier_multibody --trials 12 --out-of-library 2 --gentle-chirp"
  "dart-plan bench 9103 --reference-engine dart --trials 12 --out-of-library 2"
  "dart-chirp bench 9104 --reference-engine dart --trials 12 --out-of-library 2 --gentle-chirp"
  "mujoco-py mujoco 9105 --trials 24 --out-of-library 4"
)
EVAL3_SETS=(
  "rapier-plan bench 9201 --reference-engine rapier_multibody --trials 12 --out-of-library 2"
  "rapier-chirp bench 9202 --reference-engine rapier_multibody --trials 12 --out-of-library 2 --gentle-chirp"
  "dart-plan bench 9203 --reference-engine dart --trials 12 --out-of-library 2"
  "dart-chirp bench 9204 --reference-engine dart --trials 12 --out-of-library 2 --gentle-chirp"
  "mujoco-py mujoco 9205 --trials 24 --out-of-library 4"
)
EVAL4_SETS=(
  "rapier-plan bench 9301 --reference-engine rapier_multibody --trials 12 --out-of-library 2"
  "rapier-chirp bench 9302 --reference-engine rapier_multibody --trials 12 --out-of-library 2 --gentle-chirp"
  "dart-plan bench 9303 --reference-engine dart --trials 12 --out-of-library 2"
  "dart-chirp bench 9304 --reference-engine dart --trials 12 --out-of-library 2 --gentle-chirp"
  "mujoco-py mujoco 9305 --trials 24 --out-of-library 4"
)
EVAL5_SETS=(
  "rapier-plan bench 9401 --reference-engine rapier_multibody --trials 12 --out-of-library 2"
  "rapier-chirp bench 9402 --reference-engine rapier_multibody --trials 12 --out-of-library 2 --gentle-chirp"
  "dart-plan bench 9403 --reference-engine dart --trials 12 --out-of-library 2"
  "dart-chirp bench 9404 --reference-engine dart --trials 12 --out-of-library 2 --gentle-chirp"
  "mujoco-py mujoco 9405 --trials 24 --out-of-library 4"
)
DEV_SETS=(
  "rapier-plan bench 101 --reference-engine rapier_multibody --trials 12 --out-of-library 2"
  "rapier-chirp bench 102 --reference-engine rapier_multibody --trials 12 --out-of-library 2 --gentle-chirp"
  "dart-plan bench 103 --reference-engine dart --trials 12 --out-of-library 2"
  "dart-chirp bench 104 --reference-engine dart --trials 12 --out-of-library 2 --gentle-chirp"
  "mujoco-py mujoco 105 --trials 16 --out-of-library 2"
)

score() {
  local dir=out/gap-eval/$1
  local sets=()
  for d in "$dir"/*/; do [ -d "$d" ] && sets+=("$d"); done
  "$ULAB_PYTHON" bench/gap-eval/score.py "${sets[@]}" --json "$dir/score.json" | tee "$dir/score.md"
}

rediagnose=false
visibility=false
if [ "$split" = rediagnose ]; then rediagnose=true; split=${1:?dev, eval, eval2, eval3, eval4 or eval5}; shift; fi
if [ "$split" = visibility ]; then visibility=true; split=${1:?dev, eval, eval2, eval3, eval4 or eval5}; shift; fi
case "$split" in
  score) score "${1:?dev, eval, eval2, eval3, eval4 or eval5}"; exit 0 ;;
  eval) sets=("${EVAL_SETS[@]}") ;;
  eval2) sets=("${EVAL2_SETS[@]}") ;;
  eval3) sets=("${EVAL3_SETS[@]}") ;;
  eval4) sets=("${EVAL4_SETS[@]}") ;;
  eval5) sets=("${EVAL5_SETS[@]}") ;;
  dev) sets=("${DEV_SETS[@]}") ;;
  *) echo "usage: run.sh dev|eval|eval2|eval3|eval4|eval5 [SET...] | run.sh rediagnose dev|eval|eval2|eval3|eval4|eval5 [SET...] | run.sh score dev|eval|eval2|eval3|eval4|eval5" >&2; exit 2 ;;
esac
if $visibility; then
  # The plants again, without each hidden effect; the judge's reports and its binary copy stay as they are.
  [ -x "$BIN" ] || cargo build --release --locked -p ulab
  plan=out/gap-eval/plan.mcap
  for spec in "${sets[@]}"; do
    read -r name kind seed args <<< "$spec"
    if [ $# -gt 0 ] && [[ " $* " != *" $name "* ]]; then continue; fi
    dir=out/gap-eval/$split/$name
    # shellcheck disable=SC2086
    n=$(( $(echo $args | sed -E 's/.*--trials ([0-9]+).*/\1/') + $(echo $args | sed -E 's/.*--out-of-library ([0-9]+).*/\1/') ))
    echo "run.sh: visibility of $split/$name ($n trials)"
    for ((w = 0; w < JOBS; w++)); do
      (
        only=()
        for ((i = w; i < n; i += JOBS)); do only+=(--only "$i"); done
        if [ "$kind" = bench ]; then
          # shellcheck disable=SC2086
          "$BIN" gap bench $args --seed "$seed" --duration "$DURATION" --out "$dir/counterfactual" "${only[@]}" \
            --counterfactuals 2> /dev/null
        else
          # shellcheck disable=SC2086
          "$ULAB_PYTHON" bench/gap-eval/mujoco_trials.py $args --seed "$seed" --duration "$DURATION" --plan "$plan" \
            --out "$dir/counterfactual" "${only[@]}" --counterfactuals > /dev/null
        fi
      ) &
    done
    wait
    "$ULAB_PYTHON" bench/gap-eval/visibility.py "$dir" > "$dir/visibility.txt"
  done
  score "$split"
  exit 0
fi
src_split=$split
if $rediagnose && [ -n "${ULAB_EVAL_AS:-}" ]; then split="$split@$ULAB_EVAL_AS"; fi
[ -x "$BIN" ] || cargo build --release --locked -p ulab
mkdir -p "out/gap-eval/$split"
cp "$BIN" "out/gap-eval/$split/ulab"
{ git describe --always --dirty; [ -z "${ULAB_BIN:-}" ] || echo "binary: $ULAB_BIN"; } > "out/gap-eval/$split/ulab.version"
BIN=out/gap-eval/$split/ulab
plan=out/gap-eval/plan.mcap
[ -f "$plan" ] || { mkdir -p out/gap-eval; "$BIN" gap excite --out "$plan" --duration "$DURATION" --rate 500; }

# Trials of a set, dealt to $JOBS workers (each runs every JOBS-th trial).
for spec in "${sets[@]}"; do
  read -r name kind seed args <<< "$spec"
  if [ $# -gt 0 ] && [[ " $* " != *" $name "* ]]; then continue; fi
  src=out/gap-eval/$src_split/$name
  dir=out/gap-eval/$split/$name
  mkdir -p "$dir"
  if [ "$src" != "$dir" ]; then
    for f in "$src"/trial_*.mcap "$src"/trial_*.labels.json "$src"/scores.json; do
      [ -e "$f" ] && ln -sf "$(readlink -f "$f")" "$dir/"
    done
  fi
  # shellcheck disable=SC2086
  n=$(( $(echo $args | sed -E 's/.*--trials ([0-9]+).*/\1/') + $(echo $args | sed -E 's/.*--out-of-library ([0-9]+).*/\1/') ))
  echo "run.sh: $split/$name ($n trials)"
  for ((w = 0; w < JOBS; w++)); do
    (
      only=()
      for ((i = w; i < n; i += JOBS)); do only+=(--only "$i"); done
      if $rediagnose; then
        for ((i = w; i < n; i += JOBS)); do
          t=$(printf "trial_%03d" "$i")
          "$BIN" gap diagnose --log "$src/$t.mcap" --out "$dir/$t" --seed "$seed" --format json > /dev/null
        done
      elif [ "$kind" = bench ]; then
        # shellcheck disable=SC2086
        "$BIN" gap bench $args --seed "$seed" --duration "$DURATION" --out "$dir/w$w" "${only[@]}" > "$dir/w$w.txt"
      else
        # shellcheck disable=SC2086
        "$ULAB_PYTHON" bench/gap-eval/mujoco_trials.py $args --seed "$seed" --duration "$DURATION" --plan "$plan" \
          --out "$dir" "${only[@]}" > /dev/null
        for ((i = w; i < n; i += JOBS)); do
          t=$(printf "trial_%03d" "$i")
          "$BIN" gap diagnose --log "$dir/$t.mcap" --out "$dir/$t" --seed "$seed" --format json > /dev/null
        done
      fi
    ) &
  done
  wait
  if [ "$kind" = bench ] && ! $rediagnose; then
    # One set directory: the workers' trials and their labels side by side.
    "$ULAB_PYTHON" - "$dir" "$JOBS" <<'PY'
import json, os, shutil, sys
d, jobs = sys.argv[1], int(sys.argv[2])
scores = []
for w in range(jobs):
    wd = os.path.join(d, f"w{w}")
    scores += json.load(open(os.path.join(wd, "scores.json")))
    for f in os.listdir(wd):
        if f.startswith("trial_"):
            dst = os.path.join(d, f)
            if os.path.isdir(dst):
                shutil.rmtree(dst)
            elif os.path.exists(dst):
                os.remove(dst)
            shutil.move(os.path.join(wd, f), dst)
scores.sort(key=lambda s: s["trial"])
json.dump(scores, open(os.path.join(d, "scores.json"), "w"), indent=1)
PY
  fi
done
score "$split"
