//! The default check run. Each check judges one property, on the evidence that bears on it alone, so that one fault
//! of the peer fails one check and not its neighbours:
//!
//! * the **state stream** is judged once: CRC on every sample, rate, jitter and tick while nothing is sent
//!   (`stream`); freshness, finiteness, quaternion and joint ranges only on *clean* traffic (before any probe that
//!   a conformant peer refuses), so that the consequences of a wrongly applied probe are reported by that probe's
//!   check alone;
//! * everything else uses the samples as they come, CRC or not, with durations scaled to the rate the peer was
//!   measured to publish at ([`Timing`]);
//! * **command handling** (`command`) steps several free arm joints in both directions and reads the evidence a
//!   command leaves: the joint's motion where it can move, and the `tau_est` it reports, compared with the torque
//!   Unitree's PD law gives for each candidate interpretation of the command;
//! * **robustness** (`robust`): malformed samples alternate with a valid hold; the peer must keep publishing
//!   (relative to its own measured rate) and keep the robot where it was;
//! * **interop** ([`crate::interop`]): Cyclone DDS 0.10.2 and Cyclone 11 participants of our own try to read the
//!   peer's state.
//!
//! How the probing checks turn probes into a verdict (a pass at once, a fail only when it repeats, at most three
//! probes), and the margin every check reports, are in [`decision`].

mod command;
mod decision;
mod discovery;
mod robust;
mod stream;

use crate::interop::{self, InteropOptions};
use crate::report::{CheckId, CheckResult, Group, Status};
use crate::target::{StateSample, Target};
use crate::ConformError;
use std::collections::BTreeSet;
use unitree_idl::{h1_2, hg};

pub use stream::StreamFacts;

/// Settings of a check run.
#[derive(Debug, Clone)]
pub struct Options {
    /// Nominal LowState rate (Hz) `state_rate` is judged against (the real robot: about 500 Hz).
    pub expected_state_rate_hz: f64,
    /// Passive observation at the start (s).
    pub passive_s: f64,
    /// Which checks to run (phases nothing asks for are skipped).
    pub selection: Selection,
    /// The interop probes.
    pub interop: InteropOptions,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            expected_state_rate_hz: 500.0,
            passive_s: 1.5,
            selection: Selection::all(),
            interop: InteropOptions::default(),
        }
    }
}

/// The checks asked for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Selection(BTreeSet<CheckId>);

impl Selection {
    /// Every check of the default run.
    pub fn all() -> Self {
        Selection(CheckId::DEFAULT_RUN.into_iter().collect())
    }

    /// Parses a comma-separated list of check ids and group names (`state_stream`, `discovery`, `interop`,
    /// `command_handling`, `robustness`).
    pub fn parse(text: &str) -> Result<Self, ConformError> {
        let mut set = BTreeSet::new();
        for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let group = CheckId::DEFAULT_RUN.into_iter().filter(|c| c.group().name() == item).collect::<Vec<_>>();
            if !group.is_empty() {
                set.extend(group);
            } else if let Some(id) = CheckId::parse(item).filter(|c| CheckId::DEFAULT_RUN.contains(c)) {
                set.insert(id);
            } else {
                return Err(ConformError::Selection(format!(
                    "`{item}` is neither a check nor a group (groups: state_stream, discovery, interop, command_handling, robustness)"
                )));
            }
        }
        if set.is_empty() {
            return Err(ConformError::Selection("no check selected".into()));
        }
        Ok(Selection(set))
    }

    pub fn wants(&self, id: CheckId) -> bool {
        self.0.contains(&id)
    }

    fn wants_group(&self, g: Group) -> bool {
        self.0.iter().any(|c| c.group() == g)
    }

    /// The selected ids in report order.
    pub fn ids(&self) -> Vec<CheckId> {
        CheckId::DEFAULT_RUN.into_iter().filter(|c| self.0.contains(c)).collect()
    }
}

pub use crate::timing::Timing;

