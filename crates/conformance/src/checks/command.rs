//! Command handling. A session first holds every joint where it stands ([`commands::hold_command`], the *hold* H)
//! and picks up to [`MAX_TEST_JOINTS`] **test joints** among light arm joints that are free: not near a range limit,
//! settled, not loaded (judged from q, dq, `tau_est`), alternating directions. Every probe is then judged on those
//! joints with two kinds of evidence:
//!
//! * **torque**: the `tau_est` a peer reports is its motor torque, which Unitree's PD law fixes for the command in
//!   force: `tau = tau_ff + kp (q_des - q) + kd (dq_des - dq)`, clamped to the joint's limit, zero in mode 0.
//!   Evaluated at each sample's own q and dq, the law predicts the torque of every interpretation of a probe
//!   (applied, ignored, clamped, limp) whatever the joint can do: a joint pinned against a limit or under the fallen
//!   robot still shows the torque its motor was told to produce;
//! * **motion**: where a joint can move, an applied step moves it. Motion is compared between two runs with opposite
//!   directions, so that gravity and any sag (the same in both runs) cancel.
//!
//! The valid step (`cmd_valid_moves_joint`) calibrates both: a joint's torque evidence is used only if its
//! `tau_est` followed the PD law of the valid step, its motion only if it moved at least half the step both ways.
//! Probes a conformant peer refuses alternate 1:1 with the hold, so the peer always has a fresh valid command and a
//! refused probe leaves the robot where it was.

use super::decision::{self, strongest, weakest};
use super::{decoded, max_gap, round, tail_pose, tilt, Timing, COMMAND_RATE};
use crate::commands::{self, hex, wire};
use crate::report::{CheckId, CheckResult, Margin, Status};
use crate::target::{StateSample, Target};
use crate::ConformError;
use lowlevel_codec::{crc, validate};
use serde::Serialize;
use serde_json::json;
use std::ops::Range;
use unitree_idl::{h1_2, hg};

/// Candidate test joints in order of preference: light arm joints, far from the balance-critical legs (elbows,
/// shoulder pitch, shoulder yaw, wrist pitch; left and right alternating).
pub const CANDIDATE_SLOTS: [usize; 8] = [16, 23, 13, 20, 15, 22, 18, 25];
/// Test joints stepped at once.
pub const MAX_TEST_JOINTS: usize = 4;
/// Step of a test joint's target (rad): large against sensor noise and gravity sag, small against the arm ranges.
pub const STEP_RAD: f32 = 0.3;
/// Smallest step a joint is tested with (rad); a joint with less room both ways is not free.
const MIN_STEP_RAD: f32 = 0.1;
/// Room kept from a joint's range limits (rad).
const RANGE_MARGIN: f32 = 0.05;
/// A joint is settled when its position varies by at most this much over the hold's tail (rad) ...
const SETTLED_RANGE_RAD: f32 = 0.05;
/// ... and moves no faster than this (rad/s).
const SETTLED_SPEED: f32 = 0.5;
/// A joint is loaded when it reports a hold torque above this fraction of its limit: a step would saturate it.
const LOADED_FRACTION: f64 = 0.5;
/// Below this tilt of the IMU from vertical (rad, ~29 degrees) the robot is upright: its arms hang free.
const UPRIGHT_TILT_RAD: f64 = 0.5;
/// A valid step moved a joint when it achieved this fraction of the step.
const MOVED_FRACTION: f64 = 0.5;
/// `tau_est` follows a law when its RMS residual is at most this fraction of the RMS separation of the two laws.
const TORQUE_FIT: f64 = 0.35;
/// Torque laws closer than this (N·m, RMS) cannot be told apart.
const MIN_SEPARATION_NM: f64 = 1.0;
/// A probe's torque evidence at a joint needs this many samples at which its unsafe law is told apart.
const MIN_SEPARABLE_SAMPLES: usize = 10;
/// A probe counts as applied at this fraction of the effect full application predicts ...
const APPLIED: f64 = 0.5;
/// ... and as not applied at most at this fraction.
const NOT_APPLIED: f64 = 0.25;
/// Share of the probe phase during which the probe message is the latest (it alternates 1:1 with the hold) when the
/// sender keeps its schedule. A starved sender does not: the message sent last before a stall stays in force
/// through it, so each probe measures its own share from the times it sent at ([`probe_duty`]).
const DUTY: f64 = 0.5;
/// A probe whose message was the latest for less than this share of the judged window is spoilt (undecided, probed
/// again): half its nominal share leaves too few samples at which an applying peer could show it.
const MIN_DUTY: f64 = 0.25;
/// A joint's hold torque is a load worth watching from this magnitude (N·m) ...
const LOAD_MIN_NM: f64 = 2.0;
/// ... and when `tau_est` matches the hold's PD law within this fraction.
const LOAD_FIT: f64 = 0.2;
/// After commands stop, behaviour is judged from this long after the last command (s): a peer may keep a command
/// for a short timeout (`ulab sim`: 0.1 s).
const SILENCE_GRACE_S: f64 = 0.3;
/// A joint not under test that strays this far from its hold (rad) while a refused probe runs was disturbed.
const DISTURBED_RAD: f32 = 0.15;

/// A test joint and what the valid step showed about it.
#[derive(Debug, Clone, Serialize)]
struct TestJoint {
    slot: usize,
    name: &'static str,
    /// Step size (rad) and the direction of the first run (+1 or -1).
    step: f32,
    dir: f32,
    limit: f64,
    /// Fraction of the valid step achieved in each run (second run in the opposite direction).
    moved: [Option<f64>; 2],
    /// `tau_est` residuals against the valid step's PD law and against the hold's, and the laws' separation (RMS
    /// N·m, over both runs).
    torque_residual_step_nm: f64,
    torque_residual_hold_nm: f64,
    torque_separation_nm: f64,
    /// Its reported torque follows the PD law of the command in force.
    torque: bool,
    /// It moved at least half the step both ways.
    motion: bool,
}

impl TestJoint {
    fn applied(&self) -> bool {
        self.torque || self.moved.iter().any(|m| m.is_some_and(|f| f >= MOVED_FRACTION))
    }
    fn usable(&self) -> bool {
        self.torque || self.motion
    }
}

/// Reported and predicted torques of one joint at one sample.
#[derive(Debug, Clone, Copy)]
struct JointSample {
    q: f32,
    dq: f32,
    tau: f64,
}

fn joint_sample(s: &hg::LowState_, slot: usize) -> JointSample {
    let m = &s.motor_state[slot];
    JointSample { q: m.q, dq: m.dq, tau: f64::from(m.tau_est) }
}

/// Motor torque Unitree's PD law gives for `m` at (q, dq), clamped to `limit`; none in mode 0. A non-finite result is
/// no torque (what a peer that sanitises it would apply; the limp interpretation covers the rest).
fn pd(m: &hg::MotorCmd_, js: JointSample, limit: f64) -> f64 {
    if m.mode == 0 {
        return 0.0;
    }
    let t = f64::from(m.tau) + f64::from(m.kp) * f64::from(m.q - js.q) + f64::from(m.kd) * f64::from(m.dq - js.dq);
    if t.is_nan() {
        0.0
    } else {
        t.clamp(-limit, limit)
    }
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// The outcome of a probe at one joint, or for a whole case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
enum Effect {
    /// The probe acted as the unsafe interpretation predicts.
    Unsafe,
    /// It acted as a safe interpretation predicts (ignored, rejected, clamped).
    Safe,
    /// Evidence was there but matched neither clearly.
    Unclear,
    /// No evidence could tell the interpretations apart.
    Undecidable,
}

/// What a peer did with a message carrying one non-finite value, as `cmd_non_finite_rejected` tells them apart: a
/// peer that rejects the message, one that applies its valid part, one whose robot goes limp (every motor gives up,
/// as MuJoCo does when it clears its controls) and one whose physics goes undefined (its state turns non-finite).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
enum NonFiniteResponse {
    Rejected,
    AppliedInPart,
    Limp,
    Undefined,
    Undecided,
}

impl NonFiniteResponse {
    /// From the probe's effect on the test joints (`applied`), the limp test on the rest of the robot, the number
    /// of non-finite states seen during the probe, and the case's combined effect. A non-finite state is the
    /// strongest evidence (the message reached the physics); a limp robot comes next (its torque collapsed or
    /// joints not under test left their hold), then the valid part's motion on the test joints.
    fn classify(applied: Effect, limp: Effect, non_finite_states: usize, combined: Effect) -> Self {
        if non_finite_states > 0 {
            NonFiniteResponse::Undefined
        } else if limp == Effect::Unsafe {
            NonFiniteResponse::Limp
        } else if applied == Effect::Unsafe {
            NonFiniteResponse::AppliedInPart
        } else if combined == Effect::Safe {
            NonFiniteResponse::Rejected
        } else {
            NonFiniteResponse::Undecided
        }
    }

    fn describe(self) -> &'static str {
        match self {
            NonFiniteResponse::Rejected => "rejected",
            NonFiniteResponse::AppliedInPart => "applied in part: the valid values moved the test joints",
            NonFiniteResponse::Limp => "limp: the robot's torque collapsed or its other joints left their hold",
            NonFiniteResponse::Undefined => "undefined: the peer's state turned non-finite",
            NonFiniteResponse::Undecided => "undecided",
        }
    }
}

