//! Fuzz mode: structure-aware mutation of LowCmd sequences, guided by the target's state.
//!
//! A sequence is a list of [`Gene`]s: a decoded LowCmd (built from the hold command by typed
//! mutations of fields, modes and slots), a wire corruption (bad CRC, truncation, header,
//! representation, oversize) and a repeat count. It is executed like the checks' probes: the
//! valid hold command alternates 1:1 with the sequence's samples at 500 Hz, then the hold runs
//! on for a settling time. Feedback is the largest deviation of any joint from its reference
//! and the largest speed relative to the joint's limit; the corpus keeps the most disturbing
//! sequences and mutates them further. A run *fails* when
//! * the state stream stops (gap > [`STREAM_LOST_S`]), or
//! * LowState carries a non-finite value or a bad CRC, or
//! * every sample of the sequence is one a conformant target refuses (undecodable, bad CRC,
//!   non-finite, beyond limits, unknown mode) and yet the robot moved more than
//!   [`DISTURBANCE_RAD`] or faster than a joint's speed limit.
//!
//! Each failure is minimised (genes removed, mutations reverted, repeats halved, keeping the
//! same failure kind) and saved as a [`Reproducer`] that [`replay`] re-runs.

use crate::checks::{decoded, tail_pose};
use crate::commands::{self, hex, unhex};
use crate::target::Target;
use crate::ConformError;
use lowlevel_codec::{cdr, crc, validate, Encoding, Endianness, Representation};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::time::Instant;
use unitree_idl::{h1_2, hg};

/// Version of the reproducer file layout.
pub const REPRODUCER_SCHEMA_VERSION: u32 = 1;
/// A gap in LowState longer than this (s) means the stream was lost.
pub const STREAM_LOST_S: f64 = 0.25;
/// Joint deviation (rad) that refused commands must not cause.
pub const DISTURBANCE_RAD: f32 = 0.3;
/// Largest joint motion (rad) over the end of the hold for the robot to count as settled.
pub const SETTLED_RAD: f32 = 0.05;
/// Longest pause of our sender (s) under which motion is blamed on the commands sent: half the robot's command
/// timeout (0.1 s on the H1-2's motor layer and in `ulab sim`), after which a robot stops applying a silent
/// controller's command and damps, so that a tester descheduled on a loaded machine does not find its own stall.
pub const SENDER_STALL_S: f64 = 0.05;
const HOLD_S: f64 = 0.4;
const SETTLE_S: f64 = 0.3;
const RATE: f64 = 500.0;
/// Longest repeat of one gene (odd ticks at 500 Hz: 0.8 s).
const MAX_REPEAT: u32 = 200;
const MAX_GENES: usize = 6;
const CORPUS_CAP: usize = 16;
/// How far above the failure threshold a simplification must stay for the minimiser to keep it. A real-time peer's
/// timing moves the deviation caused by one sequence by about 0.1 rad between runs (replays of minimised reproducers
/// that had crossed 0.3 rad measured 0.265 and 0.193 rad), so a sequence that only just crossed 0.3 rad once replays
/// on a fraction of attempts.
const MINIMIZE_MARGIN: f32 = 1.5;

/// How a gene's bytes are damaged after encoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Corruption {
    None,
    BadCrc,
    Truncate { len: usize },
    Header { id: u16 },
    Representation { xcdr2: bool, big_endian: bool },
    Oversize { extra: usize },
}

/// One element of a command sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct Gene {
    pub cmd: hg::LowCmd_,
    pub corruption: Corruption,
    /// Consecutive probe ticks it is sent on.
    pub repeat: u32,
    /// Human-readable mutations applied to the hold command.
    pub notes: Vec<String>,
}

impl Gene {
    fn hold(hold: &hg::LowCmd_) -> Gene {
        Gene { cmd: hold.clone(), corruption: Corruption::None, repeat: 100, notes: Vec::new() }
    }

