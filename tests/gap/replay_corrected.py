"""Replays a log's held-out windows on two MJCF models with MuJoCo's official Python bindings, independently of
ulab's replay, and prints how much the second model cuts the gap of the first: the check of `ulab gap diagnose
--export-mjcf` (the corrected model must shrink the residual by what the report says).

    replay_corrected.py --nominal NOMINAL.xml --corrected CORRECTED.xml --log LOG.mcap --report REPORT.json

NOMINAL.xml is the file `--export-mjcf` writes beside the corrected one. Each model's pelvis is welded 2 m above the world (its free joint and the floor removed), as on the diagnosis's rig.
A window starts from the logged state at a held-out window's start (`window_residuals` of the report) and replays
the logged commands through a PD law written here, with the model's `ulab_*` custom numerics (gain scale, encoder
offset, dead band, command latency) and its motors' ctrlrange; the gap metric is the mean over the window's samples
of the joints' squared residuals of angle, speed and torque over 2 mrad, 0.1 rad/s and 1 % of the torque limit
(the nominal model's), averaged over the three and summed over joints. Prints one JSON object.
"""
import argparse
import json
import re
import sys
import types

sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from mcap.reader import make_reader  # noqa: E402
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowCmd_, LowState_  # noqa: E402

SIGMA_Q, SIGMA_DQ, SIGMA_TAU_FRAC = 2e-3, 0.1, 0.01


def welded(path):
    xml = open(path).read()
    xml = re.sub(r"<freejoint[^>]*/>", "", xml)
    xml = re.sub(r'<geom name="floor"[^>]*/>', "", xml)
    xml = re.sub(r'(<body name="pelvis"[^>]*?)pos="[^"]*"', r'\1pos="0 0 2"', xml, count=1)
    return mujoco.MjModel.from_xml_string(xml)


def numeric(m, name, n):
    try:
        return np.array(m.numeric(name).data[:n], dtype=float)
    except KeyError:
        return np.zeros(n)


def read_log(path, nj):
    raw = []
    with open(path, "rb") as f:
        for _s, ch, msg in make_reader(f).iter_messages(topics=["rt/lowcmd", "rt/lowstate"]):
            raw.append((msg.log_time, ch.topic, msg.data))
    t0 = min(t for t, _, _ in raw)
    cmds, states = [], []
    for t, topic, data in sorted(raw, key=lambda r: r[0]):
        ts = (t - t0) * 1e-9
        if topic == "rt/lowcmd":
            c = LowCmd_.deserialize(data).motor_cmd[:nj]
            cmds.append((ts, np.array([x.q for x in c]), np.array([x.dq for x in c]), np.array([x.kp for x in c]),
                         np.array([x.kd for x in c]), np.array([x.tau for x in c]),
                         np.array([x.mode for x in c])))
        else:
            s = LowState_.deserialize(data).motor_state[:nj]
            states.append((ts, np.array([x.q for x in s]), np.array([x.dq for x in s]),
                           np.array([x.tau_est for x in s])))
    return cmds, states


def window_gap(m, cmds, cmd_t, states, start, n, sigma_tau):
    nj = m.nu
    gain = numeric(m, "ulab_gain_scale", nj)
    gain[gain == 0] = 1.0
    offset = numeric(m, "ulab_encoder_offset", nj)
    band = numeric(m, "ulab_backlash", nj)
    latency = float(numeric(m, "ulab_command_latency", 1)[0])
    lo, hi = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
    d = mujoco.MjData(m)
    t, q0, dq0, tau0 = states[start]
    d.qpos[:] = q0 - offset
    d.qvel[:] = dq0
    mujoco.mj_forward(m, d)
    tau = tau0.copy()
    score = 0.0
    count = 0
    for k in range(1, n + 1):
        if start + k >= len(states):
            break
        target = states[start + k]
        steps = max(0, int(round((target[0] - t) / m.opt.timestep)))
        for _ in range(steps):
            i = np.searchsorted(cmd_t, t - latency + 1e-9, side="right") - 1
            if i >= 0:
                _, q_des, dq_des, kp, kd, tff, mode = cmds[i]
                kp, kd, tff = np.where(mode == 0, 0.0, kp), np.where(mode == 0, 0.0, kd), np.where(mode == 0, 0.0, tff)
                err = q_des - (d.qpos + offset)
                err = np.sign(err) * np.maximum(np.abs(err) - 0.5 * band, 0.0)
                tau = np.clip(tff + gain * (kp * err + kd * (dq_des - d.qvel)), lo, hi)
            else:
                tau = np.zeros(nj)
            d.ctrl[:] = tau
            mujoco.mj_step(m, d)
            t += m.opt.timestep
        t = target[0]
        eq = (target[1] - (d.qpos + offset)) / SIGMA_Q
        edq = (target[2] - d.qvel) / SIGMA_DQ
        et = (target[3] - tau) / sigma_tau
        score += np.sum((eq * eq + edq * edq + et * et) / 3.0)
        count += 1
    return score / max(count, 1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--nominal", required=True)
    ap.add_argument("--corrected", required=True)
    ap.add_argument("--log", required=True)
    ap.add_argument("--report", required=True)
    a = ap.parse_args()
    report = json.load(open(a.report))
    nominal, corrected = welded(a.nominal), welded(a.corrected)
    # Both replayed with the numerics the diagnosis replayed the log with (the corrected file's).
    nominal.opt.timestep, nominal.opt.integrator = corrected.opt.timestep, corrected.opt.integrator
    nj = nominal.nu
    sigma_tau = SIGMA_TAU_FRAC * np.maximum(nominal.actuator_ctrlrange[:, 1], 1.0)
    cmds, states = read_log(a.log, nj)
    cmd_t = np.array([c[0] for c in cmds])
    state_t = np.array([s[0] for s in states])
    dt_state = float(np.median(np.diff(state_t)))
    n = max(2, int(round(report["window_s"] / dt_state)))
    starts = [int(np.argmin(np.abs(state_t - w["t"]))) for w in report["window_residuals"] if w["held_out"]]
    gaps = {name: [window_gap(m, cmds, cmd_t, states, s, n, sigma_tau) for s in starts]
            for name, m in (("nominal", nominal), ("corrected", corrected))}
    before, after = float(np.sum(gaps["nominal"])), float(np.sum(gaps["corrected"]))
    print(json.dumps({"windows": len(starts), "nominal_gap": before / max(len(starts), 1),
                      "corrected_gap": after / max(len(starts), 1), "reduction": 1.0 - after / before}))


if __name__ == "__main__":
    main()
