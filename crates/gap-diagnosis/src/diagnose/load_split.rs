//! Whether a friction-like effect holds at every load (issue 14 item 5). Viscous damping, Coulomb friction and a
//! dead band do not depend on the torque a joint carries; a friction that grows with it (a gear whose tooth friction
//! scales with the transmitted torque) is outside the library, and on a motion that loads the joints unevenly the
//! library's effects fit it as an average. So a damping, friction or backlash that clears the floor alone is refitted,
//! as one scale of its kept values, on the training windows in which its joints carry the least torque and on those
//! in which they carry the most, and is not named (nor offered to the selection) when the heavily loaded half wants
//! a much larger scale, with bootstrap intervals apart. Only that direction counts: load comes with speed, and a
//! library effect of the wrong speed law wants more in the slow, lightly loaded windows (a Coulomb friction fitted
//! as damping; Rapier's joint friction against the library's smooth law), which says nothing about load. Checked on
//! a plant of another program (`tests/python_plant.rs`: a load-proportional friction on an elbow names nothing, a
//! viscous damping and a dry friction there want their fitted size on both halves). A first form without intervals
//! and in both directions was dropped: it un-named the true friction of Rapier's seed-1 trial 2.
use super::replay::Ctx;
use super::stats::{median, percentile_interval, Estimate};
use crate::effects::EffectKind;
use crate::plant::Effects;
use crate::GapError;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Scales of the kept values tried on each half (the fitted value is scale 1).
const SCALES: [f64; 12] = [0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0];

/// The effect is load-dependent when the high-load half wants at least this many times the scale of the low-load
/// half, with their bootstrap intervals apart (and the halves differ in load by at least [`MIN_LOAD_RATIO`]).
pub const LOAD_SCALE_RATIO: f64 = 2.0;
/// The halves must differ in mean carried torque by at least this factor for the split to say anything.
pub const MIN_LOAD_RATIO: f64 = 1.5;
/// The smaller scale is floored at this before dividing (a half that wants no effect at all).
const SCALE_FLOOR: f64 = 0.1;
/// Bootstrap resamples of each half's windows for the interval of its scale.
const RESAMPLES: usize = 200;
/// Seed of the split's own random numbers: it draws from its own stream, so that the draws of every other test,
/// and the reports of logs where it is never tried, stay as they were.
const LOAD_SPLIT_STREAM: u64 = 0x6c6f_6164_5f73_706c;

/// The kinds whose value cannot depend on the carried torque and that a load-dependent friction can stand in for.
pub const LOAD_CHECKED: [EffectKind; 3] = [EffectKind::Damping, EffectKind::Friction, EffectKind::Backlash];

/// The refit of a friction-like effect on the training windows of low and of high carried torque.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LoadSplit {
    /// Mean |torque| / torque limit over the effect's joints, on the low-load and the high-load half.
    pub load_low: f64,
    pub load_high: f64,
    /// The scale of the kept values that fits each half best (1: the value fitted on every training window), with
    /// a 95 % bootstrap interval over the half's windows.
    pub scale_low: Estimate,
    pub scale_high: Estimate,
    /// Whether the high-load half wants a scale [`LOAD_SCALE_RATIO`] times the low-load half's, intervals apart.
    pub load_dependent: bool,
}

impl LoadSplit {
    /// Why the effect is not named, when it is load-dependent.
    pub fn note(&self) -> String {
        format!(
            "its size grows with the torque its joints carry, which no effect of the library does: refitted on the \
             training windows where they carry the least torque ({:.1} % of the limit) it wants {:.2}x [{:.2}, \
             {:.2}] the fitted value, where they carry the most ({:.1} %) {:.2}x [{:.2}, {:.2}]; a friction that \
             grows with the load, or this effect standing in for another (a Coulomb friction fitted to a viscous \
             damping also wants more in the fast, heavily loaded windows); not named",
            self.load_low * 100.0,
            self.scale_low.value,
            self.scale_low.lo,
            self.scale_low.hi,
            self.load_high * 100.0,
            self.scale_high.value,
            self.scale_high.lo,
            self.scale_high.hi
        )
    }
}

