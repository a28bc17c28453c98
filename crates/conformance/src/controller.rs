//! Judging the CONTROLLER side (`ulab conform controller`): ulab plays the robot (publishes `rt/lowstate`,
//! consumes `rt/lowcmd`) and records every LowCmd the controller sends in a [`Trace`]; [`judge`] turns the trace
//! into one verdict per check of [`CheckId::CONTROLLER_RUN`], with its evidence.
//!
//! The decision model is this module's [`RULES`] table and the constants above it: every threshold is
//! a named constant whose doc comment gives its reason. Nothing outside this module decides a verdict.
//! Verdicts are made on message contents and counts wherever possible; the two timing checks use the
//! controller's own send timestamps (its loop, not the delivery or the judge's scheduling) over windows of
//! seconds, so that a loaded machine does not change them.

use crate::report::{CheckId, CheckResult, Status};
use lowlevel_codec::{crc, validate};
use std::collections::BTreeMap;
use unitree_idl::{h1_2, hg};

/// Nominal command rate of the H1-2 (Hz): its motor layer and LowState run at 500 Hz, and Unitree's
/// low-level examples command at the same rate.
pub const NOMINAL_RATE_HZ: f64 = 500.0;

/// Largest relative deviation of the mean command rate from [`NOMINAL_RATE_HZ`] (`ctl_rate`). A loop paced by
/// deadlines keeps its mean rate within about 1 % over seconds even when single cycles are late (it catches up);
/// a mean 10 % off is a loop paced by something else (sleeps that add the loop's own work, another nominal rate).
pub const RATE_TOLERANCE: f64 = 0.10;

/// Smallest share of the robot's control periods (2 ms at the nominal rate) in which a fresh command was sent
/// (`ctl_jitter`). The robot applies the latest command every period: a steady loop with scheduling noise covers
/// nearly all of them, a loop that sends in bursts (ten commands at once every 20 ms) covers a tenth, one at half the
/// rate a half. Under half, the robot sees a fresh command less often than every other period.
pub const MIN_PERIOD_COVERAGE: f64 = 0.5;

/// Largest gap between two commands (s) (`ctl_jitter`): half the robot's command timeout (0.1 s, after which the
/// robot stops applying commands and damps, see `ulab sim --command-timeout`), leaving the other half for delivery.
pub const MAX_GAP_S: f64 = 0.05;

/// Commands that count as the start (`ctl_start_jump`): the first second at the nominal rate, the span over
/// which Unitree's examples ramp from the measured pose to their first target.
pub const START_COMMANDS: usize = 500;

/// Share of a joint's peak torque that a start step must demand (`kp * step`) to count as a jump
/// (`ctl_start_jump`), in addition to moving the target faster than the joint's peak speed. A leap with gains so
/// low that it demands under a tenth of the motor's peak torque moves the joint gently (a start that ramps the
/// gains instead of the target).
pub const JUMP_TORQUE_FRACTION: f64 = 0.10;

/// Time a controller has to notice that LowState stopped before its commands are classified (s)
/// (`ctl_stale_state`): 250 state periods, far beyond any reasonable staleness timeout (Unitree-style
/// controllers and `ulab deploy` use 0.1 s) and any scheduling delay of a loaded machine.
pub const STALE_REACTION_S: f64 = 0.5;

/// Share of the nominal command count below which a controller counts as having stopped during the silence
/// (`ctl_stale_state`): a few stray commands (in flight when it stopped) do not make it a sender.
pub const STOPPED_SHARE: f64 = 0.05;

/// Time a controller has to notice that the robot fell before its commands are classified (s) (`ctl_fall`): the
/// judge tips the robot onto its back at once, so a tilt watch (`ulab deploy` damps past 0.7 rad) sees it within one
/// state period; 0.5 s is the same allowance as for a stale state, far beyond any scheduling delay.
pub const FALL_REACTION_S: f64 = 0.5;

/// Fewest commands a window needs for a timing verdict; fewer is inconclusive (20 ms at 500 Hz cannot show a
/// rate).
pub const MIN_TIMING_COMMANDS: usize = 10;

/// One row of the decision table: the check, what it asks, and the pass rule with its thresholds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rule {
    pub id: CheckId,
    pub question: &'static str,
    pub pass_rule: &'static str,
}