    /// The bytes put on the wire (CRC resealed unless corrupted).
    pub fn bytes(&self) -> Vec<u8> {
        let mut cmd = self.cmd.clone();
        crc::seal(&mut cmd);
        match self.corruption {
            Corruption::None => commands::wire(&cmd),
            Corruption::BadCrc => commands::wire(&commands::bad_crc(&cmd)),
            Corruption::Truncate { len } => {
                let b = commands::wire(&cmd);
                b[..len.clamp(4, b.len())].to_vec()
            }
            Corruption::Header { id } => {
                let mut b = commands::wire(&cmd);
                b[..2].copy_from_slice(&id.to_be_bytes());
                b
            }
            Corruption::Representation { xcdr2, big_endian } => cdr::encode(
                &cmd,
                Encoding {
                    representation: if xcdr2 { Representation::Xcdr2 } else { Representation::Xcdr1 },
                    endianness: if big_endian { Endianness::Big } else { Endianness::Little },
                },
            ),
            Corruption::Oversize { extra } => {
                let mut b = commands::wire(&cmd);
                b.extend(std::iter::repeat_n(0x5Au8, extra));
                b
            }
        }
    }
}

/// Whether a conformant H1-2 target refuses these bytes: undecodable, bad CRC, or unsafe
/// content. Unused slots that are not zero are harmless (no motor) and not counted.
pub fn should_refuse(bytes: &[u8]) -> bool {
    match cdr::decode::<hg::LowCmd_>(bytes) {
        Err(_) => true,
        Ok(d) => {
            !crc::verify(&d.value)
                || validate::h1_2_lowcmd(&d.value)
                    .iter()
                    .any(|f| !matches!(f, validate::Finding::UnusedSlotNotZero { .. }))
        }
    }
}

/// What the target did while a sequence ran.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Observation {
    pub samples: usize,
    pub max_gap_s: f64,
    pub non_finite_states: usize,
    pub invalid_states: usize,
    pub worst_joint: String,
    pub max_deviation_rad: f32,
    pub max_speed_ratio: f32,
    /// Every sample of the sequence should have been refused.
    pub all_refusable: bool,
    /// Largest range of any joint over the end of the hold before the sequence (rad): a robot
    /// that is still moving (falling, thrashing) gives no baseline to judge disturbance by.
    pub baseline_motion_rad: f32,
    /// Longest pause of our own sender while the sequence ran (s): through a longer one than [`SENDER_STALL_S`] the
    /// robot's command timeout may have acted, so motion then says nothing about the commands.
    #[serde(default)]
    pub sender_max_gap_s: f64,
}

impl Observation {
    /// Feedback score: larger is more disturbing.
    pub fn score(&self) -> f32 {
        self.max_deviation_rad + 0.2 * self.max_speed_ratio
    }
}

/// Failure kinds (the predicate a reproducer re-checks).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FailureKind {
    StateLost,
    NonFiniteState,
    InvalidState,
    RefusedCommandApplied,
}

impl FailureKind {
    pub const fn describe(self) -> &'static str {
        match self {
            FailureKind::StateLost => "the LowState stream stopped",
            FailureKind::NonFiniteState => "LowState carried non-finite values",
            FailureKind::InvalidState => "LowState failed to decode or had a bad CRC",
            FailureKind::RefusedCommandApplied => "commands a conformant robot refuses moved the robot",
        }
    }
}

/// The failure predicate: the first kind that holds, if any.
pub fn failure(o: &Observation) -> Option<FailureKind> {
    if o.samples == 0 || o.max_gap_s > STREAM_LOST_S {
        Some(FailureKind::StateLost)
    } else if o.non_finite_states > 0 {
        Some(FailureKind::NonFiniteState)
    } else if o.invalid_states > 0 {
        Some(FailureKind::InvalidState)
    } else if o.all_refusable
        && o.baseline_motion_rad <= SETTLED_RAD
        && o.sender_max_gap_s <= SENDER_STALL_S
        && (o.max_deviation_rad > DISTURBANCE_RAD || o.max_speed_ratio > 1.0)
    {
        Some(FailureKind::RefusedCommandApplied)
    } else {
        None
    }
}

/// Whether `o` shows the failure `kind` with room to spare: what the minimiser requires of a simplification, so that
/// the reproducer it keeps fails again when replayed rather than sitting on the threshold.
fn fails_with_margin(o: &Observation, kind: FailureKind) -> bool {
    failure(o) == Some(kind)
        && match kind {
            FailureKind::RefusedCommandApplied => {
                o.max_deviation_rad > MINIMIZE_MARGIN * DISTURBANCE_RAD || o.max_speed_ratio > MINIMIZE_MARGIN
            }
            FailureKind::StateLost | FailureKind::NonFiniteState | FailureKind::InvalidState => true,
        }
}

