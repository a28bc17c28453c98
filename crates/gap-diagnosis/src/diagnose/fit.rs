//! Fitting one effect kind: per unit (joint, group, the robot or the IMU) a grid search then golden-section
//! refinement on the training windows, with a bootstrap spread; the IMU effects in closed form. Fits only; whether
//! a fit explains anything held out is decided by the stages above.
use super::options::PlantKind;
use super::replay::{rot_residual, Ctx, Plant, Scores, IMU_STRIDE};
use super::stats::mean;
use crate::effects::{EffectKind, Scope};
use crate::plant::{imu_reading, Effects, DT, GROUPS};
use crate::GapError;
use rand::Rng;

/// A fitted value closer to the no-effect value than this fraction of the search range is below resolution.
pub const RESOLUTION_FRAC: f64 = 0.04;

/// One effect fitted on the training windows.
pub(super) struct Fit {
    /// Every unit at its fitted value (on top of the effects the fit started from).
    pub fx: Effects,
    /// Per-unit bootstrap standard deviation (IMU: one, over the three axes).
    pub sds: Vec<f64>,
}

/// The units of one mask fitted together.
pub(super) struct UnitFit {
    /// Every unit's value (units outside the mask: unused).
    pub values: Vec<f64>,
    pub sds: Vec<f64>,
    /// Every unit's training score (the sum of its columns over the training windows) at its value.
    pub scores: Vec<f64>,
}

/// Columns (score indices) of each fitting unit of `kind`.
pub(super) fn units_of(ctx: &Ctx<'_>, kind: EffectKind) -> Vec<Vec<usize>> {
    let nj = ctx.nj();
    match kind.scope() {
        Scope::Global => vec![(0..=nj).collect()],
        Scope::Imu => vec![vec![nj]],
        Scope::Joint => (0..nj).map(|j| vec![j]).collect(),
        Scope::Group => (0..GROUPS.len()).map(|g| (0..nj).filter(|&j| ctx.groups[j] == g).collect()).collect(),
    }
}

/// The unit's name in the report: a joint, a group, `robot` or `imu`.
pub(super) fn unit_name(ctx: &Ctx<'_>, kind: EffectKind, u: usize) -> String {
    match kind.scope() {
        Scope::Global => "robot".into(),
        Scope::Imu => "imu".into(),
        Scope::Joint => ctx.model.joints[u].motor_name.clone(),
        Scope::Group => GROUPS[u].into(),
    }
}

/// Sets unit `u` of `kind` to `v` (IMU: `v` is unused, the closed form writes all three).
pub(super) fn set_unit(kind: EffectKind, fx: &mut Effects, ctx: &Ctx<'_>, u: usize, v: f64) {
    match kind.scope() {
        Scope::Global => kind.set(fx, 0, v),
        Scope::Joint => kind.set(fx, u, v),
        Scope::Group => (0..ctx.nj()).filter(|&j| ctx.groups[j] == u).for_each(|j| kind.set(fx, j, v)),
        Scope::Imu => {}
    }
}

/// The value of unit `u` of `kind` in `fx` (a group: its first joint's).
pub(super) fn unit_value(kind: EffectKind, fx: &Effects, ctx: &Ctx<'_>, u: usize) -> f64 {
    match kind.scope() {
        Scope::Global | Scope::Imu => kind.get(fx, 0),
        Scope::Joint => kind.get(fx, u),
        Scope::Group => (0..ctx.nj()).find(|&j| ctx.groups[j] == u).map_or(kind.range().2, |j| kind.get(fx, j)),
    }
}

/// Parameter in report units (latency in ms).
pub(super) fn report_value(kind: EffectKind, v: f64) -> f64 {
    if kind == EffectKind::Latency {
        v * DT * 1e3
    } else {
        v
    }
}

/// The masks of units that are set together: every unit at once, except joint-scope effects, which go one joint
/// per limb at a time (the k-th joint of every group together): neighbouring joints of a chain would otherwise
/// trade the effect between them.
pub(super) fn unit_sets(ctx: &Ctx<'_>, kind: EffectKind) -> Vec<Vec<bool>> {
    if kind.scope() == Scope::Joint {
        let pos: Vec<usize> =
            (0..ctx.nj()).map(|j| (0..j).filter(|&i| ctx.groups[i] == ctx.groups[j]).count()).collect();
        let maxp = pos.iter().copied().max().unwrap_or(0);
        (0..=maxp).map(|k| pos.iter().map(|&p| p == k).collect()).collect()
    } else {
        vec![vec![true; units_of(ctx, kind).len()]]
    }
}

