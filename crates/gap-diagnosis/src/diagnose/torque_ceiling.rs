//! What the log's own torque says about a torque ceiling: measurements, no verdict. A saturation is a ceiling on
//! the torque the motor delivers, and `tau_est` reports the delivered torque, so
//! - a fitted ceiling that the logged torque exceeds, often and by more than noise, is not a ceiling: the judge
//!   treats such a fit as no estimate ([`joints_above_ceiling`]);
//! - the log can show a ceiling directly: the delivered torque held at one level below the nominal limit while the
//!   PD law of the log's own command and state asks for more, and following the PD law below that level
//!   ([`ceilings_in_log`], reported as evidence). A gain drop delivers a fixed fraction of every demand and the
//!   nominal clamp sits at the limit, so neither looks so; a command latency can (the demand read off the newest
//!   command leads the torque delivered), so the command delay is read off the log as the torque's lag is.
use super::replay::Ctx;
use super::stats::median;
use crate::effects::EffectKind;
use crate::log::{Command, Measurement, RobotLog};
use crate::plant::Effects;
use serde::{Deserialize, Serialize};

/// A logged torque counts against a fitted ceiling only beyond this multiple of it: the torque estimate's noise and
/// a fitted value a little low.
pub const CEILING_MARGIN: f64 = 1.1;
/// A fitted ceiling is contradicted when some joint's logged torque exceeds [`CEILING_MARGIN`] times it in more than
/// this fraction of the log's samples: a true ceiling is never exceeded, but a short spike of the torque estimate is
/// no evidence against it.
pub const MAX_FRACTION_ABOVE: f64 = 0.01;

/// The joints whose torque `fx` limits and whose logged |tau_est| exceeds [`CEILING_MARGIN`] times their fitted
/// ceiling (the speed-independent one: the fitted scale times the torque limit) in more than [`MAX_FRACTION_ABOVE`]
/// of the log's samples.
pub(super) fn joints_above_ceiling(ctx: &Ctx<'_>, fx: &Effects) -> Vec<usize> {
    let kind = EffectKind::TorqueSaturation;
    let v0 = kind.range().2;
    let n = ctx.log.states.len().max(1) as f64;
    (0..ctx.nj())
        .filter(|&j| kind.get(fx, j) < v0)
        .filter(|&j| {
            let Some(m) = ctx.model.joints.get(j) else { return false };
            let ceiling = CEILING_MARGIN * kind.get(fx, j) * m.torque_limit;
            let above = ctx.log.states.iter().filter(|s| s.tau.get(j).is_some_and(|t| t.abs() > ceiling)).count();
            above as f64 / n > MAX_FRACTION_ABOVE
        })
        .collect()
}

/// The logged torque counts as held at a plateau when within this fraction of it (sensor noise, the torque-speed
/// line's first few percent).
pub const PLATEAU_BAND: f64 = 0.10;
/// ... while the PD law the log's own command and state imply asks for at least this multiple of the plateau.
pub const DEMAND_OVER: f64 = 1.15;
/// A plateau needs at least this many such samples (20 ms at the robot's 500 Hz), and is taken as the
/// `MIN_PINNED`-th largest logged |torque| so that a noise spike does not set it.
pub const MIN_PINNED: usize = 10;
/// A plateau at this fraction of the nominal torque limit or above is the nominal clamp, which the diagnosing
/// plant models already.
pub const MAX_SCALE_IN_LOG: f64 = 0.9;
/// Below the plateau the drive must follow the PD law: the median of logged over demanded torque, over the samples
/// whose demand is between half the plateau and [`FOLLOW_BELOW`] of it, within this distance of 1. A gain drop
/// (the drive delivers a fixed fraction of every demand) fails it, and so does a command latency the delay search
/// ([`MAX_COMMAND_DELAY`]) missed (the demand read off a newer command is not the one applied).
pub const FOLLOW_TOL: f64 = 0.1;
/// The upper end of the demands over which the drive's following is checked, as a fraction of the plateau.
pub const FOLLOW_BELOW: f64 = 0.9;
/// The following is judged on no fewer samples than this.
pub const MIN_FOLLOW: usize = 20;

