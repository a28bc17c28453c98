"""Triage of the blind campaign's flags (issue 63): every flagged scene of a campaign is put into exactly one class,
and a class is a documented limitation that the scene demonstrably depends on: the scene is rerun with that one
cause removed (a counterfactual variant of the scene or of the engine option) and the flag must go away.

    python3 bench/rediscovery/triage.py target-rediscovery/blind-out/mujoco-3.17.0 [OUT_DIR ...]

Each OUT_DIR is a `blind campaign` output (findings.jsonl, scenes/), named PKG-VER; the venv is
$REDISCOVERY_VENVS/PKG-VER (default target-rediscovery/venvs), or for PKG `rapier` the Rust adapter
$CARGO_TARGET_DIR/debug/blind-rapier-VER (VER with `_` for `.` and `-`, built by blind.sh), and the judge is the harness's own `blind replay`
($CARGO_TARGET_DIR/debug/blind, default target-rediscovery). For every flag, the variants below are built and replayed
on the same engine version; the flag's class is the first variant, in the order `ORDER` gives for its violation, on
which the scene is judged and no longer shows the flag's violation (for the variants that change the step or lift a
velocity cap, `coarse_step`, `velocity_clamp` and `several_causes`: shows no penetration, energy or non-finite
violation at all); a flag no variant clears is a candidate defect. All variants that clear it are
reported too (`cleared_by`), so overlaps are visible. The inverse-dynamics flags of pybullet have their own class
(rotated floating root, README) and are checked by the identity-orientation variant.

Variants (cause → what is removed):
* `initial_overlap`: some geom starts below the support's top → every tree lifted so its lowest point is 1 mm above
  it (only when there is such an overlap);
* `thin_support`: a box support thinner than 2 m → the same box 2 m thick (the generator's thickest);
* `mass_ratio`: a body lighter than 0.1 of its tree's mass → every such body given 0.1 of the tree's mass (inertia
  scaled with it);
* `euler_integrator` (MuJoCo only): the scene's model with `integrator="implicit"` instead of the default Euler;
* `inverted_limit`: a joint whose lower limit exceeds its upper one → that limit removed;
* `soft_contact` (MuJoCo only): a scene's own `solref` time constant → MuJoCo's default;
* `transient` (penetration only): the scene run 3 s longer, so the judged window is not in the middle of an impact;
* `capsule_as_sphere` (DART only): capsules → cylinders of the same radius and half-length (DART's default FCL
  detector builds no capsule and puts a fixed small sphere in its place; `dart/capsule_as_sphere.py`);
* `mesh_primitives` (DART only): FCL colliding spheres, boxes and cylinders as primitives instead of DART's default
  tessellated meshes (a mesh sphere rests up to 0.09 r deeper than the sphere; `dart/mesh_sphere_depth.py`);
* `velocity_clamp` (pybullet only): Bullet's maximum coordinate velocity (changeDynamics `maxJointVelocity`, 100 by
  default) lifted to infinity on every multibody; Bullet clamps each velocity coordinate of a multibody on its own, a
  floating base's six included, and on a light floating base spun past 100 rad/s by an impact that changes the
  velocities of the heavy links it carries (energy and momentum from nothing; `pybullet/velocity_clamp_energy.py`);
* `coarse_step`: the scene's time step down to `FINE_STEP` (0.1 ms; the same samples recorded), for a step that does
  not resolve the scene's fastest motion: a small body spun by an impact, or one that travels more than its own size
  in a step;
* `several_causes`: all the scene-level removals above at once (initial overlap, thin support, mass ratio, inverted
  limits, own solref, capsules on DART, the fine step; on pybullet run with the velocity clamp lifted too), for flags
  that need two of them together;
* `rotated_floating_root` (inverse dynamics only): floating roots at the identity orientation.
Counterparts: the engines of the other OUT_DIRs given, plus TRIAGE_COUNTERPARTS="PKG-VER ..." (engines whose own
campaign is not triaged in this call). Output: a markdown table per campaign on stdout and OUT_DIR/triage.jsonl (one line per flag).
"""
import copy
import json
import math
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
ADAPTERS = {"mujoco": "scenes_mujoco.py", "dartpy": "scenes_dart.py", "pybullet": "scenes_pybullet.py"}
# The generator's thickest box support (blind::generate: half-thickness log-uniform up to 1 m).
THICK_HALF = 1.0
# The `mass_ratio` variant raises every body to at least this fraction of its tree's mass, so no body carries more than
# 10 times its own weight through a joint or a contact. Why 0.1: MuJoCo's soft contact leaks (1 - d) of the
# unconstrained acceleration, so its steady-state depth is about (1 - d)/d * a0 * (d * timeconst)^2 with a0 the load
# over the carrying body's mass; at the default solref (0.02 s, d = 0.95) and a0 = 10 g that is 1.7 mm, below the
# 2 cm bound, while 1e-3 (a0 = 1000 g) still predicts 17 cm.
MASS_FRACTION = 0.1

