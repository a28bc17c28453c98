//! Means, medians, bootstrap intervals, log-likelihood gains and the noise level of a log's channels: the leaf of
//! the pipeline. It knows nothing of plants or effects, so every
//! stage can share it; the draws it takes from the one RNG fix the report, so callers keep calling it in the same
//! order.
use rand::Rng;
use serde::{Deserialize, Serialize};

/// The trimmed statistics drop this fraction of the held-out windows with the largest baseline residual.
pub const TRIM_FRAC: f64 = 0.1;

/// A value with a 95 % interval.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct Estimate {
    pub value: f64,
    pub lo: f64,
    pub hi: f64,
}

impl Estimate {
    /// No value and no spread (what a report of an older schema lacks).
    pub fn zero() -> Self {
        Estimate { value: 0.0, lo: 0.0, hi: 0.0 }
    }
}

/// The gap metric of one window: the sum of its column scores.
pub(super) fn total(s: &[f64]) -> f64 {
    s.iter().sum()
}

pub(super) fn mean(x: &[f64]) -> f64 {
    if x.is_empty() {
        0.0
    } else {
        x.iter().sum::<f64>() / x.len() as f64
    }
}

/// The median (0 for no values), by selection rather than a sort (the torque-lag search takes thousands of them).
pub(super) fn median(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let mut v = x.to_vec();
    let n = v.len();
    let (below, mid, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    let upper = *mid;
    if n % 2 == 1 {
        upper
    } else {
        0.5 * (below.iter().copied().fold(f64::NEG_INFINITY, f64::max) + upper)
    }
}

/// Percentile interval of the mean by resampling `x` with replacement.
pub(super) fn bootstrap_mean(x: &[f64], b: usize, rng: &mut impl Rng) -> Estimate {
    let v = mean(x);
    if x.len() < 2 {
        return Estimate { value: v, lo: v, hi: v };
    }
    let ms: Vec<f64> = (0..b)
        .map(|_| {
            let mut s = 0.0;
            for _ in 0..x.len() {
                s += x[rng.gen_range(0..x.len())];
            }
            s / x.len() as f64
        })
        .collect();
    percentile_interval(v, ms)
}

/// `value` with the 95 % percentile interval of its resampled `draws` (empty: no spread).
pub(super) fn percentile_interval(value: f64, mut draws: Vec<f64>) -> Estimate {
    if draws.is_empty() {
        return Estimate { value, lo: value, hi: value };
    }
    draws.sort_by(f64::total_cmp);
    let at = |p: f64| draws[((p * (draws.len() - 1) as f64).round() as usize).min(draws.len() - 1)];
    Estimate { value, lo: at(0.025), hi: at(0.975) }
}

/// Paired relative reduction `1 - mean(after)/mean(before)` with a bootstrap interval over windows.
pub(super) fn bootstrap_ratio(before: &[f64], after: &[f64], b: usize, rng: &mut impl Rng) -> Estimate {
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
    let ms: Vec<f64> = (0..b)
        .map(|_| {
            let idx: Vec<usize> = (0..n).map(|_| rng.gen_range(0..n)).collect();
            r(&mut idx.into_iter())
        })
        .collect();
    percentile_interval(v, ms)
}

/// Gap metric of sensor noise alone, per joint column, from the logged states: per channel, the noise standard
/// deviation estimated from the median absolute second difference of its samples (white noise of deviation σ gives
/// second differences of deviation √6 σ, whose median absolute value is 0.6745 times that; smooth motion hardly
/// contributes at the log's rate, and the median ignores the jumps of torque when a new command arrives).
pub(super) fn noise_per_joint(model: &robot_model::RobotModel, states: &[crate::log::Measurement]) -> Vec<f64> {
    if states.len() < 3 {
        return vec![0.0; model.nj()];
    }
    let var = |f: &dyn Fn(usize) -> f64| -> f64 {
        let d: Vec<f64> = (1..states.len() - 1).map(|k| (f(k + 1) - 2.0 * f(k) + f(k - 1)).abs()).collect();
        let sigma = median(&d) / (0.674_489_75 * 6f64.sqrt());
        sigma * sigma
    };
    let at = |v: &[f64], j: usize| v.get(j).copied().unwrap_or(0.0);
    model
        .joints
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            let sigma_tau = crate::noise::SIGMA_TAU_FRAC * joint.torque_limit.max(1.0);
            let vq = var(&|k| at(&states[k].q, j)) / (crate::noise::SIGMA_Q * crate::noise::SIGMA_Q);
            let vdq = var(&|k| at(&states[k].dq, j)) / (crate::noise::SIGMA_DQ * crate::noise::SIGMA_DQ);
            let vt = var(&|k| at(&states[k].tau, j)) / (sigma_tau * sigma_tau);
            (vq + vdq + vt) / 3.0
        })
        .collect()
}

