//! Fitting one effect kind's parameter on candidate units: a grid over the library's range then a parabola through
//! the best grid point and its neighbours, on the training windows, each unit scored on its own columns; the IMU
//! effects in closed form. Fits only; whether a fit explains anything held out is the judge's question
//! ([`super::judge`]).
//!
//! Units are fitted in lockstep sets: the units of one set act on different limbs (every limb at once, or the k-th
//! joint of every limb), and with the pelvis held still a limb's effect barely moves another limb, so one replay
//! per grid value serves every unit of the set.
use super::options::PlantKind;
use super::replay::{rot_residual, Ctx, Plant, Scores, IMU_STRIDE};
use super::stats::mean;
use crate::effects::{EffectKind, Scope};
use crate::plant::{imu_reading, Effects, DT, GROUPS};
use crate::GapError;
use rand::Rng;

/// A fitted value closer to the no-effect value than this fraction of the search range is below resolution: no
/// candidate (the grid's resolution, a fraction of one grid cell).
pub const RESOLUTION_FRAC: f64 = 0.02;

/// A fitted value within this fraction of its search range from a bound other than the no-effect end sits on the
/// bound: the fit wanted more than the range holds (the parabola's vertex clamps to the bound).
pub const AT_BOUND_FRAC: f64 = 0.005;

/// Grid values per fit across the range (the no-effect value is the baseline, already scored); the parabola through
/// the best and its neighbours refines it.
const GRID: usize = 5;

/// Bootstrap resamples of the parabola that give a fit's standard deviation.
const SD_RESAMPLES: usize = 50;

/// What an effect's parameter acts on.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Unit {
    /// The whole robot (latency, ground contact).
    Robot,
    /// The IMU (three axes, fitted in closed form).
    Imu,
    /// Every joint of a limb at one value.
    Group { index: usize, name: String, joints: Vec<usize> },
    /// One joint; `limb` holds the joints of its limb (the columns it is scored on: a link's mass or COM shows in
    /// the joints that carry it, not only its own).
    Joint { index: usize, name: String, limb: Vec<usize> },
}

impl Unit {
    /// A joint, a limb, `robot` or `imu`.
    pub fn name(&self) -> &str {
        match self {
            Unit::Robot => "robot",
            Unit::Imu => "imu",
            Unit::Group { name, .. } | Unit::Joint { name, .. } => name,
        }
    }

    /// The joints it sets (none for the robot and the IMU).
    pub fn joints(&self) -> Vec<usize> {
        match self {
            Unit::Robot | Unit::Imu => vec![],
            Unit::Group { joints, .. } => joints.clone(),
            Unit::Joint { index, .. } => vec![*index],
        }
    }

    /// Whether `other` acts on a subset of what this unit acts on.
    pub fn contains(&self, other: &Unit) -> bool {
        match (self, other) {
            (Unit::Robot, Unit::Robot) | (Unit::Imu, Unit::Imu) => true,
            (Unit::Robot | Unit::Imu, _) | (_, Unit::Robot | Unit::Imu) => false,
            _ => other.joints().iter().all(|j| self.joints().contains(j)),
        }
    }

    /// Whether the two act on some joint in common (the robot acts on every joint; the IMU only on itself).
    pub fn overlaps(&self, other: &Unit) -> bool {
        match (self, other) {
            (Unit::Imu, Unit::Imu) => true,
            (Unit::Imu, _) | (_, Unit::Imu) => false,
            (Unit::Robot, _) | (_, Unit::Robot) => true,
            _ => other.joints().iter().any(|j| self.joints().contains(j)),
        }
    }

    /// The score columns it is judged on: its limb's joints, every column for the robot, the IMU's for the IMU.
    pub fn score_columns(&self, ctx: &Ctx<'_>) -> Vec<usize> {
        match self {
            Unit::Robot => (0..=ctx.nj()).collect(),
            Unit::Imu => vec![ctx.nj()],
            Unit::Group { joints, .. } => joints.clone(),
            Unit::Joint { limb, .. } => limb.clone(),
        }
    }

    /// Sets `kind`'s parameter on this unit to `v` (the IMU's three axes are set by [`FittedUnit::apply`]).
    pub fn set(&self, kind: EffectKind, fx: &mut Effects, v: f64) {
        match self {
            Unit::Robot => kind.set(fx, 0, v),
            Unit::Imu => {}
            Unit::Group { joints, .. } => joints.iter().for_each(|&j| kind.set(fx, j, v)),
            Unit::Joint { index, .. } => kind.set(fx, *index, v),
        }
    }
}

/// One unit's fitted parameter.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct FittedUnit {
    pub unit: Unit,
    /// The fitted value (internal units; the IMU: the norm of its three axes).
    pub value: f64,
    /// Bootstrap standard deviation over training windows.
    pub sd: f64,
    /// The IMU's three axes (IMU effects only).
    pub axes: Option<[f64; 3]>,
}

