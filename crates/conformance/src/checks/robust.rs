//! Robustness: malformed or unusual LowCmd samples alternate with the valid hold. Each case passes when the peer
//! keeps publishing LowState (no gap beyond the stream-loss limit, at least half its own measured rate), the state
//! stays finite, and every joint that was settled under the hold stays within [`HOLD_TOLERANCE`] of it. The state's
//! CRC and its rate against the nominal one are the state-stream checks' business, not these.

use super::command::Session;
use super::{decoded, max_gap, round, span, tail_pose, StreamFacts, COMMAND_RATE};
use crate::commands::{self, hex, wire};
use crate::report::{CheckId, CheckResult, Margin, Status};
use crate::ConformError;
use lowlevel_codec::{cdr, validate, Encoding, Endianness, Representation};
use unitree_idl::h1_2;

/// How far (rad) a settled joint may stray from its hold while the peer is fed malformed samples.
pub const HOLD_TOLERANCE: f32 = 0.15;
/// Settled: a joint's position varies by at most this much over the hold's tail (rad).
const SETTLED_RANGE_RAD: f32 = 0.05;
/// The stream must keep at least this fraction of the peer's own measured rate.
const MIN_RATE_FRACTION: f64 = 0.5;
/// Each case runs this long (s), at least.
const CASE_S: f64 = 0.5;

pub(super) fn run(
    s: &mut Session<'_>,
    sel: &super::Selection,
    facts: Option<&StreamFacts>,
) -> Result<Vec<CheckResult>, ConformError> {
    let hold = s.hold.clone();
    let good = wire(&hold);
    let mut out = Vec::new();
    if sel.wants(CheckId::RobustTruncated) {
        let truncated: Vec<Vec<u8>> = [4, 5, 8, 100, good.len() / 2, good.len() - 1]
            .iter()
            .map(|len| good[..(*len).min(good.len())].to_vec())
            .collect();
        out.push(super::decision::settle(|| {
            case(
                s,
                facts,
                CheckId::RobustTruncated,
                "truncated LowCmd samples (4 bytes up to one byte short)",
                &truncated,
                1,
            )
        })?);
    }
    if sel.wants(CheckId::RobustBadHeader) {
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
        out.push(super::decision::settle(|| {
            case(
                s,
                facts,
                CheckId::RobustBadHeader,
                "wrong encapsulation headers (PL_CDR, XML, PL_CDR2, unknown ids)",
                &bad_header,
                1,
            )
        })?);
    }
    if sel.wants(CheckId::RobustOversize) {
        let oversize: Vec<Vec<u8>> = [1024usize, 60 * 1024]
            .iter()
            .map(|extra| {
                let mut b = good.clone();
                b.extend(std::iter::repeat_n(0xA5u8, *extra));
                b
            })
            .collect();
        out.push(super::decision::settle(|| {
            case(
                s,
                facts,
                CheckId::RobustOversize,
                "oversize samples (valid command + 1 KiB and + 60 KiB of junk)",
                &oversize,
                1,
            )
        })?);
    }
    if sel.wants(CheckId::RobustXcdr2) {
        let encodings: Vec<Vec<u8>> = [
            Encoding { representation: Representation::Xcdr2, endianness: Endianness::Little },
            Encoding { representation: Representation::Xcdr2, endianness: Endianness::Big },
            Encoding { representation: Representation::Xcdr1, endianness: Endianness::Big },
        ]
        .iter()
        .map(|e| cdr::encode(&hold, *e))
        .collect();
        out.push(super::decision::settle(|| {
            case(s, facts, CheckId::RobustXcdr2, "the hold command in XCDR2 LE/BE and XCDR1 BE", &encodings, 1)
        })?);
    }
    if sel.wants(CheckId::RobustFlood) {
        out.push(super::decision::settle(|| {
            case(
                s,
                facts,
                CheckId::RobustFlood,
                "a flood of valid hold commands at 10x the control rate (5 kHz)",
                std::slice::from_ref(&good),
                10,
            )
        })?);
    }
    if sel.wants(CheckId::RobustDuplicatesReordering) {
        // Small variations of one arm joint around where it stands, each sent twice, pairs swapped.
        let slot = 16;
        let reference = s.target.latest().map_or(0.0, |st| st.motor_state[slot].q);
        let (kp, kd) = commands::hold_gains(slot);
        let wiggle: Vec<Vec<u8>> = (0..8)
            .map(|k| {
                let mut c = hold.clone();
                c.motor_cmd[slot].q = commands::clamp_target(slot, reference + 0.01 * (k as f32 - 4.0));
                c.motor_cmd[slot].kp = kp;
                c.motor_cmd[slot].kd = kd;
                lowlevel_codec::crc::seal(&mut c);
                wire(&c)
            })
            .collect();
        let mut shuffled = Vec::new();
        for pair in wiggle.chunks(2) {
            for m in pair.iter().rev() {
                shuffled.push(m.clone());
                shuffled.push(m.clone());
            }
        }
        out.push(super::decision::settle(|| {
            case(s, facts, CheckId::RobustDuplicatesReordering, "duplicated and reordered commands", &shuffled, 1)
        })?);
    }
    Ok(out)
}

