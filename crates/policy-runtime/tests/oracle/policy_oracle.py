#!/usr/bin/env python3
"""Independent reference for policy-runtime: recorded robot-state sequences, the observations the two H1-2
policy conventions build from them, and the networks' outputs.

Written from the conventions in ../shared/reference/README.md ("Policy conventions") and the upstream deploy
scripts (Gepetto/h1v2-Isaac biped_deploy controllers/rl.py; unitree_rl_gym deploy_mujoco.py / deploy_real.py),
NOT from the Rust code:

* Gepetto demo_rsl (ONNX MLP, 270 inputs): frame = [ang_vel*0.25, projected gravity, command, q-default (12),
  dq*0.05 (12), last action (12)]; per-term history of 6 frames (first call fills it with copies), flattened
  term by term, oldest first. Run with onnxruntime.
* unitree_rl_gym LSTM (47 inputs): [ang_vel*0.25, projected gravity, command*(2,2,0.25), q-default, dq*0.05,
  last action, sin, cos of 2*pi*((t mod 0.8)/0.8)]. Run with numpy (float64) from the .npz arrays, PyTorch's
  LSTM equations (gates i, f, g, o; both biases), state persisting from the stored hidden/cell state.

Both: policy joints are motor slots 0..11; q_des = default + 0.25*action on those, default elsewhere.

Writes <out>/gepetto_demo_rsl.json and <out>/unitree_rl_gym_lstm.json (deterministic: fixed seeds).
Usage: policy_oracle.py [--out DIR]  (reads $ULAB_SHARED/reference/policies/)
"""
import argparse
import hashlib
import json
import os
import sys

import numpy as np
import onnxruntime as ort

LEG_DEFAULT = [0.0, -0.16, 0.0, 0.36, -0.2, 0.0] * 2
DEFAULT_Q = np.array(LEG_DEFAULT + [0.0] * 15)  # 27 slots: legs, waist, arms at 0
N_SLOTS = 27
PERIOD = 0.02


