"""Rediscovery bench: the cross-engine scenes in DART, through the `dartpy` wheel of the interpreter's venv.
Same protocol as scenes_mujoco.py: raw observables per scene, no verdicts."""
import json
import sys

import dartpy as dart
import numpy as np

from scene_common import Rejected, emit, engine_label_line, quat_rotate, run_world, world_trees


def passive_chain(s):
    """Rods along x joined by revolute joints about y, released from rest at q0; returns the mechanical energy
    (DART's kinetic energy plus the gravitational potential of every body's centre of mass, computed here
    because Skeleton::computePotentialEnergy covers joint springs only) before the first step and after
    every step."""
    g = s["gravity"]
    sk = dart.dynamics.Skeleton("chain")
    parent, previous = None, 0.0
    for i, (m, l) in enumerate(zip(s["masses"], s["lengths"])):
        jp = dart.dynamics.RevoluteJointProperties()
        jp.mAxis = [0.0, 1.0, 0.0]
        jp.mName = "j{}".format(i)
        if parent is not None:
            t = dart.math.Isometry3()
            t.set_translation([previous, 0.0, 0.0])
            jp.mT_ParentBodyToJoint = t
        props = dart.dynamics.BodyNodeProperties(dart.dynamics.BodyNodeAspectProperties("b{}".format(i)))
        joint, body = sk.createRevoluteJointAndBodyNodePair(parent, jp, props)
        # A thin rod about its centre (a massless link gets zero inertia: what URDF exports of frames carry).
        body.setInertia(dart.dynamics.Inertia(m, [l / 2.0, 0.0, 0.0], np.diag([0.0, m * l * l / 12.0, m * l * l / 12.0])))
        lim = s["limits"][i]
        if lim is not None:
            joint.setPositionLowerLimit(0, lim[0])
            joint.setPositionUpperLimit(0, lim[1])
            joint.setLimitEnforcement(True)
        parent, previous = body, l
    sk.setPositions(s["q0"])
    world = dart.simulation.World()
    world.setGravity([0.0, 0.0, g])
    world.setTimeStep(s["dt"])
    world.addSkeleton(sk)

    def energy():
        pe = sum(-sk.getBodyNode(k).getMass() * g * sk.getBodyNode(k).getCOM()[2] for k in range(sk.getNumBodyNodes()))
        return float(sk.computeKineticEnergy() + pe)

    t, e = [0.0], [energy()]
    steps = int(round(s["duration"] / s["dt"]))
    for i in range(steps):
        world.step()
        t.append((i + 1) * s["dt"])
        e.append(energy())
    return {"t": t, "energy": e, "q_final": [float(x) for x in sk.getPositions()]}