/// Share of `[from, to]` during which the probe message (odd ticks of an alternating phase; even ticks carry the
/// hold) was the latest one sent, from the send time of every tick.
fn probe_duty(tick_times: &[f64], from: f64, to: f64) -> Option<f64> {
    if !(to > from) {
        return None;
    }
    let mut probe_time = 0.0;
    for (k, t) in tick_times.iter().enumerate() {
        let end = tick_times.get(k + 1).copied().unwrap_or(to);
        let overlap = end.min(to) - t.max(from);
        if k % 2 == 1 && overlap > 0.0 {
            probe_time += overlap;
        }
    }
    Some(probe_time / (to - from))
}

/// Combines per-joint effects: any unsafe joint makes the case unsafe.
fn combine(effects: impl Iterator<Item = Effect>) -> Effect {
    let v: Vec<Effect> = effects.collect();
    if v.contains(&Effect::Unsafe) {
        Effect::Unsafe
    } else if v.contains(&Effect::Safe) {
        Effect::Safe
    } else if v.contains(&Effect::Unclear) {
        Effect::Unclear
    } else {
        Effect::Undecidable
    }
}

/// Judges fractions of the unsafe effect against each safe interpretation (`None`: not separable).
fn judge(fractions: &[Option<f64>]) -> Effect {
    let decisive: Vec<f64> = fractions.iter().flatten().copied().filter(|f| f.is_finite()).collect();
    if decisive.is_empty() {
        Effect::Undecidable
    } else if decisive.iter().any(|f| (-0.5..=NOT_APPLIED).contains(f)) {
        Effect::Safe
    } else if decisive.iter().all(|f| *f >= APPLIED) {
        Effect::Unsafe
    } else {
        Effect::Unclear
    }
}

/// The margin of a check made of cases, from the fraction of the unsafe effect each joint showed (the statistic
/// [`judge`] compares with [`NOT_APPLIED`] and [`APPLIED`]). A case is safe when one joint shows it safe and unsafe
/// when one joint shows it unsafe: its margin is its most decisive joint's. A check passes when every case is safe
/// (its margin: the weakest case's) and fails when one case is unsafe (the strongest unsafe case's). Cases decided
/// on other evidence (a limp robot, a non-finite state) carry no fraction and no margin.
fn verdict_margin(status: Status, outcomes: &[(String, Effect, serde_json::Value)]) -> Option<Margin> {
    let case_margin = |effect: Effect, detail: &serde_json::Value| -> Option<Margin> {
        let joints = detail["joints"].as_array()?;
        let fractions = joints.iter().filter_map(|j| {
            let f = j["fraction_of_unsafe_effect"].as_f64()?;
            let e: Effect = serde_json::from_value(j["effect"].clone()).ok()?;
            Some((f, e))
        });
        match effect {
            Effect::Unsafe => strongest(
                fractions
                    .filter(|(_, e)| *e == Effect::Unsafe)
                    .map(|(f, _)| Margin::at_least("fraction_of_unsafe_effect", f, APPLIED)),
            ),
            Effect::Safe => strongest(
                fractions
                    .filter(|(_, e)| *e == Effect::Safe)
                    .map(|(f, _)| Margin::at_most("fraction_of_unsafe_effect", f, NOT_APPLIED)),
            ),
            Effect::Unclear | Effect::Undecidable => {
                strongest(fractions.map(|(f, _)| Margin::at_most("fraction_of_unsafe_effect", f, NOT_APPLIED)))
            }
        }
    };
    let margins = outcomes.iter().filter_map(|(_, effect, detail)| Some((*effect, case_margin(*effect, detail)?)));
    match status {
        Status::Fail => strongest(margins.filter(|(e, _)| *e == Effect::Unsafe).map(|(_, m)| m)),
        Status::Pass | Status::Inconclusive => weakest(margins.map(|(_, m)| m)),
    }
}

/// How the torque evidence of a probe is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Metric {
    /// Mean torque: the probe's interpretations push the joint differently.
    Signed,
    /// Mean |tau - hold law|: the interpretations differ in how hard the motor works, not in the mean (a huge gain
    /// near its target saturates in both directions).
    Activity,
}

/// One probe message and its interpretations at the test joints.
struct Case {
    name: String,
    bytes: Vec<u8>,
    /// The command in force during the probe's half of the time if the peer applies the message as sent.
    unsafe_: hg::LowCmd_,
    /// The same under each conformant reading (ignored: the hold; clamped; mode 0 honoured).
    safe: Vec<(&'static str, hg::LowCmd_)>,
    metric: Metric,
    /// Sign of the unsafe motion relative to each joint's direction (+1: toward the offset target, -1: away from
    /// it); `None`: motion cannot show it.
    motion_sign: Option<f32>,
}

/// A hold phase: its samples and the pose it settled at.
struct Held {
    range: Range<usize>,
    reference: [f32; h1_2::NUM_JOINTS],
}

/// What the clean part of the session showed (also the `cmd_valid_moves_joint` result).
#[derive(Debug, Clone)]
pub(super) struct Calibration {
    pub result: CheckResult,
    /// Samples of the clean driven phase (initial hold and valid steps).
    pub driven: Range<usize>,
}

/// A command session: the hold command and the probes built on it.
pub(super) struct Session<'a> {
    pub(super) target: &'a mut Target,
    pub(super) hold: hg::LowCmd_,
    pub(super) timing: Timing,
    joints: Vec<TestJoint>,
    /// Why candidates were not chosen.
    rejected: Vec<String>,
    /// Tilt of the IMU from vertical during the initial hold (rad).
    tilt: Option<f64>,
    /// Slots (not under test) whose `tau_est` follows the hold's PD law under a load: the whole robot's torque.
    loaded: Vec<usize>,
    /// Slot that carries the non-finite values (never a test joint).
    carrier: usize,
    /// Hold and probe samples of the last run of [`Session::run_case`].
    last_probe: Option<(Range<usize>, Range<usize>)>,
}

impl<'a> Session<'a> {
    pub(super) fn start(target: &'a mut Target, mode_machine: u8, timing: Timing) -> Result<Self, ConformError> {
        let s = target.latest().ok_or_else(|| ConformError::BadStartState("no decoded LowState".into()))?;
        let pose: [f32; h1_2::NUM_JOINTS] = std::array::from_fn(|i| s.motor_state[i].q);
        if pose.iter().any(|q| !q.is_finite()) {
            return Err(ConformError::BadStartState("non-finite joint position".into()));
        }
        let hold = commands::hold_command(&pose, mode_machine);
        Ok(Session {
            target,
            hold,
            timing,
            joints: Vec::new(),
            rejected: Vec::new(),
            tilt: None,
            loaded: Vec::new(),
            carrier: 26,
            last_probe: None,
        })
    }

    pub(super) fn hold_bytes(&self) -> Vec<u8> {
        wire(&self.hold)
    }

