//! Where the gap lies: the baseline (no effect) residual of every window broken down by joint, joint group,
//! contact phase and frequency band, and the baseline's held-out gap metric that every effect is measured against.
//! Nothing is fitted here; it tells the reader where to look before the effects say why.
use super::replay::{Ctx, Plant, Scores, IMU_STRIDE};
use super::stats::{bootstrap_mean, total, Estimate};
use crate::floating::{self, Feet};
use crate::log::RobotLog;
use crate::noise::SIGMA_Q;
use crate::plant::{Effects, GROUPS};
use crate::GapError;
use rand::Rng;
use robot_model::{FootContact, RobotModel};
use serde::{Deserialize, Serialize};

/// A share of the gap.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Share {
    pub name: String,
    /// Mean normalised residual per window.
    pub residual: f64,
    /// Fraction of the total.
    pub share: f64,
    pub windows: usize,
}

/// The baseline residual broken down.
pub(super) struct Breakdown {
    pub by_joint: Vec<Share>,
    pub by_group: Vec<Share>,
    pub by_phase: Vec<Share>,
    pub by_band: Vec<Share>,
    /// Baseline scores of every window (indexed like the starts).
    pub scores: Scores,
    /// Whether foot contact is estimated anywhere in the log (from the knee torques).
    pub any_contact: bool,
}

/// The baseline on the training and held-out windows: what every effect must beat.
pub(super) struct Baseline {
    pub train: Scores,
    pub test: Scores,
    /// Gap metric of each held-out window.
    pub test_tot: Vec<f64>,
    /// Held-out gap metric with its bootstrap interval.
    pub metric: Estimate,
}

impl Baseline {
    /// Splits the breakdown's scores into training and held-out windows and takes the held-out metric's interval.
    pub(super) fn split(ctx: &Ctx<'_>, scores: &Scores, bootstrap: usize, rng: &mut impl Rng) -> Self {
        let test: Scores = ctx.test.iter().map(|&w| scores[w].clone()).collect();
        let train: Scores = ctx.train.iter().map(|&w| scores[w].clone()).collect();
        let test_tot: Vec<f64> = test.iter().map(|s| total(s)).collect();
        let metric = bootstrap_mean(&test_tot, bootstrap, rng);
        Baseline { train, test, test_tot, metric }
    }
}

/// Replays every window without effects and breaks the residual down.
pub(super) fn breakdown(ctx: &Ctx<'_>) -> Result<Breakdown, GapError> {
    let (model, log) = (ctx.model, ctx.log);
    let nj = ctx.nj();
    let null = Effects::none(nj);
    let all: Vec<usize> = (0..ctx.starts.len()).collect();
    let mut base_rig = Plant::new(ctx.plant, model, ctx.opts, &null)?;
    let mut base_all: Scores = Vec::with_capacity(all.len());
    let mut band_tot = [0.0; 3];
    let cont = contacts(model, log);
    let mut phase_sum: std::collections::BTreeMap<&str, (f64, usize)> = Default::default();
    for &w in &all {
        let mut ser = Vec::new();
        let s = ctx.window_scores(&mut base_rig, model, &null, w, Some(&mut ser))?;
        for x in &ser {
            let b = bands(x, ctx.dt_state);
            for k in 0..3 {
                band_tot[k] += b[k] / (SIGMA_Q * SIGMA_Q) / x.len().max(1) as f64 / 3.0;
            }
        }
        let phase = match &ctx.feet {
            Some(feet) => floating_phase(model, feet, log, ctx.starts[w], ctx.len)?,
            None => phase_of(&cont, ctx.starts[w]),
        };
        let e = phase_sum.entry(phase.name()).or_insert((0.0, 0));
        e.0 += total(&s);
        e.1 += 1;
        base_all.push(s);
    }
    let nw = all.len() as f64;
    let mut names: Vec<String> = model.joints.iter().map(|j| j.motor_name.clone()).collect();
    names.push("imu".into());
    let col_mean: Vec<f64> = (0..=nj).map(|c| base_all.iter().map(|s| s[c]).sum::<f64>() / nw).collect();
    let by_joint = shares(names.clone(), col_mean.clone(), vec![all.len(); nj + 1]);
    let mut gvals = vec![0.0; GROUPS.len() + 1];
    for (j, &g) in ctx.groups.iter().enumerate() {
        gvals[g] += col_mean[j];
    }
    gvals[GROUPS.len()] = col_mean[nj];
    let mut gnames: Vec<String> = GROUPS.iter().map(|s| s.to_string()).collect();
    gnames.push("imu".into());
    let by_group = shares(gnames, gvals, vec![all.len(); GROUPS.len() + 1]);
    let by_phase = shares(
        phase_sum.keys().map(|k| k.to_string()).collect(),
        phase_sum.values().map(|(s, n)| s / (*n).max(1) as f64).collect(),
        phase_sum.values().map(|(_, n)| *n).collect(),
    );
    let by_band = shares(
        vec!["0-10 Hz (drift)".into(), "10-50 Hz".into(), "above 50 Hz".into()],
        band_tot.iter().map(|b| b / nw).collect(),
        vec![all.len(); 3],
    );
    let any_contact = cont.iter().any(|(l, r)| *l || *r);
    Ok(Breakdown { by_joint, by_group, by_phase, by_band, scores: base_all, any_contact })
}

