"""Inverse dynamics of a floating robot held at rest: a 5 kg base and one 2 kg link (a 0.3 m rod along x) on a
revolute joint about y, tilted by q. With zero velocities and accelerations the joint torque is the gravity
torque of the link about its joint, m g (l/2) cos q (analytic). pybullet 3.2.6: the joint vector handed to the
inverse dynamics is shifted by one slot for floating bases, so the torque is computed at the wrong angle.
Fixed in 3.2.7 (bullet3 PR #4585)."""
import math
import os
import sys
import tempfile

import pybullet as p

M, L, Q = 2.0, 0.3, 0.7
URDF = """<robot name="r">
<link name="base"><inertial><mass value="5"/><inertia ixx="0.05" iyy="0.05" izz="0.05" ixy="0" ixz="0" iyz="0"/></inertial></link>
<link name="rod"><inertial><origin xyz="{c} 0 0"/><mass value="{m}"/><inertia ixx="0.001" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="j" type="revolute"><parent link="base"/><child link="rod"/><origin xyz="0.1 0 0"/><axis xyz="0 1 0"/>
<limit lower="-3" upper="3" effort="100" velocity="10"/></joint>
</robot>""".format(c=L / 2, m=M)

c = p.connect(p.DIRECT)
p.setGravity(0, 0, -9.81)
with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
    f.write(URDF)
body = p.loadURDF(f.name, [0, 0, 1], [0, 0, 0, 1], useFixedBase=False, flags=p.URDF_USE_INERTIA_FROM_FILE)
os.unlink(f.name)
p.resetJointState(body, 0, Q)
q = [0, 0, 1, 0, 0, 0, 1, Q]
tau = p.calculateInverseDynamics(body, q, [0.0] * 7, [0.0] * 7)
# Rotation about +y by Q lowers the rod's tip; the joint must hold it: tau = -m g (l/2) cos Q about +y.
expected = -M * 9.81 * (L / 2) * math.cos(Q)
print("pybullet: joint torque %.4f N m, analytic %.4f N m" % (tau[6], expected))
sys.exit(0 if abs(tau[6] - expected) < 1e-6 * abs(expected) + 1e-9 else 1)
