//! The diagnosis: replay the logged commands in short windows from the logged state, break the residual down
//! (joint, phase, frequency band), fit every effect on training windows, rank by held-out reduction against a
//! data-derived noise floor, fit the best combination, and attach bootstrap confidence intervals.
use crate::effects::{EffectKind, Scope};
use crate::floating::{self, Feet, FloatingPlant};
use crate::log::{Measurement, RobotLog};
use crate::plant::{imu_reading, joint_groups, predict_window, Effects, EngineChoice, Rig, DT, GROUPS};
use crate::rig_check::{self, RigCheck};
use crate::GapError;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};

/// Schema version of `report.json`.
/// `/2`: adds `outcome` and `rig_check` (the rig-assumption check, see [`crate::rig_check`]).
/// `/3`: adds `plant` (rig or floating base) and `windows_unsettled`.
/// `/4`: adds `windows_down` and `rig_check.foot_load_fraction`.
pub const SCHEMA_VERSION: &str = "ulab-gap-report/4";

pub use crate::noise::{SIGMA_DQ, SIGMA_GYRO, SIGMA_Q, SIGMA_QUAT, SIGMA_TAU_FRAC};

/// Every this many samples of a floating-base window are checked for a robot that is down.
const DOWN_CHECK_STRIDE: usize = 5;

/// Default window cap on the floating base ([`PlantKind::default_max_windows`]).
pub const FLOATING_MAX_WINDOWS: usize = 120;

/// Options of a diagnosis.
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    pub engine: EngineChoice,
    /// Window length (s).
    pub window_s: f64,
    /// At most this many windows (spread evenly over the log); `None`: the plant's default
    /// ([`PlantKind::default_max_windows`]).
    pub max_windows: Option<usize>,
    /// Train/held-out blocks alternate every `block_s` seconds.
    pub block_s: f64,
    /// Bootstrap resamples for confidence intervals.
    pub bootstrap: usize,
    pub seed: u64,
    /// Restrict the effect library (None: all).
    pub kinds: Option<Vec<EffectKind>>,
    /// Which plant replays the windows.
    pub plant: PlantChoice,
}

/// The plant requested for a diagnosis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlantChoice {
    /// The rig when the log passes the rig-assumption check, the floating base otherwise.
    #[default]
    Auto,
    /// The suspension rig only: a log that fails the rig check is not diagnosed (every effect abstains).
    Rig,
    /// The floating base on flat ground ([`crate::floating`]), whatever the rig check says.
    Floating,
}

impl PlantChoice {
    /// Parses `auto`, `rig` or `floating`.
    pub fn parse(s: &str) -> Result<Self, GapError> {
        match s {
            "auto" => Ok(PlantChoice::Auto),
            "rig" => Ok(PlantChoice::Rig),
            "floating" => Ok(PlantChoice::Floating),
            other => Err(GapError::Input(format!("unknown plant {other:?} (auto, rig, floating)"))),
        }
    }
}

/// The plant a diagnosis used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlantKind {
    /// The robot on the suspension rig ([`crate::plant::Rig`]).
    #[default]
    Rig,
    /// The robot on flat ground, base state estimated from the log ([`crate::floating::FloatingPlant`]).
    Floating,
}

impl PlantKind {
    /// Default window cap. A floating-base window (ground contact, a base estimate per start) costs about three
    /// rig windows, so its cap is lower; both keep a 60 s log within a minute on 2 cores, and both are above
    /// what a short log holds (a 6 s log at 0.1 s windows has at most 60).
    pub fn default_max_windows(self) -> usize {
        match self {
            PlantKind::Rig => 300,
            PlantKind::Floating => FLOATING_MAX_WINDOWS,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            PlantKind::Rig => "rig",
            PlantKind::Floating => "floating",
        }
    }
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            engine: EngineChoice { integrator: "implicitfast".into() },
            window_s: 0.1,
            max_windows: None,
            block_s: 1.0,
            bootstrap: 200,
            seed: 1,
            kinds: None,
            plant: PlantChoice::Auto,
        }
    }
}

/// A value with a 95 % interval.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct Estimate {
    pub value: f64,
    pub lo: f64,
    pub hi: f64,
}

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

/// One fitted parameter.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct FittedParam {
    /// Joint, group, `robot` or `imu_x|y|z`.
    pub unit: String,
    pub value: f64,
    /// Bootstrap standard deviation over training windows.
    pub sd: f64,
    /// Held-out reduction of the gap metric credited to this unit (absolute, normalised units per window): its
    /// own residual's reduction, or, when several units are kept, the whole-gap reduction it gives alone.
    pub held_out_reduction: f64,
}

/// An effect's result.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct EffectResult {
    pub kind: EffectKind,
    pub parameter: String,
    pub scope: Scope,
    /// Named (confident): the held-out reduction's lower bound clears the noise floor (for an effect added to
    /// the best combination after the first: the reduction of the residual the effects before it leave).
    pub named: bool,
    /// Relative held-out reduction of the gap metric (0..1), with a bootstrap interval; for an effect added to the
    /// combination after the first, relative to the residual that remains with the effects before it.
    pub reduction: Estimate,
    /// Held-out gap metric with this effect added (to the effects before it, when named given them).
    pub metric_after: Estimate,
    /// Relative noise floor the reduction had to clear.
    pub noise_floor: f64,
    /// The units kept (reduction above the unit floor), with values.
    pub params: Vec<FittedParam>,
    /// Why it was not fitted or not named, or, when named given other effects, which.
    pub note: Option<String>,
}

/// The best combination of named effects.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Combination {
    pub effects: Vec<EffectKind>,
    pub metric_after: Estimate,
    pub reduction: Estimate,
}

/// What the diagnosis concluded about the log as a whole.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Effects were fitted and ranked (on the plant in [`Report::plant`]).
    Diagnosed,
    /// The rig was requested ([`PlantChoice::Rig`]) but the log is not from a suspended robot (the pelvis moves):
    /// nothing was fitted, every effect abstained.
    RigAssumptionViolated,
}

