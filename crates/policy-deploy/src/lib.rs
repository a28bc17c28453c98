//! A policy deployed as the robot's low-level controller, the way Unitree's deploy scripts run one: read
//! `LowState`, build the policy's observation (torso IMU brought to the pelvis through the waist joint), run the
//! policy at its own rate, and send `LowCmd` with PD targets and a sealed CRC at the command rate.
//!
//! [`Deployer`] holds no I/O: the caller feeds it every decoded `LowState` with its arrival time
//! ([`Deployer::on_state`]) and asks it for the command to send ([`Deployer::command`]), so that the same logic
//! runs over DDS (`ulab deploy`), in a test with synthetic states, or against a recording. Phases:
//! 1. [`Phase::WaitingForState`]: nothing is sent until a valid state arrives (a robot or simulator holding its
//!    pose keeps holding it);
//! 2. [`Phase::MovingToDefault`]: the joints move from where they are to the standing pose over
//!    [`DeployConfig::ramp_s`], with stiff leg gains (the policies' own ankle gains cannot hold a pose without the
//!    policy balancing it);
//! 3. [`Phase::Running`]: the policy's targets, clamped to the joint, velocity, torque and gain limits;
//! 4. [`Phase::Damping`]: a safety stop (stale or non-finite state, a policy error, a fall seen by the torso IMU
//!    while the policy runs, or a stop request): zero stiffness, damping only, until the caller stops sending.
#![forbid(unsafe_code)]

pub mod keyboard;

use diff_physics::PdTarget;
use lowlevel_codec::crc;
use policy_runtime::{Controller, RobotObservation};
use robot_model::RobotModel;
use serde::Serialize;
use thiserror::Error;
use unitree_idl::{h1_2, hg};

/// Leg gains while moving to the standing pose (the standing hold of `ulab sim` uses the same figures).
const STAND_LEG_KP: f64 = 500.0;
const STAND_LEG_KD: f64 = 5.0;
const STAND_ANKLE_KP: f64 = 600.0;
const STAND_ANKLE_KD: f64 = 10.0;
/// Smallest damping gain (N·m·s/rad) of the safety stop, whatever the model's gains.
const MIN_DAMPING_KD: f64 = 2.0;

/// Errors of setting up a deployment.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum DeployError {
    /// The model's joints do not fit the message layout this deployer writes.
    #[error("robot model: {0}")]
    Model(String),
    /// A setting out of range.
    #[error("deploy setting: {0}")]
    Setting(String),
}

/// Settings of a deployment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DeployConfig {
    /// Velocity command `(vx m/s, vy m/s, wz rad/s)` given to the policy.
    pub command: [f64; 3],
    /// Seconds to move from the pose found to the standing pose before the policy takes over.
    pub ramp_s: f64,
    /// A `LowState` older than this (s) when a command is due stops the policy (damping).
    pub stale_s: f64,
    /// While the policy runs, a torso tilt from vertical above this (rad, from the IMU quaternion) is a fall and
    /// stops it (damping); `None` switches the check off. The H1-2's waist turns about the vertical only, so the
    /// torso's tilt is the pelvis's. A walking policy stays within a few degrees; a robot past 40° does not recover.
    pub max_tilt_rad: Option<f64>,
}

/// Default fall threshold of [`DeployConfig::max_tilt_rad`]: 0.7 rad (40°).
pub const DEFAULT_MAX_TILT_RAD: f64 = 0.7;

impl Default for DeployConfig {
    fn default() -> Self {
        DeployConfig { command: [0.0; 3], ramp_s: 2.0, stale_s: 0.1, max_tilt_rad: Some(DEFAULT_MAX_TILT_RAD) }
    }
}

/// Where the deployment is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    WaitingForState,
    MovingToDefault,
    Running,
    Damping,
}

/// Why the deployment went to damping.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "reason", rename_all = "snake_case")]
#[non_exhaustive]
pub enum StopReason {
    /// No valid `LowState` for `age_s` seconds.
    StaleState { age_s: f64 },
    /// A `LowState` with a non-finite joint or IMU value (or an all-zero quaternion).
    NonFiniteState { field: String },
    /// The policy failed (its message).
    Policy { message: String },
    /// The torso tilted `tilt_rad` from vertical while the policy ran (more than [`DeployConfig::max_tilt_rad`]).
    Fallen { tilt_rad: f64 },
    /// The caller asked to stop (Ctrl-C, end of the run).
    Requested,
}

