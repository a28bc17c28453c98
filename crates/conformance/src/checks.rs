//! The default check run. Phases, in order: a passive look at the state stream (nothing sent),
//! discovery data, command handling, robustness, and last the command timeout (the robot may go
//! limp after it). Every command phase first re-establishes a *hold* (every joint held where it
//! stood, [`commands::hold_command`]) and measures the reference pose; the probe then
//! alternates the hold with the command under test (1:1 at 500 Hz), so the target always has a
//! fresh valid command and a refused probe leaves the robot where it was, whatever the target
//! does on silence. Probes whose effect depends on gravity are run twice, with the elbow target
//! above and below the reference: an ignored command moves the joint the same way in both runs,
//! an applied one moves it apart.

use crate::commands::{self, hex, wire, TEST_JOINT};
use crate::report::{CheckResult, Group, Status};
use crate::target::{StateSample, Target};
use crate::ConformError;
use dds_transport::{Durability, EndpointKind, Reliability};
use lowlevel_codec::{cdr, crc, validate, Encoding, Endianness, Representation};
use std::ops::Range;
use unitree_idl::{h1_2, hg};

/// Rate at which commands are published in every phase (Hz), Unitree's usual control rate.
pub const COMMAND_RATE: f64 = 500.0;
/// Hold phase before each probe (s).
const HOLD_S: f64 = 0.4;
/// Probe phase (s).
const PROBE_S: f64 = 0.6;
/// Tail of a phase averaged for the end position (s).
const TAIL_S: f64 = 0.1;
/// How far (rad) a joint may stray from its reference while the target is expected to hold it.
pub const HOLD_TOLERANCE: f32 = 0.15;
/// Slack (rad) beyond the joint range before a reported position counts as out of limits.
pub const LIMIT_TOLERANCE: f32 = 0.05;
/// A valid step must achieve at least this fraction of the commanded displacement.
const MIN_RESPONSE_FRACTION: f32 = 0.5;
/// An ignored probe may move the joint apart by at most this fraction of the valid response.
const MAX_LEAK_FRACTION: f32 = 0.25;
/// Fraction of consecutive identical LowState samples above which state counts as stale.
const MAX_REPEAT_FRACTION: f64 = 0.1;

/// Settings of a check run.
#[derive(Debug, Clone)]
pub struct Options {
    /// Nominal LowState rate (Hz) the stream is judged against.
    pub expected_state_rate_hz: f64,
    /// Passive observation at the start (s).
    pub passive_s: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options { expected_state_rate_hz: 500.0, passive_s: 2.0 }
    }
}

