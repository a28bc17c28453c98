//! The plant: a physics engine holding the robot on a suspension rig, plus an actuator/sensor effect layer applied
//! outside the engine (command latency, gain scaling, backlash dead band, torque saturation with a torque-speed
//! line, viscous and Coulomb/stiction friction, encoder offset, IMU bias and misalignment) and model-level effects
//! applied to a clone of the [`RobotModel`] before the engine is built (armature, link mass, link COM).
//!
//! Rig assumption (stated once): the pelvis is held by a stiff stand at a known pose high above the ground
//! ("suspended"), so the joint-level effects are identifiable without estimating the floating base. The stand is a
//! spring-damper on the pelvis (1e7 N/m, 1e6 N·m/rad) with weight feed-forward on a pelvis made 1000x heavier, applied
//! as an external base wrench (MuJoCo's `qfrc_applied`, or the other engines' own base force); the pelvis moves by
//! well under a millimetre.
use crate::log::{Command, Measurement, RobotLog};
use crate::GapError;
use diff_physics::mujoco::{MujocoEngine, MujocoSettings};
use diff_physics::suspension::Suspended;
use diff_physics::Engine;
use nalgebra::{UnitQuaternion, Vector3};
use robot_model::{GenCoords, RobotModel};

/// Physics timestep (s).
pub const DT: f64 = 0.002;
/// Pelvis position on the stand (m); the stand is defined once, in [`diff_physics::suspension`] (also `ulab sim --hang`).
pub const RIG_BASE_POS: [f64; 3] = diff_physics::suspension::BASE_POS;
/// Mass and inertia multiplier of the pelvis on the stand.
pub const RIG_PELVIS_SCALE: f64 = diff_physics::suspension::PELVIS_SCALE;
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

/// The engine of a plant: MuJoCo with one of its integrators (the diagnosing simulator, and the default reference
/// plant), or another engine on the suspension rig (a reference plant independent of MuJoCo: `ulab gap bench
/// --reference-engine`).
#[derive(Debug, Clone, PartialEq)]
pub enum EngineChoice {
    /// MuJoCo with this integrator (`implicitfast`, `RK4`, `Euler`, `implicit`).
    Mujoco { integrator: String },
    /// An engine that can hold the pelvis on the stand ([`diff_physics::Engine::set_base_wrench`]): Bullet, DART or
    /// Rapier multibody. Rig only (the floating plant's contact effects are MuJoCo's).
    Other(diff_physics::EngineKind),
}

impl EngineChoice {
    /// MuJoCo with this integrator.
    pub fn mujoco(integrator: &str) -> Self {
        EngineChoice::Mujoco { integrator: integrator.into() }
    }

    /// Parses `mujoco` (implicitfast), `mujoco-rk4`, `mujoco-euler`, `mujoco-implicit`, or `bullet`, `dart`,
    /// `rapier_multibody` (whether the engine is compiled in is checked when the plant is built).
    pub fn parse(s: &str) -> Result<Self, GapError> {
        let integrator = match s {
            "mujoco" | "mujoco-implicitfast" => "implicitfast",
            "mujoco-rk4" => "RK4",
            "mujoco-euler" => "Euler",
            "mujoco-implicit" => "implicit",
            other => {
                use diff_physics::EngineKind;
                return match EngineKind::parse(other) {
                    Some(kind @ (EngineKind::Bullet | EngineKind::Dart | EngineKind::RapierMultibody)) => {
                        Ok(EngineChoice::Other(kind))
                    }
                    Some(kind) => Err(GapError::Input(format!(
                        "engine {}: the plants need an engine that holds the pelvis on the rig by an external wrench \
                         (mujoco, mujoco-rk4, mujoco-euler, mujoco-implicit, bullet, dart, rapier_multibody); compare \
                         {} with MuJoCo with `ulab diff`",
                        kind.name(),
                        kind.name()
                    ))),
                    None => Err(GapError::Input(format!(
                        "unknown engine {other:?} (mujoco, mujoco-rk4, mujoco-euler, mujoco-implicit, bullet, dart, \
                         rapier_multibody)"
                    ))),
                };
            }
        };
        Ok(EngineChoice::mujoco(integrator))
    }

    /// Whether this is MuJoCo (the diagnosing simulator's engine, with any integrator).
    pub fn is_mujoco(&self) -> bool {
        matches!(self, EngineChoice::Mujoco { .. })
    }

