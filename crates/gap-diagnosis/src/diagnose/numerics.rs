//! The diagnosing simulator's own numerics (issue 14 item 5): how far the prediction moves when only MuJoCo's
//! integrator, the physics timestep or the PD rate changes, and whether one of those explains the log better. A
//! gap between two simulators (or a simulator and a robot) of the size such a choice alone makes is numerics, not
//! evidence of a physical effect; a variant that cuts the held-out gap says part of the baseline is a numerics
//! mismatch, and which setting it lies in. Reporting only: effects are fitted and judged against the diagnosing
//! settings. The timestep and PD-rate variants are the rig's (the floating plant takes one 2 ms step).
use super::options::{DiagnoseOptions, PlantKind};
use super::replay::Ctx;
use super::stats::{bootstrap_ratio, mean, noise_floor, total, Estimate};
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
    /// Held-out gap metric of the log against this variant.
    pub held_out_gap: f64,
    /// Relative reduction of the held-out gap against the diagnosing simulator's, with a paired bootstrap interval
    /// over windows (negative: this variant fits the log worse).
    pub reduction: Estimate,
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
    /// The relative noise floor of the held-out gap: a variant cutting the gap by more is reported as a numerics
    /// mismatch.
    pub noise_floor: f64,
}

impl Numerics {
    /// The variant that cuts the held-out gap most, when its cut's lower bound clears the noise floor (the test an
    /// effect must pass to be named).
    pub fn better_variant(&self) -> Option<&NumericsVariant> {
        self.variants
            .iter()
            .filter(|v| v.reduction.lo > self.noise_floor)
            .max_by(|a, b| a.reduction.value.total_cmp(&b.reduction.value))
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

/// Replays the held-out windows with every other MuJoCo integrator and, on the rig, every other stepping (`None`
/// for an engine other than MuJoCo, or no held-out window). `baseline_tot`: the diagnosing simulator's held-out
/// gap per window.
pub(super) fn numerics(ctx: &Ctx<'_>, baseline_tot: &[f64], rng: &mut impl Rng) -> Result<Option<Numerics>, GapError> {
    let EngineChoice::Mujoco { integrator } = &ctx.opts.engine else { return Ok(None) };
    if ctx.test.is_empty() {
        return Ok(None);
    }
    let none = Effects::none(ctx.nj());
    let base_pred = ctx.predictions(&none, &ctx.test)?;
    let base_gap = mean(baseline_tot);
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
        let pred = alt.predictions(&none, &ctx.test)?;
        let shift = mean(
            &base_pred
                .iter()
                .zip(&pred)
                .map(|(a, b)| ctx.difference_scores(a, b).iter().take(ctx.nj()).sum::<f64>())
                .collect::<Vec<f64>>(),
        );
        // The gap from the same replay (scoring a prediction is what `eval_many` does after replaying it).
        let alt_tot: Vec<f64> = ctx
            .test
            .iter()
            .zip(&pred)
            .map(|(&w, p)| alt.prediction_scores(&none, w, p).map(|s| total(&s)))
            .collect::<Result<_, _>>()?;
        variants.push(NumericsVariant {
            engine: opts.engine.name(),
            timestep_ms: 1e3 * opts.stepping.timestep(),
            pd_period_ms: 1e3 * opts.stepping.pd_period(),
            held_out_gap: mean(&alt_tot),
            reduction: bootstrap_ratio(baseline_tot, &alt_tot, ctx.opts.bootstrap, rng),
            prediction_shift: shift,
        });
    }
    let mut n = Numerics {
        engine: ctx.opts.engine.name(),
        timestep_ms: 1e3 * ctx.opts.stepping.timestep(),
        pd_period_ms: 1e3 * ctx.opts.stepping.pd_period(),
        variants,
        shift_share_of_baseline: 0.0,
        noise_floor: noise_floor(baseline_tot),
    };
    n.shift_share_of_baseline = if base_gap > 0.0 { n.largest_shift() / base_gap } else { 0.0 };
    Ok(Some(n))
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
            held_out_gap: 0.0,
            reduction,
            prediction_shift: shift,
        }
    }

    #[test]
    fn only_a_variant_whose_cut_clears_the_floor_is_a_numerics_mismatch() {
        let n = Numerics {
            engine: "mujoco".into(),
            timestep_ms: 2.0,
            pd_period_ms: 2.0,
            // A 6 % cut whose interval reaches 1 %, and a variant that fits worse.
            variants: vec![variant("mujoco-rk4", 0.06, 0.01, 0.5), variant("mujoco-euler", -0.3, -0.5, 2.0)],
            shift_share_of_baseline: 0.1,
            noise_floor: 0.03,
        };
        assert!(n.better_variant().is_none());
        assert_eq!(n.largest_shift(), 2.0);
        assert_eq!(n.largest_shift_variant().map(|v| v.engine.as_str()), Some("mujoco-euler"));
        // The larger cut wins only if it clears the floor.
        let n = Numerics {
            variants: vec![variant("mujoco-rk4", 0.4, 0.3, 0.5), variant("mujoco-implicit", 0.5, 0.02, 0.2)],
            ..n
        };
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
            held_out_gap: 0.0,
            reduction: Estimate { value: 0.0, lo: 0.0, hi: 0.0 },
            prediction_shift: 0.0,
        };
        assert_eq!(v("mujoco-rk4", 2.0, 2.0).diagnose_flags(), "--engine mujoco-rk4");
        assert_eq!(v("mujoco", 1.0, 1.0).diagnose_flags(), "--engine mujoco --substeps 2");
        assert_eq!(v("mujoco", 1.0, 2.0).diagnose_flags(), "--engine mujoco --substeps 2 --pd-held");
    }
}
