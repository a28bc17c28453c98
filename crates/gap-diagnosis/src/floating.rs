//! The floating-base plant: the robot standing or walking on flat ground, for logs of a robot that is not on the
//! suspension rig. A window starts from a base state *estimated from the log sample* (the robot does not log its
//! pelvis position or linear velocity), then replays the logged commands through MuJoCo with ground contact and the
//! same actuator/sensor effect layer as the rig ([`crate::plant::actuator_torques`]).
//!
//! Base-state estimate from one LowState sample (assumptions stated once):
//! * orientation and angular velocity: the torso IMU brought to the pelvis through the joint kinematics
//!   ([`crate::plant::imu_site_relative`]), after removing the IMU effects (misalignment, gyro bias) in `fx`;
//! * height: the ground is the plane z = 0 and the robot's lowest collision point touches it (the lowest sole);
//! * stance: a foot whose lowest point is within [`STANCE_BAND`] of the lowest foot's is in contact (weight falling
//!   linearly from 1 at the lowest to 0 at the band's edge);
//! * linear velocity: the lowest point of every stance foot is stationary (a flat foot, or the heel or toe edge it
//!   rolls on), so the pelvis moves opposite to that point's motion relative to the pelvis (leg kinematics,
//!   measured joint speeds); weighted mean over stance feet;
//! * horizontal position and heading are free on flat ground: x = y = 0, heading as the IMU reports it.
use crate::log::{Command, Measurement, RobotLog};
use crate::noise::{SIGMA_DQ, SIGMA_GYRO, SIGMA_Q, SIGMA_QUAT, SIGMA_TAU_FRAC};
use crate::plant::{
    actuator_torques, idle_command, imu_reading_floating, imu_site_relative, joint_groups, replay_window, sensed,
    true_joint_angles, Effects, EngineChoice, DT,
};
use crate::GapError;
use diff_physics::mujoco::{MujocoEngine, MujocoSettings};
use diff_physics::{CommonSettings, Engine, State};
use nalgebra::{Point3, Quaternion, UnitQuaternion, Vector3};
use robot_model::{GenCoords, RobotModel, Shape};
use serde::{Deserialize, Serialize};

/// A foot whose lowest point is at most this far above the lowest foot's counts as in contact (m).
pub const STANCE_BAND: f64 = 0.005;

/// Pelvis state in the engine conventions (`diff_physics::engine`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BaseState {
    /// Pelvis origin, world frame (m).
    pub pos: [f64; 3],
    /// `[w, x, y, z]`, pelvis-to-world.
    pub quat: [f64; 4],
    /// Velocity of the pelvis origin, world frame (m/s).
    pub lin_vel: [f64; 3],
    /// Angular velocity, pelvis frame (rad/s).
    pub ang_vel: [f64; 3],
}

impl BaseState {
    /// The base part of an engine state.
    pub fn of(s: &State) -> Self {
        BaseState { pos: s.base_pos, quat: s.base_quat, lin_vel: s.base_lin_vel, ang_vel: s.base_ang_vel }
    }
}

/// A base-state estimate with what it was derived from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseEstimate {
    pub base: BaseState,
    /// Feet taken as in contact (left, right).
    pub stance: [bool; 2],
    /// Height of each foot's lowest point above the ground (m).
    pub sole_height: [f64; 2],
    /// No foot in contact now was off the ground within [`SETTLE_S`] before: the sample is not in a touchdown's
    /// transient, where soft-contact penetration and rebound break the stationary-foot assumption. Windows should
    /// start at settled samples.
    pub settled: bool,
}

/// Pelvis lower than this (m) means the robot is down (fell).
pub const FALLEN_HEIGHT: f64 = 0.6;
/// Pelvis tilted more than this from upright (rad) means the robot is down (fell).
pub const FALLEN_TILT: f64 = std::f64::consts::FRAC_PI_4;

/// Whether a pelvis at height `z` (m) with orientation `quat` (unit, `[w, x, y, z]`, pelvis-to-world) is down:
/// below [`FALLEN_HEIGHT`] or tilted beyond [`FALLEN_TILT`].
pub fn is_down(z: f64, quat: [f64; 4]) -> bool {
    z < FALLEN_HEIGHT || robot_model::tilt_from_vertical(quat) > FALLEN_TILT
}

