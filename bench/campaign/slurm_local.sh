#!/usr/bin/env bash
# scripts/campaign.slurm on a one-node Slurm cluster started on this machine (issue 62): a `ulab diff` campaign as a
# 3-task job array plus the dependent merge job, then the same campaign unsharded; the merged output must equal the
# unsharded one (JSON with the wall-clock fields left out, every other file byte for byte).
#
#   bash bench/campaign/slurm_local.sh            as root, with Debian's slurm-wlm and munge installed
#                                                 (apt-get install slurm-wlm munge)
#
# Starts munged (if none runs), slurmctld and slurmd with a configuration written to out/slurm-local/ (SLURM_CONF
# points there: /etc/slurm is untouched), and stops the two Slurm daemons at the end. ULAB overrides the binary
# (default target/release/ulab, built if missing).
set -euo pipefail
cd "$(dirname "$0")/../.."
source scripts/env.sh
for tool in slurmctld slurmd sbatch munged; do
  command -v "$tool" > /dev/null || { echo "slurm_local.sh: $tool missing (apt-get install slurm-wlm munge)" >&2; exit 2; }
done
[ "$(id -u)" = 0 ] || { echo "slurm_local.sh: slurmd runs as root here" >&2; exit 2; }
export ULAB=${ULAB:-$PWD/target/release/ulab}
[ -x "$ULAB" ] || cargo build --release --locked -p ulab
dir=$PWD/out/slurm-local
rm -rf "$dir"
mkdir -p "$dir/state" "$dir/spool" "$dir/run"
host=$(hostname)
export SLURM_CONF=$dir/slurm.conf
cat > "$SLURM_CONF" <<CONF
ClusterName=ulab-local
SlurmctldHost=$host
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
NodeName=$host CPUs=$(nproc) State=UNKNOWN
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
if ! munge -n > /dev/null 2>&1; then
  mkdir -p /run/munge && chown munge:munge /run/munge
  [ -f /etc/munge/munge.key ] || mungekey -c
  runuser -u munge -- munged
fi
slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
stop() { kill "$(cat "$dir/run/slurmd.pid" 2> /dev/null)" "$(cat "$dir/run/slurmctld.pid" 2> /dev/null)" 2> /dev/null || true; }
trap stop EXIT
for _ in $(seq 60); do sinfo -h -o %T 2> /dev/null | grep -q idle && break; sleep 1; done

campaign=(diff --engines mujoco,dart --episodes 6 --seconds 0.5 --seed 7)
(cd "$dir" && SHARDS=3 OUT=$dir/sharded bash "$OLDPWD/scripts/campaign.slurm" "${campaign[@]}")
"$ULAB" "${campaign[@]}" --out "$dir/unsharded" > "$dir/unsharded.log" 2>&1
for _ in $(seq 600); do [ -z "$(squeue -h)" ] && break; sleep 1; done
[ -f "$dir/sharded/report.json" ] || { echo "slurm_local.sh: no merged report; see $dir/slurm-*.out" >&2; exit 1; }
"$ULAB_PYTHON" - "$dir/sharded" "$dir/unsharded" <<'PY'
import sys
from pathlib import Path
sys.path.insert(0, "tests/campaign")
from ray_local import same_outputs
diffs = same_outputs(Path(sys.argv[1]), Path(sys.argv[2]))
print("slurm_local.sh: merged output equals the unsharded run" if not diffs else f"slurm_local.sh: DIFFERENT: {diffs}")
sys.exit(1 if diffs else 0)
PY
