#!/usr/bin/env python3
"""Runs a ulab campaign as N shards on a Ray cluster and merges them (issue 62, docs/campaigns.md).

    python scripts/campaign.py --shards N --out DIR [--address ADDR] [--ulab PATH] -- CAMPAIGN ARGS...

CAMPAIGN ARGS is a ulab campaign command without `--shard` and `--out` (e.g. `diff --engines mujoco,dart
--episodes 12 --seconds 2`, `validate --policy SPEC --train-engine mujoco`). Each shard K (1..N) runs
`ulab CAMPAIGN ARGS --shard K/N --out SHARD_DIR` as one Ray task on some worker; the task sends its shard directory
(`shard-K-of-N.cbor`) back as a tar archive, so workers need no shared file system, only the same ulab binary at the same path (--ulab,
default target/release/ulab, made absolute) and the files the arguments name. The driver unpacks the shards under
DIR/shards/ and runs `ulab merge --out DIR DIR/shards/*`, which writes what the unsharded run would.

A task whose ulab exits non-zero is retried once (on any worker); a shard that fails twice is reported with its
exit status and the tail of its stderr, and the driver exits 1 without merging. Progress: one line per finished
shard, with its wall time and worker.

--address: `auto` (a cluster started with `ray start --head` on this machine), HOST:PORT of a cluster's head,
or `local` (default: a Ray instance in this process, one worker per core). Ray is not among the project's
default Python packages: `scripts/setup.sh --ray` installs it.
"""
from __future__ import annotations

import argparse
import io
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path


def run_shard(ulab: str, args: list[str], k: int, n: int, cwd: str) -> dict:
    """One shard on whatever worker Ray chose: its output directory as a tar archive, or the failure."""
    import socket

    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix=f"ulab-shard-{k}-") as tmp:
        out = Path(tmp) / "out"
        cmd = [ulab, *args, "--shard", f"{k}/{n}", "--out", str(out)]
        p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
        result = {"shard": k, "exit": p.returncode, "host": socket.gethostname(), "pid": os.getpid(),
                  "seconds": time.monotonic() - start, "stderr": p.stderr[-2000:]}
        if p.returncode != 0:
            # Raising makes Ray retry the task (retry_exceptions); the message keeps the evidence.
            raise RuntimeError(f"shard {k}/{n}: `{' '.join(cmd)}` exited {p.returncode}\n{p.stderr[-2000:]}")
        buf = io.BytesIO()
        with tarfile.open(fileobj=buf, mode="w:gz") as tar:
            tar.add(out, arcname=".")
        result["tar"] = buf.getvalue()
        return result


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shards", type=int, required=True, help="number of shards N (tasks)")
    ap.add_argument("--out", type=Path, required=True, help="merged output directory")
    ap.add_argument("--address", default="local", help="local | auto | HOST:PORT of a Ray head")
    ap.add_argument("--ulab", default="target/release/ulab", help="the ulab binary (same path on every worker)")
    ap.add_argument("campaign", nargs=argparse.REMAINDER, help="-- then the campaign command and its arguments")
    a = ap.parse_args()
    args = a.campaign[1:] if a.campaign[:1] == ["--"] else a.campaign
    if not args:
        ap.error("give the campaign after --, e.g. -- diff --episodes 6")
    if any(x in ("--shard", "--out") for x in args):
        ap.error("the campaign arguments must not contain --shard or --out: the driver sets them")
    if a.shards < 1 or a.shards > 10_000:
        ap.error("--shards must be in 1..=10000")
    ulab = str(Path(a.ulab).resolve())
    if not os.access(ulab, os.X_OK):
        ap.error(f"{ulab} is not an executable ulab binary (build it: cargo build --release -p ulab)")
    try:
        import ray
    except ImportError:
        print("campaign: Ray is not installed (scripts/setup.sh --ray)", file=sys.stderr)
        return 2

    if a.address == "local":
        ray.init(include_dashboard=False, log_to_driver=False)
    else:
        ray.init(address=a.address, include_dashboard=False, log_to_driver=False)
    task = ray.remote(num_cpus=1, max_retries=1, retry_exceptions=True)(run_shard)
    cwd = os.getcwd()
    started = time.monotonic()
    pending = {task.remote(ulab, args, k, a.shards, cwd): k for k in range(1, a.shards + 1)}
    shards_dir = a.out / "shards"
    if shards_dir.exists():
        shutil.rmtree(shards_dir)
    shards_dir.mkdir(parents=True)
    failed = []
    while pending:
        done, _ = ray.wait(list(pending), num_returns=1)
        ref = done[0]
        k = pending.pop(ref)
        try:
            r = ray.get(ref)
        except Exception as e:  # the task failed twice: Ray's error carries our message
            failed.append(k)
            print(f"campaign: shard {k}/{a.shards} FAILED after a retry: {e}", file=sys.stderr)
            continue
        with tarfile.open(fileobj=io.BytesIO(r["tar"]), mode="r:gz") as tar:
            tar.extractall(shards_dir / f"shard-{k:05}", filter="data")
        print(f"campaign: shard {k}/{a.shards} done in {r['seconds']:.1f} s on {r['host']} (pid {r['pid']}); "
              f"{a.shards - len(pending) - len(failed)} of {a.shards} done", flush=True)
    ray.shutdown()
    if failed:
        print(f"campaign: {len(failed)} shard(s) failed: {sorted(failed)}; not merged", file=sys.stderr)
        return 1
    shard_dirs = sorted(str(p) for p in shards_dir.iterdir())
    p = subprocess.run([ulab, "merge", "--out", str(a.out), *shard_dirs])
    print(f"campaign: {a.shards} shards in {time.monotonic() - started:.1f} s; merge exited {p.returncode}")
    return p.returncode


if __name__ == "__main__":
    sys.exit(main())