/// Runs every check against a connected target. `progress` gets a short line per phase.
pub fn run_all(
    target: &mut Target,
    opts: &Options,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<CheckResult>, ConformError> {
    let mut results = Vec::new();
    progress("state stream: observing without sending");
    let passive = target.observe(opts.passive_s)?;
    let mode_machine = target.latest().map_or(h1_2::MODE_MACHINE, |s| s.mode_machine);
    results.push(discovery_types_qos(target)?);
    results.push(discovery_type_information(target)?);

    let mut s = Session::start(target, mode_machine)?;
    let cmd_start = s.target.samples.len();
    progress("command handling");
    if !s.target.command_reader_matched {
        for id in COMMAND_CHECKS {
            results.push(CheckResult::new(
                id,
                Group::CommandHandling,
                Status::Inconclusive,
                "no reader of the target matched our rt/lowcmd writer",
            ));
        }
    } else {
        let valid = s.valid_moves_joint()?;
        let response = valid.evidence.get("displacement_rad").and_then(serde_json::Value::as_f64).map(|x| x as f32);
        let usable = valid.status == Status::Pass;
        results.push(valid);
        results.push(s.bad_crc_ignored(response, usable)?);
        results.push(s.mode0_no_torque(response, usable)?);
        results.push(s.absurd_gains_safe()?);
        results.push(s.non_finite_rejected()?);
    }
    progress("robustness");
    results.extend(s.robustness(opts)?);
    progress("command timeout");
    // Before the timeout the robot is under control; after it, it may legitimately collapse.
    let controlled_end = s.target.samples.len();
    if s.target.command_reader_matched {
        results.push(s.timeout_behaviour(opts)?);
    }
    let cmd_end = s.target.samples.len();
    let samples = &s.target.samples;
    let mut stream = vec![
        state_crc(samples),
        state_rate(&samples[passive.clone()], opts),
        state_jitter(&samples[passive.clone()], opts),
        state_tick(&samples[passive], opts),
        state_fresh(&samples[cmd_start..cmd_end]),
        state_finite(samples),
        state_quaternion(samples),
        state_joint_limits(&samples[..controlled_end]),
    ];
    stream.append(&mut results);
    Ok(stream)
}

/// Ids of the command-handling checks (reported inconclusive together when no reader matched).
pub const COMMAND_CHECKS: [&str; 6] = [
    "cmd_valid_moves_joint",
    "cmd_bad_crc_ignored",
    "cmd_mode0_no_torque",
    "cmd_absurd_gains_safe",
    "cmd_non_finite_rejected",
    "cmd_timeout_behaviour",
];

// ---------------------------------------------------------------------------------------------
// Sample statistics.

pub(crate) fn decoded(samples: &[StateSample]) -> impl Iterator<Item = (f64, &hg::LowState_)> {
    samples.iter().filter_map(|s| s.state.as_ref().map(|st| (s.t, st)))
}

/// Mean position of each used joint over the samples in the last `tail` seconds.
pub(crate) fn tail_pose(samples: &[StateSample], tail: f64) -> Option<[f32; h1_2::NUM_JOINTS]> {
    let end = samples.iter().rev().find(|s| s.state.is_some())?.t;
    let mut sum = [0.0f64; h1_2::NUM_JOINTS];
    let mut n = 0usize;
    for (t, st) in decoded(samples) {
        if t >= end - tail {
            for (i, acc) in sum.iter_mut().enumerate() {
                *acc += f64::from(st.motor_state[i].q);
            }
            n += 1;
        }
    }
    (n > 0).then(|| std::array::from_fn(|i| (sum[i] / n as f64) as f32))
}

/// Interval statistics (s): mean, standard deviation, p99, max.
fn intervals(times: &[f64]) -> Option<(f64, f64, f64, f64)> {
    if times.len() < 3 {
        return None;
    }
    let mut d: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / d.len() as f64;
    d.sort_by(f64::total_cmp);
    let p99 = d[((d.len() as f64 * 0.99) as usize).min(d.len() - 1)];
    Some((mean, var.sqrt(), p99, d[d.len() - 1]))
}

fn round(x: f64, digits: i32) -> f64 {
    let f = 10f64.powi(digits);
    (x * f).round() / f
}

// ---------------------------------------------------------------------------------------------
// State stream.

fn state_crc(samples: &[StateSample]) -> CheckResult {
    let undecodable: Vec<&StateSample> = samples.iter().filter(|s| s.state.is_none()).collect();
    let bad: Vec<&StateSample> = samples.iter().filter(|s| s.state.is_some() && !s.crc_ok).collect();
    let n = samples.len();
    let status = if n == 0 {
        Status::Inconclusive
    } else if bad.is_empty() && undecodable.is_empty() {
        Status::Pass
    } else {
        Status::Fail
    };
    let mut r = CheckResult::new(
        "state_crc",
        Group::StateStream,
        status,
        format!(
            "{} of {n} LowState samples decode with a valid CRC ({} bad CRC, {} undecodable)",
            n - bad.len() - undecodable.len(),
            bad.len(),
            undecodable.len()
        ),
    )
    .with("samples", n)
    .with("bad_crc", bad.len())
    .with("undecodable", undecodable.len());
    if let Some(s) = bad.first() {
        if let Some(st) = &s.state {
            r = r
                .with("first_bad_stored_crc", format!("{:#010x}", st.crc))
                .with("first_bad_computed_crc", format!("{:#010x}", crc::compute(st)));
        }
        if let Some(raw) = &s.raw {
            r = r.with("first_bad_bytes_hex", hex(raw, 96));
        }
    }
    if let Some(s) = undecodable.first() {
        r = r.with("first_undecodable_error", s.decode_error.clone().unwrap_or_default());
        if let Some(raw) = &s.raw {
            r = r.with("first_undecodable_bytes_hex", hex(raw, 96));
        }
    }
    r
}

fn span(samples: &[StateSample]) -> Option<(usize, f64)> {
    let first = samples.first()?.t;
    let last = samples.last()?.t;
    (samples.len() >= 2 && last > first).then_some((samples.len(), last - first))
}

fn state_rate(samples: &[StateSample], opts: &Options) -> CheckResult {
    let Some((n, dt)) = span(samples) else {
        return CheckResult::new(
            "state_rate",
            Group::StateStream,
            Status::Inconclusive,
            "fewer than 2 LowState samples while observing",
        );
    };
    let rate = (n - 1) as f64 / dt;
    let ok = rate >= 0.9 * opts.expected_state_rate_hz;
    CheckResult::new(
        "state_rate",
        Group::StateStream,
        if ok { Status::Pass } else { Status::Fail },
        format!("{rate:.1} Hz achieved against {} Hz nominal (pass: >= 90 %)", opts.expected_state_rate_hz),
    )
    .with("rate_hz", round(rate, 2))
    .with("samples", n)
    .with("window_s", round(dt, 3))
}

fn state_jitter(samples: &[StateSample], opts: &Options) -> CheckResult {
    let times: Vec<f64> = samples.iter().map(|s| s.t).collect();
    let Some((mean, std, p99, max)) = intervals(&times) else {
        return CheckResult::new("state_jitter", Group::StateStream, Status::Inconclusive, "too few LowState samples");
    };
    let period = 1.0 / opts.expected_state_rate_hz;
    let ok = p99 <= 5.0 * period;
    CheckResult::new(
        "state_jitter",
        Group::StateStream,
        if ok { Status::Pass } else { Status::Fail },
        format!(
            "arrival interval mean {:.3} ms, std {:.3} ms, p99 {:.3} ms, max {:.3} ms (pass: p99 <= 5 periods)",
            mean * 1e3,
            std * 1e3,
            p99 * 1e3,
            max * 1e3
        ),
    )
    .with("interval_mean_ms", round(mean * 1e3, 4))
    .with("interval_std_ms", round(std * 1e3, 4))
    .with("interval_p99_ms", round(p99 * 1e3, 4))
    .with("interval_max_ms", round(max * 1e3, 4))
    .with("intervals", times.len() - 1)
}

fn state_tick(samples: &[StateSample], opts: &Options) -> CheckResult {
    let ticks: Vec<(f64, u32)> = decoded(samples).map(|(t, s)| (t, s.tick)).collect();
    if ticks.len() < 3 {
        return CheckResult::new(
            "state_tick",
            Group::StateStream,
            Status::Inconclusive,
            "too few decoded LowState samples",
        );
    }
    let mut not_increasing = Vec::new();
    let mut total: u64 = 0;
    for w in ticks.windows(2) {
        let d = w[1].1.wrapping_sub(w[0].1);
        // A step of more than half the counter range is a step backwards.
        if d == 0 || d > u32::MAX / 2 {
            not_increasing.push((w[0].1, w[1].1));
        } else {
            total += u64::from(d);
        }
    }
    let dt = ticks[ticks.len() - 1].0 - ticks[0].0;
    let tick_rate = total as f64 / dt.max(1e-9);
    let per_sample = total as f64 / (ticks.len() - 1) as f64;
    let expected_per_sample = 1000.0 / opts.expected_state_rate_hz;
    // tick counts milliseconds: it must advance with the wall clock (within 10 %).
    let consistent = (tick_rate / 1000.0 - 1.0).abs() <= 0.1;
    let status = if not_increasing.is_empty() && consistent { Status::Pass } else { Status::Fail };
    CheckResult::new(
        "state_tick",
        Group::StateStream,
        status,
        format!(
            "{} non-increasing steps in {} samples; tick advances {tick_rate:.1} per s (pass: 1000 ± 10 %), {per_sample:.2} per sample",
            not_increasing.len(),
            ticks.len()
        ),
    )
    .with("non_increasing", not_increasing.len())
    .with("first_non_increasing", not_increasing.first().map(|(a, b)| format!("{a} -> {b}")))
    .with("tick_per_s", round(tick_rate, 2))
    .with("tick_per_sample", round(per_sample, 3))
    .with("expected_tick_per_sample", round(expected_per_sample, 3))
}

/// The part of a LowState that physics changes at every step: joint q/dq and the IMU.
fn physics_key(s: &hg::LowState_) -> Vec<u32> {
    let mut k = Vec::with_capacity(2 * h1_2::NUM_JOINTS + 7);
    for m in &s.motor_state[..h1_2::NUM_JOINTS] {
        k.push(m.q.to_bits());
        k.push(m.dq.to_bits());
    }
    k.extend(s.imu_state.quaternion.iter().map(|x| x.to_bits()));
    k.extend(s.imu_state.gyroscope.iter().map(|x| x.to_bits()));
    k
}

fn state_fresh(samples: &[StateSample]) -> CheckResult {
    let states: Vec<(u32, Vec<u32>)> = decoded(samples).map(|(_, s)| (s.tick, physics_key(s))).collect();
    if states.len() < 100 {
        return CheckResult::new(
            "state_fresh",
            Group::StateStream,
            Status::Inconclusive,
            "fewer than 100 LowState samples while the robot was driven",
        );
    }
    let pairs = states.len() - 1;
    let repeats: Vec<(u32, u32)> = states.windows(2).filter(|w| w[0].1 == w[1].1).map(|w| (w[0].0, w[1].0)).collect();
    let fraction = repeats.len() as f64 / pairs as f64;
    let ok = fraction <= MAX_REPEAT_FRACTION;
    CheckResult::new(
        "state_fresh",
        Group::StateStream,
        if ok { Status::Pass } else { Status::Fail },
        format!(
            "{} of {pairs} consecutive samples repeat the previous joint and IMU state bit for bit while the robot is driven ({:.1} %, pass: <= {:.0} %)",
            repeats.len(),
            fraction * 100.0,
            MAX_REPEAT_FRACTION * 100.0
        ),
    )
    .with("pairs", pairs)
    .with("identical_pairs", repeats.len())
    .with("first_identical_ticks", repeats.iter().take(5).map(|(a, b)| format!("{a}->{b}")).collect::<Vec<_>>())
}

fn state_finite(samples: &[StateSample]) -> CheckResult {
    let mut bad = 0usize;
    let mut first = None;
    let mut n = 0usize;
    for (_, s) in decoded(samples) {
        n += 1;
        let f = validate::non_finite(s);
        if !f.is_empty() {
            bad += 1;
            first.get_or_insert_with(|| f.iter().map(ToString::to_string).take(3).collect::<Vec<_>>());
        }
    }
    let status = if n == 0 {
        Status::Inconclusive
    } else if bad == 0 {
        Status::Pass
    } else {
        Status::Fail
    };
    CheckResult::new(
        "state_finite",
        Group::StateStream,
        status,
        format!("{bad} of {n} LowState samples carry a non-finite value"),
    )
    .with("samples", n)
    .with("non_finite_samples", bad)
    .with("first_findings", first)
}

fn state_quaternion(samples: &[StateSample]) -> CheckResult {
    let norms: Vec<f32> =
        decoded(samples).map(|(_, s)| s.imu_state.quaternion.iter().map(|x| x * x).sum::<f32>().sqrt()).collect();
    if norms.is_empty() {
        return CheckResult::new("state_quaternion", Group::StateStream, Status::Inconclusive, "no decoded LowState");
    }
    let worst = norms.iter().map(|n| (n - 1.0).abs()).fold(0.0f32, |a, b| if b.is_nan() || b > a { b } else { a });
    let bad = norms
        .iter()
        .filter(|n| {
            let e = (*n - 1.0).abs();
            e.is_nan() || e > 1e-3
        })
        .count();
    CheckResult::new(
        "state_quaternion",
        Group::StateStream,
        if bad == 0 { Status::Pass } else { Status::Fail },
        format!(
            "{bad} of {} IMU quaternions off unit norm by more than 1e-3 (worst |norm-1| = {worst:.2e})",
            norms.len()
        ),
    )
    .with("samples", norms.len())
    .with("off_norm", bad)
    .with("worst_norm_error", f64::from(worst))
}

fn state_joint_limits(samples: &[StateSample]) -> CheckResult {
    let mut n = 0usize;
    let mut violations = 0usize;
    let mut worst: Option<(String, f32, f32, f32)> = None;
    let mut worst_excess = 0.0f32;
    for (_, s) in decoded(samples) {
        n += 1;
        let mut any = false;
        for j in &h1_2::JOINTS {
            let q = s.motor_state[j.slot].q;
            let excess = (j.lower - q).max(q - j.upper);
            if excess.is_nan() || excess > LIMIT_TOLERANCE {
                any = true;
                if excess.is_nan() || excess > worst_excess {
                    worst_excess = excess;
                    worst = Some((j.name.to_owned(), q, j.lower, j.upper));
                }
            }
        }
        violations += usize::from(any);
    }
    let status = if n == 0 {
        Status::Inconclusive
    } else if violations == 0 {
        Status::Pass
    } else {
        Status::Fail
    };
    CheckResult::new(
        "state_joint_limits",
        Group::StateStream,
        status,
        format!("{violations} of {n} samples (while the robot is commanded) report a joint beyond its range by more than {LIMIT_TOLERANCE} rad"),
    )
    .with("samples", n)
    .with("violating_samples", violations)
    .with("worst", worst.map(|(name, q, lo, hi)| format!("{name} q={q} range [{lo}, {hi}]")))
}

// ---------------------------------------------------------------------------------------------
// Discovery.

fn discovery_types_qos(target: &Target) -> Result<CheckResult, ConformError> {
    let eps = target.remote_endpoints()?;
    let writers: Vec<_> = eps
        .iter()
        .filter(|e| e.kind == EndpointKind::Publication && e.topic_name == unitree_idl::topics::LOWSTATE)
        .collect();
    let readers: Vec<_> = eps
        .iter()
        .filter(|e| e.kind == EndpointKind::Subscription && e.topic_name == unitree_idl::topics::LOWCMD)
        .collect();
    let mut problems = Vec::new();
    for w in &writers {
        if w.type_name != dds_transport::topics::HG_LOWSTATE_TYPE {
            problems.push(format!(
                "rt/lowstate writer type `{}` (Unitree: `{}`)",
                w.type_name,
                dds_transport::topics::HG_LOWSTATE_TYPE
            ));
        }
    }
    if readers.is_empty() {
        problems.push("no reader on rt/lowcmd announced".to_owned());
    }
    for r in &readers {
        if r.type_name != dds_transport::topics::HG_LOWCMD_TYPE {
            problems.push(format!(
                "rt/lowcmd reader type `{}` (Unitree: `{}`)",
                r.type_name,
                dds_transport::topics::HG_LOWCMD_TYPE
            ));
        }
        // Unitree's SDK writes rt/lowcmd VOLATILE: a reader asking for more never matches it.
        if matches!(r.durability, Some(d) if d != Durability::Volatile) {
            problems.push(format!(
                "rt/lowcmd reader durability {:?} does not match Unitree's VOLATILE writer",
                r.durability
            ));
        }
    }
    let describe = |e: &dds_transport::DiscoveredEndpoint| {
        format!(
            "{} {} reliability={:?} history={:?} durability={:?} type_information={}",
            e.topic_name, e.type_name, e.reliability, e.history_depth, e.durability, e.has_type_information
        )
    };
    let status = if !problems.is_empty() {
        Status::Fail
    } else if writers.is_empty() {
        Status::Inconclusive
    } else {
        Status::Pass
    };
    let summary = if problems.is_empty() && !writers.is_empty() {
        "type names and QoS of rt/lowstate and rt/lowcmd match Unitree's SDK".to_owned()
    } else if problems.is_empty() {
        "LowState arrives but its writer was not seen in discovery data".to_owned()
    } else {
        problems.join("; ")
    };
    Ok(CheckResult::new("discovery_types_qos", Group::Discovery, status, summary)
        .with("lowstate_writers", writers.iter().map(|e| describe(e)).collect::<Vec<_>>())
        .with("lowcmd_readers", readers.iter().map(|e| describe(e)).collect::<Vec<_>>())
        .with("lowcmd_reader_matched_our_writer", target.command_reader_matched)
        .with("best_effort_writer", writers.iter().any(|w| w.reliability == Some(Reliability::BestEffort))))
}

fn discovery_type_information(target: &Target) -> Result<CheckResult, ConformError> {
    let eps = target.remote_endpoints()?;
    if eps.is_empty() {
        return Ok(CheckResult::new(
            "discovery_type_information",
            Group::Discovery,
            Status::Inconclusive,
            "no discovery data from the target",
        ));
    }
    let with: Vec<String> =
        eps.iter().filter(|e| e.has_type_information).map(|e| format!("{} {:?}", e.topic_name, e.kind)).collect();
    Ok(if with.is_empty() {
        CheckResult::new(
            "discovery_type_information",
            Group::Discovery,
            Status::Pass,
            "no XTypes type information announced: nothing a Cyclone DDS 0.10.2 peer can trip on",
        )
        .with("endpoints", eps.len())
    } else {
        // Cyclone 0.10.2 announces type information of its own that it understands; that of
        // Cyclone 11 makes 0.10.2 peers fail. The flag alone cannot tell them apart.
        CheckResult::new(
            "discovery_type_information",
            Group::Discovery,
            Status::Inconclusive,
            "XTypes type information announced: compatible only if produced by Cyclone DDS <= 0.10 (11.x type information breaks 0.10.2 peers); check with a Unitree SDK client",
        )
        .with("endpoints_with_type_information", with)
    })
}

// ---------------------------------------------------------------------------------------------
// Command handling.

/// End displacements of the elbow with the target above and below, an example of the bytes
/// sent, and the number of samples.
type Differential = (Option<f32>, Option<f32>, Vec<u8>, usize);

/// Builds an unsafe probe from the hold command and the elbow reference: (command, elbow goal).
type MakeProbe = Box<dyn Fn(&hg::LowCmd_, f32) -> (hg::LowCmd_, f32)>;

/// A command session: the hold command and the probes built on it.
struct Session<'a> {
    target: &'a mut Target,
    hold: hg::LowCmd_,
}

