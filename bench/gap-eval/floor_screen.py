"""A first look, on development reports, at how the judge's gain floor could be tested differently: where a report's
judge stopped because its best effect of interest gained too little (`gain_below_floor`), would a variant of test (a)
have named that effect, and was it injected? Reads the stored reports only; nothing is rediagnosed, so what the
judge would have done after that step is not known (a screen, not a score).

    floor_screen.py DIR [DIR...]

DIR is one set's output as `score.py` reads it (labels or scores.json, and `trial_NNN/report.json`). Variants, each
on the winner's held-out gain per window (value and 95 % interval):
- `lower bound`: the interval's lower bound reaches the floor (the judge's test; names nothing here by construction);
- `estimate`: the estimate reaches the floor and the interval excludes 0 (significance and size tested apart).
Matching is score.py's.
"""
import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from score import load_set, matches  # noqa: E402

MIN_GAIN = 0.3  # docs/gap/method.md, `min_gain`

VARIANTS = {
    "lower bound": lambda g: g["lo"] >= MIN_GAIN,
    "estimate": lambda g: g["value"] >= MIN_GAIN and g["lo"] > 0.0,
}


def stopped_winner(report):
    """The effect the judge's last step set aside for gaining too little, or None."""
    steps = report.get("steps") or []
    if not steps or steps[-1].get("abstention") != "gain_below_floor" or steps[-1].get("winner") is None:
        return None
    return steps[-1]["candidates"][steps[-1]["winner"]]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dirs", nargs="+")
    a = ap.parse_args()
    tally = {v: {"injected": 0, "not injected": 0} for v in VARIANTS}
    for d in a.dirs:
        name = os.path.basename(os.path.normpath(d))
        for trial, cls, injected, report, _motion, _log in load_set(d):
            w = report and stopped_winner(report)
            if not w:
                continue
            named = (w["kind"], [w["unit"]])
            hit = any(matches(named, i) for i in injected)
            for v, test in VARIANTS.items():
                if test(w["gain"]):
                    tally[v]["injected" if hit else "not injected"] += 1
                    if v != "lower bound":
                        g = w["gain"]
                        print(f"{name} trial {trial} ({cls}): {v} names {w['kind']} on {w['unit']}, gain "
                              f"{g['value']:.2f} [{g['lo']:.2f}, {g['hi']:.2f}], "
                              f"{'injected' if hit else 'not injected'}")
    print("\n| variant | names an injected effect | names an effect not injected |\n|---|---|---|")
    for v, t in tally.items():
        print(f"| {v} | {t['injected']} | {t['not injected']} |")


if __name__ == "__main__":
    main()
