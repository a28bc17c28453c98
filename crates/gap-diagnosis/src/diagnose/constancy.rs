//! Whether each named effect keeps one size across the held-out windows (issue 14 item 5). A library effect is one
//! law with one size: where a window shows it, the size that fits that window best is the size fitted on all of
//! them. A library effect standing in for one outside the library (a gear friction that grows with the carried
//! torque, fitted as viscous damping) is a compromise: the windows where it acts want sizes far apart (some three
//! times the fitted one, some half), and the fitted size is the one that hurts the others least. This is the
//! parameter-constancy test of system identification, window by window.
//!
//! Each named joint-space effect is replayed on the held-out windows at scaled sizes (its fitted change from the
//! no-effect value times each of [`SIZE_SCALES`]), on top of the other members of the best combination. In each
//! window the best scale and the depth of its cut (the window's gap without the effect minus its smallest gap over
//! the scales) are read off; the effect's **misfit share** is the depth-weighted share of the windows whose best
//! scale is at least [`MISFIT_RATIO`] times away from the best scale over all windows. Windows the effect does not
//! change, or only worsens, weigh nothing, so an effect that acts in few windows (a torque limit) is judged on
//! those. An effect whose misfit share reaches [`MISFIT_SHARE`], with the lower bound of its bootstrap interval over
//! windows at [`MISFIT_SHARE_LO`] at least (not one window's doing), is not named: no single size of it explains
//! the windows it acts in. Both thresholds were set on the Rapier reference plant's seed 2 benchmark and five logs
//! of single effects (docs/gap/reference-engines.md), before the other seeds and engines were run with them.
use super::assess::sort_results;
use super::confound::AmbiguousSet;
use super::replay::Ctx;
use super::select::{abstentions, Selection};
use super::stats::{bootstrap_mean, bootstrap_ratio, total, Estimate};
use crate::effects::{EffectKind, Scope};
use crate::plant::Effects;
use crate::GapError;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Scales of the fitted change (from the no-effect value) replayed on the held-out windows; sizes past the search
/// range are clamped to it.
pub const SIZE_SCALES: [f64; 7] = [0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0];
/// A window misfits when its best scale is at least this factor away from the best scale over all windows.
pub const MISFIT_RATIO: f64 = 2.0;
/// An effect is not named when its misfit share reaches this ...
pub const MISFIT_SHARE: f64 = 0.4;
/// ... and the lower bound of the share's bootstrap interval reaches this.
pub const MISFIT_SHARE_LO: f64 = 0.1;

/// One named effect's size, window by window.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ConstancyCheck {
    pub kind: EffectKind,
    /// The joints it was fitted on (every joint for a robot-wide effect).
    pub joints: Vec<String>,
    /// Best scale of the fitted change over all held-out windows.
    pub scale_all: f64,
    /// Depth-weighted median of the windows' own best scales.
    pub scale_median: f64,
    /// Held-out windows the effect cuts at some scale (depth > 0).
    pub windows_cut: usize,
    /// Depth-weighted share of those windows whose best scale is [`MISFIT_RATIO`] times away from `scale_all`,
    /// with a bootstrap interval over windows.
    pub misfit_share: Estimate,
    /// No single size explains the windows the effect acts in: not named.
    pub inconsistent: bool,
}

impl ConstancyCheck {
    /// The abstention note of an effect whose size does not hold across windows.
    pub fn note(&self) -> String {
        format!(
            "no single size of it explains the windows it acts in: {:.0} % [{:.0}, {:.0}] of its cut lies in held-out \
             windows that want a size {MISFIT_RATIO:.0} times larger or smaller than the fitted one (the windows' \
             median wants {:.2} times it): an effect outside the library (a friction growing with the carried \
             torque, say) is likely, not named",
            100.0 * self.misfit_share.value,
            100.0 * self.misfit_share.lo,
            100.0 * self.misfit_share.hi,
            self.scale_median / self.scale_all
        )
    }
}

