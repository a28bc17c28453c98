//! What is left after the best combination: every window's residual before and after it, flagged by what the
//! motion did in it (torque at its limit, a joint at its range, a fast transient), robust statistics of the
//! held-out gap that a few such windows cannot swamp (median, trimmed mean, with the trimmed windows counted), and
//! the residual no named effect explains, with where it lies (by joint) against the noise floor. Reporting only:
//! nothing here changes which effects are named.
use super::breakdown::{Baseline, Share};
use super::replay::{Ctx, Scores};
use super::stats::{mean, median, total, trim_order};
use crate::log::Measurement;
use crate::plant::Effects;
use crate::GapError;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};

/// A torque within this fraction of its limit counts as saturated.
pub const SATURATED_FRAC: f64 = 0.95;
/// A joint faster than this fraction of its speed limit counts as a fast transient.
pub const FAST_FRAC: f64 = 0.5;
/// A remaining residual more than this many times the log's own sensor-noise level is reported as unexplained.
pub const UNEXPLAINED_FACTOR: f64 = 2.0;

/// Why a window may be dominated by what the library does not model well.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WindowFlag {
    /// A logged motor torque within [`SATURATED_FRAC`] of its limit.
    Saturated,
    /// A logged joint angle within [`crate::diagnose::AT_LIMIT_RAD`] of its range.
    AtLimit,
    /// A logged joint speed above [`FAST_FRAC`] of its speed limit.
    FastTransient,
}

/// One window's gap metric before and after the best combination.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct WindowResidual {
    /// Log time of the window's first state (s).
    pub t: f64,
    pub held_out: bool,
    /// Gap metric without effects.
    pub baseline: f64,
    /// Gap metric with the best combination (= baseline when nothing was named).
    pub after: f64,
    pub flags: Vec<WindowFlag>,
    /// Joint with the largest baseline residual in the window.
    pub worst_joint: String,
}

/// Held-out gap statistics that a few windows cannot dominate.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct RobustGap {
    pub median_baseline: f64,
    pub median_after: f64,
    /// Median over held-out windows of each window's own relative reduction.
    pub median_window_reduction: f64,
    pub trimmed_mean_baseline: f64,
    pub trimmed_mean_after: f64,
    /// Held-out windows dropped from the trimmed means (the largest baselines), and how many of them carry a flag.
    pub trimmed_windows: usize,
    pub trimmed_flagged: usize,
    /// Relative reduction of the plain mean (what the ranking uses) and of the trimmed mean.
    pub mean_reduction: f64,
    pub trimmed_reduction: f64,
    /// Held-out windows per flag.
    pub flagged: Vec<(WindowFlag, usize)>,
}

/// The residual that the named effects leave.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Unexplained {
    /// Held-out gap metric after the best combination (the baseline when nothing was named).
    pub metric_after: f64,
    /// The gap metric that the log's sensor noise alone would leave: the noise of each joint's angle, speed and
    /// torque estimated from the log itself (median absolute second difference of its samples).
    pub noise_metric: f64,
    /// Fraction of the held-out baseline gap that remains.
    pub fraction_of_baseline: f64,
    /// Whether what remains exceeds [`UNEXPLAINED_FACTOR`] times the noise metric: then part of the gap is explained
    /// by no named effect (a model mismatch, an effect outside the library, or the simulators' numerics).
    pub significant: bool,
    /// Where the remaining held-out residual lies, largest first (joints and the IMU).
    pub by_joint: Vec<Share>,
}

/// The remainder stage's results.
pub(super) struct Remainder {
    pub windows: Vec<WindowResidual>,
    pub robust: RobustGap,
    pub unexplained: Unexplained,
}

fn ratio_reduction(before: f64, after: f64) -> f64 {
    if before > 0.0 {
        1.0 - after / before
    } else {
        0.0
    }
}

/// Flags of a window from its logged states.
fn flags(model: &RobotModel, states: &[Measurement]) -> Vec<WindowFlag> {
    let (mut sat, mut fast) = (false, false);
    for m in states {
        for (j, joint) in model.joints.iter().enumerate() {
            let (Some(&dq), Some(&tau)) = (m.dq.get(j), m.tau.get(j)) else { continue };
            sat |= joint.torque_limit > 0.0 && tau.abs() >= SATURATED_FRAC * joint.torque_limit;
            fast |= joint.speed_limit > 0.0 && dq.abs() > FAST_FRAC * joint.speed_limit;
        }
    }
    let lim = super::windows::joints_at_limit(model, states).iter().any(|&x| x);
    [(sat, WindowFlag::Saturated), (lim, WindowFlag::AtLimit), (fast, WindowFlag::FastTransient)]
        .into_iter()
        .filter_map(|(on, f)| on.then_some(f))
        .collect()
}