# Seconds added by the `transient` variant: more than the generator's longest scene (3 s), so a body in the middle of
# an impact or a bounce when the judged window began has come to rest if it can.
LONGER_S = 3.0

# The `coarse_step` variant's time step. Why 0.1 ms: the generator draws steps of 1, 2 or 5 ms and geoms down to 5 mm
# (lever arms down to 2.5 mm), and an impact at its speeds (up to about 5 m/s: 3 m/s initial per axis plus a fall of
# about 1 m) spins such a body at omega ~ v / lever, up to ~2000 rad/s (measured in converged runs: 400 rad/s on
# MuJoCo's s1-350 and s1-577, 900 rad/s on DART's s1-35 run in MuJoCo); a first-order step treats the
# velocity-dependent (Coriolis, gyroscopic) terms and the contact as constant over the step, which is accurate only
# while omega * dt is a small angle (<= 0.2 rad), i.e. dt <= 0.1 ms. 1, 2 and 5 ms are whole multiples of it, so the
# same samples are recorded.
FINE_STEP = 1e-4

# Wrapper that runs the MuJoCo adapter with another integrator (the adapter itself is unchanged).
MUJOCO_IMPLICIT = """import sys
sys.path.insert(0, {adapters!r})
import mujoco
_orig = mujoco.MjModel.from_xml_string
def _implicit(xml, *a, **k):
    return _orig(xml.replace("<option ", '<option integrator="implicit" ', 1), *a, **k)
mujoco.MjModel.from_xml_string = _implicit
import runpy
sys.argv = [{adapter!r}] + sys.argv[1:]
runpy.run_path({adapter!r}, run_name="__main__")
"""

# Wrapper that runs the DART adapter with FCL colliding primitives as primitives instead of DART's default meshes
# (`FCLCollisionDetector::setPrimitiveShapeType(PRIMITIVE)`; the adapter itself is unchanged).
DART_PRIMITIVE = """import sys
sys.path.insert(0, {adapters!r})
import dartpy as dart
_World = dart.simulation.World
def _world(*a):
    w = _World(*a)
    d = dart.collision.FCLCollisionDetector()
    d.setPrimitiveShapeType(dart.collision.FCLCollisionDetector.PrimitiveShape.PRIMITIVE)
    w.getConstraintSolver().setCollisionDetector(d)
    return w
dart.simulation.World = _world
import runpy
sys.argv = [{adapter!r}] + sys.argv[1:]
runpy.run_path({adapter!r}, run_name="__main__")
"""
# Wrapper that runs the pybullet adapter with Bullet's maximum coordinate velocity lifted: changeDynamics
# `maxJointVelocity` (one value per multibody, btMultiBody::setMaxCoordinateVelocity; 100 by default) set to infinity
# on every multibody the adapter creates, so no velocity coordinate is ever clamped (the adapter itself is unchanged).
PYBULLET_NO_CLAMP = """import sys
sys.path.insert(0, {adapters!r})
import pybullet as p
_create = p.createMultiBody
def _unclamped(*a, **k):
    mb = _create(*a, **k)
    if mb >= 0:
        p.changeDynamics(mb, -1, maxJointVelocity=float("inf"), physicsClientId=k.get("physicsClientId", 0))
    return mb
p.createMultiBody = _unclamped
import runpy
sys.argv = [{adapter!r}] + sys.argv[1:]
runpy.run_path({adapter!r}, run_name="__main__")
"""
# Engine-option variants: the variant's name -> the wrapper that runs the engine's adapter with that option changed.
WRAPPERS = {"euler_integrator": MUJOCO_IMPLICIT, "mesh_primitives": DART_PRIMITIVE, "velocity_clamp": PYBULLET_NO_CLAMP}
# Engine options that `several_causes` removes too, on that engine (the variant is a scene transform run through the
# option's wrapper).
ALL_CAUSES_WRAPPER = {"pybullet": "velocity_clamp"}


