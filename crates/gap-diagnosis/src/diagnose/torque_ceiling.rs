//! Whether the log's own torque contradicts a fitted torque saturation (issue 14 item 6). A saturation is a ceiling
//! on the torque the motor delivers, and `tau_est` reports the delivered torque (a motor's current estimate; the
//! benchmark's plants and the effect layer report it after the clamp): a unit whose fitted ceiling the logged torque
//! exceeds, often and by more than noise or a fitting error, did not fit a saturation but stood in for another effect
//! that slows the joint under high torque (an added armature: Rapier seed 4's trial 6 named a ceiling of 0.68 of the
//! limit on a shoulder whose logged torque reaches 1.5 times that in 27 % of its samples). A true saturation's
//! logged torque stays under its ceiling by construction. A group fit of a one-joint saturation puts the ceiling on
//! every joint of the group, and a joint that really carries more contradicts it there only: the ceiling is taken
//! off the contradicted joints and the unit kept on the others (Rapier seed 1's trial 6: a hip roll's saturation,
//! fitted on the whole left leg at 0.38, which the ankle pitch exceeds in 14 % of the samples).
use super::replay::Ctx;
use crate::effects::EffectKind;
use crate::plant::Effects;

/// A logged torque counts against the ceiling only beyond this multiple of it (noise, a fitted value a little low).
pub const CEILING_MARGIN: f64 = 1.1;
/// A unit is contradicted when some joint's logged torque exceeds [`CEILING_MARGIN`] times its fitted ceiling in more
/// than this fraction of the log's samples.
pub const MAX_FRACTION_ABOVE: f64 = 0.10;

/// The joints whose torque `fx` limits and whose logged |tau_est| exceeds [`CEILING_MARGIN`] times their fitted
/// ceiling (the speed-independent one: the fitted scale times the torque limit) in more than [`MAX_FRACTION_ABOVE`]
/// of the log's samples.
pub(super) fn joints_above_ceiling(ctx: &Ctx<'_>, fx: &Effects) -> Vec<usize> {
    let kind = EffectKind::TorqueSaturation;
    let v0 = kind.range().2;
    let n = ctx.log.states.len().max(1) as f64;
    (0..ctx.nj())
        .filter(|&j| kind.get(fx, j) < v0)
        .filter(|&j| {
            let Some(m) = ctx.model.joints.get(j) else { return false };
            let ceiling = CEILING_MARGIN * kind.get(fx, j) * m.torque_limit;
            let above = ctx.log.states.iter().filter(|s| s.tau.get(j).is_some_and(|t| t.abs() > ceiling)).count();
            above as f64 / n > MAX_FRACTION_ABOVE
        })
        .collect()
}
