"""Rediscovery bench: the cross-engine scenes in Bullet, through the `pybullet` wheel of the interpreter's
venv. Same protocol as scenes_mujoco.py: raw observables per scene, no verdicts."""
import json
import math
import os
import sys
import tempfile

import pybullet as p

from scene_common import emit, engine_label_line, inertial_box

LABEL = "pybullet " + (p.__version__ if hasattr(p, "__version__") else "")


def _version():
    try:
        from importlib.metadata import version
        return version("pybullet")
    except Exception:
        return "?"


def _xyzw(q):
    w, x, y, z = q
    return [x, y, z, w]


def _wxyz(q):
    x, y, z, w = q
    return [w, x, y, z]


def drop(s):
    c = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, s["gravity"], physicsClientId=c)
        p.setTimeStep(s["dt"], physicsClientId=c)
        sup = s["support"]
        if sup["type"] == "plane":
            shape = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=c)
            p.createMultiBody(0, shape, basePosition=[0, 0, 0], physicsClientId=c)
        else:
            hx, hy, hz = sup["half"]
            shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[hx, hy, hz], physicsClientId=c)
            p.createMultiBody(0, shape, basePosition=[0, 0, -hz], physicsClientId=c)
        b = s["body"]
        types, halves, radii, poss = [], [], [], []
        for g in b["geoms"]:
            if g["type"] == "box":
                types.append(p.GEOM_BOX)
                halves.append(g["half"])
                radii.append(0)
            else:
                types.append(p.GEOM_SPHERE)
                halves.append([0, 0, 0])
                radii.append(g["radius"])
            poss.append(g["pos"])
        shape = p.createCollisionShapeArray(types, radii=radii, halfExtents=halves, collisionFramePositions=poss,
                                            physicsClientId=c)
        body = p.createMultiBody(b["mass"], shape, basePosition=s["init"]["pos"],
                                 baseOrientation=_xyzw(s["init"]["quat"]), physicsClientId=c)
        # createCollisionShapeArray may shift the body frame to the shapes' centre; read the offset back.
        p.changeDynamics(body, -1, localInertiaDiagonal=list(inertial_box(b["mass"], b["inertia_half"])),
                         physicsClientId=c)
        p.resetBaseVelocity(body, s["init"]["linvel"], [0, 0, 0], physicsClientId=c)
        steps = int(round(s["duration"] / s["dt"]))
        t, pos, quat = [], [], []

        def sample(i):
            x, q = p.getBasePositionAndOrientation(body, physicsClientId=c)
            t.append(i * s["dt"])
            pos.append(list(x))
            quat.append(_wxyz(q))

        sample(0)
        for i in range(steps):
            p.stepSimulation(physicsClientId=c)
            sample(i + 1)
            if not all(math.isfinite(v) for v in pos[-1]):
                break
        return {"t": t, "pos": pos, "quat": quat}
    finally:
        p.disconnect(c)


def inverse_dynamics(s):
    """Joint torques of the floating robot held at rest in configuration q: calculateInverseDynamics with
    q = [base position, base quaternion (x y z w), joints], zero velocities and accelerations; returns the
    joint part (the last n entries of the base-wrench-then-joints result)."""
    c = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -9.81, physicsClientId=c)
        with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
            f.write(s["urdf"])
            path = f.name
        try:
            body = p.loadURDF(path, s["base_pos"], _xyzw(s["base_quat"]), useFixedBase=False,
                              flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=c)
        finally:
            os.unlink(path)
        n = len(s["q"])
        if p.getNumJoints(body, physicsClientId=c) != n:
            raise RuntimeError("joint count mismatch")
        for j, qj in enumerate(s["q"]):
            p.resetJointState(body, j, qj, physicsClientId=c)
        q = list(s["base_pos"]) + _xyzw(s["base_quat"]) + list(s["q"])
        zeros = [0.0] * (6 + n)
        tau = p.calculateInverseDynamics(body, q, zeros, zeros, physicsClientId=c)
        if len(tau) != 6 + n:
            raise RuntimeError("inverse dynamics returned {} entries for {} dofs".format(len(tau), 6 + n))
        return {"tau": list(tau[6:])}
    finally:
        p.disconnect(c)


KINDS = {"drop": drop, "inverse_dynamics": inverse_dynamics}

if __name__ == "__main__":
    LABEL = "pybullet " + _version()
    engine_label_line(LABEL)
    for scene in json.load(open(sys.argv[1])):
        if len(sys.argv) > 2 and scene["id"] != sys.argv[2]:
            continue
        emit(LABEL, scene, KINDS)