/// Checks every named effect and un-names those whose size does not hold, until every effect still named holds
/// (each round replays the effects still named on top of the combination that remains: an effect un-named no longer
/// absorbs part of what another explains). `fitted`: every candidate effect at its values fitted alone. Returns the
/// last check of each effect checked.
pub(super) fn check_and_unname(
    ctx: &Ctx<'_>,
    sel: &mut Selection,
    ambiguous: &mut Vec<AmbiguousSet>,
    fitted: &[(EffectKind, Effects)],
    baseline_tot: &[f64],
    rng: &mut impl Rng,
) -> Result<Vec<ConstancyCheck>, GapError> {
    let mut out: Vec<ConstancyCheck> = Vec::new();
    loop {
        let members: Vec<EffectKind> = sel.best_combination.as_ref().map(|c| c.effects.clone()).unwrap_or_default();
        let named: Vec<(EffectKind, Effects)> = sel
            .ranked
            .iter()
            .filter_map(|&k| match &sel.combo_fx {
                Some(combo) if members.contains(&k) => {
                    let mut fx = Effects::none(ctx.nj());
                    k.copy(combo, &mut fx);
                    Some((k, fx))
                }
                _ => fitted.iter().find(|(f, _)| *f == k).cloned(),
            })
            .collect();
        let checks = constancy_checks(ctx, &named, sel.combo_fx.as_ref(), &members, rng)?;
        let again = checks.iter().any(|c| c.inconsistent);
        unname_inconsistent(ctx, sel, ambiguous, &checks, baseline_tot, rng)?;
        for c in checks {
            out.retain(|x| x.kind != c.kind);
            out.push(c);
        }
        if !again {
            return Ok(out);
        }
    }
}

/// The check of every named effect but the IMU ones (which act on the IMU reading alone).
/// `named`: each named effect at its fitted values (a member of the combination: its values in the combination);
/// `combo`: the best combination (its other members stay applied while an effect is scaled).
fn constancy_checks(
    ctx: &Ctx<'_>,
    named: &[(EffectKind, Effects)],
    combo: Option<&Effects>,
    members: &[EffectKind],
    rng: &mut impl Rng,
) -> Result<Vec<ConstancyCheck>, GapError> {
    let mut out = Vec::new();
    for (kind, fx) in named.iter().filter(|(k, _)| k.scope() != Scope::Imu) {
        let null = Effects::none(ctx.nj());
        let rest = match combo {
            Some(c) if members.contains(kind) => {
                let mut r = c.clone();
                kind.copy(&null, &mut r);
                r
            }
            _ => null.clone(),
        };
        let (lo, hi, v0) = kind.range();
        let joints: Vec<usize> = match kind.scope() {
            Scope::Global => (0..ctx.nj()).collect(),
            _ => (0..ctx.nj()).filter(|&j| (kind.get(fx, j) - v0).abs() > 1e-12).collect(),
        };
        if joints.is_empty() {
            continue;
        }
        let set: Vec<usize> = if kind.scope() == Scope::Global { vec![0] } else { joints.clone() };
        let cfgs: Vec<Effects> = std::iter::once(0.0)
            .chain(SIZE_SCALES)
            .map(|s| {
                let mut c = rest.clone();
                for &j in &set {
                    kind.set(&mut c, j, (v0 + s * (kind.get(fx, j) - v0)).clamp(lo, hi));
                }
                c
            })
            .collect();
        let totals: Vec<Vec<f64>> =
            ctx.eval_many(&cfgs, &ctx.test)?.iter().map(|sc| sc.iter().map(|w| total(w)).collect()).collect();
        if let Some(c) = judge(*kind, &totals, ctx.opts.bootstrap, rng) {
            let names = joints.iter().map(|&j| ctx.model.joints[j].motor_name.clone()).collect();
            out.push(ConstancyCheck { joints: names, ..c });
        }
    }
    Ok(out)
}