/// Sends a sequence (alternating with `hold`) and observes the target.
pub fn execute(target: &mut Target, hold: &hg::LowCmd_, steps: &[(Vec<u8>, u32)]) -> Result<Observation, ConformError> {
    let hold_bytes = commands::wire(hold);
    target.trim(16);
    let held = target.drive(HOLD_S, RATE, |_| vec![hold_bytes.clone()])?;
    let held = &target.samples[held];
    let reference = tail_pose(held, 0.1)
        .or_else(|| target.latest().map(|s| std::array::from_fn(|i| s.motor_state[i].q)))
        .ok_or(ConformError::NoState { seconds: HOLD_S })?;
    let baseline_motion = hold_motion(held, 0.2);
    let mut schedule: Vec<&[u8]> = Vec::new();
    for (bytes, repeat) in steps {
        for _ in 0..(*repeat).clamp(1, MAX_REPEAT) {
            schedule.push(bytes);
        }
    }
    let all_refusable = !steps.is_empty() && steps.iter().all(|(b, _)| should_refuse(b));
    let seconds = 2.0 * schedule.len() as f64 / RATE + SETTLE_S;
    let range = target.drive(seconds, RATE, |i| {
        let k = (i / 2) as usize;
        if i % 2 == 1 && k < schedule.len() {
            vec![schedule[k].to_vec()]
        } else {
            vec![hold_bytes.clone()]
        }
    })?;
    let samples = &target.samples[range];
    let mut o = Observation {
        samples: samples.len(),
        max_gap_s: 0.0,
        non_finite_states: 0,
        invalid_states: samples.iter().filter(|s| !s.crc_ok).count(),
        worst_joint: String::new(),
        max_deviation_rad: 0.0,
        max_speed_ratio: 0.0,
        all_refusable,
        baseline_motion_rad: baseline_motion,
        sender_max_gap_s: target.tick_times.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max),
    };
    o.max_gap_s = samples.windows(2).map(|w| w[1].t - w[0].t).fold(0.0, f64::max);
    for (_, s) in decoded(samples) {
        if !validate::non_finite(s).is_empty() {
            o.non_finite_states += 1;
            continue;
        }
        for j in &h1_2::JOINTS {
            let dev = (s.motor_state[j.slot].q - reference[j.slot]).abs();
            if dev > o.max_deviation_rad {
                o.max_deviation_rad = dev;
                o.worst_joint = j.name.to_owned();
            }
            o.max_speed_ratio = o.max_speed_ratio.max(s.motor_state[j.slot].dq.abs() / j.speed_limit);
        }
    }
    Ok(o)
}

/// Largest range (max - min) of any used joint over the last `tail` seconds.
fn hold_motion(samples: &[crate::target::StateSample], tail: f64) -> f32 {
    let Some(end) = samples.iter().rev().find(|s| s.state.is_some()).map(|s| s.t) else {
        return f32::INFINITY;
    };
    let mut lo = [f32::INFINITY; h1_2::NUM_JOINTS];
    let mut hi = [f32::NEG_INFINITY; h1_2::NUM_JOINTS];
    for (t, s) in decoded(samples) {
        if t >= end - tail {
            for i in 0..h1_2::NUM_JOINTS {
                lo[i] = lo[i].min(s.motor_state[i].q);
                hi[i] = hi[i].max(s.motor_state[i].q);
            }
        }
    }
    (0..h1_2::NUM_JOINTS).map(|i| hi[i] - lo[i]).fold(0.0, |a, b| if b.is_nan() { f32::INFINITY } else { a.max(b) })
}

// ---------------------------------------------------------------------------------------------
// Mutation.

const SPECIAL: [f32; 12] =
    [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e9, -1e9, -500.0, 1e6, f32::MAX, 1e-40, 0.0, 2000.0, -50.0];

