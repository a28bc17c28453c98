#!/usr/bin/env python3
"""A local Ray cluster (a head and two worker nodes on this machine, `ray.cluster_utils.Cluster`) runs a campaign of
each shardable kind — `ulab diff`, `ulab diff fuzz` (lanes), `ulab validate`, `ulab gap bench` — as 3 shards through
scripts/campaign.py; the merged output must equal the unsharded run's, file by file in every subdirectory, with the
wall-clock fields and lines left out as crates/ulab/tests/it/shard_cli.rs leaves them out. Run by scripts/nightly.sh with the Ray venv of `scripts/setup.sh --ray`:

    $ULAB_RAY_PYTHON tests/campaign/ray_local.py [--ulab target/debug/ulab]

Prints the wall time of each campaign unsharded and through Ray, and Ray's overhead per task (a no-op task's round
trip). Exit 0 when every merged output equals its unsharded run.
"""
import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CAMPAIGNS = {
    "diff": ["diff", "--engines", "mujoco,rapier-multibody", "--episodes", "6", "--seconds", "0.2", "--window", "25",
             "--jobs", "1"],
    "diff-fuzz": ["diff", "fuzz", "--engines", "mujoco,rapier-impulse", "--iterations", "12", "--lanes", "4",
                  "--seconds", "0.1", "--seed", "2", "--window", "10", "--minimize", "1"],
    "validate": ["validate", "--policy", "robots/h1_2/policies/unitree_rl_gym_lstm.toml", "--train-engine", "mujoco",
                 "--engines", "mujoco,rapier-multibody", "--commands", "stand,forward", "--episodes", "2",
                 "--seconds", "2", "--no-evidence"],
    "gap-bench": ["gap", "bench", "--trials", "4", "--seed", "3", "--duration", "4", "--effects", "damping",
                  "--max-windows", "8"],
}
# Wall-clock fields, as (parent key, key) or (key,): campaign timings, a diagnosis's time and its stages' times.
WALL_CLOCK = {("timing", "engine_s"), ("timing", "total_s"), ("diagnose_s",), ("elapsed_s",), ("stages", "s")}
# Wall-clock lines of Markdown outputs, by their start.
WALL_CLOCK_LINES = ("| mean diagnosis time per log |", "Diagnosis time:")


def strip_wall_clock(x, path=()):
    if isinstance(x, dict):
        return {k: strip_wall_clock(v, path + (k,)) for k, v in x.items()
                if tuple(path[-1:] + (k,)) not in WALL_CLOCK and (k,) not in WALL_CLOCK}
    if isinstance(x, list):
        return [strip_wall_clock(v, path) for v in x]
    return x


def strip_wall_clock_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if not line.startswith(WALL_CLOCK_LINES)]


def same_outputs(a: Path, b: Path) -> list[str]:
    """Files of `a` and `b` (every subdirectory) that differ, wall-clock fields and lines aside."""
    diffs = []
    names = sorted(str(p.relative_to(a)) for p in a.rglob("*") if p.is_file())
    other = sorted(str(p.relative_to(b)) for p in b.rglob("*") if p.is_file() and not p.is_relative_to(b / "shards"))
    if names != other:
        diffs.append(f"files differ: {sorted(set(names) ^ set(other))}")
    for n in names:
        if not (b / n).is_file():
            continue
        if n.endswith(".json"):
            if strip_wall_clock(json.loads((a / n).read_text())) != strip_wall_clock(json.loads((b / n).read_text())):
                diffs.append(n)
        elif n.endswith(".md"):
            if strip_wall_clock_lines((a / n).read_text()) != strip_wall_clock_lines((b / n).read_text()):
                diffs.append(n)
        elif (a / n).read_bytes() != (b / n).read_bytes():
            diffs.append(n)
    return diffs


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ulab", default=str(ROOT / "target/debug/ulab"))
    a = ap.parse_args()
    import ray
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False})
    for _ in range(2):
        cluster.add_node(num_cpus=1)
    ray.init(address=cluster.address)

    @ray.remote(num_cpus=1)
    def noop():
        return 0

    ray.get([noop.remote() for _ in range(4)])  # workers started
    t = time.monotonic()
    for _ in range(20):
        ray.get(noop.remote())
    overhead = (time.monotonic() - t) / 20
    ray.shutdown()
    print(f"ray_local: Ray {ray.__version__}, head + 2 worker nodes; overhead per task {overhead * 1000:.1f} ms")
    failed = 0
    with tempfile.TemporaryDirectory(prefix="ulab-ray-") as tmp:
        for name, args in CAMPAIGNS.items():
            plain, sharded = Path(tmp) / f"{name}-plain", Path(tmp) / f"{name}-ray"
            t = time.monotonic()
            p = subprocess.run([a.ulab, *args, "--out", str(plain)], cwd=ROOT, capture_output=True, text=True)
            t_plain = time.monotonic() - t
            if p.returncode not in (0, 1):
                print(f"ray_local: {name}: the unsharded run exited {p.returncode}\n{p.stderr[-2000:]}")
                failed += 1
                continue
            t = time.monotonic()
            q = subprocess.run([sys.executable, str(ROOT / "scripts/campaign.py"), "--address", cluster.address,
                                "--shards", "3", "--ulab", a.ulab, "--out", str(sharded), "--", *args],
                               cwd=ROOT, capture_output=True, text=True)
            t_ray = time.monotonic() - t
            print(q.stdout.strip())
            if q.returncode != p.returncode:
                print(f"ray_local: {name}: Ray campaign exited {q.returncode}, unsharded {p.returncode}\n"
                      f"{q.stderr[-2000:]}")
                failed += 1
                continue
            diffs = same_outputs(plain, sharded)
            status = "identical" if not diffs else f"DIFFER: {diffs}"
            failed += bool(diffs)
            print(f"ray_local: {name}: unsharded {t_plain:.1f} s, 3 shards through Ray {t_ray:.1f} s; merged "
                  f"output {status}")
    cluster.shutdown()
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
