//! Masked effects: a second effect whose units' own residual the first effect swamps cuts none of them by the unit
//! floor when fitted alone (a knee damping under a whole leg's armature, a shoulder friction under its arm's link
//! mass), so it never becomes a candidate of the conditional selection ([`super::select`]). Once the selection
//! stops, each such effect is refitted with the combination applied, and its units are judged by the same unit test
//! as alone ([`super::assess::judge_unit`]) but against the residual the combination leaves; the best one with a
//! kept unit is offered to the selection, which adds it only when it clears that residual's own noise floor. Rig
//! only (the floating plant's fits are several times dearer), and one effect per diagnosis: every refit is a full
//! fit. Its draws come from a stream of its own, so the other stages draw as they did without it. Another masked
//! effect on the same limb whose cut the log cannot rank against the offered one is reported with it ([`Rival`]).
//! The same check runs on each candidate the selection adds after the first ([`rivals_of_added`]): that it kept a
//! unit alone and a masked effect did not says nothing once another effect is in.
use super::assess::{judge_unit, single_joints, EffectResult, FittedParam, UnitVerdict, SINGLE_JOINT_FRAC};
use super::confound::cosine;
use super::fit::{fit_at_joints, fit_kind, report_value, set_unit, unit_name, unit_value, units_of, RESOLUTION_FRAC};
use super::options::PlantKind;
use super::replay::Ctx;
use super::stats::{bootstrap_mean, judge, mean, noise_floor, total, trim_order, Estimate, Judged};
use crate::effects::{EffectKind, Scope};
use crate::plant::Effects;
use crate::GapError;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The stream of this stage's draws ("unmask").
const UNMASK_STREAM: u64 = 0x756e_6d61_736b;
/// The stream of the check of an added candidate's rivals ("rivals").
const ADDED_RIVALS_STREAM: u64 = 0x7269_7661_6c73;
/// The stream of the check of the first effect's rivals on its joints ("first").
const FIRST_RIVALS_STREAM: u64 = 0x0066_6972_7374;
/// The stream of the check of an added candidate's rivals on its joints ("joints").
const JOINT_RIVALS_STREAM: u64 = 0x6a6f_696e_7473;

/// An effect that keeps a unit only once the combination is applied.
pub(super) struct Unmasked {
    pub kind: EffectKind,
    /// The combination with its kept units added.
    pub fx: Effects,
    /// Its kept units alone (for the ambiguity stage).
    pub alone: Effects,
    /// Held-out gap metric per window with it added.
    pub totals: Vec<f64>,
    pub metric_after: Estimate,
    /// Its kept units, each with its mean held-out cut of the residual the combination leaves there.
    pub params: Vec<FittedParam>,
    /// How it cut the residual the combination leaves (it cleared that residual's noise floor).
    pub judged: Judged,
    /// The other masked effects the log cannot rank against it ([`rivals`]).
    pub rivals: Vec<Rival>,
}

/// A masked effect that, refitted with the combination applied, also clears the remaining residual's floor on the
/// same limb as the one offered, by a cut the log cannot rank against it: the report puts the two in one
/// [`super::confound::AmbiguousSet`] ([`super::confound::Ambiguity::EqualCut`]). Written for Rapier's seed 17,
/// trial 22 (a shoulder-yaw link mass offered and named for the injected COM shift of the shoulder-roll link, both
/// cutting what the arm's armature leaves), where it does not fire: on the windows the mass was named on it cuts
/// measurably more (BENCHMARKS.md, "A masked effect's rivals").
pub(super) struct Rival {
    pub kind: EffectKind,
    /// Its kept units.
    pub params: Vec<FittedParam>,
    /// |cosine| of its change of the held-out predictions (from the combination's) with the offered effect's.
    pub cosine: f64,
    /// |mean difference| of the two held-out gaps per window, relative to the residual the combination leaves (on
    /// the windows the offered effect was named on).
    pub gap_difference: f64,
}

/// One masked effect refitted with the combination applied that kept a unit.
struct Offer {
    kind: EffectKind,
    with: Effects,
    alone: Effects,
    params: Vec<FittedParam>,
    /// The limbs ([`crate::plant::GROUPS`]) of its kept units.
    limbs: Vec<usize>,
}