/// Alternates the hold with `bad[k % len]` (`burst` samples per tick after the hold when `burst > 1`).
fn case(
    s: &mut Session<'_>,
    facts: Option<&StreamFacts>,
    id: CheckId,
    what: &str,
    bad: &[Vec<u8>],
    burst: usize,
) -> Result<CheckResult, ConformError> {
    let timing = s.timing;
    let hold_bytes = s.hold_bytes();
    let held = s.target.drive(timing.hold, COMMAND_RATE, |_| vec![hold_bytes.clone()])?;
    let hold_samples = s.target.samples[held.clone()].to_vec();
    let reference = tail_pose(&hold_samples, timing.tail);
    // Joints that were settled under the hold: only they are expected to stay put.
    let end = hold_samples.last().map_or(0.0, |x| x.t);
    let mut lo = [f32::INFINITY; h1_2::NUM_JOINTS];
    let mut hi = [f32::NEG_INFINITY; h1_2::NUM_JOINTS];
    for (_, st) in decoded(&hold_samples).filter(|(t, _)| *t >= end - timing.tail) {
        for i in 0..h1_2::NUM_JOINTS {
            lo[i] = lo[i].min(st.motor_state[i].q);
            hi[i] = hi[i].max(st.motor_state[i].q);
        }
    }
    let settled: Vec<usize> = (0..h1_2::NUM_JOINTS).filter(|&i| hi[i] - lo[i] <= SETTLED_RANGE_RAD).collect();

    let list = bad.to_vec();
    let mut k = 0usize;
    let seconds = CASE_S.max(timing.probe);
    let start = s.target.elapsed();
    let range = s.target.drive(seconds, COMMAND_RATE, move |i| {
        if i % 2 == 0 && burst == 1 {
            vec![hold_bytes.clone()]
        } else {
            let mut v = Vec::with_capacity(burst + 1);
            if burst > 1 {
                v.push(hold_bytes.clone());
            }
            for _ in 0..burst {
                v.push(list[k % list.len()].clone());
                k += 1;
            }
            v
        }
    })?;
    let samples = &s.target.samples[range];
    let rate = span(samples).map_or(0.0, |(n, dt)| (n - 1) as f64 / dt);
    let gap = max_gap(samples, start, s.target.elapsed());
    let own_rate = facts.map_or(1.0 / timing.period, |f| f.rate_hz);
    let non_finite = decoded(samples).filter(|(_, st)| !validate::non_finite(*st).is_empty()).count();
    let mut worst = (0.0f32, "");
    if let Some(r) = reference {
        for (_, st) in decoded(samples) {
            for &i in &settled {
                let dev = (st.motor_state[i].q - r[i]).abs();
                if dev.is_nan() || dev > worst.0 {
                    worst = (if dev.is_nan() { f32::INFINITY } else { dev }, h1_2::JOINTS[i].name);
                }
            }
        }
    }
    // Every criterion must hold: the one closest to (or farthest past) its threshold is the margin. A non-finite
    // state is categorical: it joins only when it happened.
    let margin = super::decision::weakest(
        [
            Some(Margin::at_least("state_rate_hz", rate, MIN_RATE_FRACTION * own_rate)),
            Some(Margin::at_most("max_gap_ms", gap * 1e3, timing.gap_limit * 1e3)),
            Some(Margin::at_most("worst_settled_deviation_rad", f64::from(worst.0), f64::from(HOLD_TOLERANCE))),
            (non_finite > 0).then(|| Margin::at_most("non_finite_states", non_finite as f64, 0.0)),
        ]
        .into_iter()
        .flatten(),
    );
    let publishing = gap <= timing.gap_limit && rate >= MIN_RATE_FRACTION * own_rate;
    let held_still = worst.0 <= HOLD_TOLERANCE;
    let status =
        if samples.is_empty() || !publishing || non_finite > 0 || !held_still { Status::Fail } else { Status::Pass };
    Ok(CheckResult::new(
        id,
        status,
        format!(
            "{what}: LowState {rate:.0} Hz (its own rate {own_rate:.0} Hz; pass >= {:.0} %), max gap {:.1} ms (pass <= {:.0}), {non_finite} non-finite, worst settled joint moved {:.3} rad{} (pass <= {HOLD_TOLERANCE})",
            MIN_RATE_FRACTION * 100.0,
            gap * 1e3,
            timing.gap_limit * 1e3,
            worst.0,
            if worst.1.is_empty() { String::new() } else { format!(" ({})", worst.1) },
        ),
    )
    .with("state_rate_hz", round(rate, 1))
    .with("own_rate_hz", round(own_rate, 1))
    .with("max_gap_ms", round(gap * 1e3, 2))
    .with("non_finite_states", non_finite)
    .with("settled_joints", settled.len())
    .with("worst_deviation_rad", f64::from(worst.0))
    .with("sent_kinds", bad.len())
    .with("samples_per_tick", burst)
    .with("example_bytes_hex", bad.first().map(|b| hex(b, 48)))
    .with_margin(margin))
}
