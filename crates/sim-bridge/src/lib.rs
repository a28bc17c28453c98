//! The robot side of Unitree's low-level protocol, simulated, without any transport.
//!
//! [`SimRobot`] owns one physics [`Engine`] and does what the real robot's motor layer does
//! with `rt/lowcmd` and `rt/lowstate`, but stricter than the public simulator bridges:
//! * every LowCmd is decoded, its CRC checked ([`Verdict::BadCrc`]: dropped and counted), and
//!   validated against the robot's limits ([`Verdict::Rejected`]: never applied);
//! * the latest accepted command drives Unitree's PD law at **every physics step**, per motor
//!   `mode` (0 = disabled: no torque);
//! * optionally the standing pose is held until the first command arrives;
//! * when commands stop for [`BridgeConfig::command_timeout`], the robot falls back to damping
//!   mode: `tau = -kd_default * dq` on every joint (what Unitree's damp mode does), no stiffness;
//! * every LowState is built from the physics state of that instant (fresh), with the IMU on
//!   the torso (quaternion w,x,y,z; gyroscope in the IMU frame; accelerometer = specific force
//!   `R^T (a - g)`, so +9.81 m/s² on z at rest), `tick` in ms and a correct CRC.
//!
//! [`loco`] is the built-in locomotion service (what Unitree's `LocoClient` talks to over RPC): a walking policy
//! and the FSM states behind it, driving the robot through an internal command that any fresh `rt/lowcmd`
//! command overrides ([`SimRobot::set_internal_command`]). [`motion_switcher`] is the motion-switcher service
//! Unitree's low-level examples ask to release that locomotion service before they take the motors.
//! [`Defect`]s switch single protocol faults on, for testing conformance tools; none is active in normal use.
//!
//! [`suspension`] holds the robot on a stiff stand (pelvis still, feet in the air) for `ulab sim --hang`; the gap
//! diagnosis's rig uses the same stand (defined in `diff_physics::suspension`, re-exported here).
//!
//! DDS, timing and status lines live in the `ulab sim` command; tests drive this directly.
#![forbid(unsafe_code)]

mod imu;
pub mod loco;
pub mod motion_switcher;
mod rpc;
pub use diff_physics::suspension;

use diff_physics::{pd, Engine, EngineError, PdTarget, State};
use lowlevel_codec::{cdr, crc, validate, DecodeError};
use robot_model::RobotModel;
use std::collections::BTreeSet;
use unitree_idl::{go, hg};

pub use imu::ImuReading;

/// A deliberate deviation from Unitree's protocol (test-only, `ulab sim --unsafe-defect NAME`). Each one reproduces a
/// fault seen in a public simulator bridge, so the conformance tester can prove that it reports exactly that fault
/// and nothing else. None is active in normal use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Defect {
    /// LowState goes out with `crc = 0` (unitree_mujoco's Python bridge never computes it).
    NoStateCrc,
    /// LowState `tick` stays 0 (same bridge).
    TickStuck,
    /// LowState is a snapshot refreshed only every [`STALE_REFRESH`] publishes.
    StaleState,
    /// Commands whose CRC is wrong are applied (no public bridge checks it).
    ApplyBadCrc,
    /// Motor mode 0 drives the motor like mode 1.
    IgnoreMode0,
    /// Gains outside `[0, KP_MAX]` / `[0, KD_MAX]` (negative, huge) are applied as sent.
    ApplyAbsurdGains,
    /// Non-finite values are accepted; a step whose torque is not finite zeroes every motor, as MuJoCo clears all
    /// controls on a bad control value: the robot goes limp instead of rejecting the message.
    LimpOnNonFinite,
    /// Non-finite values are accepted and reach the physics, whose state turns non-finite: while such a command is
    /// applied, every motor reports NaN position, velocity, acceleration and torque, as an engine integrating a NaN
    /// torque would. Unlike a real engine, the physics underneath stays intact (the NaN torque is never handed to
    /// it) and the state is finite again once a finite command applies, so that later checks stay decidable.
    UndefinedOnNonFinite,
    /// No command timeout: the last command is applied forever when commands stop.
    KeepLastCommand,
    /// The robot starts lying on its back and [`PINNED_SLOTS`] are held by brakes (standing in for the robot's own
    /// body lying on them after a fall): commands reach their motors, whose torque is reported, but cannot move them.
    FallenPinned,
}