/// Replays every window with the best combination `combo` (None: nothing named) and summarises what is left.
pub(super) fn remainder(
    ctx: &Ctx<'_>,
    baseline_scores: &Scores,
    baseline: &Baseline,
    combo: Option<&Effects>,
) -> Result<Remainder, GapError> {
    let all: Vec<usize> = (0..ctx.starts.len()).collect();
    let after_scores: Scores = match combo {
        Some(fx) => ctx.eval_many(std::slice::from_ref(fx), &all)?.remove(0),
        None => baseline_scores.clone(),
    };
    let nj = ctx.nj();
    let column_name = |c: usize| if c < nj { ctx.model.joints[c].motor_name.clone() } else { "imu".to_string() };
    let windows: Vec<WindowResidual> = all
        .iter()
        .map(|&w| {
            let b = &baseline_scores[w];
            let worst = (0..b.len()).max_by(|&x, &y| b[x].total_cmp(&b[y])).unwrap_or(0);
            WindowResidual {
                t: ctx.log.states.get(ctx.starts[w]).map_or(0.0, |m| m.t),
                held_out: ctx.test.contains(&w),
                baseline: total(b),
                after: total(&after_scores[w]),
                flags: flags(ctx.model, ctx.window_states(w)),
                worst_joint: column_name(worst),
            }
        })
        .collect();
    let held: Vec<&WindowResidual> = ctx.test.iter().filter_map(|&w| windows.get(w)).collect();
    let before: Vec<f64> = held.iter().map(|w| w.baseline).collect();
    let after: Vec<f64> = held.iter().map(|w| w.after).collect();
    // Trim the windows with the largest baseline residual.
    let (order, n_trim) = trim_order(&before);
    let kept = &order[n_trim.min(order.len())..];
    let tmean =
        |x: &[f64]| if kept.is_empty() { 0.0 } else { kept.iter().map(|&i| x[i]).sum::<f64>() / kept.len() as f64 };
    let per_window: Vec<f64> = before.iter().zip(&after).map(|(&b, &a)| ratio_reduction(b, a)).collect();
    let count = |f: WindowFlag| held.iter().filter(|w| w.flags.contains(&f)).count();
    let robust = RobustGap {
        median_baseline: median(&before),
        median_after: median(&after),
        median_window_reduction: median(&per_window),
        trimmed_mean_baseline: tmean(&before),
        trimmed_mean_after: tmean(&after),
        trimmed_windows: n_trim,
        trimmed_flagged: order[..n_trim.min(order.len())].iter().filter(|&&i| !held[i].flags.is_empty()).count(),
        mean_reduction: ratio_reduction(mean(&before), mean(&after)),
        trimmed_reduction: ratio_reduction(tmean(&before), tmean(&after)),
        flagged: [WindowFlag::Saturated, WindowFlag::AtLimit, WindowFlag::FastTransient]
            .into_iter()
            .map(|f| (f, count(f)))
            .collect(),
    };
    // Where the held-out remainder lies, per column.
    let cols = nj + 1;
    let mut col = vec![0.0; cols];
    for &w in &ctx.test {
        for (c, v) in after_scores[w].iter().enumerate().take(cols) {
            col[c] += v / ctx.test.len().max(1) as f64;
        }
    }
    let sum: f64 = col.iter().sum();
    let mut by_joint: Vec<Share> = (0..cols)
        .map(|c| Share {
            name: column_name(c),
            residual: col[c],
            share: if sum > 0.0 { col[c] / sum } else { 0.0 },
            windows: ctx.test.len(),
        })
        .collect();
    by_joint.sort_by(|a, b| b.residual.total_cmp(&a.residual));
    by_joint.truncate(5);
    let noise: f64 = super::stats::noise_per_joint(ctx.model, &ctx.log.states).iter().sum();
    let metric_after = mean(&after);
    let unexplained = Unexplained {
        metric_after,
        noise_metric: noise,
        fraction_of_baseline: if baseline.metric.value > 0.0 { metric_after / baseline.metric.value } else { 0.0 },
        significant: metric_after > UNEXPLAINED_FACTOR * noise,
        by_joint,
    };
    Ok(Remainder { windows, robust, unexplained })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn model() -> RobotModel {
        robot_model::builtin("h1_2").expect("model")
    }

    fn still(model: &RobotModel, n: usize) -> Vec<Measurement> {
        crate::log::still_states(model, n)
    }

    #[test]
    fn flags_name_what_the_window_did() {
        let m = model();
        assert!(flags(&m, &still(&m, 50)).is_empty(), "a still robot at its default pose");
        let mut s = still(&m, 50);
        s[20].tau[3] = 0.97 * m.joints[3].torque_limit;
        assert_eq!(flags(&m, &s), vec![WindowFlag::Saturated]);
        let mut s = still(&m, 50);
        s[10].q[5] = m.joints[5].upper - 0.01;
        assert_eq!(flags(&m, &s), vec![WindowFlag::AtLimit]);
        let mut s = still(&m, 50);
        s[40].dq[0] = -0.6 * m.joints[0].speed_limit;
        assert_eq!(flags(&m, &s), vec![WindowFlag::FastTransient]);
    }

    /// White noise of known size on a smooth motion: the estimate recovers it (the motion's own second difference
    /// at 500 Hz is negligible), so "within noise" means what it says.
    #[test]
    fn noise_metric_recovers_white_noise_on_a_smooth_motion() {
        let m = model();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut s = still(&m, 5000);
        let sq = 1e-3;
        for (k, x) in s.iter_mut().enumerate() {
            let t = k as f64 * 0.002;
            for j in 0..m.nj() {
                // Box-Muller normal.
                let (u1, u2): (f64, f64) = (rng.gen_range(1e-12..1.0), rng.gen_range(0.0..1.0));
                let n = (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos();
                x.q[j] = 0.3 * (2.0 * std::f64::consts::PI * 0.5 * t).sin() + sq * n;
            }
        }
        let expect = m.nj() as f64 * (sq / crate::noise::SIGMA_Q).powi(2) / 3.0;
        let got: f64 = super::super::stats::noise_per_joint(&m, &s).iter().sum();
        assert!((got / expect - 1.0).abs() < 0.1, "noise metric {got}, expected {expect}");
    }
}