/// Un-names the effects whose size does not hold across windows: their results say why, and they leave the
/// ranking, the ambiguous sets and the best combination (whose held-out gap is replayed again without them).
fn unname_inconsistent(
    ctx: &Ctx<'_>,
    sel: &mut Selection,
    ambiguous: &mut Vec<AmbiguousSet>,
    checks: &[ConstancyCheck],
    baseline_tot: &[f64],
    rng: &mut impl Rng,
) -> Result<(), GapError> {
    let failing: Vec<&ConstancyCheck> = checks.iter().filter(|c| c.inconsistent).collect();
    if failing.is_empty() {
        return Ok(());
    }
    let kinds: Vec<EffectKind> = failing.iter().map(|c| c.kind).collect();
    for r in sel.effects.iter_mut() {
        if let Some(c) = failing.iter().find(|c| c.kind == r.kind) {
            r.named = false;
            r.note = Some(c.note());
        }
    }
    sel.ranked.retain(|k| !kinds.contains(k));
    for set in ambiguous.iter_mut() {
        set.effects.retain(|k| !kinds.contains(k));
        set.at_bound.retain(|k| !kinds.contains(k));
    }
    ambiguous.retain(|s| s.effects.len() >= 2);
    if let (Some(combo), Some(fx)) = (sel.best_combination.as_mut(), sel.combo_fx.as_mut()) {
        if combo.effects.iter().any(|k| kinds.contains(k)) {
            combo.effects.retain(|k| !kinds.contains(k));
            let null = Effects::none(ctx.nj());
            kinds.iter().for_each(|k| k.copy(&null, fx));
            let after: Vec<f64> = ctx
                .eval_many(std::slice::from_ref(fx), &ctx.test)?
                .first()
                .map(|sc| sc.iter().map(|w| total(w)).collect())
                .unwrap_or_default();
            combo.metric_after = bootstrap_mean(&after, ctx.opts.bootstrap, rng);
            combo.reduction = bootstrap_ratio(baseline_tot, &after, ctx.opts.bootstrap, rng);
        }
    }
    if sel.best_combination.as_ref().is_some_and(|c| c.effects.is_empty()) {
        sel.best_combination = None;
        sel.combo_fx = None;
    }
    sort_results(&mut sel.effects);
    sel.abstentions = abstentions(&sel.effects);
    Ok(())
}