/// Rate at which commands are published in every phase (Hz), Unitree's usual control rate.
pub const COMMAND_RATE: f64 = 500.0;

/// What a check run produced.
#[derive(Debug, Clone)]
pub struct RunOutcome {
    pub results: Vec<CheckResult>,
    /// The stream as measured while nothing was sent.
    pub facts: Option<StreamFacts>,
    /// How the peer's participant (the one publishing rt/lowstate) answered on the wire (loopback only).
    pub wire: Option<crate::wire::WireParticipant>,
}

/// Runs the selected checks against a connected target. `progress` gets a short line per phase.
pub fn run_all(
    target: &mut Target,
    opts: &Options,
    progress: &mut dyn FnMut(&str),
) -> Result<RunOutcome, ConformError> {
    let sel = &opts.selection;
    let domain = target.config().domain_id();
    let sniff = dds_transport::config::is_loopback_interface(target.config().interface_name()).then(|| {
        std::thread::spawn(move || crate::wire::answering_participants(domain, std::time::Duration::from_millis(1500)))
    });
    let mut results: Vec<CheckResult> = Vec::new();
    // The Cyclone 0.10.2 probe only listens: it runs beside the whole run. The Cyclone 11 one comes last (its XTypes
    // type information can crash a peer built on Cyclone 0.10).
    let c010 = sel.wants(CheckId::InteropCyclone010).then(|| interop::start_c010(target, &opts.interop));
    let c11 = sel.wants(CheckId::InteropCyclone11).then(|| interop::start_cyclone11(target, &opts.interop));

    progress("state stream: observing without sending");
    let passive = target.observe(opts.passive_s)?;
    let facts = StreamFacts::measure(&target.samples[passive.clone()]);
    let timing = Timing::from_period(facts.as_ref().map_or(1.0 / opts.expected_state_rate_hz, StreamFacts::period));

    if sel.wants(CheckId::DiscoveryTypesQos) {
        results.push(discovery::types_qos(target)?);
    }

    // Command phases: the clean part (initial hold and valid steps) first, then everything a conformant peer refuses.
    let needs_session = sel.wants_group(Group::CommandHandling)
        || sel.wants_group(Group::Robustness)
        || sel.wants(CheckId::StateFresh)
        || sel.wants(CheckId::StateJointLimits);
    let mut driven = target.samples.len()..target.samples.len();
    if needs_session {
        let mode_machine = target.latest().map_or(h1_2::MODE_MACHINE, |s| s.mode_machine);
        if !target.command_reader_matched {
            let why = "no reader of the target matched our rt/lowcmd writer";
            for id in sel.ids().into_iter().filter(|c| matches!(c.group(), Group::CommandHandling | Group::Robustness))
            {
                results.push(CheckResult::new(id, Status::Inconclusive, why).with_probes(0));
            }
        } else {
            let mut s = command::Session::start(target, mode_machine, timing)?;
            progress("command handling: choosing test joints and stepping them");
            let calibration = s.calibrate()?;
            driven = calibration.driven.clone();
            if sel.wants(CheckId::CmdValidMovesJoint) {
                results.push(calibration.result.clone());
            }
            if sel.wants(CheckId::CmdBadCrcIgnored) {
                results.push(decision::settle(|| s.bad_crc_ignored())?);
            }
            if sel.wants(CheckId::CmdMode0NoTorque) {
                results.push(decision::settle(|| s.mode0_no_torque())?);
            }
            if sel.wants(CheckId::CmdAbsurdGainsSafe) {
                progress("command handling: absurd gains");
                results.push(decision::settle(|| s.absurd_gains_safe())?);
            }
            if sel.wants(CheckId::CmdNonFiniteRejected) {
                progress("command handling: non-finite values");
                results.push(decision::settle(|| s.non_finite_rejected())?);
            }
            if sel.wants_group(Group::Robustness) {
                progress("robustness");
                results.extend(robust::run(&mut s, sel, facts.as_ref())?);
            }
            if sel.wants(CheckId::CmdTimeoutBehaviour) {
                progress("command loss: stopping commands");
                // Last of the command phases: after it the robot may legitimately collapse.
                results.push(decision::settle(|| s.timeout_behaviour())?);
            }
        }
    }

    if let Some(probe) = c010 {
        progress("interop: Cyclone DDS 0.10.2 probe");
        results.push(interop::finish_c010(probe, target));
    }
    if let Some(probe) = c11 {
        progress("interop: Cyclone 11 probe");
        results.push(interop::finish_cyclone11(probe, target, timing)?);
    }

    // State stream, each property on its own evidence.
    let samples = &target.samples;
    let clean: Vec<StateSample> =
        samples[passive.clone()].iter().chain(&samples[driven.clone()]).cloned().collect::<Vec<_>>();
    let mut stream = Vec::new();
    for id in sel.ids().into_iter().filter(|c| c.group() == Group::StateStream) {
        stream.push(match id {
            CheckId::StateCrc => stream::crc(samples),
            CheckId::StateRate => stream::rate(facts.as_ref(), opts.expected_state_rate_hz),
            CheckId::StateJitter => stream::jitter(&samples[passive.clone()], facts.as_ref()),
            CheckId::StateTick => stream::tick(&samples[passive.clone()]),
            CheckId::StateFresh => stream::fresh(&samples[driven.clone()]),
            CheckId::StateFinite => stream::finite(&clean),
            CheckId::StateQuaternion => stream::quaternion(&clean),
            CheckId::StateJointLimits => stream::joint_limits(&samples[driven.clone()]),
            _ => continue,
        });
    }
    stream.append(&mut results);
    let order = |id: CheckId| CheckId::DEFAULT_RUN.iter().position(|c| *c == id).unwrap_or(usize::MAX);
    stream.sort_by_key(|r| order(r.id));
    let answers = sniff.and_then(|h| h.join().ok()).and_then(Result::ok).unwrap_or_default();
    let peer = target.remote_endpoints()?.into_iter().find(|e| e.topic_name == unitree_idl::topics::LOWSTATE);
    let wire = peer.and_then(|e| {
        let mut prefix = [0u8; 12];
        prefix.copy_from_slice(&e.participant_guid[..12]);
        answers.get(&prefix).copied()
    });
    Ok(RunOutcome { results: stream, facts, wire })
}