    /// Sends the hold for `seconds` and measures the pose it settles at.
    fn settle_for(&mut self, seconds: f64) -> Result<Held, ConformError> {
        let hold = self.hold_bytes();
        let range = self.target.drive(seconds, COMMAND_RATE, |_| vec![hold.clone()])?;
        let reference = tail_pose(&self.target.samples[range.clone()], self.timing.tail)
            .or_else(|| self.target.latest().map(|s| std::array::from_fn(|i| s.motor_state[i].q)))
            .ok_or(ConformError::NoState { seconds })?;
        Ok(Held { range, reference })
    }

    fn settle(&mut self) -> Result<Held, ConformError> {
        self.settle_for(self.timing.hold)
    }

    /// Publishes `bytes` for `seconds`, alone or alternating 1:1 with the hold.
    fn send(&mut self, seconds: f64, bytes: Vec<u8>, alternate: bool) -> Result<Range<usize>, ConformError> {
        let hold = self.hold_bytes();
        self.target.drive(seconds, COMMAND_RATE, move |i| {
            vec![if alternate && i % 2 == 0 { hold.clone() } else { bytes.clone() }]
        })
    }

    /// Samples of `range` from `latency` after its first one (older ones may still show the previous command).
    fn settled_part(&self, range: &Range<usize>) -> &[StateSample] {
        let samples = &self.target.samples[range.clone()];
        let Some(first) = samples.first().map(|s| s.t) else { return samples };
        let skip = samples.iter().position(|s| s.t >= first + self.timing.latency).unwrap_or(samples.len());
        &samples[skip..]
    }

    /// The samples in the last `tail` seconds of `range`.
    fn tail_part(&self, range: &Range<usize>) -> &[StateSample] {
        let samples = &self.target.samples[range.clone()];
        let Some(end) = samples.last().map(|s| s.t) else { return samples };
        let from = samples.iter().position(|s| s.t >= end - self.timing.tail).unwrap_or(samples.len());
        &samples[from..]
    }

    /// The hold with each usable test joint's command changed by `f(joint, reference, direction, motor)`, resealed.
    fn with_joints<F>(&self, base: &hg::LowCmd_, reference: &[f32; h1_2::NUM_JOINTS], sign: f32, f: F) -> hg::LowCmd_
    where
        F: Fn(&TestJoint, f32, f32, &mut hg::MotorCmd_),
    {
        self.with_joints_where(base, reference, sign, TestJoint::usable, f)
    }

    /// [`Session::with_joints`] on the test joints `pick` selects.
    fn with_joints_where<F>(
        &self,
        base: &hg::LowCmd_,
        reference: &[f32; h1_2::NUM_JOINTS],
        sign: f32,
        pick: fn(&TestJoint) -> bool,
        f: F,
    ) -> hg::LowCmd_
    where
        F: Fn(&TestJoint, f32, f32, &mut hg::MotorCmd_),
    {
        let mut cmd = base.clone();
        for j in self.joints.iter().filter(|j| pick(j)) {
            f(j, reference[j.slot], j.dir * sign, &mut cmd.motor_cmd[j.slot]);
        }
        crc::seal(&mut cmd);
        cmd
    }

    /// The hold with every usable test joint's target `direction * step` away from the reference.
    fn stepped(&self, reference: &[f32; h1_2::NUM_JOINTS], sign: f32) -> hg::LowCmd_ {
        self.with_joints(&self.hold, reference, sign, |j, r, d, m| m.q = commands::clamp_target(j.slot, r + d * j.step))
    }

    // -----------------------------------------------------------------------------------------
    // Calibration: joint choice and the valid step.

    /// Picks the test joints from a settled hold and runs the valid step in both directions; when that leaves no
    /// usable joint (none free, or none that showed the step by torque or by motion both ways), it probes again from
    /// a new hold, up to [`decision::MAX_PROBES`] times: the later checks all need a usable joint.
    pub(super) fn calibrate(&mut self) -> Result<Calibration, ConformError> {
        let first = self.target.samples.len();
        let mut statuses = Vec::new();
        let mut result = loop {
            self.joints.clear();
            self.rejected.clear();
            let result = self.calibrate_once()?;
            statuses.push(result.status.name());
            if self.joints.iter().any(TestJoint::usable) || statuses.len() >= decision::MAX_PROBES as usize {
                break result;
            }
        };
        result.probes = u32::try_from(statuses.len()).unwrap_or(u32::MAX);
        let result = result.with("probe_statuses", statuses);
        Ok(Calibration { result, driven: first..self.target.samples.len() })
    }

    fn calibrate_once(&mut self) -> Result<CheckResult, ConformError> {
        let held = self.settle_for(2.0 * self.timing.hold)?;
        self.choose_joints(&held);
        if self.joints.is_empty() {
            let result = CheckResult::new(
                CheckId::CmdValidMovesJoint,
                Status::Inconclusive,
                format!("no arm joint is free to test: {}", self.rejected.join("; ")),
            )
            .with("rejected_candidates", &self.rejected)
            .with("tilt_deg", self.tilt.map(f64::to_degrees));
            return Ok(result);
        }
        let mut residual = vec![(Vec::new(), Vec::new(), Vec::new()); self.joints.len()];
        let mut bytes_example = Vec::new();
        for pass in 0..2 {
            let sign = if pass == 0 { 1.0 } else { -1.0 };
            let held = self.settle()?;
            let step = self.with_joints_where(
                &self.hold,
                &held.reference,
                sign,
                |_| true,
                |j, r, d, m| {
                    m.q = commands::clamp_target(j.slot, r + d * j.step);
                },
            );
            let bytes = wire(&step);
            if pass == 0 {
                bytes_example.clone_from(&bytes);
            }
            let range = self.send(self.timing.probe, bytes, false)?;
            let end_pose = tail_pose(&self.target.samples[range.clone()], self.timing.tail);
            for j in &mut self.joints {
                let d = j.dir * sign;
                j.moved[pass] = end_pose.map(|q| f64::from((q[j.slot] - held.reference[j.slot]) * d / j.step));
            }
            let settled = self.settled_part(&range).to_vec();
            for (k, j) in self.joints.iter().enumerate() {
                let hm = &self.hold.motor_cmd[j.slot];
                let sm = &step.motor_cmd[j.slot];
                for (_, s) in decoded(&settled) {
                    let js = joint_sample(s, j.slot);
                    residual[k].0.push(js.tau - pd(sm, js, j.limit));
                    residual[k].1.push(js.tau - pd(hm, js, j.limit));
                    residual[k].2.push(pd(sm, js, j.limit) - pd(hm, js, j.limit));
                }
            }
        }
        for (j, (to_step, to_hold, sep)) in self.joints.iter_mut().zip(residual) {
            j.torque_residual_step_nm = rms(to_step.into_iter());
            j.torque_residual_hold_nm = rms(to_hold.into_iter());
            j.torque_separation_nm = rms(sep.into_iter());
            let sep = j.torque_separation_nm;
            j.torque = sep >= MIN_SEPARATION_NM && j.torque_residual_step_nm <= TORQUE_FIT * sep;
            j.motion = j.moved.iter().all(|m| m.is_some_and(|f| f >= MOVED_FRACTION));
        }
        Ok(self.valid_result(&bytes_example))
    }

