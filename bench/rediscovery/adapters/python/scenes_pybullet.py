"""Rediscovery bench: the cross-engine scenes in Bullet, through the `pybullet` wheel of the interpreter's
venv. Same protocol as scenes_mujoco.py: raw observables per scene, no verdicts."""
import json
import math
import os
import sys
import tempfile

import pybullet as p

from scene_common import Rejected, emit, engine_label_line, inertial_box, quat_rotate, run_world, world_trees

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


def world(s):
    """A generated scene (harness `blind::World`): one btMultiBody per tree (a floating root is its base; a tree
    jointed to the world hangs from a massless fixed base at the origin). Bullet's link frame sits at the joint
    (the body's `anchor`) with the body's orientation, and the inertial frame at the centre of mass. Links of one
    multibody do not collide with each other (no self-collision flag), as the scene format says."""
    c = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, s["gravity"], physicsClientId=c)
        p.setTimeStep(s["dt"], physicsClientId=c)
        sup = s.get("support")
        if sup is not None and s["collide"]:
            if sup["type"] == "plane":
                shape = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=c)
                p.createMultiBody(0, shape, basePosition=[0, 0, 0], physicsClientId=c)
            else:
                shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=sup["half"], physicsClientId=c)
                p.createMultiBody(0, shape, basePosition=[0, 0, -sup["half"][2]], physicsClientId=c)
        bodies = s["bodies"]
        tree = world_trees(s)

        def shapes(b, offset):
            if not s["collide"] or not b["geoms"]:
                return -1
            kw = {"shapeTypes": [], "radii": [], "halfExtents": [], "lengths": [], "collisionFramePositions": [],
                  "collisionFrameOrientations": []}
            for g in b["geoms"]:
                sh = g["shape"]
                kw["shapeTypes"].append({"box": p.GEOM_BOX, "sphere": p.GEOM_SPHERE, "capsule": p.GEOM_CAPSULE,
                                         "cylinder": p.GEOM_CYLINDER}[sh["type"]])
                kw["halfExtents"].append(sh.get("half", [0, 0, 0]))
                kw["radii"].append(sh.get("radius", 0))
                kw["lengths"].append(2 * sh.get("half_length", 0))
                kw["collisionFramePositions"].append([g["pos"][k] - offset[k] for k in range(3)])
                kw["collisionFrameOrientations"].append(_xyzw(g["quat"]))
            return p.createCollisionShapeArray(physicsClientId=c, **kw)

        handles = []  # per scene body: (multibody id, link index or -1)
        for t in sorted(set(tree)):
            members = [i for i in range(len(bodies)) if tree[i] == t]
            root = members[0]
            free = bodies[root]["joint"]["type"] == "free"
            links = members[1:] if free else members
            link_of = {i: k for k, i in enumerate(links)}
            kw = {k: [] for k in ("linkMasses", "linkCollisionShapeIndices", "linkVisualShapeIndices", "linkPositions",
                                  "linkOrientations", "linkInertialFramePositions", "linkInertialFrameOrientations",
                                  "linkParentIndices", "linkJointTypes", "linkJointAxis")}
            for i in links:
                b = bodies[i]
                par = b["parent"]
                par_anchor = [0, 0, 0] if par is None or (free and par == root) else bodies[par]["anchor"]
                ra = quat_rotate(b["quat"], b["anchor"])
                kw["linkMasses"].append(b["mass"])
                kw["linkCollisionShapeIndices"].append(shapes(b, b["anchor"]))
                kw["linkVisualShapeIndices"].append(-1)
                kw["linkPositions"].append([b["pos"][k] + ra[k] - par_anchor[k] for k in range(3)])
                kw["linkOrientations"].append(_xyzw(b["quat"]))
                kw["linkInertialFramePositions"].append([-a for a in b["anchor"]])
                kw["linkInertialFrameOrientations"].append([0, 0, 0, 1])
                kw["linkParentIndices"].append(0 if par is None or (free and par == root) else link_of[par] + 1)
                j = b["joint"]["type"]
                kw["linkJointTypes"].append({"fixed": p.JOINT_FIXED, "hinge": p.JOINT_REVOLUTE,
                                             "slide": p.JOINT_PRISMATIC}[j])
                kw["linkJointAxis"].append(b["joint"].get("axis", [0, 0, 1]))
            if free:
                rb = bodies[root]
                mb = p.createMultiBody(rb["mass"], shapes(rb, [0, 0, 0]), -1, rb["pos"], _xyzw(rb["quat"]),
                                       physicsClientId=c, **kw)
            else:
                mb = p.createMultiBody(0, -1, -1, [0, 0, 0], [0, 0, 0, 1], physicsClientId=c, **kw)
            if mb < 0:
                raise Rejected("createMultiBody failed")
            if free:
                rb = bodies[root]
                handles.append((mb, -1))
                p.changeDynamics(mb, -1, localInertiaDiagonal=rb["inertia"], linearDamping=0, angularDamping=0,
                                 lateralFriction=(rb["geoms"] or [{"friction": 1.0}])[0]["friction"], physicsClientId=c)
                p.resetBaseVelocity(mb, rb["joint"]["linvel"], rb["joint"]["angvel"], physicsClientId=c)
            else:
                p.changeDynamics(mb, -1, linearDamping=0, angularDamping=0, physicsClientId=c)
            for i in links:
                b, k = bodies[i], link_of[i]
                handles.append((mb, k))
                p.changeDynamics(mb, k, localInertiaDiagonal=b["inertia"], jointDamping=0,
                                 lateralFriction=(b["geoms"] or [{"friction": 1.0}])[0]["friction"], physicsClientId=c)
                j = b["joint"]
                if j["type"] in ("hinge", "slide"):
                    if j.get("limit"):
                        p.changeDynamics(mb, k, jointLowerLimit=j["limit"][0], jointUpperLimit=j["limit"][1],
                                         physicsClientId=c)
                    # No default velocity motor: the joints are passive.
                    p.setJointMotorControl2(mb, k, p.VELOCITY_CONTROL, force=0, physicsClientId=c)
                    p.resetJointState(mb, k, j["q0"], j["v0"], physicsClientId=c)
        order = [i for t in sorted(set(tree)) for i in range(len(bodies)) if tree[i] == t]
        slot = {i: h for i, h in zip(order, handles)}

        def state():
            out = []
            for i in range(len(bodies)):
                mb, k = slot[i]
                if k < 0:
                    x, q = p.getBasePositionAndOrientation(mb, physicsClientId=c)
                    v, w = p.getBaseVelocity(mb, physicsClientId=c)
                else:
                    ls = p.getLinkState(mb, k, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=c)
                    x, q, v, w = ls[0], ls[1], ls[6], ls[7]
                out.append(list(x) + _wxyz(q) + list(v) + list(w))
            return out

        return run_world(s, lambda: p.stepSimulation(physicsClientId=c), state)
    finally:
        p.disconnect(c)


KINDS = {"drop": drop, "inverse_dynamics": inverse_dynamics, "world": world}

if __name__ == "__main__":
    LABEL = "pybullet " + _version()
    engine_label_line(LABEL)
    for scene in json.load(open(sys.argv[1])):
        if len(sys.argv) > 2 and scene["id"] != sys.argv[2]:
            continue
        emit(LABEL, scene, KINDS)