/// Fits one effect on the training windows.
/// `base` holds effects already accepted (their units stay as they are) and `base_train` its training scores.
pub(super) fn fit_kind(
    ctx: &Ctx<'_>,
    kind: EffectKind,
    base: &Effects,
    base_train: &Scores,
    rng: &mut impl Rng,
) -> Result<Fit, GapError> {
    if kind.scope() == Scope::Imu {
        return fit_imu(ctx, kind);
    }
    let units = units_of(ctx, kind);
    let mut fx = base.clone();
    let mut sds = vec![0.0; units.len()];
    let sets = unit_sets(ctx, kind);
    let setter = |fx: &mut Effects, u: usize, v: f64| set_unit(kind, fx, ctx, u, v);
    for mask in sets {
        let fit = fit_units(ctx, kind, base, base_train, rng, &mask, &setter)?;
        for u in (0..units.len()).filter(|&u| mask[u]) {
            set_unit(kind, &mut fx, ctx, u, fit.values[u]);
            sds[u] = fit.sds[u];
        }
    }
    Ok(Fit { fx, sds })
}

/// A group-scope effect fitted on one joint per group (`joints[g]`, e.g. the joint carrying most of the group's
/// residual), each scored on its whole group's residual (a joint's effect also shows in its neighbours'): the
/// values per group and their training scores, to compare with the group fit and name a single joint when it
/// explains as much.
pub(super) fn fit_one_joint_per_group(
    ctx: &Ctx<'_>,
    kind: EffectKind,
    joints: &[usize],
    base: &Effects,
    base_train: &Scores,
    rng: &mut impl Rng,
) -> Result<UnitFit, GapError> {
    let mask = vec![true; units_of(ctx, kind).len()];
    let setter = |fx: &mut Effects, u: usize, v: f64| {
        if let Some(&j) = joints.get(u) {
            kind.set(fx, j, v)
        }
    };
    fit_units(ctx, kind, base, base_train, rng, &mask, &setter)
}

/// A joint or group effect fitted on the given joints only (a group unit on the one of its joints among them, scored
/// on the group's residual as [`fit_one_joint_per_group`]; the other units stay at no effect), on top of `base`:
/// the effect set and, per joint, its value and bootstrap standard deviation. `None` for the other scopes, or when
/// no unit holds one of the joints.
pub(super) fn fit_at_joints(
    ctx: &Ctx<'_>,
    kind: EffectKind,
    joints: &[usize],
    base: &Effects,
    base_train: &Scores,
    rng: &mut impl Rng,
) -> Result<Option<(Effects, Vec<(usize, f64, f64)>)>, GapError> {
    let units = units_of(ctx, kind);
    // Per unit, the joint it is fitted on.
    let at: Vec<Option<usize>> = match kind.scope() {
        Scope::Joint => (0..units.len()).map(|u| joints.contains(&u).then_some(u)).collect(),
        Scope::Group => units.iter().map(|cols| joints.iter().copied().find(|j| cols.contains(j))).collect(),
        Scope::Global | Scope::Imu => return Ok(None),
    };
    if at.iter().all(Option::is_none) {
        return Ok(None);
    }
    let mask: Vec<bool> = at.iter().map(Option::is_some).collect();
    let setter = |fx: &mut Effects, u: usize, v: f64| {
        if let Some(Some(j)) = at.get(u) {
            kind.set(fx, *j, v)
        }
    };
    let fit = fit_units(ctx, kind, base, base_train, rng, &mask, &setter)?;
    let mut fx = base.clone();
    let mut values = Vec::new();
    for (u, j) in at.iter().enumerate() {
        if let Some(j) = *j {
            kind.set(&mut fx, j, fit.values[u]);
            values.push((j, fit.values[u], fit.sds[u]));
        }
    }
    Ok(Some((fx, values)))
}