/// Whether the robot is down at logged sample `m`, with the pelvis orientation from the torso IMU through the
/// waist and its height from the lowest collision point (as the base estimate takes them). The floating plant
/// models a robot on its feet; a window in which it is down is not diagnosed.
pub fn logged_down(model: &RobotModel, feet: &Feet, m: &Measurement, fx: &Effects) -> Result<bool, GapError> {
    let k = sample_kinematics(model, feet, m, fx)?;
    Ok(is_down(k.z, [k.rb.w, k.rb.i, k.rb.j, k.rb.k]))
}

/// The feet: the last link of each leg, and the points of its collision shapes that can touch the ground (box
/// corners; the bottom of other shapes at the zero pose), in the link frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Feet {
    pub links: [usize; 2],
    pub points: [Vec<Vector3<f64>>; 2],
}

impl Feet {
    /// The child link of the last joint of each leg group (the ankle roll link of the H1-2).
    pub fn of(model: &RobotModel) -> Result<Self, GapError> {
        let groups = joint_groups(model);
        let mut links = [0usize; 2];
        let mut points = [Vec::new(), Vec::new()];
        for side in 0..2 {
            let j = (0..model.nj()).rev().find(|&j| groups[j] == side).ok_or_else(|| {
                GapError::Input(format!("model {} has no {} leg", model.name, ["left", "right"][side]))
            })?;
            let link = model.joints[j].child_link;
            for c in &model.links[link].collisions {
                let local: Vec<Point3<f64>> = match c.shape {
                    Shape::Box { half_extents: h } => (0..8)
                        .map(|k| {
                            Point3::new(
                                if k & 1 == 0 { -h[0] } else { h[0] },
                                if k & 2 == 0 { -h[1] } else { h[1] },
                                if k & 4 == 0 { -h[2] } else { h[2] },
                            )
                        })
                        .collect(),
                    Shape::Sphere { radius } => vec![Point3::new(0.0, 0.0, -radius)],
                    Shape::Capsule { radius, half_length } => vec![Point3::new(0.0, 0.0, -half_length - radius)],
                    Shape::Cylinder { half_length, .. } => vec![Point3::new(0.0, 0.0, -half_length)],
                };
                points[side].extend(local.into_iter().map(|p| (c.origin * p).coords));
            }
            if points[side].is_empty() {
                return Err(GapError::Input(format!("foot link {} has no collision shape", model.links[link].name)));
            }
            links[side] = link;
        }
        Ok(Feet { links, points })
    }
}

fn unit_quat(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
}

/// Foot contact points relative to the pelvis origin, in the pelvis frame, at joint angles `q`.
fn foot_points_rel(model: &RobotModel, feet: &Feet, q: &[f64]) -> Result<[Vec<Vector3<f64>>; 2], GapError> {
    let fk = model
        .fk(&GenCoords { base_pos: [0.0; 3], base_quat: [1.0, 0.0, 0.0, 0.0], q: q.to_vec() })
        .map_err(GapError::from)?;
    Ok([0, 1]
        .map(|s| feet.points[s].iter().map(|p| (fk.link_poses[feet.links[s]] * Point3::from(*p)).coords).collect()))
}

/// What one sample says about the base and the feet.
struct SampleKinematics {
    rb: UnitQuaternion<f64>,
    w_world: Vector3<f64>,
    w_body: Vector3<f64>,
    z: f64,
    /// Each foot's lowest point relative to the pelvis (pelvis frame) and its velocity relative to the pelvis.
    contact: [(Vector3<f64>, Vector3<f64>); 2],
    height: [f64; 2],
}

