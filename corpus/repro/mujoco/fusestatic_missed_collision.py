"""A leg (box) with a tripod foot (three spheres) attached WITHOUT a joint, as URDF fixed joints import, dropped
10 cm onto a plane. Expectation: the foot holds the leg up (the body comes to rest with the sphere bottoms on the
plane, body origin at z = 0.4 m). MuJoCo 3.1.5 and earlier (fusestatic on): the fused foot's geoms are missing
from the body's bounding-volume hierarchy, the foot falls through and the leg box lands on its end (z = 0.2 m).
Fixed in 3.1.6 (changelog: "collisions missed when fusestatic is enabled", issues #1069, #1577)."""
import sys

import mujoco

XML = """<mujoco>
  <compiler fusestatic="true"/>
  <worldbody>
    <geom type="plane" size="5 5 0.1"/>
    <body pos="0 0 0.5">
      <freejoint/>
      <geom type="box" size="0.05 0.05 0.2"/>
      <body>
        <geom type="sphere" size="0.1" pos="0.15 0.1 -0.3"/>
        <geom type="sphere" size="0.1" pos="-0.15 0.1 -0.3"/>
        <geom type="sphere" size="0.1" pos="0 -0.15 -0.3"/>
      </body>
    </body>
  </worldbody>
</mujoco>"""

m = mujoco.MjModel.from_xml_string(XML)
d = mujoco.MjData(m)
for _ in range(1000):
    mujoco.mj_step(m, d)
z = d.qpos[2]
print("MuJoCo", mujoco.__version__, "- body height after 2 s: %.4f m (expected 0.4: resting on its foot)" % z)
sys.exit(0 if abs(z - 0.4) < 0.02 else 1)
