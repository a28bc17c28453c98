//! Which stretches of the log are replayed: windows only where the robot was under command and its states kept
//! their rate, spread evenly over the log, moved to settled samples on the floating base (dropped where the robot
//! is down), and split into alternating training and held-out blocks. Everything later sees only these windows.
use super::options::{DiagnoseOptions, PlantKind};
use crate::floating::{self, Feet};
use crate::log::RobotLog;
use crate::plant::{Effects, DT};
use crate::GapError;
use robot_model::RobotModel;

/// A window is used only while the latest command is at most this old (s): the robot's command timeout (Unitree's
/// motors and `ulab sim` fall back to damping after about 0.1 s without a command).
pub const COMMAND_STALE_S: f64 = 0.1;

/// Largest spread (s) of a window's state log times around a regular grid at the median rate.
pub const TIMING_TOL_S: f64 = 0.005;

/// A joint within this distance of its range (rad) is at its limit: where simulators' joint-limit models (soft,
/// hard, stiffness) differ most, so a residual found only there says little about the robot.
pub const AT_LIMIT_RAD: f64 = 0.02;

/// Which joints come within [`AT_LIMIT_RAD`] of their range in these logged states.
/// The logged states of the window starting at `start`: its `len` steps and the state they end on (fewer at the
/// end of the log).
pub(super) fn window_states(log: &RobotLog, start: usize, len: usize) -> &[crate::log::Measurement] {
    let end = (start + len + 1).min(log.states.len());
    log.states.get(start..end).unwrap_or(&[])
}

pub(super) fn joints_at_limit(model: &RobotModel, states: &[crate::log::Measurement]) -> Vec<bool> {
    model
        .joints
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            joint.lower < joint.upper
                && states
                    .iter()
                    .filter_map(|m| m.q.get(j))
                    .any(|&q| q - joint.lower < AT_LIMIT_RAD || joint.upper - q < AT_LIMIT_RAD)
        })
        .collect()
}

/// Every this many samples of a floating-base window are checked for a robot that is down.
const DOWN_CHECK_STRIDE: usize = 5;

/// The windows of a diagnosis.
pub(super) struct Windows {
    /// State sample period of the log (median).
    pub dt_state: f64,
    /// Window length in state samples.
    pub len: usize,
    /// First state sample of each window.
    pub starts: Vec<usize>,
    /// Indices into `starts` of the training and held-out windows.
    pub train: Vec<usize>,
    pub test: Vec<usize>,
    /// The feet (floating plant only).
    pub feet: Option<Feet>,
    pub tally: Tally,
}

/// How many window starts were not used, and why (reported as is).
#[derive(Debug, Clone, Copy)]
pub(super) struct Tally {
    /// Fraction of possible starts without a fresh command or with irregular state timing.
    pub skipped_fraction: f64,
    /// Floating base: nominal starts with no settled sample within one window length.
    pub unsettled: usize,
    /// Floating base: nominal starts where the robot was down.
    pub down: usize,
}

/// Starts that may begin a window, before the floating base moves or drops any.
struct Eligible {
    starts: Vec<usize>,
    /// `fresh_run[i]`: states from `i` on with a fresh command.
    fresh_run: Vec<usize>,
    skipped_fraction: f64,
}

/// Floating-base starts after settling.
struct Settled {
    starts: Vec<usize>,
    unsettled: usize,
    down: usize,
}

/// Training and held-out windows (indices into the starts).
struct Split {
    train: Vec<usize>,
    test: Vec<usize>,
}

/// Chooses, settles and splits the windows of `log` for `plant`.
pub(super) fn cut(
    model: &RobotModel,
    log: &RobotLog,
    opts: &DiagnoseOptions,
    plant: PlantKind,
) -> Result<Windows, GapError> {
    let dt_state = state_period(log);
    let len = ((opts.window_s / dt_state).round() as usize).max(2);
    let eligible = eligible_starts(log, dt_state, len);
    if eligible.starts.len() < 4 {
        return Err(GapError::Log(format!(
            "the log is too short for {} s windows after the first command",
            opts.window_s
        )));
    }
    let n = eligible.starts.len();
    let count = opts.max_windows.unwrap_or(plant.default_max_windows()).min(n / len.max(1)).max(4);
    let starts: Vec<usize> = (0..count).map(|k| eligible.starts[k * n / count]).collect();
    // This happens before the train/held-out split, so both sides see only settled windows.
    let feet = if plant == PlantKind::Floating { Some(Feet::of(model)?) } else { None };
    let settled = match &feet {
        None => Settled { starts, unsettled: 0, down: 0 },
        Some(feet) => settle(model, log, feet, &eligible.fresh_run, starts, len)?,
    };
    let split = split(log, &settled.starts, opts.block_s)?;
    Ok(Windows {
        dt_state,
        len,
        starts: settled.starts,
        train: split.train,
        test: split.test,
        feet,
        tally: Tally { skipped_fraction: eligible.skipped_fraction, unsettled: settled.unsettled, down: settled.down },
    })
}