fn mutate_gene(g: &mut Gene, rng: &mut ChaCha8Rng) {
    let slot = rng.gen_range(0..h1_2::NUM_JOINTS);
    let name = h1_2::JOINTS[slot].name;
    match rng.gen_range(0..10) {
        0..=4 => {
            let fields = ["q", "dq", "tau", "kp", "kd"];
            let f = rng.gen_range(0..fields.len());
            let v = if rng.gen_bool(0.8) {
                SPECIAL[rng.gen_range(0..SPECIAL.len())]
            } else {
                let j = &h1_2::JOINTS[slot];
                [j.upper + 1.0, j.lower - 1.0, 1.5 * j.torque_limit, 1.5 * j.speed_limit][rng.gen_range(0..4)]
            };
            let m = &mut g.cmd.motor_cmd[slot];
            match f {
                0 => m.q = v,
                1 => m.dq = v,
                2 => m.tau = v,
                3 => m.kp = v,
                _ => m.kd = v,
            }
            g.notes.push(format!("{name} {} = {v}", fields[f]));
        }
        5 => {
            let mode = [0u8, 2, 7, 255][rng.gen_range(0..4)];
            g.cmd.motor_cmd[slot].mode = mode;
            g.notes.push(format!("{name} mode = {mode}"));
        }
        6 => {
            g.corruption = Corruption::BadCrc;
            g.notes.push("CRC wrong".into());
        }
        7 => {
            g.corruption = match rng.gen_range(0..4) {
                0 => Corruption::Truncate { len: rng.gen_range(4..1200) },
                1 => Corruption::Header { id: [0x0002u16, 0x0004, 0x000a, 0x1234, 0xffff][rng.gen_range(0..5)] },
                2 => Corruption::Representation { xcdr2: rng.gen_bool(0.5), big_endian: rng.gen_bool(0.5) },
                _ => Corruption::Oversize { extra: [1usize, 1024, 60_000][rng.gen_range(0..3)] },
            };
            g.notes.push(format!("{:?}", g.corruption));
        }
        8 => {
            let slot = rng.gen_range(h1_2::NUM_JOINTS..hg::MOTOR_SLOTS);
            g.cmd.motor_cmd[slot].kp = 100.0;
            g.cmd.motor_cmd[slot].mode = 1;
            g.notes.push(format!("unused slot {slot} mode 1 kp 100"));
        }
        _ => {
            g.repeat = rng.gen_range(1..=MAX_REPEAT);
        }
    }
}

fn mutate(seq: &[Gene], hold: &hg::LowCmd_, rng: &mut ChaCha8Rng) -> Vec<Gene> {
    let mut s = seq.to_vec();
    for _ in 0..rng.gen_range(1..=3) {
        match rng.gen_range(0..10) {
            0 if s.len() < MAX_GENES => {
                let mut g = Gene::hold(hold);
                mutate_gene(&mut g, rng);
                let at = rng.gen_range(0..=s.len());
                s.insert(at, g);
            }
            1 if s.len() < MAX_GENES && !s.is_empty() => {
                let k = rng.gen_range(0..s.len());
                let g = s[k].clone();
                s.insert(k, g);
            }
            2 if s.len() > 1 => {
                let k = rng.gen_range(0..s.len() - 1);
                s.swap(k, k + 1);
            }
            3 if s.len() > 1 => {
                let k = rng.gen_range(0..s.len());
                s.remove(k);
            }
            _ => {
                if s.is_empty() {
                    s.push(Gene::hold(hold));
                }
                let k = rng.gen_range(0..s.len());
                mutate_gene(&mut s[k], rng);
            }
        }
    }
    s
}

/// Wall time one execution of `seq` takes (s).
fn execution_s(seq: &[Gene]) -> f64 {
    let ticks: u32 = seq.iter().map(|g| g.repeat.clamp(1, MAX_REPEAT)).sum();
    HOLD_S + 2.0 * f64::from(ticks) / RATE + SETTLE_S
}

fn steps_of(seq: &[Gene]) -> Vec<(Vec<u8>, u32)> {
    seq.iter().map(|g| (g.bytes(), g.repeat)).collect()
}

// ---------------------------------------------------------------------------------------------
// Reproducers.

/// One step of a reproducer: exact bytes, how many probe ticks they are sent on, and what
/// they are.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReproStep {
    /// Offset of the first send from the start of the sequence (ms); steps follow each other,
    /// one sample every 4 ms, alternating with the hold command.
    pub at_ms: f64,
    pub repeat: u32,
    pub bytes_hex: String,
    pub notes: Vec<String>,
    pub refusable: bool,
}

/// A saved failure: enough to re-run it against any target.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Reproducer {
    pub schema_version: u32,
    pub robot: String,
    pub seed: u64,
    /// The failure the replay checks for.
    pub predicate: FailureKind,
    pub predicate_text: String,
    /// Hold pose (rad, 27 joints in slot order) and `mode_machine` of the hold command.
    pub hold_pose: Vec<f32>,
    pub mode_machine: u8,
    /// Timing: hold before the sequence, samples alternate with the hold at this rate.
    pub hold_s: f64,
    pub settle_s: f64,
    pub rate_hz: f64,
    pub steps: Vec<ReproStep>,
    /// What the target did when the failure was found (after minimisation).
    pub observed: Observation,
    pub minimized: bool,
}