/// The decision table, in report order (the same order as [`CheckId::CONTROLLER_RUN`]).
pub const RULES: [Rule; 10] = [
    Rule {
        id: CheckId::CtlCrc,
        question: "does every LowCmd decode and carry a valid CRC?",
        pass_rule: "no malformed sample and no CRC mismatch (the robot drops each such command)",
    },
    Rule {
        id: CheckId::CtlModeMachine,
        question: "does every LowCmd echo the mode_machine of the robot's LowState?",
        pass_rule: "every command's mode_machine equals the LowState value",
    },
    Rule {
        id: CheckId::CtlMotorModes,
        question: "are the motors it drives enabled and the unused slots off?",
        pass_rule: "mode 1 on every used slot with a non-zero gain, target velocity or torque; mode 0 on slots 27..34",
    },
    Rule {
        id: CheckId::CtlLimits,
        question: "are gains and targets within the robot's limits?",
        pass_rule: "on every enabled joint: kp in [0, KP_MAX], kd in [0, KD_MAX], q within the joint range (when kp > 0), dq within the speed limit, tau within the torque limit",
    },
    Rule {
        id: CheckId::CtlFinite,
        question: "are all values finite?",
        pass_rule: "no NaN or infinity in any float of any command",
    },
    Rule {
        id: CheckId::CtlRate,
        question: "does it command at the robot's rate?",
        pass_rule: "mean rate before the silence within RATE_TOLERANCE of NOMINAL_RATE_HZ (send timestamps)",
    },
    Rule {
        id: CheckId::CtlJitter,
        question: "is its command stream regular?",
        pass_rule: "a fresh command in at least MIN_PERIOD_COVERAGE of the robot's periods and no gap of MAX_GAP_S or more (a gap is inconclusive if the judge itself stalled as long)",
    },
    Rule {
        id: CheckId::CtlStartJump,
        question: "does it start from the measured pose without a jump?",
        pass_rule: "over the first START_COMMANDS commands no enabled joint's target moves faster than its peak speed while demanding kp*step over JUMP_TORQUE_FRACTION of its peak torque (the first step is taken from the measured pose)",
    },
    Rule {
        id: CheckId::CtlStaleState,
        question: "what does it do when LowState stops?",
        pass_rule: "after STALE_REACTION_S of silence it has stopped commanding or only damps (kp 0); fail if it keeps commanding stiff targets or switches every motor off",
    },
    Rule {
        id: CheckId::CtlFall,
        question: "what does it do when the robot falls?",
        pass_rule: "after FALL_REACTION_S on its back it has stopped commanding, only damps (kp 0) or switched its motors off; fail if it keeps commanding stiff targets; inconclusive if it sent no stiff command in the FALL_REACTION_S before the fall (it had already stopped)",
    },
];

/// When, relative to the robot's LowState stream, a command arrived.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// LowState published normally.
    Observe,
    /// LowState withheld.
    Silence,
    /// LowState published again after the silence.
    Resume,
    /// The robot tipped onto its back by the judge, LowState published.
    Fall,
}

/// One received LowCmd sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Received {
    /// Judge's clock when it was taken (s since the run started).
    pub t: f64,
    /// Seconds since the start of its phase (judge's clock).
    pub t_in_phase: f64,
    pub phase: Phase,
    /// The controller's source timestamp (s, system clock), if it sent one.
    pub sent_s: Option<f64>,
    /// The decoded command, or `None` if the sample did not decode.
    pub cmd: Option<hg::LowCmd_>,
    /// Joint positions of the latest LowState published before it arrived (slot order).
    pub pose: [f32; h1_2::NUM_JOINTS],
}

/// What the judge saw in one run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trace {
    /// `mode_machine` the robot reported in every LowState.
    pub mode_machine: u8,
    /// Every LowCmd sample, in arrival order.
    pub commands: Vec<Received>,
    /// How long LowState was withheld (s).
    pub silence_s: f64,
    /// How long the robot lay on its back (s); 0 when the run did not tip it over.
    pub fall_s: f64,
    /// When the judge tipped the robot over (judge's clock, s since the run started).
    pub fall_at_s: f64,
    /// Longest stall of the judge's own loop behind real time (s): how loaded the machine was.
    pub judge_max_stall_s: f64,
}

/// Why a run cannot be judged: nothing to judge.
pub fn has_commands(trace: &Trace) -> bool {
    trace.commands.iter().any(|c| c.cmd.is_some())
}

fn result(id: CheckId, status: Status, summary: impl Into<String>) -> CheckResult {
    CheckResult::new(id, status, summary)
}

fn decoded(trace: &Trace) -> impl Iterator<Item = (&Received, &hg::LowCmd_)> {
    trace.commands.iter().filter_map(|r| r.cmd.as_ref().map(|c| (r, c)))
}

/// Every check of [`RULES`], in its order.
pub fn judge(trace: &Trace) -> Vec<CheckResult> {
    let mut out = vec![
        check_crc(trace),
        check_mode_machine(trace),
        check_motor_modes(trace),
        check_limits(trace),
        check_finite(trace),
    ];
    out.extend(check_timing(trace));
    out.push(check_start_jump(trace));
    out.push(check_stale_state(trace));
    out.push(check_fall(trace));
    out
}

fn check_crc(trace: &Trace) -> CheckResult {
    let total = trace.commands.len();
    let malformed = trace.commands.iter().filter(|r| r.cmd.is_none()).count();
    let mut bad = 0usize;
    let mut example = None;
    for (_, c) in decoded(trace) {
        let computed = crc::compute(c);
        if computed != c.crc {
            bad += 1;
            example.get_or_insert(format!("stored {:#010x}, computed {computed:#010x}", c.crc));
        }
    }
    let status = if total == 0 {
        Status::Inconclusive
    } else if bad + malformed > 0 {
        Status::Fail
    } else {
        Status::Pass
    };
    let summary = match status {
        Status::Inconclusive => "no LowCmd received".to_owned(),
        Status::Fail => format!(
            "{bad} of {total} commands with a wrong CRC and {malformed} malformed: the robot drops every one of them"
        ),
        Status::Pass => format!("all {total} commands decode and carry a valid CRC"),
    };
    result(CheckId::CtlCrc, status, summary)
        .with("commands", total)
        .with("bad_crc", bad)
        .with("malformed", malformed)
        .with("first_bad_crc", example)
}

fn check_mode_machine(trace: &Trace) -> CheckResult {
    let mut seen: BTreeMap<u8, usize> = BTreeMap::new();
    for (_, c) in decoded(trace) {
        *seen.entry(c.mode_machine).or_default() += 1;
    }
    let total: usize = seen.values().sum();
    let wrong: usize = seen.iter().filter(|(m, _)| **m != trace.mode_machine).map(|(_, n)| n).sum();
    let status = count_verdict(total, wrong);
    let summary = match status {
        Status::Inconclusive => "no decodable LowCmd".to_owned(),
        Status::Pass => format!("all {total} commands echo mode_machine {}", trace.mode_machine),
        Status::Fail => format!(
            "{wrong} of {total} commands do not echo the robot's mode_machine {} (sent: {})",
            trace.mode_machine,
            seen.keys().map(u8::to_string).collect::<Vec<_>>().join(", ")
        ),
    };
    let counts: BTreeMap<String, usize> = seen.iter().map(|(m, n)| (m.to_string(), *n)).collect();
    result(CheckId::CtlModeMachine, status, summary)
        .with("robot_mode_machine", trace.mode_machine)
        .with("mode_machine_counts", counts)
}

