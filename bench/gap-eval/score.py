"""Strict scores of gap-diagnosis reports against the labels of their trials, written independently of ulab's own
bench scoring (which it does not import).

    score.py DIR [DIR...] [--json OUT]

DIR is one set's output: either `trial_NNN.labels.json` from `mujoco_trials.py`, or `scores.json` from `ulab gap bench --out
DIR`; and `trial_NNN/report.json` per trial. A set's name (its directory name) says plant and motion.

Rules (issue 57):
- the named effects of a report are its effects with `named: true`, each on the units of its `params`;
- a named effect matches an injected one when the kinds agree and, for joint and group effects, every named unit
  overlaps the injected joints and together they cover them (a limb covers its joints);
- a single effect is right when it is matched and nothing else is named; a pair when both are matched and nothing
  else is named; a control or an out-of-library trial when nothing is named;
- a trial has a wrong name when some named effect matches no injected one (any name on a control or out-of-library
  trial is wrong).

A second table applies the same rules to the effects the log can show. A torque ceiling acts only when the motor
demands more than it: while the delivered torque (`tau_est`) stays below the ceiling, the plant with it and the plant
without it give the same log, and no method can name it. An injected torque_saturation whose unit's largest |tau_est|
in the trial's log (`trial_NNN.mcap`) stays under REACHED of its ceiling (value x the joint's torque limit in
Unitree's MJCF) is dropped from the trial's expected set: a single becomes an "unseen" trial, right when nothing is
named; a pair becomes a single. The log, the labels and Unitree's MJCF decide this, not ulab.
"""
import argparse
import json
import os
import re
import sys
import types

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from mujoco_trials import LIMBS, MOTORS, covered  # noqa: E402

GROUPS = set(LIMBS) | {"torso"}
# A ceiling counts as reached when the delivered torque comes within 5 % of it: the plants' torque noise is a fraction
# of that, and a clip that engages holds tau_est at the ceiling (the reached ones of eval2 sit at 1.00-1.05 of it,
# the others under 0.75).
REACHED = 0.95


def torque_limits():
    """Each motor's torque limit (N·m) from Unitree's MJCF (`actuatorfrcrange` of its joint)."""
    shared = os.environ.get("ULAB_SHARED") or os.path.join(HERE, "..", "..", "..", "shared")
    xml = open(os.path.join(shared, "reference/h1_2/unitree_mujoco_h1_2_handless.xml")).read()
    found = dict(re.findall(r'<joint name="([a-z_]+)_joint"[^>]*actuatorfrcrange="-?[0-9.]+ ([0-9.]+)"', xml))
    return {m: float(found[m]) for m in MOTORS}


def peak_torques(log):
    """Largest |tau_est| of each motor over the log's LowStates (N·m), read with the mcap reader and Unitree's IDL."""
    sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))
    from mcap.reader import make_reader
    from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowState_
    peak = [0.0] * len(MOTORS)
    with open(log, "rb") as f:
        for _, _, msg in make_reader(f).iter_messages(topics=["rt/lowstate"]):
            s = LowState_.deserialize(msg.data)
            for k in range(len(MOTORS)):
                peak[k] = max(peak[k], abs(s.motor_state[k].tau_est))
    return dict(zip(MOTORS, peak))


def unseen(injected, log, limits):
    """Whether the log never shows this injected effect: a torque ceiling its delivered torque never reaches."""
    if injected["kind"] != "torque_saturation" or not os.path.exists(log):
        return False
    joints = injected_joints(injected) or set()
    peaks = peak_torques(log)
    return all(peaks[j] < REACHED * injected["value"] * limits[j] for j in joints)


def unit_joints(unit):
    """Motor names a report's unit covers; None for the robot-wide and IMU units."""
    if unit == "robot" or unit.startswith("imu"):
        return None
    if unit in GROUPS:
        return set(covered(unit)) if unit != "torso" else {"torso"}
    if unit in MOTORS:
        return {unit}
    raise ValueError(f"unknown unit {unit!r}")


def named_effects(report):
    """(kind, [units]) of every named effect."""
    return [(e["kind"], [p["unit"] for p in e.get("params", [])]) for e in report.get("effects", []) if e.get("named")]


def matches(named, injected):
    kind, units = named
    if kind != injected["kind"]:
        return False
    want = injected_joints(injected)
    if want is None:
        return True
    got = [unit_joints(u) for u in units]
    if not got or any(g is None for g in got):
        return False
    return all(g & want for g in got) and want <= set().union(*got)


