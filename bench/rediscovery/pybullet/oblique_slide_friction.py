"""Standalone reproducer (blind campaign flags s1-9, s1-140, s1-260, s1-279 and s1-360 on pybullet 3.2.7, issue 63):
a body whose only degree of freedom is a prismatic joint with a nearly horizontal axis, landing with friction on a
static support, is driven into the support and gains energy without bound.

A 0.586 kg sphere (radius 14.5 mm, the campaign's s1-279 reduced to one body) hangs from a fixed base by a prismatic
joint (no limit, motor off, no damping) whose axis points down at an angle theta from the vertical, its horizontal
part at an azimuth phi from the x axis; it starts 0.85 m above a static plane (GEOM_PLANE), at rest, friction
coefficient mu, step 5 ms, 2 s. Physically the plane stops it: at contact the normal force and Coulomb friction
both oppose the joint's motion (when mu * tan(theta) > 1 it jams, a wedge), so the sphere ends at the plane and the
mechanical energy (kinetic + gravitational, exact for one joint) never exceeds its initial value; the same scene
with mu = 0 does that here. Measured: the lowest point's minimum height and the largest energy gain over the run.
The wrong behaviour (measured on 3.2.7): with mu = 1, theta = 66.7 deg and phi away from 0 and 90 deg (the joint's
horizontal motion along neither world axis), the sphere ends 25 m below the plane and gains 2.9 kJ; at phi = 0 or 90
deg, or with mu = 0, it stops at the plane. At phi = 45 deg it also goes through at theta = 45 deg (5 m, sinking
without gaining energy), 60 and 75 deg, not at 30 deg (mu * tan(theta) < 1: friction alone cannot jam the joint).
Where: with pybullet's implicit cone friction off (setPhysicsEngineParameter(enableConeFriction=0), an engine option;
on by default) the same case stops at the plane. In Bullet's source (3.2.7's commit) that option selects
btMultiBodyConstraintSolver::resolveConeFrictionConstraintRows, which updates a contact's two friction rows together
from the same velocities and then clips them to the cone; the two rows' directions come from btPlaneSpace1 of the
normal (world x and y for a horizontal plane), so only a joint whose horizontal motion has both components couples them.
Measured at theta = 66.7 deg: through the plane for phi from 15 to 75 deg, stopped at 0-12 and 78-90 deg.

Exit 1 when a case with mu = 1 gains more than 1 J (the campaign's energy bound, physics-invariants) or ends more
than 2 cm below the plane (its penetration bound), 2 when a control (frictionless, or cone friction off) does (then
something else is wrong), 0 otherwise.

    python bench/rediscovery/pybullet/oblique_slide_friction.py
"""
import math
import sys

import pybullet as p

ENERGY_BOUND = 1.0  # J
DEPTH_BOUND = 0.02  # m
MASS, RADIUS, HEIGHT, DT, DURATION = 0.586, 0.0145, 0.85, 0.005, 2.0


def drop(theta_deg, phi_deg, mu, cone=True):
    """(lowest point's minimum height, largest gain of mechanical energy) over the run; `cone`: pybullet's implicit
    cone friction (its default) on or off."""
    th, ph = math.radians(theta_deg), math.radians(phi_deg)
    axis = [math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), -math.cos(th)]
    c = p.connect(p.DIRECT)
    try:
        g = 9.81
        p.setGravity(0, 0, -g, physicsClientId=c)
        p.setTimeStep(DT, physicsClientId=c)
        if not cone:
            p.setPhysicsEngineParameter(enableConeFriction=0, physicsClientId=c)
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=c)
        ground = p.createMultiBody(0, plane, physicsClientId=c)
        p.changeDynamics(ground, -1, lateralFriction=1.0, physicsClientId=c)
        sphere = p.createCollisionShape(p.GEOM_SPHERE, radius=RADIUS, physicsClientId=c)
        mb = p.createMultiBody(0, -1, -1, [0, 0, 0], [0, 0, 0, 1], linkMasses=[MASS],
                               linkCollisionShapeIndices=[sphere], linkVisualShapeIndices=[-1],
                               linkPositions=[[0, 0, HEIGHT]], linkOrientations=[[0, 0, 0, 1]],
                               linkInertialFramePositions=[[0, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                               linkParentIndices=[0], linkJointTypes=[p.JOINT_PRISMATIC], linkJointAxis=[axis],
                               physicsClientId=c)
        # Bullet combines the two bodies' coefficients by product: the plane's 1.0 times the sphere's mu.
        p.changeDynamics(mb, 0, lateralFriction=mu, jointDamping=0, linearDamping=0, angularDamping=0,
                         localInertiaDiagonal=[1e-5] * 3, physicsClientId=c)
        p.setJointMotorControl2(mb, 0, p.VELOCITY_CONTROL, force=0, physicsClientId=c)
        e0 = MASS * g * HEIGHT
        lowest, gain = float("inf"), float("-inf")
        for _ in range(int(round(DURATION / DT))):
            p.stepSimulation(physicsClientId=c)
            z = p.getLinkState(mb, 0, computeForwardKinematics=1, physicsClientId=c)[4][2]
            v = p.getJointState(mb, 0, physicsClientId=c)[1]
            lowest = min(lowest, z - RADIUS)
            gain = max(gain, 0.5 * MASS * v * v + MASS * g * z - e0)
        return lowest, gain
    finally:
        p.disconnect(c)


if __name__ == "__main__":
    bad = control_bad = False
    cases = [(66.7, 0, 1.0), (66.7, 90, 1.0), (66.7, 30, 1.0), (66.7, 45, 1.0), (66.7, 123, 1.0), (30, 45, 1.0),
             (45, 45, 1.0), (60, 45, 1.0), (75, 45, 1.0), (66.7, 45, 0.0), (66.7, 123, 0.0)]
    # Controls (exit 2 when wrong): frictionless, and the defect's case with implicit cone friction off.
    cases = [(t, f, m, True) for t, f, m in cases] + [(66.7, 45, 1.0, False), (66.7, 123, 1.0, False)]
    for theta, phi, mu, cone in cases:
        lowest, gain = drop(theta, phi, mu, cone)
        wrong = gain > ENERGY_BOUND or lowest < -DEPTH_BOUND
        print("theta {:5.1f} deg, phi {:4.0f} deg, mu {:.1f} (mu tan theta {:5.2f}), cone friction {}: lowest point "
              "{:9.3f} m, largest energy gain {:10.3g} J: {}".format(theta, phi, mu, mu * math.tan(math.radians(theta)),
                                                                    "on " if cone else "off", lowest, gain,
                                                                    "WRONG" if wrong else "ok"))
        if wrong:
            if mu == 0.0 or not cone:
                control_bad = True
            else:
                bad = True
    sys.exit(2 if control_bad else 1 if bad else 0)