/// The verdict of a check that counts offending commands: nothing to judge without commands, a pass only when none
/// offends.
fn count_verdict(commands: usize, offending: usize) -> Status {
    match (commands, offending) {
        (0, _) => Status::Inconclusive,
        (_, 0) => Status::Pass,
        _ => Status::Fail,
    }
}

/// Whether a used slot's command asks the motor to do anything.
fn drives(m: &hg::MotorCmd_) -> bool {
    m.kp != 0.0 || m.kd != 0.0 || m.tau != 0.0 || m.dq != 0.0
}

fn check_motor_modes(trace: &Trace) -> CheckResult {
    let mut total = 0usize;
    let mut bad_commands = 0usize;
    let mut disabled_driven: BTreeMap<usize, usize> = BTreeMap::new();
    let mut unknown: BTreeMap<usize, u8> = BTreeMap::new();
    let mut unused_on: BTreeMap<usize, u8> = BTreeMap::new();
    let mut enabled: std::collections::BTreeSet<usize> = Default::default();
    for (_, c) in decoded(trace) {
        total += 1;
        let mut bad = false;
        for (slot, m) in c.motor_cmd.iter().enumerate() {
            if slot >= h1_2::NUM_JOINTS {
                if m.mode != 0 {
                    unused_on.insert(slot, m.mode);
                    bad = true;
                }
                continue;
            }
            match m.mode {
                1 => {
                    enabled.insert(slot);
                }
                0 if drives(m) => {
                    *disabled_driven.entry(slot).or_default() += 1;
                    bad = true;
                }
                0 => {}
                other => {
                    unknown.insert(slot, other);
                    bad = true;
                }
            }
        }
        bad_commands += usize::from(bad);
    }
    let status = count_verdict(total, bad_commands);
    let summary = match status {
        Status::Inconclusive => "no decodable LowCmd".to_owned(),
        Status::Pass => format!(
            "{} used slots enabled (mode 1) wherever driven, unused slots 27..34 off, in all {total} commands",
            enabled.len()
        ),
        Status::Fail => {
            let mut parts = Vec::new();
            if !disabled_driven.is_empty() {
                parts.push(format!(
                    "slots {:?} carry gains or targets with mode 0 (the robot ignores them)",
                    disabled_driven.keys().collect::<Vec<_>>()
                ));
            }
            if !unknown.is_empty() {
                parts.push(format!("slots {:?} have a mode other than 0/1", unknown.keys().collect::<Vec<_>>()));
            }
            if !unused_on.is_empty() {
                parts.push(format!("unused slots {:?} are not mode 0", unused_on.keys().collect::<Vec<_>>()));
            }
            format!("{bad_commands} of {total} commands: {}", parts.join("; "))
        }
    };
    let as_map = |m: &BTreeMap<usize, u8>| m.iter().map(|(k, v)| (k.to_string(), *v)).collect::<BTreeMap<_, _>>();
    result(CheckId::CtlMotorModes, status, summary)
        .with("enabled_slots", enabled.into_iter().collect::<Vec<_>>())
        .with(
            "driven_but_disabled_slots",
            disabled_driven.iter().map(|(k, v)| (k.to_string(), *v)).collect::<BTreeMap<_, _>>(),
        )
        .with("unknown_modes", as_map(&unknown))
        .with("unused_slots_not_off", as_map(&unused_on))
}