    fn choose_joints(&mut self, held: &Held) {
        let tail = self.tail_part(&held.range).to_vec();
        let states: Vec<&hg::LowState_> = decoded(&tail).map(|(_, s)| s).collect();
        self.tilt = states.last().map(|s| tilt(s.imu_state.quaternion)).filter(|t| t.is_finite());
        let mut dir = 1.0f32;
        for slot in CANDIDATE_SLOTS {
            if self.joints.len() >= MAX_TEST_JOINTS {
                break;
            }
            let joint = &h1_2::JOINTS[slot];
            let qs: Vec<f32> = states.iter().map(|s| s.motor_state[slot].q).collect();
            if qs.is_empty() || qs.iter().any(|q| !q.is_finite()) {
                self.rejected.push(format!("{}: no finite position", joint.name));
                continue;
            }
            let q = held.reference[slot];
            let spread =
                qs.iter().fold(f32::NEG_INFINITY, |a, b| a.max(*b)) - qs.iter().fold(f32::INFINITY, |a, b| a.min(*b));
            let speed = states.iter().map(|s| s.motor_state[slot].dq.abs()).fold(0.0f32, f32::max);
            let torque = mean(states.iter().map(|s| f64::from(s.motor_state[slot].tau_est)));
            let room = (q - joint.lower - RANGE_MARGIN).min(joint.upper - RANGE_MARGIN - q);
            let why = if room < MIN_STEP_RAD {
                Some(format!(
                    "{} at {q:.2} rad has {room:.2} rad of room to its range [{}, {}]",
                    joint.name, joint.lower, joint.upper
                ))
            } else if spread > SETTLED_RANGE_RAD || !(speed <= SETTLED_SPEED) {
                Some(format!(
                    "{} not settled (moved {spread:.3} rad, |dq| up to {speed:.2} rad/s while held)",
                    joint.name
                ))
            } else if torque.abs() > LOADED_FRACTION * f64::from(joint.torque_limit) {
                Some(format!("{} loaded ({torque:.1} N·m of its {} N·m)", joint.name, joint.torque_limit))
            } else {
                None
            };
            if let Some(why) = why {
                self.rejected.push(why);
                continue;
            }
            self.joints.push(TestJoint {
                slot,
                name: joint.name,
                step: STEP_RAD.min(room),
                dir,
                limit: f64::from(joint.torque_limit),
                moved: [None, None],
                torque_residual_step_nm: f64::NAN,
                torque_residual_hold_nm: f64::NAN,
                torque_separation_nm: f64::NAN,
                torque: false,
                motion: false,
            });
            dir = -dir;
        }
        let tested: Vec<usize> = self.joints.iter().map(|j| j.slot).collect();
        self.carrier = [26usize, 19, 24, 17, 12].into_iter().find(|s| !tested.contains(s)).unwrap_or(12);
        // Joints under a load whose tau_est follows the hold's PD law: they show the whole robot's torque.
        self.loaded = (0..h1_2::NUM_JOINTS)
            .filter(|slot| !tested.contains(slot))
            .filter(|&slot| {
                let limit = f64::from(h1_2::JOINTS[slot].torque_limit);
                let m = &self.hold.motor_cmd[slot];
                let predicted = mean(states.iter().map(|s| pd(m, joint_sample(s, slot), limit)));
                let reported = mean(states.iter().map(|s| f64::from(s.motor_state[slot].tau_est)));
                predicted.abs() >= LOAD_MIN_NM.max(0.05 * limit)
                    && (reported - predicted).abs() <= LOAD_FIT * predicted.abs() + 0.5
            })
            .collect();
    }

    fn joints_evidence(&self) -> serde_json::Value {
        serde_json::to_value(&self.joints).unwrap_or_default()
    }

    fn valid_result(&self, example: &[u8]) -> CheckResult {
        let applied: Vec<&TestJoint> = self.joints.iter().filter(|j| j.applied()).collect();
        let by_torque: Vec<&str> = self.joints.iter().filter(|j| j.torque).map(|j| j.name).collect();
        let by_motion: Vec<&str> = self
            .joints
            .iter()
            .filter(|j| j.moved.iter().any(|m| m.is_some_and(|f| f >= MOVED_FRACTION)))
            .map(|j| j.name)
            .collect();
        let follows_hold: Vec<&str> = self
            .joints
            .iter()
            .filter(|j| {
                j.torque_separation_nm >= MIN_SEPARATION_NM
                    && j.torque_residual_hold_nm <= TORQUE_FIT * j.torque_separation_nm
            })
            .map(|j| j.name)
            .collect();
        let upright = self.tilt.is_some_and(|t| t <= UPRIGHT_TILT_RAD);
        let tilt = self.tilt.map_or("unknown".to_owned(), |t| format!("{:.0} deg", t.to_degrees()));
        let names: Vec<&str> = self.joints.iter().map(|j| j.name).collect();
        let (status, summary) = if !applied.is_empty() {
            (
                Status::Pass,
                format!(
                    "a valid step of {} was applied: {}{}",
                    names.join(", "),
                    if by_motion.is_empty() {
                        String::new()
                    } else {
                        format!("moved {} by >= {:.0} % of the step", by_motion.join(", "), MOVED_FRACTION * 100.0)
                    },
                    if by_torque.is_empty() {
                        String::new()
                    } else {
                        format!(
                            "{}tau_est of {} follows the step's PD law",
                            if by_motion.is_empty() { "" } else { "; " },
                            by_torque.join(", ")
                        )
                    }
                ),
            )
        } else if !follows_hold.is_empty() {
            (
                Status::Fail,
                format!(
                    "a valid step was not applied: tau_est of {} kept following the hold's PD law, none of {} moved",
                    follows_hold.join(", "),
                    names.join(", ")
                ),
            )
        } else if upright {
            (
                Status::Fail,
                format!(
                    "a valid step was not applied: the robot is upright (tilt {tilt}) and none of the free joints {} moved or reported the step's torque",
                    names.join(", ")
                ),
            )
        } else {
            (
                Status::Inconclusive,
                format!(
                    "the robot is down (tilt {tilt}): none of {} moved and tau_est follows no PD law, so pinned joints cannot be told from an ignored command",
                    names.join(", ")
                ),
            )
        };
        // A joint shows the step by torque (its tau_est fits the step's law) or by motion: the best-shown joint
        // decides.
        let margin = strongest(self.joints.iter().flat_map(|j| {
            let torque = (j.torque_separation_nm >= MIN_SEPARATION_NM).then(|| {
                Margin::at_most(
                    "torque_residual_over_separation",
                    j.torque_residual_step_nm / j.torque_separation_nm,
                    TORQUE_FIT,
                )
            });
            let motion = j
                .moved
                .iter()
                .flatten()
                .copied()
                .reduce(f64::max)
                .map(|m| Margin::at_least("fraction_of_step_moved", m, MOVED_FRACTION));
            [torque, motion].into_iter().flatten()
        }));
        CheckResult::new(CheckId::CmdValidMovesJoint, status, summary)
            .with_margin(margin)
            .with("test_joints", self.joints_evidence())
            .with("rejected_candidates", &self.rejected)
            .with("tilt_deg", self.tilt.map(|t| round(t.to_degrees(), 1)))
            .with(
                "loaded_joints_reporting_torque",
                self.loaded.iter().map(|s| h1_2::JOINTS[*s].name).collect::<Vec<_>>(),
            )
            .with("probe_bytes_hex", hex(example, 64))
    }

    fn no_usable_joint(&self, id: CheckId) -> Option<CheckResult> {
        if self.joints.iter().any(TestJoint::usable) {
            return None;
        }
        Some(
            CheckResult::new(
                id,
                Status::Inconclusive,
                if self.joints.is_empty() {
                    "no free joint to test with (see cmd_valid_moves_joint)".to_owned()
                } else {
                    "no test joint showed a valid command applied, by motion both ways or by tau_est (see cmd_valid_moves_joint): nothing to compare a refused command with".to_owned()
                },
            )
            .with("test_joints", self.joints_evidence())
            .with_probes(0),
        )
    }

    // -----------------------------------------------------------------------------------------
    // Probes judged against interpretations.

