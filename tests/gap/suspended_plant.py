"""A suspended H1-2 simulated by another program than ulab, for the gap diagnosis's tests: Unitree's published MuJoCo
model run by MuJoCo's official Python bindings, the pelvis fixed 2 m above the world (its free joint removed), a PD
law computed here as Unitree's MuJoCo bridge does, and the log written by the official Python `mcap` writer (zstd)
with Unitree hg messages serialized by Cyclone DDS's Python serializer. Nothing of ulab is imported.

    suspended_plant.py OUT.mcap [--timestep S] [--pd-every N] [--integrator NAME] [--duration S] [--cmd-rate HZ]
                       [--extra-damping|--extra-frictionloss|--extra-armature JOINT=VALUE]...
                       [--gain-scale JOINT=S]... [--encoder-offset JOINT=RAD]... [--load-friction JOINT=MU]...
                       [--torque-scale JOINT=S]...

The physics runs at `--timestep`; the PD torque is recomputed every `--pd-every` physics steps and held between;
commands arrive at `--cmd-rate` (chirps around the standing pose on every joint) and states are logged every 2 ms.
A hidden effect goes through MuJoCo's own joint parameters (damping, frictionloss, armature) or through the PD law
and the encoder (gain scale, offset) or clips the motor torque (`--torque-scale`, a plain clip at S times the limit:
no torque-speed line, unlike the diagnosis's saturation); `--load-friction` is a law outside the diagnosis's
library. Prints one JSON
object with what was simulated.
"""
import argparse
import json
import math
import os
import re
import sys
import types

# The unitree_sdk2py wheel imports a `b2` subpackage it does not ship.
sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from mcap.writer import Writer  # noqa: E402
from unitree_sdk2py.idl.default import unitree_hg_msg_dds__LowCmd_, unitree_hg_msg_dds__LowState_  # noqa: E402

LOWCMD = "unitree_hg::msg::dds_::LowCmd_"
LOWSTATE = "unitree_hg::msg::dds_::LowState_"
T0_NS = 1_700_000_000_000_000_000
STATE_PERIOD = 0.002
PELVIS_HEIGHT = 2.0

# Unitree's RL deploy gains for the H1-2 (legs per side, waist) and the SDK example's arm gains, in the model's
# hinge order: left leg, right leg, torso, left arm, right arm.
LEG_KP, LEG_KD = [200, 200, 200, 300, 40, 40], [2.5, 2.5, 2.5, 4, 2, 2]
ARM_KP, ARM_KD = [120, 120, 120, 80, 80, 80, 80], [2] * 7
KP = LEG_KP * 2 + [300] + ARM_KP * 2
KD = LEG_KD * 2 + [3] + ARM_KD * 2
# Standing pose (unitree_rl_gym's default leg angles), torso and arms at zero.
STAND = [0, -0.16, 0, 0.36, -0.2, 0] * 2 + [0] * 15
# Chirp amplitude (rad) per joint: hips and knee, ankles; torso; shoulders and elbow, wrists.
AMP = [0.3, 0.3, 0.2, 0.3, 0.15, 0.1] * 2 + [0.3] + [0.4, 0.3, 0.4, 0.4, 0.3, 0.3, 0.3] * 2


