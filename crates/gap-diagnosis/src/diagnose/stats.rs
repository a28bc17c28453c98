//! Means, bootstrap intervals and the noise floor: the leaf of the pipeline. It knows nothing of plants or effects,
//! so every stage can share it; the draws it takes from the one RNG are what the report snapshots pin, so callers
//! must keep calling it in the same order.
use rand::Rng;
use serde::{Deserialize, Serialize};

/// An effect must cut the whole held-out gap by at least this fraction (lower bound of the interval).
pub const EFFECT_FLOOR_FRAC: f64 = 0.03;

/// A value with a 95 % interval.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct Estimate {
    pub value: f64,
    pub lo: f64,
    pub hi: f64,
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

/// The median (0 for no values).
pub(super) fn median(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let mut v = x.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Percentile interval of the mean by resampling `x` with replacement.
pub(super) fn bootstrap_mean(x: &[f64], b: usize, rng: &mut impl Rng) -> Estimate {
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

/// The relative noise floor of the whole-gap reduction: the larger of a fixed fraction and the relative spread
/// between the two halves of the held-out windows (how much the gap metric varies without any change).
pub(super) fn noise_floor(base_tot: &[f64]) -> f64 {
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
