"""Rediscovery of Newton issue #4269 (SolverFeatherstone unstable with zero joint armature) and a check of #2303
(SolverFeatherstone ignoring MJCF joint damping), on the H1-2 in free fall, Newton 1.8.0 on the CPU.

Scene: the H1-2 MJCF that `ulab model mjcf` prints (floor geom dropped), pelvis at 2 m, no contacts, zero torques,
joint rates uniform in ±1 rad/s (seed 1), dt 2 ms, 0.5 s. Oracle (the project's finite-state invariant): the
state must stay finite. Configurations: Featherstone with armature 0, with the model's armature (0.1 kg·m²), and
SolverMuJoCo with armature 0 (the independent solver; needs `pip install "newton[sim]==1.8.0"`).
#2303: Featherstone with the model's damping (1 N·m·s/rad) vs none, largest joint rate after 0.5 s; damping
honoured means a smaller rate.

  ulab model mjcf > /tmp/h1_2.xml
  .venv-newton/bin/python bench/rediscovery/newton/issue_4269.py /tmp/h1_2.xml ["CONFIG"] [--dt S]
Prints one JSON line per configuration (CONFIG: that row only) and exits 0 (the verdicts are data, not a test).
`--dt` changes the step (default 2 ms) to test the mechanism against the bound `explicit_damping_bound.py` predicts.
"""
import argparse
import json
import re

import numpy as np
import newton
import warp as wp

wp.config.quiet = True
SECONDS, DT = 0.5, 0.002


def build(mjcf, armature, damping):
    xml = re.sub(r"<geom name=\"floor\"[^>]*/>", "", mjcf)
    if not armature:
        xml = re.sub(r'armature="[^"]*"', 'armature="0"', xml)
    if not damping:
        xml = re.sub(r'damping="[^"]*"', 'damping="0"', xml)
    b = newton.ModelBuilder()
    b.add_mjcf(xml, enable_self_collisions=False, parse_visuals=False)
    return b.finalize(device="cpu")


def run(mjcf, solver, armature, damping=True, dt=DT):
    m = build(mjcf, armature, damping)
    s0, s1, ctl = m.state(), m.state(), m.control()
    q = m.joint_q.numpy()
    q[2] = 2.0
    qd = np.zeros(m.joint_dof_count, np.float32)
    qd[6:] = np.random.default_rng(1).uniform(-1, 1, m.joint_dof_count - 6)
    s0.joint_q.assign(q)
    s0.joint_qd.assign(qd)
    newton.eval_fk(m, s0.joint_q, s0.joint_qd, s0)
    if solver == "featherstone":
        sol = newton.solvers.SolverFeatherstone(m, angular_damping=0.0)
    else:
        sol = newton.solvers.SolverMuJoCo(m, disable_contacts=True)
    for i in range(int(round(SECONDS / dt))):
        sol.step(s0, s1, ctl, None, dt)
        s0, s1 = s1, s0
        x = np.concatenate([s0.joint_q.numpy(), s0.joint_qd.numpy()])
        if not np.isfinite(x).all():
            return {"finite": False, "t": round((i + 1) * dt, 6)}
    return {"finite": True, "t": SECONDS, "max_joint_rate": float(np.abs(s0.joint_qd.numpy()[6:]).max())}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mjcf")
    ap.add_argument("config", nargs="?")
    ap.add_argument("--dt", type=float, default=DT)
    a = ap.parse_args()
    mjcf, dt = open(a.mjcf).read(), a.dt
    rows = [
        ("#4269", "SolverFeatherstone", "armature 0", lambda: run(mjcf, "featherstone", False, dt=dt)),
        ("#4269", "SolverFeatherstone", "armature 0.1", lambda: run(mjcf, "featherstone", True, dt=dt)),
        # Featherstone applies joint damping explicitly: d·dt/I ≫ 2 on the wrists without armature.
        ("#4269", "SolverFeatherstone", "armature 0, damping 0",
         lambda: run(mjcf, "featherstone", False, False, dt=dt)),
        ("#4269", "SolverMuJoCo", "armature 0", lambda: run(mjcf, "mujoco", False, dt=dt)),
        ("#2303", "SolverFeatherstone", "damping 1", lambda: run(mjcf, "featherstone", True, True, dt=dt)),
        ("#2303", "SolverFeatherstone", "damping 0", lambda: run(mjcf, "featherstone", True, False, dt=dt)),
    ]
    for issue, solver, config, f in rows:
        if a.config and a.config != config:
            continue
        try:
            r = f()
            verdict = "flagged" if not r["finite"] else "quiet"
        except Exception as e:  # noqa: BLE001 - a solver that cannot run is reported, not fatal
            r, verdict = {"error": f"{type(e).__name__}: {e}"[:200]}, "n/a"
        print(json.dumps({"newton": newton.__version__, "issue": issue, "solver": solver, "config": config,
                          "dt": dt, "verdict": verdict, **r}), flush=True)


if __name__ == "__main__":
    main()
