"""A suspended H1-2 simulated by another program than ulab, for the gap diagnosis's tests and its evaluation set:
Unitree's published MuJoCo model run by MuJoCo's official Python bindings, the pelvis fixed 2 m above the world (its
free joint removed), a PD law computed here as Unitree's MuJoCo bridge does, and the log written by the official
Python `mcap` writer (zstd) with Unitree hg messages serialized by Cyclone DDS's Python serializer. Nothing of ulab
is imported.

    suspended_plant.py OUT.mcap [--timestep S] [--pd-every N] [--integrator NAME] [--duration S] [--cmd-rate HZ]
                       [--plan PLAN.mcap] [--chirp-scale X] [--noise] [--seed N] [--state-stamp-offset S]
                       [--extra-damping|--extra-frictionloss|--extra-armature UNIT=VALUE]...
                       [--gain-scale UNIT=S]... [--encoder-offset UNIT=RAD]... [--torque-scale UNIT=S]...
                       [--backlash UNIT=RAD]... [--link-mass UNIT=S]... [--link-com UNIT=M]... [--latency-ms MS]
                       [--gyro-bias AXIS=RAD_S]... [--load-friction UNIT=MU]... [--torque-ripple UNIT=FRACTION]...

UNIT is a joint of Unitree's MJCF (`left_elbow_joint`) or a limb (`left_leg`, `right_leg`, `torso`, `left_arm`,
`right_arm`: every joint of it). The physics runs at `--timestep`; the PD torque is recomputed every `--pd-every`
physics steps and held between. Commands come from `--plan` (an MCAP of hg LowCmd on rt/lowcmd, such as `ulab gap
excite` writes; played at their log times, gains as given) or are chirps around the standing pose on every joint at
`--cmd-rate` (`--chirp-scale` scales their amplitude). States are logged every 2 ms, stamped with the physical time
they hold (`--state-stamp-offset` moves the stamps: a logging mistake, for the timing checks).

Hidden effects, each written here from its physical law:
- MuJoCo's own joint parameters: `--extra-damping` (N·m·s/rad), `--extra-frictionloss` (N·m, a hard Coulomb law),
  `--extra-armature` (kg·m², added to the model's 0.1);
- the drive: `--gain-scale` (kp and kd of the PD law, not of the logged command), `--encoder-offset` (the encoder,
  hence the log and the PD law, reads this much more than the true angle), `--torque-scale` (the motor delivers at
  most S times its limit: a plain clip, reported as tau_est), `--backlash` (the PD law sees no position error inside
  a band of that width, and the error beyond it minus half the band), `--latency-ms` (every command reaches the PD law
  this much after its stamp);
- the links: `--link-mass` (the joint's child body's mass and inertia times S), `--link-com` (its centre of mass moved
  along the body's z axis by M metres);
- the IMU: `--gyro-bias` (AXIS x|y|z, added to the logged gyroscope);
- outside the diagnosis's library: `--load-friction` (MU times the motor torque's magnitude against the motion, a
  torque the motor does not report), `--torque-ripple` (FRACTION of the torque limit times sin(8 q), periodic in the
  angle, against the motor).
`--noise` adds sensor noise of a real robot's size (q 2e-4 rad, dq 0.01 rad/s, tau 1 % of 1 N·m... per motor, gyro
0.002 rad/s). Prints one JSON object with what was simulated.
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
from mcap.reader import make_reader  # noqa: E402
from mcap.writer import Writer  # noqa: E402
from unitree_sdk2py.idl.default import unitree_hg_msg_dds__LowCmd_, unitree_hg_msg_dds__LowState_  # noqa: E402
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowCmd_  # noqa: E402

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
# The limbs, as hinge index ranges of the model.
LIMBS = {"left_leg": range(0, 6), "right_leg": range(6, 12), "torso": range(12, 13), "left_arm": range(13, 20),
         "right_arm": range(20, 27)}
# Sensor noise of `--noise` (standard deviations): joint angle, velocity, torque, gyroscope.
NOISE = {"q": 2e-4, "dq": 0.01, "tau": 0.1, "gyro": 0.002}


def suspended_model(path):
    """Unitree's MJCF without its meshes (not shipped; they carry no mass) and without the free joint, so the pelvis
    is welded to the world, raised above any ground."""
    xml = open(path).read()
    xml = re.sub(r"<asset>.*?</asset>", "", xml, flags=re.S)
    xml = re.sub(r"<geom[^>]*type=\"mesh\"[^>]*/>", "", xml)
    xml = re.sub(r"<joint[^>]*type=\"free\"[^>]*/>", "", xml)
    xml = re.sub(r"(<body name=\"pelvis\"[^>]*?)pos=\"[^\"]*\"", r'\1pos="0 0 %g"' % PELVIS_HEIGHT, xml, count=1)
    return mujoco.MjModel.from_xml_string(xml)


def units(m, spec):
    """The hinge ids of UNIT=VALUE's unit (a joint or a limb) and the value."""
    name, value = spec.split("=")
    if name in LIMBS:
        return list(LIMBS[name]), float(value)
    return [m.joint(name).id], float(value)


