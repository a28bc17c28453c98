//! Effects this log cannot tell apart (issue 14 item 6). Each named joint-space effect, alone at its fitted
//! values, changes the predicted measurements of the held-out windows; two effects whose changes are nearly
//! collinear (a COM shift of the forearm and an elbow encoder offset under slow motion both shift the elbow's
//! gravity torque) and that leave held-out gaps the log cannot rank (the paired difference's 95 % interval holds 0,
//! or the difference is under the noise floor a named effect must clear) explain the log the same way, whatever their order in the ranking. They are reported as one ambiguous set, so
//! that the first name of such a set is not read as a confident first effect.
use super::assess::EffectResult;
use super::replay::Ctx;
use super::stats::{bootstrap_mean, mean, noise_floor, total};
use crate::effects::{EffectKind, Scope};
use crate::plant::Effects;
use crate::GapError;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Two effects can be ambiguous when the cosine of their prediction changes (in the gap metric's normalised units)
/// is at least this in magnitude (a change and its opposite are equally ambiguous: the fit picks the sign).
pub const AMBIGUOUS_COSINE: f64 = 0.8;

/// Named effects the log cannot tell apart.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct AmbiguousSet {
    /// In rank order.
    pub effects: Vec<EffectKind>,
    /// The smallest |cosine| between the prediction changes of two members linked in the set.
    pub cosine: f64,
    /// The largest difference of the held-out gap between two linked members alone, relative to the baseline gap
    /// (each such difference is under the noise floor or its interval holds 0).
    pub gap_difference: f64,
    /// Members whose fit sits at the edge of its search range ([`EffectResult::at_search_bound`]).
    #[serde(default)]
    pub at_bound: Vec<EffectKind>,
    /// Why the log cannot tell them apart.
    #[serde(default)]
    pub reason: Ambiguity,
}

/// Why the effects of an [`AmbiguousSet`] cannot be told apart.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Ambiguity {
    /// Named effects whose prediction changes, each alone, are nearly collinear (|cosine| at least
    /// [`AMBIGUOUS_COSINE`]) and whose held-out gaps the log cannot rank (`diagnose/confound.rs`).
    #[default]
    Collinear,
    /// A masked effect (`diagnose/unmask.rs`), or a candidate the selection added after the first, and its rivals
    /// (masked effects): each, refitted with the combination before it applied, cuts what that combination leaves on
    /// the same limb beyond its noise floor, and the log cannot rank their cuts (here `cosine` compares their changes
    /// given the combination and `gap_difference` is relative to the residual the combination leaves). The first is
    /// named; the others are not, but are as likely. Also an effect named on part of the held-out windows only (the
    /// trimmed ones or those away from the range limits) on single joints, and the effects that, fitted on those
    /// joints, cut as much there (`rivals_on_joints` in `diagnose/unmask.rs`: an elbow encoder offset and a COM shift of
    /// the forearm).
    EqualCut,
}

impl AmbiguousSet {
    /// Whether `a` and `b` are both in this set.
    pub fn links(&self, a: EffectKind, b: EffectKind) -> bool {
        self.effects.contains(&a) && self.effects.contains(&b)
    }
}

#[cfg(test)]
impl AmbiguousSet {
    /// A collinear set of `effects` for the tests of the stages that read sets.
    pub(super) fn for_test(effects: Vec<EffectKind>) -> Self {
        AmbiguousSet { effects, cosine: 0.9, gap_difference: 0.0, at_bound: vec![], reason: Ambiguity::Collinear }
    }
}

/// The ambiguous sets among `named` (rank order, each with its fitted effect alone). IMU effects act on the IMU
/// reading only, which no joint effect predicts, and are not compared.
pub(super) fn ambiguous_sets(
    ctx: &Ctx<'_>,
    named: &[(EffectKind, Effects)],
    baseline_tot: &[f64],
    rng: &mut impl Rng,
) -> Result<Vec<AmbiguousSet>, GapError> {
    let joint: Vec<&(EffectKind, Effects)> = named.iter().filter(|(k, _)| k.scope() != Scope::Imu).collect();
    if joint.len() < 2 || ctx.test.is_empty() {
        return Ok(Vec::new());
    }
    let none = ctx.predictions(&Effects::none(ctx.nj()), &ctx.test)?;
    let fxs: Vec<Effects> = joint.iter().map(|(_, fx)| fx.clone()).collect();
    let totals: Vec<Vec<f64>> =
        ctx.eval_many(&fxs, &ctx.test)?.iter().map(|sc| sc.iter().map(|w| total(w)).collect()).collect();
    let mut changes = Vec::with_capacity(joint.len());
    for (_, fx) in &joint {
        let with = ctx.predictions(fx, &ctx.test)?;
        changes.push(none.iter().zip(&with).flat_map(|(a, b)| ctx.normalised_change(a, b)).collect::<Vec<f64>>());
    }
    // Union of the linked pairs, in rank order.
    let mut set_of: Vec<usize> = (0..joint.len()).collect();
    let mut weakest: Vec<f64> = vec![1.0; joint.len()];
    let mut widest: Vec<f64> = vec![0.0; joint.len()];
    for a in 0..joint.len() {
        for b in a + 1..joint.len() {
            let c = cosine(&changes[a], &changes[b]).abs();
            if c < AMBIGUOUS_COSINE {
                continue;
            }
            let diffs: Vec<f64> = totals[a].iter().zip(&totals[b]).map(|(x, y)| x - y).collect();
            let d = bootstrap_mean(&diffs, ctx.opts.bootstrap, rng);
            let rel = d.value.abs() / mean(baseline_tot).max(1e-300);
            if (d.lo > 0.0 || d.hi < 0.0) && rel >= noise_floor(baseline_tot) {
                continue;
            }
            let (sa, sb) = (set_of[a], set_of[b]);
            let root = sa.min(sb);
            let low = weakest[sa].min(weakest[sb]).min(c);
            let wide = widest[sa].max(widest[sb]).max(rel);
            for s in set_of.iter_mut().filter(|s| **s == sa || **s == sb) {
                *s = root;
            }
            (weakest[root], widest[root]) = (low, wide);
        }
    }
    let mut sets = Vec::new();
    for root in 0..joint.len() {
        let members: Vec<EffectKind> = (0..joint.len()).filter(|&i| set_of[i] == root).map(|i| joint[i].0).collect();
        if members.len() >= 2 {
            sets.push(AmbiguousSet {
                effects: members,
                cosine: weakest[root],
                gap_difference: widest[root],
                at_bound: Vec::new(),
                reason: Ambiguity::Collinear,
            });
        }
    }
    Ok(sets)
}

