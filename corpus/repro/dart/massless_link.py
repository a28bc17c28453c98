"""A passive triple pendulum (rods of 1, 1 and 0 kg, revolute joints about y) released from rest. Expectation: a
massless last link (a frame, as URDF exports often carry) changes nothing; the state stays finite. dartpy 6.16.5
and earlier: the articulated-body recursion divides by the zero mass and the whole state is NaN after the first
step. Fixed in 6.16.6 (release notes: "Guard against non-finite articulated body computations from zero/epsilon
mass", gz-physics#849)."""
import math
import sys

import dartpy as dart
import numpy as np

sk = dart.dynamics.Skeleton("chain")
parent, previous = None, 0.0
for i, (m, l) in enumerate([(1.0, 0.5), (1.0, 0.5), (0.0, 0.1)]):
    jp = dart.dynamics.RevoluteJointProperties()
    jp.mAxis = [0.0, 1.0, 0.0]
    if parent is not None:
        t = dart.math.Isometry3()
        t.set_translation([previous, 0.0, 0.0])
        jp.mT_ParentBodyToJoint = t
    _, body = sk.createRevoluteJointAndBodyNodePair(parent, jp, dart.dynamics.BodyNodeProperties())
    body.setInertia(dart.dynamics.Inertia(m, [l / 2, 0, 0], np.diag([0.0, m * l * l / 12, m * l * l / 12])))
    parent, previous = body, l
sk.setPositions([0.5, 0.3, 0.2])
world = dart.simulation.World()
world.setGravity([0, 0, -9.81])
world.setTimeStep(0.001)
world.addSkeleton(sk)
world.step()
q = sk.getPositions()
print("dartpy: joint angles after one step", q)
sys.exit(0 if all(math.isfinite(x) for x in q) else 1)