/// Grid search then lockstep golden-section refinement of the units in `mask` (the others stay at no effect);
/// `set` writes a unit's value into an effect set (each unit is scored on its own columns, [`units_of`]);
/// returns every unit's value and bootstrap standard deviation.
fn fit_units(
    ctx: &Ctx<'_>,
    kind: EffectKind,
    base: &Effects,
    base_train: &Scores,
    rng: &mut impl Rng,
    mask: &[bool],
    set: &dyn Fn(&mut Effects, usize, f64),
) -> Result<UnitFit, GapError> {
    let null = base.clone();
    let units = units_of(ctx, kind);
    let (lo, hi, v0) = kind.range();
    let unit_score =
        |s: &Scores, u: usize| -> f64 { s.iter().map(|w| units[u].iter().map(|&c| w[c]).sum::<f64>()).sum() };
    let with_values = |vals: &[f64]| -> Effects {
        let mut fx = null.clone();
        for (u, &v) in vals.iter().enumerate() {
            if mask[u] {
                set(&mut fx, u, v);
            }
        }
        fx
    };
    // Grid (integers for latency).
    let grid: Vec<f64> = if kind == EffectKind::Latency {
        (0..=hi as usize).map(|k| k as f64).collect()
    } else {
        let n = 9;
        let mut g: Vec<f64> = (0..n).map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64).collect();
        g.push(v0);
        g.sort_by(f64::total_cmp);
        g.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
        g
    };
    let cfgs: Vec<Effects> =
        grid.iter().filter(|&&v| (v - v0).abs() > 1e-12).map(|&v| with_values(&vec![v; units.len()])).collect();
    let grid_nz: Vec<f64> = grid.iter().copied().filter(|&v| (v - v0).abs() > 1e-12).collect();
    let scores = ctx.eval_many(&cfgs, &ctx.train)?;
    let mut best = vec![(v0, f64::INFINITY); units.len()];
    for (u, b) in best.iter_mut().enumerate() {
        *b = (v0, unit_score(base_train, u));
        for (k, s) in scores.iter().enumerate() {
            let sc = unit_score(s, u);
            if sc < b.1 {
                *b = (grid_nz[k], sc);
            }
        }
    }
    if kind == EffectKind::Latency {
        return Ok(UnitFit { values: vec![best[0].0], sds: vec![0.0], scores: vec![best[0].1] });
    }
    // Golden-section refinement of every unit in lockstep within the neighbouring grid cells.
    let step = grid.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    let mut a: Vec<f64> = best.iter().map(|b| (b.0 - step).max(lo)).collect();
    let mut b: Vec<f64> = best.iter().map(|b| (b.0 + step).min(hi)).collect();
    let gr = 0.618_033_988_749_895;
    let mut x1: Vec<f64> = (0..units.len()).map(|u| b[u] - gr * (b[u] - a[u])).collect();
    let mut x2: Vec<f64> = (0..units.len()).map(|u| a[u] + gr * (b[u] - a[u])).collect();
    let s12 = ctx.eval_many(&[with_values(&x1), with_values(&x2)], &ctx.train)?;
    let mut f1: Vec<f64> = (0..units.len()).map(|u| unit_score(&s12[0], u)).collect();
    let mut f2: Vec<f64> = (0..units.len()).map(|u| unit_score(&s12[1], u)).collect();
    for _ in 0..4 {
        // Each unit moves its own bracket; the new trial points are evaluated together.
        let mut trial = vec![0.0; units.len()];
        let mut left = vec![false; units.len()];
        for u in 0..units.len() {
            if f1[u] < f2[u] {
                b[u] = x2[u];
                x2[u] = x1[u];
                f2[u] = f1[u];
                x1[u] = b[u] - gr * (b[u] - a[u]);
                trial[u] = x1[u];
                left[u] = true;
            } else {
                a[u] = x1[u];
                x1[u] = x2[u];
                f1[u] = f2[u];
                x2[u] = a[u] + gr * (b[u] - a[u]);
                trial[u] = x2[u];
            }
        }
        let s = ctx.eval_many(&[with_values(&trial)], &ctx.train)?.remove(0);
        for u in 0..units.len() {
            let f = unit_score(&s, u);
            if left[u] {
                f1[u] = f;
            } else {
                f2[u] = f;
            }
        }
    }
    let mut vals = vec![0.0; units.len()];
    let mut scores = vec![0.0; units.len()];
    for u in 0..units.len() {
        let (xr, fr) = if f1[u] < f2[u] { (x1[u], f1[u]) } else { (x2[u], f2[u]) };
        (vals[u], scores[u]) = if fr < best[u].1 { (xr, fr) } else { best[u] };
    }
    // Uncertainty: a parabola through (v-h, v, v+h) on bootstrap resamples of the training windows.
    let h = 0.05 * (hi - lo);
    let minus: Vec<f64> = vals.iter().map(|v| v - h).collect();
    let plus: Vec<f64> = vals.iter().map(|v| v + h).collect();
    let s3 = ctx.eval_many(&[with_values(&minus), with_values(&vals), with_values(&plus)], &ctx.train)?;
    let nwin = ctx.train.len();
    let mut sds = vec![0.0; units.len()];
    for u in 0..units.len() {
        let per: Vec<[f64; 3]> = (0..nwin)
            .map(|w| {
                let f = |s: &Scores| units[u].iter().map(|&c| s[w][c]).sum::<f64>();
                [f(&s3[0]), f(&s3[1]), f(&s3[2])]
            })
            .collect();
        let mut vs = Vec::new();
        for _ in 0..50 {
            let mut acc = [0.0; 3];
            for _ in 0..nwin {
                let p = per[rng.gen_range(0..nwin)];
                (0..3).for_each(|k| acc[k] += p[k]);
            }
            let curv = acc[0] - 2.0 * acc[1] + acc[2];
            let shift =
                if curv > 0.0 { (h * (acc[0] - acc[2]) / (2.0 * curv)).clamp(-3.0 * h, 3.0 * h) } else { 3.0 * h };
            vs.push(vals[u] + shift);
        }
        let m = mean(&vs);
        sds[u] = (vs.iter().map(|v| (v - m).powi(2)).sum::<f64>() / vs.len() as f64).sqrt();
    }
    Ok(UnitFit { values: vals, sds, scores })
}

