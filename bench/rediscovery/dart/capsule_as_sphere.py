"""Standalone reproducer of the cause of most DART 6.16.6 flags of the blind campaign (issue 63): with dartpy's
default collision detector (FCL, what the bench's adapter uses), a CapsuleShape collides as a fixed sphere whatever
the capsule's size ("Attempting to create an unsupported shape type [CapsuleShape]. Creating a sphere with 0.1 radius
instead." on stderr). Measured with this script's scene: the capsule's centre comes to rest 0.05 m above the support
for radii 0.01, 0.05 and 0.2 m (a SphereShape of radius 0.1 m rests at 0.097 m), so the substitute behaves as a
sphere of 0.05 m radius, not the 0.1 m the message names.

An upright capsule (radius 0.05 m, 0.4 m between its cap centres, so 0.5 m tall) is dropped from 1 cm above a fixed
box; it should rest with its centre 0.25 m above the box's top. A cylinder of the same radius and total height is
the control (FCL builds it). The measured penetration is how far the lowest point of the true shape ends below the
top, against the campaign's bound (2 cm, physics-invariants PENETRATION_MAX). Exit 1 when the capsule penetrates
beyond the bound, 2 when the cylinder does too (then something else is wrong), 0 otherwise.

    python bench/rediscovery/dart/capsule_as_sphere.py
"""
import sys

import dartpy as dart

BOUND = 0.02  # m
RADIUS, CORE = 0.05, 0.4  # m: capsule radius and distance between its cap centres
HALF_HEIGHT = RADIUS + CORE / 2  # m, half the total height of the capsule (and of the control cylinder)


def rest_penetration(shape):
    w = dart.simulation.World()
    w.setGravity([0.0, 0.0, -9.81])
    w.setTimeStep(0.001)
    ground = dart.dynamics.Skeleton("ground")
    _, gb = ground.createWeldJointAndBodyNodePair()
    node = gb.createShapeNode(dart.dynamics.BoxShape([4.0, 4.0, 0.2]))
    node.setRelativeTranslation([0.0, 0.0, -0.1])  # top face at z = 0
    node.createCollisionAspect()
    node.createDynamicsAspect()
    w.addSkeleton(ground)
    sk = dart.dynamics.Skeleton("body")
    joint, body = sk.createFreeJointAndBodyNodePair()
    body.setInertia(dart.dynamics.Inertia(1.0, [0.0, 0.0, 0.0], [[0.02, 0, 0], [0, 0.02, 0], [0, 0, 0.002]]))
    node = body.createShapeNode(shape)
    node.createCollisionAspect()
    node.createDynamicsAspect()
    t = dart.math.Isometry3()
    t.set_translation([0.0, 0.0, HALF_HEIGHT + 0.01])
    joint.setPositions(dart.dynamics.FreeJoint.convertToPositions(t))
    w.addSkeleton(sk)
    for _ in range(2000):  # 2 s
        w.step()
    return HALF_HEIGHT - body.getWorldTransform().translation()[2]


if __name__ == "__main__":
    capsule = rest_penetration(dart.dynamics.CapsuleShape(RADIUS, CORE))
    cylinder = rest_penetration(dart.dynamics.CylinderShape(RADIUS, 2 * HALF_HEIGHT))
    print("capsule: centre rests {:.4f} m above the support, penetration {:.4f} m; cylinder: {:.4f} m, {:.4f} m "
          "(bound {} m)".format(HALF_HEIGHT - capsule, capsule, HALF_HEIGHT - cylinder, cylinder, BOUND))
    sys.exit(2 if cylinder > BOUND else 1 if capsule > BOUND else 0)