    /// Runs one case: with torque evidence, one run (directions alternate across joints); with motion evidence
    /// only, two runs in opposite directions. Returns the effect and its evidence.
    fn run_case<F>(&mut self, make: F) -> Result<(Effect, serde_json::Value), ConformError>
    where
        F: Fn(&Self, &[f32; h1_2::NUM_JOINTS], f32) -> Case,
    {
        let torque_joints: Vec<TestJoint> = self.joints.iter().filter(|j| j.torque).cloned().collect();
        if !torque_joints.is_empty() {
            let held = self.settle()?;
            let case = make(self, &held.reference, 1.0);
            let range = self.send(self.timing.probe, case.bytes.clone(), true)?;
            self.last_probe = Some((held.range.clone(), range.clone()));
            let hold_tail = self.tail_part(&held.range).to_vec();
            let probe = self.settled_part(&range).to_vec();
            let duty = match (probe.first(), probe.last()) {
                (Some(a), Some(b)) => probe_duty(&self.target.tick_times, a.t, b.t),
                _ => None,
            };
            let mut effects = Vec::new();
            let mut details = Vec::new();
            for j in &torque_joints {
                let (effect, detail) = self.torque_effect(j, &case, &hold_tail, &probe, duty);
                effects.push(effect);
                details.push(detail);
            }
            let effect = combine(effects.into_iter());
            return Ok((
                effect,
                json!({"case": case.name, "evidence": "tau_est", "effect": effect, "joints": details,
                       "samples": probe.len(), "probe_duty": duty.map(|d| round(d, 3)),
                       "bytes_hex": hex(&case.bytes, 64)}),
            ));
        }
        let motion_joints: Vec<TestJoint> = self.joints.iter().filter(|j| j.motion).cloned().collect();
        let probe_case = make(self, &[0.0; h1_2::NUM_JOINTS], 1.0);
        let (Some(sign), false) = (probe_case.motion_sign, motion_joints.is_empty()) else {
            return Ok((
                Effect::Undecidable,
                json!({"case": probe_case.name, "effect": Effect::Undecidable,
                       "why": if motion_joints.is_empty() { "no joint reports tau_est by the PD law and none moves both ways" } else { "only tau_est could show this case, and no joint reports it by the PD law" }}),
            ));
        };
        let mut displacement = vec![[f64::NAN; 2]; motion_joints.len()];
        let mut duties = [None; 2];
        let mut name = String::new();
        for (pass, pass_sign) in [1.0f32, -1.0].into_iter().enumerate() {
            let held = self.settle()?;
            let case = make(self, &held.reference, pass_sign);
            name = case.name.clone();
            let range = self.send(self.timing.probe, case.bytes.clone(), true)?;
            self.last_probe = Some((held.range.clone(), range.clone()));
            // The end pose shows what was in force over the tail it is averaged on.
            let last = self.target.samples[range.clone()].last().map(|s| s.t);
            duties[pass] = last.and_then(|t| probe_duty(&self.target.tick_times, t - self.timing.tail, t));
            let end = tail_pose(&self.target.samples[range], self.timing.tail);
            for (k, j) in motion_joints.iter().enumerate() {
                let d = j.dir * pass_sign;
                displacement[k][pass] =
                    end.map_or(f64::NAN, |q| f64::from((q[j.slot] - held.reference[j.slot]) * d / j.step));
            }
        }
        let mut effects = Vec::new();
        let mut details = Vec::new();
        // Both passes must have had their probe in force for its share; the fraction is scaled by the mean share.
        let duty = match duties {
            [Some(a), Some(b)] if a.min(b) >= MIN_DUTY => Some(0.5 * (a + b)),
            _ => None,
        };
        for (k, j) in motion_joints.iter().enumerate() {
            // Gravity and sag are the same in both runs; projected on opposite directions they cancel.
            let mean_disp = 0.5 * (displacement[k][0] + displacement[k][1]) * f64::from(sign);
            let fraction = duty.map_or(f64::NAN, |d| mean_disp / d);
            let effect = judge(&[Some(fraction)]);
            effects.push(effect);
            details.push(json!({"joint": j.name, "displacement_fraction": displacement[k].map(|d| round(d, 3)),
                                "fraction_of_unsafe_effect": round(fraction, 3), "effect": effect}));
        }
        let effect = combine(effects.into_iter());
        Ok((
            effect,
            json!({"case": name, "evidence": "motion (two runs, opposite directions)", "effect": effect, "joints": details,
                   "probe_duty": duties.map(|d| d.map(|d| round(d, 3)))}),
        ))
    }

    /// Reads one joint's `tau_est` during an alternating probe against the case's interpretations.
    fn torque_effect(
        &self,
        j: &TestJoint,
        case: &Case,
        hold_tail: &[StateSample],
        probe: &[StateSample],
        duty: Option<f64>,
    ) -> (Effect, serde_json::Value) {
        let h = &self.hold.motor_cmd[j.slot];
        let u = &case.unsafe_.motor_cmd[j.slot];
        let samples: Vec<JointSample> = decoded(probe).map(|(_, s)| joint_sample(s, j.slot)).collect();
        let observed;
        let expected_unsafe;
        let mut expected_safe = Vec::new();
        match case.metric {
            Metric::Signed => {
                let hold = mean(samples.iter().map(|s| pd(h, *s, j.limit)));
                observed = mean(samples.iter().map(|s| s.tau));
                expected_unsafe = (1.0 - DUTY) * hold + DUTY * mean(samples.iter().map(|s| pd(u, *s, j.limit)));
                for (name, c) in &case.safe {
                    let m = &c.motor_cmd[j.slot];
                    expected_safe
                        .push((*name, (1.0 - DUTY) * hold + DUTY * mean(samples.iter().map(|s| pd(m, *s, j.limit)))));
                }
            }
            Metric::Activity => {
                // The hold's own residual is the floor of |tau - law|.
                let floor = mean(decoded(hold_tail).map(|(_, s)| {
                    let js = joint_sample(s, j.slot);
                    (js.tau - pd(h, js, j.limit)).abs()
                }));
                let floor = if floor.is_finite() { floor } else { 0.0 };
                observed = mean(samples.iter().map(|s| (s.tau - pd(h, *s, j.limit)).abs())) - floor;
                expected_unsafe = DUTY * mean(samples.iter().map(|s| (pd(u, *s, j.limit) - pd(h, *s, j.limit)).abs()));
                for (name, c) in &case.safe {
                    let m = &c.motor_cmd[j.slot];
                    expected_safe.push((
                        *name,
                        DUTY * mean(samples.iter().map(|s| (pd(m, *s, j.limit) - pd(h, *s, j.limit)).abs())),
                    ));
                }
            }
        }
        // The verdict counts samples instead of comparing the means above: at each sample where the unsafe law is
        // at least MIN_SEPARATION_NM from the hold's and from every safe reading, which law does tau_est follow?
        // A conformant peer's samples never follow the unsafe law, however its steps split between the hold and
        // the probe (on a loaded host the alternating messages arrive in bursts, so that split is not DUTY).
        let mut separable = 0usize;
        let mut follows_unsafe = 0usize;
        for s in samples.iter().filter(|s| s.tau.is_finite()) {
            let unsafe_law = pd(u, *s, j.limit);
            let others: Vec<f64> = std::iter::once(pd(h, *s, j.limit))
                .chain(case.safe.iter().map(|(_, c)| pd(&c.motor_cmd[j.slot], *s, j.limit)))
                .collect();
            let apart = others.iter().map(|o| (unsafe_law - o).abs()).fold(f64::INFINITY, f64::min);
            if !(apart >= MIN_SEPARATION_NM && unsafe_law.is_finite()) {
                continue;
            }
            separable += 1;
            let nearest_other = others.iter().map(|o| (s.tau - o).abs()).fold(f64::INFINITY, f64::min);
            if (s.tau - unsafe_law).abs() < nearest_other {
                follows_unsafe += 1;
            }
        }
        // A peer applying the probe follows its law for the share of the time the probe was in force: scaled by that
        // share, 1 is full application. A probe in force too little of the time (a starved sender) cannot show it.
        let fraction = match duty {
            Some(d) if d >= MIN_DUTY && separable >= MIN_SEPARABLE_SAMPLES => {
                Some(follows_unsafe as f64 / separable as f64 / d)
            }
            _ => None,
        };
        let effect = judge(&[fraction]);
        (
            effect,
            json!({
                "joint": j.name,
                "observed_nm": round(observed, 3),
                "expected_unsafe_nm": round(expected_unsafe, 3),
                "expected_safe_nm": expected_safe.iter().map(|(n, e)| json!({"reading": n, "nm": round(*e, 3)})).collect::<Vec<_>>(),
                "separable_samples": separable,
                "samples_following_unsafe_law": follows_unsafe,
                "fraction_of_unsafe_effect": fraction.map(|x| round(x, 3)),
                "effect": effect,
            }),
        )
    }