# ---- geometry (conventions of harness/src/blind.rs) ---------------------------------------------------------------

def qmul(a, b):
    return [a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]]


def rot(q, v):
    w, x, y, z = q
    tx, ty, tz = y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0]
    ux, uy, uz = y * tz - z * ty, z * tx - x * tz, x * ty - y * tx
    return [v[0] + 2 * (w * tx + ux), v[1] + 2 * (w * ty + uy), v[2] + 2 * (w * tz + uz)]


def initial_poses(w):
    out = []
    for b in w["bodies"]:
        pp, pq = out[b["parent"]] if b["parent"] is not None else ([0.0] * 3, [1.0, 0, 0, 0])
        q = qmul(pq, b["quat"])
        p = [pp[k] + rot(pq, b["pos"])[k] for k in range(3)]
        j = b["joint"]
        if j["type"] == "hinge":
            aw = [p[k] + rot(q, b["anchor"])[k] for k in range(3)]
            s, c = math.sin(j["q0"] / 2), math.cos(j["q0"] / 2)
            q = qmul(q, [c] + [a * s for a in j["axis"]])
            p = [aw[k] - rot(q, b["anchor"])[k] for k in range(3)]
        elif j["type"] == "slide":
            d = rot(q, [a * j["q0"] for a in j["axis"]])
            p = [p[k] + d[k] for k in range(3)]
        out.append((p, q))
    return out


def lowest_z(shape, pos, q):
    az = rot(q, [0, 0, 1])[2]
    t = shape["type"]
    if t == "box":
        w, x, y, z = q
        row = [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]
        return pos[2] - sum(abs(r) * h for r, h in zip(row, shape["half"]))
    if t == "sphere":
        return pos[2] - shape["radius"]
    if t == "capsule":
        return pos[2] - abs(az) * shape["half_length"] - shape["radius"]
    return pos[2] - abs(az) * shape["half_length"] - shape["radius"] * math.sqrt(max(1 - az * az, 0.0))


def trees(w):
    t = []
    for b in w["bodies"]:
        t.append(len(t) if b["parent"] is None else t[b["parent"]])
    return t


def initial_penetration(w):
    """Depth of the deepest geom below the support's top at the start (<= 0: none)."""
    if w.get("support") is None or not w["collide"]:
        return 0.0
    depth = 0.0
    for b, (p, q) in zip(w["bodies"], initial_poses(w)):
        for g in b["geoms"]:
            c = [p[k] + rot(q, g["pos"])[k] for k in range(3)]
            depth = max(depth, -lowest_z(g["shape"], c, qmul(q, g["quat"])))
    return depth


# ---- variants ---------------------------------------------------------------------------------------------------

def v_initial_overlap(w):
    d = initial_penetration(w)
    if d <= 0:
        return None
    c = copy.deepcopy(w)
    for b in c["bodies"]:
        if b["parent"] is None:
            b["pos"][2] += d + 1e-3
    return c


def v_thin_support(w):
    s = w.get("support")
    if s is None or s["type"] != "box" or s["half"][2] >= THICK_HALF:
        return None
    c = copy.deepcopy(w)
    c["support"]["half"][2] = THICK_HALF
    return c


def v_mass_ratio(w):
    tr = trees(w)
    total = {}
    for t, b in zip(tr, w["bodies"]):
        total[t] = total.get(t, 0.0) + b["mass"]
    c = copy.deepcopy(w)
    changed = False
    for t, b in zip(tr, c["bodies"]):
        floor = MASS_FRACTION * total[t]
        if b["mass"] < floor:
            # Inertia of the body's own box (blind::generate draws it from half-extents h); keep its shape.
            scale = floor / b["mass"] if b["mass"] > 0 else None
            b["inertia"] = [i * scale for i in b["inertia"]] if scale else [floor * 1e-4] * 3
            b["mass"] = floor
            changed = True
    return c if changed else None