fn check_limits(trace: &Trace) -> CheckResult {
    let mut total = 0usize;
    let mut bad = 0usize;
    // One example per (slot, field), with the most extreme value seen.
    let mut worst: BTreeMap<(usize, &'static str), (f32, String)> = BTreeMap::new();
    for (_, c) in decoded(trace) {
        total += 1;
        let mut any = false;
        for f in validate::h1_2_lowcmd(c) {
            if let validate::Finding::OutOfLimits { slot, field, value, .. } = &f {
                any = true;
                let e = worst.entry((*slot, field.name())).or_insert((*value, f.to_string()));
                if value.abs() > e.0.abs() {
                    *e = (*value, f.to_string());
                }
            }
        }
        bad += usize::from(any);
    }
    let status = count_verdict(total, bad);
    let summary = match status {
        Status::Inconclusive => "no decodable LowCmd".to_owned(),
        Status::Pass => format!("gains and targets within the H1-2's limits in all {total} commands"),
        Status::Fail => format!(
            "{bad} of {total} commands outside the limits: {}",
            worst.values().map(|(_, s)| s.as_str()).take(3).collect::<Vec<_>>().join("; ")
        ),
    };
    result(CheckId::CtlLimits, status, summary)
        .with("kp_max", h1_2::KP_MAX)
        .with("kd_max", h1_2::KD_MAX)
        .with("commands_out_of_limits", bad)
        .with("findings", worst.into_values().map(|(_, s)| s).collect::<Vec<_>>())
}

fn check_finite(trace: &Trace) -> CheckResult {
    let mut total = 0usize;
    let mut bad = 0usize;
    let mut paths: std::collections::BTreeSet<String> = Default::default();
    for (_, c) in decoded(trace) {
        total += 1;
        let found = validate::non_finite(c);
        bad += usize::from(!found.is_empty());
        for f in found {
            if let validate::Finding::NonFinite { path, .. } = f {
                paths.insert(path);
            }
        }
    }
    let status = count_verdict(total, bad);
    let summary = match status {
        Status::Inconclusive => "no decodable LowCmd".to_owned(),
        Status::Pass => format!("every float finite in all {total} commands"),
        Status::Fail => format!(
            "{bad} of {total} commands carry NaN or infinity (in {})",
            paths.iter().take(3).cloned().collect::<Vec<_>>().join(", ")
        ),
    };
    result(CheckId::CtlFinite, status, summary)
        .with("commands_non_finite", bad)
        .with("paths", paths.into_iter().take(20).collect::<Vec<_>>())
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let k = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[k.min(sorted.len() - 1)]
}

fn round(x: f64, digits: i32) -> f64 {
    let s = 10f64.powi(digits);
    (x * s).round() / s
}

/// `ctl_rate` and `ctl_jitter`, from the commands sent before the silence.
fn check_timing(trace: &Trace) -> [CheckResult; 2] {
    let observe: Vec<&Received> = trace.commands.iter().filter(|r| r.phase == Phase::Observe).collect();
    // The controller's own send stamps where it gave them (its loop's timing); else our arrival times.
    let use_sent = observe.iter().all(|r| r.sent_s.is_some());
    let times: Vec<f64> = observe.iter().map(|r| if use_sent { r.sent_s.unwrap_or(r.t) } else { r.t }).collect();
    let clock = if use_sent { "controller's send timestamps" } else { "arrival times (no send timestamps)" };
    if times.len() < MIN_TIMING_COMMANDS {
        let why = format!("only {} commands before the silence (need {MIN_TIMING_COMMANDS})", times.len());
        return [
            result(CheckId::CtlRate, Status::Inconclusive, why.clone()).with("commands", times.len()),
            result(CheckId::CtlJitter, Status::Inconclusive, why).with("commands", times.len()),
        ];
    }
    let span = times.last().copied().unwrap_or(0.0) - times.first().copied().unwrap_or(0.0);
    let rate = if span > 0.0 { (times.len() - 1) as f64 / span } else { f64::INFINITY };
    let rel = (rate / NOMINAL_RATE_HZ - 1.0).abs();
    let rate_status = if rel <= RATE_TOLERANCE { Status::Pass } else { Status::Fail };
    let rate_result = result(
        CheckId::CtlRate,
        rate_status,
        format!(
            "{rate:.1} Hz mean over {span:.2} s ({} commands), {:.1} % from {NOMINAL_RATE_HZ} Hz (limit {:.0} %)",
            times.len(),
            rel * 100.0,
            RATE_TOLERANCE * 100.0
        ),
    )
    .with("rate_hz", round(rate, 1))
    .with("window_s", round(span, 3))
    .with("commands", times.len())
    .with("clock", clock);

    let mut intervals: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    intervals.sort_by(f64::total_cmp);
    let period = 1.0 / NOMINAL_RATE_HZ;
    let median = percentile(&intervals, 0.5);
    let p99 = percentile(&intervals, 0.99);
    let max_gap = intervals.last().copied().unwrap_or(0.0);
    // Periods of the robot's clock (counted from the first send) that saw at least one fresh command.
    let first = times.first().copied().unwrap_or(0.0);
    let bins: std::collections::BTreeSet<i64> = times.iter().map(|t| ((t - first) / period).floor() as i64).collect();
    let coverage = bins.len() as f64 / ((span / period).floor() + 1.0);
    let (status, summary) = if coverage < MIN_PERIOD_COVERAGE {
        (
            Status::Fail,
            format!(
                "a fresh command in only {:.0} % of the robot's {:.1} ms periods (limit {:.0} %): the loop is too slow or sends in bursts",
                coverage * 100.0,
                period * 1e3,
                MIN_PERIOD_COVERAGE * 100.0
            ),
        )
    } else if max_gap >= MAX_GAP_S && trace.judge_max_stall_s >= MAX_GAP_S {
        (
            Status::Inconclusive,
            format!(
                "a {:.1} ms gap between commands, but the judge itself stalled {:.1} ms: the machine, not necessarily the controller",
                max_gap * 1e3,
                trace.judge_max_stall_s * 1e3
            ),
        )
    } else if max_gap >= MAX_GAP_S {
        (
            Status::Fail,
            format!(
                "a {:.1} ms gap between commands (limit {:.0} ms, half the robot's command timeout)",
                max_gap * 1e3,
                MAX_GAP_S * 1e3
            ),
        )
    } else {
        (
            Status::Pass,
            format!(
                "a fresh command in {:.0} % of the periods; median interval {:.2} ms, p99 {:.2} ms, largest gap {:.1} ms",
                coverage * 100.0,
                median * 1e3,
                p99 * 1e3,
                max_gap * 1e3
            ),
        )
    };
    let jitter_result = result(CheckId::CtlJitter, status, summary)
        .with("period_coverage", round(coverage, 3))
        .with("median_ms", round(median * 1e3, 3))
        .with("p99_ms", round(p99 * 1e3, 3))
        .with("max_gap_ms", round(max_gap * 1e3, 2))
        .with("judge_max_stall_ms", round(trace.judge_max_stall_s * 1e3, 2))
        .with("clock", clock);
    [rate_result, jitter_result]
}

fn check_start_jump(trace: &Trace) -> CheckResult {
    let period = 1.0 / NOMINAL_RATE_HZ;
    // (ratio to the speed-limit step, slot, step, kp, implied torque, command index)
    let mut worst: Option<(f64, usize, f64, f64, f64, usize)> = None;
    let mut jumps = 0usize;
    let mut prev: Option<(&Received, &hg::LowCmd_)> = None;
    let mut judged = 0usize;
    for (k, (r, c)) in decoded(trace).filter(|(r, _)| r.phase == Phase::Observe).take(START_COMMANDS).enumerate() {
        judged += 1;
        let dt = match prev {
            Some((p, _)) => {
                let t = |x: &Received| x.sent_s.unwrap_or(x.t);
                (t(r) - t(p)).max(period)
            }
            None => period,
        };
        for (slot, joint) in h1_2::JOINTS.iter().enumerate() {
            let m = &c.motor_cmd[slot];
            if m.mode != 1 || m.kp <= 0.0 || !m.q.is_finite() || !m.kp.is_finite() {
                continue;
            }
            // The first step is from the measured pose; later ones from the previous target (or the measured
            // pose where the previous command did not hold this joint stiffly).
            let from = match prev {
                Some((_, pc)) if pc.motor_cmd[slot].mode == 1 && pc.motor_cmd[slot].kp > 0.0 => pc.motor_cmd[slot].q,
                _ => r.pose[slot],
            };
            let step = f64::from((m.q - from).abs());
            let allowed = f64::from(joint.speed_limit) * dt;
            let torque = f64::from(m.kp) * step;
            let ratio = step / allowed;
            let jump = ratio > 1.0 && torque > JUMP_TORQUE_FRACTION * f64::from(joint.torque_limit);
            jumps += usize::from(jump);
            let score = if jump { ratio + 1e6 } else { ratio };
            if worst.is_none_or(|w| score > w.0) {
                worst = Some((score, slot, step, f64::from(m.kp), torque, k));
            }
        }
        prev = Some((r, c));
    }
    let Some((score, slot, step, kp, torque, index)) = worst else {
        return result(
            CheckId::CtlStartJump,
            Status::Inconclusive,
            "no command holds any joint stiffly (mode 1, kp > 0) at the start: nothing can jump",
        )
        .with("commands_judged", judged);
    };
    let joint = &h1_2::JOINTS[slot];
    let status = if jumps > 0 { Status::Fail } else { Status::Pass };
    let what = format!(
        "largest step {step:.4} rad on {} (slot {slot}) at command {index}: kp {kp:.0} implies {torque:.1} N·m ({:.0} % of its {:.0} N·m peak)",
        joint.name,
        torque / f64::from(joint.torque_limit) * 100.0,
        joint.torque_limit
    );
    let summary = if jumps > 0 {
        format!(
            "{jumps} joint steps faster than the joint can move and over {:.0} % of peak torque; {what}",
            JUMP_TORQUE_FRACTION * 100.0
        )
    } else {
        format!("no jump over the first {judged} commands; {what}")
    };
    result(CheckId::CtlStartJump, status, summary)
        .with("commands_judged", judged)
        .with("jumps", jumps)
        .with("largest_step_rad", round(step, 5))
        .with("largest_step_joint", joint.name)
        .with("largest_step_kp", kp)
        .with("implied_torque_nm", round(torque, 2))
        .with("speed_limit_ratio", round(if jumps > 0 { score - 1e6 } else { score }, 3))
}

/// What a controller did while LowState was withheld.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StaleBehaviour {
    /// Stopped sending (the robot's own command timeout then damps).
    Stop,
    /// Kept sending with kp 0 on every enabled motor (damping).
    Damp,
    /// Kept sending with every motor disabled.
    Limp,
    /// Kept sending the same stiff targets (a stale pose).
    StalePose,
    /// Kept sending changing stiff targets computed from a stale state.
    OpenLoop,
}

