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

A second table applies the same rules to the effects the log can show. An effect that moves the log by less than the
judge needs to name anything cannot be named by any method that keeps that bar: `visibility.py` compares each trial's
log with the log of the same plant, motion and sensor noise without one hidden effect (`run.sh visibility SPLIT`
writes them), and an injected effect whose `signature` (the judge's evidence for a replay that models everything,
over the whole log) is below the report's own `min_gain` is dropped from the trial's expected set: a single becomes
an "unseen" trial, right when nothing is named; a pair becomes a single. The plant and the log decide this, not the
judge. A set without `visibility.json` gets no second table.
"""
import argparse
import json
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from mujoco_trials import LIMBS, MOTORS, covered  # noqa: E402

GROUPS = set(LIMBS) | {"torso"}


def torque_limits():
    """Each motor's torque limit (N·m) from Unitree's MJCF (`actuatorfrcrange` of its joint)."""
    shared = os.environ.get("ULAB_SHARED") or os.path.join(HERE, "..", "..", "..", "shared")
    xml = open(os.path.join(shared, "reference/h1_2/unitree_mujoco_h1_2_handless.xml")).read()
    found = dict(re.findall(r'<joint name="([a-z_]+)_joint"[^>]*actuatorfrcrange="-?[0-9.]+ ([0-9.]+)"', xml))
    return {m: float(found[m]) for m in MOTORS}


def load_visibility(d):
    """{(trial, effect index): signature} of a set, or None when `visibility.py` has not run on it."""
    path = os.path.join(d, "visibility.json")
    if not os.path.exists(path):
        return None
    return {(r["trial"], r["effect"]): (r["kind"], r["signature"]) for r in json.load(open(path))}


def shown_effects(trial, injected, visibility, min_gain):
    """The injected effects whose signature in the log reaches the judge's bar."""
    shown = []
    for k, inj in enumerate(injected):
        kind, sig = visibility.get((trial, k), (None, None))
        if kind != inj["kind"]:
            raise SystemExit(f"trial {trial}: visibility.json has no signature of its effect {k} ({inj['kind']})")
        if sig >= min_gain:
            shown.append(inj)
    return shown


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
    table, seen_table, rows, no_visibility = {}, {}, [], []
    for d in a.dirs:
        name = os.path.basename(os.path.normpath(d))
        visibility = load_visibility(d)
        if visibility is None:
            no_visibility.append(name)
        for trial, cls, injected, report, motion, log in load_set(d):
            if report is None:
                rows.append({"set": name, "trial": trial, "class": cls, "missing": True})
                continue
            s = score_trial(cls, injected, report)
            count(table, name, cls, s)
            if visibility is None:
                rows.append(dict(s, set=name, trial=trial, cls=cls, motion=motion, injected=injected))
                continue
            shown = shown_effects(trial, injected, visibility, report["thresholds"]["min_gain"])
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
    if seen_table:
        print_table("Effects the log can show (an effect whose signature in the log is below the judge's min_gain is "
                    "dropped; a single left with none is an unseen trial, right when nothing is named):", seen_table,
                    classes[:2] + ["unseen"] + classes[2:],
                    heads[:2] + ["unseen clean"] + heads[2:])
    if no_visibility:
        print("\nNo visibility.json (run.sh visibility SPLIT), so not in the second table: " + ", ".join(no_visibility))
    if a.json:
        json.dump({"table": table, "seen_table": seen_table, "rows": rows}, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