    /// Verdict of a check made of cases: fail on any unsafe case, pass when every case was shown safe.
    fn verdict(&self, id: CheckId, what: &str, outcomes: Vec<(String, Effect, serde_json::Value)>) -> CheckResult {
        let unsafe_: Vec<&str> = outcomes.iter().filter(|o| o.1 == Effect::Unsafe).map(|o| o.0.as_str()).collect();
        let open: Vec<&str> = outcomes
            .iter()
            .filter(|o| matches!(o.1, Effect::Unclear | Effect::Undecidable))
            .map(|o| o.0.as_str())
            .collect();
        let joints: Vec<&str> = self.joints.iter().filter(|j| j.usable()).map(|j| j.name).collect();
        let (status, summary) = if !unsafe_.is_empty() {
            (
                Status::Fail,
                format!("{what}: applied in {} of {} cases: {}", unsafe_.len(), outcomes.len(), unsafe_.join("; ")),
            )
        } else if open.is_empty() {
            (
                Status::Pass,
                format!(
                    "{what}: all {} cases rejected or made harmless, judged on {}",
                    outcomes.len(),
                    joints.join(", ")
                ),
            )
        } else {
            (
                Status::Inconclusive,
                format!("{what}: not applied where visible, but undecided in {}: {}", open.len(), open.join("; ")),
            )
        };
        let margin = verdict_margin(status, &outcomes);
        CheckResult::new(id, status, summary)
            .with_margin(margin)
            .with("cases", outcomes.into_iter().map(|o| o.2).collect::<Vec<_>>())
            .with("test_joints", self.joints_evidence())
    }

    // -----------------------------------------------------------------------------------------
    // The checks.

    pub(super) fn bad_crc_ignored(&mut self) -> Result<CheckResult, ConformError> {
        if let Some(r) = self.no_usable_joint(CheckId::CmdBadCrcIgnored) {
            return Ok(r);
        }
        let (effect, detail) = self.run_case(|s, r, sign| {
            let step = s.stepped(r, sign);
            Case {
                name: "valid step with every CRC bit flipped".into(),
                bytes: wire(&commands::bad_crc(&step)),
                unsafe_: step,
                safe: vec![("ignored (the hold stays in force)", s.hold.clone())],
                metric: Metric::Signed,
                motion_sign: Some(1.0),
            }
        })?;
        Ok(self.verdict(
            CheckId::CmdBadCrcIgnored,
            "commands with a wrong CRC (alternating with the valid hold)",
            vec![("bad CRC".into(), effect, detail)],
        ))
    }

    pub(super) fn mode0_no_torque(&mut self) -> Result<CheckResult, ConformError> {
        if let Some(r) = self.no_usable_joint(CheckId::CmdMode0NoTorque) {
            return Ok(r);
        }
        let (effect, detail) = self.run_case(|s, r, sign| {
            let step = s.stepped(r, sign);
            let mut off = step.clone();
            let mut zero = step.clone();
            for j in s.joints.iter().filter(|j| j.usable()) {
                off.motor_cmd[j.slot].mode = 0;
                zero.motor_cmd[j.slot] = hg::MotorCmd_::default();
            }
            crc::seal(&mut off);
            Case {
                name: "valid step with the test joints in motor mode 0".into(),
                bytes: wire(&off),
                unsafe_: step,
                safe: vec![("mode 0 honoured (no torque)", zero)],
                metric: Metric::Signed,
                motion_sign: Some(1.0),
            }
        })?;
        Ok(self.verdict(
            CheckId::CmdMode0NoTorque,
            "test joints in mode 0 with stiff far targets",
            vec![("mode 0".into(), effect, detail)],
        ))
    }

    pub(super) fn absurd_gains_safe(&mut self) -> Result<CheckResult, ConformError> {
        if let Some(r) = self.no_usable_joint(CheckId::CmdAbsurdGainsSafe) {
            return Ok(r);
        }
        let mut outcomes = Vec::new();
        // Negative stiffness toward a target 0.05 rad away: applied, it pushes the joint away from the target.
        let (e, d) = self.run_case(|s, r, sign| {
            let p = s.with_joints(&s.hold, r, sign, |j, r, d, m| {
                m.q = commands::clamp_target(j.slot, r + d * 0.05);
                m.kp = -500.0;
            });
            let clamped = s.with_joints(&p, r, sign, |_, _, _, m| m.kp = 0.0);
            Case {
                name: "kp = -500 toward a target 0.05 rad away".into(),
                bytes: wire(&p),
                unsafe_: p,
                safe: vec![("rejected", s.hold.clone()), ("kp clamped to 0", clamped)],
                metric: Metric::Signed,
                motion_sign: Some(-1.0),
            }
        })?;
        outcomes.push(("kp = -500".to_owned(), e, d));
        // Negative damping with a velocity target: applied, it pushes against the target velocity.
        let (e, d) = self.run_case(|s, r, sign| {
            let p = s.with_joints(&s.hold, r, sign, |_, r, d, m| {
                m.q = r;
                m.dq = 0.4 * d;
                m.kd = -50.0;
            });
            let clamped = s.with_joints(&p, r, sign, |_, _, _, m| m.kd = 0.0);
            Case {
                name: "kd = -50 with a target speed of 0.4 rad/s".into(),
                bytes: wire(&p),
                unsafe_: p,
                safe: vec![("rejected", s.hold.clone()), ("kd clamped to 0", clamped)],
                metric: Metric::Signed,
                motion_sign: Some(-1.0),
            }
        })?;
        outcomes.push(("kd = -50".to_owned(), e, d));
        // A huge stiffness toward a target 4 mrad away: applied, the motor saturates (bang-bang) where a gain clamped
        // to the sane maximum asks for a few N·m. Only tau_est shows it.
        let (e, d) = self.run_case(|s, r, sign| {
            let p = s.with_joints(&s.hold, r, sign, |j, r, d, m| {
                m.q = commands::clamp_target(j.slot, r + d * 0.004);
                m.kp = 1.0e6;
            });
            let clamped = s.with_joints(&p, r, sign, |_, _, _, m| m.kp = h1_2::KP_MAX);
            Case {
                name: "kp = 1e6 toward a target 4 mrad away".into(),
                bytes: wire(&p),
                unsafe_: p,
                safe: vec![("rejected", s.hold.clone()), ("kp clamped to KP_MAX", clamped)],
                metric: Metric::Activity,
                motion_sign: None,
            }
        })?;
        outcomes.push(("kp = 1e6".to_owned(), e, d));
        Ok(self.verdict(CheckId::CmdAbsurdGainsSafe, "absurd gains on the test joints", outcomes))
    }

    pub(super) fn non_finite_rejected(&mut self) -> Result<CheckResult, ConformError> {
        if let Some(r) = self.no_usable_joint(CheckId::CmdNonFiniteRejected) {
            return Ok(r);
        }
        let carrier = self.carrier;
        let carrier_name = h1_2::JOINTS[carrier].name;
        let cases: [(&str, fn(&mut hg::MotorCmd_)); 3] = [
            ("q = NaN", |m| m.q = f32::NAN),
            ("kp = +inf", |m| m.kp = f32::INFINITY),
            ("tau = NaN", |m| m.tau = f32::NAN),
        ];
        let mut outcomes = Vec::new();
        for (what, poison) in cases {
            let name = format!("{carrier_name} {what}, test joints stepped");
            let (applied, mut detail) = self.run_case(|s, r, sign| {
                let step = s.stepped(r, sign);
                let mut p = step.clone();
                poison(&mut p.motor_cmd[carrier]);
                crc::seal(&mut p);
                Case {
                    name: name.clone(),
                    bytes: wire(&p),
                    unsafe_: step,
                    safe: vec![("rejected", s.hold.clone())],
                    metric: Metric::Signed,
                    motion_sign: Some(1.0),
                }
            })?;
            // The same probe's samples: did the robot go limp, or its state become non-finite?
            let limp = self.limp_effect();
            let effect = match (applied, limp.0) {
                (Effect::Unsafe, _) | (_, Effect::Unsafe) => Effect::Unsafe,
                (Effect::Safe, Effect::Safe) => Effect::Safe,
                (Effect::Safe, Effect::Undecidable) if self.joints.iter().any(|j| j.torque) => {
                    // No loaded joint to watch: tau_est of the test joints still shows the hold in force, which a
                    // limp robot would not report (its motors give no torque at all).
                    self.test_joints_hold_kept()
                }
                (a, _) => a,
            };
            let response = NonFiniteResponse::classify(applied, limp.0, limp.2, effect);
            if let Some(obj) = detail.as_object_mut() {
                obj.insert("applied_effect".into(), json!(applied));
                obj.insert("limp".into(), limp.1);
                obj.insert("effect".into(), json!(effect));
                obj.insert("response".into(), json!(response));
            }
            let label = match response {
                NonFiniteResponse::Rejected => String::new(),
                other => format!(" ({})", other.describe()),
            };
            outcomes.push((format!("{what} on {carrier_name}{label}"), effect, detail));
        }
        Ok(self.verdict(
            CheckId::CmdNonFiniteRejected,
            "messages with one non-finite value (the rest a valid step): rejected whole, not applied in part, no limp robot, no non-finite state",
            outcomes,
        ))
    }