    /// The name [`EngineChoice::parse`] reads.
    pub fn name(&self) -> String {
        match self {
            EngineChoice::Mujoco { integrator } if integrator == "implicitfast" => "mujoco".into(),
            EngineChoice::Mujoco { integrator } => format!("mujoco-{}", integrator.to_lowercase()),
            EngineChoice::Other(kind) => kind.name().into(),
        }
    }

    /// The MuJoCo integrator, for the diagnosing plants (which are MuJoCo); other engines are refused.
    pub fn mujoco_integrator(&self) -> Result<&str, GapError> {
        match self {
            EngineChoice::Mujoco { integrator } => Ok(integrator),
            EngineChoice::Other(kind) => Err(GapError::Input(format!(
                "engine {}: the diagnosing simulator is MuJoCo (the floating plant's contact effect is MuJoCo's \
                 solref, and the rig's window replay is tuned on it); {} serves as an independent reference plant \
                 (`ulab gap bench --reference-engine`, `ulab gap simulate --engine`)",
                kind.name(),
                kind.name()
            ))),
        }
    }
}

/// When the effect layer (PD law, friction, saturation) is evaluated within a control step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PdUpdate {
    /// Once per control step ([`DT`]), the torque held over its physics steps.
    PerControlStep,
    /// At every physics step, from that step's state.
    PerPhysicsStep,
}

/// How a plant integrates one control step of [`DT`]: `substeps` physics steps, the effect layer evaluated once
/// or at each. The diagnosing simulator takes one 2 ms step ([`Stepping::DIAGNOSING`]); another simulator (the
/// issue's ran 1 ms steps) or a robot whose drivers close the PD loop faster integrates the same commands
/// differently, which the numerics stage sizes by replaying with other steppings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stepping {
    /// Physics steps per control step (at least 1).
    pub substeps: u32,
    pub pd: PdUpdate,
}

impl Stepping {
    /// One physics step per control step.
    pub const DIAGNOSING: Stepping = Stepping { substeps: 1, pd: PdUpdate::PerPhysicsStep };

    /// `substeps` physics steps per control step, PD at each or held.
    pub fn new(substeps: u32, pd: PdUpdate) -> Result<Self, GapError> {
        if !(1..=64).contains(&substeps) {
            return Err(GapError::Input(format!(
                "{substeps} physics steps per {} ms control step (1 to 64)",
                DT * 1e3
            )));
        }
        Ok(Stepping { substeps, pd })
    }

    /// The physics timestep (s).
    pub fn timestep(&self) -> f64 {
        DT / f64::from(self.substeps.max(1))
    }

    /// How often the PD law is evaluated (s).
    pub fn pd_period(&self) -> f64 {
        match self.pd {
            PdUpdate::PerControlStep => DT,
            PdUpdate::PerPhysicsStep => self.timestep(),
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
    /// Foot-ground Coulomb friction coefficient (model-level; `None`: the model's value). Acts only in a plant with
    /// ground contact ([`crate::floating::FloatingPlant`]).
    #[serde(default)]
    pub contact_friction: Option<f64>,
    /// Foot-ground contact time constant (s), MuJoCo's `solref[0]`: larger is softer (engine-level; `None`: the
    /// engine's default). Acts only in a plant with ground contact.
    #[serde(default)]
    pub contact_timeconst: Option<f64>,
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
            contact_friction: None,
            contact_timeconst: None,
        }
    }

    /// Whether the model-level parts differ from `other` (then a new engine is needed).
    pub fn same_model(&self, other: &Effects) -> bool {
        self.armature_scale == other.armature_scale
            && self.mass_scale == other.mass_scale
            && self.com_shift == other.com_shift
            && self.contact_friction == other.contact_friction
            && self.contact_timeconst == other.contact_timeconst
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
        if let Some(mu) = self.contact_friction {
            m.contact.friction = mu;
        }
        m
    }
}

/// A physics engine with the robot on the suspension rig ([`diff_physics::suspension`]): MuJoCo for the diagnosis
/// ([`Rig::new`], stepped on worker threads), or any engine that can hold the pelvis for a reference plant
/// ([`Rig::reference`]).
#[derive(Debug)]
pub struct Rig<E: Engine + ?Sized = MujocoEngine> {
    engine: Suspended<E>,
    stepping: Stepping,
    torque_limit: Vec<f64>,
    speed_limit: Vec<f64>,
    tau: Vec<f64>,
}