impl StaleBehaviour {
    pub const fn name(self) -> &'static str {
        match self {
            StaleBehaviour::Stop => "stop",
            StaleBehaviour::Damp => "damp",
            StaleBehaviour::Limp => "limp",
            StaleBehaviour::StalePose => "stale_pose",
            StaleBehaviour::OpenLoop => "open_loop",
        }
    }

    /// What the commands `judged`, sent over a window in which `expected` commands fit at the nominal rate, did.
    fn of(judged: &[&hg::LowCmd_], expected: f64) -> Self {
        if (judged.len() as f64) < STOPPED_SHARE * expected {
            StaleBehaviour::Stop
        } else if judged.iter().any(|c| stiff(c)) {
            let targets = |c: &hg::LowCmd_| c.motor_cmd.iter().map(|m| m.q.to_bits()).collect::<Vec<_>>();
            let first = judged.iter().find(|c| stiff(c)).map(|c| targets(c));
            let constant = judged.iter().filter(|c| stiff(c)).all(|c| Some(targets(c)) == first);
            if constant {
                StaleBehaviour::StalePose
            } else {
                StaleBehaviour::OpenLoop
            }
        } else if judged.iter().any(|c| enabled(c)) {
            StaleBehaviour::Damp
        } else {
            StaleBehaviour::Limp
        }
    }
}

/// Whether a command drives any joint with stiffness.
fn stiff(c: &hg::LowCmd_) -> bool {
    c.motor_cmd.iter().take(h1_2::NUM_JOINTS).any(|m| m.mode == 1 && m.kp != 0.0)
}

/// Whether a command enables any joint's motor.
fn enabled(c: &hg::LowCmd_) -> bool {
    c.motor_cmd.iter().take(h1_2::NUM_JOINTS).any(|m| m.mode == 1)
}