/// Per window, the held-out log-likelihood gain of `after` over `before` (both per window and column) on `cols`
/// (all columns: `None`): `Σ_c ln((before + ν_c) / (after + ν_c))`. A window's column score is a mean squared
/// residual, and with each column of each window given its own unknown variance, the Gaussian log-likelihood is
/// `−(n/2) Σ ln(score)` up to constants: a window or a column whose residual is large for other reasons (a joint at
/// its limit, another engine's model of it) weighs no more than any other, and an effect local to a few joints is not
/// diluted by the rest of the robot. `ν_c` (the sensor noise's score, at least [`SCORE_FLOOR`]) is what no model can
/// remove, so a column already at noise gains nothing. Reported per window in nats without the factor `n/2`.
pub(super) fn log_gain(before: &[Vec<f64>], after: &[Vec<f64>], cols: Option<&[usize]>, nu: &[f64]) -> Vec<f64> {
    before
        .iter()
        .zip(after)
        .map(|(b, a)| {
            let term = |c: usize| -> f64 {
                let n = nu.get(c).copied().unwrap_or(SCORE_FLOOR).max(SCORE_FLOOR);
                match (b.get(c), a.get(c)) {
                    (Some(&x), Some(&y)) => ((x + n) / (y + n)).ln(),
                    _ => 0.0,
                }
            };
            match cols {
                Some(cs) => cs.iter().map(|&c| term(c)).sum(),
                None => (0..b.len()).map(term).sum(),
            }
        })
        .collect()
}

/// The smallest noise score of a column: a hundredth of one residual scale (0.2 mrad, 0.01 rad/s, 0.1 % of the
/// torque limit), far below any effect of interest, so that a noise-free log does not make tiny residuals count.
pub const SCORE_FLOOR: f64 = 0.01;

/// The windows by decreasing `before` and how many of the first the trimmed statistics drop ([`TRIM_FRAC`]): the
/// one rule for the trimmed naming test here and the trimmed mean of "What is left".
pub(super) fn trim_order(before: &[f64]) -> (Vec<usize>, usize) {
    let mut order: Vec<usize> = (0..before.len()).collect();
    order.sort_by(|&a, &b| before[b].total_cmp(&before[a]));
    let n_trim = (before.len() as f64 * TRIM_FRAC).floor() as usize;
    (order, n_trim)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn the_ratio_interval_holds_its_value_and_narrows_with_agreeing_windows() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let before: Vec<f64> = (0..40).map(|i| 10.0 + (i % 4) as f64).collect();
        let after: Vec<f64> = before.iter().map(|b| 0.6 * b).collect();
        let r = bootstrap_ratio(&before, &after, 500, &mut rng);
        assert!((r.value - 0.4).abs() < 1e-12 && (r.lo - 0.4).abs() < 1e-9 && (r.hi - 0.4).abs() < 1e-9, "{r:?}");
        let noisy: Vec<f64> = before.iter().enumerate().map(|(i, b)| b * if i % 2 == 0 { 0.3 } else { 0.9 }).collect();
        let r = bootstrap_ratio(&before, &noisy, 500, &mut rng);
        assert!(r.lo < r.value && r.value < r.hi, "{r:?}");
    }

    #[test]
    fn the_log_gain_counts_a_local_cut_fully_and_noise_not_at_all() {
        // Two columns: the first halved in every window, the second (ten times larger) unchanged.
        let before = vec![vec![1.0, 10.0]; 4];
        let after = vec![vec![0.5, 10.0]; 4];
        let nu = [0.0, 0.0];
        let g = log_gain(&before, &after, None, &nu);
        assert!(g.iter().all(|x| (x - (1.01_f64 / 0.51).ln()).abs() < 1e-12), "{g:?}");
        assert_eq!(log_gain(&before, &after, Some(&[1]), &nu), vec![0.0; 4]);
        // A column at the noise level gains little when its residual falls further.
        let g = log_gain(&[vec![0.2]], &[vec![0.1]], None, &[1.0]);
        assert!((g[0] - (1.2_f64 / 1.1).ln()).abs() < 1e-12, "{g:?}");
    }

    #[test]
    fn the_median_of_odd_and_even_counts() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&[]), 0.0);
    }

    #[test]
    fn the_trim_order_puts_the_largest_windows_first() {
        let (order, n) = trim_order(&[1.0, 9.0, 3.0, 7.0, 2.0, 4.0, 5.0, 6.0, 8.0, 0.5, 10.0]);
        assert_eq!((&order[..3], n), (&[10, 1, 8][..], 1));
    }
}