/// What the deployment has seen and done.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DeployCounters {
    /// `LowState` samples accepted.
    pub states: u64,
    /// `LowState` samples dropped for a CRC that does not match.
    pub bad_crc: u64,
    /// Commands produced (every one sealed).
    pub commands: u64,
    /// Policy steps.
    pub policy_steps: u64,
    /// Command values clamped to a limit (joint range, velocity, torque, gains). The shipped LSTM policy asks for
    /// ankle-roll targets beyond the joint range (±0.26 rad) while walking: most of its clamps are those.
    pub clamped: u64,
}

/// The latest accepted state, in model joint order.
#[derive(Debug, Clone)]
struct Latest {
    at: f64,
    q: Vec<f64>,
    dq: Vec<f64>,
    quat: [f64; 4],
    gyro: [f64; 3],
    mode_machine: u8,
}

/// The deployment's state machine (see the crate docs).
#[derive(Debug)]
pub struct Deployer {
    model: RobotModel,
    controller: Box<dyn Controller>,
    cfg: DeployConfig,
    phase: Phase,
    stop: Option<StopReason>,
    latest: Option<Latest>,
    phase_start: f64,
    ramp_from: Vec<f64>,
    target: PdTarget,
    next_policy: f64,
    counters: DeployCounters,
}

impl Deployer {
    /// A deployment of `controller` on `model` (an H1-2 layout: every joint's slot inside the hg message).
    pub fn new(model: RobotModel, mut controller: Box<dyn Controller>, cfg: DeployConfig) -> Result<Self, DeployError> {
        if let Some(j) = model.joints.iter().find(|j| j.slot >= h1_2::NUM_JOINTS) {
            return Err(DeployError::Model(format!(
                "joint {} has slot {} (H1-2 has {})",
                j.name,
                j.slot,
                h1_2::NUM_JOINTS
            )));
        }
        if !(cfg.ramp_s.is_finite() && cfg.ramp_s >= 0.0 && cfg.stale_s.is_finite() && cfg.stale_s > 0.0) {
            return Err(DeployError::Setting(format!("ramp {} s, stale limit {} s", cfg.ramp_s, cfg.stale_s)));
        }
        if let Some(t) = cfg.max_tilt_rad {
            if !(t.is_finite() && t > 0.0 && t < std::f64::consts::PI) {
                return Err(DeployError::Setting(format!("fall tilt limit {t} rad is not in (0, pi)")));
            }
        }
        if cfg.command.iter().any(|c| !c.is_finite()) {
            return Err(DeployError::Setting(format!("command {:?} is not finite", cfg.command)));
        }
        if !(controller.period().is_finite() && controller.period() > 0.0) {
            return Err(DeployError::Setting(format!("policy period {} s", controller.period())));
        }
        controller.reset();
        let target = PdTarget::hold_standing(&model);
        Ok(Deployer {
            ramp_from: model.default_q(),
            model,
            controller,
            cfg,
            phase: Phase::WaitingForState,
            stop: None,
            latest: None,
            phase_start: 0.0,
            target,
            next_policy: 0.0,
            counters: DeployCounters::default(),
        })
    }

    /// The current phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The velocity command `(vx, vy, wz)` the policy is given now.
    pub fn velocity_command(&self) -> [f64; 3] {
        self.cfg.command
    }

    /// Changes the velocity command (`--keyboard`); the policy sees it from its next step. A non-finite command is
    /// refused and the previous one stays.
    pub fn set_velocity_command(&mut self, command: [f64; 3]) -> Result<(), DeployError> {
        if command.iter().any(|c| !c.is_finite()) {
            return Err(DeployError::Setting(format!("command {command:?} is not finite")));
        }
        self.cfg.command = command;
        Ok(())
    }

    /// Why the deployment is damping, if it is.
    pub fn stop_reason(&self) -> Option<&StopReason> {
        self.stop.as_ref()
    }

    /// Counters so far.
    pub fn counters(&self) -> &DeployCounters {
        &self.counters
    }