/// Refits the kept values `kept` of `kind` (one of [`LOAD_CHECKED`]; other kinds: `None`) on the low- and
/// high-load halves of the training windows, scoring each half on the columns of the groups the effect acts in.
pub(super) fn load_split(ctx: &Ctx<'_>, kind: EffectKind, kept: &Effects) -> Result<Option<LoadSplit>, GapError> {
    if !LOAD_CHECKED.contains(&kind) || ctx.train.len() < 8 {
        return Ok(None);
    }
    let v0 = kind.range().2;
    let joints: Vec<usize> = (0..ctx.nj()).filter(|&j| (kind.get(kept, j) - v0).abs() > 1e-12).collect();
    if joints.is_empty() {
        return Ok(None);
    }
    let cols: Vec<usize> = (0..ctx.nj()).filter(|&c| joints.iter().any(|&j| ctx.groups[j] == ctx.groups[c])).collect();
    let load: Vec<f64> = ctx.train.iter().map(|&w| window_load(ctx, &joints, w)).collect();
    let cut = median(&load);
    let (low, high): (Vec<usize>, Vec<usize>) = (0..ctx.train.len()).partition(|&i| load[i] <= cut);
    if low.len() < 4 || high.len() < 4 {
        return Ok(None);
    }
    let mean_of = |idx: &[usize]| idx.iter().map(|&i| load[i]).sum::<f64>() / idx.len() as f64;
    let (load_low, load_high) = (mean_of(&low), mean_of(&high));
    let (lo, hi, _) = kind.range();
    let cfgs: Vec<Effects> = SCALES
        .iter()
        .map(|&s| {
            let mut fx = kept.clone();
            for &j in &joints {
                kind.set(&mut fx, j, (v0 + s * (kind.get(kept, j) - v0)).clamp(lo, hi));
            }
            fx
        })
        .collect();
    let scores = ctx.eval_many(&cfgs, &ctx.train)?;
    // Per training window, its score on the effect's columns at every scale.
    let per_window: Vec<Vec<f64>> = (0..ctx.train.len())
        .map(|i| {
            scores
                .iter()
                .map(|s| s.get(i).map_or(0.0, |w| cols.iter().filter_map(|&c| w.get(c)).sum::<f64>()))
                .collect()
        })
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(LOAD_SPLIT_STREAM);
    let scale_low = half_scale(&per_window, &low, &mut rng);
    let scale_high = half_scale(&per_window, &high, &mut rng);
    // Only a larger effect under the larger load counts: a smaller one there is what a library effect of another
    // speed law shows (a Coulomb friction fitted as damping wants more at the low speeds of lightly loaded windows;
    // Rapier's joint friction against the library's smooth one does the same), and the load does not cause it.
    let load_dependent = load_high >= MIN_LOAD_RATIO * load_low
        && scale_high.value >= LOAD_SCALE_RATIO * scale_low.value.max(SCALE_FLOOR)
        && scale_high.lo > scale_low.hi;
    Ok(Some(LoadSplit { load_low, load_high, scale_low, scale_high, load_dependent }))
}

/// The best scale on the windows `idx` (indices into `per_window`), with a percentile interval over resamples of
/// those windows.
fn half_scale(per_window: &[Vec<f64>], idx: &[usize], rng: &mut impl Rng) -> Estimate {
    let curve = |pick: &mut dyn Iterator<Item = usize>| -> Vec<f64> {
        let mut f = vec![0.0; SCALES.len()];
        for i in pick {
            if let Some(w) = per_window.get(i) {
                f.iter_mut().zip(w).for_each(|(a, b)| *a += b);
            }
        }
        f
    };
    let value = best_scale(&curve(&mut idx.iter().copied()));
    let draws: Vec<f64> = (0..RESAMPLES)
        .map(|_| best_scale(&curve(&mut (0..idx.len()).map(|_| idx[rng.gen_range(0..idx.len())]))))
        .collect();
    percentile_interval(value, draws)
}

/// Mean |measured torque| / torque limit of `joints` over training window `w`.
fn window_load(ctx: &Ctx<'_>, joints: &[usize], w: usize) -> f64 {
    let start = ctx.starts.get(w).copied().unwrap_or(0);
    let end = (start + ctx.len + 1).min(ctx.log.states.len());
    let states = ctx.log.states.get(start..end).unwrap_or(&[]);
    let (mut acc, mut n) = (0.0, 0usize);
    for s in states {
        for &j in joints {
            if let (Some(t), Some(m)) = (s.tau.get(j), ctx.model.joints.get(j)) {
                acc += t.abs() / m.torque_limit.max(1.0);
                n += 1;
            }
        }
    }
    if n == 0 {
        0.0
    } else {
        acc / n as f64
    }
}

/// The scale at the minimum of `f` over [`SCALES`], refined by a parabola through the minimum and its neighbours.
fn best_scale(f: &[f64]) -> f64 {
    let Some((k, _)) = f.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)) else { return 1.0 };
    if k == 0 || k + 1 >= f.len() {
        return SCALES[k];
    }
    let (x0, x1, x2) = (SCALES[k - 1], SCALES[k], SCALES[k + 1]);
    let (y0, y1, y2) = (f[k - 1], f[k], f[k + 1]);
    // Vertex of the parabola through three points with uneven spacing.
    let den = (x0 - x1) * (x0 - x2) * (x1 - x2);
    let a = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / den;
    let b = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / den;
    if a <= 0.0 || !a.is_finite() || !b.is_finite() {
        return x1;
    }
    (-b / (2.0 * a)).clamp(x0, x2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_best_scale_is_the_vertex_of_a_parabola_through_the_grid_minimum() {
        // f(s) = (s - 1.7)^2 sampled on the grid: the vertex is found exactly between uneven grid points.
        let f: Vec<f64> = SCALES.iter().map(|s| (s - 1.7) * (s - 1.7)).collect();
        assert!((best_scale(&f) - 1.7).abs() < 1e-9, "{}", best_scale(&f));
        // A minimum at the grid's end is that end.
        let g: Vec<f64> = SCALES.iter().map(|s| -s).collect();
        assert_eq!(best_scale(&g), 6.0);
        let h: Vec<f64> = SCALES.to_vec();
        assert_eq!(best_scale(&h), 0.0);
    }
}
