//! Identifiability: could this log show each effect at all? For every effect kind, the held-out windows are
//! replayed with each candidate unit at the kind's magnitude of interest ([`EffectKind::magnitude_of_interest`]) and
//! without it; how far the two simulations move apart on the unit's columns, in the gap metric's units, is the
//! *signal* an effect of that size would add. Were the effect in the log, the judge's evidence for it would be about
//! the log-likelihood gain of removing that signal from the baseline residual, `Σ_c ln((b + d + ν) / (b + ν))` per
//! window where it acts; under [`super::Thresholds::min_gain`] the log cannot reveal the effect there, whatever a fit says: the
//! report says so, with the motion that would reveal it ([`EffectKind::revealed_by`]). Simulator sensitivities only (no log residual in the signal): an effect is
//! unidentifiable because the log's motion does not excite it, not because the data happen to hide it.
use super::fit::{lockstep_sets, report_value};
use super::options::PlantKind;
use super::replay::{Ctx, Scores};
use super::stats::{log_gain, mean};
use super::Thresholds;
use crate::effects::{EffectKind, Scope};
use crate::plant::Effects;
use crate::GapError;
use serde::{Deserialize, Serialize};

/// One unit (joint, group or the robot): the evidence an effect of the magnitude of interest would give there, and
/// the evidence a named effect needs.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct UnitSignal {
    pub unit: String,
    /// Mean over held-out windows of the log-likelihood gain the effect's signal (the normalised squared difference
    /// between the simulation with the effect and without it) would give on top of the baseline residual, on the
    /// unit's columns.
    pub signal: f64,
    /// [`super::Thresholds::min_gain`].
    pub floor: f64,
}

impl UnitSignal {
    pub fn identifiable(&self) -> bool {
        self.signal >= self.floor
    }
}

/// One effect kind: where this log could reveal it at the magnitude of interest.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Identifiability {
    pub kind: EffectKind,
    /// The magnitude asked about, in the report's units (latency in ms).
    pub magnitude: f64,
    /// Every unit, in the fit's order.
    pub units: Vec<UnitSignal>,
    /// The motion that would reveal it (said when some unit is not identifiable).
    pub revealed_by: Option<String>,
}

impl Identifiability {
    /// The units on which the log could reveal the effect.
    pub fn identifiable_units(&self) -> Vec<&str> {
        self.units.iter().filter(|u| u.identifiable()).map(|u| u.unit.as_str()).collect()
    }

    /// The magnitude as the report prints it (three decimals, no trailing zeros).
    pub fn magnitude_text(&self) -> String {
        format!("{}", (self.magnitude * 1000.0).round() / 1000.0)
    }

    /// The largest signal-to-floor ratio over the units.
    pub fn best_ratio(&self) -> f64 {
        self.units.iter().map(|u| if u.floor > 0.0 { u.signal / u.floor } else { f64::INFINITY }).fold(0.0, f64::max)
    }
}

/// Every replayed effect kind of `kinds` (IMU effects are fitted in closed form from the IMU residual and ground
/// contact effects cannot be fitted on the rig: neither is listed). `baseline`: every window's baseline scores.
pub(super) fn identify(
    ctx: &Ctx<'_>,
    baseline: &Scores,
    kinds: &[EffectKind],
    th: &Thresholds,
) -> Result<Vec<Identifiability>, GapError> {
    let windows = &ctx.test;
    if windows.is_empty() {
        return Ok(Vec::new());
    }
    let none = Effects::none(ctx.nj());
    let without = ctx.predictions(&none, windows)?;
    let train: Scores = ctx.train.iter().filter_map(|&w| baseline.get(w).cloned()).collect();
    let base: Scores = windows.iter().filter_map(|&w| baseline.get(w).cloned()).collect();
    let floor = th.min_gain;
    let mut out = Vec::new();
    for &kind in kinds {
        if kind.scope() == Scope::Imu || (ctx.plant == PlantKind::Rig && !kind.identifiable_suspended()) {
            continue;
        }
        let m = kind.magnitude_of_interest();
        let mut units = Vec::new();
        for set in lockstep_sets(ctx, kind, &train, th.joints_per_limb) {
            let mut fx = none.clone();
            set.iter().for_each(|u| u.set(kind, &mut fx, m));
            let with = ctx.predictions(&fx, windows)?;
            let diffs: Vec<Vec<f64>> = without.iter().zip(&with).map(|(a, b)| ctx.difference_scores(a, b)).collect();
            // The residual with the signal on top of the baseline: the log as it would be with the effect in it.
            let with_signal: Scores =
                base.iter().zip(&diffs).map(|(b, d)| b.iter().zip(d).map(|(x, y)| x + y).collect()).collect();
            for u in &set {
                let cols: Vec<usize> = u.score_columns(ctx).into_iter().filter(|&c| c < ctx.nj()).collect();
                // Over the windows where the effect acts, as the judge's test (a) weighs it.
                let gains = log_gain(&with_signal, &base, Some(&cols), &ctx.noise);
                let acting: Vec<f64> = gains
                    .iter()
                    .zip(&diffs)
                    .filter(|(_, d)| cols.iter().any(|&c| d.get(c).is_some_and(|&x| x != 0.0)))
                    .map(|(&g, _)| g)
                    .collect();
                let signal = mean(&acting);
                units.push(UnitSignal { unit: u.name().into(), signal, floor });
            }
        }
        let all = units.iter().all(UnitSignal::identifiable);
        out.push(Identifiability {
            kind,
            magnitude: report_value(kind, m),
            units,
            revealed_by: (!all).then(|| kind.revealed_by().to_string()),
        });
    }
    Ok(out)
}

/// The abstention note's addition for an effect no unit of which could show at the magnitude of interest.
pub(super) fn not_identifiable_note(i: &Identifiability) -> Option<String> {
    if !i.identifiable_units().is_empty() {
        return None;
    }
    Some(format!(
        "not identifiable from this log: at {} ({}) it would give no unit the evidence a named effect needs (at best \
         {:.0} % of it); {} would reveal it",
        i.magnitude_text(),
        i.kind.parameter(),
        100.0 * i.best_ratio(),
        i.kind.revealed_by()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ident(signals: &[(f64, f64)]) -> Identifiability {
        Identifiability {
            kind: EffectKind::Friction,
            magnitude: 1.0,
            units: signals
                .iter()
                .enumerate()
                .map(|(i, &(signal, floor))| UnitSignal { unit: format!("u{i}"), signal, floor })
                .collect(),
            revealed_by: None,
        }
    }

    #[test]
    fn a_unit_is_identifiable_when_its_signal_reaches_the_floor() {
        let i = ident(&[(0.5, 1.0), (2.0, 1.0), (1.0, 1.0)]);
        assert_eq!(i.identifiable_units(), vec!["u1", "u2"]);
        assert!((i.best_ratio() - 2.0).abs() < 1e-12);
        assert!(not_identifiable_note(&i).is_none());
    }

    #[test]
    fn the_note_speaks_only_when_no_unit_could_show_the_effect() {
        let i = ident(&[(0.25, 1.0), (0.1, 1.0)]);
        let note = not_identifiable_note(&i).expect("note");
        assert!(note.contains("25 %") && note.contains(EffectKind::Friction.revealed_by()), "{note}");
    }
}
