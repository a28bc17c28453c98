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

from scene_common import emit, engine_label_line, inertial_box


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


KINDS = {"drop": drop, "inverse_dynamics": inverse_dynamics}

if __name__ == "__main__":
    engine_label_line("MuJoCo " + mujoco.__version__)
    for scene in json.load(open(sys.argv[1])):
        if len(sys.argv) > 2 and scene["id"] != sys.argv[2]:
            continue
        emit("MuJoCo " + mujoco.__version__, scene, KINDS)