def v_inverted_limit(w):
    c = copy.deepcopy(w)
    changed = False
    for b in c["bodies"]:
        lim = b["joint"].get("limit")
        if lim and lim[0] > lim[1]:
            b["joint"]["limit"] = None
            changed = True
    return c if changed else None


def v_soft_contact(w):
    if w.get("contact_timeconst") is None:
        return None
    c = copy.deepcopy(w)
    c["contact_timeconst"] = None
    return c


def v_longer(w):
    c = copy.deepcopy(w)
    c["duration"] = round((w["duration"] + LONGER_S) / w["dt"]) * w["dt"]
    return c


def v_capsule_as_cylinder(w):
    c = copy.deepcopy(w)
    changed = False
    for b in c["bodies"]:
        for g in b["geoms"]:
            if g["shape"]["type"] == "capsule":
                g["shape"]["type"] = "cylinder"
                changed = True
    return c if changed else None


def v_fine_step(w):
    k = round(w["dt"] / FINE_STEP)
    if k <= 1:
        return None
    c = copy.deepcopy(w)
    c["dt"] = w["dt"] / k
    c["record_every"] = w["record_every"] * k
    return c


def v_all_scene_causes(w, pkg):
    """Every scene-level cause above removed at once (for flags that need two of them together, e.g. a body that
    starts embedded in a thin support), the engine-specific ones only on their engine."""
    c, changed = w, False
    for f, only in ((v_initial_overlap, None), (v_thin_support, None), (v_mass_ratio, None), (v_inverted_limit, None),
                    (v_soft_contact, None), (v_capsule_as_cylinder, {"dartpy"}), (v_fine_step, None)):
        if only and pkg not in only:
            continue
        n = f(c)
        if n is not None:
            c, changed = n, True
    return copy.deepcopy(c) if changed else None


def v_identity_roots(w):
    c = copy.deepcopy(w)
    changed = False
    for b in c["bodies"]:
        if b["joint"]["type"] == "free" and b["quat"] != [1.0, 0.0, 0.0, 0.0]:
            b["quat"] = [1.0, 0.0, 0.0, 0.0]
            changed = True
    return c if changed else None


# (name, engines or None for all, violations it may explain, scene transform (World, engine) or None for an engine
# option of WRAPPERS)
VARIANTS = [
    ("rotated_floating_root", None, {"inverse_dynamics"}, v_identity_roots),
    ("initial_overlap", None, {"penetration", "energy", "non_finite"}, v_initial_overlap),
    ("thin_support", None, {"penetration", "energy", "non_finite"}, v_thin_support),
    ("mass_ratio", None, {"penetration", "energy", "non_finite"}, v_mass_ratio),
    ("euler_integrator", {"mujoco"}, {"penetration", "energy", "non_finite"}, None),
    ("inverted_limit", None, {"penetration", "energy", "non_finite"}, v_inverted_limit),
    ("soft_contact", {"mujoco"}, {"penetration", "energy", "non_finite"}, v_soft_contact),
    ("transient", None, {"penetration"}, v_longer),
    ("capsule_as_sphere", {"dartpy"}, {"penetration", "energy", "non_finite"}, v_capsule_as_cylinder),
    ("mesh_primitives", {"dartpy"}, {"penetration", "energy", "non_finite"}, None),
    ("velocity_clamp", {"pybullet"}, {"penetration", "energy", "non_finite"}, None),
    ("coarse_step", None, {"penetration", "energy", "non_finite"}, v_fine_step),
    ("several_causes", None, {"penetration", "energy", "non_finite"}, v_all_scene_causes),
]
# Violations of the physical invariants (the inverse-dynamics consistency one does not depend on contacts or the step).
PHYSICAL = {"penetration", "energy", "non_finite", "engine_failure"}
# Variants that must leave the scene free of every physical violation to clear a flag: they change the step, or lift
# pybullet's velocity clamp, which also lets a runaway that the clamp held back grow (the campaign's s1-9, a slide
# driven through the support by the cone-friction defect, then trades its penetration for an energy violation).
STRICT = {"coarse_step", "velocity_clamp", "several_causes"}
# The order in which variants name the class, per violation: the most direct mechanism first (a thin support for a
# body that ends below it; the integrator for a state that diverges or gains energy without contact).
ORDER = {
    "inverse_dynamics": ["rotated_floating_root"],
    "penetration": ["initial_overlap", "thin_support", "mass_ratio", "soft_contact", "transient", "euler_integrator",
                    "inverted_limit", "capsule_as_sphere", "mesh_primitives", "velocity_clamp", "coarse_step",
                    "several_causes"],
    "energy": ["euler_integrator", "inverted_limit", "mass_ratio", "initial_overlap", "thin_support", "soft_contact",
               "capsule_as_sphere", "mesh_primitives", "velocity_clamp", "coarse_step", "several_causes"],
    "non_finite": ["euler_integrator", "inverted_limit", "mass_ratio", "initial_overlap", "thin_support",
                   "soft_contact", "capsule_as_sphere", "mesh_primitives", "velocity_clamp", "coarse_step",
                   "several_causes"],
}