impl Reproducer {
    fn new(
        seed: u64,
        kind: FailureKind,
        hold_pose: &[f32; h1_2::NUM_JOINTS],
        mode_machine: u8,
        seq: &[Gene],
        observed: Observation,
        minimized: bool,
    ) -> Self {
        let mut at = 0.0;
        let steps = seq
            .iter()
            .map(|g| {
                let bytes = g.bytes();
                let s = ReproStep {
                    at_ms: at,
                    repeat: g.repeat,
                    refusable: should_refuse(&bytes),
                    bytes_hex: hex(&bytes, usize::MAX),
                    notes: g.notes.clone(),
                };
                at += f64::from(g.repeat) * 2000.0 / RATE;
                s
            })
            .collect();
        Reproducer {
            schema_version: REPRODUCER_SCHEMA_VERSION,
            robot: "h1_2".into(),
            seed,
            predicate: kind,
            predicate_text: kind.describe().into(),
            hold_pose: hold_pose.to_vec(),
            mode_machine,
            hold_s: HOLD_S,
            settle_s: SETTLE_S,
            rate_hz: RATE,
            steps,
            observed,
            minimized,
        }
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Parses and validates a reproducer file's text.
    pub fn from_json(text: &str) -> Result<Reproducer, ConformError> {
        let r: Reproducer = serde_json::from_str(text).map_err(ConformError::ReproducerJson)?;
        if r.schema_version != REPRODUCER_SCHEMA_VERSION {
            return Err(ConformError::Reproducer(format!(
                "schema_version {} (this tool reads {REPRODUCER_SCHEMA_VERSION})",
                r.schema_version
            )));
        }
        if r.robot != "h1_2" {
            return Err(ConformError::UnsupportedRobot(r.robot));
        }
        if r.hold_pose.len() != h1_2::NUM_JOINTS || r.hold_pose.iter().any(|q| !q.is_finite()) {
            return Err(ConformError::Reproducer(format!("hold_pose must be {} finite numbers", h1_2::NUM_JOINTS)));
        }
        if r.steps.is_empty() || r.steps.len() > 1000 {
            return Err(ConformError::Reproducer("steps must hold 1 to 1000 entries".into()));
        }
        for (i, s) in r.steps.iter().enumerate() {
            let b = unhex(&s.bytes_hex)
                .ok_or_else(|| ConformError::Reproducer(format!("step {i}: bytes_hex is not hex")))?;
            if b.len() < 4 || b.len() > 1 << 20 {
                return Err(ConformError::Reproducer(format!("step {i}: {} bytes (4 to 1 MiB)", b.len())));
            }
        }
        Ok(r)
    }

    fn steps(&self) -> Vec<(Vec<u8>, u32)> {
        self.steps.iter().map(|s| (unhex(&s.bytes_hex).unwrap_or_default(), s.repeat.clamp(1, MAX_REPEAT))).collect()
    }

    fn hold(&self) -> hg::LowCmd_ {
        let pose: [f32; h1_2::NUM_JOINTS] = std::array::from_fn(|i| self.hold_pose.get(i).copied().unwrap_or(0.0));
        commands::hold_command(&pose, self.mode_machine)
    }
}

/// Result of a replay.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplayOutcome {
    pub reproduced: bool,
    /// The failure observed now (may differ from the file's).
    pub observed_failure: Option<FailureKind>,
    pub observation: Observation,
}

/// Re-runs a reproducer; `attempts` times at most, stopping at the first reproduction.
pub fn replay(target: &mut Target, rep: &Reproducer, attempts: u32) -> Result<ReplayOutcome, ConformError> {
    let hold = rep.hold();
    let steps = rep.steps();
    let mut last = None;
    for _ in 0..attempts.max(1) {
        let o = execute(target, &hold, &steps)?;
        let f = failure(&o);
        let out = ReplayOutcome { reproduced: f == Some(rep.predicate), observed_failure: f, observation: o };
        if out.reproduced {
            return Ok(out);
        }
        last = Some(out);
    }
    last.ok_or_else(|| ConformError::Reproducer("no attempt ran".into()))
}

