//! The plant: a physics engine holding the robot on a suspension rig, plus an actuator/sensor effect layer applied
//! outside the engine (command latency, gain scaling, backlash dead band, torque saturation with a torque-speed
//! line, viscous and Coulomb/stiction friction, encoder offset, IMU bias and misalignment) and model-level effects
//! applied to a clone of the [`RobotModel`] before the engine is built (armature, link mass, link COM).
//!
//! Rig assumption (stated once): the pelvis is held by a stiff stand at a known pose high above the ground
//! ("suspended"), so the joint-level effects are identifiable without estimating the floating base. The stand is a
//! spring-damper on the free joint (1e7 N/m, 1e6 N·m/rad) with weight feed-forward on a pelvis made 1000x heavier, applied through MuJoCo's
//! `qfrc_applied`; the pelvis moves by well under a millimetre.
use crate::log::{Command, Measurement, RobotLog};
use crate::GapError;
use diff_physics::mujoco::{MujocoEngine, MujocoSettings};
use diff_physics::{CommonSettings, Engine, State};
use nalgebra::{UnitQuaternion, Vector3};
use robot_model::{GenCoords, RobotModel};

/// Physics timestep (s).
pub const DT: f64 = 0.002;
/// Pelvis position on the stand (m).
pub const RIG_BASE_POS: [f64; 3] = [0.0, 0.0, 2.0];
/// Mass and inertia multiplier of the pelvis on the stand.
pub const RIG_PELVIS_SCALE: f64 = 1000.0;
/// Velocity scale of the smooth Coulomb law (rad/s): `tanh(dq / COULOMB_EPS)`.
pub const COULOMB_EPS: f64 = 0.05;

/// Joint groups (where a group parameter is physical: one actuator family / one limb).
pub const GROUPS: [&str; 5] = ["left_leg", "right_leg", "torso", "left_arm", "right_arm"];

/// Group index of every joint (model order), from the motor names.
pub fn joint_groups(model: &RobotModel) -> Vec<usize> {
    model
        .joints
        .iter()
        .map(|j| {
            let n = j.motor_name.to_lowercase();
            let leg = n.contains("hip") || n.contains("knee") || n.contains("ankle");
            match (n.starts_with("left"), n.starts_with("right"), leg) {
                (true, _, true) => 0,
                (_, true, true) => 1,
                (true, _, false) => 3,
                (_, true, false) => 4,
                _ => 2,
            }
        })
        .collect()
}

/// The engine variant of a plant.
#[derive(Debug, Clone, PartialEq)]
pub struct EngineChoice {
    /// MuJoCo integrator (`implicitfast`, `RK4`, `Euler`, `implicit`).
    pub integrator: String,
}

impl EngineChoice {
    /// Parses `mujoco` (implicitfast), `mujoco-rk4`, `mujoco-euler`, `mujoco-implicit`.
    pub fn parse(s: &str) -> Result<Self, GapError> {
        let integrator = match s {
            "mujoco" | "mujoco-implicitfast" => "implicitfast",
            "mujoco-rk4" => "RK4",
            "mujoco-euler" => "Euler",
            "mujoco-implicit" => "implicit",
            "rapier-multibody" | "rapier_multibody" | "rapier-impulse" | "rapier_impulse" => {
                return Err(GapError::Input(format!(
                    "engine {s}: the suspension rig needs an applied base wrench, which only the MuJoCo engine exposes; use mujoco, mujoco-rk4, mujoco-euler or mujoco-implicit"
                )))
            }
            other => return Err(GapError::Input(format!("unknown engine {other:?} (mujoco, mujoco-rk4, mujoco-euler, mujoco-implicit)"))),
        };
        Ok(EngineChoice { integrator: integrator.into() })
    }
    pub fn name(&self) -> String {
        match self.integrator.as_str() {
            "implicitfast" => "mujoco".into(),
            other => format!("mujoco-{}", other.to_lowercase()),
        }
    }
}