    /// Goes to damping (idempotent: the first reason is kept).
    pub fn stop(&mut self, reason: StopReason) {
        if self.stop.is_none() {
            self.stop = Some(reason);
        }
        self.phase = Phase::Damping;
    }

    /// Takes a received `LowState` (arrival time `now`, seconds on the caller's clock). A sample whose CRC does not
    /// match is counted and dropped; one with a non-finite joint or IMU value stops the deployment.
    pub fn on_state(&mut self, state: &hg::LowState_, now: f64) {
        if !crc::verify(state) {
            self.counters.bad_crc += 1;
            return;
        }
        let f = |x: f32| f64::from(x);
        let (mut q, mut dq) = (Vec::with_capacity(self.model.nj()), Vec::with_capacity(self.model.nj()));
        for j in &self.model.joints {
            let m = &state.motor_state[j.slot];
            q.push(f(m.q));
            dq.push(f(m.dq));
        }
        let imu = &state.imu_state;
        let quat = imu.quaternion.map(f);
        let gyro = imu.gyroscope.map(f);
        let bad = if q.iter().any(|x| !x.is_finite()) {
            Some("motor_state.q")
        } else if dq.iter().any(|x| !x.is_finite()) {
            Some("motor_state.dq")
        } else if quat.iter().chain(&gyro).any(|x| !x.is_finite()) || quat.iter().all(|x| *x == 0.0) {
            Some("imu_state")
        } else {
            None
        };
        if let Some(field) = bad {
            self.stop(StopReason::NonFiniteState { field: field.into() });
            return;
        }
        self.counters.states += 1;
        self.latest = Some(Latest { at: now, q, dq, quat, gyro, mode_machine: state.mode_machine });
    }

    /// The command to send at `now`, CRC sealed; `None` while no valid state has arrived.
    pub fn command(&mut self, now: f64) -> Option<hg::LowCmd_> {
        let latest = self.latest.clone()?;
        if self.phase != Phase::Damping && now - latest.at > self.cfg.stale_s {
            self.stop(StopReason::StaleState { age_s: now - latest.at });
        }
        match self.phase {
            Phase::WaitingForState => {
                self.phase = Phase::MovingToDefault;
                self.phase_start = now;
                self.ramp_from = latest.q.clone();
                self.target = self.stand_target();
                self.moving_to_default(now);
            }
            Phase::MovingToDefault => self.moving_to_default(now),
            Phase::Running => {
                // The IMU's f32 quaternion is not exactly unit length (an all-zero one never gets here).
                let n = latest.quat.iter().map(|x| x * x).sum::<f64>().sqrt();
                let tilt = robot_model::tilt_from_vertical(latest.quat.map(|x| x / n));
                match self.cfg.max_tilt_rad {
                    Some(limit) if tilt > limit => self.stop(StopReason::Fallen { tilt_rad: tilt }),
                    _ => self.running(now, &latest),
                }
            }
            Phase::Damping => {}
        }
        let target = if self.phase == Phase::Damping { self.damping_target(&latest) } else { self.target.clone() };
        let mut cmd = self.encode(&target, latest.mode_machine);
        crc::seal(&mut cmd);
        self.counters.commands += 1;
        Some(cmd)
    }

    fn stand_target(&self) -> PdTarget {
        let mut t = PdTarget::hold_standing(&self.model);
        for (i, j) in self.model.joints.iter().enumerate() {
            let (kp, kd) = if j.name.contains("ankle") {
                (STAND_ANKLE_KP, STAND_ANKLE_KD)
            } else if j.name.contains("hip") || j.name.contains("knee") {
                (STAND_LEG_KP, STAND_LEG_KD)
            } else {
                continue;
            };
            t.kp[i] = t.kp[i].max(kp);
            t.kd[i] = t.kd[i].max(kd);
        }
        t
    }

    fn moving_to_default(&mut self, now: f64) {
        let w = if self.cfg.ramp_s > 0.0 { ((now - self.phase_start) / self.cfg.ramp_s).clamp(0.0, 1.0) } else { 1.0 };
        let goal = self.model.default_q();
        for (i, (from, to)) in self.ramp_from.iter().zip(&goal).enumerate() {
            self.target.q_des[i] = from + w * (to - from);
        }
        if w >= 1.0 {
            self.phase = Phase::Running;
            self.phase_start = now;
            self.next_policy = now;
        }
    }

