//! Replaying windows and scoring them: the engine every later stage calls. A window's score is its normalised
//! squared residual per column (joints, then the IMU); engines of the unmodified model are pooled because building
//! one costs far more than replaying a window.
use super::options::{DiagnoseOptions, PlantKind};
use super::windows::Windows;
use crate::floating::{self, Feet, FloatingPlant};
use crate::log::{Measurement, RobotLog};
use crate::plant::{imu_reading, joint_groups, predict_window, Effects, Rig, Stepping};
use crate::GapError;
use rayon::prelude::*;
use robot_model::RobotModel;

use crate::noise::{SIGMA_GYRO, SIGMA_QUAT};

/// Per-window scores: `[window][column]`, columns = joints then the IMU.
pub(super) type Scores = Vec<Vec<f64>>;

/// The engine that replays a window: on the rig, or on the ground.
pub(super) enum Plant {
    Rig(Rig),
    Floating(Box<FloatingPlant>),
}

impl Plant {
    /// A plant of `kind` for `model` (already carrying the model-level effects of `fx`; `fx` supplies the contact
    /// time constant of the floating plant), in the options' engine and stepping (the floating plant takes one
    /// step per control step only).
    pub(super) fn new(
        kind: PlantKind,
        model: &RobotModel,
        opts: &DiagnoseOptions,
        fx: &Effects,
    ) -> Result<Self, GapError> {
        Ok(match kind {
            PlantKind::Rig => Plant::Rig(Rig::new(model, &opts.engine, opts.stepping)?),
            PlantKind::Floating if opts.stepping != Stepping::DIAGNOSING => {
                return Err(GapError::Input(format!(
                    "the floating plant integrates one {} ms step per control step; other steppings are the rig's",
                    crate::plant::DT * 1e3
                )))
            }
            PlantKind::Floating => Plant::Floating(Box::new(FloatingPlant::new(model, &opts.engine, fx)?)),
        })
    }

    /// The window's predicted measurements ([`crate::plant::predict_window`] or [`floating::predict_window`]).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn predict(
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

/// What every stage after the windows shares: the inputs, the windows and the pooled engines.
pub(super) struct Ctx<'a> {
    pub model: &'a RobotModel,
    pub log: &'a RobotLog,
    pub opts: &'a DiagnoseOptions,
    pub plant: PlantKind,
    /// The feet (floating plant only).
    pub feet: Option<Feet>,
    /// State sample period of the log (median).
    pub dt_state: f64,
    pub starts: Vec<usize>,
    pub len: usize,
    pub train: Vec<usize>,
    pub test: Vec<usize>,
    /// Group index of each joint ([`crate::plant::GROUPS`]).
    pub groups: Vec<usize>,
    sigma_tau: Vec<f64>,
    /// Per score column, the score the log's sensor noise alone would leave (joints; the IMU's: 0).
    pub noise: Vec<f64>,
    null: Effects,
    /// Idle engines of the unmodified model.
    pool: std::sync::Mutex<Vec<Plant>>,
}

impl<'a> Ctx<'a> {
    /// The context of `windows` (their bookkeeping counts stay with the caller).
    pub(super) fn new(
        model: &'a RobotModel,
        log: &'a RobotLog,
        opts: &'a DiagnoseOptions,
        plant: PlantKind,
        windows: Windows,
    ) -> Self {
        Ctx {
            model,
            log,
            opts,
            plant,
            feet: windows.feet,
            dt_state: windows.dt_state,
            starts: windows.starts,
            len: windows.len,
            train: windows.train,
            test: windows.test,
            groups: joint_groups(model),
            sigma_tau: crate::noise::torque_scales(model),
            noise: super::stats::noise_per_joint(model, &log.states).into_iter().chain([0.0]).collect(),
            null: Effects::none(model.nj()),
            pool: std::sync::Mutex::new(Vec::new()),
        }
    }
}

impl<'a> Ctx<'a> {
    /// The same windows replayed under other options (another integrator: [`super::numerics`]), with its own pool.
    pub(super) fn with_options<'b>(&self, opts: &'b DiagnoseOptions) -> Ctx<'b>
    where
        'a: 'b,
    {
        self.rebind(self.log, opts)
    }

    /// The same windows of another version of the log (its commands moved in time: [`super::timing`]), with its own
    /// pool.
    pub(super) fn with_log<'b>(&self, log: &'b RobotLog) -> Ctx<'b>
    where
        'a: 'b,
    {
        self.rebind(log, self.opts)
    }

    fn rebind<'b>(&self, log: &'b RobotLog, opts: &'b DiagnoseOptions) -> Ctx<'b>
    where
        'a: 'b,
    {
        Ctx {
            model: self.model,
            log,
            opts,
            plant: self.plant,
            feet: self.feet.clone(),
            dt_state: self.dt_state,
            starts: self.starts.clone(),
            len: self.len,
            train: self.train.clone(),
            test: self.test.clone(),
            groups: self.groups.clone(),
            sigma_tau: self.sigma_tau.clone(),
            noise: self.noise.clone(),
            null: self.null.clone(),
            pool: std::sync::Mutex::new(Vec::new()),
        }
    }
}

