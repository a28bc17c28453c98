"""Shared by the Python adapters of the rediscovery bench: the output protocol (one JSON line per scene)."""
import json
import math
import sys
import traceback


def inertial_box(mass, half):
    """Principal inertia of a solid box of `mass` with half-extents `half` (every engine gets these numbers,
    not its own estimate from the collision shapes)."""
    hx, hy, hz = half
    return (mass * (hy * hy + hz * hz) / 3.0, mass * (hx * hx + hz * hz) / 3.0, mass * (hx * hx + hy * hy) / 3.0)


def _finite(x):
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    return x


def engine_label_line(label):
    print(json.dumps({"engine": label}), flush=True)


def emit(label, scene, kinds):
    """Runs one scene with the adapter's function for its kind and prints the observables line:
    `{"engine", "scene", "status": "ok"|"unsupported"|"error", "detail", "data"}`. Non-finite numbers are
    written as null (the judge treats them as a non-finite state)."""
    out = {"engine": label, "scene": scene["id"], "status": "ok", "detail": "", "data": None}
    f = kinds.get(scene["kind"])
    only = scene.get("engines")
    if f is None or (only and not any(label.lower().startswith(e) for e in only)):
        out["status"] = "unsupported"
        out["detail"] = "scene kind {} not run on this engine".format(scene["kind"])
    else:
        try:
            out["data"] = _finite(f(scene))
        except Exception as e:  # an engine failure is a verdict (flagged), never a crash of the bench
            out["status"] = "error"
            out["detail"] = "{}: {}".format(type(e).__name__, e)
            traceback.print_exc(file=sys.stderr)
    print(json.dumps(out), flush=True)
