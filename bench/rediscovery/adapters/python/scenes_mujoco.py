"""Rediscovery bench: the cross-engine scenes in MuJoCo, through the `mujoco` Python bindings of whatever
wheel version the interpreter has (2.2 ... 3.17 share the calls used here).

Reads the scene list (JSON, written by the harness's `scenes` binary) from the file named on the command
line, runs every scene it can express and prints one JSON line of raw observables per scene on stdout. No
verdicts here: the harness judges (`judge` binary) with the project's invariants.
"""
import json
import sys

import mujoco
import numpy as np

from scene_common import Rejected, emit, engine_label_line, inertial_box, quat_mul, quat_rotate, run_world, world_trees


def support_xml(s):
    sup = s["support"]
    if sup["type"] == "plane":
        return '<geom type="plane" size="5 5 0.1"{}/>'.format(solref(s))
    hx, hy, hz = sup["half"]
    return '<geom type="box" size="{} {} {}" pos="0 0 {}"{}/>'.format(hx, hy, hz, -hz, solref(s))


def solref(s):
    tc = s.get("contact_timeconst")
    return ' solref="{} 1"'.format(tc) if tc else ""


def geom_xml(g, s):
    x, y, z = g["pos"]
    if g["type"] == "box":
        hx, hy, hz = g["half"]
        return '<geom type="box" size="{} {} {}" pos="{} {} {}" mass="0"{}/>'.format(hx, hy, hz, x, y, z, solref(s))
    return '<geom type="sphere" size="{}" pos="{} {} {}" mass="0"{}/>'.format(g["radius"], x, y, z, solref(s))


def drop(s):
    b = s["body"]
    geoms = b["geoms"]
    # Geoms after the first sit on a child body without a joint when `fused_child` is set: the compiler
    # (fusestatic, on by default for URDF imports) merges it into the free body.
    first = geom_xml(geoms[0], s)
    rest = "".join(geom_xml(g, s) for g in geoms[1:])
    if b.get("fused_child") and rest:
        # The child's own inertia is negligible (1e-6 kg): the compiler refuses a massless child body before
        # fusing it, in versions before 3.3.
        rest = '<body name="child"><inertial pos="0 0 0" mass="1e-6" diaginertia="1e-9 1e-9 1e-9"/>{}</body>'.format(rest)
    ixx, iyy, izz = inertial_box(b["mass"], b["inertia_half"])
    px, py, pz = s["init"]["pos"]
    xml = """<mujoco>
  <compiler fusestatic="{fuse}"/>
  <option timestep="{dt}" gravity="0 0 {g}"/>
  <worldbody>
    {support}
    <body name="body" pos="{px} {py} {pz}">
      <freejoint/>
      <inertial pos="0 0 0" mass="{m}" diaginertia="{ixx} {iyy} {izz}"/>
      {first}{rest}
    </body>
  </worldbody>
</mujoco>""".format(fuse="true" if b.get("fused_child") else "false", dt=s["dt"], g=s["gravity"],
                    support=support_xml(s), px=px, py=py, pz=pz, m=b["mass"], ixx=ixx, iyy=iyy, izz=izz,
                    first=first, rest=rest)
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qpos[3:7] = s["init"]["quat"]
    d.qvel[0:3] = s["init"]["linvel"]
    steps = int(round(s["duration"] / s["dt"]))
    t, pos, quat = [0.0], [list(d.qpos[0:3])], [list(d.qpos[3:7])]
    for i in range(steps):
        mujoco.mj_step(m, d)
        t.append((i + 1) * s["dt"])
        pos.append(list(d.qpos[0:3]))
        quat.append(list(d.qpos[3:7]))
        if not np.all(np.isfinite(d.qpos)):
            break
    return {"t": t, "pos": pos, "quat": quat}


def inverse_dynamics(s):
    """Joint torques of the URDF's floating robot held at rest in configuration `q` (zero velocities and
    accelerations): mj_inverse's joint part. The URDF importer fixes the root link, so the model is edited
    through mjSpec (MuJoCo >= 3.2) to give the root a free joint."""
    if not hasattr(mujoco, "MjSpec"):
        raise NotImplementedError("needs mjSpec (MuJoCo >= 3.2)")
    spec = mujoco.MjSpec.from_string(s["urdf"])
    spec.compiler.fusestatic = False
    spec.worldbody.first_body().add_freejoint()
    m = spec.compile()
    d = mujoco.MjData(m)
    if m.nq != 7 + len(s["q"]):
        raise RuntimeError("expected a free joint and {} hinges, got nq={}".format(len(s["q"]), m.nq))
    d.qpos[0:3] = s["base_pos"]
    d.qpos[3:7] = s["base_quat"]
    d.qpos[7:] = s["q"]
    d.qvel[:] = 0
    d.qacc[:] = 0
    mujoco.mj_inverse(m, d)
    return {"tau": list(d.qfrc_inverse[6:])}


def _v(x):
    return " ".join(repr(float(a)) for a in x)