fn sample_kinematics(
    model: &RobotModel,
    feet: &Feet,
    m: &Measurement,
    fx: &Effects,
) -> Result<SampleKinematics, GapError> {
    const EPS: f64 = 1e-6;
    let norm = m.quat.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !(norm.is_finite() && norm > 1e-6) {
        return Err(GapError::Log(format!("state at t = {}: IMU quaternion {:?} is not a rotation", m.t, m.quat)));
    }
    let q = true_joint_angles(m, fx);
    // Orientation: measured = R_pelvis · R_site · R_mis.
    let (site_rel, w_rel) = imu_site_relative(model, &q, &m.dq)?;
    let mis = UnitQuaternion::from_scaled_axis(Vector3::from(fx.imu_misalignment));
    let r_imu = unit_quat(m.quat);
    let rb = r_imu * mis.inverse() * site_rel.inverse();
    // Angular velocity: gyro = R_imuᵀ ω_world + bias, ω_world = R_pelvis (ω_pelvis + ω_rel).
    let w_world = r_imu * (Vector3::from(m.gyro) - Vector3::from(fx.imu_gyro_bias));
    let w_body = rb.inverse() * w_world - w_rel;
    // Height: the lowest collision point is on the ground.
    let low = model
        .lowest_point_z(&GenCoords { base_pos: [0.0; 3], base_quat: [rb.w, rb.i, rb.j, rb.k], q: q.clone() })
        .map_err(GapError::from)?;
    let z = -low;
    let p0 = foot_points_rel(model, feet, &q)?;
    let p1 = foot_points_rel(model, feet, &q.iter().zip(&m.dq).map(|(a, b)| a + b * EPS).collect::<Vec<_>>())?;
    let mut contact = [(Vector3::zeros(), Vector3::zeros()); 2];
    let mut height = [0.0; 2];
    for s in 0..2 {
        let zs: Vec<f64> = p0[s].iter().map(|p| (rb * p).z).collect();
        let k = (0..zs.len()).min_by(|&a, &b| zs[a].total_cmp(&zs[b])).unwrap_or(0);
        height[s] = z + zs.get(k).copied().unwrap_or(0.0);
        contact[s] = (p0[s][k], (p1[s][k] - p0[s][k]) / EPS);
    }
    Ok(SampleKinematics { rb, w_world, w_body, z, contact, height })
}

/// Stance weight of each foot from its lowest point's height: 1 for the lowest foot, falling linearly to 0 at
/// [`STANCE_BAND`] above it.
fn stance_weights(height: [f64; 2]) -> [f64; 2] {
    let floor = height[0].min(height[1]);
    height.map(|h| (1.0 - (h - floor) / STANCE_BAND).max(0.0))
}

fn combine(k: &SampleKinematics, weight: [f64; 2]) -> BaseEstimate {
    let (mut v, mut wsum) = (Vector3::zeros(), 0.0);
    for (&w, &(a, v_rel)) in weight.iter().zip(&k.contact) {
        if w > 0.0 {
            v -= (k.w_world.cross(&(k.rb * a)) + k.rb * v_rel) * w;
            wsum += w;
        }
    }
    if wsum > 0.0 {
        v /= wsum;
    }
    let rb = k.rb;
    BaseEstimate {
        base: BaseState {
            pos: [0.0, 0.0, k.z],
            quat: [rb.w, rb.i, rb.j, rb.k],
            lin_vel: v.into(),
            ang_vel: k.w_body.into(),
        },
        stance: weight.map(|w| w > 0.0),
        sole_height: k.height,
        settled: true,
    }
}

/// Estimates the pelvis state from one logged sample alone (see the module docs; without history, `settled` is
/// true). `fx` supplies the sensor effects to undo (encoder offset, IMU misalignment and gyro bias).
pub fn estimate_base(model: &RobotModel, feet: &Feet, m: &Measurement, fx: &Effects) -> Result<BaseEstimate, GapError> {
    let k = sample_kinematics(model, feet, m, fx)?;
    Ok(combine(&k, stance_weights(k.height)))
}

/// Times back (s) at which a foot must already have been in contact to enter the velocity estimate: a foot that
/// is landing (its heel within the band but still moving down) is left out.
pub const STANCE_HISTORY_S: [f64; 3] = [0.01, 0.02, 0.04];
/// Half-width (s) of the centred average of the linear velocity estimate.
pub const VELOCITY_AVERAGE_S: f64 = 0.01;
/// Duration (s) after a foot enters the stance band during which a sample is not [`BaseEstimate::settled`]: the
/// band is entered ~20 ms before the impact, and MuJoCo's soft contact takes ~0.1 s to push the landed foot back
/// out of the ground.
pub const SETTLE_S: f64 = 0.15;