/// Every effect's parameters; the default is "no effect" (the baseline simulator).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Effects {
    /// Command latency in physics steps (2 ms each).
    pub latency_steps: usize,
    /// Multiplier of kp and kd, per joint.
    pub gain_scale: Vec<f64>,
    /// Available torque as a fraction of the nominal limit, with a torque-speed line (full torque up to half the
    /// speed limit, zero at the speed limit); 1 = nominal clamp only. Per joint.
    pub torque_scale: Vec<f64>,
    /// Extra viscous damping (N·m·s/rad), per joint (may be negative: less than modelled).
    pub damping: Vec<f64>,
    /// Extra Coulomb friction (N·m) with 50 % stiction overshoot near zero speed, per joint.
    pub coulomb: Vec<f64>,
    /// Backlash dead band width (rad) on the position error, per joint.
    pub backlash: Vec<f64>,
    /// Encoder offset (rad): measured = true + offset, per joint.
    pub encoder_offset: Vec<f64>,
    /// Gyroscope bias (rad/s), IMU frame.
    pub imu_gyro_bias: [f64; 3],
    /// IMU mounting misalignment (rotation vector, rad).
    pub imu_misalignment: [f64; 3],
    /// Armature multiplier, per joint (model-level).
    pub armature_scale: Vec<f64>,
    /// Mass (and inertia) multiplier of the links moved by each joint, per joint (model-level).
    pub mass_scale: Vec<f64>,
    /// COM shift along the link's z axis (m), per joint's child link (model-level).
    pub com_shift: Vec<f64>,
}

impl Effects {
    pub fn none(nj: usize) -> Self {
        Effects {
            latency_steps: 0,
            gain_scale: vec![1.0; nj],
            torque_scale: vec![1.0; nj],
            damping: vec![0.0; nj],
            coulomb: vec![0.0; nj],
            backlash: vec![0.0; nj],
            encoder_offset: vec![0.0; nj],
            imu_gyro_bias: [0.0; 3],
            imu_misalignment: [0.0; 3],
            armature_scale: vec![1.0; nj],
            mass_scale: vec![1.0; nj],
            com_shift: vec![0.0; nj],
        }
    }

    /// Whether the model-level parts differ from `other` (then a new engine is needed).
    pub fn same_model(&self, other: &Effects) -> bool {
        self.armature_scale == other.armature_scale && self.mass_scale == other.mass_scale && self.com_shift == other.com_shift
    }

    /// The robot model with the model-level effects applied.
    pub fn apply_to_model(&self, base: &RobotModel) -> RobotModel {
        let mut m = base.clone();
        for (j, joint) in m.joints.iter_mut().enumerate() {
            joint.armature *= self.armature_scale[j];
        }
        for j in 0..m.joints.len() {
            let link = m.joints[j].child_link;
            let l = &mut m.links[link];
            l.inertial.mass *= self.mass_scale[j];
            l.inertial.inertia *= self.mass_scale[j];
            l.inertial.com.z += self.com_shift[j];
        }
        m
    }
}

/// A physics engine with the robot on the suspension rig.
#[derive(Debug)]
pub struct Rig {
    engine: MujocoEngine,
    weight: f64,
    torque_limit: Vec<f64>,
    speed_limit: Vec<f64>,
    tau: Vec<f64>,
}