impl FittedUnit {
    /// Sets the fitted parameter of `kind` in `fx`.
    pub fn apply(&self, kind: EffectKind, fx: &mut Effects) {
        match self.axes {
            Some(a) => (0..3).for_each(|k| kind.set(fx, k, a[k])),
            None => self.unit.set(kind, fx, self.value),
        }
    }
}

/// The limbs of the model: per group of [`GROUPS`], its joints.
pub(super) fn limbs(ctx: &Ctx<'_>) -> Vec<Vec<usize>> {
    (0..GROUPS.len()).map(|g| (0..ctx.nj()).filter(|&j| ctx.groups[j] == g).collect()).collect()
}

/// The lockstep sets of `kind`'s candidate units: the robot, the IMU, or, for joint-level kinds, every limb at once
/// and then the k-th joint of every limb (a limb of one joint is its joint), its joints ranked by their residual in
/// `train` (training scores), the first `per_limb` of each.
pub(super) fn lockstep_sets(ctx: &Ctx<'_>, kind: EffectKind, train: &Scores, per_limb: usize) -> Vec<Vec<Unit>> {
    match kind.scope() {
        Scope::Global => vec![vec![Unit::Robot]],
        Scope::Imu => vec![vec![Unit::Imu]],
        Scope::Joint | Scope::Group => {
            let limbs = limbs(ctx);
            let mut sets = vec![limbs
                .iter()
                .enumerate()
                .filter(|(_, js)| !js.is_empty())
                .map(|(g, js)| group_unit(ctx, g, js))
                .collect::<Vec<Unit>>()];
            let residual = |j: usize| train.iter().filter_map(|w| w.get(j)).sum::<f64>();
            let ranked: Vec<Vec<usize>> = limbs
                .iter()
                .map(|js| {
                    let mut r = js.clone();
                    r.sort_by(|&a, &b| residual(b).total_cmp(&residual(a)));
                    r
                })
                .collect();
            for k in 0..per_limb {
                let set: Vec<Unit> = ranked
                    .iter()
                    .zip(&limbs)
                    .filter(|(js, _)| js.len() > 1)
                    .filter_map(|(r, js)| r.get(k).map(|&j| joint_unit(ctx, j, js)))
                    .collect();
                if !set.is_empty() {
                    sets.push(set);
                }
            }
            sets
        }
    }
}

fn group_unit(ctx: &Ctx<'_>, g: usize, joints: &[usize]) -> Unit {
    // A limb of one joint (the waist) is named by its joint.
    if let [j] = joints {
        return Unit::Joint { index: *j, name: ctx.model.joints[*j].motor_name.clone(), limb: joints.to_vec() };
    }
    Unit::Group { index: g, name: GROUPS[g].into(), joints: joints.to_vec() }
}

fn joint_unit(ctx: &Ctx<'_>, j: usize, limb: &[usize]) -> Unit {
    Unit::Joint { index: j, name: ctx.model.joints[j].motor_name.clone(), limb: limb.to_vec() }
}

/// Parameter in report units (latency in ms).
pub(super) fn report_value(kind: EffectKind, v: f64) -> f64 {
    if kind == EffectKind::Latency {
        v * DT * 1e3
    } else {
        v
    }
}

/// Whether a fitted value is within the grid's resolution of the no-effect value.
pub(super) fn below_resolution(kind: EffectKind, v: f64) -> bool {
    let (lo, hi, v0) = kind.range();
    (v - v0).abs() < RESOLUTION_FRAC * (hi - lo)
}

/// Whether a fitted value sits on a bound of the range other than the no-effect end.
pub(super) fn at_bound(kind: EffectKind, v: f64) -> bool {
    let (lo, hi, v0) = kind.range();
    let edge = AT_BOUND_FRAC * (hi - lo);
    ((v - lo).abs() <= edge && (v0 - lo).abs() > edge) || ((hi - v).abs() <= edge && (hi - v0).abs() > edge)
}