/// Estimates the pelvis state at state sample `i` of `log`: as [`estimate_base`], with each foot's stance weight
/// the smallest of its weights now and at [`STANCE_HISTORY_S`] before (when no foot keeps a weight, the weights
/// of sample `i` alone), and [`BaseEstimate::settled`] from the contact history over [`SETTLE_S`].
pub fn estimate_base_at(
    model: &RobotModel,
    feet: &Feet,
    log: &RobotLog,
    i: usize,
    fx: &Effects,
) -> Result<BaseEstimate, GapError> {
    let (k, w, settled) = contact_history(model, feet, log, i, fx)?;
    let m = &log.states[i];
    let mut est = BaseEstimate { settled, ..combine(&k, w) };
    // The linear velocity is averaged over the samples within ±VELOCITY_AVERAGE_S (same stance weights): the
    // joint-speed noise of one sample, through a 1 m leg, is a few cm/s; the average has no lag to first order.
    let (mut v, mut n) = (Vector3::from(est.base.lin_vel), 1.0);
    let lo = log.states.partition_point(|s| s.t < m.t - VELOCITY_AVERAGE_S - 1e-9);
    let hi = log.states.partition_point(|s| s.t <= m.t + VELOCITY_AVERAGE_S + 1e-9);
    for s in log.states[lo..hi].iter().enumerate().filter(|(j, _)| lo + j != i).map(|(_, s)| s).take(64) {
        v += Vector3::from(combine(&sample_kinematics(model, feet, s, fx)?, w).base.lin_vel);
        n += 1.0;
    }
    est.base.lin_vel = (v / n).into();
    Ok(est)
}

/// Sample `i`'s kinematics, the feet's stance weights with their [`STANCE_HISTORY_S`] history, and whether the
/// sample is settled.
fn contact_history(
    model: &RobotModel,
    feet: &Feet,
    log: &RobotLog,
    i: usize,
    fx: &Effects,
) -> Result<(SampleKinematics, [f64; 2], bool), GapError> {
    let m = log
        .states
        .get(i)
        .ok_or_else(|| GapError::Input(format!("state {i} beyond the log's {} states", log.states.len())))?;
    let k = sample_kinematics(model, feet, m, fx)?;
    let now = stance_weights(k.height);
    let mut w = now;
    let mut settled = true;
    let mut back = STANCE_HISTORY_S.to_vec();
    back.extend((2..=5).map(|n| SETTLE_S * n as f64 / 5.0));
    for b in back {
        let j = log.states[..i].partition_point(|s| s.t <= m.t - b + 1e-9);
        let Some(past) = j.checked_sub(1).and_then(|j| log.states.get(j)) else {
            settled = false;
            continue;
        };
        let wp = stance_weights(sample_kinematics(model, feet, past, fx)?.height);
        if STANCE_HISTORY_S.contains(&b) {
            w = [w[0].min(wp[0]), w[1].min(wp[1])];
        }
        settled &= (0..2).all(|s| now[s] <= 0.0 || wp[s] > 0.0);
    }
    if w[0] + w[1] <= 0.0 {
        w = now;
    }
    Ok((k, w, settled))
}

/// The first settled sample in `from..until` ([`BaseEstimate::settled`]), where a window should start.
pub fn settled_start(
    model: &RobotModel,
    feet: &Feet,
    log: &RobotLog,
    fx: &Effects,
    from: usize,
    until: usize,
) -> Result<Option<usize>, GapError> {
    for i in from..until.min(log.states.len()) {
        if contact_history(model, feet, log, i, fx)?.2 {
            return Ok(Some(i));
        }
    }
    Ok(None)
}

/// The kinematic contact state at sample `i` (cheaper than [`estimate_base_at`]: no velocity): the feet in
/// stance (with their [`STANCE_HISTORY_S`] history) and whether the sample is [`BaseEstimate::settled`].
pub fn contact_state(
    model: &RobotModel,
    feet: &Feet,
    log: &RobotLog,
    i: usize,
    fx: &Effects,
) -> Result<([bool; 2], bool), GapError> {
    let (_, w, settled) = contact_history(model, feet, log, i, fx)?;
    Ok((w.map(|w| w > 0.0), settled))
}

/// MuJoCo with the ground and collisions, the rig's joint model (armature, damping, friction, limits) and the
/// shared actuator effect layer.
#[derive(Debug)]
pub struct FloatingPlant {
    engine: MujocoEngine,
    torque_limit: Vec<f64>,
    speed_limit: Vec<f64>,
    tau: Vec<f64>,
    rest_sink: f64,
}