/// A torque ceiling the log shows on one joint: its logged torque (`tau_est`, what the drive delivered) held at a
/// plateau below the nominal limit while the PD law of the log's own command and state asked for more.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LogCeiling {
    /// The joint (motor name).
    pub joint: String,
    /// The plateau as a fraction of the joint's nominal torque limit.
    pub scale: f64,
    /// Samples held at the plateau while the PD law asked for more than [`DEMAND_OVER`] times it.
    pub pinned: usize,
    /// Median of logged over demanded torque below the plateau (≈ 1: the drive follows the PD law there).
    pub follow: f64,
    /// State samples by which the logged torque trails the demand it was paired with ([`MAX_TORQUE_LAG`]).
    #[serde(default)]
    pub lag_samples: usize,
    /// State samples by which the command the demand was computed from precedes the state ([`MAX_COMMAND_DELAY`]).
    #[serde(default)]
    pub command_delay_samples: usize,
}

/// The ceilings the log shows ([`LogCeiling`]), one per joint at most, in joint order. `joints` gives each
/// joint's name and nominal torque limit, in the log's joint order. Reads the log only: no simulation, no fit.
pub fn ceilings_in_log(log: &RobotLog, joints: &[(&str, f64)]) -> Vec<LogCeiling> {
    // The command in force at each state (None before the first).
    let cmds: Vec<Option<&Command>> =
        log.states.iter().map(|s| log.command_at(s.t).and_then(|i| log.commands.get(i))).collect();
    let mut out = Vec::new();
    for (j, &(name, limit)) in joints.iter().enumerate() {
        let taus: Vec<f64> = log.states.iter().map(|s| s.tau.get(j).copied().unwrap_or(f64::NAN)).collect();
        // Per command delay, the PD demand at each state of the command in force that many states earlier.
        let demands_at = |delay: usize| -> Vec<f64> {
            (0..log.states.len())
                .map(|i| {
                    let c = i.checked_sub(delay).and_then(|k| cmds.get(k).copied().flatten());
                    c.and_then(|c| pd_demand(&log.states[i], c, j)).unwrap_or(f64::NAN)
                })
                .collect()
        };
        let (delay, lag) = demand_alignment(&taus, demands_at);
        let demands = demands_at(delay);
        if let Some(c) = plateau(&aligned(&demands, &taus, lag), limit) {
            out.push(LogCeiling { joint: name.to_string(), lag_samples: lag, command_delay_samples: delay, ..c });
        }
    }
    out
}

/// The torque the PD law of command `c` asks of joint `j` at state `s`.
fn pd_demand(s: &Measurement, c: &Command, j: usize) -> Option<f64> {
    Some(c.tau.get(j)? + c.kp.get(j)? * (c.q.get(j)? - s.q.get(j)?) + c.kd.get(j)? * (c.dq.get(j)? - s.dq.get(j)?))
}

/// The delivered torque may trail the state the PD law read by a sample or more: a drive computes its torque from
/// the position it measured at one tick and reports it with the next state. Paired with the demand of the same state,
/// a short saturation then loses the first sample of every episode.
pub const MAX_TORQUE_LAG: usize = 3;

/// A command may reach the drive some state samples after the log records it (a command latency). The demand read
/// off the newest command then leads the delivered torque, and where the command steps, the torque seems to stop
/// short of it, as if held. So the demand is taken of the command in force up to this many states earlier (40 ms at
/// 500 Hz), the delay read off the log as the lag is.
pub const MAX_COMMAND_DELAY: usize = 20;