/// Marks, in each ambiguous set, the members whose fit sits at the edge of its search range: information for the
/// reader (the optimum may lie beyond what the library allows, as when an effect stands in for another), not a
/// reason to reorder them: a true effect near the edge of the range fits there too (a 69 % heavier ankle link was
/// fitted at the 1.8x bound), and a rule that ranked such members last cost as many hits as it gained.
pub(super) fn mark_range_edges(sets: &mut [AmbiguousSet], effects: &[EffectResult]) {
    let at_bound = |k: EffectKind| effects.iter().any(|e| e.kind == k && e.named && e.at_search_bound());
    for set in sets.iter_mut() {
        set.at_bound = set.effects.iter().copied().filter(|&k| at_bound(k)).collect();
    }
}

/// Cosine of two vectors (0 when either is zero).
pub(super) fn cosine(a: &[f64], b: &[f64]) -> f64 {
    let dot: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    let na: f64 = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    let nb: f64 = b.iter().map(|x| x * x).sum::<f64>().sqrt();
    if na > 0.0 && nb > 0.0 {
        dot / (na * nb)
    } else {
        0.0
    }
}

/// Whether `kinds` (rank order) open with an ambiguous set: then the report gives the set, not its first name, as
/// the most explanatory effect.
pub fn leading_set<'a>(ranked: &[EffectKind], sets: &'a [AmbiguousSet]) -> Option<&'a AmbiguousSet> {
    let first = *ranked.first()?;
    sets.iter().find(|s| s.effects.contains(&first))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn named(kind: EffectKind, value: f64) -> EffectResult {
        let mut r = EffectResult::for_test(kind, true, 0.0);
        r.params = vec![super::super::assess::FittedParam {
            unit: "right_elbow".into(),
            value,
            sd: 0.0,
            held_out_reduction: 0.0,
        }];
        r
    }

    #[test]
    fn members_fitted_at_their_range_edge_are_marked_and_nothing_moves() {
        use EffectKind::{EncoderOffset, Friction, LinkCom};
        // Encoder offset range ±0.1 rad: 0.097 is at the edge; link COM range ±0.08 m: 0.06 is inside.
        let effects = [named(EncoderOffset, 0.097), named(LinkCom, 0.06), named(Friction, 3.95)];
        assert!(effects[0].at_search_bound() && !effects[1].at_search_bound() && effects[2].at_search_bound());
        let set = AmbiguousSet::for_test;
        let mut sets = vec![set(vec![EncoderOffset, LinkCom])];
        mark_range_edges(&mut sets, &effects);
        assert_eq!(sets[0].effects, vec![EncoderOffset, LinkCom]);
        assert_eq!(sets[0].at_bound, vec![EncoderOffset]);
        // Inside the range (or at the no-effect end of it): nothing marked.
        let inside = [named(EncoderOffset, -0.05), named(LinkCom, 0.06)];
        let mut sets = vec![set(vec![EncoderOffset, LinkCom])];
        mark_range_edges(&mut sets, &inside);
        assert!(sets[0].at_bound.is_empty());
    }

    #[test]
    fn collinear_changes_of_either_sign_are_ambiguous_orthogonal_ones_are_not() {
        let a = [1.0, 2.0, 0.0, -1.0];
        assert!((cosine(&a, &[2.0, 4.0, 0.0, -2.0]) - 1.0).abs() < 1e-12);
        assert!((cosine(&a, &[-1.0, -2.0, 0.0, 1.0]) + 1.0).abs() < 1e-12);
        assert!(cosine(&a, &[2.0, -1.0, 5.0, 0.0]).abs() < 1e-12);
        assert_eq!(cosine(&a, &[0.0; 4]), 0.0);
    }
}