def suspended_model(path):
    """Unitree's MJCF without its meshes (not shipped; they carry no mass) and without the free joint, so the pelvis
    is welded to the world, raised above any ground."""
    xml = open(path).read()
    xml = re.sub(r"<asset>.*?</asset>", "", xml, flags=re.S)
    xml = re.sub(r"<geom[^>]*type=\"mesh\"[^>]*/>", "", xml)
    xml = re.sub(r"<joint[^>]*type=\"free\"[^>]*/>", "", xml)
    xml = re.sub(r"(<body name=\"pelvis\"[^>]*?)pos=\"[^\"]*\"", r'\1pos="0 0 %g"' % PELVIS_HEIGHT, xml, count=1)
    return mujoco.MjModel.from_xml_string(xml)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--timestep", type=float, default=0.001)
    ap.add_argument("--pd-every", type=int, default=1)
    ap.add_argument("--integrator", default="implicitfast", choices=["Euler", "RK4", "implicit", "implicitfast"])
    ap.add_argument("--duration", type=float, default=6.0)
    ap.add_argument("--cmd-rate", type=float, default=500.0)
    ap.add_argument("--extra-damping", action="append", default=[], metavar="JOINT=N*M*S",
                    help="add to a joint's damping (MuJoCo's dof_damping); repeatable")
    ap.add_argument("--extra-frictionloss", action="append", default=[], metavar="JOINT=N*M",
                    help="add to a joint's dry friction (MuJoCo's dof_frictionloss); repeatable")
    ap.add_argument("--extra-armature", action="append", default=[], metavar="JOINT=KG*M2",
                    help="add to a joint's armature (MuJoCo's dof_armature); repeatable")
    ap.add_argument("--gain-scale", action="append", default=[], metavar="JOINT=S",
                    help="scale the joint's kp and kd in the PD law (not in the logged command); repeatable")
    ap.add_argument("--encoder-offset", action="append", default=[], metavar="JOINT=RAD",
                    help="the joint's encoder reads this much more than the true angle (the PD law sees it too)")
    ap.add_argument("--load-friction", action="append", default=[], metavar="JOINT=MU",
                    help="a friction outside the diagnosis's library: MU times the motor torque's magnitude, against "
                         "the joint's motion, applied as a torque the motor does not report; repeatable")
    ap.add_argument("--torque-scale", action="append", default=[], metavar="JOINT=S",
                    help="the motor delivers at most S times the joint's torque limit (a plain clip, reported as "
                         "tau_est); repeatable")
    ap.add_argument("--shared", default=os.environ.get("ULAB_SHARED") or os.path.join(
        os.path.dirname(__file__), "../../../shared"))
    a = ap.parse_args()

    m = suspended_model(os.path.join(a.shared, "reference/h1_2/unitree_mujoco_h1_2_handless.xml"))
    m.opt.timestep = a.timestep
    m.opt.integrator = getattr(mujoco.mjtIntegrator, "mjINT_" + a.integrator.upper())
    effects = []
    engine_params = (("dof_damping", a.extra_damping), ("dof_frictionloss", a.extra_frictionloss),
                     ("dof_armature", a.extra_armature))
    for field, specs in engine_params:
        for spec in specs:
            name, value = spec.split("=")
            dof = m.jnt_dofadr[m.joint(name).id]
            getattr(m, field)[dof] += float(value)
            effects.append({"field": field, "joint": name, "added": float(value)})
    nj = m.njnt
    gain, offset, load_mu, torque_scale = np.ones(nj), np.zeros(nj), np.zeros(nj), np.ones(nj)
    for field, specs, arr in (("gain_scale", a.gain_scale, gain), ("encoder_offset", a.encoder_offset, offset),
                              ("load_friction", a.load_friction, load_mu),
                              ("torque_scale", a.torque_scale, torque_scale)):
        for spec in specs:
            name, value = spec.split("=")
            arr[m.joint(name).id] = float(value)
            effects.append({"field": field, "joint": name, "value": float(value)})
    d = mujoco.MjData(m)
    assert nj == 27 and m.nu == 27, (nj, m.nu)
    # Actuator k drives hinge k (the file's order); its ctrlrange is the motor's torque limit.
    act_joint = [int(m.actuator_trnid[k, 0]) for k in range(m.nu)]
    assert act_joint == list(range(nj)), act_joint
    lo, hi = m.jnt_range[:, 0], m.jnt_range[:, 1]
    tau_lim = m.actuator_ctrlrange[:, 1] * torque_scale
    d.qpos[:] = STAND
    mujoco.mj_forward(m, d)
    sens = {n: m.sensor(n).adr[0] for n in ("imu_quat", "imu_gyro", "imu_acc")}
    rng = np.random.default_rng(7)
    phase = rng.uniform(0, 2 * math.pi, nj)

    def target(t):
        # Frequency rises from 0.3 to 1.5 Hz over the log; each joint has its own phase.
        f0, f1 = 0.3, 1.5
        ph = 2 * math.pi * (f0 * t + 0.5 * (f1 - f0) * t * t / a.duration)
        q = [STAND[j] + AMP[j] * math.sin(ph + phase[j]) for j in range(nj)]
        return [min(max(q[j], lo[j] + 0.05), hi[j] - 0.05) for j in range(nj)]

    steps = int(round(a.duration / a.timestep))
    per_state = int(round(STATE_PERIOD / a.timestep))
    per_cmd = int(round(1.0 / (a.cmd_rate * a.timestep)))
    assert per_state >= 1 and per_cmd >= 1 and abs(per_state * a.timestep - STATE_PERIOD) < 1e-12
    with open(a.out, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="python mcap writer (ulab test plant)")
        ids = {}
        for topic, name in (("rt/lowcmd", LOWCMD), ("rt/lowstate", LOWSTATE)):
            sid = w.register_schema(name=name, encoding="omgidl", data=f"// {name}".encode())
            ids[topic] = w.register_channel(topic=topic, message_encoding="cdr", schema_id=sid)
        q_des = list(STAND)
        tau = np.zeros(nj)
        n_cmd = n_state = 0
        for i in range(steps):
            t = i * a.timestep
            if i % per_cmd == 0:
                q_des = target(t)
                c = unitree_hg_msg_dds__LowCmd_()
                for k in range(nj):
                    c.motor_cmd[k].mode = 1
                    c.motor_cmd[k].q = q_des[k]
                    c.motor_cmd[k].kp = float(KP[k])
                    c.motor_cmd[k].kd = float(KD[k])
                ns = T0_NS + int(round(t * 1e9))
                w.add_message(ids["rt/lowcmd"], log_time=ns, data=c.serialize(), publish_time=ns, sequence=n_cmd)
                n_cmd += 1
            if i % a.pd_every == 0:
                q_meas = d.qpos + offset
                tau = np.array([gain[k] * (KP[k] * (q_des[k] - q_meas[k]) - KD[k] * d.qvel[k]) for k in range(nj)])
                tau = np.clip(tau, -tau_lim, tau_lim)
                d.ctrl[:] = tau
            # Smooth sign (0.05 rad/s), so the plant stays an ODE.
            d.qfrc_applied[:] = -load_mu * np.abs(tau) * np.tanh(d.qvel / 0.05)
            mujoco.mj_step(m, d)
            if (i + 1) % per_state == 0:
                s = unitree_hg_msg_dds__LowState_()
                s.tick = n_state
                s.imu_state.quaternion = [float(x) for x in d.sensordata[sens["imu_quat"]:sens["imu_quat"] + 4]]
                s.imu_state.gyroscope = [float(x) for x in d.sensordata[sens["imu_gyro"]:sens["imu_gyro"] + 3]]
                s.imu_state.accelerometer = [float(x) for x in d.sensordata[sens["imu_acc"]:sens["imu_acc"] + 3]]
                for k in range(nj):
                    s.motor_state[k].mode = 1
                    s.motor_state[k].q = float(d.qpos[k] + offset[k])
                    s.motor_state[k].dq = float(d.qvel[k])
                    s.motor_state[k].tau_est = float(tau[k])
                ns = T0_NS + int(round((i + 1) * a.timestep * 1e9))
                w.add_message(ids["rt/lowstate"], log_time=ns, data=s.serialize(), publish_time=ns, sequence=n_state)
                n_state += 1
        w.finish()
    print(json.dumps({"path": a.out, "timestep": a.timestep, "pd_period": a.pd_every * a.timestep,
                      "integrator": a.integrator, "effects": effects, "commands": n_cmd, "states": n_state}))


if __name__ == "__main__":
    main()