    fn running(&mut self, now: f64, latest: &Latest) {
        if now + 1e-9 < self.next_policy {
            return;
        }
        let period = self.controller.period();
        // A caller that fell behind resumes on the next period instead of running the policy back to back.
        self.next_policy = if now - self.next_policy > period { now + period } else { self.next_policy + period };
        let obs = RobotObservation::from_torso_imu(
            now - self.phase_start,
            latest.quat,
            latest.gyro,
            latest.q.clone(),
            latest.dq.clone(),
            self.cfg.command,
        );
        match obs.and_then(|o| self.controller.act(&o)) {
            Ok(t) if t.q_des.len() == self.model.nj() => {
                self.target = t;
                self.counters.policy_steps += 1;
            }
            Ok(t) => self.stop(StopReason::Policy {
                message: format!("{} targets for {} joints", t.q_des.len(), self.model.nj()),
            }),
            Err(e) => self.stop(StopReason::Policy { message: e.to_string() }),
        }
    }

    /// Zero stiffness, the model's damping (at least [`MIN_DAMPING_KD`]), holding the current position as target.
    fn damping_target(&self, latest: &Latest) -> PdTarget {
        let mut t = PdTarget::hold_standing(&self.model);
        t.q_des = latest.q.clone();
        t.kp.iter_mut().for_each(|k| *k = 0.0);
        t.kd.iter_mut().for_each(|k| *k = k.max(MIN_DAMPING_KD));
        t
    }

