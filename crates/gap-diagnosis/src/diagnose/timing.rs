//! The log's timing, checked before anything is attributed. Timing is not a physical effect: a state stamped before
//! the time it holds, or commands stamped late against the states (two clocks), makes the robot seem to answer a
//! command before it was sent, which no effect of the library can do and which a fit would absorb as something
//! unphysical (a negative damping on the stiffest joints). So the replay is tried with every command acting earlier
//! than its stamp by each of [`ADVANCES_MS`]; the best advance on the training windows is applied — the commands'
//! stamps are moved, the report says by how much — when it gains as much held-out evidence as a named effect must
//! ([`super::Thresholds::min_gain`]). A command acting *later* than its stamp is what a latency is, and that is an
//! effect of the library, judged with the others.
//!
//! The stamps' regularity is reported too: windows whose states stray from a regular grid are not replayed
//! ([`super::windows`]), and a log most of whose windows do so is not diagnosed at all.
use super::replay::{Ctx, Scores};
use super::stats::{bootstrap_mean, bootstrap_ratio, log_gain, mean, total, Estimate};
use super::Thresholds;
use crate::log::RobotLog;
use crate::plant::Effects;
use crate::GapError;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Command advances tried (ms): from a millisecond (a state stamped at the start of the physics step that produced
/// it) to 16 ms (two clocks apart by more than a control period).
pub const ADVANCES_MS: [f64; 5] = [1.0, 2.0, 4.0, 8.0, 16.0];

/// What the timing check found.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct TimingCheck {
    /// Median interval of the logged states and of the logged commands (s).
    pub state_period_s: f64,
    pub command_period_s: f64,
    /// Fraction of state intervals outside half to twice the median (a stalled loop, a burst).
    pub irregular_fraction: f64,
    /// Each advance tried: the held-out gap's relative cut against the log as stamped.
    pub tried: Vec<AdvanceTried>,
    /// The advance applied to every command's stamp before the diagnosis (ms; 0: none).
    pub applied_advance_ms: f64,
    /// What the check concluded, in words.
    pub finding: String,
}

/// One command advance tried.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct AdvanceTried {
    pub advance_ms: f64,
    /// Training gap metric (mean per window).
    pub train_gap: f64,
    /// Held-out log-likelihood gain per window against the log as stamped.
    pub gain: Estimate,
    /// Relative cut of the held-out gap against the log as stamped.
    pub cut: Estimate,
}

/// `log` with every command acting `advance_s` earlier against the states.
pub(super) fn advanced(log: &RobotLog, advance_s: f64) -> RobotLog {
    let mut out = log.clone();
    out.commands.iter_mut().for_each(|c| c.t -= advance_s);
    out
}

/// Checks the timing of the log behind `ctx` (replayed as stamped).
pub(super) fn check(ctx: &Ctx<'_>, th: &Thresholds, rng: &mut impl Rng) -> Result<TimingCheck, GapError> {
    let log = ctx.log;
    let median = |mut d: Vec<f64>| {
        d.retain(|x| *x > 0.0);
        d.sort_by(f64::total_cmp);
        d.get(d.len() / 2).copied().unwrap_or(0.0)
    };
    let state_dt: Vec<f64> = log.states.windows(2).map(|w| w[1].t - w[0].t).collect();
    let state_period_s = median(state_dt.clone());
    let command_period_s = median(log.commands.windows(2).map(|w| w[1].t - w[0].t).collect());
    let irregular = state_dt
        .iter()
        .filter(|&&d| d < crate::noise::TIMING_LO * state_period_s || d > crate::noise::TIMING_HI * state_period_s)
        .count();
    let irregular_fraction = irregular as f64 / state_dt.len().max(1) as f64;
    let null = [Effects::none(ctx.nj())];
    let scores = |c: &Ctx<'_>, w: &[usize]| -> Result<Scores, GapError> { Ok(c.eval_many(&null, w)?.remove(0)) };
    let totals = |s: &Scores| -> Vec<f64> { s.iter().map(|w| total(w)).collect() };
    let (train0, test0) = (scores(ctx, &ctx.train)?, scores(ctx, &ctx.test)?);
    let mut tried = Vec::new();
    for &ms in &ADVANCES_MS {
        let shifted = advanced(log, ms * 1e-3);
        let c = ctx.with_log(&shifted);
        let (train, test) = (scores(&c, &c.train)?, scores(&c, &c.test)?);
        tried.push(AdvanceTried {
            advance_ms: ms,
            train_gap: mean(&totals(&train)),
            gain: bootstrap_mean(&log_gain(&test0, &test, None, &ctx.noise), ctx.opts.bootstrap, rng),
            cut: bootstrap_ratio(&totals(&test0), &totals(&test), ctx.opts.bootstrap, rng),
        });
    }
    let base_train = mean(&totals(&train0));
    let best = tried
        .iter()
        .enumerate()
        .filter(|(_, t)| t.train_gap < base_train)
        .min_by(|a, b| a.1.train_gap.total_cmp(&b.1.train_gap));
    let (applied_advance_ms, finding) = match best {
        Some((_, t)) if t.gain.lo >= th.min_gain => (
            t.advance_ms,
            format!(
                "the robot answers the commands {} ms before their stamps say they were sent: the states are stamped \
                 before the time they hold, or the commands after it (two clocks). The commands are replayed {} ms \
                 earlier (held-out log-likelihood gain {:.3} [{:.3}, {:.3}] per window, gap cut {:.1} %, against the \
                 log as stamped); fix the recorder's stamps",
                t.advance_ms,
                t.advance_ms,
                t.gain.value,
                t.gain.lo,
                t.gain.hi,
                100.0 * t.cut.value
            ),
        ),
        Some((_, t)) => (
            0.0,
            format!(
                "the stamps are consistent: replaying the commands {} ms earlier fits the training windows a little \
                 better but gains {:.3} [{:.3}, {:.3}] per held-out window only",
                t.advance_ms, t.gain.value, t.gain.lo, t.gain.hi
            ),
        ),
        None => (0.0, "the stamps are consistent: no command advance fits the log better".into()),
    };
    let finding = if irregular_fraction > 0.0 {
        format!(
            "{finding}; {:.1} % of the state intervals are irregular (outside half to twice the median)",
            100.0 * irregular_fraction
        )
    } else {
        finding
    };
    Ok(TimingCheck { state_period_s, command_period_s, irregular_fraction, tried, applied_advance_ms, finding })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::Command;

    #[test]
    fn an_advance_moves_every_command_earlier_and_nothing_else() {
        let c = |t: f64| Command { t, q: vec![], dq: vec![], kp: vec![], kd: vec![], tau: vec![] };
        let log = RobotLog { commands: vec![c(0.0), c(0.002), c(0.004)], states: vec![] };
        let a = advanced(&log, 0.001);
        let t: Vec<f64> = a.commands.iter().map(|c| c.t).collect();
        assert_eq!(t, vec![-0.001, 0.001, 0.003]);
        assert_eq!(a.states, log.states);
    }
}
