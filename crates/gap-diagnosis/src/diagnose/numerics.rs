//! The diagnosing simulator's own numerics (issue 14 item 5): how far the prediction moves when only MuJoCo's
//! integrator changes, and whether another integrator explains the log better. A gap between two simulators (or a
//! simulator and a robot) of the size the integrator choice alone makes is numerics, not evidence of a physical
//! effect; an integrator that cuts the held-out gap says part of the baseline is a numerics mismatch. Reporting
//! only: effects are fitted and judged against the diagnosing integrator. The timestep and the PD rate are fixed
//! by the plants (2 ms, PD every step) and are not varied here.
use super::options::DiagnoseOptions;
use super::replay::Ctx;
use super::stats::{bootstrap_ratio, mean, noise_floor, total, Estimate};
use crate::plant::{Effects, EngineChoice};
use crate::GapError;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// MuJoCo's integrators; every one but the diagnosing one is replayed.
pub const INTEGRATORS: [&str; 4] = ["implicitfast", "implicit", "RK4", "Euler"];

/// The held-out windows replayed with another integrator, without effects.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct IntegratorVariant {
    /// The engine, as `--engine` reads it (`mujoco-rk4`, ...).
    pub engine: String,
    /// Held-out gap metric of the log against this variant.
    pub held_out_gap: f64,
    /// Relative reduction of the held-out gap against the diagnosing simulator's, with a paired bootstrap interval
    /// over windows (negative: this variant fits the log worse).
    pub reduction: Estimate,
    /// How far this variant's prediction moves from the diagnosing simulator's, in the gap metric's units (mean
    /// over held-out windows of the normalised squared difference, joints only).
    pub prediction_shift: f64,
}

/// What the integrator choice alone does to the prediction and to the gap.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Numerics {
    /// The diagnosing simulator's engine.
    pub engine: String,
    pub variants: Vec<IntegratorVariant>,
    /// The largest prediction shift, relative to the baseline held-out gap.
    pub shift_share_of_baseline: f64,
    /// The relative noise floor of the held-out gap: a variant cutting the gap by more is reported as a numerics
    /// mismatch.
    pub noise_floor: f64,
}

impl Numerics {
    /// The variant that cuts the held-out gap most, when its cut's lower bound clears the noise floor (the test an
    /// effect must pass to be named).
    pub fn better_variant(&self) -> Option<&IntegratorVariant> {
        self.variants
            .iter()
            .filter(|v| v.reduction.lo > self.noise_floor)
            .max_by(|a, b| a.reduction.value.total_cmp(&b.reduction.value))
    }

    /// The largest prediction shift (gap metric units).
    pub fn largest_shift(&self) -> f64 {
        self.variants.iter().map(|v| v.prediction_shift).fold(0.0, f64::max)
    }
}

/// Replays the held-out windows with every other MuJoCo integrator (`None` for an engine other than MuJoCo, or no
/// held-out window). `baseline_tot`: the diagnosing simulator's held-out gap per window.
pub(super) fn numerics(ctx: &Ctx<'_>, baseline_tot: &[f64], rng: &mut impl Rng) -> Result<Option<Numerics>, GapError> {
    let EngineChoice::Mujoco { integrator } = &ctx.opts.engine else { return Ok(None) };
    if ctx.test.is_empty() {
        return Ok(None);
    }
    let none = Effects::none(ctx.nj());
    let base_pred = ctx.predictions(&none, &ctx.test)?;
    let base_gap = mean(baseline_tot);
    let mut variants = Vec::new();
    for other in INTEGRATORS.iter().filter(|i| !i.eq_ignore_ascii_case(integrator)) {
        let opts = DiagnoseOptions { engine: EngineChoice::mujoco(other), ..ctx.opts.clone() };
        let alt = ctx.with_options(&opts);
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
        variants.push(IntegratorVariant {
            engine: opts.engine.name(),
            held_out_gap: mean(&alt_tot),
            reduction: bootstrap_ratio(baseline_tot, &alt_tot, ctx.opts.bootstrap, rng),
            prediction_shift: shift,
        });
    }
    let mut n = Numerics {
        engine: ctx.opts.engine.name(),
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

    fn variant(engine: &str, cut: f64, lo: f64, shift: f64) -> IntegratorVariant {
        let reduction = Estimate { value: cut, lo, hi: cut + 0.1 };
        IntegratorVariant { engine: engine.into(), held_out_gap: 0.0, reduction, prediction_shift: shift }
    }

    #[test]
    fn only_a_variant_whose_cut_clears_the_floor_is_a_numerics_mismatch() {
        let n = Numerics {
            engine: "mujoco".into(),
            // A 6 % cut whose interval reaches 1 %, and a variant that fits worse.
            variants: vec![variant("mujoco-rk4", 0.06, 0.01, 0.5), variant("mujoco-euler", -0.3, -0.5, 2.0)],
            shift_share_of_baseline: 0.1,
            noise_floor: 0.03,
        };
        assert!(n.better_variant().is_none());
        assert_eq!(n.largest_shift(), 2.0);
        // The larger cut wins only if it clears the floor.
        let n = Numerics {
            variants: vec![variant("mujoco-rk4", 0.4, 0.3, 0.5), variant("mujoco-implicit", 0.5, 0.02, 0.2)],
            ..n
        };
        assert_eq!(n.better_variant().map(|v| v.engine.as_str()), Some("mujoco-rk4"));
    }
}
