"""Trials of the gap diagnosis's evaluation made by a plant outside ulab: `tests/gap/suspended_plant.py` (Unitree's
MJCF in MuJoCo's Python bindings, 1 ms steps, PD at 1 kHz, sensor noise, zstd MCAP from the official writer) with
hidden effects drawn here, written as logs with a labels file each.

    mujoco_trials.py --seed S --trials N --out DIR --plan PLAN.mcap [--duration S] [--out-of-library K] [--only I]...
                     [--counterfactuals]

Trial i follows the pattern single, single, pair, control (i mod 4); blocks of four alternate between the excitation
plan (`--plan`, written by `ulab gap excite`) and gentle chirps (a third of the plant's chirp amplitude). Then K
trials hide one effect outside the library (a load-proportional friction on a limb, a torque ripple on a joint).
Each trial's draws come from the seed and its index alone. `trial_NNN.labels.json` holds what was injected in the
diagnosis's terms (kind, unit, the motor names the unit covers, the value in the library's units); the diagnosis
never reads it.
"""
import argparse
import json
import os
import random
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "tests", "gap"))
import suspended_plant as plant  # noqa: E402

MOTORS = ["left_hip_yaw", "left_hip_pitch", "left_hip_roll", "left_knee", "left_ankle_pitch", "left_ankle_roll",
          "right_hip_yaw", "right_hip_pitch", "right_hip_roll", "right_knee", "right_ankle_pitch", "right_ankle_roll",
          "torso",
          "left_shoulder_pitch", "left_shoulder_roll", "left_shoulder_yaw", "left_elbow", "left_wrist_roll",
          "left_wrist_pitch", "left_wrist_yaw",
          "right_shoulder_pitch", "right_shoulder_roll", "right_shoulder_yaw", "right_elbow", "right_wrist_roll",
          "right_wrist_pitch", "right_wrist_yaw"]
LIMBS = ["left_leg", "right_leg", "left_arm", "right_arm"]
# Joints an effect is drawn on: not the wrists nor the ankle rolls, whose light links and small motion on the rig leave
# a joint-level effect below any log's resolution.
JOINTS = [m for m in MOTORS if "wrist" not in m and not m.endswith("ankle_roll")]
# Joints whose gravity load changes with the pose (an encoder offset shows only through it).
LOADED = [m for m in MOTORS if m.endswith(("hip_pitch", "knee", "shoulder_pitch", "elbow"))]
MODEL_ARMATURE = 0.1
KINDS = ["damping", "friction", "armature", "gain_scale", "encoder_offset", "torque_saturation", "latency",
         "backlash", "link_mass", "link_com", "imu_bias"]


def covered(unit):
    """The motor names a unit covers."""
    if unit in LIMBS:
        side, limb = unit.split("_")
        return [m for m in MOTORS if m.startswith(side + "_") and (("leg" == limb) == any(
            k in m for k in ("hip", "knee", "ankle")))]
    return [unit]


def draw_effect(kind, rng):
    """One effect of `kind`: (label, plant arguments)."""
    sign = rng.choice([-1.0, 1.0])
    unit = rng.choice(LIMBS) if rng.random() < 0.5 else rng.choice(JOINTS)
    if kind == "encoder_offset":
        unit = rng.choice(LOADED) if rng.random() < 0.7 else rng.choice(LIMBS)
    target = unit if unit in LIMBS else unit + "_joint"
    if kind == "damping":
        v = rng.uniform(1.5, 4.0)
        args = ["--extra-damping", f"{target}={v}"]
    elif kind == "friction":
        v = rng.uniform(1.0, 3.0)
        args = ["--extra-frictionloss", f"{target}={v}"]
    elif kind == "armature":
        added = rng.uniform(0.1, 0.25)
        v = (MODEL_ARMATURE + added) / MODEL_ARMATURE
        args = ["--extra-armature", f"{target}={added}"]
    elif kind == "gain_scale":
        v = rng.uniform(0.6, 0.75) if rng.random() < 0.5 else rng.uniform(1.3, 1.5)
        args = ["--gain-scale", f"{target}={v}"]
    elif kind == "encoder_offset":
        v = sign * rng.uniform(0.04, 0.08)
        args = ["--encoder-offset", f"{target}={v}"]
    elif kind == "torque_saturation":
        v = rng.uniform(0.3, 0.5)
        args = ["--torque-scale", f"{target}={v}"]
    elif kind == "latency":
        unit, v = "robot", float(rng.randint(6, 14) * 2)
        args = ["--latency-ms", f"{v}"]
    elif kind == "backlash":
        v = rng.uniform(0.02, 0.05)
        args = ["--backlash", f"{target}={v}"]
    elif kind == "link_mass":
        v = rng.uniform(1.3, 1.7)
        args = ["--link-mass", f"{target}={v}"]
    elif kind == "link_com":
        v = sign * rng.uniform(0.03, 0.07)
        args = ["--link-com", f"{target}={v}"]
    elif kind == "imu_bias":
        axis = rng.choice("xyz")
        unit, v = "imu_" + axis, sign * rng.uniform(0.05, 0.2)
        args = ["--gyro-bias", f"{axis}={v}"]
    else:
        raise ValueError(kind)
    joints = covered(unit) if unit not in ("robot",) and not unit.startswith("imu") else []
    return {"kind": kind, "unit": unit, "joints": joints, "value": v}, args