    /// Whether the last probe left the robot limp: the torque of loaded joints collapsing toward zero during the
    /// probe's half of the time, non-finite state, or joints not under test knocked out of their hold.
    /// Also returns how many of the probe's states carried non-finite values.
    fn limp_effect(&self) -> (Effect, serde_json::Value, usize) {
        let Some((hold, probe)) = self.last_probe.clone() else {
            return (Effect::Undecidable, json!({"why": "no probe ran"}), 0);
        };
        let probe = self.settled_part(&probe);
        let hold = self.tail_part(&hold);
        let non_finite = decoded(probe).filter(|(_, s)| !validate::non_finite(*s).is_empty()).count();
        let tested: Vec<usize> = self.joints.iter().map(|j| j.slot).collect();
        let reference = tail_pose(hold, self.timing.tail);
        let mut worst = (0.0f32, "");
        if let Some(r) = reference {
            for (_, s) in decoded(probe) {
                for j in h1_2::JOINTS.iter().filter(|j| !tested.contains(&j.slot)) {
                    let dev = (s.motor_state[j.slot].q - r[j.slot]).abs();
                    if dev > worst.0 {
                        worst = (dev, j.name);
                    }
                }
            }
        }
        let (mut kept, mut full) = (0.0, 0.0);
        for &slot in &self.loaded {
            let limit = f64::from(h1_2::JOINTS[slot].torque_limit);
            let m = &self.hold.motor_cmd[slot];
            let states: Vec<JointSample> = decoded(probe).map(|(_, s)| joint_sample(s, slot)).collect();
            let predicted = mean(states.iter().map(|s| pd(m, *s, limit)));
            let reported = mean(states.iter().map(|s| s.tau));
            if predicted.is_finite() && reported.is_finite() {
                // Limp during the probe's half: E = (1 - DUTY) * predicted; kept: E = predicted.
                let sign = predicted.signum();
                kept += sign * (reported - (1.0 - DUTY) * predicted);
                full += sign * DUTY * predicted;
            }
        }
        let retained = (full >= MIN_SEPARATION_NM).then(|| kept / full);
        let effect = if non_finite > 0 || worst.0 > DISTURBED_RAD {
            Effect::Unsafe
        } else {
            match retained {
                Some(r) if r <= APPLIED => Effect::Unsafe,
                Some(r) if r >= 1.0 - NOT_APPLIED => Effect::Safe,
                Some(_) => Effect::Unclear,
                None => Effect::Undecidable,
            }
        };
        (
            effect,
            json!({
                "effect": effect,
                "non_finite_states": non_finite,
                "loaded_joints": self.loaded.len(),
                "hold_torque_retained": retained.map(|r| round(r, 3)),
                "worst_other_joint_deviation_rad": round(f64::from(worst.0), 4),
                "worst_other_joint": worst.1,
            }),
            non_finite,
        )
    }

    /// With no loaded joint to watch, the test joints' tau_est during the last probe: still the hold's (safe) or
    /// collapsed to zero (limp).
    fn test_joints_hold_kept(&self) -> Effect {
        let Some((_, probe)) = self.last_probe.clone() else { return Effect::Undecidable };
        let probe: Vec<&hg::LowState_> = decoded(self.settled_part(&probe)).map(|(_, s)| s).collect();
        let mut effects = Vec::new();
        for j in self.joints.iter().filter(|j| j.torque) {
            let m = &self.hold.motor_cmd[j.slot];
            let predicted = mean(probe.iter().map(|s| pd(m, joint_sample(s, j.slot), j.limit)));
            let reported = mean(probe.iter().map(|s| f64::from(s.motor_state[j.slot].tau_est)));
            if predicted.abs() >= MIN_SEPARATION_NM {
                let retained = (reported - (1.0 - DUTY) * predicted) / (DUTY * predicted);
                effects.push(if retained >= 1.0 - NOT_APPLIED {
                    Effect::Safe
                } else if retained <= APPLIED {
                    Effect::Unsafe
                } else {
                    Effect::Unclear
                });
            }
        }
        if effects.is_empty() {
            // Nothing loaded anywhere: a limp motor and a holding one give the same (zero) torque, and no joint
            // would move either way. The message was not applied, and nothing could have been harmed.
            Effect::Safe
        } else {
            combine(effects.into_iter())
        }
    }

    // -----------------------------------------------------------------------------------------
    // Command loss.

