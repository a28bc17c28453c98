"""Standalone reproducer of the `mesh_primitives` cause of DART 6.16.6 blind flags (issue 63; s1-41, s1-157): with
dartpy's default collision detector (FCL with primitive shapes built as meshes, the FCLCollisionDetector default
`PrimitiveShape.MESH`, which DART's own warning recommends over FCL's primitives), a sphere collides as a tessellated
mesh whose flat faces lie inside the true sphere, so a large sphere sinks into the support by a fixed fraction of its
radius, beyond the campaign's penetration bound (2 cm, physics-invariants PENETRATION_MAX) from r of about 0.25 m.

A sphere of radius r (1 kg, solid-sphere inertia) rolls at 1 m/s on a fixed box, at rest on it at the start, for 3 s
(1 ms steps); measured after the first 0.5 s: how far its centre comes below r (a true sphere's centre stays at r, the
analytic value). The same with FCL's primitive sphere (`setPrimitiveShapeType(PRIMITIVE)`) is the control. Exit 1
when a mesh sphere sinks beyond the bound, 2 when a primitive one does too (then something else is wrong), 0
otherwise. A modelling approximation of DART's default set-up, not a defect.

    python bench/rediscovery/dart/mesh_sphere_depth.py
"""
import sys

import dartpy as dart
import numpy as np

BOUND = 0.02  # m
DT, DURATION, SKIP, SPEED = 0.001, 3.0, 0.5, 1.0  # s, s, s, m/s


def sink(radius, primitive):
    """Largest depth of the sphere's centre below its radius while rolling (m)."""
    w = dart.simulation.World()
    w.setGravity([0.0, 0.0, -9.81])
    w.setTimeStep(DT)
    if primitive:
        det = dart.collision.FCLCollisionDetector()
        det.setPrimitiveShapeType(dart.collision.FCLCollisionDetector.PrimitiveShape.PRIMITIVE)
        w.getConstraintSolver().setCollisionDetector(det)
    ground = dart.dynamics.Skeleton("ground")
    _, gb = ground.createWeldJointAndBodyNodePair()
    node = gb.createShapeNode(dart.dynamics.BoxShape([200.0, 200.0, 20.0]))
    node.setRelativeTranslation([0.0, 0.0, -10.0])
    node.createCollisionAspect()
    node.createDynamicsAspect()
    w.addSkeleton(ground)
    ball = dart.dynamics.Skeleton("ball")
    joint, body = ball.createFreeJointAndBodyNodePair()
    body.setInertia(dart.dynamics.Inertia(1.0, [0.0, 0.0, 0.0], np.eye(3) * 0.4 * radius * radius))
    node = body.createShapeNode(dart.dynamics.SphereShape(radius))
    node.createCollisionAspect()
    node.createDynamicsAspect()
    w.addSkeleton(ball)
    tf = dart.math.Isometry3()
    tf.set_translation([0.0, 0.0, radius])
    joint.setPositions(dart.dynamics.FreeJoint.convertToPositions(tf))
    joint.setVelocities([0.0, SPEED / radius, 0.0, SPEED, 0.0, 0.0])  # rolling along x (angular about y first)
    depth = 0.0
    for k in range(int(round(DURATION / DT))):
        w.step()
        if k * DT >= SKIP:
            depth = max(depth, radius - body.getWorldTransform().translation()[2])
    return depth


if __name__ == "__main__":
    bad = control_bad = False
    for r in (0.05, 0.1, 0.2, 0.4, 0.8):
        mesh, prim = sink(r, False), sink(r, True)
        print("sphere r = {:.2f} m rolling: centre up to {:.4f} m below r with meshes ({:.3f} r), {:.4f} m with FCL "
              "primitives".format(r, mesh, mesh / r, prim))
        bad |= mesh > BOUND
        control_bad |= prim > BOUND
    sys.exit(2 if control_bad else 1 if bad else 0)