impl Rig<MujocoEngine> {
    /// The diagnosing rig for `model` (already carrying the model-level effects): MuJoCo with the choice's
    /// integrator, stepped as `stepping` says.
    pub fn new(model: &RobotModel, choice: &EngineChoice, stepping: Stepping) -> Result<Self, GapError> {
        Ok(Rig::around(mujoco_on_stand(model, choice.mujoco_integrator()?, stepping)?, model, stepping))
    }
}

/// MuJoCo with `integrator` holding `model` on the stand.
fn mujoco_on_stand(
    model: &RobotModel,
    integrator: &str,
    stepping: Stepping,
) -> Result<Suspended<MujocoEngine>, GapError> {
    let settings = MujocoSettings { integrator: integrator.to_string(), ..MujocoSettings::default() };
    Suspended::new(model, stepping.timestep(), &settings).map_err(GapError::from)
}

impl Rig<dyn Engine> {
    /// A reference rig in any engine of [`EngineChoice`] (MuJoCo with its integrator, Bullet, DART, Rapier).
    pub fn reference(model: &RobotModel, choice: &EngineChoice, stepping: Stepping) -> Result<Self, GapError> {
        let engine: Suspended = match choice {
            EngineChoice::Mujoco { integrator } => mujoco_on_stand(model, integrator, stepping)?.into_dyn(),
            EngineChoice::Other(kind) => {
                Suspended::with_engine(*kind, model, stepping.timestep()).map_err(GapError::from)?
            }
        };
        Ok(Rig::around(engine, model, stepping))
    }
}

impl<E: Engine + ?Sized> Rig<E> {
    fn around(engine: Suspended<E>, model: &RobotModel, stepping: Stepping) -> Self {
        Rig {
            engine,
            stepping,
            torque_limit: model.joints.iter().map(|j| j.torque_limit).collect(),
            speed_limit: model.joints.iter().map(|j| j.speed_limit).collect(),
            tau: vec![0.0; model.nj()],
        }
    }

    /// Puts the robot on the stand with these joint angles and speeds (true, not measured, values).
    pub fn reset(&mut self, q: &[f64], dq: &[f64]) -> Result<(), GapError> {
        let s = diff_physics::suspension::state_on_stand(q, dq);
        self.engine.reset(&s).map_err(GapError::from)
    }

    /// Joint angles and speeds (true values).
    pub fn joints(&self) -> (Vec<f64>, Vec<f64>) {
        let s = self.engine.state();
        (s.q, s.dq)
    }

    /// Pelvis position and orientation (`[w, x, y, z]`) on the stand, to check that the stand holds.
    pub fn pelvis(&self) -> ([f64; 3], [f64; 4]) {
        let s = self.engine.state();
        (s.base_pos, s.base_quat)
    }

    /// One control step of [`DT`] (its physics steps as the rig's [`Stepping`] says): the effect layer turns `cmd`
    /// into joint torques; returns the last motor torque (what `tau_est` reports).
    pub fn step(&mut self, cmd: &Command, fx: &Effects) -> Result<&[f64], GapError> {
        self.step_disturbed(cmd, fx, &[])
    }

    /// [`Rig::step`] with `disturbance` (N·m per joint; missing joints: none) added to the joint torques but not to
    /// the motor torque: a torque the actuator does not know of (a benchmark's effect outside the library).
    pub fn step_disturbed(&mut self, cmd: &Command, fx: &Effects, disturbance: &[f64]) -> Result<&[f64], GapError> {
        let mut joint_tau = Vec::new();
        for k in 0..self.stepping.substeps.max(1) {
            if k == 0 || self.stepping.pd == PdUpdate::PerPhysicsStep {
                let s = self.engine.state();
                joint_tau =
                    actuator_torques(cmd, fx, &s.q, &s.dq, &self.torque_limit, &self.speed_limit, &mut self.tau);
                joint_tau.iter_mut().zip(disturbance).for_each(|(t, d)| *t += d);
            }
            self.engine.step(&joint_tau).map_err(GapError::from)?;
        }
        Ok(&self.tau)
    }

    /// The torque limit of every joint (N·m).
    pub fn torque_limits(&self) -> &[f64] {
        &self.torque_limit
    }
}