/// What a probe observed.
struct Probe {
    /// Pose at the end of the hold phase.
    reference: [f32; h1_2::NUM_JOINTS],
    /// Samples of the probe phase.
    range: Range<usize>,
}

impl<'a> Session<'a> {
    fn start(target: &'a mut Target, mode_machine: u8) -> Result<Self, ConformError> {
        let pose = target
            .latest()
            .map(|s| std::array::from_fn(|i| s.motor_state[i].q))
            .ok_or_else(|| ConformError::BadStartState("no decoded LowState".into()))?;
        let pose: [f32; h1_2::NUM_JOINTS] = pose;
        if pose.iter().any(|q| !q.is_finite()) {
            return Err(ConformError::BadStartState("non-finite joint position".into()));
        }
        let hold = commands::hold_command(&pose, mode_machine);
        Ok(Session { target, hold })
    }

    fn hold_bytes(&self) -> Vec<u8> {
        wire(&self.hold)
    }

    /// Holds for [`HOLD_S`], then runs `probe(i)` at [`COMMAND_RATE`] for `seconds`.
    fn probe<F>(&mut self, seconds: f64, probe: F) -> Result<Probe, ConformError>
    where
        F: FnMut(u64) -> Vec<Vec<u8>>,
    {
        let hold = self.hold_bytes();
        let held = self.target.drive(HOLD_S, COMMAND_RATE, |_| vec![hold.clone()])?;
        let reference = tail_pose(&self.target.samples[held], TAIL_S)
            .or_else(|| self.target.latest().map(|s| std::array::from_fn(|i| s.motor_state[i].q)))
            .ok_or(ConformError::NoState { seconds: HOLD_S })?;
        let range = self.target.drive(seconds, COMMAND_RATE, probe)?;
        Ok(Probe { reference, range })
    }

