//! The diagnosing simulator's own numerics, settled before anything is attributed: how the log is replayed is not
//! a physical effect. The log may have been made by a simulator with another integrator, a finer timestep or a faster
//! PD loop (a 1 kHz simulator, a robot whose drives close the loop faster), and then part of the gap is numerics.
//! Every variant (MuJoCo's other integrators; on the rig, 1 ms steps with the PD law held for 2 ms or run at each
//! step) replays every window without effects; the variant that fits the training windows best is adopted for the
//! rest of the diagnosis when it gains as much held-out evidence as a named effect must
//! ([`super::Thresholds::min_gain`]), and the report says so. The floating plant takes one 2 ms step (its integrators
//! only).
use super::options::{DiagnoseOptions, PlantKind};
use super::replay::Ctx;
use super::stats::{bootstrap_mean, bootstrap_ratio, log_gain, mean, total, Estimate};
use crate::log::Measurement;
use crate::plant::{Effects, EngineChoice, PdUpdate, Stepping, DT};
use crate::GapError;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// MuJoCo's integrators; every one but the diagnosing one is replayed (with the diagnosing stepping).
pub const INTEGRATORS: [&str; 4] = ["implicitfast", "implicit", "RK4", "Euler"];

/// The steppings replayed on the rig (with the diagnosing integrator), but the diagnosing one: one 2 ms step,
/// 1 ms steps with the PD law held for 2 ms (the timestep alone), 1 ms steps with the PD law at each (timestep and
/// PD rate, as a 1 kHz simulator runs).
pub const STEPPINGS: [Stepping; 3] = [
    Stepping::DIAGNOSING,
    Stepping { substeps: 2, pd: PdUpdate::PerControlStep },
    Stepping { substeps: 2, pd: PdUpdate::PerPhysicsStep },
];

/// The held-out windows replayed with another integrator or stepping, without effects.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct NumericsVariant {
    /// The engine, as `--engine` reads it (`mujoco-rk4`, ...).
    pub engine: String,
    /// Physics timestep (ms).
    pub timestep_ms: f64,
    /// How often the PD law is evaluated (ms).
    pub pd_period_ms: f64,
    /// Training gap metric (mean per window) of the log against this variant: what chooses it.
    #[serde(default)]
    pub train_gap: f64,
    /// Held-out gap metric of the log against this variant.
    pub held_out_gap: f64,
    /// Relative reduction of the held-out gap against the diagnosing simulator's, with a paired bootstrap interval
    /// over windows (negative: this variant fits the log worse).
    pub reduction: Estimate,
    /// Held-out log-likelihood gain per window against the diagnosing simulator's (what adopts it).
    #[serde(default = "Estimate::zero")]
    pub gain: Estimate,
    /// How far this variant's prediction moves from the diagnosing simulator's, in the gap metric's units (mean
    /// over held-out windows of the normalised squared difference, joints only).
    pub prediction_shift: f64,
}

impl NumericsVariant {
    /// `mujoco-rk4, 2 ms steps, PD every 2 ms`.
    pub fn label(&self) -> String {
        format!("{}, {} ms steps, PD every {} ms", self.engine, self.timestep_ms, self.pd_period_ms)
    }

    /// The `ulab gap diagnose` options that make this variant the diagnosing simulator.
    pub fn diagnose_flags(&self) -> String {
        let substeps = (1e3 * DT / self.timestep_ms).round().max(1.0);
        let mut flags = format!("--engine {}", self.engine);
        if substeps > 1.0 {
            flags += &format!(" --substeps {substeps}");
            if self.pd_period_ms > self.timestep_ms * 1.5 {
                flags += " --pd-held";
            }
        }
        flags
    }
}

/// What the integrator, timestep or PD-rate choice alone does to the prediction and to the gap.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Numerics {
    /// The diagnosing simulator's engine.
    pub engine: String,
    /// The diagnosing simulator's physics timestep (ms).
    pub timestep_ms: f64,
    /// The diagnosing simulator's PD period (ms).
    pub pd_period_ms: f64,
    pub variants: Vec<NumericsVariant>,
    /// The largest prediction shift, relative to the baseline held-out gap.
    pub shift_share_of_baseline: f64,
    /// The gain a variant's lower bound must reach to be adopted ([`super::Thresholds::min_gain`]).
    pub noise_floor: f64,
    /// Index into `variants` of the variant the diagnosis replayed the log with, if one was adopted.
    #[serde(default)]
    pub adopted: Option<usize>,
    /// What the stage concluded, in words.
    #[serde(default)]
    pub finding: String,
}