/// The actuator effect layer, one definition for every plant (the suspension [`Rig`] and
/// [`crate::floating::FloatingPlant`]): the PD law on the encoder reading (encoder offset) with scaled gains and a
/// backlash dead band on the position error, clamped to the torque limit (scaled, with the torque-speed line, when
/// `torque_scale` is not 1). The result is the motor torque, written to `motor` (what `tau_est` reports); the
/// returned joint torque is that minus the extra viscous damping and Coulomb friction with stiction. `q`, `dq` are
/// the true joint state; command latency is applied by the caller when it picks the command.
pub fn actuator_torques(
    cmd: &Command,
    fx: &Effects,
    q: &[f64],
    dq: &[f64],
    torque_limit: &[f64],
    speed_limit: &[f64],
    motor: &mut [f64],
) -> Vec<f64> {
    for j in 0..motor.len() {
        let qm = q[j] + fx.encoder_offset[j];
        let g = fx.gain_scale[j];
        let mut e = cmd.q[j] - qm;
        let half = 0.5 * fx.backlash[j];
        e = if e > half {
            e - half
        } else if e < -half {
            e + half
        } else {
            0.0
        };
        let raw = cmd.tau[j] + g * cmd.kp[j] * e + g * cmd.kd[j] * (cmd.dq[j] - dq[j]);
        let mut lim = torque_limit[j];
        if fx.torque_scale[j] != 1.0 {
            let speed = (2.0 * (1.0 - dq[j].abs() / speed_limit[j])).clamp(0.0, 1.0);
            lim *= fx.torque_scale[j] * speed;
        }
        motor[j] = raw.clamp(-lim, lim);
    }
    let mut joint_tau = motor.to_vec();
    for (j, t) in joint_tau.iter_mut().enumerate() {
        let v = dq[j];
        let stiction = 1.0 + 0.5 * (-(v / (2.0 * COULOMB_EPS)).powi(2)).exp();
        *t -= fx.damping[j] * v + fx.coulomb[j] * stiction * (v / COULOMB_EPS).tanh();
    }
    joint_tau
}

/// Pose of the IMU site relative to the pelvis for joint angles `q`, and the site's angular velocity relative to the
/// pelvis for joint speeds `dq`, in the pelvis frame (finite difference of the kinematics). The one place of the
/// torso-IMU-to-pelvis kinematics: the IMU model below and the floating-base estimate
/// ([`crate::floating::estimate_base`]) both use it.
pub fn imu_site_relative(
    model: &RobotModel,
    q: &[f64],
    dq: &[f64],
) -> Result<(UnitQuaternion<f64>, Vector3<f64>), GapError> {
    const EPS: f64 = 1e-6;
    let [w, x, y, z] = model.imu.quat;
    let site = nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::from(Vector3::from(model.imu.pos)),
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z)),
    );
    let pose = |q: Vec<f64>| -> Result<nalgebra::Isometry3<f64>, GapError> {
        let c = GenCoords { base_pos: RIG_BASE_POS, base_quat: [1.0, 0.0, 0.0, 0.0], q };
        let fk = model.fk(&c).map_err(GapError::from)?;
        Ok(fk.link_poses[model.imu.link] * site)
    };
    let p0 = pose(q.to_vec())?;
    let p1 = pose(q.iter().zip(dq).map(|(a, b)| a + b * EPS).collect())?;
    let w_rel = (p1.rotation * p0.rotation.inverse()).scaled_axis() / EPS;
    Ok((p0.rotation, w_rel))
}

/// IMU reading on the torso for joint state `(q, dq)` with the pelvis on the stand: quaternion (IMU-to-world) and
/// gyroscope (IMU frame). Effects: misalignment then bias.
pub fn imu_reading(model: &RobotModel, q: &[f64], dq: &[f64], fx: &Effects) -> Result<([f64; 4], [f64; 3]), GapError> {
    let (rel, w_world) = imu_site_relative(model, q, dq)?;
    Ok(imu_from_site(rel, w_world, fx))
}

/// IMU reading for a free pelvis: orientation `base_quat` (`[w, x, y, z]`, pelvis-to-world) and angular velocity
/// `base_ang_vel` (pelvis frame), as [`imu_reading`] otherwise.
pub fn imu_reading_floating(
    model: &RobotModel,
    base_quat: [f64; 4],
    base_ang_vel: [f64; 3],
    q: &[f64],
    dq: &[f64],
    fx: &Effects,
) -> Result<([f64; 4], [f64; 3]), GapError> {
    let (rel, w_rel) = imu_site_relative(model, q, dq)?;
    let [w, x, y, z] = base_quat;
    let rb = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
    Ok(imu_from_site(rb * rel, rb * (Vector3::from(base_ang_vel) + w_rel), fx))
}