    /// The hold and `test` alternating 1:1.
    fn alternating(&mut self, seconds: f64, test: Vec<u8>) -> Result<Probe, ConformError> {
        let hold = self.hold_bytes();
        self.probe(seconds, move |i| vec![if i % 2 == 0 { hold.clone() } else { test.clone() }])
    }

    fn samples(&self, p: &Probe) -> &[StateSample] {
        &self.target.samples[p.range.clone()]
    }

    /// Elbow displacement from the reference at the end of the probe.
    fn end_displacement(&self, p: &Probe) -> Option<f32> {
        tail_pose(self.samples(p), TAIL_S).map(|q| q[TEST_JOINT] - p.reference[TEST_JOINT])
    }

    fn valid_moves_joint(&mut self) -> Result<CheckResult, ConformError> {
        let start = self.measure_reference()?;
        let dir = step_direction(start);
        let cmd_goal = elbow_target(start, dir * commands::STEP);
        let (kp, kd) = commands::hold_gains(TEST_JOINT);
        let bytes = wire(&commands::with_joint(&self.hold, TEST_JOINT, cmd_goal, kp, kd));
        let p = self.probe(PROBE_S, move |_| vec![bytes.clone()])?;
        let wanted = cmd_goal - p.reference[TEST_JOINT];
        let Some(moved) = self.end_displacement(&p) else {
            return Ok(CheckResult::new(
                "cmd_valid_moves_joint",
                Group::CommandHandling,
                Status::Inconclusive,
                "no LowState during the probe",
            ));
        };
        let fraction = if wanted.abs() > 1e-3 { moved / wanted } else { 0.0 };
        let ok = fraction >= MIN_RESPONSE_FRACTION;
        Ok(CheckResult::new(
            "cmd_valid_moves_joint",
            Group::CommandHandling,
            if ok { Status::Pass } else { Status::Fail },
            format!(
                "left elbow commanded {wanted:+.3} rad from {:.3}, moved {moved:+.3} rad in {PROBE_S} s ({:.0} % of the step, pass: >= {:.0} %)",
                p.reference[TEST_JOINT],
                fraction * 100.0,
                MIN_RESPONSE_FRACTION * 100.0
            ),
        )
        .with("joint", h1_2::JOINTS[TEST_JOINT].name)
        .with("reference_rad", f64::from(p.reference[TEST_JOINT]))
        .with("target_rad", f64::from(cmd_goal))
        .with("displacement_rad", f64::from(moved.abs()))
        .with("signed_displacement_rad", f64::from(moved))
        .with("samples", p.range.len()))
    }