impl FloatingPlant {
    /// Builds the plant for `model` (already carrying the model-level effects, [`Effects::apply_to_model`], which
    /// include the contact friction); `fx` supplies the contact time constant, the one engine-level effect.
    pub fn new(model: &RobotModel, choice: &EngineChoice, fx: &Effects) -> Result<Self, GapError> {
        let common = CommonSettings::default();
        let mut settings =
            MujocoSettings { integrator: choice.mujoco_integrator()?.to_string(), ..MujocoSettings::default() };
        if let Some(tc) = fx.contact_timeconst {
            if !(tc.is_finite() && tc >= 2.0 * DT) {
                return Err(GapError::Input(format!(
                    "contact time constant {tc} s must be at least two timesteps ({} s)",
                    2.0 * DT
                )));
            }
            settings.solref[0] = tc;
        }
        let engine = MujocoEngine::new(model, &common, &settings).map_err(GapError::from)?;
        let mut plant = FloatingPlant {
            engine,
            torque_limit: model.joints.iter().map(|j| j.torque_limit).collect(),
            speed_limit: model.joints.iter().map(|j| j.speed_limit).collect(),
            tau: vec![0.0; model.nj()],
            rest_sink: 0.0,
        };
        plant.rest_sink = plant.measure_rest_sink(model)?;
        Ok(plant)
    }

    /// How deep (m) the lowest point of the robot standing at rest sinks into this plant's soft ground: MuJoCo's
    /// contacts hold a penetration that depends on the contact parameters (to first order not on the load). A
    /// window whose start places the lowest point exactly at z = 0 would begin with the robot dropping by this much.
    pub fn rest_sink(&self) -> f64 {
        self.rest_sink
    }

    /// The sink for the feet in contact: [`FloatingPlant::rest_sink`] (both feet) scaled by the load per foot, i.e.
    /// doubled on one foot (MuJoCo's penetration grows with the load a contact carries: measured 0.7 mm on both
    /// feet, 1.5 mm on one, H1-2 with the default contact parameters).
    pub fn stance_sink(&self, stance: [bool; 2]) -> f64 {
        let feet = stance.iter().filter(|s| **s).count().max(1) as f64;
        self.rest_sink * 2.0 / feet
    }

    /// Stands the robot in its default pose (model gains) for 0.2 s; the mean depth over the last 0.1 s.
    fn measure_rest_sink(&mut self, model: &RobotModel) -> Result<f64, GapError> {
        let s0 = State::standing(model);
        self.reset(&BaseState::of(&s0), &s0.q, &s0.dq)?;
        let n = model.nj();
        let hold = Command {
            t: 0.0,
            q: model.default_q(),
            dq: vec![0.0; n],
            kp: model.joints.iter().map(|j| j.kp).collect(),
            kd: model.joints.iter().map(|j| j.kd).collect(),
            tau: vec![0.0; n],
        };
        let fx = Effects::none(n);
        let (mut depth, mut count) = (0.0, 0.0);
        for k in 0..100 {
            self.step(&hold, &fx)?;
            if k >= 50 {
                let low = model.lowest_point_z(&self.engine.state().coords()).map_err(GapError::from)?;
                depth -= low;
                count += 1.0;
            }
        }
        Ok(depth / count)
    }

    /// Sets the base state and the (true) joint angles and speeds.
    pub fn reset(&mut self, base: &BaseState, q: &[f64], dq: &[f64]) -> Result<(), GapError> {
        let s = State {
            base_pos: base.pos,
            base_quat: base.quat,
            q: q.to_vec(),
            base_lin_vel: base.lin_vel,
            base_ang_vel: base.ang_vel,
            dq: dq.to_vec(),
        };
        self.engine.reset(&s).map_err(GapError::from)
    }

    /// The whole (true) state.
    pub fn state(&self) -> State {
        self.engine.state()
    }

    /// One physics step through the effect layer; returns the motor torque (what `tau_est` reports).
    pub fn step(&mut self, cmd: &Command, fx: &Effects) -> Result<&[f64], GapError> {
        let s = self.engine.state();
        let joint_tau = actuator_torques(cmd, fx, &s.q, &s.dq, &self.torque_limit, &self.speed_limit, &mut self.tau);
        self.engine.step(&joint_tau).map_err(GapError::from)?;
        Ok(&self.tau)
    }

    /// What the sensors report at the current state: joints (with the encoder offset), last motor torque, IMU.
    fn measure(
        &self,
        model: &RobotModel,
        fx: &Effects,
        t: f64,
        tau: &[f64],
        with_imu: bool,
    ) -> Result<Measurement, GapError> {
        let s = self.engine.state();
        let imu = if with_imu {
            Some(imu_reading_floating(model, s.base_quat, s.base_ang_vel, &s.q, &s.dq, fx)?)
        } else {
            None
        };
        Ok(sensed(t, &s.q, s.dq, tau, imu, fx))
    }
}