impl Defect {
    /// Every defect, in declaration order.
    pub const ALL: [Defect; 10] = [
        Defect::NoStateCrc,
        Defect::TickStuck,
        Defect::StaleState,
        Defect::ApplyBadCrc,
        Defect::IgnoreMode0,
        Defect::ApplyAbsurdGains,
        Defect::LimpOnNonFinite,
        Defect::UndefinedOnNonFinite,
        Defect::KeepLastCommand,
        Defect::FallenPinned,
    ];

    /// The command-line name (kebab-case).
    pub const fn name(self) -> &'static str {
        match self {
            Defect::NoStateCrc => "no-state-crc",
            Defect::TickStuck => "tick-stuck",
            Defect::StaleState => "stale-state",
            Defect::ApplyBadCrc => "apply-bad-crc",
            Defect::IgnoreMode0 => "ignore-mode0",
            Defect::ApplyAbsurdGains => "apply-absurd-gains",
            Defect::LimpOnNonFinite => "limp-on-non-finite",
            Defect::UndefinedOnNonFinite => "undefined-on-non-finite",
            Defect::KeepLastCommand => "keep-last-command",
            Defect::FallenPinned => "fallen-pinned",
        }
    }

    /// Parses a [`Defect::name`].
    pub fn parse(name: &str) -> Option<Defect> {
        Defect::ALL.into_iter().find(|d| d.name() == name)
    }
}

/// How many publishes a stale snapshot is reused for under [`Defect::StaleState`].
pub const STALE_REFRESH: u32 = 10;

/// Motor slots braked by [`Defect::FallenPinned`]: both elbows and the left shoulder pitch (the right shoulder pitch
/// stays free, so one arm joint can still move).
pub const PINNED_SLOTS: [usize; 3] = [16, 23, 13];

/// Brake of a pinned joint (N·m/rad, N·m·s/rad): stiff enough that a motor torque at its limit deflects the joint by
/// a few milliradians, soft enough for explicit integration at 2 ms with the model's 0.1 kg·m² armature
/// (K dt²/I = 0.08, D dt/I = 0.4).
const BRAKE_KP: f64 = 2000.0;
const BRAKE_KD: f64 = 20.0;

/// Bridge behaviour.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BridgeConfig {
    /// Seconds without an accepted command before damping mode.
    pub command_timeout: f64,
    /// `mode_machine` reported in LowState.
    pub mode_machine: u8,
    /// Until the first command is accepted, hold the standing pose with the model's default
    /// gains (a simulator that starts standing); afterwards silence means damping.
    pub hold_until_first_command: bool,
    /// Deliberate protocol defects (test-only; empty in normal use).
    pub defects: BTreeSet<Defect>,
}

impl BridgeConfig {
    /// Whether `defect` is active.
    pub fn has(&self, defect: Defect) -> bool {
        self.defects.contains(&defect)
    }
}

impl Default for BridgeConfig {
    fn default() -> Self {
        BridgeConfig {
            command_timeout: 0.1,
            mode_machine: unitree_idl::h1_2::MODE_MACHINE,
            hold_until_first_command: false,
            defects: BTreeSet::new(),
        }
    }
}

/// What happened to one received LowCmd sample.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Applied from now on.
    Accepted,
    /// Not a valid CDR hg LowCmd.
    Malformed(DecodeError),
    /// CRC mismatch: dropped.
    BadCrc { stored: u32, computed: u32 },
    /// Valid bytes, unsafe content: not applied. The findings say why.
    Rejected(Vec<validate::Finding>),
}

/// Counters for status lines and reports.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counters {
    pub received: u64,
    pub accepted: u64,
    pub malformed: u64,
    pub bad_crc: u64,
    pub rejected: u64,
    pub states_published: u64,
    /// Physics steps run in damping mode because no command was fresh.
    pub damping_steps: u64,
    /// Physics steps driven by the internal command (the locomotion service).
    pub internal_steps: u64,
}

/// Stiffness that keeps the robot standing without a balance controller (N·m/rad, N·m·s/rad):
/// the model's default (RL deploy) gains cannot. Leg joints are raised to at least these; the
/// ankles dominate (the H1-2 topples at about 690 N·m/rad of ankle stiffness demand, against
/// 2 x 40 in the deploy gains). Figures checked by the model's standing oracle.
const STAND_LEG_KP: f64 = 500.0;
const STAND_LEG_KD: f64 = 5.0;
const STAND_ANKLE_KP: f64 = 600.0;
const STAND_ANKLE_KD: f64 = 10.0;