def world(s):
    """A generated scene (harness `blind::World`): MJCF with one nested body per scene body, its frame at its
    centre of mass, explicit inertia; contacts between trees and with the support only (contype/conaffinity: one
    bit per tree)."""
    bodies = s["bodies"]
    tree = world_trees(s)
    children = {i: [] for i in range(-1, len(bodies))}
    for i, b in enumerate(bodies):
        children[-1 if b["parent"] is None else b["parent"]].append(i)
    tc = s.get("contact_timeconst")
    sol = ' solref="{} 1"'.format(tc) if tc else ""

    def contact(k):
        if not s["collide"]:
            return ' contype="0" conaffinity="0"'
        return ' contype="{}" conaffinity="{}"'.format(1 << k, 15 & ~(1 << k)) if k is not None else ' contype="15" conaffinity="15"'

    def geom(g, k):
        sh = g["shape"]
        if sh["type"] == "box":
            t, size = "box", sh["half"]
        elif sh["type"] == "sphere":
            t, size = "sphere", [sh["radius"]]
        else:
            t, size = sh["type"], [sh["radius"], sh["half_length"]]
        return '<geom type="{}" size="{}" pos="{}" quat="{}" friction="{} 0.005 0.0001"{}{}/>'.format(
            t, _v(size), _v(g["pos"]), _v(g["quat"]), g["friction"], contact(k), sol)

    def body(i):
        b = bodies[i]
        j = b["joint"]
        if j["type"] == "free":
            jx = '<freejoint name="j{}"/>'.format(i)
        elif j["type"] == "fixed":
            jx = ""
        else:
            lim = ' limited="true" range="{}"'.format(_v(j["limit"])) if j.get("limit") else ' limited="false"'
            jx = '<joint name="j{}" type="{}" pos="{}" axis="{}"{}/>'.format(
                i, "hinge" if j["type"] == "hinge" else "slide", _v(b["anchor"]), _v(j["axis"]), lim)
        inertial = '<inertial pos="0 0 0" mass="{}" diaginertia="{}"/>'.format(b["mass"], _v(b["inertia"])) \
            if b["mass"] > 0 else ""
        return '<body name="b{}" pos="{}" quat="{}">{}{}{}{}</body>'.format(
            i, _v(b["pos"]), _v(b["quat"]), jx, inertial, "".join(geom(g, tree[i]) for g in b["geoms"]),
            "".join(body(c) for c in children[i]))

    sup = s.get("support")
    if sup is None:
        support = ""
    elif sup["type"] == "plane":
        support = '<geom type="plane" size="100 100 0.1"{}{}/>'.format(contact(None), sol)
    else:
        support = '<geom type="box" size="{}" pos="0 0 {}"{}{}/>'.format(_v(sup["half"]), -sup["half"][2], contact(None), sol)
    xml = """<mujoco>
  <compiler angle="radian" fusestatic="{fuse}" inertiafromgeom="false"/>
  <option timestep="{dt}" gravity="0 0 {g}"/>
  <worldbody>{support}{bodies}</worldbody>
</mujoco>""".format(fuse="true" if s["fuse_static"] else "false", dt=s["dt"], g=s["gravity"], support=support,
                    bodies="".join(body(c) for c in children[-1]))
    try:
        m = mujoco.MjModel.from_xml_string(xml)
    except Exception as e:
        raise Rejected(str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__)
    d = mujoco.MjData(m)
    ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "b{}".format(i)) for i in range(len(bodies))]
    for i, b in enumerate(bodies):
        j = b["joint"]
        if j["type"] == "fixed":
            continue
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "j{}".format(i))
        qa, da = m.jnt_qposadr[jid], m.jnt_dofadr[jid]
        if j["type"] == "free":
            d.qvel[da:da + 3] = j["linvel"]
            # MuJoCo's free-joint angular velocity is in the body frame.
            q = b["quat"]
            d.qvel[da + 3:da + 6] = quat_rotate([q[0], -q[1], -q[2], -q[3]], j["angvel"])
        else:
            d.qpos[qa] = j["q0"]
            d.qvel[da] = j["v0"]
    mujoco.mj_forward(m, d)
    res = np.zeros(6)

    def state():
        # MuJoCo resets the state itself when it detects divergence (a bad qacc warning): that is a non-finite state.
        if d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0:
            return [[float("nan")] * 13 for _ in bodies]
        out = []
        for i, b in enumerate(bodies):
            if ids[i] >= 0:
                mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, ids[i], res, 0)
                out.append(list(d.xpos[ids[i]]) + list(d.xquat[ids[i]]) + list(res[3:6]) + list(res[0:3]))
            elif b["parent"] is None:
                # Welded to the world and fused into it: static.
                out.append(list(b["pos"]) + list(b["quat"]) + [0.0] * 6)
            else:
                # Fused into its parent (fusestatic): rigidly attached, so its state follows from the parent's.
                pp, pq, pv, pw = out[b["parent"]][0:3], out[b["parent"]][3:7], out[b["parent"]][7:10], out[b["parent"]][10:13]
                r = quat_rotate(pq, b["pos"])
                v = [pv[0] + pw[1] * r[2] - pw[2] * r[1], pv[1] + pw[2] * r[0] - pw[0] * r[2], pv[2] + pw[0] * r[1] - pw[1] * r[0]]
                out.append([pp[k] + r[k] for k in range(3)] + quat_mul(pq, b["quat"]) + v + list(pw))
        return out

    return run_world(s, lambda: mujoco.mj_step(m, d), state)


KINDS = {"drop": drop, "inverse_dynamics": inverse_dynamics, "world": world}

if __name__ == "__main__":
    engine_label_line("MuJoCo " + mujoco.__version__)
    for scene in json.load(open(sys.argv[1])):
        if len(sys.argv) > 2 and scene["id"] != sys.argv[2]:
            continue
        emit("MuJoCo " + mujoco.__version__, scene, KINDS)
