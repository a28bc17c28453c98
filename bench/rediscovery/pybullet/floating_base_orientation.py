"""Standalone reproducer (blind campaign finding on pybullet 3.2.6 and 3.2.7, issue 63): calculateInverseDynamics of
a floating base disagrees with Bullet's own forward dynamics when the base is rotated about more than one axis.

A single free box (no joints, no contact) falls under gravity: its forward acceleration is g (linear) and zero
(angular), so the generalized force inverse dynamics must return at (q, q̇ = 0, q̈ = free fall) is zero. The base's
velocity and acceleration are given as (angular, linear) in the base frame, the convention under which the same
call returns the applied wrench exactly for rotations about one axis (checked below as the control). Exit 1 when
the rotated case is inconsistent (|wrench| > 1e-8 of the weight, the analytic-dynamics tolerance), 2 when the
control fails too (then the convention, not the orientation, is wrong), 0 when both are consistent.

    python bench/rediscovery/pybullet/floating_base_orientation.py
"""
import math
import sys

import pybullet as p


def rotate_inverse(q_xyzw, v):
    """Rotates v by the inverse of the unit quaternion q (x, y, z, w): world → base frame."""
    m = p.getMatrixFromQuaternion(q_xyzw)  # row-major R (base → world)
    return [m[0] * v[0] + m[3] * v[1] + m[6] * v[2], m[1] * v[0] + m[4] * v[1] + m[7] * v[2],
            m[2] * v[0] + m[5] * v[1] + m[8] * v[2]]


def free_fall_wrench(euler):
    c = p.connect(p.DIRECT)
    try:
        g = [0.0, 0.0, -9.81]
        p.setGravity(*g, physicsClientId=c)
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.1, 0.2, 0.3], physicsClientId=c)
        q = p.getQuaternionFromEuler(euler)
        body = p.createMultiBody(2.0, shape, -1, [0, 0, 1], q, physicsClientId=c)
        a = rotate_inverse(q, g)
        wrench = p.calculateInverseDynamics(body, [0, 0, 1] + list(q), [0.0] * 6, [0.0, 0.0, 0.0] + a,
                                            physicsClientId=c)
        return math.sqrt(sum(x * x for x in wrench)) / (2.0 * 9.81)
    finally:
        p.disconnect(c)


if __name__ == "__main__":
    control = max(free_fall_wrench(e) for e in ([0.6, 0, 0], [0, 0.6, 0], [0, 0, 0.6]))
    rotated = free_fall_wrench([0.6, 0.4, 0.0])
    print("one-axis rotations: |wrench|/weight = {:.2e}; rotated about x and y: {:.3f}".format(control, rotated))
    sys.exit(2 if control > 1e-8 else 1 if rotated > 1e-8 else 0)