/// The check from the held-out gap per window without the effect (`totals[0]`) and at each of [`SIZE_SCALES`]
/// (`totals[1..]`); `None` when the effect cuts no window at any scale. `joints` is left for the caller.
fn judge(kind: EffectKind, totals: &[Vec<f64>], bootstrap: usize, rng: &mut impl Rng) -> Option<ConstancyCheck> {
    let n = totals.first().map_or(0, Vec::len);
    if totals.len() != SIZE_SCALES.len() + 1 || totals.iter().any(|t| t.len() != n) {
        return None;
    }
    let scale = |k: usize| SIZE_SCALES[k - 1];
    let best_of = |gap: &dyn Fn(usize) -> f64| (1..totals.len()).min_by(|&a, &b| gap(a).total_cmp(&gap(b)));
    let k_all = best_of(&|k| totals[k].iter().sum())?;
    // Per window: its own best scale and the depth of its cut there.
    let per: Vec<(f64, f64)> = (0..n)
        .filter_map(|w| {
            let k = best_of(&|k| totals[k][w])?;
            Some((scale(k), (totals[0][w] - totals[k][w]).max(0.0)))
        })
        .collect();
    let cut: Vec<(f64, f64)> = per.iter().copied().filter(|&(_, d)| d > 0.0).collect();
    if cut.is_empty() {
        return None;
    }
    let s_all = scale(k_all);
    let misfit = |s: f64| s >= MISFIT_RATIO * s_all || s * MISFIT_RATIO <= s_all;
    let depth: Vec<f64> = cut.iter().map(|&(_, d)| d).collect();
    let off: Vec<f64> = cut.iter().map(|&(s, d)| if misfit(s) { d } else { 0.0 }).collect();
    // Share = 1 - Σ(depth - off) / Σ depth, the ratio's complement.
    let fit: Vec<f64> = depth.iter().zip(&off).map(|(d, o)| d - o).collect();
    let misfit_share = bootstrap_ratio(&depth, &fit, bootstrap, rng);
    let mut by_scale = cut.clone();
    by_scale.sort_by(|a, b| a.0.total_cmp(&b.0));
    let half = 0.5 * depth.iter().sum::<f64>();
    let mut acc = 0.0;
    let scale_median = by_scale.iter().find(|&&(_, d)| {
        acc += d;
        acc >= half
    });
    Some(ConstancyCheck {
        kind,
        joints: vec![],
        scale_all: s_all,
        scale_median: scale_median.map_or(s_all, |&(s, _)| s),
        windows_cut: cut.len(),
        misfit_share,
        inconsistent: misfit_share.value >= MISFIT_SHARE && misfit_share.lo >= MISFIT_SHARE_LO,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// Held-out gaps of `n` windows for an effect whose best size in window `w` is `best(w)` times the fitted one
    /// (a bowl in the scale whose depth is `depth(w)` of the window's gap), with a little noise.
    fn bowls(n: usize, best: impl Fn(usize) -> f64, depth: impl Fn(usize) -> f64) -> Vec<Vec<f64>> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let base: Vec<f64> = (0..n).map(|w| 10.0 + (w % 3) as f64).collect();
        std::iter::once(0.0)
            .chain(SIZE_SCALES)
            .map(|s| {
                (0..n)
                    .map(|w| {
                        let (b, depth) = (best(w), depth(w) * base[w]);
                        if s == 0.0 {
                            base[w]
                        } else {
                            base[w] - depth + depth * ((s - b) / b).powi(2).min(1.0) + rng.gen_range(-0.05..0.05)
                        }
                    })
                    .collect()
            })
            .collect()
    }

    fn check(totals: &[Vec<f64>]) -> ConstancyCheck {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        judge(EffectKind::Damping, totals, 500, &mut rng).expect("the effect cuts some window")
    }

    #[test]
    fn windows_that_want_sizes_far_apart_make_the_effect_inconsistent() {
        // Half the windows want three times the fitted size, the other half half of it.
        let c = check(&bowls(40, |w| if w % 2 == 0 { 3.0 } else { 0.5 }, |_| 0.9));
        assert!(c.inconsistent && c.misfit_share.value >= MISFIT_SHARE, "{c:?}");
    }

    #[test]
    fn windows_that_agree_on_one_size_keep_the_effect() {
        let c = check(&bowls(40, |_| 1.0, |_| 0.9));
        assert_eq!((c.scale_all, c.scale_median, c.windows_cut), (1.0, 1.0, 40), "{c:?}");
        assert!(!c.inconsistent && c.misfit_share.value == 0.0, "{c:?}");
    }

    #[test]
    fn an_effect_that_acts_in_few_windows_is_judged_on_those() {
        // A torque limit: most windows never reach it, so every size leaves them as they are (or worse).
        let mut totals = bowls(40, |_| 1.0, |_| 0.9);
        for t in totals.iter_mut().skip(1) {
            for (w, x) in t.iter_mut().enumerate().filter(|(w, _)| w % 5 != 0) {
                *x = 10.0 + (w % 3) as f64 + 0.01;
            }
        }
        let c = check(&totals);
        assert_eq!(c.windows_cut, 8, "{c:?}");
        assert!(!c.inconsistent, "{c:?}");
    }

    #[test]
    fn a_few_shallow_misfits_do_not_make_it_inconsistent() {
        // Every fourth window wants three times the size, but the effect hardly acts there.
        let totals = bowls(40, |w| if w % 4 == 0 { 3.0 } else { 1.0 }, |w| if w % 4 == 0 { 0.05 } else { 0.9 });
        let c = check(&totals);
        assert!(!c.inconsistent && c.misfit_share.value < 0.05, "{c:?}");
    }

    #[test]
    fn an_effect_that_cuts_no_window_gives_no_verdict() {
        let mut totals = bowls(10, |_| 1.0, |_| 0.9);
        for t in totals.iter_mut().skip(1) {
            t.iter_mut().for_each(|x| *x = 20.0);
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        assert!(judge(EffectKind::Damping, &totals, 100, &mut rng).is_none());
    }
}