/// Estimates foot contact from the log: a foot carries load when its knee torque exceeds what the shank and
/// foot alone can cause. Returns per state sample `(left, right)`.
fn contacts(model: &RobotModel, log: &RobotLog) -> Vec<(bool, bool)> {
    let knee = |side: &str| model.joints.iter().position(|j| j.motor_name == format!("{side}_knee"));
    let (l, r) = (knee("left"), knee("right"));
    let thr = 0.06 * model.total_mass() * robot_model::GRAVITY_EARTH; // ~40 N·m for the H1-2
    log.states
        .iter()
        .map(|s| (l.is_some_and(|j| s.tau[j].abs() > thr), r.is_some_and(|j| s.tau[j].abs() > thr)))
        .collect()
}

/// The phase a window is counted under in the breakdown: a touchdown, or which feet are on the ground
/// ([`FootContact`], the type `engine-diff` classifies its windows with).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum WindowPhase {
    /// A foot touches down within the window.
    Impact,
    /// No touchdown: these feet are on the ground.
    Feet(FootContact),
}

impl WindowPhase {
    /// The report's name: "impact", "stance" (both feet), "swing" (one foot, either side) or "flight".
    fn name(self) -> &'static str {
        match self {
            WindowPhase::Impact => "impact",
            WindowPhase::Feet(FootContact::Double) => "stance",
            WindowPhase::Feet(FootContact::Left | FootContact::Right) => "swing",
            WindowPhase::Feet(FootContact::Flight) => "flight",
        }
    }
}

/// Floating base: the phase of the window starting at `start` from the kinematic contact estimate
/// ([`floating::contact_state`]): impact when a touchdown starts within the window (a sample after the start is
/// not settled), else the feet in stance at the start.
fn floating_phase(
    model: &RobotModel,
    feet: &Feet,
    log: &RobotLog,
    start: usize,
    len: usize,
) -> Result<WindowPhase, GapError> {
    let null = Effects::none(model.nj());
    let (stance, _) = floating::contact_state(model, feet, log, start, &null)?;
    for k in (IMU_STRIDE..=len).step_by(IMU_STRIDE) {
        if start + k < log.states.len() && !floating::contact_state(model, feet, log, start + k, &null)?.1 {
            return Ok(WindowPhase::Impact);
        }
    }
    Ok(WindowPhase::Feet(FootContact::from_feet(stance[0], stance[1])))
}

/// Rig: the phase of the window starting at sample `i` from the knee-torque contact estimate ([`contacts`]):
/// impact when a foot took load within the last 25 samples, else the feet carrying load.
fn phase_of(c: &[(bool, bool)], i: usize) -> WindowPhase {
    let (l, r) = c[i];
    let before = c[i.saturating_sub(25)];
    if (l && !before.0) || (r && !before.1) {
        WindowPhase::Impact
    } else {
        WindowPhase::Feet(FootContact::from_feet(l, r))
    }
}

/// Band energies of a residual series sampled at `dt`: [< 10 Hz incl. drift, 10–50 Hz, > 50 Hz].
fn bands(x: &[f64], dt: f64) -> [f64; 3] {
    let n = x.len();
    let mut out = [0.0; 3];
    if n < 4 {
        return out;
    }
    // Drift: the mean and linear trend count as the lowest band.
    let mean = x.iter().sum::<f64>() / n as f64;
    out[0] += mean * mean * n as f64;
    let y: Vec<f64> = x.iter().map(|v| v - mean).collect();
    for k in 1..=n / 2 {
        let f = k as f64 / (n as f64 * dt);
        let (mut re, mut im) = (0.0, 0.0);
        for (i, v) in y.iter().enumerate() {
            let a = -2.0 * std::f64::consts::PI * (k * i) as f64 / n as f64;
            re += v * a.cos();
            im += v * a.sin();
        }
        let e = 2.0 * (re * re + im * im) / n as f64;
        let b = if f < 10.0 + 1e-9 {
            0
        } else if f <= 50.0 {
            1
        } else {
            2
        };
        out[b] += e;
    }
    out
}

fn shares(names: Vec<String>, values: Vec<f64>, counts: Vec<usize>) -> Vec<Share> {
    let tot: f64 = values.iter().sum::<f64>().max(1e-300);
    let mut v: Vec<Share> = names
        .into_iter()
        .zip(values)
        .zip(counts)
        .map(|((name, residual), windows)| Share { name, share: residual / tot, residual, windows })
        .collect();
    v.sort_by(|a, b| b.residual.total_cmp(&a.residual));
    v
}
