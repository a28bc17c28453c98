"""Standalone reproducer (blind campaign flags s1-80, s1-156 and s1-380 on pybullet 3.2.7, issue 63): on a multibody
whose base is fixed (base mass 0), a link attached by a fixed joint to link 0 does not collide with static geometry
when link 0's own joint moves (prismatic or revolute): a sphere carried by it falls through a plane.

The multibody is a chain built with createMultiBody: a fixed base at the origin, then links each the child of the
previous one, joint axes along z (revolute: along y, the chain 0.2 m up, the sphere 0.3 m out), no joint limits or
motors, each link 1 kg; one link carries a sphere of radius 0.05 m above a static plane (GEOM_PLANE), at rest.
Gravity brings the chain down until the sphere rests on the plane with its centre 0.05 m above it (analytic; the
same sphere on link 0 itself does). Measured: the sphere's centre after 1 s, at 240 Hz. The wrong behaviour: the
sphere on a fixed child of a prismatic or revolute link 0 passes through the plane (4 m below it after 1 s on the
prismatic joint; hanging 9 cm below it on the revolute one), while with a fixed link 0 in front of the moving joint
(the same dynamics, the sphere one fixed joint further from the base) it rests. Cause, read in the source pybullet
3.2.7 builds (bullet3 commit 6c888f4ab): createMultiBody goes through PhysicsServerCommandProcessor's
processCreateMultiBodyCommandSingle and processImportedObjects into ConvertURDF2BulletInternal
(examples/Importers/ImportURDFDemo/URDF2Bullet.cpp), which gives a link of a fixed-base multibody CF_STATIC_OBJECT when
every joint between it and the base is fixed; its walk up the parents stops on reaching link 0 (`testLinkIndex > 0`)
without checking link 0's own joint, and two static objects get no contact response (btCollisionDispatcher::
needsResponse). Draft upstream report: UPSTREAM.md.

Exit 1 when a sphere on a fixed child of a moving link 0 ends more than 2 cm (the campaign's penetration bound,
physics-invariants PENETRATION_MAX) below the plane, 2 when a control configuration does too (then something else is
wrong), 0 otherwise.

    python bench/rediscovery/pybullet/fixed_link_static.py
"""
import sys

import pybullet as p

BOUND = 0.02  # m
RADIUS = 0.05  # m
F, P, R = p.JOINT_FIXED, p.JOINT_PRISMATIC, p.JOINT_REVOLUTE


def rest_height(chain, shape_on, horizontal=False):
    """Centre height of the sphere on link `shape_on` after 1 s; `chain` lists the links' joint types (each link the
    child of the previous one). `horizontal`: the chain 0.2 m above the plane and the sphere 0.3 m off the joint
    axis, horizontal (a revolute joint about a horizontal axis then swings it down onto the plane)."""
    c = p.connect(p.DIRECT)
    try:
        dt = 1.0 / 240.0
        p.setGravity(0, 0, -9.81, physicsClientId=c)
        p.setTimeStep(dt, physicsClientId=c)
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=c)
        p.createMultiBody(0, plane, physicsClientId=c)
        n = len(chain)
        sphere = p.createCollisionShape(p.GEOM_SPHERE, radius=RADIUS, physicsClientId=c)
        offset = [0.3, 0, 0] if horizontal else [0, 0, 0]
        axis = [0, 1, 0] if horizontal else [0, 0, 1]
        mb = p.createMultiBody(
            0, -1, -1, [0, 0, 0], [0, 0, 0, 1], linkMasses=[1.0] * n,
            linkCollisionShapeIndices=[sphere if k == shape_on else -1 for k in range(n)],
            linkVisualShapeIndices=[-1] * n,
            linkPositions=[[0, 0, 0.2 if horizontal else 0.5]]
            + [offset if k == shape_on else [0, 0, 0] for k in range(1, n)],
            linkOrientations=[[0, 0, 0, 1]] * n, linkInertialFramePositions=[[0, 0, 0]] * n,
            linkInertialFrameOrientations=[[0, 0, 0, 1]] * n, linkParentIndices=list(range(n)),
            linkJointTypes=chain, linkJointAxis=[axis] * n, physicsClientId=c)
        for k in range(n):
            if chain[k] != F:
                p.setJointMotorControl2(mb, k, p.VELOCITY_CONTROL, force=0, physicsClientId=c)
        for _ in range(240):
            p.stepSimulation(physicsClientId=c)
        return p.getLinkState(mb, shape_on, computeForwardKinematics=1, physicsClientId=c)[4][2]
    finally:
        p.disconnect(c)


if __name__ == "__main__":
    # (description, chain, link carrying the sphere, sphere off a horizontal revolute axis, is this the defect case)
    cases = [
        ("prismatic link 0 carrying the sphere", [P], 0, False, False),
        ("prismatic link 0, sphere on fixed link 1", [P, F], 1, False, True),
        ("prismatic link 0, sphere on fixed link 2 (fixed link 1)", [P, F, F], 2, False, True),
        ("revolute link 0 (horizontal axis), sphere on fixed link 1", [R, F], 1, True, True),
        ("fixed link 0, prismatic link 1 carrying the sphere", [F, P], 1, False, False),
        ("fixed link 0, prismatic link 1, sphere on fixed link 2", [F, P, F], 2, False, False),
        ("fixed link 0, revolute link 1 (horizontal axis), sphere on fixed link 2", [F, R, F], 2, True, False),
    ]
    bad = control_bad = False
    for name, chain, on, horizontal, defect in cases:
        z = rest_height(chain, on, horizontal)
        depth = RADIUS - z
        wrong = depth > BOUND
        print("{:<72} sphere centre z = {:8.3f} m (rests at {:.3f}): {}".format(
            name, z, RADIUS, "FALLS THROUGH" if wrong else "rests"))
        if wrong and defect:
            bad = True
        if wrong and not defect:
            control_bad = True
    sys.exit(2 if control_bad else 1 if bad else 0)