/// State sample period from the log (median), at least the plant's step.
fn state_period(log: &RobotLog) -> f64 {
    let mut dts: Vec<f64> = log.states.windows(2).map(|w| w[1].t - w[0].t).filter(|d| *d > 0.0).collect();
    dts.sort_by(f64::total_cmp);
    dts.get(dts.len() / 2).copied().unwrap_or(DT).max(DT)
}

/// Window starts at least 50 ms after the first command where the robot was under command and its states kept
/// their rate.
fn eligible_starts(log: &RobotLog, dt_state: f64, len: usize) -> Eligible {
    let t0 = log.commands.first().map_or(0.0, |c| c.t);
    // Windows only where the robot was under command: every state of the window (and its start) has a command at
    // most COMMAND_STALE_S old (a robot whose commands stopped falls back to damping, which the plant does not model).
    let age: Vec<f64> =
        log.states.iter().map(|s| log.command_at(s.t).map_or(f64::INFINITY, |c| s.t - log.commands[c].t)).collect();
    // ... and where the states kept their rate: the robot publishes at a fixed rate, so a window whose state log
    // times stray from a regular grid by more than TIMING_TOL_S (range of `t_k - k * dt` over the window) saw the
    // robot's (or simulator's) loop or the transport stall; the log times there are not the measurement times (a
    // simulator that falls behind real time publishes a burst of states to catch up).
    let lag: Vec<f64> = log.states.iter().enumerate().map(|(k, s)| s.t - k as f64 * dt_state).collect();
    let mut fresh_run = vec![0usize; log.states.len() + 1];
    for i in (0..log.states.len()).rev() {
        fresh_run[i] = if age[i] <= COMMAND_STALE_S { fresh_run[i + 1] + 1 } else { 0 };
    }
    let regular = |i: usize| {
        let w = &lag[i..=(i + len).min(lag.len() - 1)];
        let (lo, hi) = w.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
        hi - lo <= TIMING_TOL_S
    };
    let candidates: Vec<usize> =
        (0..log.states.len().saturating_sub(len + 1)).filter(|&i| log.states[i].t >= t0 + 0.05).collect();
    let starts: Vec<usize> = candidates.iter().copied().filter(|&i| fresh_run[i] > len && regular(i)).collect();
    let skipped_fraction = 1.0 - starts.len() as f64 / candidates.len().max(1) as f64;
    Eligible { starts, fresh_run, skipped_fraction }
}

/// Floating base: each start moves to the first settled sample within one window length (no foot in a touchdown
/// transient, where the kinematic base estimate is 10-15 times worse); starts with none, or where the robot is
/// down, are dropped.
fn settle(
    model: &RobotModel,
    log: &RobotLog,
    feet: &Feet,
    fresh_run: &[usize],
    starts: Vec<usize>,
    len: usize,
) -> Result<Settled, GapError> {
    let mut windows_unsettled = 0;
    let mut windows_down = 0;
    let null = Effects::none(model.nj());
    let usable = |i: usize| i + len + 1 < log.states.len() && fresh_run[i] > len;
    // Whether the robot is down (fell) anywhere in the span a window from nominal start `s` can cover (it may
    // begin up to one window length later): the plant models a robot on its feet.
    let down_within = |s: usize| -> Result<bool, GapError> {
        for i in (s..(s + 2 * len + 1).min(log.states.len())).step_by(DOWN_CHECK_STRIDE) {
            if floating::logged_down(model, feet, &log.states[i], &null)? {
                return Ok(true);
            }
        }
        Ok(false)
    };
    let mut settled: Vec<usize> = Vec::with_capacity(starts.len());
    for s in starts {
        if down_within(s)? {
            windows_down += 1;
            continue;
        }
        match floating::settled_start(model, feet, log, &null, s, s + len)? {
            Some(i) if usable(i) && settled.last().is_none_or(|&p| i > p) => settled.push(i),
            _ => windows_unsettled += 1,
        }
    }
    if settled.len() < 4 && windows_down > 0 && windows_down >= windows_unsettled {
        return Err(GapError::Log(format!(
            "the robot is down (pelvis tilted beyond {:.0} deg or lower than {} m) in {windows_down} of {} windows: the floating-base plant models a robot on its feet",
            floating::FALLEN_TILT.to_degrees(),
            floating::FALLEN_HEIGHT,
            settled.len() + windows_unsettled + windows_down
        )));
    }
    if settled.len() < 4 {
        return Err(GapError::Log(format!(
            "only {} of {} windows start at a settled sample (no foot in a touchdown transient): the log is too short or the feet never settle",
            settled.len(),
            settled.len() + windows_unsettled
        )));
    }
    Ok(Settled { starts: settled, unsettled: windows_unsettled, down: windows_down })
}