    /// Runs `make(reference, goal)` twice, with the elbow goal a step above and below the
    /// reference, alternating with the hold; returns the end displacements and the bytes sent.
    fn differential<F>(&mut self, mut make: F) -> Result<Differential, ConformError>
    where
        F: FnMut(f32) -> hg::LowCmd_,
    {
        let mut out = [None, None];
        let mut example = Vec::new();
        let mut samples = 0;
        for (k, sign) in [1.0f32, -1.0].into_iter().enumerate() {
            let reference = self.measure_reference()?;
            let goal = elbow_target(reference, sign * commands::STEP);
            let bytes = wire(&make(goal));
            let p = self.alternating(PROBE_S, bytes.clone())?;
            out[k] = self.end_displacement(&p);
            samples += p.range.len();
            if k == 0 {
                example = bytes;
            }
        }
        Ok((out[0], out[1], example, samples))
    }

    /// The elbow position now (each probe re-holds and re-measures before it starts).
    fn measure_reference(&mut self) -> Result<f32, ConformError> {
        Ok(self.target.latest().map_or(0.0, |s| s.motor_state[TEST_JOINT].q))
    }

    fn judge_leak(
        &self,
        id: &str,
        what: &str,
        response: Option<f32>,
        usable: bool,
        (up, down, example, samples): Differential,
    ) -> CheckResult {
        let (Some(up), Some(down)) = (up, down) else {
            return CheckResult::new(id, Group::CommandHandling, Status::Inconclusive, "no LowState during the probe");
        };
        let apart = up - down;
        let response = response.unwrap_or(0.0);
        let limit = (MAX_LEAK_FRACTION * response).max(0.05);
        let status = if !usable {
            Status::Inconclusive
        } else if apart <= limit {
            Status::Pass
        } else {
            Status::Fail
        };
        CheckResult::new(
            id,
            Group::CommandHandling,
            status,
            format!(
                "{what}: with the elbow target {} rad above vs below, the elbow ended {apart:+.3} rad apart (pass: <= {limit:.3}, {:.0} % of the valid response {response:.3}){}",
                commands::STEP,
                MAX_LEAK_FRACTION * 100.0,
                if usable { "" } else { "; inconclusive: a valid command had no clear effect" }
            ),
        )
        .with("displacement_target_above_rad", f64::from(up))
        .with("displacement_target_below_rad", f64::from(down))
        .with("apart_rad", f64::from(apart))
        .with("limit_rad", f64::from(limit))
        .with("samples", samples)
        .with("probe_bytes_hex", hex(&example, 64))
    }

