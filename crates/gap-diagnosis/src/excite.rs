//! Safe excitation plans: chirps and steps per joint group around the standing pose, within joint limits, at the
//! model's PD gains, for the suspended rig (large leg steps would topple a standing robot). Each group is moved alone (clean attribution), then all together.
use crate::log::Command;
use crate::plant::{joint_groups, GROUPS};
use robot_model::RobotModel;

/// Margin kept from every joint limit (rad).
pub const LIMIT_MARGIN: f64 = 0.1;
/// Largest excursion from the standing pose (rad).
pub const MAX_AMPLITUDE: f64 = 0.5;

/// Per-joint excitation amplitude: within limits (with margin) on both sides of the standing angle.
pub fn amplitudes(model: &RobotModel) -> Vec<f64> {
    model
        .joints
        .iter()
        .map(|j| {
            let room = (j.default_q - j.lower - LIMIT_MARGIN).min(j.upper - LIMIT_MARGIN - j.default_q).max(0.0);
            room.min(MAX_AMPLITUDE).min(0.35 * (j.upper - j.lower))
        })
        .collect()
}

/// The plan's target at time `t` (s) for a plan of `duration` s: joint targets in model order.
pub fn target(model: &RobotModel, amp: &[f64], groups: &[usize], duration: f64, t: f64) -> Vec<f64> {
    // Each segment = chirp (60 %) then steps (40 %).
    let (k, tl, seg) = segment(duration, t);
    let chirp_len = 0.6 * seg;
    let x = if tl < chirp_len {
        // Linear chirp 0.3 -> 3 Hz, amplitude ramped in over 0.3 s.
        let (f0, f1) = (0.3, 3.0);
        let phase = 2.0 * std::f64::consts::PI * (f0 * tl + 0.5 * (f1 - f0) / chirp_len * tl * tl);
        (tl / 0.3).min(1.0) * phase.sin()
    } else {
        // Steps of alternating sign (hold 0.15-0.4 s, shorter in short plans so every segment has several).
        let ts = tl - chirp_len;
        let hold = (0.1 * seg).clamp(0.15, 0.4);
        let n = (ts / hold).floor() as i64;
        if n % 2 == 0 {
            0.8
        } else {
            -0.8
        }
    };
    pose(model, amp, groups, k, 1.0, x)
}

/// The segment at time `t` of a plan of `duration` s (one per group, then one with every group): its index, the
/// time into it and its length.
fn segment(duration: f64, t: f64) -> (usize, f64, f64) {
    let ng = GROUPS.len();
    let seg = duration / (ng + 1) as f64;
    let k = ((t / seg).floor() as usize).min(ng);
    (k, t - k as f64 * seg, seg)
}

/// Joint targets of segment `k` at waveform value `x`: the segment's joints (every joint in the last one) move by
/// `scale · amp · x` from the standing pose, alternating sign along the model, within the limits' margin.
fn pose(model: &RobotModel, amp: &[f64], groups: &[usize], k: usize, scale: f64, x: f64) -> Vec<f64> {
    let ng = GROUPS.len();
    model
        .joints
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            let active = k == ng || groups[j] == k;
            let sign = if j % 2 == 0 { 1.0 } else { -1.0 };
            let q = joint.default_q + if active { sign * scale * amp[j] * x } else { 0.0 };
            q.clamp(joint.lower + LIMIT_MARGIN, joint.upper - LIMIT_MARGIN)
        })
        .collect()
}

/// Amplitude of the gentle chirp, as a fraction of the plan's ([`amplitudes`]).
pub const GENTLE_AMPLITUDE: f64 = 0.3;
/// Frequency range of the gentle chirp (Hz).
pub const GENTLE_HZ: (f64, f64) = (0.1, 1.0);

/// A gentle chirp at time `t`: the kind of motion a user records anyway (slow sweeps, no steps), with the plan's
/// segments (each group alone, then all) but [`GENTLE_AMPLITUDE`] of its amplitude (`amp`) and a sweep over
/// [`GENTLE_HZ`] that fills each segment. It excites little inertia or torque limit: the benchmark's third input
/// kind, on which such effects should be found not identifiable rather than named.
pub fn gentle_target(model: &RobotModel, amp: &[f64], groups: &[usize], duration: f64, t: f64) -> Vec<f64> {
    let (k, tl, seg) = segment(duration, t);
    let (f0, f1) = GENTLE_HZ;
    let phase = 2.0 * std::f64::consts::PI * (f0 * tl + 0.5 * (f1 - f0) / seg * tl * tl);
    pose(model, amp, groups, k, GENTLE_AMPLITUDE, (tl / 0.5).min(1.0) * phase.sin())
}

/// The plan as commands at `rate_hz` over `duration` s, gains from the model (the first second ramps from the
/// standing pose).
pub fn plan(model: &RobotModel, duration: f64, rate_hz: f64) -> Vec<Command> {
    let amp = amplitudes(model);
    let groups = joint_groups(model);
    let n = (duration * rate_hz).floor() as usize;
    (0..n)
        .map(|i| {
            let t = i as f64 / rate_hz;
            command_at(model, &amp, &groups, duration, t)
        })
        .collect()
}

/// The plan's command at time `t`.
pub fn command_at(model: &RobotModel, amp: &[f64], groups: &[usize], duration: f64, t: f64) -> Command {
    command_to(model, t, target(model, amp, groups, duration, t))
}

/// The gentle chirp's command at time `t` ([`gentle_target`]).
pub fn gentle_command_at(model: &RobotModel, amp: &[f64], groups: &[usize], duration: f64, t: f64) -> Command {
    command_to(model, t, gentle_target(model, amp, groups, duration, t))
}

/// A position command to `q` at the model's gains.
fn command_to(model: &RobotModel, t: f64, q: Vec<f64>) -> Command {
    let nj = model.nj();
    Command {
        t,
        q,
        dq: vec![0.0; nj],
        kp: model.joints.iter().map(|j| j.kp).collect(),
        kd: model.joints.iter().map(|j| j.kd).collect(),
        tau: vec![0.0; nj],
    }
}