/// IMU bias or misalignment in closed form: the mean residual on the training windows (rig: the reading predicted
/// from the logged joints; floating base: the no-effect window prediction, whose base state is estimated from the
/// IMU itself, so the residual grows from zero at the window start and the fit is conservative).
fn fit_imu(ctx: &Ctx<'_>, kind: EffectKind) -> Result<Fit, GapError> {
    let null = Effects::none(ctx.nj());
    let mut acc = Vec::new();
    let mut floating_plant = match ctx.plant {
        PlantKind::Floating => Some(Plant::new(PlantKind::Floating, ctx.model, ctx.opts, &null)?),
        PlantKind::Rig => None,
    };
    for &w in &ctx.train {
        let start = ctx.starts[w];
        let pred = match floating_plant.as_mut() {
            Some(p) => Some(p.predict(ctx.model, ctx.feet.as_ref(), ctx.log, &null, start, ctx.len, true)?),
            None => None,
        };
        for k in (1..=ctx.len).step_by(IMU_STRIDE) {
            let Some(m) = ctx.log.states.get(start + k) else { break };
            let (quat, gyro) = match pred.as_ref().and_then(|p| p.get(k - 1)) {
                Some(p) => (p.quat, p.gyro),
                None if pred.is_some() => break,
                None => imu_reading(ctx.model, &m.q, &m.dq, &null)?,
            };
            acc.push(match kind {
                EffectKind::ImuBias => [m.gyro[0] - gyro[0], m.gyro[1] - gyro[1], m.gyro[2] - gyro[2]],
                _ => rot_residual(&m.quat, &quat),
            });
        }
    }
    let n = acc.len().max(1) as f64;
    let mut fx = null.clone();
    let mut sds = Vec::new();
    for k in 0..3 {
        let m = acc.iter().map(|a| a[k]).sum::<f64>() / n;
        kind.set(&mut fx, k, m);
        let var = acc.iter().map(|a| (a[k] - m).powi(2)).sum::<f64>() / n;
        // Samples within a window are correlated: count windows, not samples.
        sds.push((var / ctx.train.len().max(1) as f64).sqrt());
    }
    let sd = sds.iter().map(|s| s * s).sum::<f64>().sqrt();
    Ok(Fit { fx, sds: vec![sd] })
}