/// The whole diagnosis.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    pub schema_version: String,
    pub outcome: Outcome,
    /// The rig-assumption check that decided whether the diagnosis could run.
    pub rig_check: RigCheck,
    /// The plant that replayed the windows (`/2` reports: always the rig).
    #[serde(default)]
    pub plant: PlantKind,
    /// Floating base only: nominal window starts dropped because no sample within one window length after them
    /// was settled (every foot in contact had been in contact for [`crate::floating::SETTLE_S`]).
    #[serde(default)]
    pub windows_unsettled: usize,
    /// Floating base only: nominal window starts dropped because the robot was down (fell: pelvis tilted beyond
    /// [`crate::floating::FALLEN_TILT`] or lower than [`crate::floating::FALLEN_HEIGHT`]) within the window.
    #[serde(default)]
    pub windows_down: usize,
    pub robot: String,
    pub engine: String,
    pub log_duration_s: f64,
    pub windows_train: usize,
    pub windows_held_out: usize,
    pub window_s: f64,
    /// Fraction of possible window starts not used: no fresh command (older than [`COMMAND_STALE_S`]) or irregular
    /// state timing (log times straying more than [`TIMING_TOL_S`] from a regular grid) within the window.
    #[serde(default)]
    pub windows_skipped_fraction: f64,
    /// Held-out gap metric of the baseline simulator.
    pub baseline_metric: Estimate,
    pub by_joint: Vec<Share>,
    pub by_group: Vec<Share>,
    pub by_phase: Vec<Share>,
    pub by_band: Vec<Share>,
    /// Every effect tried: named ones first, each group by its own held-out reduction.
    pub effects: Vec<EffectResult>,
    /// The named effects in rank order: the best combination's selection order (each adds the most held-out
    /// explanatory power given the ones before it), then the other named effects.
    pub ranked: Vec<EffectKind>,
    /// Effects not named, with the reason.
    pub abstentions: Vec<(EffectKind, String)>,
    pub best_combination: Option<Combination>,
    /// No effect was named: the gap is reported as unexplained.
    pub unexplained: bool,
    pub elapsed_s: f64,
}

/// Per-window scores: `[window][column]`, columns = joints then the IMU.
type Scores = Vec<Vec<f64>>;

/// The engine that replays a window: on the rig, or on the ground.
enum Plant {
    Rig(Rig),
    Floating(FloatingPlant),
}

impl Plant {
    /// A plant of `kind` for `model` (already carrying the model-level effects of `fx`; `fx` supplies the contact
    /// time constant of the floating plant).
    fn new(kind: PlantKind, model: &RobotModel, engine: &EngineChoice, fx: &Effects) -> Result<Self, GapError> {
        Ok(match kind {
            PlantKind::Rig => Plant::Rig(Rig::new(model, engine)?),
            PlantKind::Floating => Plant::Floating(FloatingPlant::new(model, engine, fx)?),
        })
    }

    /// The window's predicted measurements ([`crate::plant::predict_window`] or [`floating::predict_window`]).
    #[allow(clippy::too_many_arguments)]
    fn predict(
        &mut self,
        model: &RobotModel,
        feet: Option<&Feet>,
        log: &RobotLog,
        fx: &Effects,
        start: usize,
        len: usize,
        with_imu: bool,
    ) -> Result<Vec<Measurement>, GapError> {
        match (self, feet) {
            (Plant::Rig(rig), _) => predict_window(rig, model, log, fx, start, len, with_imu),
            (Plant::Floating(p), Some(feet)) => floating::predict_window(p, model, feet, log, fx, start, len, with_imu),
            (Plant::Floating(_), None) => Err(GapError::Input("floating plant without feet".into())),
        }
    }
}

struct Ctx<'a> {
    model: &'a RobotModel,
    log: &'a RobotLog,
    opts: &'a DiagnoseOptions,
    plant: PlantKind,
    /// The feet (floating plant only).
    feet: Option<Feet>,
    starts: Vec<usize>,
    len: usize,
    train: Vec<usize>,
    test: Vec<usize>,
    groups: Vec<usize>,
    sigma_tau: Vec<f64>,
    null: Effects,
    /// Idle engines of the unmodified model.
    pool: std::sync::Mutex<Vec<Plant>>,
}

impl Ctx<'_> {
    fn nj(&self) -> usize {
        self.model.nj()
    }

    /// Scores of the given windows under each configuration (parallel over configurations × window chunks).
    fn eval_many(&self, cfgs: &[Effects], windows: &[usize]) -> Result<Vec<Scores>, GapError> {
        let chunks = (rayon::current_num_threads() * 2).max(1);
        let per = windows.len().div_ceil(chunks).max(1);
        let jobs: Vec<(usize, &[usize])> =
            (0..cfgs.len()).flat_map(|c| windows.chunks(per).map(move |w| (c, w))).collect();
        let results: Vec<Result<(usize, Scores), GapError>> = jobs
            .par_iter()
            .map(|(c, ws)| {
                let fx = &cfgs[*c];
                // Engines of the unmodified model are reused (building one costs far more than a window).
                let baseline_model = fx.same_model(&self.null);
                let model = if baseline_model { self.model.clone() } else { fx.apply_to_model(self.model) };
                let pooled = if baseline_model { self.pool.lock().ok().and_then(|mut p| p.pop()) } else { None };
                let mut rig = match pooled {
                    Some(r) => r,
                    None => Plant::new(self.plant, &model, &self.opts.engine, fx)?,
                };
                let mut out = Vec::with_capacity(ws.len());
                for &w in ws.iter() {
                    out.push(self.window_scores(&mut rig, &model, fx, w, None)?);
                }
                if baseline_model {
                    if let Ok(mut p) = self.pool.lock() {
                        p.push(rig);
                    }
                }
                Ok((*c, out))
            })
            .collect();
        let mut all: Vec<Scores> = vec![Vec::new(); cfgs.len()];
        for r in results {
            let (c, s) = r?;
            all[c].extend(s);
        }
        Ok(all)
    }

    /// Normalised squared residual of one window per column; `series` receives the q residual time series.
    fn window_scores(
        &self,
        rig: &mut Plant,
        model: &RobotModel,
        fx: &Effects,
        w: usize,
        series: Option<&mut Vec<Vec<f64>>>,
    ) -> Result<Vec<f64>, GapError> {
        let nj = self.nj();
        let start = self.starts[w];
        let floating = self.plant == PlantKind::Floating;
        let pred = rig.predict(model, self.feet.as_ref(), self.log, fx, start, self.len, floating)?;
        let mut s = vec![0.0; nj + 1];
        let mut ser = vec![Vec::with_capacity(pred.len()); nj];
        for (k, p) in pred.iter().enumerate() {
            let m = &self.log.states[start + 1 + k];
            for j in 0..nj {
                let eq = (m.q[j] - p.q[j]) / SIGMA_Q;
                let edq = (m.dq[j] - p.dq[j]) / SIGMA_DQ;
                let et = (m.tau[j] - p.tau[j]) / self.sigma_tau[j];
                s[j] += (eq * eq + edq * edq + et * et) / 3.0;
                ser[j].push(m.q[j] - p.q[j]);
            }
        }
        let n = pred.len().max(1) as f64;
        s.iter_mut().take(nj).for_each(|x| *x /= n);
        s[nj] = if floating { floating_imu_score(self.log, start, &pred) } else { self.imu_score(fx, w)? };
        if let Some(out) = series {
            *out = ser;
        }
        Ok(s)
    }

    /// IMU residual of a window: the reading predicted from the logged joints on the rig vs the logged reading.
    fn imu_score(&self, fx: &Effects, w: usize) -> Result<f64, GapError> {
        let start = self.starts[w];
        let mut s = 0.0;
        let step = 5;
        let mut n = 0.0_f64;
        for k in (1..=self.len).step_by(step) {
            let Some(m) = self.log.states.get(start + k) else { break };
            let q: Vec<f64> = m.q.iter().zip(&fx.encoder_offset).map(|(a, o)| a - o).collect();
            let (quat, gyro) = imu_reading(self.model, &q, &m.dq, fx)?;
            let r = rot_residual(&m.quat, &quat);
            for k in 0..3 {
                s += (r[k] / SIGMA_QUAT).powi(2) + ((m.gyro[k] - gyro[k]) / SIGMA_GYRO).powi(2);
            }
            n += 1.0;
        }
        Ok(s / (6.0 * n.max(1.0)))
    }
}