    fn bad_crc_ignored(&mut self, response: Option<f32>, usable: bool) -> Result<CheckResult, ConformError> {
        let hold = self.hold.clone();
        let (kp, kd) = commands::hold_gains(TEST_JOINT);
        let d = self.differential(|goal| commands::bad_crc(&commands::with_joint(&hold, TEST_JOINT, goal, kp, kd)))?;
        Ok(self.judge_leak(
            "cmd_bad_crc_ignored",
            "commands with a wrong CRC (alternating with the valid hold)",
            response,
            usable,
            d,
        ))
    }

    fn mode0_no_torque(&mut self, response: Option<f32>, usable: bool) -> Result<CheckResult, ConformError> {
        let hold = self.hold.clone();
        let (kp, kd) = commands::hold_gains(TEST_JOINT);
        let d = self.differential(|goal| {
            let mut c = commands::with_joint(&hold, TEST_JOINT, goal, kp, kd);
            c.motor_cmd[TEST_JOINT].mode = 0;
            crc::seal(&mut c);
            c
        })?;
        Ok(self.judge_leak("cmd_mode0_no_torque", "elbow in mode 0 with stiff far targets", response, usable, d))
    }

    /// Runs one unsafe probe (alternating with the hold) and says whether every used joint
    /// stayed within `band` of the reference (elbow: within the band around reference..goal),
    /// with bounded speed and finite state.
    fn unsafe_probe(
        &mut self,
        name: &str,
        make: &dyn Fn(&hg::LowCmd_, f32) -> (hg::LowCmd_, f32),
    ) -> Result<(bool, serde_json::Value), ConformError> {
        let reference = self.measure_reference()?;
        let (cmd, goal) = make(&self.hold, reference);
        let bytes = wire(&cmd);
        let p = self.alternating(PROBE_S, bytes.clone())?;
        let verdict = self.stability(&p, Some(goal));
        Ok((
            verdict.ok,
            serde_json::json!({
                "case": name,
                "ok": verdict.ok,
                "elbow_reference_rad": p.reference[TEST_JOINT],
                "elbow_goal_rad": goal,
                "worst_joint": verdict.worst_joint,
                "worst_deviation_rad": verdict.worst_deviation,
                "max_speed_ratio": verdict.max_speed_ratio,
                "non_finite_samples": verdict.non_finite,
                "samples": p.range.len(),
                "bytes_hex": hex(&bytes, 64),
            }),
        ))
    }

    fn stability(&self, p: &Probe, elbow_goal: Option<f32>) -> Stability {
        let mut v = Stability {
            ok: true,
            worst_joint: String::new(),
            worst_deviation: 0.0,
            max_speed_ratio: 0.0,
            non_finite: 0,
            samples: 0,
        };
        for (_, s) in decoded(self.samples(p)) {
            v.samples += 1;
            if !validate::non_finite(s).is_empty() {
                v.non_finite += 1;
                continue;
            }
            for j in &h1_2::JOINTS {
                let q = s.motor_state[j.slot].q;
                let r = p.reference[j.slot];
                let (lo, hi) = match elbow_goal {
                    Some(g) if j.slot == TEST_JOINT => (r.min(g), r.max(g)),
                    _ => (r, r),
                };
                let dev = (lo - q).max(q - hi).max(0.0);
                if dev > v.worst_deviation {
                    v.worst_deviation = dev;
                    v.worst_joint = j.name.to_owned();
                }
                let ratio = s.motor_state[j.slot].dq.abs() / j.speed_limit;
                v.max_speed_ratio = v.max_speed_ratio.max(ratio);
            }
        }
        v.ok = v.samples > 0 && v.non_finite == 0 && v.worst_deviation <= HOLD_TOLERANCE && v.max_speed_ratio <= 1.0;
        v
    }

    fn absurd_gains_safe(&mut self) -> Result<CheckResult, ConformError> {
        let (_, kd) = commands::hold_gains(TEST_JOINT);
        let cases: Vec<(&str, MakeProbe)> = vec![
            (
                "kp = -500 (negative stiffness) at the reference",
                Box::new(move |h, r| (commands::with_joint(h, TEST_JOINT, r, -500.0, kd), r)),
            ),
            (
                "kd = -50 (negative damping) at the reference",
                Box::new(|h, r| (commands::with_joint(h, TEST_JOINT, r, 40.0, -50.0), r)),
            ),
            (
                "kp = 1e6 toward a target 0.3 rad away",
                Box::new(move |h, r| {
                    let g = elbow_target(r, 0.3 * step_direction(r));
                    (commands::with_joint(h, TEST_JOINT, g, 1.0e6, kd), g)
                }),
            ),
        ];
        self.unsafe_cases("cmd_absurd_gains_safe", "absurd gains on the left elbow", cases)
    }

