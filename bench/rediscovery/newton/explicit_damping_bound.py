"""The step at which explicitly integrated joint damping turns unstable, computed with MuJoCo (not Newton).

An explicit (or semi-implicit Euler) step applies the damping torque -D·q̇ from the start of the step, so the
damped modes of q̈ = -M⁻¹D·q̇ shrink only while dt·λ < 2 for every eigenvalue λ of M⁻¹D; beyond, the fastest mode
grows by |1 - dt·λ| > 1 per step. This prints λ_max and the critical step 2/λ_max for the MJCF as given and with
every armature set to 0, from MuJoCo's mass matrix at the standing pose lifted to 2 m (the scene of
issue_4269.py). `issue_4269.py --dt S` then tests Newton's SolverFeatherstone on either side of the bound.

  ulab model mjcf > /tmp/h1_2.xml
  .venv/bin/python bench/rediscovery/newton/explicit_damping_bound.py /tmp/h1_2.xml
"""
import json
import re
import sys

import mujoco
import numpy as np


def bound(xml):
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qpos[2] = 2.0
    mujoco.mj_forward(m, d)
    mass = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, mass)
    lam = float(np.linalg.eigvals(np.linalg.solve(mass, np.diag(m.dof_damping))).real.max())
    return {"lambda_max": lam, "critical_dt": 2.0 / lam}


def main():
    xml = open(sys.argv[1]).read()
    for config, x in [("as given", xml), ("armature 0", re.sub(r'armature="[^"]*"', 'armature="0"', xml))]:
        print(json.dumps({"mujoco": mujoco.__version__, "config": config, **bound(x)}), flush=True)


if __name__ == "__main__":
    main()