/// IMU sample stride of the IMU score (the IMU changes slowly within a window).
const IMU_STRIDE: usize = 5;

/// Floating base: the IMU residual of a window is the logged reading against the window's predicted one (the
/// simulated pelvis carries the IMU), at the same samples and in the same units as the rig's [`Ctx::imu_score`].
fn floating_imu_score(log: &RobotLog, start: usize, pred: &[Measurement]) -> f64 {
    let (mut s, mut n) = (0.0, 0.0_f64);
    for k in (1..=pred.len()).step_by(IMU_STRIDE) {
        let (Some(m), Some(p)) = (log.states.get(start + k), pred.get(k - 1)) else { break };
        let r = rot_residual(&m.quat, &p.quat);
        for ((r, gm), gp) in r.iter().zip(&m.gyro).zip(&p.gyro) {
            s += (r / SIGMA_QUAT).powi(2) + ((gm - gp) / SIGMA_GYRO).powi(2);
        }
        n += 1.0;
    }
    s / (6.0 * n.max(1.0))
}

/// Rotation vector taking `pred` to `meas` in the IMU frame.
fn rot_residual(meas: &[f64; 4], pred: &[f64; 4]) -> [f64; 3] {
    let q = |a: &[f64; 4]| nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(a[0], a[1], a[2], a[3]));
    (q(pred).inverse() * q(meas)).scaled_axis().into()
}

fn total(s: &[f64]) -> f64 {
    s.iter().sum()
}

fn mean(x: &[f64]) -> f64 {
    if x.is_empty() {
        0.0
    } else {
        x.iter().sum::<f64>() / x.len() as f64
    }
}

/// Percentile interval of the mean by resampling `x` with replacement.
fn bootstrap_mean(x: &[f64], b: usize, rng: &mut impl Rng) -> Estimate {
    let v = mean(x);
    if x.len() < 2 {
        return Estimate { value: v, lo: v, hi: v };
    }
    let mut ms: Vec<f64> = (0..b)
        .map(|_| {
            let mut s = 0.0;
            for _ in 0..x.len() {
                s += x[rng.gen_range(0..x.len())];
            }
            s / x.len() as f64
        })
        .collect();
    ms.sort_by(f64::total_cmp);
    let at = |p: f64| ms[((p * (ms.len() - 1) as f64).round() as usize).min(ms.len() - 1)];
    Estimate { value: v, lo: at(0.025), hi: at(0.975) }
}

/// Paired relative reduction `1 - mean(after)/mean(before)` with a bootstrap interval over windows.
fn bootstrap_ratio(before: &[f64], after: &[f64], b: usize, rng: &mut impl Rng) -> Estimate {
    let n = before.len().min(after.len());
    let r = |idx: &mut dyn Iterator<Item = usize>| {
        let (mut a, mut c) = (0.0, 0.0);
        for i in idx {
            a += before[i];
            c += after[i];
        }
        if a > 0.0 {
            1.0 - c / a
        } else {
            0.0
        }
    };
    let v = r(&mut (0..n));
    if n < 2 {
        return Estimate { value: v, lo: v, hi: v };
    }
    let mut ms: Vec<f64> = (0..b)
        .map(|_| {
            let idx: Vec<usize> = (0..n).map(|_| rng.gen_range(0..n)).collect();
            r(&mut idx.into_iter())
        })
        .collect();
    ms.sort_by(f64::total_cmp);
    let at = |p: f64| ms[((p * (ms.len() - 1) as f64).round() as usize).min(ms.len() - 1)];
    Estimate { value: v, lo: at(0.025), hi: at(0.975) }
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

/// Floating base: the phase of the window starting at `start` from the kinematic contact estimate
/// ([`floating::contact_state`]): "impact" when a touchdown starts within the window (a sample after the start is
/// not settled), else "stance" (both feet), "swing" (one) or "flight".
fn floating_phase(
    model: &RobotModel,
    feet: &Feet,
    log: &RobotLog,
    start: usize,
    len: usize,
) -> Result<&'static str, GapError> {
    let null = Effects::none(model.nj());
    let (stance, _) = floating::contact_state(model, feet, log, start, &null)?;
    for k in (IMU_STRIDE..=len).step_by(IMU_STRIDE) {
        if start + k < log.states.len() && !floating::contact_state(model, feet, log, start + k, &null)?.1 {
            return Ok("impact");
        }
    }
    Ok(match stance {
        [true, true] => "stance",
        [true, false] | [false, true] => "swing",
        [false, false] => "flight",
    })
}

