"""Rediscovery bench: the cross-engine scenes in DART, through the `dartpy` wheel of the interpreter's venv.
Same protocol as scenes_mujoco.py: raw observables per scene, no verdicts."""
import json
import sys

import dartpy as dart
import numpy as np

from scene_common import emit, engine_label_line


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


KINDS = {"passive_chain": passive_chain}

if __name__ == "__main__":
    from importlib.metadata import version

    label = "dartpy " + version("dartpy")
    engine_label_line(label)
    for scene in json.load(open(sys.argv[1])):
        if len(sys.argv) > 2 and scene["id"] != sys.argv[2]:
            continue
        emit(label, scene, KINDS)