def _rot(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _iso(pos, q):
    t = dart.math.Isometry3()
    t.set_translation(list(pos))
    t.set_rotation(_rot(q))
    return t


def _quat(r):
    """[w, x, y, z] of a rotation matrix (Shepperd's method)."""
    tr = r[0, 0] + r[1, 1] + r[2, 2]
    if tr > 0:
        k = 2.0 * np.sqrt(tr + 1.0)
        return [0.25 * k, (r[2, 1] - r[1, 2]) / k, (r[0, 2] - r[2, 0]) / k, (r[1, 0] - r[0, 1]) / k]
    i = int(np.argmax([r[0, 0], r[1, 1], r[2, 2]]))
    j, l = (i + 1) % 3, (i + 2) % 3
    k = 2.0 * np.sqrt(max(1.0 + r[i, i] - r[j, j] - r[l, l], 0.0))
    q = [0.0] * 4
    q[0] = (r[l, j] - r[j, l]) / k
    q[1 + i] = 0.25 * k
    q[1 + j] = (r[j, i] + r[i, j]) / k
    q[1 + l] = (r[l, i] + r[i, l]) / k
    return q


def _shape(sh):
    if sh["type"] == "box":
        return dart.dynamics.BoxShape([2 * h for h in sh["half"]])
    if sh["type"] == "sphere":
        return dart.dynamics.SphereShape(sh["radius"])
    if sh["type"] == "capsule":
        return dart.dynamics.CapsuleShape(sh["radius"], 2 * sh["half_length"])
    return dart.dynamics.CylinderShape(sh["radius"], 2 * sh["half_length"])


def world(s):
    """A generated scene (harness `blind::World`): one Skeleton per tree (self-collision off, DART's default, so
    bodies of a tree never touch each other), joints placed at each body's anchor, body frames at the centres of
    mass. A plane support is a 20 m thick box (DART's default collision detector has no half-space)."""
    w = dart.simulation.World()
    w.setGravity([0.0, 0.0, s["gravity"]])
    w.setTimeStep(s["dt"])
    sup = s.get("support")
    if sup is not None and s["collide"]:
        half = [100.0, 100.0, 10.0] if sup["type"] == "plane" else sup["half"]
        g = dart.dynamics.Skeleton("support")
        _, gb = g.createWeldJointAndBodyNodePair()
        node = gb.createShapeNode(dart.dynamics.BoxShape([2 * h for h in half]))
        node.setRelativeTranslation([0.0, 0.0, -half[2]])
        node.createCollisionAspect()
        node.createDynamicsAspect()
        w.addSkeleton(g)
    bodies = s["bodies"]
    tree = world_trees(s)
    nodes, skels = [], {}
    for i, b in enumerate(bodies):
        j = b["joint"]
        t = tree[i]
        if t not in skels:
            skels[t] = dart.dynamics.Skeleton("tree{}".format(t))
        sk = skels[t]
        parent = None if b["parent"] is None else nodes[b["parent"]]
        create = {"free": sk.createFreeJointAndBodyNodePair, "fixed": sk.createWeldJointAndBodyNodePair,
                  "hinge": sk.createRevoluteJointAndBodyNodePair, "slide": sk.createPrismaticJointAndBodyNodePair}
        joint, body = create[j["type"]](parent)
        if j["type"] != "free":
            joint.setTransformFromParentBodyNode(_iso([b["pos"][k] + quat_rotate(b["quat"], b["anchor"])[k] for k in range(3)], b["quat"]))
            joint.setTransformFromChildBodyNode(_iso(b["anchor"], [1.0, 0.0, 0.0, 0.0]))
        if j["type"] in ("hinge", "slide"):
            joint.setAxis(list(j["axis"]))
            if j.get("limit"):
                joint.setPositionLowerLimit(0, j["limit"][0])
                joint.setPositionUpperLimit(0, j["limit"][1])
                joint.setLimitEnforcement(True)
        body.setInertia(dart.dynamics.Inertia(b["mass"], [0.0, 0.0, 0.0], np.diag(b["inertia"])))
        if s["collide"]:
            for g in b["geoms"]:
                node = body.createShapeNode(_shape(g["shape"]))
                node.setRelativeTranslation(list(g["pos"]))
                node.setRelativeRotation(_rot(g["quat"]))
                node.createCollisionAspect()
                node.createDynamicsAspect().setFrictionCoeff(g["friction"])
        nodes.append(body)
    for i, b in enumerate(bodies):
        j, joint = b["joint"], nodes[i].getParentJoint()
        if j["type"] == "free":
            joint.setPositions(dart.dynamics.FreeJoint.convertToPositions(_iso(b["pos"], b["quat"])))
        elif j["type"] != "fixed":
            joint.setPosition(0, j["q0"])
            joint.setVelocity(0, j["v0"])
    for t in sorted(skels):
        w.addSkeleton(skels[t])
    # Free-joint velocities once the skeletons' kinematics are in place (world frame, at the centre of mass).
    for i, b in enumerate(bodies):
        j = b["joint"]
        if j["type"] == "free":
            joint = nodes[i].getParentJoint()
            joint.setLinearVelocity(list(j["linvel"]))
            joint.setAngularVelocity(list(j["angvel"]))

    def state():
        out = []
        for body in nodes:
            tf = body.getWorldTransform()
            out.append([float(x) for x in tf.translation()] + [float(x) for x in _quat(tf.rotation())]
                       + [float(x) for x in body.getLinearVelocity()] + [float(x) for x in body.getAngularVelocity()])
        return out

    return run_world(s, w.step, state)


KINDS = {"passive_chain": passive_chain, "world": world}

if __name__ == "__main__":
    from importlib.metadata import version

    label = "dartpy " + version("dartpy")
    engine_label_line(label)
    for scene in json.load(open(sys.argv[1])):
        if len(sys.argv) > 2 and scene["id"] != sys.argv[2]:
            continue
        emit(label, scene, KINDS)