    fn non_finite_rejected(&mut self) -> Result<CheckResult, ConformError> {
        let (kp, kd) = commands::hold_gains(TEST_JOINT);
        let cases: Vec<(&str, MakeProbe)> = vec![
            ("elbow q = NaN", Box::new(move |h, r| (commands::with_joint(h, TEST_JOINT, f32::NAN, kp, kd), r))),
            ("elbow kp = +inf", Box::new(move |h, r| (commands::with_joint(h, TEST_JOINT, r, f32::INFINITY, kd), r))),
            (
                "elbow tau = NaN",
                Box::new(move |h, r| {
                    let mut c = h.clone();
                    c.motor_cmd[TEST_JOINT].tau = f32::NAN;
                    crc::seal(&mut c);
                    (c, r)
                }),
            ),
            // The rest of a message holding a NaN must not be applied either: a non-finite
            // value has no safe clamp and says the sender is broken.
            (
                "right wrist kp = NaN, elbow stepped 0.5 rad",
                Box::new(move |h, r| {
                    let mut c = commands::with_joint(
                        h,
                        TEST_JOINT,
                        elbow_target(r, commands::STEP * step_direction(r)),
                        kp,
                        kd,
                    );
                    c.motor_cmd[24].kp = f32::NAN;
                    crc::seal(&mut c);
                    (c, r)
                }),
            ),
        ];
        self.unsafe_cases("cmd_non_finite_rejected", "non-finite values", cases)
    }

    fn unsafe_cases(
        &mut self,
        id: &str,
        what: &str,
        cases: Vec<(&str, MakeProbe)>,
    ) -> Result<CheckResult, ConformError> {
        let mut details = Vec::new();
        let mut failed = Vec::new();
        for (name, make) in &cases {
            let (ok, detail) = self.unsafe_probe(name, make.as_ref())?;
            if !ok {
                failed.push((*name).to_owned());
            }
            details.push(detail);
        }
        let status = if failed.is_empty() { Status::Pass } else { Status::Fail };
        let summary = if failed.is_empty() {
            format!("{what}: {} cases rejected or clamped; every joint stayed within {HOLD_TOLERANCE} rad of its hold (or commanded) position, below its speed limit, state finite", cases.len())
        } else {
            format!("{what}: unstable or applied in {} of {} cases: {}", failed.len(), cases.len(), failed.join("; "))
        };
        Ok(CheckResult::new(id, Group::CommandHandling, status, summary).with("cases", details))
    }

    // -----------------------------------------------------------------------------------------
    // Robustness.

    fn robustness(&mut self, opts: &Options) -> Result<Vec<CheckResult>, ConformError> {
        let hold = self.hold.clone();
        let good = wire(&hold);
        let mut truncated = Vec::new();
        for len in [4, 5, 8, 100, good.len() / 2, good.len() - 1] {
            truncated.push(good[..len.min(good.len())].to_vec());
        }
        let bad_header: Vec<Vec<u8>> =
            [[0x00u8, 0x02], [0x00, 0x03], [0x00, 0x04], [0x00, 0x0a], [0x12, 0x34], [0xff, 0xff]]
                .iter()
                .map(|id| {
                    let mut b = good.clone();
                    b[0] = id[0];
                    b[1] = id[1];
                    b
                })
                .collect();
        let oversize: Vec<Vec<u8>> = [1024usize, 60 * 1024]
            .iter()
            .map(|extra| {
                let mut b = good.clone();
                b.extend(std::iter::repeat_n(0xA5u8, *extra));
                b
            })
            .collect();
        let encodings: Vec<Vec<u8>> = [
            Encoding { representation: Representation::Xcdr2, endianness: Endianness::Little },
            Encoding { representation: Representation::Xcdr2, endianness: Endianness::Big },
            Encoding { representation: Representation::Xcdr1, endianness: Endianness::Big },
        ]
        .iter()
        .map(|e| cdr::encode(&hold, *e))
        .collect();

        let mut out = vec![self.robust_case(
            "robust_truncated",
            "truncated LowCmd samples (4 bytes up to one byte short)",
            &truncated,
            1,
            opts,
        )?];
        out.push(self.robust_case(
            "robust_bad_header",
            "wrong encapsulation headers (PL_CDR, XML, PL_CDR2, unknown ids)",
            &bad_header,
            1,
            opts,
        )?);
        out.push(self.robust_case(
            "robust_oversize",
            "oversize samples (valid command + 1 KiB and + 60 KiB of junk)",
            &oversize,
            1,
            opts,
        )?);
        out.push(self.robust_case(
            "robust_xcdr2",
            "the hold command in XCDR2 LE/BE and XCDR1 BE",
            &encodings,
            1,
            opts,
        )?);
        out.push(self.robust_case(
            "robust_flood",
            "a flood of valid hold commands at 10x the control rate (5 kHz)",
            std::slice::from_ref(&good),
            10,
            opts,
        )?);
        // Duplicates and reordering: small elbow variations, each sent twice, pairs swapped.
        let reference = self.measure_reference()?;
        let (kp, kd) = commands::hold_gains(TEST_JOINT);
        let wiggle: Vec<Vec<u8>> = (0..8)
            .map(|k| {
                wire(&commands::with_joint(
                    &hold,
                    TEST_JOINT,
                    commands::clamp_target(TEST_JOINT, reference + 0.01 * (k as f32 - 4.0)),
                    kp,
                    kd,
                ))
            })
            .collect();
        let mut shuffled = Vec::new();
        for pair in wiggle.chunks(2) {
            for m in pair.iter().rev() {
                shuffled.push(m.clone());
                shuffled.push(m.clone());
            }
        }
        out.push(self.robust_case(
            "robust_duplicates_reordering",
            "duplicated and reordered commands",
            &shuffled,
            1,
            opts,
        )?);
        Ok(out)
    }

