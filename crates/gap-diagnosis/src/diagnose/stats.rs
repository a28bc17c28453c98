//! Means, bootstrap intervals and the noise floor: the leaf of the pipeline. It knows nothing of plants or effects,
//! so every stage can share it; the draws it takes from the one RNG are what the report snapshots pin, so callers
//! must keep calling it in the same order.
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

/// An effect must cut the whole held-out gap by at least this fraction (lower bound of the interval).
pub const EFFECT_FLOOR_FRAC: f64 = 0.03;

/// The trimmed statistics drop this fraction of the held-out windows with the largest baseline residual.
pub const TRIM_FRAC: f64 = 0.1;

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

/// How a reduction of the held-out gap was judged against the noise floor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Judged {
    /// Relative reduction over every window, and the floor it had to clear.
    pub reduction: Estimate,
    pub floor: f64,
    /// Set when only the trimmed windows cleared: the relative reduction over the windows left after dropping the
    /// [`TRIM_FRAC`] with the largest gap before, and the floor there.
    pub trimmed: Option<(Estimate, f64)>,
    /// Set when only the windows in which no joint reaches a range limit cleared: the relative reduction there, the
    /// floor there and how many windows they are.
    pub off_limit: Option<(Estimate, f64, usize)>,
}

impl Judged {
    /// Cleared the floor on every window, on the trimmed ones or on those away from the range limits.
    pub fn clears(&self) -> bool {
        self.reduction.lo > self.floor || self.trimmed.is_some() || self.off_limit.is_some()
    }

    /// Cleared the floor only on part of the windows (the trimmed ones or those away from the range limits), not on
    /// every window.
    pub fn cleared_on_part_only(&self) -> bool {
        self.clears() && self.reduction.lo <= self.floor
    }

    /// Why it was named on part of the windows only (`None` when every window cleared, or nothing did).
    pub fn route_note(&self) -> Option<String> {
        if let Some((r, f)) = self.trimmed {
            return Some(format!(
                "named on the held-out windows without the {:.0} % with the largest gap (a few windows the library \
                 does not model, e.g. at a joint limit or in resonance, swamp the mean): reduction {:.3} (lower bound \
                 {:.3}) over the floor {:.3} there",
                TRIM_FRAC * 100.0,
                r.value,
                r.lo,
                f
            ));
        }
        let (r, f, n) = self.off_limit?;
        Some(format!(
            "named on the {n} held-out windows in which no joint reaches a range limit (simulators model the limits \
             differently, and the windows at a limit carry most of the gap): reduction {:.3} (lower bound {:.3}) \
             over the floor {:.3} there",
            r.value, r.lo, f
        ))
    }
}

/// The off-limit route needs at least this fraction of the held-out windows away from every range limit.
pub const MIN_OFF_LIMIT_FRAC: f64 = 0.25;

/// Seed of the off-limit route's own random numbers: it draws from its own stream, so that adding it left the draws
/// of every other test, and the reports of the logs on which it is never tried, as they were.
const OFF_LIMIT_STREAM: u64 = 0x6f66_665f_6c69_6d69;

/// Judges the reduction from `before` to `after` (held-out gap per window): its lower bound must clear the noise
/// floor over every window or, failing that, over the windows left after dropping the [`TRIM_FRAC`] with the
/// largest `before` (heavy-tailed residuals, issue 14 item 4: a few windows must not swamp an effect), or, failing
/// that, over the windows marked `off_limit` (no joint within [`super::AT_LIMIT_RAD`] of its range; at least
/// [`MIN_OFF_LIMIT_FRAC`] of them, and not all): in a log of another engine the windows at a range limit carry a
/// mismatch of the limit models that can swamp an effect both other tests see diluted. The trimmed test draws from
/// `rng` only when the first fails; the off-limit test never does.
pub(super) fn judge(before: &[f64], after: &[f64], off_limit: &[bool], b: usize, rng: &mut impl Rng) -> Judged {
    let reduction = bootstrap_ratio(before, after, b, rng);
    let floor = noise_floor(before);
    let mut judged = Judged { reduction, floor, trimmed: None, off_limit: None };
    if reduction.lo > floor {
        return judged;
    }
    let (tb, ta) = trimmed(before, after);
    let tr = bootstrap_ratio(&tb, &ta, b, rng);
    let tf = noise_floor(&tb);
    if tr.lo > tf && tr.value > 0.0 {
        judged.trimmed = Some((tr, tf));
        return judged;
    }
    let n = before.len().min(after.len());
    let free: Vec<usize> = (0..n).filter(|&i| off_limit.get(i).copied().unwrap_or(false)).collect();
    if free.len() == n || (free.len() as f64) < MIN_OFF_LIMIT_FRAC * n as f64 || free.len() < 4 {
        return judged;
    }
    let (fb, fa): (Vec<f64>, Vec<f64>) = free.iter().map(|&i| (before[i], after[i])).unzip();
    let mut own = rand_chacha::ChaCha8Rng::seed_from_u64(OFF_LIMIT_STREAM);
    let fr = bootstrap_ratio(&fb, &fa, b, &mut own);
    let ff = noise_floor(&fb);
    if fr.lo > ff && fr.value > 0.0 {
        judged.off_limit = Some((fr, ff, free.len()));
    }
    judged
}