impl Ctx<'_> {
    /// The logged states of window `w` (empty when there is no such window).
    pub(super) fn window_states(&self, w: usize) -> &[Measurement] {
        self.starts.get(w).map_or(&[], |&s| super::windows::window_states(self.log, s, self.len))
    }

    pub(super) fn nj(&self) -> usize {
        self.model.nj()
    }

    /// Scores of the given windows under each configuration (parallel over configurations × window chunks).
    pub(super) fn eval_many(&self, cfgs: &[Effects], windows: &[usize]) -> Result<Vec<Scores>, GapError> {
        self.per_window(cfgs, windows, |rig, model, fx, w| self.window_scores(rig, model, fx, w, None))
    }

    /// `f` on every window under every configuration, in parallel over configurations × chunks of windows, each
    /// chunk on one plant of its configuration's model; results per configuration in window order.
    fn per_window<T: Send>(
        &self,
        cfgs: &[Effects],
        windows: &[usize],
        f: impl Fn(&mut Plant, &RobotModel, &Effects, usize) -> Result<T, GapError> + Sync,
    ) -> Result<Vec<Vec<T>>, GapError> {
        let chunks = (rayon::current_num_threads() * 2).max(1);
        let per = windows.len().div_ceil(chunks).max(1);
        let jobs: Vec<(usize, &[usize])> =
            (0..cfgs.len()).flat_map(|c| windows.chunks(per).map(move |w| (c, w))).collect();
        let results: Vec<Result<(usize, Vec<T>), GapError>> = jobs
            .par_iter()
            .map(|(c, ws)| {
                let fx = &cfgs[*c];
                // Engines of the unmodified model are reused (building one costs far more than a window).
                let baseline_model = fx.same_model(&self.null);
                let model = if baseline_model { self.model.clone() } else { fx.apply_to_model(self.model) };
                let pooled = if baseline_model { self.pool.lock().ok().and_then(|mut p| p.pop()) } else { None };
                let mut rig = match pooled {
                    Some(r) => r,
                    None => Plant::new(self.plant, &model, self.opts, fx)?,
                };
                let mut out = Vec::with_capacity(ws.len());
                for &w in ws.iter() {
                    out.push(f(&mut rig, &model, fx, w)?);
                }
                if baseline_model {
                    if let Ok(mut p) = self.pool.lock() {
                        p.push(rig);
                    }
                }
                Ok((*c, out))
            })
            .collect();
        let mut all: Vec<Vec<T>> = (0..cfgs.len()).map(|_| Vec::new()).collect();
        for r in results {
            let (c, s) = r?;
            all[c].extend(s);
        }
        Ok(all)
    }

    /// Normalised squared residual of one window per column; `series` receives the q residual time series.
    pub(super) fn window_scores(
        &self,
        rig: &mut Plant,
        model: &RobotModel,
        fx: &Effects,
        w: usize,
        series: Option<&mut Vec<Vec<f64>>>,
    ) -> Result<Vec<f64>, GapError> {
        let start = self.starts[w];
        let floating = self.plant == PlantKind::Floating;
        let pred = rig.predict(model, self.feet.as_ref(), self.log, fx, start, self.len, floating)?;
        if let Some(out) = series {
            *out = (0..self.nj())
                .map(|j| pred.iter().enumerate().map(|(k, p)| self.log.states[start + 1 + k].q[j] - p.q[j]).collect())
                .collect();
        }
        self.prediction_scores(fx, w, &pred)
    }

    /// Normalised squared residual per column of window `w` against its prediction `pred` under `fx` (what
    /// [`Ctx::window_scores`] computes after replaying the window).
    pub(super) fn prediction_scores(&self, fx: &Effects, w: usize, pred: &[Measurement]) -> Result<Vec<f64>, GapError> {
        let nj = self.nj();
        let start = self.starts[w];
        let mut s = vec![0.0; nj + 1];
        for (k, p) in pred.iter().enumerate() {
            self.add_joint_terms(&self.log.states[start + 1 + k], p, &mut s);
        }
        let n = pred.len().max(1) as f64;
        s.iter_mut().take(nj).for_each(|x| *x /= n);
        s[nj] = if self.plant == PlantKind::Floating {
            floating_imu_score(self.log, start, pred)
        } else {
            self.imu_score(fx, w)?
        };
        Ok(s)
    }

    /// Adds one sample's normalised squared joint residual (position, velocity, torque, averaged) to `s[j]`.
    fn add_joint_terms(&self, m: &Measurement, p: &Measurement, s: &mut [f64]) {
        crate::noise::add_joint_terms(&self.sigma_tau, m, p, s);
    }

    /// Predicted measurements of `windows` under `fx` (parallel over chunks of windows).
    pub(super) fn predictions(&self, fx: &Effects, windows: &[usize]) -> Result<Vec<Vec<Measurement>>, GapError> {
        let floating = self.plant == PlantKind::Floating;
        let mut per_cfg = self.per_window(std::slice::from_ref(fx), windows, |rig, model, fx, w| {
            rig.predict(model, self.feet.as_ref(), self.log, fx, self.starts[w], self.len, floating)
        })?;
        Ok(per_cfg.pop().unwrap_or_default())
    }

    /// The joint columns of a window's score with prediction `b` in place of the log: how far two simulations of
    /// the same window move apart, in the gap metric's units (the IMU column is 0).
    pub(super) fn difference_scores(&self, a: &[Measurement], b: &[Measurement]) -> Vec<f64> {
        let mut s = vec![0.0; self.nj() + 1];
        for (m, p) in a.iter().zip(b) {
            self.add_joint_terms(m, p, &mut s);
        }
        let n = a.len().min(b.len()).max(1) as f64;
        s.iter_mut().take(self.nj()).for_each(|x| *x /= n);
        s
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
pub(super) const IMU_STRIDE: usize = 5;

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
pub(super) fn rot_residual(meas: &[f64; 4], pred: &[f64; 4]) -> [f64; 3] {
    let q = |a: &[f64; 4]| nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(a[0], a[1], a[2], a[3]));
    (q(pred).inverse() * q(meas)).scaled_axis().into()
}