impl Rig {
    /// Builds the rig for `model` (already carrying the model-level effects).
    pub fn new(model: &RobotModel, choice: &EngineChoice) -> Result<Self, GapError> {
        let common = CommonSettings { ground: false, collisions: false, ..CommonSettings::default() };
        let settings = MujocoSettings { integrator: choice.integrator.clone(), ..MujocoSettings::default() };
        // The stand: the pelvis is made RIG_PELVIS_SCALE times heavier (a rigid mount), so the spring that holds it
        // can be stiff and still be integrated stably, and the limbs' reactions barely move it.
        let mut rigged = model.clone();
        if let Some(root) = rigged.links.iter_mut().find(|l| l.parent_joint.is_none()) {
            root.inertial.mass *= RIG_PELVIS_SCALE;
            root.inertial.inertia *= RIG_PELVIS_SCALE;
        }
        let engine = MujocoEngine::new(&rigged, &common, &settings).map_err(|e| GapError::Engine(e.to_string()))?;
        Ok(Rig {
            engine,
            weight: rigged.total_mass() * robot_model::GRAVITY_EARTH,
            torque_limit: model.joints.iter().map(|j| j.torque_limit).collect(),
            speed_limit: model.joints.iter().map(|j| j.speed_limit).collect(),
            tau: vec![0.0; model.nj()],
        })
    }

    /// Puts the robot on the stand with these joint angles and speeds (true, not measured, values).
    pub fn reset(&mut self, q: &[f64], dq: &[f64]) -> Result<(), GapError> {
        let s = State {
            base_pos: RIG_BASE_POS,
            base_quat: [1.0, 0.0, 0.0, 0.0],
            q: q.to_vec(),
            base_lin_vel: [0.0; 3],
            base_ang_vel: [0.0; 3],
            dq: dq.to_vec(),
        };
        self.engine.reset(&s).map_err(|e| GapError::Engine(e.to_string()))
    }

    /// Joint angles and speeds (true values).
    pub fn joints(&self) -> (Vec<f64>, Vec<f64>) {
        let s = self.engine.state();
        (s.q, s.dq)
    }

    /// One physics step: the effect layer turns `cmd` into joint torques; returns the motor torque (what
    /// `tau_est` reports).
    pub fn step(&mut self, cmd: &Command, fx: &Effects) -> Result<&[f64], GapError> {
        let s = self.engine.state();
        for j in 0..self.tau.len() {
            let qm = s.q[j] + fx.encoder_offset[j];
            let g = fx.gain_scale[j];
            let mut e = cmd.q[j] - qm;
            let half = 0.5 * fx.backlash[j];
            e = if e > half { e - half } else if e < -half { e + half } else { 0.0 };
            let raw = cmd.tau[j] + g * cmd.kp[j] * e + g * cmd.kd[j] * (cmd.dq[j] - s.dq[j]);
            let mut lim = self.torque_limit[j];
            if fx.torque_scale[j] != 1.0 {
                let speed = (2.0 * (1.0 - s.dq[j].abs() / self.speed_limit[j])).clamp(0.0, 1.0);
                lim *= fx.torque_scale[j] * speed;
            }
            self.tau[j] = raw.clamp(-lim, lim);
        }
        let mut joint_tau = self.tau.clone();
        for (j, t) in joint_tau.iter_mut().enumerate() {
            let v = s.dq[j];
            let stiction = 1.0 + 0.5 * (-(v / (2.0 * COULOMB_EPS)).powi(2)).exp();
            *t -= fx.damping[j] * v + fx.coulomb[j] * stiction * (v / COULOMB_EPS).tanh();
        }
        self.hold_base(&s);
        self.engine.step(&joint_tau).map_err(|e| GapError::Engine(e.to_string()))?;
        Ok(&self.tau)
    }

    fn hold_base(&mut self, s: &State) {
        const K: f64 = 1e7;
        const D: f64 = 1e5;
        const KR: f64 = 1e6;
        const DR: f64 = 3e3;
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(s.base_quat[0], s.base_quat[1], s.base_quat[2], s.base_quat[3]));
        let rotvec = q.scaled_axis(); // target orientation is identity
        let d = self.engine.raw_data();
        let f = d.qfrc_applied_mut();
        for k in 0..3 {
            f[k] = -K * (s.base_pos[k] - RIG_BASE_POS[k]) - D * s.base_lin_vel[k];
            // Rotational dofs are in the pelvis frame; rotvec is in the world frame (= pelvis frame to first order).
            f[3 + k] = -KR * rotvec[k] - DR * s.base_ang_vel[k];
        }
        f[2] += self.weight;
    }
}