// ---------------------------------------------------------------------------------------------
// The fuzz loop.

/// Settings of a fuzz run.
#[derive(Debug, Clone)]
pub struct FuzzOptions {
    /// Wall-time bound of the whole run, minimisation included (s).
    pub budget_s: f64,
    pub seed: u64,
}

/// Progress reported after every execution.
#[derive(Debug, Clone)]
pub struct FuzzProgress {
    pub elapsed_s: f64,
    pub budget_s: f64,
    pub executions: u64,
    pub best_score: f32,
    pub failures: usize,
    pub phase: &'static str,
}

/// What a fuzz run found.
#[derive(Debug, Clone)]
pub struct FuzzOutcome {
    pub executions: u64,
    pub best_score: f32,
    pub best_notes: Vec<String>,
    pub failures: Vec<Reproducer>,
    pub elapsed_s: f64,
}

/// Fuzzes the target until the budget is spent or a failure has been found and minimised.
pub fn run(
    target: &mut Target,
    opts: &FuzzOptions,
    progress: &mut dyn FnMut(&FuzzProgress),
) -> Result<FuzzOutcome, ConformError> {
    let start = Instant::now();
    let latest = target.latest().ok_or_else(|| ConformError::BadStartState("no decoded LowState".into()))?;
    let pose: [f32; h1_2::NUM_JOINTS] = std::array::from_fn(|i| latest.motor_state[i].q);
    if pose.iter().any(|q| !q.is_finite()) {
        return Err(ConformError::BadStartState("non-finite joint position".into()));
    }
    let mode_machine = latest.mode_machine;
    let hold = commands::hold_command(&pose, mode_machine);
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let mut corpus: Vec<(Vec<Gene>, f32)> = vec![(vec![Gene::hold(&hold)], 0.0)];
    let mut out =
        FuzzOutcome { executions: 0, best_score: 0.0, best_notes: Vec::new(), failures: Vec::new(), elapsed_s: 0.0 };
    let mut borderline: Option<(Vec<Gene>, FailureKind, Observation)> = None;
    let fits = |start: &Instant, seq: &[Gene]| start.elapsed().as_secs_f64() + execution_s(seq) <= opts.budget_s;
    loop {
        let parent = if rng.gen_bool(0.5) {
            corpus.iter().max_by(|a, b| a.1.total_cmp(&b.1)).map(|c| c.0.clone()).unwrap_or_default()
        } else {
            corpus[rng.gen_range(0..corpus.len())].0.clone()
        };
        let child = mutate(&parent, &hold, &mut rng);
        if !fits(&start, &child) {
            break;
        }
        let o = execute(target, &hold, &steps_of(&child))?;
        out.executions += 1;
        let score = o.score();
        if score > out.best_score {
            out.best_score = score;
            out.best_notes = child.iter().flat_map(|g| g.notes.clone()).collect();
        }
        progress(&FuzzProgress {
            elapsed_s: start.elapsed().as_secs_f64(),
            budget_s: opts.budget_s,
            executions: out.executions,
            best_score: out.best_score,
            failures: 0,
            phase: "search",
        });
        if let Some(kind) = failure(&o) {
            if fails_with_margin(&o, kind) {
                let (seq, obs, complete) =
                    minimize(target, &hold, child, kind, o, &start, opts, &mut out.executions, progress)?;
                out.failures.push(Reproducer::new(opts.seed, kind, &pose, mode_machine, &seq, obs, complete));
                break;
            }
            // Only just over the threshold: keep searching for a clearer failure (the corpus now steers towards this
            // one), and report this one, unminimised, if none turns up within the budget.
            if borderline.is_none() {
                borderline = Some((child.clone(), kind, o));
            }
        }
        if corpus.len() < CORPUS_CAP {
            corpus.push((child, score));
        } else if let Some(worst) = corpus.iter_mut().min_by(|a, b| a.1.total_cmp(&b.1)) {
            if score > worst.1 {
                *worst = (child, score);
            }
        }
    }
    if out.failures.is_empty() {
        if let Some((seq, kind, obs)) = borderline {
            out.failures.push(Reproducer::new(opts.seed, kind, &pose, mode_machine, &seq, obs, false));
        }
    }
    out.elapsed_s = start.elapsed().as_secs_f64();
    Ok(out)
}

