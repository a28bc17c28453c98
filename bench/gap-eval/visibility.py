"""How much each hidden effect of a trial shows in its log: the trial's log against the log the same plant writes
without that effect (same motion, same sensor noise), in the gap diagnosis's residual units, without anything of the
diagnosis in it. Written independently of ulab (reads the MCAP with the official reader and Unitree's IDL).

    visibility.py DIR [DIR...]        writes DIR/visibility.json and prints one line per hidden effect

DIR is one set of a split (`run.sh visibility SPLIT` fills it): `DIR/counterfactual/` holds the trials' logs again
and, per hidden effect K, `trial_NNN.without_K.mcap` with the removed effect in `trial_NNN.without_K.json`
(`ulab gap bench --counterfactuals`, `mujoco_trials.py --counterfactuals`); each regenerated log must be byte for
byte the set's `trial_NNN.mcap`, the log the judge read.

The measure is the judge's evidence for a perfect replay. Per window of 0.1 s of log time and per column (each joint;
the IMU), d = the mean over the window's states of the squared difference of the two logs in the diagnosis's
residual scales (joint angle 2 mrad, speed 0.1 rad/s, torque 1 % of the joint's torque limit, averaged over the
three; IMU: orientation 5 mrad and gyro 0.02 rad/s, averaged over the six components), and nu = the column's sensor
noise read off the trial's log (second differences, as the diagnosis reads it; at least 0.01). A replay that models
everything but the effect leaves d + nu in that window, a replay that also models it leaves nu, and the judge scores
that change as ln((d + 2 nu) / (2 nu)) summed over columns (docs/gap/method.md, "Evidence"). `signature` is its mean
over the log's windows. The judge names an effect only when the lower bound of this evidence on held-out windows
reaches `min_gain`; an effect whose signature is below `min_gain` does not move the log enough for that, whatever the
fit, so score.py's second table drops it from the trial's expected set (it is still scored in the strict table).
The signature counts the whole log difference, also the part a replay restarted from each window's logged state does
not see (an encoder offset moves every angle reading); it is an upper bound of what a window's replay can show.
"""
import json
import math
import os
import re
import sys
import types

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from score import torque_limits  # noqa: E402
from mujoco_trials import MOTORS  # noqa: E402

SIGMA_Q, SIGMA_DQ, SIGMA_TAU_FRAC, SIGMA_QUAT, SIGMA_GYRO = 2e-3, 0.1, 0.01, 5e-3, 0.02
SCORE_FLOOR = 0.01
WINDOW_S = 0.1


def read_states(path):
    """Stamps (s) and arrays q, dq, tau (n x motors), quat (n x 4, w first), gyro (n x 3) of the log's LowStates."""
    sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))
    from mcap.reader import make_reader
    from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowState_
    t, q, dq, tau, quat, gyro = [], [], [], [], [], []
    nm = len(MOTORS)
    with open(path, "rb") as f:
        for _, _, msg in make_reader(f).iter_messages(topics=["rt/lowstate"]):
            s = LowState_.deserialize(msg.data)
            t.append(msg.log_time * 1e-9)
            q.append([s.motor_state[k].q for k in range(nm)])
            dq.append([s.motor_state[k].dq for k in range(nm)])
            tau.append([s.motor_state[k].tau_est for k in range(nm)])
            quat.append(list(s.imu_state.quaternion))
            gyro.append(list(s.imu_state.gyroscope))
    return tuple(np.asarray(x, dtype=float) for x in (t, q, dq, tau, quat, gyro))


def rotation_angle(qa, qb):
    """Angle (rad) of the rotation between unit quaternions, row by row (w, x, y, z)."""
    dot = np.abs(np.sum(qa * qb, axis=1)) / (np.linalg.norm(qa, axis=1) * np.linalg.norm(qb, axis=1))
    return 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))


def noise_variance(x):
    """Per column of x (samples x channels), the white-noise variance read off its second differences."""
    d = np.abs(x[2:] - 2.0 * x[1:-1] + x[:-2])
    sigma = np.median(d, axis=0) / (0.67448975 * math.sqrt(6.0))
    return sigma * sigma