    /// Alternates the hold with `bad[k % len]` (`burst` samples per odd tick) for 0.8 s; the
    /// target must keep publishing valid, finite state and hold the robot where it stood.
    fn robust_case(
        &mut self,
        id: &str,
        what: &str,
        bad: &[Vec<u8>],
        burst: usize,
        opts: &Options,
    ) -> Result<CheckResult, ConformError> {
        let hold = self.hold_bytes();
        let list = bad.to_vec();
        let mut k = 0usize;
        let seconds = 0.8;
        let p = self.probe(seconds, move |i| {
            if i % 2 == 0 && burst == 1 {
                vec![hold.clone()]
            } else {
                let mut v = Vec::with_capacity(burst + 1);
                if burst > 1 {
                    v.push(hold.clone());
                }
                for _ in 0..burst {
                    v.push(list[k % list.len()].clone());
                    k += 1;
                }
                v
            }
        })?;
        let samples = self.samples(&p);
        let times: Vec<f64> = samples.iter().map(|s| s.t).collect();
        let rate = span(samples).map_or(0.0, |(n, dt)| (n - 1) as f64 / dt);
        let max_gap = times.windows(2).map(|w| w[1] - w[0]).fold(0.0f64, f64::max);
        let invalid = samples.iter().filter(|s| !s.crc_ok).count();
        let stab = self.stability(&p, None);
        let publishing = rate >= 0.8 * opts.expected_state_rate_hz && max_gap <= 0.1;
        let ok = publishing && invalid == 0 && stab.ok;
        let status = if samples.is_empty() {
            Status::Fail
        } else if ok {
            Status::Pass
        } else {
            Status::Fail
        };
        Ok(CheckResult::new(
            id,
            Group::Robustness,
            status,
            format!(
                "{what}: LowState {rate:.0} Hz (max gap {:.1} ms), {invalid} invalid, worst joint deviation {:.3} rad{}, max speed {:.0} % of limit",
                max_gap * 1e3,
                stab.worst_deviation,
                if stab.worst_joint.is_empty() { String::new() } else { format!(" ({})", stab.worst_joint) },
                stab.max_speed_ratio * 100.0
            ),
        )
        .with("state_rate_hz", round(rate, 1))
        .with("max_gap_ms", round(max_gap * 1e3, 2))
        .with("invalid_states", invalid)
        .with("non_finite_states", stab.non_finite)
        .with("worst_deviation_rad", f64::from(stab.worst_deviation))
        .with("max_speed_ratio", f64::from(stab.max_speed_ratio))
        .with("sent_kinds", bad.len())
        .with("samples_per_tick", burst)
        .with("example_bytes_hex", bad.first().map(|b| hex(b, 48))))
    }

    // -----------------------------------------------------------------------------------------
    // Timeout.

    fn timeout_behaviour(&mut self, opts: &Options) -> Result<CheckResult, ConformError> {
        let reference = self.measure_reference()?;
        let (kp, kd) = commands::hold_gains(TEST_JOINT);
        let goal = elbow_target(reference, 0.3 * step_direction(reference));
        let cmd = wire(&commands::with_joint(&self.hold, TEST_JOINT, goal, kp, kd));
        let p = self.probe(0.5, move |_| vec![cmd.clone()])?;
        let at_stop = tail_pose(self.samples(&p), TAIL_S);
        let after = self.target.observe(1.5)?;
        let samples = &self.target.samples[after];
        let Some(at_stop) = at_stop else {
            return Ok(CheckResult::new(
                "cmd_timeout_behaviour",
                Group::CommandHandling,
                Status::Inconclusive,
                "no LowState before the stop",
            ));
        };
        let rate = span(samples).map_or(0.0, |(n, dt)| (n - 1) as f64 / dt);
        let mut non_finite = 0usize;
        let mut max_ratio = 0.0f32;
        let mut settled_speed = 0.0f32;
        let end = samples.last().map_or(0.0, |s| s.t);
        for s in samples {
            if let Some(st) = &s.state {
                if !validate::non_finite(st).is_empty() {
                    non_finite += 1;
                    continue;
                }
                for j in &h1_2::JOINTS {
                    let dq = st.motor_state[j.slot].dq.abs();
                    max_ratio = max_ratio.max(dq / j.speed_limit);
                    if s.t >= end - 0.3 {
                        settled_speed = settled_speed.max(dq);
                    }
                }
            }
        }
        let end_pose = tail_pose(samples, TAIL_S);
        let elbow_drift = end_pose.map(|q| q[TEST_JOINT] - at_stop[TEST_JOINT]);
        let behaviour = match elbow_drift {
            Some(d) if d.abs() <= 0.02 => "keeps the last command (elbow stayed within 0.02 rad)",
            Some(_) => "releases the last command (elbow left its commanded position)",
            None => "unknown",
        };
        let ok = rate >= 0.5 * opts.expected_state_rate_hz && non_finite == 0 && max_ratio <= 1.0;
        Ok(CheckResult::new(
            "cmd_timeout_behaviour",
            Group::CommandHandling,
            if ok { Status::Pass } else { Status::Fail },
            format!(
                "after commands stop the target {behaviour}; LowState {rate:.0} Hz, max joint speed {:.0} % of limit, {}",
                max_ratio * 100.0,
                if settled_speed < 0.5 { "settled (all |dq| < 0.5 rad/s over the last 0.3 s)".to_owned() } else { format!("still moving (|dq| up to {settled_speed:.2} rad/s at the end)") }
            ),
        )
        .with("state_rate_hz", round(rate, 1))
        .with("non_finite_states", non_finite)
        .with("max_speed_ratio", f64::from(max_ratio))
        .with("elbow_drift_after_stop_rad", elbow_drift.map(f64::from))
        .with("final_max_speed_rad_s", f64::from(settled_speed))
        .with("observed_s", 1.5))
    }
}

/// Elbow target `offset` from the reference, inside the joint range.
fn elbow_target(reference: f32, offset: f32) -> f32 {
    commands::clamp_target(TEST_JOINT, reference + offset)
}

/// The direction (+1 or -1) that leaves the elbow the most room for a step.
fn step_direction(reference: f32) -> f32 {
    let (lo, hi) = commands::range(TEST_JOINT).unwrap_or((-1.0, 1.0));
    if hi - reference >= reference - lo {
        1.0
    } else {
        -1.0
    }
}

struct Stability {
    ok: bool,
    worst_joint: String,
    worst_deviation: f32,
    max_speed_ratio: f32,
    non_finite: usize,
    samples: usize,
}
