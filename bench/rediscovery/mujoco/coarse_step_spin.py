"""Standalone reproducer of the blind campaign's non-finite flags s1-350 and s1-577 on MuJoCo 3.17.0 (issue 63),
classed `coarse_step`: a valid model whose 5 ms step does not resolve how fast an impact spins its millimetre-sized
bodies, so MuJoCo's first-order integrators diverge and mj_checkAcc resets the state ("Nan, Inf or huge value in
QACC"), which the campaign counts as a non-finite state.

The scene is s1-350's only diverging tree (the other two trees stay finite alone), rounded to 4 digits: a free 3.9 g
body with a 2.4 mm cylinder, a welded 258 g body, a 1.46 kg sphere of 5 mm on an unlimited hinge and a 9.8 g cylinder
on a limited hinge, thrown at 3 m/s and 4 rad/s at a plane 3.6 cm below. The model is valid: the compiler accepts it,
every mass is positive, every diagonal inertia satisfies the triangle inequality (the compiler checks it). After the
first contact (t = 0.04 s) the bodies spin at over 200 rad/s (measured in the converged runs below), more than 1 rad
per 5 ms step. Runs: the default Euler, implicit and RK4 integrators at 5 ms, Euler at 0.5 and 0.1 ms; measured: when
MuJoCo's BADQACC warning first fires, the fastest body rotation of a finite run, and its mechanical energy at 2.725 s
(the scene's duration). Right: the run finite and its energy at most the initial 9.0 J (a passive system). Measured on
3.17.0: Euler at 5 ms resets at 0.185 s (as the campaign saw), implicit at 5 ms stays finite but ends with 1.3 kJ
created, Euler at 0.5 ms still resets (later, at 0.89 s), while RK4 at 5 ms and Euler at 0.1 ms stay finite and agree
on the end energy (0.08 J): the state diverges only while the step is coarse for the motion. (The unrounded
campaign scene: the implicit integrator also resets, at 1.18 s, and Euler at 0.5 ms stays finite.) Exit 1 while the
flagged configuration (Euler, 5 ms) goes non-finite, 2 when Euler at 0.1 ms does too (then the step does not explain
it), 0 otherwise.

    python bench/rediscovery/mujoco/coarse_step_spin.py
"""
import sys

import mujoco
import numpy as np

DURATION = 2.725  # s, the scene's
CONTACT = ' friction="1 0.005 0.0001" contype="1" conaffinity="14"'
MODEL = """<mujoco>
 <compiler angle="radian" inertiafromgeom="false"/>
 <option timestep="{dt}" integrator="{integrator}" gravity="0 0 -9.81"/>
 <worldbody>
  <geom type="plane" size="100 100 0.1" contype="15" conaffinity="15"/>
  <body name="b0" pos="-0.004741 0.004269 0.03614">
   <freejoint/>
   <inertial pos="0 0 0" mass="0.00391" diaginertia="3.921e-08 3.981e-08 8.463e-09"/>
   <geom type="cylinder" size="0.0024 0.005425" quat="0.4068 -0.5187 -0.4126 0.6287"{c}/>
   <body name="b1" pos="0.002218 -0.007248 0.005814">
    <inertial pos="0 0 0" mass="0.258" diaginertia="2.011e-06 1.166e-06 2.189e-06"/>
    <geom type="cylinder" size="0.002482 0.003796" quat="0.7539 -0.3006 -0.01311 -0.584"{c}/>
    <geom type="capsule" size="0.001459 0.002029" pos="-0.003133 0.0009118 0.004474"{c}/>
   </body>
   <body name="b2" pos="-0.009785 0.003575 -0.006988" quat="-0.3564 -0.3433 0.7143 0.4948">
    <joint name="j2" type="hinge" pos="0.004892 -0.001788 0.003494" axis="0.1197 0.839 0.5308" limited="false"/>
    <inertial pos="0 0 0" mass="1.459" diaginertia="2.312e-05 2.414e-05 2.736e-05"/>
    <geom type="sphere" size="0.005232" friction="0.9507 0.005 0.0001" contype="1" conaffinity="14"/>
   </body>
   <body name="b3" pos="-0.007975 -0.004571 0.006583" quat="-0.287 0.8439 -0.4033 0.207">
    <joint name="j3" type="hinge" pos="0.003988 0.002286 -0.003291" axis="-0.3006 -0.698 -0.65" limited="true"
     range="0.3527 1.553"/>
    <inertial pos="0 0 0" mass="0.009773" diaginertia="2.31e-08 3.958e-08 3.426e-08"/>
    <geom type="cylinder" size="0.00224 0.003773"{c}/>
   </body>
  </body>
 </worldbody>
</mujoco>"""
# Initial state: the free body's linear velocity (world) and angular velocity (body frame = world: its orientation is
# the identity), the hinges' angles.
LINVEL, ANGVEL = [1.994, 2.334, -0.5385], [-2.432, 2.048, -3.076]
HINGES = {"j2": -0.07505, "j3": 1.2038}


def run(dt, integrator):
    """(time of the first BADQACC reset or None, largest body angular speed, end energy, initial energy)."""
    m = mujoco.MjModel.from_xml_string(MODEL.format(dt=dt, integrator=integrator, c=CONTACT))
    d = mujoco.MjData(m)
    d.qvel[0:3], d.qvel[3:6] = LINVEL, ANGVEL
    for name, q in HINGES.items():
        d.qpos[m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)]] = q
    mujoco.mj_forward(m, d)
    mujoco.mj_energyPos(m, d)
    mujoco.mj_energyVel(m, d)
    e0 = float(d.energy.sum())
    res, spin = np.zeros(6), 0.0
    for k in range(int(round(DURATION / dt))):
        mujoco.mj_step(m, d)
        if d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0:
            return (k + 1) * dt, spin, None, e0
        for b in range(1, m.nbody):
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, res, 0)
            spin = max(spin, float(np.linalg.norm(res[:3])))
    mujoco.mj_energyPos(m, d)
    mujoco.mj_energyVel(m, d)
    return None, spin, float(d.energy.sum()), e0


if __name__ == "__main__":
    out = {}
    for dt, integrator in [(0.005, "Euler"), (0.005, "implicit"), (0.005, "RK4"), (0.0005, "Euler"), (0.0001, "Euler")]:
        bad, spin, end, e0 = run(dt, integrator)
        out[(dt, integrator)] = bad
        if bad is not None:
            print("{:<9} dt {:6.4f} s: non-finite (MuJoCo's reset) at t = {:.4f} s".format(integrator, dt, bad))
        else:
            print("{:<9} dt {:6.4f} s: finite; fastest body rotation {:5.0f} rad/s ({:.2f} rad per 5 ms); energy "
                  "{:.2f} J at the end (initial {:.2f} J)".format(integrator, dt, spin, spin * 0.005, end, e0))
    sys.exit(2 if out[(0.0001, "Euler")] is not None else 1 if out[(0.005, "Euler")] is not None else 0)