def injected_joints(injected):
    unit = injected["unit"]
    if injected.get("joints"):
        return set(injected["joints"])
    return unit_joints(unit)


def load_set(d):
    """Trials of one set: (trial, class, injected, report or None)."""
    out = []
    label_files = sorted(f for f in os.listdir(d) if f.endswith(".labels.json"))
    if label_files:
        labels = [json.load(open(os.path.join(d, f))) for f in label_files]
        rows = [(v["trial"], v["injected"], v.get("out_of_library"), v.get("motion")) for v in labels]
    elif os.path.exists(os.path.join(d, "scores.json")):
        scores = json.load(open(os.path.join(d, "scores.json")))
        rows = [(s["trial"], s["injected"], s.get("out_of_library"), s.get("input")) for s in scores]
    else:
        raise SystemExit(f"{d}: neither labels.json nor scores.json")
    for trial, injected, ool, motion in sorted(rows, key=lambda r: r[0]):
        path = os.path.join(d, f"trial_{trial:03}", "report.json")
        report = json.load(open(path)) if os.path.exists(path) else None
        cls = "out_of_library" if ool else {0: "control", 1: "single", 2: "pair"}[len(injected)]
        out.append((trial, cls, injected, report, motion, os.path.join(d, f"trial_{trial:03}.mcap")))
    return out


def score_trial(cls, injected, report):
    named = named_effects(report)
    matched = [any(matches(n, i) for n in named) for i in injected]
    wrong = [n for n in named if not any(matches(n, i) for i in injected)]
    right = all(matched) and not wrong if injected else not named
    return {"right": right, "wrong_names": len(wrong), "named": named, "matched": matched}


def print_table(title, table, classes, heads):
    print(f"\n{title}\n" if title else "", end="")
    print("| set | " + " | ".join(heads) + " |")
    print("|---|" + "---|" * len(heads))
    total = {c: [0, 0] for c in classes}
    for name, t in table.items():
        cells = []
        for c in classes:
            r, n = t.get(c, [0, 0])
            total[c][0] += r
            total[c][1] += n
            cells.append(f"{r}/{n}" if n else "-")
        print(f"| {name} | " + " | ".join(cells) + " |")
    cells = [f"{r}/{n} ({100 * r / n:.0f} %)" if n else "-" for r, n in (total[c] for c in classes)]
    print("| all | " + " | ".join(cells) + " |")


def count(table, name, cls, s):
    t = table.setdefault(name, {})
    c = t.setdefault(cls, [0, 0])
    c[0] += s["right"]
    c[1] += 1
    w = t.setdefault("wrong_trials", [0, 0])
    w[0] += s["wrong_names"] > 0
    w[1] += 1


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--json")
    a = ap.parse_args()
    limits = torque_limits()
    table, seen_table, rows = {}, {}, []
    for d in a.dirs:
        name = os.path.basename(os.path.normpath(d))
        for trial, cls, injected, report, motion, log in load_set(d):
            if report is None:
                rows.append({"set": name, "trial": trial, "class": cls, "missing": True})
                continue
            s = score_trial(cls, injected, report)
            count(table, name, cls, s)
            shown = [i for i in injected if not unseen(i, log, limits)]
            seen_cls = cls if cls == "out_of_library" or len(shown) == len(injected) else (
                {0: "unseen", 1: "single", 2: "pair"}[len(shown)])
            seen_s = s if len(shown) == len(injected) else score_trial(seen_cls, shown, report)
            count(seen_table, name, seen_cls, seen_s)
            rows.append(dict(s, set=name, trial=trial, cls=cls, motion=motion, injected=injected,
                             unseen=[i for i in injected if i not in shown], seen_cls=seen_cls, seen_right=seen_s["right"]))
    classes = ["single", "pair", "control", "out_of_library", "wrong_trials"]
    heads = ["singles right", "pairs right", "controls clean", "out-of-library clean", "trials with a wrong name"]
    print_table(None, table, classes, heads)
    missing = [r for r in rows if r.get("missing")]
    if missing:
        print(f"\n{len(missing)} trials without a report: " + ", ".join(f"{r['set']}/{r['trial']}" for r in missing))
    print_table("Effects the log can show (a torque ceiling its delivered torque never reaches is dropped; a single "
                "left with none is an unseen trial, right when nothing is named):", seen_table,
                classes[:2] + ["unseen"] + classes[2:],
                heads[:2] + ["unseen clean"] + heads[2:])
    if a.json:
        json.dump({"table": table, "seen_table": seen_table, "rows": rows}, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