/// Fits `kind` on every unit of `set`, on top of `base` (whose training scores are `base_train`).
pub(super) fn fit_set(
    ctx: &Ctx<'_>,
    kind: EffectKind,
    base: &Effects,
    base_train: &Scores,
    set: &[Unit],
    rng: &mut impl Rng,
) -> Result<Vec<FittedUnit>, GapError> {
    if kind.scope() == Scope::Imu {
        return Ok(vec![fit_imu(ctx, kind)?]);
    }
    let (lo, hi, v0) = kind.range();
    let cols: Vec<Vec<usize>> = set.iter().map(|u| u.score_columns(ctx)).collect();
    // Per training window, unit u's score.
    let per_window =
        |s: &Scores, u: usize| -> Vec<f64> { s.iter().map(|w| cols[u].iter().map(|&c| w[c]).sum()).collect() };
    let with = |vals: &[f64]| -> Effects {
        let mut fx = base.clone();
        set.iter().zip(vals).for_each(|(u, &v)| u.set(kind, &mut fx, v));
        fx
    };
    let grid: Vec<f64> = if kind == EffectKind::Latency {
        (0..=hi.round() as usize).step_by(2).map(|k| k as f64).filter(|&v| v != v0).collect()
    } else {
        (0..GRID).map(|i| lo + (hi - lo) * i as f64 / (GRID - 1) as f64).filter(|&v| (v - v0).abs() > 1e-12).collect()
    };
    let cfgs: Vec<Effects> = grid.iter().map(|&v| with(&vec![v; set.len()])).collect();
    let scores = ctx.eval_many(&cfgs, &ctx.train)?;
    // Every unit's (value, per-window scores), the no-effect value included, in value order.
    let mut out = Vec::with_capacity(set.len());
    let mut refined = Vec::with_capacity(set.len());
    let mut curves: Vec<Vec<(f64, Vec<f64>)>> = Vec::with_capacity(set.len());
    for u in 0..set.len() {
        let mut curve: Vec<(f64, Vec<f64>)> = std::iter::once((v0, per_window(base_train, u)))
            .chain(grid.iter().zip(&scores).map(|(&v, s)| (v, per_window(s, u))))
            .collect();
        curve.sort_by(|a, b| a.0.total_cmp(&b.0));
        let sums: Vec<f64> = curve.iter().map(|(_, s)| s.iter().sum()).collect();
        let best = (0..curve.len()).min_by(|&a, &b| sums[a].total_cmp(&sums[b])).unwrap_or(0);
        refined.push(if kind == EffectKind::Latency {
            curve[best].0
        } else {
            vertex(&curve, &sums, best).clamp(lo, hi)
        });
        curves.push(curve);
    }
    // Latency: the odd steps beside the best even one; others: the refined value, kept when it scores better.
    let mut trial_sets: Vec<Vec<f64>> = Vec::new();
    if kind == EffectKind::Latency {
        trial_sets.push(refined.iter().map(|v| (v - 1.0).max(0.0)).collect());
        trial_sets.push(refined.iter().map(|v| (v + 1.0).min(hi)).collect());
    } else {
        trial_sets.push(refined.clone());
    }
    // A trial whose units all sit at the no-effect value or all at one grid value is a configuration already
    // replayed: replays are deterministic, so its scores are those (an absent effect of a one-sided kind fits the
    // no-effect end on every unit).
    let replayed = |vals: &[f64]| -> Option<&Scores> {
        let first = *vals.first()?;
        if vals.iter().any(|&v| v.to_bits() != first.to_bits()) {
            return None;
        }
        if first.to_bits() == v0.to_bits() {
            return Some(base_train);
        }
        grid.iter().position(|&g| g.to_bits() == first.to_bits()).and_then(|i| scores.get(i))
    };
    let fresh: Vec<Effects> = trial_sets.iter().filter(|v| replayed(v).is_none()).map(|v| with(v)).collect();
    let mut fresh_scores = ctx.eval_many(&fresh, &ctx.train)?.into_iter();
    let mut trial_scores: Vec<Scores> = Vec::with_capacity(trial_sets.len());
    for vals in &trial_sets {
        match replayed(vals) {
            Some(s) => trial_scores.push(s.clone()),
            None => trial_scores
                .push(fresh_scores.next().ok_or_else(|| GapError::Numerics("a fit's trial replay is missing".into()))?),
        }
    }
    for (u, unit) in set.iter().enumerate() {
        let curve = &mut curves[u];
        for (vals, s) in trial_sets.iter().zip(&trial_scores) {
            curve.push((vals[u], per_window(s, u)));
        }
        curve.sort_by(|a, b| a.0.total_cmp(&b.0));
        let sums: Vec<f64> = curve.iter().map(|(_, s)| s.iter().sum()).collect();
        let best = (0..curve.len()).min_by(|&a, &b| sums[a].total_cmp(&sums[b])).unwrap_or(0);
        let value = curve[best].0;
        let sd = if kind == EffectKind::Latency { 0.0 } else { vertex_sd(curve, best, rng) };
        out.push(FittedUnit { unit: unit.clone(), value, sd, axes: None });
    }
    Ok(out)
}