/// The floating-base analogue of [`crate::plant::predict_window`]: the base state is estimated from the log
/// samples around `start` ([`estimate_base_at`]) and lowered by the plant's [`FloatingPlant::stance_sink`].
#[allow(clippy::too_many_arguments)]
pub fn predict_window(
    plant: &mut FloatingPlant,
    model: &RobotModel,
    feet: &Feet,
    log: &RobotLog,
    fx: &Effects,
    start: usize,
    len: usize,
    with_imu: bool,
) -> Result<Vec<Measurement>, GapError> {
    let est = estimate_base_at(model, feet, log, start, fx)?;
    let mut base = est.base;
    base.pos[2] -= plant.stance_sink(est.stance);
    predict_window_from(plant, model, log, fx, start, len, &base, with_imu)
}

/// As [`predict_window`] from a given base state (e.g. the reference engine's truth, to measure what the
/// estimate costs).
#[allow(clippy::too_many_arguments)]
pub fn predict_window_from(
    plant: &mut FloatingPlant,
    model: &RobotModel,
    log: &RobotLog,
    fx: &Effects,
    start: usize,
    len: usize,
    base: &BaseState,
    with_imu: bool,
) -> Result<Vec<Measurement>, GapError> {
    let s0 = log
        .states
        .get(start)
        .ok_or_else(|| GapError::Input(format!("window start {start} beyond the log's {} states", log.states.len())))?;
    let q0 = true_joint_angles(s0, fx);
    plant.reset(base, &q0, &s0.dq)?;
    let idle = idle_command(model, &q0);
    replay_window(
        plant,
        log,
        fx,
        start,
        len,
        &idle,
        |p, cmd| Ok(p.step(cmd, fx)?.to_vec()),
        |p, t, tau| p.measure(model, fx, t, tau, with_imu),
    )
}

/// Residual of one window (logged minus predicted), as RMS over samples and joints / axes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WindowResidual {
    /// Joint angle (rad).
    pub q: f64,
    /// Joint speed (rad/s).
    pub dq: f64,
    /// Motor torque (N·m).
    pub tau: f64,
    /// IMU orientation angle (rad).
    pub quat: f64,
    /// Gyroscope (rad/s).
    pub gyro: f64,
    /// The diagnosis' normalised score (its `SIGMA_*` units): mean over samples of the per-joint
    /// q/dq/tau terms summed over joints, plus the IMU terms.
    pub score: f64,
}

/// Residual of the predicted window `pred` against the log's states after `start`.
pub fn window_residual(model: &RobotModel, log: &RobotLog, start: usize, pred: &[Measurement]) -> WindowResidual {
    let nj = model.nj();
    let (mut q, mut dq, mut tau, mut qa, mut gy, mut score) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let mut n = 0.0;
    for (k, p) in pred.iter().enumerate() {
        let Some(m) = log.states.get(start + 1 + k) else { break };
        for j in 0..nj {
            let (eq, edq, et) = (m.q[j] - p.q[j], m.dq[j] - p.dq[j], m.tau[j] - p.tau[j]);
            q += eq * eq;
            dq += edq * edq;
            tau += et * et;
            let st = SIGMA_TAU_FRAC * model.joints[j].torque_limit;
            score += ((eq / SIGMA_Q).powi(2) + (edq / SIGMA_DQ).powi(2) + (et / st).powi(2)) / 3.0;
        }
        let a = diff_physics::engine::quat_angle(m.quat, p.quat);
        let g: f64 = (0..3).map(|i| (m.gyro[i] - p.gyro[i]).powi(2)).sum();
        qa += a * a;
        gy += g;
        score += ((a / SIGMA_QUAT).powi(2) + g / SIGMA_GYRO.powi(2)) / 6.0;
        n += 1.0;
    }
    let n = f64::max(n, 1.0);
    let nq = n * nj.max(1) as f64;
    WindowResidual {
        q: (q / nq).sqrt(),
        dq: (dq / nq).sqrt(),
        tau: (tau / nq).sqrt(),
        quat: (qa / n).sqrt(),
        gyro: (gy / (3.0 * n)).sqrt(),
        score: score / n,
    }
}