/// The lag, in state samples up to [`MAX_TORQUE_LAG`], by which the logged torque best follows the PD demand: the one
/// with the smallest median |logged - demanded|, ties to the shorter lag, with that median (infinite when no lag has
/// [`MIN_FOLLOW`] samples). Read off the log, so a drive that reports the torque of the same state (lag 0) is paired
/// as before.
fn torque_lag(demands: &[f64], taus: &[f64]) -> (usize, f64) {
    let mut best = (0, f64::INFINITY);
    for lag in 0..=MAX_TORQUE_LAG {
        let gaps: Vec<f64> = aligned(demands, taus, lag).iter().map(|(d, t)| (t - d).abs()).collect();
        if gaps.len() < MIN_FOLLOW {
            continue;
        }
        let m = median(&gaps);
        if m < best.1 {
            best = (lag, m);
        }
    }
    best
}

/// The command delay (up to [`MAX_COMMAND_DELAY`] states) and torque lag by which the logged torque `taus` best
/// follows the PD demand (`demands_at(delay)`, per state): the smallest median |logged - demanded|, ties to the
/// shorter delay. A log without latency is paired as before (delay 0).
fn demand_alignment(taus: &[f64], demands_at: impl Fn(usize) -> Vec<f64>) -> (usize, usize) {
    let mut best = (0, 0, f64::INFINITY);
    for delay in 0..=MAX_COMMAND_DELAY {
        let (lag, gap) = torque_lag(&demands_at(delay), taus);
        if gap < best.2 {
            best = (delay, lag, gap);
        }
    }
    (best.0, best.1)
}

/// Each demand with the logged torque `lag` samples after it, both finite.
fn aligned(demands: &[f64], taus: &[f64], lag: usize) -> Vec<(f64, f64)> {
    demands
        .iter()
        .zip(taus.iter().skip(lag))
        .map(|(&d, &t)| (d, t))
        .filter(|(d, t)| d.is_finite() && t.is_finite())
        .collect()
}