fn check_stale_state(trace: &Trace) -> CheckResult {
    let judged: Vec<&hg::LowCmd_> = trace
        .commands
        .iter()
        .filter(|r| r.phase == Phase::Silence && r.t_in_phase >= STALE_REACTION_S)
        .filter_map(|r| r.cmd.as_ref())
        .collect();
    let window = (trace.silence_s - STALE_REACTION_S).max(0.0);
    if window <= 0.0 {
        return result(
            CheckId::CtlStaleState,
            Status::Inconclusive,
            format!(
                "LowState was withheld {:.2} s, not longer than the reaction time {STALE_REACTION_S} s",
                trace.silence_s
            ),
        );
    }
    let before = trace.commands.iter().filter(|r| r.phase == Phase::Observe).count();
    if before == 0 {
        return result(CheckId::CtlStaleState, Status::Inconclusive, "no command before the silence");
    }
    let behaviour = StaleBehaviour::of(&judged, window * NOMINAL_RATE_HZ);
    let status = match behaviour {
        StaleBehaviour::Stop | StaleBehaviour::Damp => Status::Pass,
        _ => Status::Fail,
    };
    let summary = match behaviour {
        StaleBehaviour::Stop => {
            "stops commanding when LowState stops (the robot's command timeout then damps)".to_owned()
        }
        StaleBehaviour::Damp => "switches to damping (kp 0) when LowState stops".to_owned(),
        StaleBehaviour::Limp => {
            "switches every motor off when LowState stops: a standing humanoid collapses".to_owned()
        }
        StaleBehaviour::StalePose => "keeps commanding the same stiff pose without LowState (blind)".to_owned(),
        StaleBehaviour::OpenLoop => "keeps commanding changing stiff targets from a stale state (open loop)".to_owned(),
    };
    let resumed = trace.commands.iter().filter(|r| r.phase == Phase::Resume).count();
    result(
        CheckId::CtlStaleState,
        status,
        format!("{summary}; {} commands in the last {window:.1} s of a {:.1} s silence", judged.len(), trace.silence_s),
    )
    .with("behaviour", behaviour.name())
    .with("silence_s", trace.silence_s)
    .with("reaction_allowed_s", STALE_REACTION_S)
    .with("commands_judged", judged.len())
    .with("stiff_commands", judged.iter().filter(|c| stiff(c)).count())
    .with("commands_after_resume", resumed)
}