    /// An hg `LowCmd` for every joint of the model (mode 1, PR mode), every value clamped to its limit.
    fn encode(&mut self, t: &PdTarget, mode_machine: u8) -> hg::LowCmd_ {
        let mut cmd = hg::LowCmd_ { mode_machine, ..Default::default() };
        let mut clamped = 0;
        let mut clamp = |x: f64, lo: f32, hi: f32| -> f32 {
            let v = if x.is_finite() { x as f32 } else { 0.0 };
            let c = v.clamp(lo, hi);
            if c != v || !x.is_finite() {
                clamped += 1;
            }
            c
        };
        for (i, joint) in self.model.joints.iter().enumerate() {
            let Some(limits) = h1_2::JOINTS.get(joint.slot) else { continue };
            let m = &mut cmd.motor_cmd[joint.slot];
            m.mode = 1;
            m.q = clamp(t.q_des[i], limits.lower, limits.upper);
            m.dq = clamp(t.dq_des[i], -limits.speed_limit, limits.speed_limit);
            m.tau = clamp(t.tau_ff[i], -limits.torque_limit, limits.torque_limit);
            m.kp = clamp(t.kp[i], 0.0, h1_2::KP_MAX);
            m.kd = clamp(t.kd[i], 0.0, h1_2::KD_MAX);
        }
        self.counters.clamped += clamped;
        cmd
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use policy_runtime::PolicyError;

    /// A policy that asks for the standing pose plus a fixed offset, or fails, or asks for NaN.
    #[derive(Debug)]
    struct Fixed {
        offset: f64,
        fail: bool,
        model: RobotModel,
        calls: std::sync::Arc<std::sync::atomic::AtomicUsize>,
    }

    impl Controller for Fixed {
        fn name(&self) -> &str {
            "fixed"
        }
        fn period(&self) -> f64 {
            0.02
        }
        fn reset(&mut self) {}
        fn act(&mut self, _obs: &RobotObservation) -> Result<PdTarget, PolicyError> {
            self.calls.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            if self.fail {
                return Err(PolicyError::Inference("planted".into()));
            }
            let mut t = PdTarget::hold_standing(&self.model);
            t.q_des.iter_mut().for_each(|q| *q += self.offset);
            Ok(t)
        }
    }

    fn model() -> RobotModel {
        RobotModel::h1_2().expect("model")
    }

    fn deployer(offset: f64, fail: bool) -> (Deployer, std::sync::Arc<std::sync::atomic::AtomicUsize>) {
        let calls = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let c = Fixed { offset, fail, model: model(), calls: calls.clone() };
        (
            Deployer::new(model(), Box::new(c), DeployConfig { ramp_s: 1.0, ..DeployConfig::default() }).expect("ok"),
            calls,
        )
    }

    /// A sealed LowState with every model joint at `q` (plus the model's pose) and an upright IMU.
    fn state(q_offset: f32) -> hg::LowState_ {
        let m = model();
        let mut s = hg::LowState_::default();
        for (j, q) in m.joints.iter().zip(m.default_q()) {
            s.motor_state[j.slot].q = q as f32 + q_offset;
        }
        s.imu_state.quaternion = [1.0, 0.0, 0.0, 0.0];
        crc::seal(&mut s);
        s
    }

    fn q_of(cmd: &hg::LowCmd_, m: &RobotModel) -> Vec<f64> {
        m.joints.iter().map(|j| f64::from(cmd.motor_cmd[j.slot].q)).collect()
    }

    #[test]
    fn nothing_is_sent_before_a_state_then_the_pose_ramps_and_the_policy_takes_over() {
        let m = model();
        let (mut d, calls) = deployer(0.05, false);
        assert!(d.command(0.0).is_none());
        d.on_state(&state(0.1), 0.0);
        let first = d.command(0.0).expect("command");
        assert!(crc::verify(&first), "every command is sealed");
        // Starts where the joints are (clamped into the joint ranges), ends at the standing pose after the ramp.
        let start = q_of(&first, &m);
        let found: Vec<f64> = m.default_q().iter().map(|q| q + 0.1).collect();
        let n_free = start.iter().zip(&found).filter(|(a, b)| (*a - *b).abs() < 1e-5).count();
        assert!(n_free > m.nj() / 2, "{start:?}");
        d.on_state(&state(0.05), 0.5);
        let mid = q_of(&d.command(0.5).expect("command"), &m);
        let i = m.joints.iter().position(|j| j.name.contains("knee")).expect("knee");
        assert!((mid[i] - (m.default_q()[i] + 0.05)).abs() < 1e-4, "halfway: {} vs {}", mid[i], m.default_q()[i]);
        assert_eq!(d.phase(), Phase::MovingToDefault);
        d.on_state(&state(0.0), 1.0);
        d.command(1.0);
        assert_eq!(d.phase(), Phase::Running);
        d.on_state(&state(0.0), 1.01);
        let run = q_of(&d.command(1.01).expect("command"), &m);
        assert_eq!(calls.load(std::sync::atomic::Ordering::SeqCst), 1);
        assert!((run[i] - (m.default_q()[i] + 0.05)).abs() < 1e-5, "policy target sent");
        // 50 Hz policy under a 500 Hz command loop: one policy step per 10 commands.
        for k in 2..=100 {
            let t = 1.0 + k as f64 * 0.002;
            d.on_state(&state(0.0), t);
            d.command(t);
        }
        assert_eq!(calls.load(std::sync::atomic::Ordering::SeqCst), 11);
    }

    #[test]
    fn stale_state_non_finite_state_and_policy_errors_damp() {
        let m = model();
        let (mut d, _) = deployer(0.0, false);
        d.on_state(&state(0.0), 0.0);
        d.command(0.0);
        let cmd = d.command(0.2).expect("still commanding");
        assert_eq!(d.stop_reason(), Some(&StopReason::StaleState { age_s: 0.2 }));
        assert!(m.joints.iter().all(|j| cmd.motor_cmd[j.slot].kp == 0.0 && cmd.motor_cmd[j.slot].kd >= 2.0));
        assert!(crc::verify(&cmd));

        let (mut d, _) = deployer(0.0, false);
        let mut s = state(0.0);
        s.motor_state[m.joints[3].slot].dq = f32::NAN;
        crc::seal(&mut s);
        d.on_state(&state(0.0), 0.0);
        d.on_state(&s, 0.002);
        assert_eq!(d.phase(), Phase::Damping);
        assert_eq!(d.stop_reason(), Some(&StopReason::NonFiniteState { field: "motor_state.dq".into() }));

        let (mut d, _) = deployer(0.0, true);
        for k in 0..600 {
            let t = k as f64 * 0.002;
            d.on_state(&state(0.0), t);
            d.command(t);
        }
        assert!(matches!(d.stop_reason(), Some(StopReason::Policy { .. })), "{:?}", d.stop_reason());
    }

    #[test]
    fn bad_crc_is_dropped_and_limits_are_enforced() {
        let m = model();
        let (mut d, _) = deployer(10.0, false); // the policy asks for 10 rad beyond every joint range
        let mut s = state(0.0);
        s.crc ^= 1;
        d.on_state(&s, 0.0);
        assert_eq!(d.counters().bad_crc, 1);
        assert!(d.command(0.0).is_none(), "a bad-CRC state is not a state");
        let mut t = 0.0;
        while d.phase() != Phase::Running || d.counters().policy_steps == 0 {
            d.on_state(&state(0.0), t);
            d.command(t);
            t += 0.002;
            assert!(t < 5.0);
        }
        let cmd = d.command(t - 0.002).expect("command");
        for j in &m.joints {
            let lim = &h1_2::JOINTS[j.slot];
            assert_eq!(cmd.motor_cmd[j.slot].q, lim.upper, "{}", j.name);
        }
        assert!(d.counters().clamped >= m.nj() as u64);
    }

    #[test]
    fn a_fall_seen_by_the_imu_damps_the_policy_but_not_the_ramp() {
        let m = model();
        // An IMU that is not unit length, rolled about x by `angle` (quaternion [cos a/2, sin a/2, 0, 0] scaled).
        let tilted = |angle: f64| {
            let mut s = state(0.0);
            s.imu_state.quaternion = [(angle / 2.0).cos() as f32 * 1.01, (angle / 2.0).sin() as f32 * 1.01, 0.0, 0.0];
            crc::seal(&mut s);
            s
        };
        let (mut d, calls) = deployer(0.0, false);
        // Tilted during the ramp (a robot being stood up): no stop.
        d.on_state(&tilted(1.0), 0.0);
        d.command(0.0);
        d.on_state(&tilted(1.0), 0.5);
        d.command(0.5);
        assert_eq!(d.phase(), Phase::MovingToDefault);
        let mut t = 0.5;
        while d.phase() != Phase::Running {
            t += 0.002;
            d.on_state(&state(0.0), t);
            d.command(t);
        }
        // 0.6 rad (34 degrees) is within the 0.7 rad default; 0.75 rad is a fall.
        for angle in [0.3, 0.6] {
            t += 0.002;
            d.on_state(&tilted(angle), t);
            d.command(t);
            assert_eq!(d.phase(), Phase::Running, "{angle} rad");
        }
        let steps = calls.load(std::sync::atomic::Ordering::SeqCst);
        t += 0.002;
        d.on_state(&tilted(0.75), t);
        let cmd = d.command(t).expect("command");
        match d.stop_reason() {
            Some(StopReason::Fallen { tilt_rad }) => assert!((tilt_rad - 0.75).abs() < 1e-3, "{tilt_rad}"),
            other => panic!("expected a fall, got {other:?}"),
        }
        assert!(m.joints.iter().all(|j| cmd.motor_cmd[j.slot].kp == 0.0), "damping");
        assert_eq!(calls.load(std::sync::atomic::Ordering::SeqCst), steps, "no policy step on a fallen robot");

        // Switched off, the same tilt runs on.
        let c = Fixed { offset: 0.0, fail: false, model: model(), calls: Default::default() };
        let cfg = DeployConfig { ramp_s: 0.0, max_tilt_rad: None, ..DeployConfig::default() };
        let mut d = Deployer::new(model(), Box::new(c), cfg).expect("ok");
        for k in 0..10 {
            d.on_state(&tilted(1.5), k as f64 * 0.002);
            d.command(k as f64 * 0.002);
        }
        assert_eq!(d.phase(), Phase::Running);
    }

    #[test]
    fn bad_settings_are_typed_errors() {
        let c = Fixed { offset: 0.0, fail: false, model: model(), calls: Default::default() };
        let bad = DeployConfig { stale_s: 0.0, ..DeployConfig::default() };
        assert!(matches!(Deployer::new(model(), Box::new(c), bad), Err(DeployError::Setting(_))));
        for tilt in [0.0, -1.0, 4.0, f64::NAN] {
            let c = Fixed { offset: 0.0, fail: false, model: model(), calls: Default::default() };
            let bad = DeployConfig { max_tilt_rad: Some(tilt), ..DeployConfig::default() };
            assert!(matches!(Deployer::new(model(), Box::new(c), bad), Err(DeployError::Setting(_))), "{tilt}");
        }
    }
}