# ---- replay -----------------------------------------------------------------------------------------------------

def venv_python(pkg, ver):
    base = os.environ.get("REDISCOVERY_VENVS", os.path.join(ROOT, "target-rediscovery", "venvs"))
    return os.path.join(base, os.environ.get("REDISCOVERY_VENV_PREFIX", "") + "{}-{}".format(pkg, ver), "bin", "python")


def blind_bin(name="blind"):
    return os.path.join(os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target-rediscovery")), "debug", name)


def engine(pkg, ver):
    """The PYTHON ADAPTER pair of `blind replay` for one version: a wheel's venv interpreter and Python adapter, or for
    PKG `rapier` the Rust adapter's executable (built by blind.sh) and `-`."""
    if pkg == "rapier":
        return blind_bin("blind-rapier-" + ver.replace(".", "_").replace("-", "_")), "-"
    return venv_python(pkg, ver), os.path.join(HERE, "adapters", "python", ADAPTERS[pkg])


def replay(python, adapter, scenes, work):
    """{scene id: (violation or None, value)} from `blind replay` of `scenes` (World dicts)."""
    if not scenes:
        return {}
    files = []
    for s in scenes:
        f = os.path.join(work, s["id"] + ".json")
        with open(f, "w") as fh:
            json.dump(s, fh)
        files.append(f)
    out = {}
    for k in range(0, len(files), 64):
        r = subprocess.run([blind_bin(), "replay", python, adapter] + files[k:k + 64], stdout=subprocess.PIPE,
                           text=True, check=True)
        for line in r.stdout.splitlines():
            v = json.loads(line)
            out[v["verdict"]["scene"]] = (v["violation"], v["verdict"]["value"], v["verdict"]["detail"])
    return out


def main(dirs):
    engines = []
    for d in dirs:
        pkg, ver = os.path.basename(os.path.normpath(d)).split("-", 1)
        engines.append((pkg, ver))
    # More counterpart engines without triaging their own campaign: TRIAGE_COUNTERPARTS="pybullet-3.2.7 ...".
    for e in os.environ.get("TRIAGE_COUNTERPARTS", "").split():
        pkg, ver = e.split("-", 1)
        if (pkg, ver) not in engines:
            engines.append((pkg, ver))
    for d in dirs:
        name = os.path.basename(os.path.normpath(d))
        pkg, ver = name.split("-", 1)
        findings = [json.loads(l) for l in open(os.path.join(d, "findings.jsonl")) if l.strip()]
        scenes = {r["scene"]: json.load(open(os.path.join(d, "scenes", r["scene"] + ".json"))) for r in findings}
        python, adapter = engine(pkg, ver)
        results = {r["scene"]: {"violation": r["violation"], "cleared_by": [], "tried": []} for r in findings}
        with tempfile.TemporaryDirectory() as work:
            base = replay(python, adapter, list(scenes.values()), work)
            for r in findings:
                results[r["scene"]]["replayed"] = base.get(r["scene"], (None,))[0]
            for vname, only, viols, fn in VARIANTS:
                if only and pkg not in only:
                    continue
                todo = []
                for r in findings:
                    if r["violation"] not in viols:
                        continue
                    w = scenes[r["scene"]]
                    if fn is v_all_scene_causes:
                        c = fn(w, pkg)
                    else:
                        c = fn(w) if fn else copy.deepcopy(w)
                    if c is None:
                        continue
                    c["id"] = "{}-{}".format(w["id"], vname)
                    todo.append((r, c))
                if not todo:
                    continue
                ad = adapter
                option = vname if fn is None else ALL_CAUSES_WRAPPER.get(pkg) if fn is v_all_scene_causes else None
                if option:  # an engine option: the engine's adapter run through its wrapper
                    ad = os.path.join(work, "adapter_{}.py".format(vname))
                    with open(ad, "w") as fh:
                        fh.write(WRAPPERS[option].format(adapters=os.path.dirname(adapter), adapter=adapter))
                got = replay(python, ad, [c for _, c in todo], work)
                for r, c in todo:
                    res = results[r["scene"]]
                    res["tried"].append(vname)
                    v = got.get(c["id"])
                    res.setdefault("outcome", {})[vname] = (
                        "not run" if v is None or (v[0] is None and v[1] is None) else v[0] or "quiet")
                    # Cleared: judged (not refused, not crashed) and no longer showing the flag's violation; for the
                    # variants that refine the step, no physical violation at all (a finer step that trades an energy
                    # flag for a body falling through the support explains nothing).
                    cleared = v is not None and v[1] is not None and v[0] != r["violation"] and v[0] != "engine_failure"
                    if vname in STRICT and v is not None and v[0] in PHYSICAL:
                        cleared = False
                    if cleared:
                        res["cleared_by"].append(vname)
            # The independent counterpart: the same flagged scenes on every other engine given.
            for opkg, over in engines:
                if opkg == pkg:
                    continue
                opy, oad = engine(opkg, over)
                mine = [scenes[r["scene"]] for r in findings if r["violation"] != "inverse_dynamics"]
                got = replay(opy, oad, mine, work)
                for r in findings:
                    if r["violation"] == "inverse_dynamics":
                        continue
                    v = got.get(r["scene"])
                    results[r["scene"]].setdefault("counterpart", {})[opkg] = (
                        "not run" if v is None or v[1] is None else (v[0] or "quiet"))
        rows = {}
        with open(os.path.join(d, "triage.jsonl"), "w") as fh:
            for r in findings:
                res = results[r["scene"]]
                ranked = [v for v in ORDER.get(r["violation"], []) if v in res["cleared_by"]]
                cls = ranked[0] if ranked else "candidate defect"
                res["class"] = cls
                fh.write(json.dumps(dict(scene=r["scene"], **res)) + "\n")
                key = (r["violation"], cls)
                row = rows.setdefault(key, {"n": 0, "also": 0, "scenes": [], "cp": {}})
                row["n"] += 1
                for opkg, v in res.get("counterpart", {}).items():
                    k = row["cp"].setdefault(opkg, {})
                    k[v] = k.get(v, 0) + 1
                row["also"] += len(res["cleared_by"]) > 1
                row["scenes"].append(r["scene"])
        n_same = sum(1 for r in findings if results[r["scene"]]["replayed"] == r["violation"])
        print("\n{} {}: {} flags ({} flagged again with the same violation on replay)".format(pkg, ver, len(findings),
                                                                                          n_same))
        print("| violation | class (first variant that clears it) | flags | also cleared by another variant | "
              "same scenes on the other engines | e.g. |")
        print("|---|---|---|---|---|---|")
        for (viol, cls), row in sorted(rows.items()):
            cp = "; ".join("{}: {}".format(k, ", ".join("{} {}".format(n, v) for v, n in sorted(vs.items())))
                           for k, vs in sorted(row["cp"].items()))
            print("| {} | {} | {} | {} | {} | {} |".format(viol, cls, row["n"], row["also"], cp or "-",
                                                       ", ".join(row["scenes"][:3])))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