fn phase_of(c: &[(bool, bool)], i: usize) -> &'static str {
    let (l, r) = c[i];
    let before = c[i.saturating_sub(25)];
    let new_contact = (l && !before.0) || (r && !before.1);
    match (l, r) {
        _ if new_contact => "impact",
        (true, true) => "stance",
        (true, false) | (false, true) => "swing",
        (false, false) => "flight",
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

/// Runs the diagnosis of `log` against `model` in the chosen engine.
pub fn diagnose(model: &RobotModel, log: &RobotLog, opts: &DiagnoseOptions) -> Result<Report, GapError> {
    let t_start = std::time::Instant::now();
    log.validate(model.nj())?;
    let rig = rig_check::check(model, log)?;
    let plant = match opts.plant {
        PlantChoice::Rig if !rig.suspended => return Ok(rig_violated(model, log, opts, rig, t_start)),
        PlantChoice::Rig => PlantKind::Rig,
        PlantChoice::Auto if rig.suspended => PlantKind::Rig,
        PlantChoice::Auto | PlantChoice::Floating => PlantKind::Floating,
    };
    let nj = model.nj();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed);
    // State sample period from the log (median).
    let mut dts: Vec<f64> = log.states.windows(2).map(|w| w[1].t - w[0].t).filter(|d| *d > 0.0).collect();
    dts.sort_by(f64::total_cmp);
    let dt_state = dts.get(dts.len() / 2).copied().unwrap_or(DT).max(DT);
    let len = ((opts.window_s / dt_state).round() as usize).max(2);
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
    let mut fresh_run = vec![0usize; log.states.len() + 1]; // fresh_run[i]: states from i on with a fresh command
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
    let eligible: Vec<usize> = candidates.iter().copied().filter(|&i| fresh_run[i] > len && regular(i)).collect();
    let skipped_fraction = 1.0 - eligible.len() as f64 / candidates.len().max(1) as f64;
    if eligible.len() < 4 {
        return Err(GapError::Log(format!(
            "the log is too short for {} s windows after the first command",
            opts.window_s
        )));
    }
    let count = opts.max_windows.unwrap_or(plant.default_max_windows()).min(eligible.len() / len.max(1)).max(4);
    let starts: Vec<usize> = (0..count).map(|k| eligible[k * eligible.len() / count]).collect();
    // Floating base: each start moves to the first settled sample within one window length (no foot in a
    // touchdown transient, where the kinematic base estimate is 10-15 times worse); starts with none are dropped.
    // This happens before the train/held-out split, so both sides see only settled windows.
    let feet = if plant == PlantKind::Floating { Some(Feet::of(model)?) } else { None };
    let mut windows_unsettled = 0;
    let mut windows_down = 0;
    let starts = match &feet {
        None => starts,
        Some(feet) => {
            let null = Effects::none(nj);
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
            settled
        }
    };
    let tlog0 = log.states[0].t;
    let (mut train, mut test) = (Vec::new(), Vec::new());
    for (w, &s) in starts.iter().enumerate() {
        let block = ((log.states[s].t - tlog0) / opts.block_s).floor() as i64;
        if block % 2 == 0 {
            train.push(w)
        } else {
            test.push(w)
        }
    }
    if train.len() < 2 || test.len() < 2 {
        return Err(GapError::Log("the log is too short to hold both training and held-out segments".into()));
    }
    let ctx = Ctx {
        model,
        log,
        opts,
        plant,
        feet,
        starts,
        len,
        train,
        test,
        groups: joint_groups(model),
        sigma_tau: model.joints.iter().map(|j| SIGMA_TAU_FRAC * j.torque_limit.max(1.0)).collect(),
        null: Effects::none(nj),
        pool: std::sync::Mutex::new(Vec::new()),
    };
    let null = Effects::none(nj);

    // ---- Where: baseline residual breakdown over every window.
    let all: Vec<usize> = (0..ctx.starts.len()).collect();
    let mut base_rig = Plant::new(plant, model, &opts.engine, &null)?;
    let mut base_all: Scores = Vec::with_capacity(all.len());
    let mut band_tot = [0.0; 3];
    let cont = contacts(model, log);
    let mut phase_sum: std::collections::BTreeMap<&str, (f64, usize)> = Default::default();
    for &w in &all {
        let mut ser = Vec::new();
        let s = ctx.window_scores(&mut base_rig, model, &null, w, Some(&mut ser))?;
        for (j, x) in ser.iter().enumerate() {
            let b = bands(x, dt_state);
            for k in 0..3 {
                band_tot[k] += b[k] / (SIGMA_Q * SIGMA_Q) / x.len().max(1) as f64 / 3.0;
            }
            let _ = j;
        }
        let phase = match &ctx.feet {
            Some(feet) => floating_phase(model, feet, log, ctx.starts[w], len)?,
            None => phase_of(&cont, ctx.starts[w]),
        };
        let e = phase_sum.entry(phase).or_insert((0.0, 0));
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
    let base_test: Scores = ctx.test.iter().map(|&w| base_all[w].clone()).collect();
    let base_train: Scores = ctx.train.iter().map(|&w| base_all[w].clone()).collect();
    let base_test_tot: Vec<f64> = base_test.iter().map(|s| total(s)).collect();
    let baseline_metric = bootstrap_mean(&base_test_tot, opts.bootstrap, &mut rng);

    // ---- Which: fit every effect on training windows, score on held-out windows.
    let kinds: Vec<EffectKind> = opts.kinds.clone().unwrap_or_else(|| EffectKind::ALL.to_vec());
    let mut results = Vec::new();
    let mut fitted: Vec<(EffectKind, Effects)> = Vec::new();
    let mut test_scores: Vec<(EffectKind, Vec<f64>)> = Vec::new();
    for kind in kinds {
        if plant == PlantKind::Rig && !kind.identifiable_suspended() {
            let any_contact = cont.iter().any(|(l, r)| *l || *r);
            let note = if any_contact {
                "foot contact is estimated in this log, but the suspended-rig plant has no ground model to fit it on"
                    .to_string()
            } else {
                "not identifiable: no foot contact in this log".to_string()
            };
            results.push(EffectResult {
                kind,
                parameter: kind.parameter().into(),
                scope: kind.scope(),
                named: false,
                reduction: Estimate { value: 0.0, lo: 0.0, hi: 0.0 },
                metric_after: baseline_metric,
                noise_floor: 0.0,
                params: vec![],
                note: Some(note),
            });
            continue;
        }
        let (fx, sds) = fit_kind(&ctx, kind, &null, &base_train, &mut rng)?;
        // Held-out: per-unit reductions decide which units are kept.
        let after = ctx.eval_many(std::slice::from_ref(&fx), &ctx.test)?.remove(0);
        let units = units_of(&ctx, kind);
        let mut pruned = null.clone();
        let mut params = Vec::new();
        for (u, cols) in units.iter().enumerate() {
            let before: Vec<f64> = base_test.iter().map(|s| cols.iter().map(|&c| s[c]).sum()).collect();
            let aft: Vec<f64> = after.iter().map(|s| cols.iter().map(|&c| s[c]).sum()).collect();
            let diffs: Vec<f64> = before.iter().zip(&aft).map(|(b, a)| b - a).collect();
            let d = bootstrap_mean(&diffs, opts.bootstrap, &mut rng);
            let unit_floor = UNIT_FLOOR_FRAC * mean(&before);
            let value = unit_value(kind, &fx, &ctx, u);
            if d.lo > unit_floor && d.value > 0.0 && kind.scope() == Scope::Imu {
                kind.copy(&fx, &mut pruned);
                for (k, axis) in ["imu_x", "imu_y", "imu_z"].into_iter().enumerate() {
                    params.push(FittedParam {
                        unit: axis.into(),
                        value: kind.get(&fx, k),
                        sd: sds[0],
                        held_out_reduction: d.value,
                    });
                }
            } else if d.lo > unit_floor
                && d.value > 0.0
                && (value - kind.range().2).abs() >= RESOLUTION_FRAC * (kind.range().1 - kind.range().0)
            {
                set_unit(kind, &mut pruned, &ctx, u, value);
                params.push(FittedParam {
                    unit: unit_name(&ctx, kind, u),
                    value: report_value(kind, value),
                    sd: report_value(kind, sds[u]),
                    held_out_reduction: d.value,
                });
            }
        }
        // With several units kept, credit each by the whole-gap reduction it gives alone (a joint's effect also
        // shows in its neighbours' residuals, so its own column is not a fair measure).
        if params.len() > 1 && matches!(kind.scope(), Scope::Joint | Scope::Group) {
            let base_sum: f64 = base_test_tot.iter().sum();
            let solo: Vec<Effects> = params
                .iter()
                .map(|p| {
                    let mut fx = null.clone();
                    if let Some(u) = (0..units.len()).find(|&u| unit_name(&ctx, kind, u) == p.unit) {
                        set_unit(kind, &mut fx, &ctx, u, unit_value(kind, &pruned, &ctx, u));
                    }
                    fx
                })
                .collect();
            let res = ctx.eval_many(&solo, &ctx.test)?;
            for (p, r) in params.iter_mut().zip(res) {
                p.held_out_reduction = (base_sum - r.iter().map(|s| total(s)).sum::<f64>()) / ctx.test.len() as f64;
            }
        }
        let (after_tot, kept) = if params.is_empty() {
            (base_test_tot.clone(), pruned)
        } else {
            let a = ctx.eval_many(std::slice::from_ref(&pruned), &ctx.test)?.remove(0);
            (a.iter().map(|s| total(s)).collect::<Vec<f64>>(), pruned)
        };
        let red = bootstrap_ratio(&base_test_tot, &after_tot, opts.bootstrap, &mut rng);
        let metric_after = bootstrap_mean(&after_tot, opts.bootstrap, &mut rng);
        let floor = noise_floor(&base_test_tot);
        let named = !params.is_empty() && red.lo > floor;
        let note = if named {
            None
        } else if params.is_empty() {
            Some("no joint/group reduced the held-out residual beyond its floor".to_string())
        } else {
            Some(format!(
                "held-out reduction {:.3} (lower bound {:.3}) does not clear the noise floor {:.3}",
                red.value, red.lo, floor
            ))
        };
        // Every effect that cut some unit's own residual stays a candidate of the conditional selection below.
        if !params.is_empty() {
            fitted.push((kind, kept.clone()));
        }
        if named {
            test_scores.push((kind, after_tot.clone()));
        }
        results.push(EffectResult {
            kind,
            parameter: kind.parameter().into(),
            scope: kind.scope(),
            named,
            reduction: red,
            metric_after,
            noise_floor: floor,
            params,
            note,
        });
    }
    results.sort_by(|a, b| {
        (b.named, b.reduction.value).partial_cmp(&(a.named, a.reduction.value)).unwrap_or(std::cmp::Ordering::Equal)
    });
    let ranked: Vec<EffectKind> = results.iter().filter(|r| r.named).map(|r| r.kind).collect();

    // ---- Best combination: conditional forward selection. It starts from the best named effect; each step then
    // judges every candidate (any effect that cut some unit's own residual, named alone or not) against the
    // residual that REMAINS with the effects already in: the candidates' fits are evaluated on top of the
    // combination, the best few joint/group/global candidates are also refitted with the combination applied (an
    // effect fitted alone absorbs part of a confusable one on the same joints), and the winner must cut the
    // remaining held-out residual by more than that residual's own noise floor. A small effect beside a large one
    // (an IMU bias beside joint damping) is thus judged against what is left, not against the whole initial gap.
    let mut best_combination = None;
    let mut ranked = ranked;
    if !ranked.is_empty() {
        let get = |k: EffectKind| fitted.iter().find(|(f, _)| *f == k).map(|(_, e)| e.clone());
        let first = ranked[0];
        let mut combo = get(first).unwrap_or_else(|| null.clone());
        let mut members = vec![first];
        let mut cur: Vec<f64> =
            test_scores.iter().find(|(k, _)| *k == first).map(|(_, s)| s.clone()).unwrap_or_default();
        // Conditional results of the effects added after the first: (kind, gain, floor, metric after, refit params).
        let mut added: Vec<Conditional> = Vec::new();
        while members.len() < MAX_COMBINATION {
            let cands: Vec<EffectKind> = fitted.iter().map(|(k, _)| *k).filter(|k| !members.contains(k)).collect();
            if cands.is_empty() {
                break;
            }
            let mut trials: Vec<Effects> = cands
                .iter()
                .map(|&k| {
                    let mut t = combo.clone();
                    if let Some(fx) = get(k) {
                        k.copy(&fx, &mut t);
                    }
                    t
                })
                .collect();
            let res = ctx.eval_many(&trials, &ctx.test)?;
            let mut tots: Vec<Vec<f64>> = res.iter().map(|r| r.iter().map(|s| total(s)).collect()).collect();
            let mut refit_params: Vec<Option<Vec<FittedParam>>> = vec![None; cands.len()];
            // Refit the most promising non-IMU candidates given the combination (the IMU fits are closed-form on
            // their own channel and do not depend on it).
            let mut order: Vec<usize> = (0..cands.len()).filter(|&i| cands[i].scope() != Scope::Imu).collect();
            order.sort_by(|&x, &y| tots[x].iter().sum::<f64>().total_cmp(&tots[y].iter().sum::<f64>()));
            order.truncate(REFIT_CANDIDATES);
            if !order.is_empty() {
                let combo_train: Scores = ctx.eval_many(std::slice::from_ref(&combo), &ctx.train)?.remove(0);
                let mut refits = Vec::new();
                for &i in &order {
                    let kind = cands[i];
                    let (fx, sds) = fit_kind(&ctx, kind, &combo, &combo_train, &mut rng)?;
                    let mut t = combo.clone();
                    let mut params = Vec::new();
                    let (lo, hi, v0) = kind.range();
                    for (u, &sd) in sds.iter().enumerate().take(units_of(&ctx, kind).len()) {
                        let v = unit_value(kind, &fx, &ctx, u);
                        if (v - v0).abs() >= RESOLUTION_FRAC * (hi - lo) {
                            set_unit(kind, &mut t, &ctx, u, v);
                            params.push(FittedParam {
                                unit: unit_name(&ctx, kind, u),
                                value: report_value(kind, v),
                                sd: report_value(kind, sd),
                                held_out_reduction: 0.0,
                            });
                        }
                    }
                    if !params.is_empty() {
                        refits.push((i, t, params));
                    }
                }
                let cfgs: Vec<Effects> = refits.iter().map(|(_, t, _)| t.clone()).collect();
                let res = ctx.eval_many(&cfgs, &ctx.test)?;
                for ((i, t, params), r) in refits.into_iter().zip(res) {
                    let tot: Vec<f64> = r.iter().map(|s| total(s)).collect();
                    if tot.iter().sum::<f64>() < tots[i].iter().sum::<f64>() {
                        trials[i] = t;
                        tots[i] = tot;
                        refit_params[i] = Some(params);
                    }
                }
            }
            let Some((i, _)) =
                tots.iter().enumerate().min_by(|a, b| a.1.iter().sum::<f64>().total_cmp(&b.1.iter().sum::<f64>()))
            else {
                break;
            };
            let gain = bootstrap_ratio(&cur, &tots[i], opts.bootstrap, &mut rng);
            let floor = noise_floor(&cur);
            if gain.lo <= floor {
                break;
            }
            let per_window = (cur.iter().sum::<f64>() - tots[i].iter().sum::<f64>()) / cur.len().max(1) as f64;
            let params = refit_params[i].take().map(|mut ps| {
                ps.iter_mut().for_each(|p| p.held_out_reduction = per_window);
                ps
            });
            added.push((cands[i], gain, floor, bootstrap_mean(&tots[i], opts.bootstrap, &mut rng), params));
            combo = trials[i].clone();
            members.push(cands[i]);
            cur = tots[i].clone();
        }
        // Effects added conditionally are named with their conditional reduction and floor.
        let before: Vec<EffectKind> = members.clone();
        for (n, (kind, gain, floor, metric_after, params)) in added.into_iter().enumerate() {
            if let Some(r) = results.iter_mut().find(|r| r.kind == kind) {
                let given: Vec<&str> = before[..=n].iter().map(|k| k.name()).collect();
                r.named = true;
                r.reduction = gain;
                r.noise_floor = floor;
                r.metric_after = metric_after;
                if let Some(p) = params {
                    r.params = p;
                }
                r.note =
                    Some(format!("named given {}: reduction of the remaining held-out residual", given.join(" + ")));
            }
        }
        results.sort_by(|a, b| {
            (b.named, b.reduction.value).partial_cmp(&(a.named, a.reduction.value)).unwrap_or(std::cmp::Ordering::Equal)
        });
        let named: Vec<EffectKind> = results.iter().filter(|r| r.named).map(|r| r.kind).collect();
        let rest: Vec<EffectKind> = named.iter().copied().filter(|k| !members.contains(k)).collect();
        ranked = members.iter().copied().chain(rest).collect();
        best_combination = Some(Combination {
            effects: members,
            metric_after: bootstrap_mean(&cur, opts.bootstrap, &mut rng),
            reduction: bootstrap_ratio(&base_test_tot, &cur, opts.bootstrap, &mut rng),
        });
    }
    let abstentions: Vec<(EffectKind, String)> =
        results.iter().filter(|r| !r.named).map(|r| (r.kind, r.note.clone().unwrap_or_default())).collect();
    Ok(Report {
        schema_version: SCHEMA_VERSION.into(),
        outcome: Outcome::Diagnosed,
        rig_check: rig,
        plant,
        windows_unsettled,
        windows_down,
        robot: model.name.clone(),
        engine: opts.engine.name(),
        log_duration_s: log.duration(),
        windows_train: ctx.train.len(),
        windows_held_out: ctx.test.len(),
        window_s: len as f64 * dt_state,
        windows_skipped_fraction: skipped_fraction,
        baseline_metric,
        by_joint,
        by_group,
        by_phase,
        by_band,
        unexplained: ranked.is_empty(),
        effects: results,
        ranked,
        abstentions,
        best_combination,
        elapsed_s: t_start.elapsed().as_secs_f64(),
    })
}

/// The report of a log that fails the rig-assumption check: no window replayed, no effect fitted, every effect
/// abstained with the check's message.
fn rig_violated(
    model: &RobotModel,
    log: &RobotLog,
    opts: &DiagnoseOptions,
    rig: RigCheck,
    t_start: std::time::Instant,
) -> Report {
    let zero = Estimate { value: 0.0, lo: 0.0, hi: 0.0 };
    let why = format!("not diagnosed: {}", rig.message);
    let kinds: Vec<EffectKind> = opts.kinds.clone().unwrap_or_else(|| EffectKind::ALL.to_vec());
    let effects: Vec<EffectResult> = kinds
        .iter()
        .map(|&kind| EffectResult {
            kind,
            parameter: kind.parameter().into(),
            scope: kind.scope(),
            named: false,
            reduction: zero,
            metric_after: zero,
            noise_floor: 0.0,
            params: vec![],
            note: Some(why.clone()),
        })
        .collect();
    Report {
        schema_version: SCHEMA_VERSION.into(),
        outcome: Outcome::RigAssumptionViolated,
        rig_check: rig,
        plant: PlantKind::Rig,
        windows_unsettled: 0,
        windows_down: 0,
        robot: model.name.clone(),
        engine: opts.engine.name(),
        log_duration_s: log.duration(),
        windows_train: 0,
        windows_held_out: 0,
        window_s: opts.window_s,
        windows_skipped_fraction: 0.0,
        baseline_metric: zero,
        by_joint: vec![],
        by_group: vec![],
        by_phase: vec![],
        by_band: vec![],
        abstentions: kinds.iter().map(|&k| (k, why.clone())).collect(),
        effects,
        ranked: vec![],
        best_combination: None,
        unexplained: true,
        elapsed_s: t_start.elapsed().as_secs_f64(),
    }
}

/// An effect added to the best combination after the first: kind, conditional reduction, its noise floor, metric
/// after, refitted parameters.
type Conditional = (EffectKind, Estimate, f64, Estimate, Option<Vec<FittedParam>>);

/// A window is used only while the latest command is at most this old (s): the robot's command timeout (Unitree's
/// motors and `ulab sim` fall back to damping after about 0.1 s without a command).
pub const COMMAND_STALE_S: f64 = 0.1;

/// Largest spread (s) of a window's state log times around a regular grid at the median rate (see `diagnose`).
pub const TIMING_TOL_S: f64 = 0.005;
pub use crate::noise::{TIMING_HI, TIMING_LO};

/// A unit must cut its own held-out residual by at least this fraction (lower bound of the interval).
pub const UNIT_FLOOR_FRAC: f64 = 0.10;
/// An effect must cut the whole held-out gap by at least this fraction (lower bound of the interval).
pub const EFFECT_FLOOR_FRAC: f64 = 0.03;
/// At most this many effects in the best combination.
pub const MAX_COMBINATION: usize = 3;
/// Candidates refitted with the combination applied at each selection step (the best by their own fits).
pub const REFIT_CANDIDATES: usize = 2;
/// A fitted value closer to the no-effect value than this fraction of the search range is below resolution.
pub const RESOLUTION_FRAC: f64 = 0.04;

/// The relative noise floor of the whole-gap reduction: the larger of a fixed fraction and the relative spread
/// between the two halves of the held-out windows (how much the gap metric varies without any change).
fn noise_floor(base_tot: &[f64]) -> f64 {
    let n = base_tot.len();
    if n < 4 {
        return EFFECT_FLOOR_FRAC;
    }
    let even: Vec<f64> = base_tot.iter().step_by(2).copied().collect();
    let odd: Vec<f64> = base_tot.iter().skip(1).step_by(2).copied().collect();
    let (a, b) = (mean(&even), mean(&odd));
    let spread = ((a - b).abs() / (a + b).max(1e-300)) * 0.5;
    EFFECT_FLOOR_FRAC.max(spread.min(0.2) * 0.5)
}

/// Columns (score indices) of each fitting unit of `kind`.
fn units_of(ctx: &Ctx<'_>, kind: EffectKind) -> Vec<Vec<usize>> {
    let nj = ctx.nj();
    match kind.scope() {
        Scope::Global => vec![(0..=nj).collect()],
        Scope::Imu => vec![vec![nj]],
        Scope::Joint => (0..nj).map(|j| vec![j]).collect(),
        Scope::Group => (0..GROUPS.len()).map(|g| (0..nj).filter(|&j| ctx.groups[j] == g).collect()).collect(),
    }
}

fn unit_name(ctx: &Ctx<'_>, kind: EffectKind, u: usize) -> String {
    match kind.scope() {
        Scope::Global => "robot".into(),
        Scope::Imu => "imu".into(),
        Scope::Joint => ctx.model.joints[u].motor_name.clone(),
        Scope::Group => GROUPS[u].into(),
    }
}

/// Sets unit `u` of `kind` to `v` (IMU: `v` is unused, the closed form writes all three).
fn set_unit(kind: EffectKind, fx: &mut Effects, ctx: &Ctx<'_>, u: usize, v: f64) {
    match kind.scope() {
        Scope::Global => kind.set(fx, 0, v),
        Scope::Joint => kind.set(fx, u, v),
        Scope::Group => (0..ctx.nj()).filter(|&j| ctx.groups[j] == u).for_each(|j| kind.set(fx, j, v)),
        Scope::Imu => {}
    }
}

fn unit_value(kind: EffectKind, fx: &Effects, ctx: &Ctx<'_>, u: usize) -> f64 {
    match kind.scope() {
        Scope::Global | Scope::Imu => kind.get(fx, 0),
        Scope::Joint => kind.get(fx, u),
        Scope::Group => (0..ctx.nj()).find(|&j| ctx.groups[j] == u).map_or(kind.range().2, |j| kind.get(fx, j)),
    }
}

/// Parameter in report units (latency in ms).
fn report_value(kind: EffectKind, v: f64) -> f64 {
    if kind == EffectKind::Latency {
        v * DT * 1e3
    } else {
        v
    }
}

/// Fits one effect on the training windows; returns the configuration (every unit at its fitted value) and the
/// per-unit bootstrap standard deviation.
/// `base` holds effects already accepted (their units stay as they are) and `base_train` its training scores.
fn fit_kind(
    ctx: &Ctx<'_>,
    kind: EffectKind,
    base: &Effects,
    base_train: &Scores,
    rng: &mut impl Rng,
) -> Result<(Effects, Vec<f64>), GapError> {
    if kind.scope() == Scope::Imu {
        return fit_imu(ctx, kind);
    }
    let units = units_of(ctx, kind);
    let mut fx = base.clone();
    let mut sds = vec![0.0; units.len()];
    // Joint-scope effects are fitted on one joint per limb at a time (the k-th joint of every group together):
    // neighbouring joints of a chain would otherwise trade the effect between them.
    let sets: Vec<Vec<bool>> = if kind.scope() == Scope::Joint {
        let pos: Vec<usize> =
            (0..ctx.nj()).map(|j| (0..j).filter(|&i| ctx.groups[i] == ctx.groups[j]).count()).collect();
        let maxp = pos.iter().copied().max().unwrap_or(0);
        (0..=maxp).map(|k| pos.iter().map(|&p| p == k).collect()).collect()
    } else {
        vec![vec![true; units.len()]]
    };
    for mask in sets {
        let (vals, sd) = fit_units(ctx, kind, base, base_train, rng, &mask)?;
        for u in (0..units.len()).filter(|&u| mask[u]) {
            set_unit(kind, &mut fx, ctx, u, vals[u]);
            sds[u] = sd[u];
        }
    }
    Ok((fx, sds))
}

/// Grid search then lockstep golden-section refinement of the units in `mask` (the others stay at no effect);
/// returns every unit's value and bootstrap standard deviation.
fn fit_units(
    ctx: &Ctx<'_>,
    kind: EffectKind,
    base: &Effects,
    base_train: &Scores,
    rng: &mut impl Rng,
    mask: &[bool],
) -> Result<(Vec<f64>, Vec<f64>), GapError> {
    let null = base.clone();
    let units = units_of(ctx, kind);
    let (lo, hi, v0) = kind.range();
    let unit_score =
        |s: &Scores, u: usize| -> f64 { s.iter().map(|w| units[u].iter().map(|&c| w[c]).sum::<f64>()).sum() };
    let with_values = |vals: &[f64]| -> Effects {
        let mut fx = null.clone();
        for (u, &v) in vals.iter().enumerate() {
            if mask[u] {
                set_unit(kind, &mut fx, ctx, u, v);
            }
        }
        fx
    };
    // Grid (integers for latency).
    let grid: Vec<f64> = if kind == EffectKind::Latency {
        (0..=hi as usize).map(|k| k as f64).collect()
    } else {
        let n = 9;
        let mut g: Vec<f64> = (0..n).map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64).collect();
        g.push(v0);
        g.sort_by(f64::total_cmp);
        g.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
        g
    };
    let cfgs: Vec<Effects> =
        grid.iter().filter(|&&v| (v - v0).abs() > 1e-12).map(|&v| with_values(&vec![v; units.len()])).collect();
    let grid_nz: Vec<f64> = grid.iter().copied().filter(|&v| (v - v0).abs() > 1e-12).collect();
    let scores = ctx.eval_many(&cfgs, &ctx.train)?;
    let mut best = vec![(v0, f64::INFINITY); units.len()];
    for (u, b) in best.iter_mut().enumerate() {
        *b = (v0, unit_score(base_train, u));
        for (k, s) in scores.iter().enumerate() {
            let sc = unit_score(s, u);
            if sc < b.1 {
                *b = (grid_nz[k], sc);
            }
        }
    }
    if kind == EffectKind::Latency {
        return Ok((vec![best[0].0], vec![0.0]));
    }
    // Golden-section refinement of every unit in lockstep within the neighbouring grid cells.
    let step = grid.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    let mut a: Vec<f64> = best.iter().map(|b| (b.0 - step).max(lo)).collect();
    let mut b: Vec<f64> = best.iter().map(|b| (b.0 + step).min(hi)).collect();
    let gr = 0.618_033_988_749_895;
    let mut x1: Vec<f64> = (0..units.len()).map(|u| b[u] - gr * (b[u] - a[u])).collect();
    let mut x2: Vec<f64> = (0..units.len()).map(|u| a[u] + gr * (b[u] - a[u])).collect();
    let s12 = ctx.eval_many(&[with_values(&x1), with_values(&x2)], &ctx.train)?;
    let mut f1: Vec<f64> = (0..units.len()).map(|u| unit_score(&s12[0], u)).collect();
    let mut f2: Vec<f64> = (0..units.len()).map(|u| unit_score(&s12[1], u)).collect();
    for _ in 0..4 {
        // Each unit moves its own bracket; the new trial points are evaluated together.
        let mut trial = vec![0.0; units.len()];
        let mut left = vec![false; units.len()];
        for u in 0..units.len() {
            if f1[u] < f2[u] {
                b[u] = x2[u];
                x2[u] = x1[u];
                f2[u] = f1[u];
                x1[u] = b[u] - gr * (b[u] - a[u]);
                trial[u] = x1[u];
                left[u] = true;
            } else {
                a[u] = x1[u];
                x1[u] = x2[u];
                f1[u] = f2[u];
                x2[u] = a[u] + gr * (b[u] - a[u]);
                trial[u] = x2[u];
            }
        }
        let s = ctx.eval_many(&[with_values(&trial)], &ctx.train)?.remove(0);
        for u in 0..units.len() {
            let f = unit_score(&s, u);
            if left[u] {
                f1[u] = f;
            } else {
                f2[u] = f;
            }
        }
    }
    let mut vals = vec![0.0; units.len()];
    for u in 0..units.len() {
        let (xr, fr) = if f1[u] < f2[u] { (x1[u], f1[u]) } else { (x2[u], f2[u]) };
        vals[u] = if fr < best[u].1 { xr } else { best[u].0 };
    }
    // Uncertainty: a parabola through (v-h, v, v+h) on bootstrap resamples of the training windows.
    let h = 0.05 * (hi - lo);
    let minus: Vec<f64> = vals.iter().map(|v| v - h).collect();
    let plus: Vec<f64> = vals.iter().map(|v| v + h).collect();
    let s3 = ctx.eval_many(&[with_values(&minus), with_values(&vals), with_values(&plus)], &ctx.train)?;
    let nwin = ctx.train.len();
    let mut sds = vec![0.0; units.len()];
    for u in 0..units.len() {
        let per: Vec<[f64; 3]> = (0..nwin)
            .map(|w| {
                let f = |s: &Scores| units[u].iter().map(|&c| s[w][c]).sum::<f64>();
                [f(&s3[0]), f(&s3[1]), f(&s3[2])]
            })
            .collect();
        let mut vs = Vec::new();
        for _ in 0..50 {
            let mut acc = [0.0; 3];
            for _ in 0..nwin {
                let p = per[rng.gen_range(0..nwin)];
                (0..3).for_each(|k| acc[k] += p[k]);
            }
            let curv = acc[0] - 2.0 * acc[1] + acc[2];
            let shift =
                if curv > 0.0 { (h * (acc[0] - acc[2]) / (2.0 * curv)).clamp(-3.0 * h, 3.0 * h) } else { 3.0 * h };
            vs.push(vals[u] + shift);
        }
        let m = mean(&vs);
        sds[u] = (vs.iter().map(|v| (v - m).powi(2)).sum::<f64>() / vs.len() as f64).sqrt();
    }
    Ok((vals, sds))
}

