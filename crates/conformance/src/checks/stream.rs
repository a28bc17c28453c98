//! State-stream checks. CRC is judged on every sample; rate, jitter and tick while nothing is sent; freshness,
//! finiteness, quaternion and joint ranges on clean traffic only (see the module above).

use super::{decoded, intervals, round};
use crate::commands::hex;
use crate::report::{CheckId, CheckResult, Margin, Status};
use crate::target::StateSample;
use lowlevel_codec::{crc, validate};
use unitree_idl::{h1_2, hg};

/// Slack (rad) beyond the joint range before a reported position counts as out of limits.
pub const LIMIT_TOLERANCE: f32 = 0.05;
/// Fraction of consecutive identical LowState samples above which state counts as stale: more than half means the
/// peer publishes over twice as many states as it computes, which is its design (a cached snapshot republished, a
/// publisher faster than its physics). A peer that builds each state from its physics repeats one only when two
/// publishes fall between two physics steps: two unsynchronised loops at the same rate repeat a few per cent, and
/// more as the physics falls behind real time on a loaded host (Unitree's Python bridge: 3 % alone, 10-23 % beside a
/// busy core), so a lower bound would judge the host's load, not the peer.
const MAX_REPEAT_FRACTION: f64 = 0.5;
/// `state_rate` passes at this fraction of the nominal rate.
const MIN_RATE_FRACTION: f64 = 0.9;
/// `state_jitter` passes when the 99th percentile arrival interval is at most this many mean intervals ...
const MAX_P99_PERIODS: f64 = 5.0;
/// ... or at most this long (s), whichever is longer: a 50 Hz policy loop (Unitree's RL deployments) still finds a
/// state newer than its step, and arrival times on a loaded host carry our own scheduler's delays of a few ms.
const MAX_P99_FLOOR_S: f64 = 0.02;
/// A unit quaternion sent as f32 and renormalised by no one stays within a few ulps of norm 1; 1e-3 is far above that
/// and far below a quaternion that is not one (a zero, an unnormalised or a mis-ordered one).
const QUATERNION_TOLERANCE: f64 = 1e-3;
/// `state_quaternion` fails when more than this fraction of the samples is off unit norm. A peer that fills the
/// quaternion wrongly does so in every sample it builds that way; a sample copied while another thread of the peer
/// writes the quaternion (a torn read) is off norm at random, once in thousands of samples, so whether one run
/// catches one is chance. Those are reported (`off_norm`, the worst error), and decide nothing.
const MAX_OFF_NORM_FRACTION: f64 = 0.01;
/// `tick` counts milliseconds: it must advance at 1000 per second of reception time, within this fraction.
const TICK_RATE_TOLERANCE: f64 = 0.1;

/// The LowState stream as measured while nothing was sent: every later duration and stream-continuity judgement
/// uses this rate, not the nominal one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamFacts {
    /// Samples received per second (any sample, CRC or not).
    pub rate_hz: f64,
    pub samples: usize,
    pub window_s: f64,
}

impl StreamFacts {
    /// Measures the rate of `samples` (at least 3, spanning a positive time).
    pub fn measure(samples: &[StateSample]) -> Option<StreamFacts> {
        let (first, last) = (samples.first()?.t, samples.last()?.t);
        let n = samples.len();
        (n >= 3 && last > first).then(|| StreamFacts {
            rate_hz: (n - 1) as f64 / (last - first),
            samples: n,
            window_s: last - first,
        })
    }

    pub fn period(&self) -> f64 {
        1.0 / self.rate_hz
    }
}