impl Numerics {
    /// The variant the diagnosis adopted, if one.
    pub fn better_variant(&self) -> Option<&NumericsVariant> {
        self.adopted.and_then(|i| self.variants.get(i))
    }

    /// The variant that moves the prediction most.
    pub fn largest_shift_variant(&self) -> Option<&NumericsVariant> {
        self.variants.iter().max_by(|a, b| a.prediction_shift.total_cmp(&b.prediction_shift))
    }

    /// The largest prediction shift (gap metric units).
    pub fn largest_shift(&self) -> f64 {
        self.variants.iter().map(|v| v.prediction_shift).fold(0.0, f64::max)
    }
}

/// Replays every window with every other MuJoCo integrator and, on the rig, every other stepping, and adopts the
/// variant that fits the training windows best when its held-out gain reaches `min_gain`: the report's numerics and the
/// options the rest of the diagnosis runs with (`None` for an engine other than MuJoCo, or no held-out window).
pub(super) fn choose(
    ctx: &Ctx<'_>,
    min_gain: f64,
    rng: &mut impl Rng,
) -> Result<Option<(Numerics, DiagnoseOptions)>, GapError> {
    let EngineChoice::Mujoco { integrator } = &ctx.opts.engine else { return Ok(None) };
    if ctx.test.is_empty() {
        return Ok(None);
    }
    let none = Effects::none(ctx.nj());
    let all: Vec<usize> = ctx.train.iter().chain(&ctx.test).copied().collect();
    let scores = |c: &Ctx<'_>, pred: &[Vec<Measurement>]| -> Result<Vec<Vec<f64>>, GapError> {
        all.iter().zip(pred).map(|(&w, p)| c.prediction_scores(&none, w, p)).collect()
    };
    let n_train = ctx.train.len();
    let totals = |s: &[Vec<f64>]| -> Vec<f64> { s.iter().map(|w| total(w)).collect() };
    let base_pred = ctx.predictions(&none, &all)?;
    let base_scores = scores(ctx, &base_pred)?;
    let (base_train, base_test) = (totals(&base_scores[..n_train]), totals(&base_scores[n_train..]));
    let base_gap = mean(&base_test);
    let mut others: Vec<DiagnoseOptions> = INTEGRATORS
        .iter()
        .filter(|i| !i.eq_ignore_ascii_case(integrator))
        .map(|other| DiagnoseOptions { engine: EngineChoice::mujoco(other), ..ctx.opts.clone() })
        .collect();
    if ctx.plant == PlantKind::Rig {
        others.extend(
            STEPPINGS
                .iter()
                .filter(|s| **s != ctx.opts.stepping)
                .map(|&stepping| DiagnoseOptions { stepping, ..ctx.opts.clone() }),
        );
    }
    let mut variants = Vec::new();
    for opts in &others {
        let alt = ctx.with_options(opts);
        let pred = alt.predictions(&none, &all)?;
        let shift = mean(
            &base_pred[n_train..]
                .iter()
                .zip(&pred[n_train..])
                .map(|(a, b)| ctx.difference_scores(a, b).iter().take(ctx.nj()).sum::<f64>())
                .collect::<Vec<f64>>(),
        );
        let alt_scores = scores(&alt, &pred)?;
        let (train, test) = (totals(&alt_scores[..n_train]), totals(&alt_scores[n_train..]));
        let gain = log_gain(&base_scores[n_train..], &alt_scores[n_train..], None, &ctx.noise);
        variants.push(NumericsVariant {
            engine: opts.engine.name(),
            timestep_ms: 1e3 * opts.stepping.timestep(),
            pd_period_ms: 1e3 * opts.stepping.pd_period(),
            train_gap: mean(&train),
            held_out_gap: mean(&test),
            reduction: bootstrap_ratio(&base_test, &test, ctx.opts.bootstrap, rng),
            gain: bootstrap_mean(&gain, ctx.opts.bootstrap, rng),
            prediction_shift: shift,
        });
    }
    let base_train_gap = mean(&base_train);
    let best = (0..variants.len())
        .filter(|&i| variants[i].train_gap < base_train_gap)
        .min_by(|&a, &b| variants[a].train_gap.total_cmp(&variants[b].train_gap));
    let adopted = best.filter(|&i| variants[i].gain.lo >= min_gain);
    let here = format!(
        "{}, {} ms steps, PD every {} ms",
        ctx.opts.engine.name(),
        1e3 * ctx.opts.stepping.timestep(),
        1e3 * ctx.opts.stepping.pd_period()
    );
    let finding = match (best, adopted) {
        (Some(i), Some(_)) => format!(
            "the log fits {} better than {here} (held-out log-likelihood gain {:.3} [{:.3}, {:.3}] per window, gap \
             cut {:.1} %): it was made with other numerics, and the diagnosis replays it so",
            variants[i].label(),
            variants[i].gain.value,
            variants[i].gain.lo,
            variants[i].gain.hi,
            100.0 * variants[i].reduction.value
        ),
        (Some(i), None) => format!(
            "{here} is kept: {} fits the training windows a little better but gains {:.3} [{:.3}, {:.3}] per \
             held-out window only",
            variants[i].label(),
            variants[i].gain.value,
            variants[i].gain.lo,
            variants[i].gain.hi
        ),
        (None, _) => format!("{here} fits the log best"),
    };
    let chosen = adopted.map_or_else(|| ctx.opts.clone(), |i| others[i].clone());
    let mut n = Numerics {
        engine: ctx.opts.engine.name(),
        timestep_ms: 1e3 * ctx.opts.stepping.timestep(),
        pd_period_ms: 1e3 * ctx.opts.stepping.pd_period(),
        variants,
        shift_share_of_baseline: 0.0,
        noise_floor: min_gain,
        adopted,
        finding,
    };
    n.shift_share_of_baseline = if base_gap > 0.0 { n.largest_shift() / base_gap } else { 0.0 };
    Ok(Some((n, chosen)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn variant(engine: &str, cut: f64, lo: f64, shift: f64) -> NumericsVariant {
        let reduction = Estimate { value: cut, lo, hi: cut + 0.1 };
        NumericsVariant {
            engine: engine.into(),
            timestep_ms: 2.0,
            pd_period_ms: 2.0,
            train_gap: 0.0,
            held_out_gap: 0.0,
            reduction,
            gain: reduction,
            prediction_shift: shift,
        }
    }

    #[test]
    fn the_adopted_variant_is_the_one_the_stage_chose_and_shifts_are_read_off_every_variant() {
        let n = Numerics {
            engine: "mujoco".into(),
            timestep_ms: 2.0,
            pd_period_ms: 2.0,
            variants: vec![variant("mujoco-rk4", 0.06, 0.01, 0.5), variant("mujoco-euler", -0.3, -0.5, 2.0)],
            shift_share_of_baseline: 0.1,
            noise_floor: 0.05,
            adopted: None,
            finding: String::new(),
        };
        assert!(n.better_variant().is_none());
        assert_eq!(n.largest_shift(), 2.0);
        assert_eq!(n.largest_shift_variant().map(|v| v.engine.as_str()), Some("mujoco-euler"));
        let n = Numerics { adopted: Some(0), ..n };
        assert_eq!(n.better_variant().map(|v| v.engine.as_str()), Some("mujoco-rk4"));
    }

    #[test]
    fn the_steppings_are_distinct_and_name_their_timestep_and_pd_period() {
        let ms: Vec<(f64, f64)> = STEPPINGS.iter().map(|s| (1e3 * s.timestep(), 1e3 * s.pd_period())).collect();
        assert_eq!(ms, vec![(2.0, 2.0), (1.0, 2.0), (1.0, 1.0)]);
        assert!(Stepping::new(0, PdUpdate::PerPhysicsStep).is_err());
        assert!(Stepping::new(65, PdUpdate::PerPhysicsStep).is_err());
        let v = |engine: &str, timestep_ms: f64, pd_period_ms: f64| NumericsVariant {
            engine: engine.into(),
            timestep_ms,
            pd_period_ms,
            train_gap: 0.0,
            held_out_gap: 0.0,
            reduction: Estimate::zero(),
            gain: Estimate::zero(),
            prediction_shift: 0.0,
        };
        assert_eq!(v("mujoco-rk4", 2.0, 2.0).diagnose_flags(), "--engine mujoco-rk4");
        assert_eq!(v("mujoco", 1.0, 1.0).diagnose_flags(), "--engine mujoco --substeps 2");
        assert_eq!(v("mujoco", 1.0, 2.0).diagnose_flags(), "--engine mujoco --substeps 2 --pd-held");
    }
}
