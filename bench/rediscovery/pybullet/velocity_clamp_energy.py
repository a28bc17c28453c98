"""Standalone reproducer (blind campaign flag s1-250 on pybullet 3.2.6 and 3.2.7, issue 63): Bullet's maximum
coordinate velocity (changeDynamics `maxJointVelocity`, default 100) clamps every velocity coordinate of a multibody
on its own, the floating base's six included; on a light floating base that spins faster than 100 rad/s the clamp
changes the velocities of the heavy links it carries, and a free body without any force gains energy and momentum.

The multibody: a floating base of 10 g (inertia 1e-7 kg m^2 about each axis, s1-250's root: 10.1 g, 1.1e-7 to
2.0e-7 kg m^2) carrying, by a fixed joint 2 cm away along x, a 0.6 kg link (inertia 1e-5 kg m^2; s1-250's slid body:
0.611 kg, 4.4e-6 to 8.9e-6 kg m^2). No gravity, no contact, no damping. At t = 0 the pair spins rigidly about its
common centre of mass at omega0 about z (base angular velocity omega0, base linear velocity omega0 x (base - centre)).
Physically (analytic) nothing changes: a free rigid body without force keeps its kinetic energy and its linear momentum
(zero here). Measured over 0.02 s at dt = 10 us (0.003 rad of spin per step, so the integration error stays small: the
unclamped control keeps its energy within 1e-3 J and its momentum within 0.011 N s; both shrink with dt): the largest
energy gain and the largest linear momentum, from the base's and the link's reported velocities. The wrong behaviour
(3.2.6 and 3.2.7): at omega0 = 150 and 300 rad/s the base's angular velocity is clamped to 100 rad/s in the first step
while its linear velocity stays, so the link is set moving at (omega0 - 100) * 2 cm: momentum 0.6 N s and 2.4 N s
appear, as that predicts, and 0.2 J and 4.2 J of energy. Controls: omega0 = 50 rad/s (below the clamp) and
omega0 = 300 rad/s with maxJointVelocity set to infinity (the clamp lifted, a documented option) keep both.

In the campaign the same thing happens through contact impulses: s1-250's minimised tree (a 10 g free root with a
hinged 167 g box and a 611 g body on a slide) is thrown at 490 rad/s (root) and 450 rad/s (hinge) by its landing
when the clamp is lifted, and its energy is then conserved within 4e-5 J; with the default clamp both rates stay at
exactly 100 and the energy jumps (+17 J in one step at t = 0.419 s, +43 J by the end). What is documented: the
PyBullet Quickstart Guide's changeDynamics lists maxJointVelocity as a maximum joint velocity, clamped when exceeded,
100 by default (its wording was not re-read for this). What is not: in Bullet's source the one value is per
multibody (b3ChangeDynamicsInfoSetMaxJointVelocity takes no link index; btMultiBody::setMaxCoordinateVelocity), and
btMultiBody::applyDeltaVeeMultiDof (btMultiBody.h) clamps each of the 6 + getNumDofs() velocity coordinates on its own
after every velocity change, the floating base's angular and linear velocity included.

Exit 1 when a default case above the clamp gains more than 1 J (the campaign's energy bound, physics-invariants), 2
when a control does (then something else is wrong), 0 otherwise. The momentum is printed next to what a clamp of the
base's angular velocity alone predicts, M_link * max(omega0 - 100, 0) * 2 cm (a check of the mechanism, not a verdict).

    python bench/rediscovery/pybullet/velocity_clamp_energy.py
"""
import math
import sys

import pybullet as p

ENERGY_BOUND = 1.0  # J
CLAMP = 100.0  # Bullet's default maximum coordinate velocity (btMultiBody constructor)
M_BASE, I_BASE = 0.01, 1e-7
M_LINK, I_LINK = 0.6, 1e-5
ARM = 0.02  # m, base centre of mass to link centre of mass, along x
DT, DURATION = 1e-5, 0.02


def spin(omega0, max_joint_velocity=None):
    """(largest energy gain (J), largest |linear momentum| (N s)) over the run."""
    c = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, 0, physicsClientId=c)
        p.setTimeStep(DT, physicsClientId=c)
        mb = p.createMultiBody(M_BASE, -1, -1, [0, 0, 1], [0, 0, 0, 1], linkMasses=[M_LINK],
                               linkCollisionShapeIndices=[-1], linkVisualShapeIndices=[-1],
                               linkPositions=[[ARM, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
                               linkInertialFramePositions=[[0, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                               linkParentIndices=[0], linkJointTypes=[p.JOINT_FIXED], linkJointAxis=[[0, 0, 1]],
                               physicsClientId=c)
        p.changeDynamics(mb, -1, localInertiaDiagonal=[I_BASE] * 3, linearDamping=0, angularDamping=0,
                         physicsClientId=c)
        p.changeDynamics(mb, 0, localInertiaDiagonal=[I_LINK] * 3, physicsClientId=c)
        if max_joint_velocity is not None:
            p.changeDynamics(mb, -1, maxJointVelocity=max_joint_velocity, physicsClientId=c)
        # Rigid rotation about the common centre of mass: the base, ARM * M_LINK / (M_BASE + M_LINK) on the -x side
        # of it, moves at omega0 * that distance along -y.
        d_base = ARM * M_LINK / (M_BASE + M_LINK)
        p.resetBaseVelocity(mb, [0, -omega0 * d_base, 0], [0, 0, omega0], physicsClientId=c)

        def energy_momentum():
            v_b, w_b = p.getBaseVelocity(mb, physicsClientId=c)
            ls = p.getLinkState(mb, 0, computeLinkVelocity=1, physicsClientId=c)
            v_l, w_l = ls[6], ls[7]
            e = 0.5 * (M_BASE * sum(x * x for x in v_b) + I_BASE * sum(x * x for x in w_b)
                       + M_LINK * sum(x * x for x in v_l) + I_LINK * sum(x * x for x in w_l))
            mom = math.sqrt(sum((M_BASE * a + M_LINK * b) ** 2 for a, b in zip(v_b, v_l)))
            return e, mom

        e0, _ = energy_momentum()
        gain, momentum = float("-inf"), 0.0
        for _ in range(int(round(DURATION / DT))):
            p.stepSimulation(physicsClientId=c)
            e, mom = energy_momentum()
            gain, momentum = max(gain, e - e0), max(momentum, mom)
        return e0, gain, momentum
    finally:
        p.disconnect(c)


if __name__ == "__main__":
    # (omega0 rad/s, maxJointVelocity or None for the default, is this a control)
    cases = [(50.0, None, True), (150.0, None, False), (300.0, None, False), (300.0, math.inf, True)]
    bad = control_bad = False
    for omega0, vmax, control in cases:
        e0, gain, momentum = spin(omega0, vmax)
        wrong = gain > ENERGY_BOUND
        predicted = M_LINK * max(omega0 - CLAMP, 0.0) * ARM if vmax is None else 0.0
        print("omega0 {:5.0f} rad/s, maxJointVelocity {:>7}: initial energy {:6.3f} J, largest gain {:7.3f} J "
              "(analytic 0), largest momentum {:7.4f} N s (analytic 0; the clamp predicts {:6.4f}): {}".format(
                  omega0, "default" if vmax is None else str(vmax), e0, gain, momentum, predicted,
                  "WRONG" if wrong else "ok"))
        if wrong:
            if control:
                control_bad = True
            else:
                bad = True
    sys.exit(2 if control_bad else 1 if bad else 0)