/// The IMU's sensor effects on the site's world orientation and world angular velocity: misalignment then bias.
fn imu_from_site(site_rot: UnitQuaternion<f64>, w_world: Vector3<f64>, fx: &Effects) -> ([f64; 4], [f64; 3]) {
    let mis = UnitQuaternion::from_scaled_axis(Vector3::from(fx.imu_misalignment));
    let r = site_rot * mis;
    let gyro = r.inverse() * w_world + Vector3::from(fx.imu_gyro_bias);
    ([r.w, r.i, r.j, r.k], gyro.into())
}

/// True joint angles behind a logged state: the encoder reading minus the encoder offset being fitted.
pub(crate) fn true_joint_angles(s: &Measurement, fx: &Effects) -> Vec<f64> {
    s.q.iter().zip(&fx.encoder_offset).map(|(q, o)| q - o).collect()
}

/// What the sensors report at time `t` for true joint state `(q, dq)`: encoder angles (offset added), speeds, the
/// last motor torque and the IMU reading (identity and zero when not simulated).
pub(crate) fn sensed(
    t: f64,
    q: &[f64],
    dq: Vec<f64>,
    tau: &[f64],
    imu: Option<([f64; 4], [f64; 3])>,
    fx: &Effects,
) -> Measurement {
    let (quat, gyro) = imu.unwrap_or(([1.0, 0.0, 0.0, 0.0], [0.0; 3]));
    Measurement {
        t,
        q: q.iter().zip(&fx.encoder_offset).map(|(q, o)| q + o).collect(),
        dq,
        tau: tau.to_vec(),
        quat,
        gyro,
        acc: [0.0; 3],
    }
}

/// Replays `log`'s commands from the measured state at state index `start` for `len` state samples; returns the
/// predicted measurements at those samples' times (what the sensors would report).
pub fn predict_window<E: Engine + ?Sized>(
    rig: &mut Rig<E>,
    model: &RobotModel,
    log: &RobotLog,
    fx: &Effects,
    start: usize,
    len: usize,
    with_imu: bool,
) -> Result<Vec<Measurement>, GapError> {
    let s0 = &log.states[start];
    let q0 = true_joint_angles(s0, fx);
    rig.reset(&q0, &s0.dq)?;
    replay_window(
        rig,
        log,
        fx,
        start,
        len,
        &idle_command(model, &q0),
        |rig, cmd| rig.step(cmd, fx).map(<[f64]>::to_vec),
        |rig, t, tau| {
            let (q, dq) = rig.joints();
            let imu = if with_imu { Some(imu_reading(model, &q, &dq, fx)?) } else { None };
            Ok(sensed(t, &q, dq, tau, imu, fx))
        },
    )
}

/// The replay loop every plant shares: from state sample `start`, steps `plant` (`step` returns the motor torque)
/// with the command in force `latency` earlier (or `idle` before the first command) up to each of the next `len`
/// state samples, and records `measure(plant, t, last motor torque)` there.
#[allow(clippy::too_many_arguments)]
pub(crate) fn replay_window<P>(
    plant: &mut P,
    log: &RobotLog,
    fx: &Effects,
    start: usize,
    len: usize,
    idle: &Command,
    mut step: impl FnMut(&mut P, &Command) -> Result<Vec<f64>, GapError>,
    mut measure: impl FnMut(&mut P, f64, &[f64]) -> Result<Measurement, GapError>,
) -> Result<Vec<Measurement>, GapError> {
    let s0 = log
        .states
        .get(start)
        .ok_or_else(|| GapError::Input(format!("window start {start} beyond the log's {} states", log.states.len())))?;
    let mut out = Vec::with_capacity(len);
    let mut t = s0.t;
    let mut last_tau = s0.tau.clone();
    let lat = fx.latency_steps as f64 * DT;
    for k in 1..=len {
        let Some(target) = log.states.get(start + k) else { break };
        let steps = ((target.t - t) / DT).round().max(0.0) as usize;
        for _ in 0..steps {
            let cmd = match log.command_at(t - lat + 1e-9) {
                Some(i) => &log.commands[i],
                None => idle,
            };
            last_tau = step(plant, cmd)?;
            t += DT;
        }
        out.push(measure(plant, target.t, &last_tau)?);
    }
    Ok(out)
}

/// Zero-gain command (before the first logged command).
pub fn idle_command(model: &RobotModel, q: &[f64]) -> Command {
    let n = model.nj();
    Command { t: 0.0, q: q.to_vec(), dq: vec![0.0; n], kp: vec![0.0; n], kd: vec![0.0; n], tau: vec![0.0; n] }
}