/// Alternating training and held-out blocks of `block_s` seconds (by the start's log time).
fn split(log: &RobotLog, starts: &[usize], block_s: f64) -> Result<Split, GapError> {
    let tlog0 = log.states[0].t;
    let (mut train, mut test) = (Vec::new(), Vec::new());
    for (w, &s) in starts.iter().enumerate() {
        let block = ((log.states[s].t - tlog0) / block_s).floor() as i64;
        if block % 2 == 0 {
            train.push(w)
        } else {
            test.push(w)
        }
    }
    if train.len() < 2 || test.len() < 2 {
        return Err(GapError::Log("the log is too short to hold both training and held-out segments".into()));
    }
    Ok(Split { train, test })
}

#[cfg(test)]
mod tests {
    use super::super::options::RIG_MAX_WINDOWS;
    use super::*;
    use crate::log::Command;

    /// A still robot logged for `seconds`: states at 500 Hz, commands at 50 Hz (the benchmark's rates).
    fn still_log(model: &RobotModel, seconds: f64) -> RobotLog {
        let (nj, q) = (model.nj(), model.default_q());
        let states = crate::log::still_states(model, (seconds * 500.0).round() as usize + 1);
        let commands = (0..=(seconds * 50.0).round() as usize)
            .map(|k| Command {
                t: k as f64 * 0.02,
                q: q.clone(),
                dq: vec![0.0; nj],
                kp: vec![100.0; nj],
                kd: vec![2.0; nj],
                tau: vec![0.0; nj],
            })
            .collect();
        RobotLog { commands, states }
    }

    fn model() -> RobotModel {
        robot_model::builtin("h1_2").expect("model")
    }

    #[test]
    fn a_long_rig_log_is_cut_into_the_default_cap_spread_over_all_of_it() {
        let m = model();
        let log = still_log(&m, 60.0);
        let w = cut(&m, &log, &DiagnoseOptions::default(), PlantKind::Rig).expect("windows");
        assert_eq!(w.starts.len(), RIG_MAX_WINDOWS);
        assert_eq!(w.len, 50, "0.1 s windows of 2 ms states");
        let t: Vec<f64> = w.starts.iter().map(|&s| log.states[s].t).collect();
        assert!(t[0] < 1.0 && t[t.len() - 1] > 58.0, "first {} s, last {} s", t[0], t[t.len() - 1]);
        let mean_gap = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
        assert!(t.windows(2).all(|p| p[1] - p[0] > 0.5 * mean_gap && p[1] - p[0] < 1.5 * mean_gap), "{t:?}");
        let (a, b) = (w.train.len(), w.test.len());
        assert_eq!(a + b, RIG_MAX_WINDOWS);
        assert!(a.abs_diff(b) <= 8, "{a} training, {b} held-out");
    }

    #[test]
    fn a_short_log_keeps_its_windows_and_the_option_overrides_the_cap() {
        let m = model();
        let short = cut(&m, &still_log(&m, 6.0), &DiagnoseOptions::default(), PlantKind::Rig).expect("windows");
        // Every non-overlapping 0.1 s window after the first 50 ms: 59 of a 6 s log.
        assert!((55..RIG_MAX_WINDOWS).contains(&short.starts.len()), "{}", short.starts.len());
        let opts = DiagnoseOptions { max_windows: Some(300), ..DiagnoseOptions::default() };
        let long = cut(&m, &still_log(&m, 60.0), &opts, PlantKind::Rig).expect("windows");
        assert_eq!(long.starts.len(), 300);
    }
}