/// The plateau of one joint's (demand, logged torque) samples, if the log shows one below [`MAX_SCALE_IN_LOG`]
/// of `limit` (the name left empty).
fn plateau(samples: &[(f64, f64)], limit: f64) -> Option<LogCeiling> {
    if !(limit > 0.0) || samples.len() < MIN_PINNED {
        return None;
    }
    let mut mags: Vec<f64> = samples.iter().map(|(_, t)| t.abs()).collect();
    mags.sort_by(f64::total_cmp);
    let c = mags[mags.len() - MIN_PINNED];
    if !(c > 0.0) || c > MAX_SCALE_IN_LOG * limit {
        return None;
    }
    let pinned = samples
        .iter()
        .filter(|(d, t)| t.abs() >= (1.0 - PLATEAU_BAND) * c && d.abs() >= DEMAND_OVER * c && d.signum() == t.signum())
        .count();
    if pinned < MIN_PINNED {
        return None;
    }
    let mut ratios: Vec<f64> =
        samples.iter().filter(|(d, _)| d.abs() >= 0.5 * c && d.abs() <= FOLLOW_BELOW * c).map(|(d, t)| t / d).collect();
    if ratios.len() < MIN_FOLLOW {
        return None;
    }
    ratios.sort_by(f64::total_cmp);
    let follow = ratios[ratios.len() / 2];
    if (follow - 1.0).abs() > FOLLOW_TOL {
        return None;
    }
    Some(LogCeiling {
        joint: String::new(),
        scale: c / limit,
        pinned,
        follow,
        lag_samples: 0,
        command_delay_samples: 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (demand, logged torque) of a joint driven by a slow sine of demand `amp`, delivered through `drive`.
    fn samples(amp: f64, drive: impl Fn(f64) -> f64) -> Vec<(f64, f64)> {
        (0..5000)
            .map(|i| {
                let d = amp * (i as f64 * 0.004).sin();
                (d, drive(d))
            })
            .collect()
    }

    #[test]
    fn a_ceiling_below_the_limit_is_seen_at_its_level() {
        // A 300 N·m knee driven to 215 N·m of demand, delivered up to 147 N·m (0.49 of the limit).
        let c = plateau(&samples(215.0, |d| d.clamp(-147.0, 147.0)), 300.0).expect("a ceiling");
        assert!((c.scale - 0.49).abs() < 0.005, "{c:?}");
        assert!(c.pinned >= MIN_PINNED && (c.follow - 1.0).abs() < 1e-9, "{c:?}");
    }

    #[test]
    fn a_short_saturation_reported_a_sample_late_is_seen_once_the_lag_is_read_off_the_samples() {
        // An ankle pitch (60 N·m) following a slow demand up to 20 N·m, kicked three times to a demand that decays
        // from 35 to 30 N·m, delivered up to 25.4 N·m and reported with the next sample: each kick holds the
        // plateau for 4 samples, of which 3 line up with the demand of the same sample (9 < MIN_PINNED).
        let mut demands: Vec<f64> = (0..5000).map(|i| 20.0 * (i as f64 * 0.004).sin()).collect();
        for start in [700, 2300, 3900] {
            demands[start..start + 4].copy_from_slice(&[35.0, 33.0, 31.0, 30.0]);
        }
        let mut taus = vec![0.0];
        taus.extend(demands.iter().map(|d| d.clamp(-25.4, 25.4)));
        taus.pop();
        assert!(plateau(&aligned(&demands, &taus, 0), 60.0).is_none(), "9 pinned samples must not pass");
        let (lag, _) = torque_lag(&demands, &taus);
        assert_eq!(lag, 1);
        let c = plateau(&aligned(&demands, &taus, lag), 60.0).expect("a ceiling once aligned");
        assert_eq!(c.pinned, 12, "{c:?}");
        assert!((c.scale - 25.4 / 60.0).abs() < 1e-9, "{c:?}");
        // A drive that reports the torque of the same sample is paired as before.
        let now: Vec<f64> = demands.iter().map(|d| d.clamp(-25.4, 25.4)).collect();
        assert_eq!(torque_lag(&demands, &now).0, 0);
    }

    /// A joint tracking a triangle-wave command: the drive applies each command 12 states after the log records it
    /// (a 24 ms latency at 500 Hz) and reports its torque with the next state. The delay and the lag are read off the
    /// samples; a drive without latency is paired at delay 0.
    #[test]
    fn a_command_latency_is_read_off_the_samples_with_the_torque_lag() {
        let n: usize = 3000;
        let cmd: Vec<f64> = (0..n).map(|i| 0.3 * (((i % 400) as f64 / 200.0) - 1.0).abs()).collect();
        let q: Vec<f64> = (0..n).map(|i| cmd[i.saturating_sub(15)]).collect();
        let demand = |delay: usize| -> Vec<f64> {
            (0..n).map(|i| i.checked_sub(delay).map_or(f64::NAN, |k| 100.0 * (cmd[k] - q[i]))).collect()
        };
        let one_late = |d: Vec<f64>| -> Vec<f64> {
            std::iter::once(0.0).chain(d.iter().take(n - 1).map(|d| if d.is_finite() { *d } else { 0.0 })).collect()
        };
        assert_eq!(demand_alignment(&one_late(demand(12)), demand), (12, 1));
        assert_eq!(demand_alignment(&one_late(demand(0)), demand), (0, 1));
    }

    #[test]
    fn the_nominal_clamp_a_gain_drop_and_a_joint_that_never_saturates_show_none() {
        // The nominal clamp: a plateau at the limit itself.
        assert!(plateau(&samples(300.0, |d| d.clamp(-200.0, 200.0)), 200.0).is_none());
        // A gain drop: every demand delivered at 0.8, no plateau.
        assert!(plateau(&samples(150.0, |d| 0.8 * d), 300.0).is_none());
        // A gain drop and a ceiling: the drive does not follow the PD law below the plateau.
        assert!(plateau(&samples(215.0, |d| (0.8 * d).clamp(-120.0, 120.0)), 300.0).is_none());
        // Nothing: delivered as demanded.
        assert!(plateau(&samples(150.0, |d| d), 300.0).is_none());
        // Too few samples, and a limit that is not one.
        assert!(plateau(&samples(215.0, |d| d.clamp(-147.0, 147.0))[..5], 300.0).is_none());
        assert!(plateau(&samples(215.0, |d| d.clamp(-147.0, 147.0)), f64::NAN).is_none());
    }
}