def plan_commands(path, nj):
    """(time s, q, dq, kp, kd, tau) of every LowCmd on rt/lowcmd of an MCAP, times from its first message."""
    out = []
    with open(path, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(topics=["rt/lowcmd"]):
            c = LowCmd_.deserialize(message.data)
            mc = c.motor_cmd[:nj]
            out.append((message.log_time, [x.q for x in mc], [x.dq for x in mc], [x.kp for x in mc],
                        [x.kd for x in mc], [x.tau for x in mc]))
    if not out:
        raise SystemExit(f"{path}: no LowCmd on rt/lowcmd")
    t0 = out[0][0]
    return [((t - t0) * 1e-9,) + tuple(rest) for (t, *rest) in out]


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--timestep", type=float, default=0.001)
    ap.add_argument("--pd-every", type=int, default=1)
    ap.add_argument("--integrator", default="implicitfast", choices=["Euler", "RK4", "implicit", "implicitfast"])
    ap.add_argument("--duration", type=float, default=6.0)
    ap.add_argument("--cmd-rate", type=float, default=500.0)
    ap.add_argument("--plan", help="MCAP of hg LowCmd on rt/lowcmd to play instead of the chirps")
    ap.add_argument("--chirp-scale", type=float, default=1.0, help="scale of the chirps' amplitude")
    ap.add_argument("--noise", action="store_true", help="sensor noise of a real robot's size")
    ap.add_argument("--seed", type=int, default=7, help="chirp phases and sensor noise")
    ap.add_argument("--state-stamp-offset", type=float, default=0.0,
                    help="seconds added to every LowState's stamp (negative: stamped before the time it holds)")
    for opt, what in (("--extra-damping", "add to the unit's damping (MuJoCo's dof_damping, N·m·s/rad)"),
                      ("--extra-frictionloss", "add to the unit's dry friction (MuJoCo's dof_frictionloss, N·m)"),
                      ("--extra-armature", "add to the unit's armature (MuJoCo's dof_armature, kg·m²)"),
                      ("--gain-scale", "scale kp and kd in the PD law (not in the logged command)"),
                      ("--encoder-offset", "the encoder reads this much more than the true angle (rad)"),
                      ("--torque-scale", "the motor delivers at most S times its torque limit (plain clip)"),
                      ("--backlash", "dead band of this width (rad) on the PD law's position error"),
                      ("--link-mass", "scale the mass and inertia of the joint's child body"),
                      ("--link-com", "move the child body's centre of mass along its z axis (m)"),
                      ("--load-friction", "MU x |motor torque| against the motion, not reported (outside the library)"),
                      ("--torque-ripple", "FRACTION x limit x sin(8 q) against the motor (outside the library)"),
                      ("--gyro-bias", "AXIS=RAD_S added to the logged gyroscope (x, y or z)")):
        ap.add_argument(opt, action="append", default=[], metavar="UNIT=VALUE", help=what + "; repeatable")
    ap.add_argument("--latency-ms", type=float, default=0.0, help="each command reaches the PD law this much late")
    ap.add_argument("--shared", default=os.environ.get("ULAB_SHARED") or os.path.join(
        os.path.dirname(__file__), "../../../shared"))
    a = ap.parse_args(argv)

    m = suspended_model(os.path.join(a.shared, "reference/h1_2/unitree_mujoco_h1_2_handless.xml"))
    m.opt.timestep = a.timestep
    m.opt.integrator = getattr(mujoco.mjtIntegrator, "mjINT_" + a.integrator.upper())
    nj = m.njnt
    assert nj == 27 and m.nu == 27, (nj, m.nu)
    effects = []
    for field, specs in (("dof_damping", a.extra_damping), ("dof_frictionloss", a.extra_frictionloss),
                         ("dof_armature", a.extra_armature)):
        for spec in specs:
            ids, value = units(m, spec)
            for j in ids:
                getattr(m, field)[m.jnt_dofadr[j]] += value
            effects.append({"field": field, "unit": spec.split("=")[0], "added": value})
    for spec in a.link_mass:
        ids, s = units(m, spec)
        for j in ids:
            b = m.jnt_bodyid[j]
            m.body_mass[b] *= s
            m.body_inertia[b] *= s
        effects.append({"field": "link_mass", "unit": spec.split("=")[0], "value": s})
    for spec in a.link_com:
        ids, dz = units(m, spec)
        for j in ids:
            # body_ipos is the centre of mass in the body frame; body_iquat turns the inertia's principal axes, not it.
            m.body_ipos[m.jnt_bodyid[j]][2] += dz
        effects.append({"field": "link_com", "unit": spec.split("=")[0], "value": dz})
    gain, offset, load_mu, torque_scale, band, ripple = (np.ones(nj), np.zeros(nj), np.zeros(nj), np.ones(nj),
                                                        np.zeros(nj), np.zeros(nj))
    for field, specs, arr in (("gain_scale", a.gain_scale, gain), ("encoder_offset", a.encoder_offset, offset),
                              ("load_friction", a.load_friction, load_mu),
                              ("torque_scale", a.torque_scale, torque_scale), ("backlash", a.backlash, band),
                              ("torque_ripple", a.torque_ripple, ripple)):
        for spec in specs:
            ids, value = units(m, spec)
            arr[ids] = value
            effects.append({"field": field, "unit": spec.split("=")[0], "value": value})
    gyro_bias = np.zeros(3)
    for spec in a.gyro_bias:
        axis, value = spec.split("=")
        gyro_bias["xyz".index(axis)] = float(value)
        effects.append({"field": "gyro_bias", "unit": axis, "value": float(value)})
    if a.latency_ms:
        effects.append({"field": "latency_ms", "value": a.latency_ms})
    # Derived quantities (subtree masses, the spring reference) follow the edited masses.
    d = mujoco.MjData(m)
    mujoco.mj_setConst(m, d)
    # Actuator k drives hinge k (the file's order); its ctrlrange is the motor's torque limit.
    act_joint = [int(m.actuator_trnid[k, 0]) for k in range(m.nu)]
    assert act_joint == list(range(nj)), act_joint
    lo, hi = m.jnt_range[:, 0], m.jnt_range[:, 1]
    limit = m.actuator_ctrlrange[:, 1].copy()
    tau_lim = limit * torque_scale
    d.qpos[:] = STAND
    mujoco.mj_forward(m, d)
    sens = {n: m.sensor(n).adr[0] for n in ("imu_quat", "imu_gyro", "imu_acc")}
    rng = np.random.default_rng(a.seed)
    phase = rng.uniform(0, 2 * math.pi, nj)

    def chirp(t):
        # Frequency rises from 0.3 to 1.5 Hz over the log; each joint has its own phase.
        f0, f1 = 0.3, 1.5
        ph = 2 * math.pi * (f0 * t + 0.5 * (f1 - f0) * t * t / a.duration)
        q = [STAND[j] + a.chirp_scale * AMP[j] * math.sin(ph + phase[j]) for j in range(nj)]
        return ([min(max(q[j], lo[j] + 0.05), hi[j] - 0.05) for j in range(nj)], [0.0] * nj, list(KP), list(KD),
                [0.0] * nj)

    steps = int(round(a.duration / a.timestep))
    per_state = int(round(STATE_PERIOD / a.timestep))
    per_cmd = int(round(1.0 / (a.cmd_rate * a.timestep)))
    assert per_state >= 1 and per_cmd >= 1 and abs(per_state * a.timestep - STATE_PERIOD) < 1e-12
    # Every command as (stamp, q, dq, kp, kd, tau), in stamp order.
    if a.plan:
        commands = [c for c in plan_commands(a.plan, nj) if c[0] < a.duration]
    else:
        commands = [(i * a.timestep,) + chirp(i * a.timestep) for i in range(0, steps, per_cmd)]
    latency = a.latency_ms * 1e-3
    with open(a.out, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="python mcap writer (ulab test plant)")
        ids = {}
        for topic, name in (("rt/lowcmd", LOWCMD), ("rt/lowstate", LOWSTATE)):
            sid = w.register_schema(name=name, encoding="omgidl", data=f"// {name}".encode())
            ids[topic] = w.register_channel(topic=topic, message_encoding="cdr", schema_id=sid)
        logged = applied = 0
        active = None
        tau = np.zeros(nj)
        n_state = 0
        eps = 1e-9
        for i in range(steps):
            t = i * a.timestep
            # Commands are logged when sent and reach the PD law `latency` later.
            while logged < len(commands) and commands[logged][0] <= t + eps:
                stamp, q, dq, kp, kd, tff = commands[logged]
                c = unitree_hg_msg_dds__LowCmd_()
                for k in range(nj):
                    mc = c.motor_cmd[k]
                    mc.mode, mc.q, mc.dq, mc.kp, mc.kd, mc.tau = 1, q[k], dq[k], kp[k], kd[k], tff[k]
                ns = T0_NS + int(round(stamp * 1e9))
                w.add_message(ids["rt/lowcmd"], log_time=ns, data=c.serialize(), publish_time=ns, sequence=logged)
                logged += 1
            while applied < len(commands) and commands[applied][0] + latency <= t + eps:
                active = commands[applied]
                applied += 1
            if i % a.pd_every == 0:
                q_meas = d.qpos + offset
                if active is None:
                    # Before the first command reaches the drive: hold the standing pose with the deploy gains.
                    q_des, dq_des, kp, kd, tff = STAND, [0.0] * nj, KP, KD, [0.0] * nj
                else:
                    _, q_des, dq_des, kp, kd, tff = active
                err = np.asarray(q_des) - q_meas
                err = np.sign(err) * np.maximum(np.abs(err) - 0.5 * band, 0.0)
                tau = np.asarray(tff) + gain * (np.asarray(kp) * err + np.asarray(kd) * (np.asarray(dq_des) - d.qvel))
                tau = np.clip(tau, -tau_lim, tau_lim)
                d.ctrl[:] = tau
            # Smooth sign (0.05 rad/s), so the plant stays an ODE.
            d.qfrc_applied[:] = (-load_mu * np.abs(tau) * np.tanh(d.qvel / 0.05)
                                 - ripple * limit * np.sin(8.0 * d.qpos))
            mujoco.mj_step(m, d)
            if (i + 1) % per_state == 0:
                s = unitree_hg_msg_dds__LowState_()
                s.tick = n_state
                noisy = (lambda x, sd: x + rng.normal(0.0, sd, np.shape(x))) if a.noise else (lambda x, sd: x)
                s.imu_state.quaternion = [float(x) for x in d.sensordata[sens["imu_quat"]:sens["imu_quat"] + 4]]
                gyro = noisy(d.sensordata[sens["imu_gyro"]:sens["imu_gyro"] + 3] + gyro_bias, NOISE["gyro"])
                s.imu_state.gyroscope = [float(x) for x in gyro]
                s.imu_state.accelerometer = [float(x) for x in d.sensordata[sens["imu_acc"]:sens["imu_acc"] + 3]]
                q_log = noisy(d.qpos + offset, NOISE["q"])
                dq_log = noisy(d.qvel, NOISE["dq"])
                tau_log = noisy(tau, NOISE["tau"])
                for k in range(nj):
                    ms = s.motor_state[k]
                    ms.mode, ms.q, ms.dq, ms.tau_est = 1, float(q_log[k]), float(dq_log[k]), float(tau_log[k])
                ns = T0_NS + int(round(((i + 1) * a.timestep + a.state_stamp_offset) * 1e9))
                w.add_message(ids["rt/lowstate"], log_time=ns, data=s.serialize(), publish_time=ns, sequence=n_state)
                n_state += 1
        w.finish()
    info = {"path": a.out, "timestep": a.timestep, "pd_period": a.pd_every * a.timestep, "integrator": a.integrator,
            "effects": effects, "commands": logged, "states": n_state}
    print(json.dumps(info))
    return info


if __name__ == "__main__":
    main()