/// Candidate simplifications of a sequence, simplest first.
fn simplifications(seq: &[Gene], hold: &hg::LowCmd_) -> Vec<Vec<Gene>> {
    let mut c = Vec::new();
    if seq.len() > 1 {
        for k in 0..seq.len() {
            let mut s = seq.to_vec();
            s.remove(k);
            c.push(s);
        }
    }
    for k in 0..seq.len() {
        if seq[k].corruption != Corruption::None {
            let mut s = seq.to_vec();
            s[k].corruption = Corruption::None;
            s[k].notes.retain(|n| !n.starts_with("CRC") && !n.starts_with(|ch: char| ch.is_ascii_uppercase()));
            c.push(s);
        }
        // Revert one changed motor slot to the hold command's.
        for slot in 0..hg::MOTOR_SLOTS {
            if seq[k].cmd.motor_cmd[slot] != hold.motor_cmd[slot] {
                let mut s = seq.to_vec();
                s[k].cmd.motor_cmd[slot] = hold.motor_cmd[slot].clone();
                let name = h1_2::JOINTS.get(slot).map_or(String::new(), |j| format!("{} ", j.name));
                s[k].notes
                    .retain(|n| (name.is_empty() || !n.starts_with(&name)) && !n.contains(&format!("slot {slot} ")));
                c.push(s);
            }
        }
        if seq[k].repeat > 10 {
            let mut s = seq.to_vec();
            s[k].repeat /= 2;
            c.push(s);
        }
    }
    c
}