/// PD target holding the standing pose: the model's default pose and gains, with leg gains
/// raised to `STAND_LEG_KP`/`STAND_ANKLE_KP` so that the robot stays up until a controller
/// takes over.
pub fn stand_target(model: &RobotModel) -> PdTarget {
    let mut t = PdTarget::hold_standing(model);
    for (i, j) in model.joints.iter().enumerate() {
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

/// The robot lying on its back in its default joint pose, pelvis 0.4 m up (it drops onto the ground within the first
/// 0.3 s): the start of [`Defect::FallenPinned`].
pub fn lying_on_back(model: &RobotModel) -> State {
    let mut s = State::standing(model);
    // -90 degrees about the world y axis: the pelvis' forward axis points up.
    let half = -std::f64::consts::FRAC_PI_4;
    s.base_quat = [half.cos(), 0.0, half.sin(), 0.0];
    s.base_pos = [0.0, 0.0, 0.4];
    s
}

/// Errors that stop the simulation.
#[derive(Debug, thiserror::Error)]
pub enum BridgeError {
    #[error(transparent)]
    Engine(#[from] EngineError),
    #[error(transparent)]
    Model(#[from] robot_model::ModelError),
    #[error("model has {model} joints but the slot map of hg LowCmd has {slots}")]
    SlotMismatch { model: usize, slots: usize },
}

/// A simulated H1-2 behind Unitree's low-level protocol.
#[derive(Debug)]
pub struct SimRobot {
    engine: Box<dyn Engine>,
    model: RobotModel,
    config: BridgeConfig,
    limits: Vec<f64>,
    damping_kd: Vec<f64>,
    /// PD target of the initial standing hold (see [`stand_target`]).
    stand: PdTarget,
    /// PD target of the latest command, refilled in place at every step (no allocation).
    target: PdTarget,
    /// Latest accepted command and when it arrived (caller's clock, s).
    command: Option<(hg::LowCmd_, f64)>,
    /// Command of the built-in controller (the locomotion service), applied while no received command is
    /// fresh; validated when set.
    internal: Option<hg::LowCmd_>,
    /// Whether the last step applied [`Self::internal`] (the motor modes LowState reports follow it).
    applied_internal: bool,
    /// Under [`Defect::UndefinedOnNonFinite`]: the last step applied a non-finite torque.
    undefined_state: bool,
    /// Motor torques of the last step (what LowState reports as `tau_est`).
    tau: Vec<f64>,
    /// Torques handed to the engine: the motor torques plus the brakes of [`Defect::FallenPinned`].
    engine_tau: Vec<f64>,
    /// Brakes of [`Defect::FallenPinned`]: (model joint index, angle held).
    brakes: Vec<(usize, f64)>,
    prev_dq: Vec<f64>,
    ddq: Vec<f64>,
    imu: imu::ImuTracker,
    /// An IMU on the pelvis: the `imu_state` of [`SimRobot::sport_mode_state`].
    pelvis_imu: imu::ImuTracker,
    stale: Option<(hg::LowState_, u32)>,
    counters: Counters,
}

impl SimRobot {
    /// Wraps `engine` (built for `model`) and resets it to `initial`.
    pub fn new(
        engine: Box<dyn Engine>,
        model: RobotModel,
        config: BridgeConfig,
        initial: &State,
    ) -> Result<Self, BridgeError> {
        let n = model.nj();
        if model.joints.iter().any(|j| j.slot >= hg::MOTOR_SLOTS) {
            return Err(BridgeError::SlotMismatch { model: n, slots: hg::MOTOR_SLOTS });
        }
        let imu = imu::ImuTracker::new(&model)?;
        let pelvis_imu = imu::ImuTracker::on_base(&model)?;
        let mut robot = SimRobot {
            limits: model.joints.iter().map(|j| j.torque_limit).collect(),
            damping_kd: model.joints.iter().map(|j| j.kd).collect(),
            stand: stand_target(&model),
            target: PdTarget::hold_standing(&model),
            engine,
            config,
            command: None,
            internal: None,
            applied_internal: false,
            undefined_state: false,
            tau: vec![0.0; n],
            engine_tau: vec![0.0; n],
            brakes: Vec::new(),
            prev_dq: vec![0.0; n],
            ddq: vec![0.0; n],
            imu,
            pelvis_imu,
            stale: None,
            counters: Counters::default(),
            model,
        };
        robot.reset(initial)?;
        Ok(robot)
    }

    /// Resets physics to `state`; forgets commands and derivative history.
    pub fn reset(&mut self, state: &State) -> Result<(), BridgeError> {
        self.engine.reset(state)?;
        self.command = None;
        self.internal = None;
        self.applied_internal = false;
        self.undefined_state = false;
        self.tau.iter_mut().for_each(|t| *t = 0.0);
        self.prev_dq.clone_from(&state.dq);
        self.ddq.iter_mut().for_each(|a| *a = 0.0);
        self.imu.reset(&self.model, state, self.engine.common().gravity)?;
        self.pelvis_imu.reset(&self.model, state, self.engine.common().gravity)?;
        self.stale = None;
        self.brakes = if self.config.has(Defect::FallenPinned) {
            self.model
                .joints
                .iter()
                .enumerate()
                .filter(|(_, j)| PINNED_SLOTS.contains(&j.slot))
                .map(|(i, _)| (i, state.q[i]))
                .collect()
        } else {
            Vec::new()
        };
        Ok(())
    }

    /// Handles one received `rt/lowcmd` sample (CDR bytes with header) at time `now` (s).
    pub fn handle_lowcmd(&mut self, bytes: &[u8], now: f64) -> Verdict {
        self.counters.received += 1;
        let cmd = match cdr::decode::<hg::LowCmd_>(bytes) {
            Ok(d) => d.value,
            Err(e) => {
                self.counters.malformed += 1;
                return Verdict::Malformed(e);
            }
        };
        self.handle_command(cmd, now)
    }

    /// Handles an already decoded command (same gates as [`SimRobot::handle_lowcmd`]).
    pub fn handle_command(&mut self, cmd: hg::LowCmd_, now: f64) -> Verdict {
        if !self.config.has(Defect::ApplyBadCrc) {
            let computed = crc::compute(&cmd);
            if computed != cmd.crc {
                self.counters.bad_crc += 1;
                return Verdict::BadCrc { stored: cmd.crc, computed };
            }
        }
        {
            // Unused slots that are not zero are harmless: the robot has no motor there.
            let absurd_gains = self.config.has(Defect::ApplyAbsurdGains);
            let non_finite = self.config.has(Defect::LimpOnNonFinite) || self.config.has(Defect::UndefinedOnNonFinite);
            // The simulated robot has the serial pitch/roll ankle joints only and applies every ankle target to them.
            let findings: Vec<_> = validate::h1_2_lowcmd_in(&cmd, validate::AnkleMode::PitchRoll)
                .into_iter()
                .filter(|f| match f {
                    validate::Finding::UnusedSlotNotZero { .. } => false,
                    validate::Finding::OutOfLimits {
                        field: validate::CmdField::Kp | validate::CmdField::Kd, ..
                    } => !absurd_gains,
                    validate::Finding::NonFinite { .. } => !non_finite,
                    _ => true,
                })
                .collect();
            if !findings.is_empty() {
                self.counters.rejected += 1;
                return Verdict::Rejected(findings);
            }
        }
        self.counters.accepted += 1;
        self.command = Some((cmd, now));
        Verdict::Accepted
    }

    /// Whether a received command is fresh at `now` (else the internal command drives the robot, or without one
    /// the robot is in damping mode).
    pub fn command_active(&self, now: f64) -> bool {
        self.command
            .as_ref()
            .is_some_and(|(_, t)| self.config.has(Defect::KeepLastCommand) || now - t <= self.config.command_timeout)
    }

    /// Sets (or clears) the internal command: what drives the motors whenever no received `rt/lowcmd` command is
    /// fresh, with no timeout of its own. A fresh received command always takes precedence, as low-level commands
    /// override the robot's own controller. The command passes the same limit checks as a received one (not the
    /// CRC: it never travelled); on findings it is refused and the previous internal command stays.
    pub fn set_internal_command(&mut self, cmd: Option<hg::LowCmd_>) -> Result<(), Vec<validate::Finding>> {
        if let Some(c) = &cmd {
            let findings: Vec<_> = validate::h1_2_lowcmd_in(c, validate::AnkleMode::PitchRoll)
                .into_iter()
                .filter(|f| !matches!(f, validate::Finding::UnusedSlotNotZero { .. }))
                .collect();
            if !findings.is_empty() {
                return Err(findings);
            }
        }
        self.internal = cmd;
        Ok(())
    }

    /// The internal command, if one is set.
    pub fn internal_command(&self) -> Option<&hg::LowCmd_> {
        self.internal.as_ref()
    }

    /// One physics step at time `now` (caller's clock, for the command timeout): PD torques from
    /// the latest accepted command (or damping), clamped to the torque limits, then the engine.
    pub fn step(&mut self, now: f64) -> Result<(), BridgeError> {
        let state = self.engine.state();
        let n = self.model.nj();
        let active = self.command_active(now);
        let applied = match (active, &self.command, &self.internal) {
            (true, Some((cmd, _)), _) => Some(cmd),
            (false, _, Some(cmd)) => {
                self.counters.internal_steps += 1;
                Some(cmd)
            }
            _ => None,
        };
        self.applied_internal = !active && self.internal.is_some();
        self.undefined_state = false;
        if let Some(cmd) = applied {
            let target = &mut self.target;
            for (i, joint) in self.model.joints.iter().enumerate() {
                let m = &cmd.motor_cmd[joint.slot];
                // mode 0: motor disabled, no torque at all (gains and feed-forward ignored).
                let enabled = m.mode != 0 || self.config.defects.contains(&Defect::IgnoreMode0);
                let value = |x: f32| if enabled { f64::from(x) } else { 0.0 };
                target.q_des[i] = value(m.q);
                target.dq_des[i] = value(m.dq);
                target.kp[i] = value(m.kp);
                target.kd[i] = value(m.kd);
                target.tau_ff[i] = value(m.tau);
            }
            pd::pd_torques_into(target, &state.q, &state.dq, &self.limits, &mut self.tau);
            // Only a defect lets a non-finite command through; never hand NaN to an engine. MuJoCo answers a bad
            // control value by clearing every control: the whole robot goes limp for that step.
            self.undefined_state =
                self.config.has(Defect::UndefinedOnNonFinite) && self.tau.iter().any(|t| !t.is_finite());
            if self.tau.iter().any(|t| !t.is_finite()) {
                if self.config.has(Defect::LimpOnNonFinite) {
                    self.tau.iter_mut().for_each(|t| *t = 0.0);
                } else {
                    self.tau.iter_mut().filter(|t| !t.is_finite()).for_each(|t| *t = 0.0);
                }
            }
        } else if self.command.is_none() && self.config.hold_until_first_command {
            pd::pd_torques_into(&self.stand, &state.q, &state.dq, &self.limits, &mut self.tau);
        } else {
            self.counters.damping_steps += 1;
            for (i, tau) in self.tau.iter_mut().enumerate() {
                *tau = (-self.damping_kd[i] * state.dq[i]).clamp(-self.limits[i], self.limits[i]);
            }
        }
        self.engine_tau.clone_from(&self.tau);
        for &(i, angle) in &self.brakes {
            self.engine_tau[i] += -BRAKE_KP * (state.q[i] - angle) - BRAKE_KD * state.dq[i];
        }
        self.engine.step(&self.engine_tau)?;
        let next = self.engine.state();
        let dt = self.engine.common().timestep;
        for i in 0..n {
            self.ddq[i] = (next.dq[i] - self.prev_dq[i]) / dt;
        }
        self.prev_dq.clone_from(&next.dq);
        self.imu.update(&self.model, &next, dt)?;
        self.pelvis_imu.update(&self.model, &next, dt)?;
        Ok(())
    }

    /// A LowState of the current physics state, sealed with its CRC.
    pub fn lowstate(&mut self) -> Result<hg::LowState_, BridgeError> {
        self.counters.states_published += 1;
        if self.config.has(Defect::StaleState) {
            let tick = self.tick();
            if let Some((snapshot, uses)) = &mut self.stale {
                if *uses < STALE_REFRESH {
                    *uses += 1;
                    let mut s = snapshot.clone();
                    s.tick = tick;
                    self.seal(&mut s);
                    return Ok(s);
                }
            }
            let s = self.build_lowstate()?;
            self.stale = Some((s.clone(), 1));
            return Ok(s);
        }
        self.build_lowstate()
    }

    fn tick(&self) -> u32 {
        if self.config.has(Defect::TickStuck) {
            return 0;
        }
        // Milliseconds of simulated time; wraps like the robot's u32 counter.
        ((self.engine.time() * 1000.0).round() as u64 & u64::from(u32::MAX)) as u32
    }

    /// Seals a LowState with its CRC (or leaves `crc = 0` under [`Defect::NoStateCrc`]).
    fn seal(&self, s: &mut hg::LowState_) {
        if self.config.has(Defect::NoStateCrc) {
            s.crc = 0;
        } else {
            crc::seal(s);
        }
    }

    fn build_lowstate(&self) -> Result<hg::LowState_, BridgeError> {
        let state = self.engine.state();
        let mut s = hg::LowState_ { mode_machine: self.config.mode_machine, tick: self.tick(), ..Default::default() };
        let reading = self.imu.reading();
        s.imu_state.quaternion = reading.quaternion.map(|x| x as f32);
        s.imu_state.gyroscope = reading.gyroscope.map(|x| x as f32);
        s.imu_state.accelerometer = reading.accelerometer.map(|x| x as f32);
        s.imu_state.rpy = reading.rpy.map(|x| x as f32);
        s.imu_state.temperature = 40;
        let enabled =
            if self.applied_internal { self.internal.as_ref() } else { self.command.as_ref().map(|(c, _)| c) };
        for (i, joint) in self.model.joints.iter().enumerate() {
            let m = &mut s.motor_state[joint.slot];
            m.mode = enabled.map_or(0, |c| u8::from(c.motor_cmd[joint.slot].mode != 0));
            m.q = state.q[i] as f32;
            m.dq = state.dq[i] as f32;
            m.ddq = self.ddq[i] as f32;
            m.tau_est = self.tau[i] as f32;
            m.temperature = [35, 35];
            if self.undefined_state {
                (m.q, m.dq, m.ddq, m.tau_est) = (f32::NAN, f32::NAN, f32::NAN, f32::NAN);
            }
        }
        self.seal(&mut s);
        Ok(s)
    }

    /// The simulator's own pelvis pose as the sport controller's state (`rt/sportmodestate`, as Unitree's MuJoCo
    /// bridge publishes it): `position` the pelvis origin and `velocity` its velocity (world frame = odometry frame,
    /// the ground at z = 0, so `body_height` is the pelvis height), `yaw_speed` the world z angular velocity,
    /// `imu_state` an ideal IMU at the pelvis origin (its quaternion is the pelvis orientation `[w, x, y, z]`),
    /// `stamp` the simulated time. The sport-controller fields (mode, gait, feet, path) stay zero: no sport
    /// controller runs.
    pub fn sport_mode_state(&self) -> go::SportModeState_ {
        let state = self.engine.state();
        let r = self.pelvis_imu.reading();
        let t = self.engine.time().max(0.0);
        let [w, x, y, z] = state.base_quat;
        // World z of the body-frame angular velocity: third row of the rotation matrix times it.
        let rz = [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)];
        let yaw_speed: f64 = rz.iter().zip(state.base_ang_vel).map(|(a, b)| a * b).sum();
        let mut s = go::SportModeState_ {
            stamp: go::TimeSpec_ { sec: t.floor().min(f64::from(i32::MAX)) as i32, nanosec: (t.fract() * 1e9) as u32 },
            position: state.base_pos.map(|v| v as f32),
            body_height: state.base_pos[2] as f32,
            velocity: state.base_lin_vel.map(|v| v as f32),
            yaw_speed: yaw_speed as f32,
            ..Default::default()
        };
        s.imu_state.quaternion = r.quaternion.map(|v| v as f32);
        s.imu_state.gyroscope = r.gyroscope.map(|v| v as f32);
        s.imu_state.accelerometer = r.accelerometer.map(|v| v as f32);
        s.imu_state.rpy = r.rpy.map(|v| v as f32);
        s.imu_state.temperature = 40;
        s
    }

    /// [`SimRobot::sport_mode_state`] as CDR bytes (XCDR1 little-endian).
    pub fn sport_mode_state_bytes(&self) -> Vec<u8> {
        cdr::encode(&self.sport_mode_state(), lowlevel_codec::Encoding::UNITREE)
    }

    /// The LowState as CDR bytes (XCDR1 little-endian, what Unitree's SDK expects).
    pub fn lowstate_bytes(&mut self) -> Result<Vec<u8>, BridgeError> {
        Ok(cdr::encode(&self.lowstate()?, lowlevel_codec::Encoding::UNITREE))
    }

    pub fn counters(&self) -> &Counters {
        &self.counters
    }
    pub fn engine(&self) -> &dyn Engine {
        self.engine.as_ref()
    }
    pub fn model(&self) -> &RobotModel {
        &self.model
    }
    pub fn config(&self) -> &BridgeConfig {
        &self.config
    }
    /// Torques applied in the last step (slot order of the model's joints).
    pub fn applied_torques(&self) -> &[f64] {
        &self.tau
    }
    /// Current IMU reading (torso).
    pub fn imu(&self) -> ImuReading {
        self.imu.reading()
    }
}