pub(super) fn crc(samples: &[StateSample]) -> CheckResult {
    let undecodable: Vec<&StateSample> = samples.iter().filter(|s| s.state.is_none()).collect();
    let bad: Vec<&StateSample> = samples.iter().filter(|s| s.state.is_some() && !s.crc_ok).collect();
    let zero = bad.iter().filter(|s| s.state.as_ref().is_some_and(|st| st.crc == 0)).count();
    let n = samples.len();
    let status = if n == 0 {
        Status::Inconclusive
    } else if bad.is_empty() && undecodable.is_empty() {
        Status::Pass
    } else {
        Status::Fail
    };
    let mut r = CheckResult::new(
        CheckId::StateCrc,
        status,
        format!(
            "{} of {n} LowState samples decode with a valid CRC ({} bad CRC, {zero} of them 0, i.e. never computed; {} undecodable)",
            n - bad.len() - undecodable.len(),
            bad.len(),
            undecodable.len()
        ),
    )
    .with("samples", n)
    .with("bad_crc", bad.len())
    .with("crc_zero", zero)
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

pub(super) fn rate(facts: Option<&StreamFacts>, nominal: f64) -> CheckResult {
    let Some(f) = facts else {
        return CheckResult::new(
            CheckId::StateRate,
            Status::Inconclusive,
            "fewer than 3 LowState samples while observing",
        );
    };
    let ok = f.rate_hz >= MIN_RATE_FRACTION * nominal;
    CheckResult::new(
        CheckId::StateRate,
        if ok { Status::Pass } else { Status::Fail },
        format!(
            "{:.1} Hz measured against {nominal} Hz nominal (pass: >= {:.0} %); the rest of the run uses the measured rate",
            f.rate_hz,
            MIN_RATE_FRACTION * 100.0
        ),
    )
    .with("rate_hz", round(f.rate_hz, 2))
    .with("nominal_hz", nominal)
    .with_margin(Some(Margin::at_least("rate_hz", f.rate_hz, MIN_RATE_FRACTION * nominal)))
    .with("samples", f.samples)
    .with("window_s", round(f.window_s, 3))
}

pub(super) fn jitter(samples: &[StateSample], facts: Option<&StreamFacts>) -> CheckResult {
    let times: Vec<f64> = samples.iter().map(|s| s.t).collect();
    let (Some((mean, std, p99, max)), Some(f)) = (intervals(&times), facts) else {
        return CheckResult::new(CheckId::StateJitter, Status::Inconclusive, "too few LowState samples");
    };
    // Judged against the peer's own period: a slower stream is state_rate's business, not jitter.
    let limit = (MAX_P99_PERIODS * f.period()).max(MAX_P99_FLOOR_S);
    let ok = p99 <= limit;
    CheckResult::new(
        CheckId::StateJitter,
        if ok { Status::Pass } else { Status::Fail },
        format!(
            "arrival interval mean {:.3} ms, std {:.3} ms, p99 {:.3} ms, max {:.3} ms (pass: p99 <= {:.1} ms, the longer of {MAX_P99_PERIODS} measured periods and {:.0} ms)",
            mean * 1e3,
            std * 1e3,
            p99 * 1e3,
            max * 1e3,
            limit * 1e3,
            MAX_P99_FLOOR_S * 1e3
        ),
    )
    .with("p99_limit_ms", round(limit * 1e3, 4))
    .with("interval_mean_ms", round(mean * 1e3, 4))
    .with("interval_std_ms", round(std * 1e3, 4))
    .with("interval_p99_ms", round(p99 * 1e3, 4))
    .with("interval_max_ms", round(max * 1e3, 4))
    .with("intervals", times.len() - 1)
    .with_margin(Some(Margin::at_most("interval_p99_ms", p99 * 1e3, limit * 1e3)))
}

pub(super) fn tick(samples: &[StateSample]) -> CheckResult {
    let ticks: Vec<(f64, u32)> = decoded(samples).map(|(t, s)| (t, s.tick)).collect();
    if ticks.len() < 3 {
        return CheckResult::new(CheckId::StateTick, Status::Inconclusive, "too few decoded LowState samples");
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
    let consistent = (tick_rate / 1000.0 - 1.0).abs() <= TICK_RATE_TOLERANCE;
    let status = if not_increasing.is_empty() && consistent { Status::Pass } else { Status::Fail };
    CheckResult::new(
        CheckId::StateTick,
        status,
        format!(
            "{} non-increasing steps in {} samples; tick advances {tick_rate:.1} per s (pass: strictly increasing, 1000 ± {:.0} % per s: milliseconds), {per_sample:.2} per sample",
            not_increasing.len(),
            ticks.len(),
            TICK_RATE_TOLERANCE * 100.0
        ),
    )
    .with("non_increasing", not_increasing.len())
    .with("first_non_increasing", not_increasing.first().map(|(a, b)| format!("{a} -> {b}")))
    .with("first_tick", ticks[0].1)
    .with("tick_per_s", round(tick_rate, 2))
    .with("tick_per_sample", round(per_sample, 3))
    .with_margin(super::decision::weakest(
        [
            Some(Margin::at_most("tick_rate_error", (tick_rate / 1000.0 - 1.0).abs(), TICK_RATE_TOLERANCE)),
            (!not_increasing.is_empty()).then(|| Margin::at_most("non_increasing_steps", not_increasing.len() as f64, 0.0)),
        ]
        .into_iter()
        .flatten(),
    ))
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

pub(super) fn fresh(samples: &[StateSample]) -> CheckResult {
    let states: Vec<(u32, Vec<u32>)> = decoded(samples).map(|(_, s)| (s.tick, physics_key(s))).collect();
    if states.len() < 30 {
        return CheckResult::new(
            CheckId::StateFresh,
            Status::Inconclusive,
            "fewer than 30 LowState samples while the robot was driven",
        );
    }
    let pairs = states.len() - 1;
    let repeats: Vec<(u32, u32)> = states.windows(2).filter(|w| w[0].1 == w[1].1).map(|w| (w[0].0, w[1].0)).collect();
    let fraction = repeats.len() as f64 / pairs as f64;
    let ok = fraction <= MAX_REPEAT_FRACTION;
    CheckResult::new(
        CheckId::StateFresh,
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
    .with_margin(Some(Margin::at_most("identical_pair_fraction", fraction, MAX_REPEAT_FRACTION)))
}

pub(super) fn finite(samples: &[StateSample]) -> CheckResult {
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
        CheckId::StateFinite,
        status,
        format!("{bad} of {n} LowState samples under clean traffic carry a non-finite value"),
    )
    .with("samples", n)
    .with("non_finite_samples", bad)
    .with("first_findings", first)
}

pub(super) fn quaternion(samples: &[StateSample]) -> CheckResult {
    let norms: Vec<f32> =
        decoded(samples).map(|(_, s)| s.imu_state.quaternion.iter().map(|x| x * x).sum::<f32>().sqrt()).collect();
    if norms.is_empty() {
        return CheckResult::new(CheckId::StateQuaternion, Status::Inconclusive, "no decoded LowState");
    }
    let worst = norms.iter().map(|n| (n - 1.0).abs()).fold(0.0f32, |a, b| if b.is_nan() || b > a { b } else { a });
    let bad = norms
        .iter()
        .filter(|n| {
            let e = (*n - 1.0).abs();
            e.is_nan() || e > QUATERNION_TOLERANCE as f32
        })
        .count();
    let fraction = bad as f64 / norms.len() as f64;
    CheckResult::new(
        CheckId::StateQuaternion,
        if fraction <= MAX_OFF_NORM_FRACTION { Status::Pass } else { Status::Fail },
        format!(
            "{bad} of {} IMU quaternions off unit norm by more than {QUATERNION_TOLERANCE:e} (worst |norm-1| = \
             {worst:.2e}; pass: at most {:.0} % of the samples, as a sample torn between the peer's threads is)",
            norms.len(),
            MAX_OFF_NORM_FRACTION * 100.0
        ),
    )
    .with("samples", norms.len())
    .with("off_norm", bad)
    .with("worst_norm_error", f64::from(worst))
    .with_margin(Some(Margin::at_most("off_norm_fraction", fraction, MAX_OFF_NORM_FRACTION)))
}

pub(super) fn joint_limits(samples: &[StateSample]) -> CheckResult {
    let mut n = 0usize;
    let mut violations = 0usize;
    let mut worst: Option<(String, f32, f32, f32)> = None;
    let mut worst_excess = 0.0f32;
    // Largest excess beyond a range over every joint and sample (negative: every joint inside its range).
    let mut largest_excess = f32::NEG_INFINITY;
    for (_, s) in decoded(samples) {
        n += 1;
        let mut any = false;
        for j in &h1_2::JOINTS {
            let q = s.motor_state[j.slot].q;
            let excess = (j.lower - q).max(q - j.upper);
            largest_excess = if excess.is_nan() { f32::INFINITY } else { largest_excess.max(excess) };
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
        CheckId::StateJointLimits,
        status,
        format!("{violations} of {n} samples (the robot held and stepped by valid commands) report a joint beyond its range by more than {LIMIT_TOLERANCE} rad"),
    )
    .with("samples", n)
    .with("violating_samples", violations)
    .with("worst", worst.map(|(name, q, lo, hi)| format!("{name} q={q} range [{lo}, {hi}]")))
    .with_margin(
        (n > 0).then(|| Margin::at_most("largest_excess_rad", f64::from(largest_excess), f64::from(LIMIT_TOLERANCE))),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t: f64, tick: u32, crc_ok: bool) -> StateSample {
        let mut s = hg::LowState_ { tick, ..Default::default() };
        s.imu_state.quaternion[0] = 1.0;
        if crc_ok {
            crc::seal(&mut s);
        }
        StateSample { t, len: 2092, state: Some(s), decode_error: None, crc_ok, raw: None }
    }

    #[test]
    fn rate_counts_samples_without_crc_and_jitter_uses_the_measured_period() {
        // 200 Hz, no CRC: rate fails against 500 Hz nominal, jitter passes against its own period.
        let samples: Vec<StateSample> = (0..200).map(|i| sample(f64::from(i) * 0.005, i * 5, false)).collect();
        let facts = StreamFacts::measure(&samples);
        assert!(facts.is_some_and(|f| (f.rate_hz - 200.0).abs() < 1e-6));
        assert_eq!(rate(facts.as_ref(), 500.0).status, Status::Fail);
        assert_eq!(jitter(&samples, facts.as_ref()).status, Status::Pass);
        assert_eq!(tick(&samples).status, Status::Pass);
        assert_eq!(crc(&samples).status, Status::Fail);
        assert_eq!(crc(&samples).evidence["crc_zero"], 200);
    }

    #[test]
    fn bursty_stream_fails_jitter() {
        // 500 Hz on average, but every 20th interval is a 40 ms pause (bursts in between): p99 40 ms > 20 ms.
        let mut t = 0.0;
        let samples: Vec<StateSample> = (0..400u32)
            .map(|i| {
                if i % 20 == 19 {
                    t += 0.04;
                }
                sample(t, i * 2, true)
            })
            .collect();
        let facts = StreamFacts::measure(&samples);
        assert_eq!(jitter(&samples, facts.as_ref()).status, Status::Fail);
    }

    /// A LowState at step `k` of a motion: every physics field moves with `k`.
    fn moving(t: f64, k: u32) -> StateSample {
        let mut s = sample(t, (t * 1000.0) as u32, true);
        if let Some(st) = s.state.as_mut() {
            let a = f64::from(k) * 1e-3;
            st.imu_state.quaternion = [a.cos() as f32, a.sin() as f32, 0.0, 0.0];
            st.motor_state[0].q = a as f32;
            st.motor_state[0].dq = 1.0 + a as f32;
            crc::seal(st);
        }
        s
    }

    /// A peer that builds every state from its physics but publishes on a loop of its own repeats a state whenever
    /// its physics falls behind: beside a busy core, Unitree's Python bridge repeated 10-23 % of its samples from one
    /// run to the next, around the 10 % bound of the time, and `state_fresh` passed once and failed nine times on the
    /// same peer. Such a peer passes however far behind its physics falls, short of computing fewer than half the
    /// states it publishes; a peer that republishes a snapshot fails.
    #[test]
    fn a_physics_behind_its_publisher_is_fresh_and_a_republished_snapshot_is_stale() {
        for repeat_every in [30u32, 4] {
            // One publish in `repeat_every` finds no new physics step (3 % and 25 %).
            let mut k = 0;
            let samples: Vec<StateSample> = (0..400u32)
                .map(|i| {
                    if i % repeat_every != 0 {
                        k += 1;
                    }
                    moving(f64::from(i) * 0.005, k)
                })
                .collect();
            assert_eq!(fresh(&samples).status, Status::Pass, "one in {repeat_every} repeated");
        }
        // A snapshot refreshed every tenth publish (our bridge's stale-state defect).
        let samples: Vec<StateSample> = (0..400u32).map(|i| moving(f64::from(i) * 0.005, i / 10)).collect();
        assert_eq!(fresh(&samples).status, Status::Fail);
    }

    /// A torn read (one sample whose quaternion mixes two physics steps) turned up in one of ten runs of a peer
    /// beside a busy core, and failed `state_quaternion` in that run only. Sporadic off-norm samples are reported
    /// and pass; a quaternion off norm in many samples fails.
    #[test]
    fn a_torn_quaternion_is_reported_and_a_wrong_one_fails() {
        let mut samples: Vec<StateSample> = (0..700u32).map(|i| moving(f64::from(i) * 0.005, i)).collect();
        let tear = |s: &mut StateSample| {
            if let Some(st) = s.state.as_mut() {
                st.imu_state.quaternion[1] += 0.0035;
            }
        };
        tear(&mut samples[300]);
        let r = quaternion(&samples);
        assert_eq!((r.status, r.evidence["off_norm"].clone()), (Status::Pass, serde_json::json!(1)), "{}", r.summary);
        // An unnormalised quaternion in every tenth sample is no tear.
        samples.iter_mut().step_by(10).for_each(tear);
        assert_eq!(quaternion(&samples).status, Status::Fail);
    }

    #[test]
    fn tick_stuck_at_zero_fails_tick_only() {
        let samples: Vec<StateSample> = (0..100).map(|i| sample(f64::from(i) * 0.002, 0, true)).collect();
        assert_eq!(tick(&samples).status, Status::Fail);
        assert_eq!(crc(&samples).status, Status::Pass);
        let facts = StreamFacts::measure(&samples);
        assert_eq!(rate(facts.as_ref(), 500.0).status, Status::Pass);
    }
}