// ---------------------------------------------------------------------------------------------
// Sample statistics shared by the checks and the fuzzer.

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
pub(crate) fn intervals(times: &[f64]) -> Option<(f64, f64, f64, f64)> {
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

pub(crate) fn round(x: f64, digits: i32) -> f64 {
    let f = 10f64.powi(digits);
    (x * f).round() / f
}

/// Number of decoded samples and the time they span.
pub(crate) fn span(samples: &[StateSample]) -> Option<(usize, f64)> {
    let mut it = decoded(samples);
    let first = it.next()?.0;
    let (n, last) = it.fold((1usize, first), |(n, _), (t, _)| (n + 1, t));
    (n >= 2 && last > first).then_some((n, last - first))
}

/// Largest gap between consecutive samples (s), including the time from `from` to the first one.
pub(crate) fn max_gap(samples: &[StateSample], from: f64, to: f64) -> f64 {
    let mut last = from;
    let mut gap = 0.0f64;
    for s in samples {
        gap = gap.max(s.t - last);
        last = s.t;
    }
    gap.max(to - last)
}

/// Tilt of the IMU's z axis from vertical (rad), from a (w, x, y, z) quaternion.
pub(crate) fn tilt(q: [f32; 4]) -> f64 {
    let [_, x, y, _] = q.map(f64::from);
    let n2: f64 = q.iter().map(|v| f64::from(*v).powi(2)).sum();
    if !(n2 > 0.0) || !n2.is_finite() {
        return f64::NAN;
    }
    (1.0 - 2.0 * (x * x + y * y) / n2).clamp(-1.0, 1.0).acos()
}