/// IMU bias or misalignment in closed form: the mean residual on the training windows (rig: the reading predicted
/// from the logged joints; floating base: the no-effect window prediction, whose base state is estimated from the
/// IMU itself, so the residual grows from zero at the window start and the fit is conservative).
fn fit_imu(ctx: &Ctx<'_>, kind: EffectKind) -> Result<(Effects, Vec<f64>), GapError> {
    let null = Effects::none(ctx.nj());
    let mut acc = Vec::new();
    let mut floating_plant = match ctx.plant {
        PlantKind::Floating => Some(Plant::new(PlantKind::Floating, ctx.model, &ctx.opts.engine, &null)?),
        PlantKind::Rig => None,
    };
    for &w in &ctx.train {
        let start = ctx.starts[w];
        let pred = match floating_plant.as_mut() {
            Some(p) => Some(p.predict(ctx.model, ctx.feet.as_ref(), ctx.log, &null, start, ctx.len, true)?),
            None => None,
        };
        for k in (1..=ctx.len).step_by(IMU_STRIDE) {
            let Some(m) = ctx.log.states.get(start + k) else { break };
            let (quat, gyro) = match pred.as_ref().and_then(|p| p.get(k - 1)) {
                Some(p) => (p.quat, p.gyro),
                None if pred.is_some() => break,
                None => imu_reading(ctx.model, &m.q, &m.dq, &null)?,
            };
            acc.push(match kind {
                EffectKind::ImuBias => [m.gyro[0] - gyro[0], m.gyro[1] - gyro[1], m.gyro[2] - gyro[2]],
                _ => rot_residual(&m.quat, &quat),
            });
        }
    }
    let n = acc.len().max(1) as f64;
    let mut fx = null.clone();
    let mut sds = Vec::new();
    for k in 0..3 {
        let m = acc.iter().map(|a| a[k]).sum::<f64>() / n;
        kind.set(&mut fx, k, m);
        let var = acc.iter().map(|a| (a[k] - m).powi(2)).sum::<f64>() / n;
        // Samples within a window are correlated: count windows, not samples.
        sds.push((var / ctx.train.len().max(1) as f64).sqrt());
    }
    let sd = sds.iter().map(|s| s * s).sum::<f64>().sqrt();
    Ok((fx, vec![sd]))
}
