#!/usr/bin/env python3
"""Campaign throughput on 1, 2 and 3 Ray workers of this machine (issue 62, BENCHMARKS.md "Campaigns").

    $ULAB_RAY_PYTHON bench/campaign/throughput.py [--ulab target/release/ulab] [--episodes 12] [--seconds 1]

One `ulab diff` campaign (MuJoCo and Rapier multibody, built-in input) runs unsharded on one thread (the reference,
measured in the same run), then through scripts/campaign.py as 6 shards on a local cluster of W one-CPU worker
nodes, W = 1, 2, 3. Prints episodes per second and the speed-up over the reference; the merged report must equal
the unsharded one (else the row says so). On a 2-core machine the third worker shares a core.
"""
import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests/campaign"))
from ray_local import same_outputs  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ulab", default=str(ROOT / "target/release/ulab"))
    ap.add_argument("--episodes", type=int, default=12)
    ap.add_argument("--seconds", type=float, default=1.0)
    a = ap.parse_args()
    from ray.cluster_utils import Cluster

    base = ["diff", "--engines", "mujoco,rapier-multibody", "--jobs", "1"]
    args = [*base, "--episodes", str(a.episodes), "--seconds", str(a.seconds)]
    with tempfile.TemporaryDirectory(prefix="ulab-tp-") as tmp:
        plain = Path(tmp) / "plain"
        # Warm-up: the first run of a process pays for loading the engines' libraries and the model from disk.
        subprocess.run([a.ulab, *base, "--episodes", "1", "--seconds", "0.2", "--out", str(Path(tmp) / "warm")],
                       cwd=ROOT, check=True, capture_output=True)
        t = time.monotonic()
        subprocess.run([a.ulab, *args, "--out", str(plain)], cwd=ROOT, check=True, capture_output=True)
        ref = time.monotonic() - t
        print("| workers | wall s | episodes/s | speed-up | merged = unsharded |")
        print("|---:|---:|---:|---:|---|")
        print(f"| unsharded, 1 thread (reference) | {ref:.1f} | {a.episodes / ref:.2f} | 1.00 | — |")
        for w in (1, 2, 3):
            cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False})
            for _ in range(w):
                cluster.add_node(num_cpus=1)
            out = Path(tmp) / f"ray{w}"
            t = time.monotonic()
            subprocess.run([sys.executable, str(ROOT / "scripts/campaign.py"), "--address", cluster.address,
                            "--shards", "6", "--ulab", a.ulab, "--out", str(out), "--", *args],
                           cwd=ROOT, check=True, capture_output=True)
            wall = time.monotonic() - t
            cluster.shutdown()
            same = "yes" if not same_outputs(plain, out) else "NO"
            print(f"| {w} | {wall:.1f} | {a.episodes / wall:.2f} | {ref / wall:.2f} | {same} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
