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


class Rejected(Exception):
    """The engine refused to build the scene (e.g. MuJoCo's compiler rejecting inverted limits or a massless moving
    body): reported as "unsupported", not as a verdict."""


def quat_rotate(q, v):
    """Rotates v by the unit quaternion q = [w, x, y, z]."""
    w, x, y, z = q
    tx, ty, tz = y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0]
    ux, uy, uz = y * tz - z * ty, z * tx - x * tz, x * ty - y * tx
    return [v[0] + 2 * (w * tx + ux), v[1] + 2 * (w * ty + uy), v[2] + 2 * (w * tz + uz)]


def quat_mul(a, b):
    return [a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]]


def world_trees(s):
    """Tree index (0, 1, ...) of every body of a generated `world` scene, in order of the roots."""
    roots, out = [], []
    for i, b in enumerate(s["bodies"]):
        if b["parent"] is None:
            roots.append(i)
            out.append(len(roots) - 1)
        else:
            out.append(out[b["parent"]])
    return out


def run_world(s, step, state):
    """Steps a `world` scene and records `state()` (per body [p(3), q wxyz(4), v(3), w(3)]) at t = 0 and every
    `record_every` steps; stops at the first non-finite sample (the judge then reports a non-finite state)."""
    steps = int(round(s["duration"] / s["dt"]))
    every = max(1, int(s["record_every"]))
    t, out = [0.0], [state()]
    for i in range(steps):
        step()
        if (i + 1) % every == 0:
            x = state()
            t.append((i + 1) * s["dt"])
            out.append(x)
            if x is None or not all(math.isfinite(v) for b in x for v in b):
                break
    return {"t": t, "state": out}


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
        except Rejected as e:
            out["status"] = "unsupported"
            out["detail"] = "rejected by the engine: {}".format(e)
        except Exception as e:  # an engine failure is a verdict (flagged), never a crash of the bench
            out["status"] = "error"
            out["detail"] = "{}: {}".format(type(e).__name__, e)
            traceback.print_exc(file=sys.stderr)
    print(json.dumps(out), flush=True)