/// Which effects may be masked: on the rig, the replayed effects (not the IMU's closed-form fits, nor a torque
/// saturation, which has routes of its own from the log's torque) that kept no unit alone (nor one dropped at the
/// bound of its range), were not set aside by a split and are not in the combination.
fn masked_kinds(plant: PlantKind, results: &[EffectResult], members: &[EffectKind]) -> Vec<EffectKind> {
    if plant != PlantKind::Rig {
        return Vec::new();
    }
    results
        .iter()
        .filter(|r| {
            r.kind.identifiable_suspended()
                && r.kind.scope() != Scope::Imu
                && r.kind != EffectKind::TorqueSaturation
                && !members.contains(&r.kind)
                && !r.named
                && r.params.is_empty()
                && r.pinned_units.is_empty()
                && r.set_aside_by_split().is_none()
        })
        .map(|r| r.kind)
        .collect()
}

/// The masked effect that, refitted with `combo` applied, leaves the smallest held-out residual among those that
/// keep a unit against the residual `combo` leaves, when it cuts that residual (`cur`, per held-out window) beyond
/// its noise floor as the selection judges (`off_limit`: the held-out windows away from the range limits); `None`
/// when none does.
pub(super) fn unmask(
    ctx: &Ctx<'_>,
    results: &[EffectResult],
    members: &[EffectKind],
    combo: &Effects,
    cur: &[f64],
    off_limit: &[bool],
) -> Result<Option<Unmasked>, GapError> {
    let kinds = masked_kinds(ctx.plant, results, members);
    if kinds.is_empty() {
        return Ok(None);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(UNMASK_STREAM ^ ctx.opts.seed);
    let (mut offers, mut totals) = offers_given(ctx, &kinds, combo, &mut rng)?;
    let sums: Vec<f64> = totals.iter().map(|t| t.iter().sum::<f64>()).collect();
    let Some(best) = (0..offers.len()).min_by(|&a, &b| sums[a].total_cmp(&sums[b])) else {
        return Ok(None);
    };
    let judged = judge(cur, &totals[best], off_limit, ctx.opts.bootstrap, &mut rng);
    if !judged.clears() {
        return Ok(None);
    }
    let metric_after = bootstrap_mean(&totals[best], ctx.opts.bootstrap, &mut rng);
    let mut rivals = rivals(ctx, combo, &offers, &totals, best, &judged, cur, off_limit, &mut rng)?;
    // Named on part of the windows only: also the effects fitted on its joints (a stream of their own).
    let mut own = ChaCha8Rng::seed_from_u64(JOINT_RIVALS_STREAM ^ UNMASK_STREAM ^ ctx.opts.seed);
    let offered = (offers[best].kind, &offers[best].with, offers[best].params.as_slice());
    for r in rivals_on_joints(ctx, results, members, combo, cur, offered, &totals[best], &judged, off_limit, &mut own)?
    {
        if !rivals.iter().any(|f| f.kind == r.kind) {
            rivals.push(r);
        }
    }
    let Offer { kind, with: fx, alone, params, .. } = offers.swap_remove(best);
    let totals = totals.swap_remove(best);
    Ok(Some(Unmasked { kind, fx, alone, totals, metric_after, params, judged, rivals }))
}

/// The masked effects `kinds` refitted with `combo` applied that keep a unit against the residual `combo` leaves,
/// each with its held-out gap metric per window.
fn offers_given(
    ctx: &Ctx<'_>,
    kinds: &[EffectKind],
    combo: &Effects,
    rng: &mut ChaCha8Rng,
) -> Result<(Vec<Offer>, Vec<Vec<f64>>), GapError> {
    let combo_train = ctx.eval_many(std::slice::from_ref(combo), &ctx.train)?.remove(0);
    let combo_test = ctx.eval_many(std::slice::from_ref(combo), &ctx.test)?.remove(0);
    let mut fits = Vec::with_capacity(kinds.len());
    let mut singles = Vec::with_capacity(kinds.len());
    for &kind in kinds {
        fits.push(fit_kind(ctx, kind, combo, &combo_train, rng)?);
        // A masked effect is often on one joint (a knee's damping under the leg's armature): fitted on the group
        // alone it spreads over joints that do not want it.
        singles.push(if kind.scope() == Scope::Group {
            Some(single_joints(ctx, kind, combo, &combo_train, rng)?)
        } else {
            None
        });
    }
    let fitted: Vec<Effects> = fits.iter().map(|f| f.fx.clone()).collect();
    let after_all = ctx.eval_many(&fitted, &ctx.test)?;
    let mut offers = Vec::new();
    for (((&kind, fit), after), single) in kinds.iter().zip(&fits).zip(&after_all).zip(&singles) {
        let (lo, hi, v0) = kind.range();
        let resolved = |v: f64| (v - v0).abs() >= RESOLUTION_FRAC * (hi - lo);
        let mut with = combo.clone();
        let mut alone = Effects::none(ctx.nj());
        let mut params = Vec::new();
        let mut limbs = Vec::new();
        for (u, cols) in units_of(ctx, kind).iter().enumerate() {
            let unit_sum = |s: &Vec<f64>| cols.iter().filter_map(|&c| s.get(c)).sum::<f64>();
            let before: Vec<f64> = combo_test.iter().map(unit_sum).collect();
            let value = unit_value(kind, &fit.fx, ctx, u);
            let group = if resolved(value) {
                let diffs: Vec<f64> = before.iter().zip(after).map(|(b, a)| b - unit_sum(a)).collect();
                judge_unit(ctx, kind, cols, &before, &diffs, rng)
            } else {
                UnitVerdict::Not
            };
            let joint = match single {
                Some(sj) if cols.len() >= 2 && sj.values.get(u).is_some_and(|&v| resolved(v)) => {
                    let diffs: Vec<f64> = before.iter().zip(&sj.after).map(|(b, a)| b - unit_sum(a)).collect();
                    Some((sj.joints[u], sj.values[u], judge_unit(ctx, kind, cols, &before, &diffs, rng)))
                }
                _ => None,
            };
            // As alone: the single joint when it cuts nearly as much as the group, or it alone clears.
            let group_cut = match group {
                UnitVerdict::Kept(d) => Some(d),
                _ => None,
            };
            match joint {
                Some((j, v, UnitVerdict::Kept(cut))) if group_cut.is_none_or(|d| cut >= SINGLE_JOINT_FRAC * d) => {
                    kind.set(&mut with, j, v);
                    kind.set(&mut alone, j, v);
                    limbs.push(ctx.groups[j]);
                    params.push(FittedParam {
                        unit: ctx.model.joints[j].motor_name.clone(),
                        value: report_value(kind, v),
                        sd: report_value(kind, fit.sds.get(u).copied().unwrap_or(0.0)),
                        held_out_reduction: cut,
                    });
                }
                _ => {
                    if let Some(cut) = group_cut {
                        set_unit(kind, &mut with, ctx, u, value);
                        set_unit(kind, &mut alone, ctx, u, value);
                        limbs.extend(cols.iter().filter_map(|&c| ctx.groups.get(c).copied()));
                        params.push(FittedParam {
                            unit: unit_name(ctx, kind, u),
                            value: report_value(kind, value),
                            sd: report_value(kind, fit.sds.get(u).copied().unwrap_or(0.0)),
                            held_out_reduction: cut,
                        });
                    }
                }
            }
        }
        if !params.is_empty() {
            limbs.sort_unstable();
            limbs.dedup();
            offers.push(Offer { kind, with, alone, params, limbs });
        }
    }
    if offers.is_empty() {
        return Ok((offers, Vec::new()));
    }
    let cfgs: Vec<Effects> = offers.iter().map(|o| o.with.clone()).collect();
    let totals: Vec<Vec<f64>> =
        ctx.eval_many(&cfgs, &ctx.test)?.iter().map(|r| r.iter().map(|s| total(s)).collect()).collect();
    Ok((offers, totals))
}

/// The masked effects the log cannot rank against `added`, a candidate the selection added to `combo` (the effects
/// before it, in `members`): refitted with `combo` applied, each shares a limb with `added`'s units (`units`, as
/// reported), clears the floor of the residual `combo` leaves (`cur`) and cuts it as much as `added` does on the
/// windows `added` was named on (`judged`, its judgement; `with`, `combo` with it; `totals`, per window). A
/// candidate kept a unit alone and a masked effect did not, but under another effect (a torso link mass and the
/// waist's armature beside latency) that is no evidence for the candidate: both change the same motion. Draws from a
/// stream of its own, so every other stage draws as it did without it.
#[allow(clippy::too_many_arguments)]
pub(super) fn rivals_of_added(
    ctx: &Ctx<'_>,
    results: &[EffectResult],
    members: &[EffectKind],
    combo: &Effects,
    cur: &[f64],
    added: (EffectKind, &Effects, &[FittedParam]),
    totals: &[f64],
    judged: &Judged,
    off_limit: &[bool],
) -> Result<Vec<Rival>, GapError> {
    let (kind, with, units) = added;
    if kind.scope() == Scope::Imu {
        return Ok(Vec::new());
    }
    let kinds = masked_kinds(ctx.plant, results, members);
    let limbs = limbs_of(ctx, kind, units);
    let mut found = Vec::new();
    if !kinds.is_empty() && !limbs.is_empty() {
        let mut rng = ChaCha8Rng::seed_from_u64(ADDED_RIVALS_STREAM ^ ctx.opts.seed);
        let (mut offers, mut all) = offers_given(ctx, &kinds, combo, &mut rng)?;
        // `alone` is read only for the offered effect of the masked-effect step, never by `rivals`.
        offers.push(Offer { kind, with: with.clone(), alone: Effects::none(ctx.nj()), params: units.to_vec(), limbs });
        all.push(totals.to_vec());
        let best = offers.len() - 1;
        found = rivals(ctx, combo, &offers, &all, best, judged, cur, off_limit, &mut rng)?;
    }
    // Named on part of the windows only: also the effects fitted on its joints (a stream of their own).
    let mut rng = ChaCha8Rng::seed_from_u64(JOINT_RIVALS_STREAM ^ ctx.opts.seed);
    for r in rivals_on_joints(ctx, results, members, combo, cur, added, totals, judged, off_limit, &mut rng)? {
        if !found.iter().any(|f: &Rival| f.kind == r.kind) {
            found.push(r);
        }
    }
    Ok(found)
}

/// The rivals on its joints ([`rivals_on_joints`]) of `first`, the selection's first effect (its effects, reported
/// units and held-out gap per window `totals`), judged against the baseline gap per held-out window `baseline`.
pub(super) fn rivals_of_first(
    ctx: &Ctx<'_>,
    results: &[EffectResult],
    first: (EffectKind, &Effects, &[FittedParam]),
    totals: &[f64],
    baseline: &[f64],
    off_limit: &[bool],
) -> Result<Vec<Rival>, GapError> {
    let mut rng = ChaCha8Rng::seed_from_u64(FIRST_RIVALS_STREAM ^ ctx.opts.seed);
    let judged = judge(baseline, totals, off_limit, ctx.opts.bootstrap, &mut rng);
    let null = Effects::none(ctx.nj());
    rivals_on_joints(ctx, results, &[], &null, baseline, first, totals, &judged, off_limit, &mut rng)
}

/// The effects the log cannot rank against `named` (its effects with `combo`, its reported units), an effect named
/// given `combo` (the effects before it, `members`; none for the first) when it cleared the floor of the residual
/// `combo` leaves (`cur`, per held-out window) only on part of the windows (`judged`: the trimmed ones or those
/// away from the range limits) and every unit it was named on is one joint: each joint or group effect that is not
/// named, fitted on those joints with `combo` applied, that clears that floor itself and whose cut the log cannot
/// rank against `named`'s on the windows `named` was named on ([`rivals`]). On Rapier's seeds 21 and 22 those two
/// routes named every wrong effect (an elbow encoder offset named as a COM shift of the forearm, each ankle-pitch
/// torque ripple as a gain scale on that joint), the plain held-out mean none: an effect that the unit test never
/// offered, fitted where the named one sits, tells whether the route's windows say which of the two it is. Rig only.
#[allow(clippy::too_many_arguments)]
pub(super) fn rivals_on_joints(
    ctx: &Ctx<'_>,
    results: &[EffectResult],
    members: &[EffectKind],
    combo: &Effects,
    cur: &[f64],
    named: (EffectKind, &Effects, &[FittedParam]),
    totals: &[f64],
    judged: &Judged,
    off_limit: &[bool],
    rng: &mut ChaCha8Rng,
) -> Result<Vec<Rival>, GapError> {
    let (kind, with, units) = named;
    if ctx.plant != PlantKind::Rig || kind.scope() == Scope::Imu || units.is_empty() || !judged.cleared_on_part_only() {
        return Ok(Vec::new());
    }
    let joints: Option<Vec<usize>> =
        units.iter().map(|p| ctx.model.joints.iter().position(|j| j.motor_name == p.unit)).collect();
    let Some(joints) = joints else {
        return Ok(Vec::new());
    };
    let limbs = limbs_of(ctx, kind, units);
    let kinds: Vec<EffectKind> = results
        .iter()
        .filter(|r| {
            r.kind != kind
                && !members.contains(&r.kind)
                && !r.named
                && r.kind.identifiable_suspended()
                && r.kind != EffectKind::TorqueSaturation
                && r.set_aside_by_split().is_none()
        })
        .map(|r| r.kind)
        .collect();
    if kinds.is_empty() {
        return Ok(Vec::new());
    }
    let combo_train = ctx.eval_many(std::slice::from_ref(combo), &ctx.train)?.remove(0);
    let mut offers = Vec::new();
    for k in kinds {
        let Some((fx, values)) = fit_at_joints(ctx, k, &joints, combo, &combo_train, rng)? else {
            continue;
        };
        let params = values
            .iter()
            .map(|&(j, v, sd)| FittedParam {
                unit: ctx.model.joints[j].motor_name.clone(),
                value: report_value(k, v),
                sd: report_value(k, sd),
                held_out_reduction: 0.0,
            })
            .collect();
        let mut alone = Effects::none(ctx.nj());
        for &(j, v, _) in &values {
            k.set(&mut alone, j, v);
        }
        offers.push(Offer { kind: k, with: fx, alone, params, limbs: limbs.clone() });
    }
    if offers.is_empty() {
        return Ok(Vec::new());
    }
    let cfgs: Vec<Effects> = offers.iter().map(|o| o.with.clone()).collect();
    let mut all: Vec<Vec<f64>> =
        ctx.eval_many(&cfgs, &ctx.test)?.iter().map(|r| r.iter().map(|s| total(s)).collect()).collect();
    for (o, t) in offers.iter_mut().zip(&all) {
        let per_window = (cur.iter().sum::<f64>() - t.iter().sum::<f64>()) / t.len().max(1) as f64;
        o.params.iter_mut().for_each(|p| p.held_out_reduction = per_window);
    }
    // `alone` is read only for the offered effect of the masked-effect step, never by `rivals`.
    offers.push(Offer { kind, with: with.clone(), alone: Effects::none(ctx.nj()), params: units.to_vec(), limbs });
    all.push(totals.to_vec());
    let best = offers.len() - 1;
    rivals(ctx, combo, &offers, &all, best, judged, cur, off_limit, rng)
}

/// The limbs ([`crate::plant::GROUPS`]) of the reported units of an effect: a group, link or joint of its own
/// units, or a single joint (named by its motor) that a group effect was narrowed to.
fn limbs_of(ctx: &Ctx<'_>, kind: EffectKind, units: &[FittedParam]) -> Vec<usize> {
    let cols = units_of(ctx, kind);
    let mut limbs: Vec<usize> = Vec::new();
    for p in units {
        if let Some(u) = (0..cols.len()).find(|&u| unit_name(ctx, kind, u) == p.unit) {
            limbs.extend(cols[u].iter().filter_map(|&c| ctx.groups.get(c).copied()));
        } else if let Some(j) = ctx.model.joints.iter().position(|j| j.motor_name == p.unit) {
            limbs.extend(ctx.groups.get(j).copied());
        }
    }
    limbs.sort_unstable();
    limbs.dedup();
    limbs
}

/// The held-out windows an effect judged `judged` was named on: every one when it cleared there, else those left
/// after trimming ([`trim_order`]) or those away from the range limits, as the route it cleared by.
fn named_on(judged: &Judged, cur: &[f64], off_limit: &[bool]) -> Vec<usize> {
    if judged.reduction.lo > judged.floor {
        (0..cur.len()).collect()
    } else if judged.trimmed.is_some() {
        let (order, n_trim) = trim_order(cur);
        let mut kept: Vec<usize> = order[n_trim..].to_vec();
        kept.sort_unstable();
        kept
    } else {
        (0..cur.len()).filter(|&w| off_limit.get(w).copied().unwrap_or(false)).collect()
    }
}

/// The offers other than `best` that share a limb with it, clear the floor of the residual `combo` leaves (`cur`)
/// themselves, and whose held-out gap the log cannot rank against `best`'s: on the windows `best` was named on
/// ([`named_on`]), the paired difference's 95 % interval holds 0 or its size is under the noise floor of that
/// residual there. Draws after every other draw of the stage, so the offered effect is judged as before.
#[allow(clippy::too_many_arguments)]
fn rivals(
    ctx: &Ctx<'_>,
    combo: &Effects,
    offers: &[Offer],
    totals: &[Vec<f64>],
    best: usize,
    judged: &Judged,
    cur: &[f64],
    off_limit: &[bool],
    rng: &mut ChaCha8Rng,
) -> Result<Vec<Rival>, GapError> {
    let boot = ctx.opts.bootstrap;
    let shares_limb = |o: &Offer| o.limbs.iter().any(|l| offers[best].limbs.contains(l));
    let mut close = Vec::new();
    let windows = named_on(judged, cur, off_limit);
    for (i, o) in offers.iter().enumerate() {
        if i == best || !shares_limb(o) || !judge(cur, &totals[i], off_limit, boot, rng).clears() {
            continue;
        }
        let diffs: Vec<f64> = windows.iter().map(|&w| totals[i][w] - totals[best][w]).collect();
        let left: Vec<f64> = windows.iter().map(|&w| cur[w]).collect();
        let d = bootstrap_mean(&diffs, boot, rng);
        let rel = d.value.abs() / mean(&left).max(1e-300);
        if (d.lo > 0.0 || d.hi < 0.0) && rel >= noise_floor(&left) {
            continue;
        }
        close.push((i, rel));
    }
    if close.is_empty() {
        return Ok(Vec::new());
    }
    let from = ctx.predictions(combo, &ctx.test)?;
    let change = |fx: &Effects| -> Result<Vec<f64>, GapError> {
        let with = ctx.predictions(fx, &ctx.test)?;
        Ok(from.iter().zip(&with).flat_map(|(a, b)| ctx.normalised_change(a, b)).collect())
    };
    let best_change = change(&offers[best].with)?;
    close
        .into_iter()
        .map(|(i, rel)| {
            Ok(Rival {
                kind: offers[i].kind,
                params: offers[i].params.clone(),
                cosine: cosine(&best_change, &change(&offers[i].with)?).abs(),
                gap_difference: rel,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result(kind: EffectKind, named: bool, kept_unit: bool) -> EffectResult {
        let mut r = EffectResult::for_test(kind, named, 0.1);
        if kept_unit {
            r.params = vec![FittedParam { unit: "left_leg".into(), value: 1.0, sd: 0.1, held_out_reduction: 1.0 }];
        }
        r
    }

    /// Only effects that kept no unit alone are refitted (the others were candidates already), never a member, an
    /// IMU effect, a torque saturation or a ground-contact effect on the rig, and nothing on the floating base.
    #[test]
    fn only_effects_that_kept_no_unit_alone_are_refitted_on_the_rig() {
        use EffectKind::*;
        let results = vec![
            result(Armature, true, true),
            result(Damping, false, false),
            result(Friction, false, true),
            result(TorqueSaturation, false, false),
            result(Latency, false, false),
            result(ImuBias, false, false),
            result(ContactFriction, false, false),
            result(LinkCom, false, false),
        ];
        assert_eq!(masked_kinds(PlantKind::Rig, &results, &[Armature]), vec![Damping, Latency, LinkCom]);
        assert_eq!(masked_kinds(PlantKind::Rig, &results, &[Armature, Latency]), vec![Damping, LinkCom]);
        assert!(masked_kinds(PlantKind::Floating, &results, &[Armature]).is_empty());
    }
}