def signature(log, without, limits):
    """Mean over 0.1 s windows of the judge's evidence for a perfect replay of the effect (see the module doc)."""
    # The states the two logs share by stamp (a latency starts a log's states later).
    ka, kb = (np.round(x[0] * 1e6).astype(np.int64) for x in (log, without))
    _, ia, ib = np.intersect1d(ka, kb, return_indices=True)
    if len(ia) < 0.9 * min(len(ka), len(kb)):
        raise SystemExit("the two logs share few LowState stamps: not the same plant run")
    t, q, dq, tau, quat, gyro = (x[ia] for x in log)
    t0, q0, dq0, tau0, quat0, gyro0 = (x[ib] for x in without)
    n = len(t)
    sig_tau = np.array([SIGMA_TAU_FRAC * max(limits[m], 1.0) for m in MOTORS])
    joint = (((q[:n] - q0[:n]) / SIGMA_Q) ** 2 + ((dq[:n] - dq0[:n]) / SIGMA_DQ) ** 2
             + ((tau[:n] - tau0[:n]) / sig_tau) ** 2) / 3.0
    # A small rotation's vector has the angle as its length: its three components' squares sum to the angle's square.
    imu = ((rotation_angle(quat[:n], quat0[:n]) / SIGMA_QUAT) ** 2
           + np.sum(((gyro[:n] - gyro0[:n]) / SIGMA_GYRO) ** 2, axis=1)) / 6.0
    d = np.column_stack([joint, imu])
    nu_joint = (noise_variance(q) / SIGMA_Q ** 2 + noise_variance(dq) / SIGMA_DQ ** 2
                + noise_variance(tau) / sig_tau ** 2) / 3.0
    nu_imu = np.sum(noise_variance(gyro) / SIGMA_GYRO ** 2) / 6.0
    nu = np.maximum(np.append(nu_joint, nu_imu), SCORE_FLOOR)
    window = np.floor((t[:n] - t[0]) / WINDOW_S).astype(int)
    gains = []
    for w in np.unique(window):
        dw = d[window == w].mean(axis=0)
        gains.append(float(np.sum(np.log((dw + 2.0 * nu) / (2.0 * nu)))))
    return float(np.mean(gains)), len(gains), nu


def oracle(differences, nu):
    """The mean over windows of the judge's evidence for a perfect replay of the effect, from the per-window,
    per-column differences of the trial's plant with and without it (`ulab gap bench --counterfactuals`)."""
    d = np.asarray(differences, dtype=float)
    return float(np.mean(np.sum(np.log((d + 2.0 * nu) / (2.0 * nu)), axis=1)))


def main(dirs):
    limits = torque_limits()
    for d in dirs:
        rows = []
        cf = os.path.join(d, "counterfactual")
        for f in sorted(os.listdir(cf)):
            m = re.fullmatch(r"trial_(\d{3})\.without_(\d+)\.mcap", f)
            if not m:
                continue
            trial, k = int(m.group(1)), int(m.group(2))
            removed = json.load(open(os.path.join(cf, f"trial_{trial:03}.without_{k}.json")))
            judged = os.path.join(d, f"trial_{trial:03}.mcap")
            regenerated = os.path.join(cf, f"trial_{trial:03}.mcap")
            if os.path.exists(judged) and open(judged, "rb").read() != open(regenerated, "rb").read():
                raise SystemExit(f"{regenerated} is not the log the judge read ({judged})")
            value, windows, nu = signature(read_states(regenerated), read_states(os.path.join(cf, f)), limits)
            windowed = oracle(removed["oracle_differences"], nu) if removed.get("oracle_differences") else None
            rows.append({"trial": trial, "effect": k, "kind": removed["kind"], "unit": removed["unit"],
                         "value": removed["value"], "signature": value, "windows": windows, "oracle": windowed})
            print(f"{os.path.basename(os.path.normpath(d))} trial {trial:3} {removed['kind']:>17}@{removed['unit']:<20}"
                  f" signature {value:8.3f}  oracle {'-' if windowed is None else format(windowed, '8.3f')}")
        with open(os.path.join(d, "visibility.json"), "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    main(sys.argv[1:])