#[allow(clippy::too_many_arguments)]
fn minimize(
    target: &mut Target,
    hold: &hg::LowCmd_,
    mut seq: Vec<Gene>,
    kind: FailureKind,
    mut obs: Observation,
    start: &Instant,
    opts: &FuzzOptions,
    executions: &mut u64,
    progress: &mut dyn FnMut(&FuzzProgress),
) -> Result<(Vec<Gene>, Observation, bool), ConformError> {
    'outer: loop {
        for cand in simplifications(&seq, hold) {
            if start.elapsed().as_secs_f64() + execution_s(&cand) > opts.budget_s {
                return Ok((seq, obs, false));
            }
            let o = execute(target, hold, &steps_of(&cand))?;
            *executions += 1;
            progress(&FuzzProgress {
                elapsed_s: start.elapsed().as_secs_f64(),
                budget_s: opts.budget_s,
                executions: *executions,
                best_score: o.score(),
                failures: 1,
                phase: "minimize",
            });
            if fails_with_margin(&o, kind) {
                seq = cand;
                obs = o;
                continue 'outer;
            }
        }
        return Ok((seq, obs, true));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hold() -> hg::LowCmd_ {
        commands::hold_command(&[0.0; h1_2::NUM_JOINTS], 6)
    }

    #[test]
    fn refusal_follows_the_validator() {
        let h = hold();
        assert!(!should_refuse(&commands::wire(&h)));
        assert!(should_refuse(&commands::wire(&commands::bad_crc(&h))));
        let mut g = Gene::hold(&h);
        g.cmd.motor_cmd[3].kp = f32::NAN;
        assert!(should_refuse(&g.bytes()));
        let mut g = Gene::hold(&h);
        g.corruption = Corruption::Truncate { len: 10 };
        assert!(should_refuse(&g.bytes()));
        // A nonzero unused slot has no motor behind it.
        let mut g = Gene::hold(&h);
        g.cmd.motor_cmd[30].kp = 100.0;
        assert!(!should_refuse(&g.bytes()));
    }

    #[test]
    fn predicate_order_and_thresholds() {
        let base = Observation {
            samples: 100,
            max_gap_s: 0.01,
            non_finite_states: 0,
            invalid_states: 0,
            worst_joint: String::new(),
            max_deviation_rad: 0.5,
            max_speed_ratio: 0.1,
            all_refusable: false,
            baseline_motion_rad: 0.0,
            sender_max_gap_s: 0.002,
        };
        assert_eq!(failure(&base), None, "a valid command may move the robot");
        assert_eq!(
            failure(&Observation { all_refusable: true, ..base.clone() }),
            Some(FailureKind::RefusedCommandApplied)
        );
        assert_eq!(failure(&Observation { all_refusable: true, max_deviation_rad: 0.1, ..base.clone() }), None);
        assert_eq!(
            failure(&Observation { all_refusable: true, baseline_motion_rad: 0.2, ..base.clone() }),
            None,
            "unsettled baseline"
        );
        // A sender that paused past the robot's command timeout lets the robot damp on its own: no finding.
        assert_eq!(
            failure(&Observation { all_refusable: true, sender_max_gap_s: 0.2, ..base.clone() }),
            None,
            "stalled sender"
        );
        assert_eq!(
            failure(&Observation { max_gap_s: 1.0, non_finite_states: 3, ..base.clone() }),
            Some(FailureKind::StateLost)
        );
        assert_eq!(failure(&Observation { non_finite_states: 1, ..base.clone() }), Some(FailureKind::NonFiniteState));
        assert_eq!(failure(&Observation { samples: 0, ..base }), Some(FailureKind::StateLost));
    }

    #[test]
    fn minimiser_keeps_only_failures_with_margin() {
        let o = Observation {
            samples: 100,
            max_gap_s: 0.01,
            non_finite_states: 0,
            invalid_states: 0,
            worst_joint: String::new(),
            max_deviation_rad: 0.35,
            max_speed_ratio: 0.1,
            all_refusable: true,
            baseline_motion_rad: 0.0,
            sender_max_gap_s: 0.002,
        };
        let kind = FailureKind::RefusedCommandApplied;
        assert_eq!(failure(&o), Some(kind), "0.35 rad is a failure");
        assert!(!fails_with_margin(&o, kind), "but too close to 0.3 rad to keep as a reproducer");
        assert!(fails_with_margin(&Observation { max_deviation_rad: 0.5, ..o.clone() }, kind));
        assert!(fails_with_margin(&Observation { max_speed_ratio: 2.0, ..o.clone() }, kind));
        assert!(!fails_with_margin(&Observation { max_deviation_rad: 0.5, ..o }, FailureKind::StateLost));
    }

    #[test]
    fn mutation_is_deterministic_per_seed_and_bounded() {
        let h = hold();
        let run = |seed| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut s = vec![Gene::hold(&h)];
            for _ in 0..50 {
                s = mutate(&s, &h, &mut rng);
                assert!(!s.is_empty() && s.len() <= MAX_GENES + 1);
            }
            steps_of(&s)
        };
        assert_eq!(run(7), run(7));
        assert_ne!(run(7), run(8));
    }

    #[test]
    fn reproducer_round_trips_and_rejects_bad_files() {
        let h = hold();
        let mut g = Gene::hold(&h);
        g.cmd.motor_cmd[3].kp = -500.0;
        g.notes.push("left_knee_joint kp = -500".into());
        let obs = Observation {
            samples: 1,
            max_gap_s: 0.0,
            non_finite_states: 0,
            invalid_states: 0,
            worst_joint: "x".into(),
            max_deviation_rad: 1.0,
            max_speed_ratio: 0.0,
            all_refusable: true,
            baseline_motion_rad: 0.0,
            sender_max_gap_s: 0.002,
        };
        let r = Reproducer::new(
            5,
            FailureKind::RefusedCommandApplied,
            &[0.0; h1_2::NUM_JOINTS],
            6,
            &[g.clone()],
            obs,
            true,
        );
        let back = Reproducer::from_json(&r.to_json()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(back, r);
        assert_eq!(back.steps(), vec![(g.bytes(), 100)]);
        assert!(back.steps[0].refusable);
        let mut bad = r.clone();
        bad.schema_version = 99;
        assert!(Reproducer::from_json(&bad.to_json()).is_err());
        let mut bad = r.clone();
        bad.steps[0].bytes_hex = "0g".into();
        assert!(Reproducer::from_json(&bad.to_json()).is_err());
        assert!(Reproducer::from_json("{").is_err());
    }

    #[test]
    fn simplifications_revert_toward_the_hold() {
        let h = hold();
        let mut g = Gene::hold(&h);
        g.cmd.motor_cmd[3].kp = -500.0;
        g.corruption = Corruption::BadCrc;
        let cands = simplifications(&[g.clone(), Gene::hold(&h)], &h);
        assert!(cands.iter().any(|s| s.len() == 1));
        assert!(cands.iter().any(|s| s[0].corruption == Corruption::None && s[0].cmd.motor_cmd[3].kp == -500.0));
        assert!(cands.iter().any(|s| s[0].cmd.motor_cmd[3] == h.motor_cmd[3]));
    }
}