/// The windows by decreasing `before` and how many of the first the trimmed statistics drop ([`TRIM_FRAC`]): the
/// one rule for the trimmed naming test here and the trimmed mean of "What is left".
pub(super) fn trim_order(before: &[f64]) -> (Vec<usize>, usize) {
    let mut order: Vec<usize> = (0..before.len()).collect();
    order.sort_by(|&a, &b| before[b].total_cmp(&before[a]));
    let n_trim = (before.len() as f64 * TRIM_FRAC).floor() as usize;
    (order, n_trim)
}

/// `before` and `after` without the [`TRIM_FRAC`] of windows with the largest `before` (window order kept).
fn trimmed(before: &[f64], after: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = before.len().min(after.len());
    let (order, n_trim) = trim_order(&before[..n]);
    let mut drop = vec![false; n];
    order.iter().take(n_trim).for_each(|&i| drop[i] = true);
    (0..n).filter(|&i| !drop[i]).map(|i| (before[i], after[i])).unzip()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// 60 windows whose gap an effect halves, plus 6 windows with a hundred times the gap that it leaves as they
    /// are (a joint at a limit, modelled differently): the mean sees a 4 % cut, under the floor; the trimmed windows
    /// see the 50 % cut. Without the halving nothing clears either way.
    #[test]
    fn a_few_huge_windows_do_not_swamp_an_effect() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let before: Vec<f64> =
            (0..66).map(|i| if i % 11 == 5 { 400.0 + i as f64 } else { 4.0 + (i % 3) as f64 }).collect();
        let halved: Vec<f64> = before.iter().map(|&b| if b > 100.0 { b } else { 0.5 * b }).collect();
        let j = judge(&before, &halved, &[], 500, &mut rng);
        assert!(j.reduction.lo <= j.floor, "the mean alone should not clear: {j:?}");
        let (t, f) = j.trimmed.expect("cleared on the trimmed windows");
        assert!((t.value - 0.5).abs() < 1e-9 && t.lo > f, "{t:?} vs floor {f}");
        assert!(j.clears() && j.route_note().is_some());
        // Noise only: a small random change per window, no effect.
        let noisy: Vec<f64> =
            before.iter().enumerate().map(|(i, &b)| b * (1.0 + 0.02 * ((i * 7 % 5) as f64 - 2.0))).collect();
        let j = judge(&before, &noisy, &[], 500, &mut rng);
        assert!(!j.clears(), "noise cleared: {j:?}");
    }

    /// 60 windows, 24 of them at a range limit with a gap a hundred times larger that an effect leaves as it is (the
    /// limit models of two engines differ): the mean sees a 2 % cut and the trimmed windows (which drop only 6 of
    /// the 24) little more; the 36 windows away from the limits see the effect's 40 % cut. The route draws no
    /// number from the caller's stream, and a noise-sized change does not clear it.
    #[test]
    fn windows_at_a_range_limit_do_not_swamp_an_effect() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let at_limit = |i: usize| i % 5 < 2;
        let before: Vec<f64> =
            (0..60).map(|i| if at_limit(i) { 300.0 + (i % 7) as f64 } else { 4.0 + (i % 3) as f64 }).collect();
        let off: Vec<bool> = (0..60).map(|i| !at_limit(i)).collect();
        let cut: Vec<f64> = before.iter().zip(&off).map(|(&b, &o)| if o { 0.6 * b } else { b }).collect();
        let mut same = rng.clone();
        let j = judge(&before, &cut, &off, 500, &mut rng);
        assert!(j.reduction.lo <= j.floor && j.trimmed.is_none(), "the mean or trimmed cleared: {j:?}");
        let (r, f, n) = j.off_limit.expect("cleared away from the limits");
        assert!((r.value - 0.4).abs() < 1e-9 && r.lo > f && n == 36, "{r:?} vs floor {f}, {n} windows");
        assert!(j.clears() && j.route_note().is_some_and(|t| t.contains("36 held-out windows")));
        let _ = judge(&before, &cut, &[], 500, &mut same);
        assert_eq!(rng.gen::<u64>(), same.gen::<u64>(), "the off-limit route drew from the caller's stream");
        let noisy: Vec<f64> =
            before.iter().enumerate().map(|(i, &b)| b * (1.0 + 0.02 * ((i * 7 % 5) as f64 - 2.0))).collect();
        assert!(!judge(&before, &noisy, &off, 500, &mut rng).clears());
        // Too few windows away from the limits: the route is not tried.
        let few: Vec<bool> = (0..60).map(|i| i < 10).collect();
        assert!(judge(&before, &cut, &few, 500, &mut rng).off_limit.is_none());
    }

    /// An effect that cuts every window clears on the mean and is not re-judged on trimmed windows.
    #[test]
    fn an_effect_on_every_window_clears_on_the_mean() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let before: Vec<f64> = (0..40).map(|i| 10.0 + (i % 4) as f64).collect();
        let after: Vec<f64> = before.iter().map(|b| 0.6 * b).collect();
        let j = judge(&before, &after, &[], 500, &mut rng);
        assert!(j.reduction.lo > j.floor && j.trimmed.is_none() && j.clears());
    }
}
