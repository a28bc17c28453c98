"""Newton's own Python loop against ulab's server on the same model and settings: the subprocess layer's overhead.

Reads a file that `cargo run -p diff-physics --features newton --example newton_throughput -- --dump DIR` writes
(DIR/newton_featherstone.json, ...): the server's start-up request (MJCF, every setting), the standing state and
Unitree's standing PD gains. Builds the robot with the server's own `Sim` class (same model, same normalisations)
and times, in this process, H1-2 standing under the PD hold, dt 2 ms, reset every 250 steps (untimed), after an
untimed warm-up window:
  own     what a Newton user writes: read joint_q/joint_qd, PD in numpy, write control.joint_f, collide, step;
  server  the server's step request without the pipe (`Sim.step`: the f64 conversions, the base wrench, the
          contact read-back with forces) plus the PD on the interface's state, as ulab's loop computes it.
  pipe    the server as a child process, one STEP frame per step as the Rust engine sends them, the state decoded
          from each reply; CPU time counts this process and the child (/proc/PID/stat).
The Rust engine through the same pipe is the example's own table (wall clock).

  .venv-newton/bin/python bench/newton/own_loop.py DIR/newton_featherstone.json [--steps 500] [--rounds 5]
Prints one JSON line: steps per second of CPU time (medians over the rounds) and of wall-clock time.
"""
import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../crates/diff-physics/python"))
import newton_server as ns  # noqa: E402


def pd(cfg, q, dq):
    p = cfg["pd"]
    tau = np.asarray(p["kp"]) * (np.asarray(p["q_des"]) - q) - np.asarray(p["kd"]) * dq
    lim = np.asarray(p["limit"])
    return np.clip(tau, -lim, lim)


def own_loop(sim, cfg, n):
    """Newton's API only, as in its examples: one collide and one solver step per control step."""
    m, jq, jd = sim.model, np.asarray(sim.jq), np.asarray(sim.jd)
    f = np.zeros(m.joint_dof_count, dtype=np.float32)
    s0, s1 = sim.state0, sim.state1
    for _ in range(n):
        q = s0.joint_q.numpy()
        qd = s0.joint_qd.numpy()
        f[jd] = pd(cfg, q[jq].astype(np.float64), qd[jd].astype(np.float64))
        sim.control.joint_f.assign(f)
        sim.pipeline.collide(s0, sim.contacts)
        if sim.observables is not None:
            sim.solver.step(s0, s1, sim.control, sim.contacts, sim.dt, observables=sim.observables)
        else:
            sim.solver.step(s0, s1, sim.control, sim.contacts, sim.dt)
        s0, s1 = s1, s0
    sim.state0, sim.state1 = s0, s1
    if not np.isfinite(s0.joint_q.numpy()).all():
        raise ns.Diverged("own loop diverged")


def server_loop(sim, cfg, n):
    nj = sim.nj
    for _ in range(n):
        qpos, qvel = sim.from_newton(sim.state0)
        sim.step(pd(cfg, qpos[7 : 7 + nj], qvel[6 : 6 + nj]).reshape(1, -1))


class Pipe:
    """ulab's server as the Rust engine drives it: a child process, one STEP frame per step, the state decoded from
    the reply (the Rust side's share, decoding and the PD, is the same numpy work here)."""

    def __init__(self, cfg):
        import subprocess

        self.p = subprocess.Popen(
            [sys.executable, ns.__file__], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL
        )
        self.request(ns.OP_INIT, json.dumps(cfg["init"]).encode())
        self.nj = len(cfg["init"]["joint_names"])

    def request(self, op, payload):
        import struct

        self.p.stdin.write(struct.pack("<IB", len(payload) + 1, op) + payload)
        self.p.stdin.flush()
        status, body = ns.read_frame(self.p.stdout)
        if status != ns.OK:
            raise RuntimeError(body.decode(errors="replace"))
        return body

    def child_cpu(self):
        with open(f"/proc/{self.p.pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def state(self, body):
        nj = self.nj
        x = np.frombuffer(body[: 8 * (7 + nj + 6 + nj + 1)], dtype="<f8")
        return x[7 : 7 + nj], x[7 + nj + 6 : 7 + nj + 6 + nj]

    def reset(self, qpos, qvel):
        self.body = self.request(ns.OP_RESET, ns.f64s(np.concatenate([qpos, qvel])))

    def close(self):
        self.request(ns.OP_QUIT, b"")
        self.p.wait()


def pipe_loop(pipe, cfg, n):
    for _ in range(n):
        q, dq = pipe.state(pipe.body)
        pipe.body = pipe.request(ns.OP_STEP, ns.f64s(pd(cfg, q, dq)))


def timed(sim, cfg, loop, steps, every):
    qpos, qvel = np.asarray(cfg["qpos"]), np.asarray(cfg["qvel"])
    sim.reset(qpos, qvel)
    loop(sim, cfg, min(50, every))  # warm-up (kernel launch caches), untimed
    total, cpu, done = 0.0, 0.0, 0
    while done < steps:
        sim.reset(qpos, qvel)
        k = min(every, steps - done)
        child = sim.child_cpu if isinstance(sim, Pipe) else (lambda: 0.0)
        t0, c0, d0 = time.perf_counter(), time.process_time(), child()
        loop(sim, cfg, k)
        total += time.perf_counter() - t0
        cpu += time.process_time() - c0 + child() - d0
        done += k
    return steps / total, steps / cpu


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("config")
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args()
    with open(a.config) as f:
        cfg = json.load(f)
    sim = ns.Sim(cfg["init"])
    sim.link_names = cfg["init"]["link_names"]
    every = int(cfg["reset_every"])
    # Interleaved rounds so that a change of the machine's load hits both loops alike; the median of each kept.
    # Wall-clock rates swing by 2x on a shared machine; the CPU-time rates (this process's user + system time;
    # Warp's CPU kernels run on the calling thread) are the comparison, the wall rates are reported beside them.
    own, server, piped = [], [], []
    pipe = Pipe(cfg)
    for _ in range(a.rounds):
        own.append(timed(sim, cfg, own_loop, a.steps, every))
        server.append(timed(sim, cfg, server_loop, a.steps, every))
        piped.append(timed(pipe, cfg, pipe_loop, a.steps, every))
    pipe.close()
    med = lambda xs, i: float(np.median([x[i] for x in xs]))  # noqa: E731
    import newton

    print(
        json.dumps(
            {
                "solver": cfg["init"]["settings"]["solver"],
                "newton": newton.__version__,
                "steps": a.steps,
                "rounds": a.rounds,
                "own_steps_per_cpu_s": med(own, 1),
                "server_in_process_steps_per_cpu_s": med(server, 1),
                "pipe_steps_per_cpu_s": med(piped, 1),
                "own_steps_per_s": med(own, 0),
                "pipe_steps_per_s": med(piped, 0),
                "server_in_process_steps_per_s": med(server, 0),
                "load_average": os.getloadavg(),
            }
        )
    )


if __name__ == "__main__":
    main()