def draw_trial(seed, i, trials):
    """The label and plant arguments of trial i."""
    lab, per_effect, motion = draw_trial_effects(seed, i, trials)
    return lab, [x for a in per_effect for x in a], motion


def draw_trial_effects(seed, i, trials):
    """The label of trial i, the plant arguments of each of its hidden effects (in the label's order) and its motion."""
    rng = random.Random(seed * 1_000_003 + i)
    if i >= trials:
        if (i - trials) % 2 == 0:
            unit = rng.choice(LIMBS)
            mu = rng.uniform(0.1, 0.2)
            return ({"injected": [], "out_of_library": {"kind": "load_friction", "unit": unit, "value": mu}},
                    [["--load-friction", f"{unit}={mu}"]], "plan")
        unit = rng.choice(JOINTS)
        frac = rng.uniform(0.03, 0.06)
        return ({"injected": [], "out_of_library": {"kind": "torque_ripple", "unit": unit, "value": frac}},
                [["--torque-ripple", f"{unit}_joint={frac}"]], "chirp")
    motion = "plan" if (i // 4) % 2 == 0 else "chirp"
    n = [1, 1, 2, 0][i % 4]
    kinds = rng.sample(KINDS, n)
    labels, per_effect = [], []
    for k in kinds:
        lab, a = draw_effect(k, rng)
        labels.append(lab)
        per_effect.append(a)
    return {"injected": labels, "out_of_library": None}, per_effect, motion


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--trials", type=int, required=True)
    ap.add_argument("--out-of-library", type=int, default=0)
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--plan", required=True, help="the excitation plan, from `ulab gap excite`")
    ap.add_argument("--out", required=True)
    ap.add_argument("--only", type=int, action="append", default=[])
    ap.add_argument("--counterfactuals", action="store_true",
                    help="also write, per hidden effect K, trial_NNN.without_K.mcap: the same plant, motion and noise "
                         "without that effect (bench/gap-eval/visibility.py)")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    for i in range(a.trials + a.out_of_library):
        if a.only and i not in a.only:
            continue
        lab, per_effect, motion = draw_trial_effects(a.seed, i, a.trials)
        args = [x for e in per_effect for x in e]
        drive = ["--plan", a.plan] if motion == "plan" else ["--chirp-scale", "0.33"]
        common = ["--duration", str(a.duration), "--noise", "--seed", str(a.seed * 1000 + i)] + drive
        log = os.path.join(a.out, f"trial_{i:03}.mcap")
        plant.main([log] + common + args)
        with open(os.path.join(a.out, f"trial_{i:03}.labels.json"), "w") as f:
            json.dump(dict(lab, trial=i, motion=motion, plant_args=args), f, indent=1, sort_keys=True)
        if a.counterfactuals:
            # The noise and the chirps' phases come from the seed alone, so the two logs differ by the effect only.
            for k, removed in enumerate(lab["injected"]):
                others = [x for j, e in enumerate(per_effect) if j != k for x in e]
                plant.main([os.path.join(a.out, f"trial_{i:03}.without_{k}.mcap")] + common + others)
                with open(os.path.join(a.out, f"trial_{i:03}.without_{k}.json"), "w") as f:
                    json.dump(removed, f, indent=1, sort_keys=True)


if __name__ == "__main__":
    main()