/// The vertex of the parabola through the best point of `curve` (values ascending, `sums` their total scores) and
/// its neighbours; the best point itself at an end of the curve or where the three points do not curve upward.
fn vertex(curve: &[(f64, Vec<f64>)], sums: &[f64], best: usize) -> f64 {
    if best == 0 || best + 1 >= curve.len() {
        return curve[best].0;
    }
    parabola_vertex([curve[best - 1].0, curve[best].0, curve[best + 1].0], [sums[best - 1], sums[best], sums[best + 1]])
        .unwrap_or(curve[best].0)
}

/// The vertex of the parabola through three points (x ascending), if it opens upward; within the outer two.
fn parabola_vertex(x: [f64; 3], y: [f64; 3]) -> Option<f64> {
    let (d1, d2) = (x[1] - x[0], x[2] - x[1]);
    if !(d1 > 0.0 && d2 > 0.0) {
        return None;
    }
    // Divided differences: the parabola is y0 + a (x - x0) + c (x - x0)(x - x1).
    let a = (y[1] - y[0]) / d1;
    let b = (y[2] - y[1]) / d2;
    let c = (b - a) / (x[2] - x[0]);
    if !(c > 0.0) {
        return None;
    }
    Some((0.5 * (x[0] + x[1] - a / c)).clamp(x[0], x[2]))
}

/// Standard deviation of the parabola's vertex around the best point over bootstrap resamples of the training windows
/// (0 at an end of the curve).
fn vertex_sd(curve: &[(f64, Vec<f64>)], best: usize, rng: &mut impl Rng) -> f64 {
    if best == 0 || best + 1 >= curve.len() {
        return 0.0;
    }
    let pts = [&curve[best - 1], &curve[best], &curve[best + 1]];
    let n = pts[1].1.len();
    if n < 2 {
        return 0.0;
    }
    let xs = [pts[0].0, pts[1].0, pts[2].0];
    let draws: Vec<f64> = (0..SD_RESAMPLES)
        .map(|_| {
            let mut ys = [0.0; 3];
            for _ in 0..n {
                let w = rng.gen_range(0..n);
                (0..3).for_each(|k| ys[k] += pts[k].1[w]);
            }
            parabola_vertex(xs, ys).unwrap_or(xs[1])
        })
        .collect();
    let m = mean(&draws);
    (draws.iter().map(|v| (v - m).powi(2)).sum::<f64>() / draws.len() as f64).sqrt()
}

/// IMU bias or misalignment in closed form: the mean residual on the training windows (rig: the reading predicted
/// from the logged joints; floating base: the no-effect window prediction, whose base state is estimated from the
/// IMU itself, so the residual grows from zero at the window start and the fit is conservative).
fn fit_imu(ctx: &Ctx<'_>, kind: EffectKind) -> Result<FittedUnit, GapError> {
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
    let mut axes = [0.0; 3];
    let mut var = 0.0;
    for k in 0..3 {
        let m = acc.iter().map(|a| a[k]).sum::<f64>() / n;
        axes[k] = m;
        // Samples within a window are correlated: count windows, not samples.
        var += acc.iter().map(|a| (a[k] - m).powi(2)).sum::<f64>() / n / ctx.train.len().max(1) as f64;
    }
    let value = axes.iter().map(|a| a * a).sum::<f64>().sqrt();
    Ok(FittedUnit { unit: Unit::Imu, value, sd: var.sqrt(), axes: Some(axes) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_parabola_through_three_points_finds_their_minimum() {
        // y = (x - 1.3)^2 + 2 at 1, 1.5, 2.
        let f = |x: f64| (x - 1.3).powi(2) + 2.0;
        let v = parabola_vertex([1.0, 1.5, 2.0], [f(1.0), f(1.5), f(2.0)]).expect("a vertex");
        assert!((v - 1.3).abs() < 1e-12, "{v}");
        // Unevenly spaced.
        let v = parabola_vertex([0.0, 1.0, 4.0], [f(0.0), f(1.0), f(4.0)]).expect("a vertex");
        assert!((v - 1.3).abs() < 1e-12, "{v}");
        // A maximum is no vertex.
        assert!(parabola_vertex([0.0, 1.0, 2.0], [0.0, 1.0, 0.0]).is_none());
    }

    #[test]
    fn a_value_on_a_bound_other_than_no_effect_is_at_the_bound() {
        use EffectKind::*;
        for kind in [Damping, Friction, Armature, GainScale, Backlash, LinkMass, EncoderOffset] {
            let (lo, hi, v0) = kind.range();
            assert!(at_bound(kind, hi), "{kind:?} {hi}");
            assert_eq!(at_bound(kind, lo), (v0 - lo).abs() > 1e-9, "{kind:?} {lo}");
            assert!(!at_bound(kind, 0.5 * (v0 + hi)), "{kind:?}");
            assert!(below_resolution(kind, v0) && !below_resolution(kind, 0.5 * (v0 + hi)), "{kind:?}");
        }
    }
}