/// IMU reading on the torso for joint state `(q, dq)` with the pelvis on the stand: quaternion (IMU-to-world) and
/// gyroscope (IMU frame). Effects: misalignment then bias.
pub fn imu_reading(model: &RobotModel, q: &[f64], dq: &[f64], fx: &Effects) -> Result<([f64; 4], [f64; 3]), GapError> {
    const EPS: f64 = 1e-6;
    let [w, x, y, z] = model.imu.quat;
    let site = nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::from(Vector3::from(model.imu.pos)),
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z)),
    );
    let pose = |q: Vec<f64>| -> Result<nalgebra::Isometry3<f64>, GapError> {
        let c = GenCoords { base_pos: RIG_BASE_POS, base_quat: [1.0, 0.0, 0.0, 0.0], q };
        let fk = model.fk(&c).map_err(|e| GapError::Engine(e.to_string()))?;
        Ok(fk.link_poses[model.imu.link] * site)
    };
    let p0 = pose(q.to_vec())?;
    let p1 = pose(q.iter().zip(dq).map(|(a, b)| a + b * EPS).collect())?;
    let w_world = (p1.rotation * p0.rotation.inverse()).scaled_axis() / EPS;
    let mis = UnitQuaternion::from_scaled_axis(Vector3::from(fx.imu_misalignment));
    let r = p0.rotation * mis;
    let gyro = r.inverse() * w_world + Vector3::from(fx.imu_gyro_bias);
    Ok(([r.w, r.i, r.j, r.k], gyro.into()))
}

/// Replays `log`'s commands from the measured state at state index `start` for `len` state samples; returns the
/// predicted measurements at those samples' times (what the sensors would report).
pub fn predict_window(
    rig: &mut Rig,
    model: &RobotModel,
    log: &RobotLog,
    fx: &Effects,
    start: usize,
    len: usize,
    with_imu: bool,
) -> Result<Vec<Measurement>, GapError> {
    let s0 = &log.states[start];
    let q0: Vec<f64> = s0.q.iter().zip(&fx.encoder_offset).map(|(q, o)| q - o).collect();
    rig.reset(&q0, &s0.dq)?;
    let mut out = Vec::with_capacity(len);
    let mut t = s0.t;
    let mut last_tau = s0.tau.clone();
    let lat = fx.latency_steps as f64 * DT;
    let idle = idle_command(model, &q0);
    for k in 1..=len {
        let Some(target) = log.states.get(start + k) else { break };
        let steps = ((target.t - t) / DT).round().max(0.0) as usize;
        for _ in 0..steps {
            let cmd = match log.command_at(t - lat + 1e-9) {
                Some(i) => &log.commands[i],
                None => &idle,
            };
            last_tau.copy_from_slice(rig.step(cmd, fx)?);
            t += DT;
        }
        let (q, dq) = rig.joints();
        let (quat, gyro) = if with_imu { imu_reading(model, &q, &dq, fx)? } else { ([1.0, 0.0, 0.0, 0.0], [0.0; 3]) };
        out.push(Measurement {
            t: target.t,
            q: q.iter().zip(&fx.encoder_offset).map(|(q, o)| q + o).collect(),
            dq,
            tau: last_tau.clone(),
            quat,
            gyro,
            acc: [0.0; 3],
        });
    }
    Ok(out)
}

/// Zero-gain command (before the first logged command).
fn idle_command(model: &RobotModel, q: &[f64]) -> Command {
    let n = model.nj();
    Command { t: 0.0, q: q.to_vec(), dq: vec![0.0; n], kp: vec![0.0; n], kd: vec![0.0; n], tau: vec![0.0; n] }
}