def quat_from_rpy(roll, pitch, yaw):
    """[w, x, y, z] of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return np.array([
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ])


def rot_from_quat(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def projected_gravity(q):
    return rot_from_quat(q).T @ np.array([0.0, 0.0, -1.0])


def states(seed, n_steps, commands):
    """A smooth, plausible walking-like state sequence (rounded to 1e-6 so the JSON stays small and exact)."""
    rng = np.random.default_rng(seed)
    rpy = np.array([0.0, 0.0, rng.uniform(-np.pi, np.pi)])
    w = np.zeros(3)
    dev = np.zeros(N_SLOTS)
    dq = np.zeros(N_SLOTS)
    out = []
    for k in range(n_steps):
        rpy[:2] = 0.8 * rpy[:2] + rng.normal(0.0, 0.03, 2)
        rpy[2] += rng.normal(0.0, 0.02)
        w = 0.7 * w + rng.normal(0.0, 0.25, 3)
        leg_sd = np.r_[np.full(12, 0.12), 0.05, np.full(14, 0.08)]
        dev = 0.75 * dev + rng.normal(0.0, 1.0, N_SLOTS) * leg_sd
        dq = 0.6 * dq + rng.normal(0.0, 1.0, N_SLOTS) * np.r_[np.full(12, 1.5), 0.3, np.full(14, 0.5)]
        quat = quat_from_rpy(*rpy)
        out.append({
            # unitree_rl_gym's deploy scripts: t = (calls so far, this one included) * 0.02 s
            "time": round((k + 1) * PERIOD, 6),
            "base_quat": [round(v, 6) for v in quat],
            "base_ang_vel": [round(v, 6) for v in w],
            "q": [round(v, 6) for v in DEFAULT_Q + dev],
            "dq": [round(v, 6) for v in dq],
            "command": list(commands[min(k * len(commands) // n_steps, len(commands) - 1)]),
        })
    return out


def q_des_from(action):
    q_des = DEFAULT_Q.copy()
    q_des[:12] += 0.25 * np.asarray(action, dtype=np.float64)
    return q_des


def frame_common(s):
    q = np.array(s["q"])
    return (
        np.array(s["base_ang_vel"]) * 0.25,
        projected_gravity(np.array(s["base_quat"])),
        q[:12] - DEFAULT_Q[:12],
        np.array(s["dq"])[:12] * 0.05,
    )


def f32_list(a):
    return [float(v) for v in np.asarray(a, dtype=np.float32)]


def gepetto(shared, out):
    path = os.path.join(shared, "reference/policies/h1_2_gepetto_demo_rsl.onnx")
    sess = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    name = sess.get_inputs()[0].name
    seq = states(20251122, 14, [(0.5, 0.0, 0.0), (0.8, -0.3, 0.4), (-0.2, 0.2, -0.6)])
    history = None  # list of 6 per-term lists, oldest first
    last_action = np.zeros(12, dtype=np.float32)
    steps = []
    for s in seq:
        ang, grav, qrel, dqs = frame_common(s)
        frame = [ang, grav, np.array(s["command"]), qrel, dqs, last_action.astype(np.float64)]
        if history is None:
            history = [[t] * 6 for t in frame]
        else:
            history = [h[1:] + [t] for h, t in zip(history, frame)]
        obs = np.concatenate([np.concatenate(h) for h in history]).astype(np.float32)
        action = sess.run(None, {name: obs[None, :]})[0][0]
        last_action = action
        steps.append(dict(s, obs=f32_list(obs), action=f32_list(action), q_des=list(q_des_from(action))))
    write(out, "gepetto_demo_rsl", path, steps, f"onnxruntime {ort.__version__}")


def lstm_forward(p, x, h, c):
    gates = p["memory.weight_ih_l0"] @ x + p["memory.bias_ih_l0"] + p["memory.weight_hh_l0"] @ h + p["memory.bias_hh_l0"]
    i, f, g, o = np.split(gates, 4)
    sig = lambda v: 1.0 / (1.0 + np.exp(-v))  # noqa: E731
    c = sig(f) * c + sig(i) * np.tanh(g)
    h = sig(o) * np.tanh(c)
    y = p["actor.0.weight"] @ h + p["actor.0.bias"]
    y = np.where(y > 0, y, np.expm1(y))  # ELU
    y = p["actor.2.weight"] @ y + p["actor.2.bias"]
    return y, h, c


def unitree_lstm(shared, out):
    path = os.path.join(shared, "reference/policies/h1_2_unitree_rl_gym_lstm.npz")
    z = np.load(path)
    p = {k: z[k].astype(np.float64) for k in z.files}
    h = p["hidden_state"].reshape(-1)
    c = p["cell_state"].reshape(-1)
    seq = states(47, 40, [(0.5, 0.0, 0.0), (0.3, 0.2, -0.5), (0.0, 0.0, 0.0), (0.8, 0.0, 0.3)])
    last_action = np.zeros(12)
    steps = []
    for s in seq:
        ang, grav, qrel, dqs = frame_common(s)
        phase = (s["time"] % 0.8) / 0.8
        obs = np.concatenate([
            ang, grav, np.array(s["command"]) * np.array([2.0, 2.0, 0.25]), qrel, dqs, last_action,
            [np.sin(2 * np.pi * phase), np.cos(2 * np.pi * phase)],
        ]).astype(np.float32)
        action, h, c = lstm_forward(p, obs.astype(np.float64), h, c)
        last_action = action.astype(np.float32).astype(np.float64)
        steps.append(dict(s, obs=f32_list(obs), action=f32_list(action), q_des=list(q_des_from(action))))
    # The recurrent state must matter for this sequence: the last step's action from a fresh state differs.
    fresh, _, _ = lstm_forward(p, np.array(steps[-1]["obs"], dtype=np.float64),
                               p["hidden_state"].reshape(-1), p["cell_state"].reshape(-1))
    assert np.max(np.abs(fresh - np.array(steps[-1]["action"]))) > 1e-2, "sequence does not exercise the LSTM state"
    write(out, "unitree_rl_gym_lstm", path, steps, f"numpy {np.__version__} (float64)")


def write(out, policy, model_path, steps, generator):
    with open(model_path, "rb") as f:
        sha = hashlib.sha256(f.read()).hexdigest()
    doc = {
        "policy": policy,
        "model": os.path.basename(model_path),
        "model_sha256": sha,
        "generator": f"crates/policy-runtime/tests/oracle/policy_oracle.py, {generator}",
        "control_period": PERIOD,
        "steps": steps,
    }
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, f"{policy}.json"), "w") as f:
        json.dump(doc, f, separators=(",", ":"))
        f.write("\n")


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.normpath(os.path.join(here, "../../../.."))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(root, "corpus/golden/policies"))
    args = ap.parse_args()
    shared = os.environ.get("ULAB_SHARED") or os.path.join(root, "../shared")
    if not os.path.isdir(os.path.join(shared, "reference/policies")):
        sys.exit(f"no reference policies under {shared}/reference/policies (set ULAB_SHARED)")
    gepetto(shared, args.out)
    unitree_lstm(shared, args.out)


if __name__ == "__main__":
    main()