/// `ctl_fall`: the judge tips the robot onto its back and keeps publishing LowState; a controller that sees it (a
/// tilt watch on the IMU) stops driving the joints into the ground. The reaction is classified like a stale state's,
/// but switching the motors off is safe here: the robot already lies on the ground.
fn check_fall(trace: &Trace) -> CheckResult {
    let id = CheckId::CtlFall;
    let window = (trace.fall_s - FALL_REACTION_S).max(0.0);
    if window <= 0.0 {
        return result(
            id,
            Status::Inconclusive,
            format!(
                "the robot lay on its back {:.2} s, not longer than the reaction time {FALL_REACTION_S} s",
                trace.fall_s
            ),
        );
    }
    let before_fall = decoded(trace)
        .filter(|(r, c)| r.t < trace.fall_at_s && r.t >= trace.fall_at_s - FALL_REACTION_S && stiff(c))
        .count();
    let judged: Vec<&hg::LowCmd_> = trace
        .commands
        .iter()
        .filter(|r| r.phase == Phase::Fall && r.t_in_phase >= FALL_REACTION_S)
        .filter_map(|r| r.cmd.as_ref())
        .collect();
    if before_fall == 0 {
        return result(
            id,
            Status::Inconclusive,
            format!(
                "no stiff command in the {FALL_REACTION_S} s before the fall (the controller had stopped or was \
                 damping since the silence), so the fall cannot show its reaction"
            ),
        )
        .with("commands_judged", judged.len());
    }
    let behaviour = StaleBehaviour::of(&judged, window * NOMINAL_RATE_HZ);
    let (status, name, summary) = match behaviour {
        StaleBehaviour::Stop => {
            (Status::Pass, "stop", "stops commanding when the robot falls (its command timeout then damps)")
        }
        StaleBehaviour::Damp => (Status::Pass, "damp", "switches to damping (kp 0) when the robot falls"),
        StaleBehaviour::Limp => {
            (Status::Pass, "limp", "switches its motors off when the robot falls (it lies on the ground)")
        }
        StaleBehaviour::StalePose => {
            (Status::Fail, "stiff_pose", "keeps commanding the same stiff pose with the robot on its back")
        }
        StaleBehaviour::OpenLoop => {
            (Status::Fail, "stiff_tracking", "keeps commanding changing stiff targets with the robot on its back")
        }
    };
    result(
        id,
        status,
        format!("{summary}; {} commands in the last {window:.1} s of {:.1} s on its back", judged.len(), trace.fall_s),
    )
    .with("behaviour", name)
    .with("fall_s", trace.fall_s)
    .with("reaction_allowed_s", FALL_REACTION_S)
    .with("stiff_commands_before_fall", before_fall)
    .with("commands_judged", judged.len())
    .with("stiff_commands", judged.iter().filter(|c| stiff(c)).count())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MM: u8 = 6;

    fn pose() -> [f32; h1_2::NUM_JOINTS] {
        let mut p = [0.0; h1_2::NUM_JOINTS];
        p[3] = 0.3;
        p[9] = 0.3;
        p
    }

    fn hold(q: &[f32; h1_2::NUM_JOINTS], kp: f32) -> hg::LowCmd_ {
        let mut c = hg::LowCmd_ { mode_machine: MM, ..Default::default() };
        for (i, m) in c.motor_cmd.iter_mut().take(h1_2::NUM_JOINTS).enumerate() {
            m.mode = 1;
            m.q = q[i];
            m.kp = kp;
            m.kd = 3.0;
        }
        crc::seal(&mut c);
        c
    }

    /// A well-behaved trace: 4 s of holds at 500 Hz, then damping during a 2 s silence, then holds again.
    fn good() -> Trace {
        let p = pose();
        let mut commands = Vec::new();
        let mut t = 0.0;
        let mut push = |phase, t_in_phase: f64, cmd: hg::LowCmd_| {
            t += 0.002;
            commands.push(Received { t, t_in_phase, phase, sent_s: Some(1000.0 + t), cmd: Some(cmd), pose: p });
        };
        for k in 0..2000 {
            push(Phase::Observe, k as f64 * 0.002, hold(&p, 100.0));
        }
        for k in 0..1000 {
            push(Phase::Silence, k as f64 * 0.002, hold(&p, 0.0));
        }
        for k in 0..500 {
            push(Phase::Resume, k as f64 * 0.002, hold(&p, 100.0));
        }
        // The robot is tipped over after the 3500th command (t = 7.0 s).
        let fall_at_s = 3500.0 * 0.002 + 0.001;
        for k in 0..1000 {
            push(Phase::Fall, k as f64 * 0.002, hold(&p, 0.0));
        }
        Trace { mode_machine: MM, commands, silence_s: 2.0, fall_s: 2.0, fall_at_s, judge_max_stall_s: 0.001 }
    }

    fn status(results: &[CheckResult], id: CheckId) -> Status {
        results.iter().find(|r| r.id == id).map(|r| r.status).unwrap_or(Status::Inconclusive)
    }

    #[test]
    fn rules_follow_the_controller_run() {
        assert_eq!(RULES.map(|r| r.id), CheckId::CONTROLLER_RUN);
        let ids: Vec<CheckId> = judge(&good()).iter().map(|r| r.id).collect();
        assert_eq!(ids, CheckId::CONTROLLER_RUN.to_vec());
    }

    #[test]
    fn good_trace_passes_everything() {
        let r = judge(&good());
        for x in &r {
            assert_eq!(x.status, Status::Pass, "{}: {}", x.id, x.summary);
        }
        assert_eq!(r[8].evidence["behaviour"], "damp");
        assert_eq!(r[9].evidence["behaviour"], "damp");
    }

    #[test]
    fn each_defect_fails_its_check() {
        let modify = |f: &dyn Fn(&mut hg::LowCmd_)| {
            let mut t = good();
            for r in &mut t.commands {
                if let Some(c) = r.cmd.as_mut() {
                    f(c);
                }
            }
            judge(&t)
        };
        let r = modify(&|c| c.crc ^= 1);
        assert_eq!(status(&r, CheckId::CtlCrc), Status::Fail);
        assert_eq!(status(&r, CheckId::CtlLimits), Status::Pass);
        let r = modify(&|c| c.mode_machine = 0);
        assert_eq!(status(&r, CheckId::CtlModeMachine), Status::Fail);
        let r = modify(&|c| c.motor_cmd[16].mode = 0);
        assert_eq!(status(&r, CheckId::CtlMotorModes), Status::Fail);
        let r = modify(&|c| c.motor_cmd[30].mode = 1);
        assert_eq!(status(&r, CheckId::CtlMotorModes), Status::Fail);
        let r = modify(&|c| c.motor_cmd[12].kp = 1500.0);
        assert_eq!(status(&r, CheckId::CtlLimits), Status::Fail);
        let r = modify(&|c| c.motor_cmd[20].tau = f32::NAN);
        assert_eq!(status(&r, CheckId::CtlFinite), Status::Fail);
        // A disabled slot with nothing in it is fine.
        let r = modify(&|c| c.motor_cmd[16] = hg::MotorCmd_::default());
        assert_eq!(status(&r, CheckId::CtlMotorModes), Status::Pass);
    }

    #[test]
    fn start_jump_needs_speed_and_torque() {
        let mut t = good();
        // The first command targets the zero pose from a pose with 0.3 rad knees, stiffly: a jump.
        let zero = [0.0; h1_2::NUM_JOINTS];
        t.commands[0].cmd = Some(hold(&zero, 200.0));
        let r = judge(&t);
        assert_eq!(status(&r, CheckId::CtlStartJump), Status::Fail, "{:?}", r[7]);
        assert_eq!(r[7].evidence["largest_step_joint"], "left_knee_joint");
        // The same leap with tiny gains (2 * 0.3 = 0.6 N·m of 300), held there, is a gentle start.
        for c in t.commands.iter_mut().take(START_COMMANDS) {
            c.cmd = Some(hold(&zero, 2.0));
        }
        let r = judge(&t);
        assert_eq!(status(&r, CheckId::CtlStartJump), Status::Pass, "{:?}", r[7]);
        // A ramp of the left knee by 0.3 rad over 300 commands (0.5 rad/s), then held, is no jump.
        let mut t = good();
        for (k, c) in t.commands.iter_mut().take(START_COMMANDS).enumerate() {
            let mut q = pose();
            q[3] = 0.3 - 0.3 * (k.min(299) as f32 + 1.0) / 300.0;
            c.cmd = Some(hold(&q, 200.0));
        }
        assert_eq!(status(&judge(&t), CheckId::CtlStartJump), Status::Pass);
    }

    #[test]
    fn stale_behaviours_are_told_apart() {
        let silence = |f: &dyn Fn(&mut Vec<Received>)| {
            let mut t = good();
            f(&mut t.commands);
            let r = judge(&t);
            (r[8].status, r[8].evidence["behaviour"].as_str().unwrap_or("").to_owned())
        };
        let stiff = |cs: &mut Vec<Received>| {
            for r in cs.iter_mut().filter(|r| r.phase == Phase::Silence) {
                r.cmd = Some(hold(&pose(), 100.0));
            }
        };
        assert_eq!(silence(&stiff), (Status::Fail, "stale_pose".to_owned()));
        let stop = |cs: &mut Vec<Received>| cs.retain(|r| r.phase != Phase::Silence || r.t_in_phase < 0.3);
        assert_eq!(silence(&stop), (Status::Pass, "stop".to_owned()));
        let limp = |cs: &mut Vec<Received>| {
            for r in cs.iter_mut().filter(|r| r.phase == Phase::Silence) {
                let mut c = hg::LowCmd_ { mode_machine: MM, ..Default::default() };
                crc::seal(&mut c);
                r.cmd = Some(c);
            }
        };
        assert_eq!(silence(&limp), (Status::Fail, "limp".to_owned()));
        // A slow reaction (stiff for the first 0.4 s) is still a damping controller.
        let slow = |cs: &mut Vec<Received>| {
            for r in cs.iter_mut().filter(|r| r.phase == Phase::Silence && r.t_in_phase < 0.4) {
                r.cmd = Some(hold(&pose(), 100.0));
            }
        };
        assert_eq!(silence(&slow), (Status::Pass, "damp".to_owned()));
    }

    #[test]
    fn fall_reactions_are_told_apart() {
        let fall = |f: &dyn Fn(&mut Vec<Received>)| {
            let mut t = good();
            f(&mut t.commands);
            let r = judge(&t);
            assert_eq!(r[9].id, CheckId::CtlFall);
            let behaviour = r[9].evidence.get("behaviour").and_then(|b| b.as_str()).unwrap_or("");
            (r[9].status, behaviour.to_owned())
        };
        let on_back = |cs: &mut Vec<Received>, cmd: &dyn Fn(usize) -> hg::LowCmd_| {
            for (k, r) in cs.iter_mut().filter(|r| r.phase == Phase::Fall).enumerate() {
                r.cmd = Some(cmd(k));
            }
        };
        let same = |cs: &mut Vec<Received>| on_back(cs, &|_| hold(&pose(), 100.0));
        assert_eq!(fall(&same), (Status::Fail, "stiff_pose".to_owned()));
        let tracking = |cs: &mut Vec<Received>| {
            on_back(cs, &|k| {
                let mut p = pose();
                p[3] += 0.001 * k as f32;
                hold(&p, 100.0)
            })
        };
        assert_eq!(fall(&tracking), (Status::Fail, "stiff_tracking".to_owned()));
        let stop = |cs: &mut Vec<Received>| cs.retain(|r| r.phase != Phase::Fall || r.t_in_phase < 0.2);
        assert_eq!(fall(&stop), (Status::Pass, "stop".to_owned()));
        let limp = |cs: &mut Vec<Received>| {
            on_back(cs, &|_| {
                let mut c = hg::LowCmd_ { mode_machine: MM, ..Default::default() };
                crc::seal(&mut c);
                c
            })
        };
        assert_eq!(fall(&limp), (Status::Pass, "limp".to_owned()));
        // A controller that already damps before the fall (e.g. since the silence) cannot show a reaction to it.
        let damping_before = |cs: &mut Vec<Received>| {
            for r in cs.iter_mut().filter(|r| r.phase == Phase::Resume) {
                r.cmd = Some(hold(&pose(), 0.0));
            }
        };
        assert_eq!(fall(&damping_before).0, Status::Inconclusive);
        // So can a run that did not tip the robot over.
        let mut t = good();
        t.fall_s = 0.0;
        t.commands.retain(|r| r.phase != Phase::Fall);
        assert_eq!(judge(&t)[9].status, Status::Inconclusive);
    }

    #[test]
    fn timing_judges_rate_and_gaps() {
        let mut t = good();
        // A 400 Hz loop: every send stamp stretched by 1.25.
        for r in &mut t.commands {
            r.sent_s = r.sent_s.map(|s| s * 1.25);
        }
        assert_eq!(status(&judge(&t), CheckId::CtlRate), Status::Fail);
        // One 80 ms stall of the controller alone fails; with the judge stalled too it is inconclusive.
        let mut t = good();
        for r in t.commands.iter_mut().skip(1000) {
            r.sent_s = r.sent_s.map(|s| s + 0.08);
        }
        let r = judge(&t);
        assert_eq!(status(&r, CheckId::CtlJitter), Status::Fail, "{:?}", r[6]);
        assert_eq!(status(&r, CheckId::CtlRate), Status::Pass, "{:?}", r[5]);
        t.judge_max_stall_s = 0.08;
        assert_eq!(status(&judge(&t), CheckId::CtlJitter), Status::Inconclusive);
        // Bursts of ten commands every 20 ms: the mean rate is right, the robot sees a fresh command in a tenth of
        // its periods.
        let mut t = good();
        for (k, r) in t.commands.iter_mut().enumerate() {
            r.sent_s = Some(1000.0 + (k / 10) as f64 * 0.02);
        }
        let r = judge(&t);
        assert_eq!(status(&r, CheckId::CtlJitter), Status::Fail, "{:?}", r[6]);
        assert_eq!(status(&r, CheckId::CtlRate), Status::Pass, "{:?}", r[5]);
        // Nothing at all: every check inconclusive.
        let r = judge(&Trace { mode_machine: MM, silence_s: 2.0, ..Trace::default() });
        assert!(r.iter().all(|x| x.status == Status::Inconclusive), "{r:?}");
    }
}