    /// Steps the usable joints with a short valid pulse, stops sending, and reads what the peer does with the last
    /// command: keeps it (its PD law, or the last torque held constant), damps (tau = -c dq) or releases (tau = 0).
    /// Keeping a command forever fails: a crashed controller would leave its torques on the robot.
    pub(super) fn timeout_behaviour(&mut self) -> Result<CheckResult, ConformError> {
        if let Some(r) = self.no_usable_joint(CheckId::CmdTimeoutBehaviour) {
            return Ok(r);
        }
        let held = self.settle()?;
        let command = self.stepped(&held.reference, 1.0);
        let pulse = (4.0 * self.timing.period).max(0.05);
        let sent = self.send(pulse, wire(&command), false)?;
        let stop_t = self.target.elapsed();
        let last_before: Option<hg::LowState_> = self.target.latest().cloned();
        let after = self.target.observe(self.timing.silence)?;
        let samples = self.target.samples[after.clone()].to_vec();
        let gap = max_gap(&samples, stop_t, self.target.elapsed());
        if gap > self.timing.gap_limit {
            return Ok(CheckResult::new(
                CheckId::CmdTimeoutBehaviour,
                Status::Fail,
                format!(
                    "LowState stopped after commands stopped (gap {:.0} ms, limit {:.0} ms)",
                    gap * 1e3,
                    self.timing.gap_limit * 1e3
                ),
            )
            .with("max_gap_ms", round(gap * 1e3, 1))
            .with_margin(Some(Margin::at_most("max_gap_ms", gap * 1e3, self.timing.gap_limit * 1e3))));
        }
        let window: Vec<&hg::LowState_> =
            decoded(&samples).filter(|(t, _)| *t >= stop_t + SILENCE_GRACE_S).map(|(_, s)| s).collect();
        let mut joints: Vec<(usize, &'static str, f64)> =
            self.joints.iter().filter(|j| j.torque).map(|j| (j.slot, j.name, j.limit)).collect();
        joints.extend(self.loaded.iter().map(|&s| (s, h1_2::JOINTS[s].name, f64::from(h1_2::JOINTS[s].torque_limit))));
        let mut votes = Vec::new();
        let mut margins = Vec::new();
        let mut details = Vec::new();
        for (slot, name, limit) in joints {
            let m = &command.motor_cmd[slot];
            let last = last_before.as_ref().map_or(0.0, |s| f64::from(s.motor_state[slot].tau_est));
            let js: Vec<JointSample> = window.iter().map(|s| joint_sample(s, slot)).collect();
            if js.len() < 5 {
                continue;
            }
            let dq2: f64 = js.iter().map(|s| f64::from(s.dq).powi(2)).sum();
            let c =
                if dq2 > 0.0 { (-js.iter().map(|s| s.tau * f64::from(s.dq)).sum::<f64>() / dq2).max(0.0) } else { 0.0 };
            let laws: [(Loss, Vec<f64>); 4] = [
                (Loss::KeepsCommand, js.iter().map(|s| pd(m, *s, limit)).collect()),
                (Loss::KeepsTorque, js.iter().map(|_| last).collect()),
                (Loss::Damps, js.iter().map(|s| -c * f64::from(s.dq)).collect()),
                (Loss::Releases, js.iter().map(|_| 0.0).collect()),
            ];
            let residual: Vec<f64> = laws.iter().map(|(_, p)| rms(js.iter().zip(p).map(|(s, p)| s.tau - p))).collect();
            let best = (0..4).min_by(|a, b| residual[*a].total_cmp(&residual[*b])).unwrap_or(3);
            // Every law that predicts something else must fit clearly worse.
            let mut decided = true;
            for k in 0..4 {
                let apart = rms(laws[k].1.iter().zip(&laws[best].1).map(|(a, b)| a - b));
                if k != best
                    && laws[k].0.keeps() != laws[best].0.keeps()
                    && (apart < MIN_SEPARATION_NM || residual[k] < 2.0 * residual[best] + 0.3)
                {
                    decided = false;
                }
            }
            if decided {
                votes.push(laws[best].0);
            }
            // The decision's closeness: the best law of the other kind (keeping vs not keeping the command) against
            // the residual it had to exceed.
            let opposing = (0..4)
                .filter(|&k| laws[k].0.keeps() != laws[best].0.keeps())
                .map(|k| residual[k])
                .fold(f64::INFINITY, f64::min);
            margins.push((
                laws[best].0,
                decided,
                Margin::at_least("opposing_law_rms_nm", opposing, 2.0 * residual[best] + 0.3),
            ));
            details.push(json!({
                "joint": name,
                "residual_nm": laws.iter().zip(&residual).map(|((l, _), r)| json!({"law": l, "rms_nm": round(*r, 3)})).collect::<Vec<_>>(),
                "fitted_damping": round(c, 3),
                "last_torque_nm": round(last, 3),
                "best": laws[best].0,
                "decided": decided,
            }));
        }
        let keeps = votes.iter().find(|l| l.keeps()).copied();
        let released = votes.iter().find(|l| !l.keeps()).copied();
        let damps = votes.iter().filter(|l| **l == Loss::Damps).count();
        let releases = votes.iter().filter(|l| **l == Loss::Releases).count();
        let (status, summary) = match (keeps, released) {
            (Some(k), _) => (
                Status::Fail,
                format!(
                    "after commands stop the peer {} ({} of {} decided joints), {:.1} s and more after the last command: a dead controller's torques stay on the robot",
                    k.describe(),
                    votes.iter().filter(|l| l.keeps()).count(),
                    votes.len(),
                    SILENCE_GRACE_S
                ),
            ),
            (None, Some(_)) => (
                Status::Pass,
                format!(
                    "after commands stop the peer {} within {SILENCE_GRACE_S} s ({} decided joints: {damps} damp, {releases} release)",
                    if damps >= releases { Loss::Damps.describe() } else { Loss::Releases.describe() },
                    votes.len()
                ),
            ),
            (None, None) => (
                Status::Inconclusive,
                "after commands stop, no joint's tau_est told keeping the last command from damping or releasing it (no test or loaded joint reports torque by the PD law)".to_owned(),
            ),
        };
        // A fail rests on the most clearly keeping joint, a pass on the most clearly releasing one; undecided, on the
        // joint that came closest to deciding.
        let margin = match status {
            Status::Fail => strongest(margins.into_iter().filter(|(l, d, _)| *d && l.keeps()).map(|(_, _, m)| m)),
            Status::Pass => strongest(margins.into_iter().filter(|(l, d, _)| *d && !l.keeps()).map(|(_, _, m)| m)),
            Status::Inconclusive => strongest(margins.into_iter().map(|(_, _, m)| m)),
        };
        Ok(CheckResult::new(CheckId::CmdTimeoutBehaviour, status, summary)
            .with_margin(margin)
            .with("joints", details)
            .with("pulse_s", round(pulse, 3))
            .with("pulse_samples", sent.len())
            .with("observed_s", round(self.timing.silence, 3))
            .with("judged_from_s_after_stop", SILENCE_GRACE_S)
            .with("max_gap_ms", round(gap * 1e3, 1))
            .with("window_samples", window.len()))
    }
}

/// What a peer does with the last command when commands stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
enum Loss {
    /// Goes on applying its PD law.
    KeepsCommand,
    /// Holds the last torque it computed (unitree_mujoco's bridge: torque is computed when a command arrives).
    KeepsTorque,
    /// tau = -c dq.
    Damps,
    /// tau = 0.
    Releases,
}

impl Loss {
    fn keeps(self) -> bool {
        matches!(self, Loss::KeepsCommand | Loss::KeepsTorque)
    }
    fn describe(self) -> &'static str {
        match self {
            Loss::KeepsCommand => "keeps applying the last command's PD law",
            Loss::KeepsTorque => "keeps the last torque",
            Loss::Damps => "damps (tau = -c dq)",
            Loss::Releases => "releases (no torque)",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probe_duty_is_the_time_share_of_the_odd_ticks() {
        // Kept schedule: hold and probe alternate every 2 ms.
        let even: Vec<f64> = (0..100).map(|k| f64::from(k) * 0.002).collect();
        assert!(probe_duty(&even, 0.02, 0.18).is_some_and(|d| (d - 0.5).abs() < 0.02));
        // A stall of 100 ms after a hold tick: the hold stays in force through it.
        let mut stalled: Vec<f64> = (0..21).map(|k| f64::from(k) * 0.002).collect();
        stalled.extend((0..20).map(|k| 0.14 + f64::from(k) * 0.002));
        let d = probe_duty(&stalled, 0.0, 0.18).unwrap_or(f64::NAN);
        // 40 ms of alternation and 40 ms after the stall, half probe each: 40 ms of 180.
        assert!((d - 0.04 / 0.18).abs() < 0.02, "{d}");
        assert_eq!(probe_duty(&even, 0.1, 0.1), None);
    }

    #[test]
    fn pd_law_clamps_and_honours_mode0() {
        let m = hg::MotorCmd_ { mode: 1, q: 1.0, kp: 100.0, kd: 2.0, ..Default::default() };
        let js = JointSample { q: 0.9, dq: 0.5, tau: 0.0 };
        assert!((pd(&m, js, 50.0) - 9.0).abs() < 1e-4);
        let far = JointSample { q: -1.0, dq: 0.0, tau: 0.0 };
        assert_eq!(pd(&m, far, 18.0), 18.0);
        assert_eq!(pd(&hg::MotorCmd_ { mode: 0, ..m }, js, 50.0), 0.0);
        assert_eq!(pd(&hg::MotorCmd_ { kp: f32::INFINITY, ..m }, js, 18.0), 18.0);
        assert_eq!(pd(&hg::MotorCmd_ { q: f32::NAN, ..m }, js, 18.0), 0.0);
    }

    #[test]
    fn a_non_finite_state_outranks_a_limp_robot_which_outranks_partial_application() {
        use Effect::{Safe, Unclear, Undecidable, Unsafe};
        use NonFiniteResponse as R;
        assert_eq!(R::classify(Safe, Unsafe, 3, Unsafe), R::Undefined);
        assert_eq!(R::classify(Undecidable, Safe, 1, Unsafe), R::Undefined);
        assert_eq!(R::classify(Unsafe, Unsafe, 0, Unsafe), R::Limp);
        assert_eq!(R::classify(Unsafe, Safe, 0, Unsafe), R::AppliedInPart);
        assert_eq!(R::classify(Safe, Safe, 0, Safe), R::Rejected);
        assert_eq!(R::classify(Safe, Unclear, 0, Unclear), R::Undecided);
    }

    #[test]
    fn judging_needs_every_safe_reading_excluded_for_unsafe() {
        assert_eq!(judge(&[Some(1.0), Some(0.9)]), Effect::Unsafe);
        assert_eq!(judge(&[Some(1.0), Some(0.1)]), Effect::Safe);
        assert_eq!(judge(&[Some(0.4)]), Effect::Unclear);
        assert_eq!(judge(&[None, None]), Effect::Undecidable);
        assert_eq!(judge(&[Some(f64::NAN)]), Effect::Undecidable);
        assert_eq!(combine([Effect::Safe, Effect::Unsafe].into_iter()), Effect::Unsafe);
        assert_eq!(combine([Effect::Undecidable, Effect::Safe].into_iter()), Effect::Safe);
    }
}
