//! The diagnosis: replay the logged commands in short windows from the logged state, settle how the log is to be
//! replayed (its timing, the simulator's numerics), break the residual down (joint, phase, frequency band), and let
//! the judge decide which effects explain the held-out windows, with confidence intervals.
//!
//! A pipeline of stages, one module each, run in order by [`diagnose()`]; a stage imports only from the ones below
//! it. `options` (what is asked) and `stats` (means, bootstrap) are the leaves; `windows` picks the windows, `replay`
//! replays and scores them, `timing` checks the log's stamps, `numerics` chooses how to integrate the replay,
//! `breakdown` says where the gap lies, `fit` fits one effect on candidate units, `judge` decides (the one decision
//! model: [`Thresholds`]), `identify` says which effects this log could reveal at all, and `remainder` says what is
//! left. One RNG is threaded through the stages in a fixed order, so a seed fixes the report.
use crate::effects::{EffectKind, Scope};
use crate::log::RobotLog;
use crate::rig_check::{self, RigCheck};
use crate::GapError;
use rand::SeedableRng;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};

mod breakdown;
mod fit;
mod identify;
mod judge;
mod numerics;
mod options;
mod remainder;
mod replay;
mod stats;
mod timing;
mod torque_ceiling;
mod windows;

pub use breakdown::Share;
pub use fit::{AT_BOUND_FRAC, RESOLUTION_FRAC};
pub use identify::{Identifiability, UnitSignal};
pub use judge::{Abstention, CandidateResult, Step, Thresholds};
pub use numerics::{Numerics, NumericsVariant, INTEGRATORS, STEPPINGS};
pub use options::{DiagnoseOptions, PlantChoice, PlantKind, FLOATING_MAX_WINDOWS, RIG_MAX_WINDOWS};
pub use remainder::{
    RobustGap, Unexplained, WindowFlag, WindowResidual, FAST_FRAC, SATURATED_FRAC, UNEXPLAINED_FACTOR,
};
pub use stats::{Estimate, TRIM_FRAC};
pub use timing::{AdvanceTried, TimingCheck, ADVANCES_MS};
pub use torque_ceiling::{ceilings_in_log, LogCeiling, CEILING_MARGIN, MAX_FRACTION_ABOVE};
pub use windows::{AT_LIMIT_RAD, COMMAND_STALE_S, TIMING_TOL_S};

pub use crate::noise::{SIGMA_DQ, SIGMA_GYRO, SIGMA_Q, SIGMA_QUAT, SIGMA_TAU_FRAC};
pub use crate::noise::{TIMING_HI, TIMING_LO};

/// Schema version of `report.json`.
/// `/2`: adds `outcome` and `rig_check` (the rig-assumption check, see [`crate::rig_check`]).
/// `/3`: adds `plant` (rig or floating base) and `windows_unsettled`.
/// `/4`: adds `windows_down` and `rig_check.foot_load_fraction`.
/// `/5`: adds `window_residuals`, `robust` and `unexplained_residual`.
/// `/6`: adds `identifiability`.
/// `/7`: adds `ambiguous`.
/// `/8`: adds `ambiguous[].at_bound` (members fitted at the edge of their search range)
/// and `numerics` (the prediction and held-out gap under MuJoCo's other integrators).
/// `/9`: `ranked` holds the best combination and the effects the log cannot tell apart from a member; an effect
/// that cut the gap alone but adds nothing given the combination is not named and carries `explained_by`.
/// `/10`: `numerics` also replays the rig with 1 ms physics steps (PD every 2 ms and every 1 ms); it and each
/// variant carry `timestep_ms` and `pd_period_ms`.
/// `/11`: effects may carry `worsening_units` and `named_off_limit_only`; a damping, friction or backlash that
/// cleared the floor on the rig carries `load_split` (not named when it grows with the load).
/// `/12`: `load_split` becomes `splits`, a list of refits on halves of the training windows, each with `by`
/// (`load`, or `speed` for a damping: not named when its scale falls with speed), `low`, `high` and `set_aside`;
/// a torque saturation may carry `contradicted_units` (fitted ceilings the logged torque exceeds, dropped).
/// `/13`: each split carries `cleared_on_part` (the effect cleared the floor only on part of the held-out windows:
/// halves apart in scale set it aside without their intervals apart) and `cut_low`/`cut_high` (the mean cut per
/// window of each half's gap by the fitted value); a friction also has a speed split, judged on those cuts
/// (`by_cut`: not named when it cuts the slow half's gap 2x the fast half's); later within `/13`, a backlash too
/// (the same fields, so the version did not change).
/// `/14`: a backlash's load split carries `load_paced`: it is set aside only when, besides its scales, its fitted
/// value cuts the heavy half's gap at least as much per unit of load as the light half's.
/// `/15`: a torque saturation no fit named may be named from the log's own torque and carries `ceilings_in_log`
/// (per joint: `joint`, `scale`, `pinned`, `follow`); it is never explained away.
/// `/16`: an ambiguous set carries `reason` (`collinear`, or `equal_cut`: a masked effect and rivals that cut as much
/// on the same limb), and the report carries `stages` (the wall time of each stage, `stage` and `s`). Both are
/// optional when read: a `/15` report still reads.
/// `/17`: a gain scale's splits include one `by` `power` (the braking share of its joints' mechanical power: not named
/// when the driving half wants 2x the braking half's change of gain), and an effect may carry `pinned_units` (units
/// whose fit stopped at the bound of the search range, dropped before it was judged again). Both optional when read.
/// `/18`: one decision model (the judge). Adds `thresholds`, `timing` and `steps` (every selection step's candidates,
/// winner, rivals and verdict); `numerics` says which variant was adopted; effects carry only `named`, `reduction`,
/// `gain`, `metric_after`, `noise_floor` (the judge's `min_gain`), `params` and `note`; `ambiguous` sets hold the winner and
/// rivals of a step that abstained; `ceilings_in_log` lists the torque plateaus the log shows (a measurement).
/// `/19`: each step's candidate carries `acting_windows` and `gain_where_acting` (the held-out windows where its replay
/// differs from the replay without it, and its gain over those: what test (a) judges).
pub const SCHEMA_VERSION: &str = "ulab-gap-report/19";

/// What the diagnosis concluded about the log as a whole.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Effects were fitted and ranked (on the plant in [`Report::plant`]).
    Diagnosed,
    /// The rig was requested ([`PlantChoice::Rig`]) but the log is not from a suspended robot (the pelvis moves):
    /// nothing was fitted, every effect abstained.
    RigAssumptionViolated,
}

/// The whole diagnosis.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    pub schema_version: String,
    pub outcome: Outcome,
    /// The rig-assumption check that decided whether the diagnosis could run.
    pub rig_check: RigCheck,
    /// The plant that replayed the windows (`/2` reports: always the rig).
    #[serde(default)]
    pub plant: PlantKind,
    /// Floating base only: nominal window starts dropped because no sample within one window length after them
    /// was settled (every foot in contact had been in contact for [`crate::floating::SETTLE_S`]).
    #[serde(default)]
    pub windows_unsettled: usize,
    /// Floating base only: nominal window starts dropped because the robot was down (fell: pelvis tilted beyond
    /// [`crate::floating::FALLEN_TILT`] or lower than [`crate::floating::FALLEN_HEIGHT`]) within the window.
    #[serde(default)]
    pub windows_down: usize,
    pub robot: String,
    pub engine: String,
    pub log_duration_s: f64,
    pub windows_train: usize,
    pub windows_held_out: usize,
    pub window_s: f64,
    /// Fraction of possible window starts not used: no fresh command (older than [`COMMAND_STALE_S`]) or irregular
    /// state timing (log times straying more than [`TIMING_TOL_S`] from a regular grid) within the window.
    #[serde(default)]
    pub windows_skipped_fraction: f64,
    /// Held-out gap metric of the baseline simulator.
    pub baseline_metric: Estimate,
    pub by_joint: Vec<Share>,
    pub by_group: Vec<Share>,
    pub by_phase: Vec<Share>,
    pub by_band: Vec<Share>,
    /// The numbers the judge decided with.
    #[serde(default)]
    pub thresholds: Thresholds,
    /// The log's timing, checked before anything was attributed (absent in reports before `/18`).
    #[serde(default)]
    pub timing: Option<TimingCheck>,
    /// Every effect kind: named ones first in selection order, then the others with why not.
    pub effects: Vec<EffectResult>,
    /// The named effects in selection order (each cut the most of what the ones before it left).
    pub ranked: Vec<EffectKind>,
    /// Effects not named, with the reason.
    pub abstentions: Vec<(EffectKind, String)>,
    /// Every named effect together.
    pub best_combination: Option<Combination>,
    /// No effect was named: the gap is reported as unexplained.
    pub unexplained: bool,
    /// The judge's steps: at each, the candidates replayed, the winner, its rivals and the decision.
    #[serde(default)]
    pub steps: Vec<Step>,
    /// Candidates the log cannot rank apart at the step that stopped the selection (the winner first).
    #[serde(default)]
    pub ambiguous: Vec<AmbiguousSet>,
    /// The torque plateaus the log shows (a measurement, reported as evidence; the judge's torque-saturation
    /// candidates are checked against the logged torque, [`torque_ceiling`]).
    #[serde(default)]
    pub ceilings_in_log: Vec<LogCeiling>,
    /// Every window's gap metric without effects and with the named ones, flagged by cause (torque at its
    /// limit, a joint at its range, a fast transient).
    #[serde(default)]
    pub window_residuals: Vec<WindowResidual>,
    /// Held-out gap statistics a few windows cannot dominate (median, trimmed mean).
    #[serde(default)]
    pub robust: Option<RobustGap>,
    /// The residual no named effect explains, against the log's own sensor-noise level, and where it lies.
    #[serde(default)]
    pub unexplained_residual: Option<Unexplained>,
    /// For every replayed effect kind, the units on which this log could reveal an effect of a magnitude of
    /// interest, and the motion that would reveal it elsewhere.
    #[serde(default)]
    pub identifiability: Vec<Identifiability>,
    /// How the log was integrated: the variants tried and the one adopted.
    #[serde(default)]
    pub numerics: Option<Numerics>,
    /// Wall time of each stage, in order (where a long diagnosis spends its time; what `--effects` can save).
    #[serde(default)]
    pub stages: Vec<StageTime>,
    pub elapsed_s: f64,
}

/// The wall time one stage of [`diagnose()`] took.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageTime {
    pub stage: String,
    pub s: f64,
}

/// One fitted parameter of a named effect.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct FittedParam {
    /// Joint, limb, `robot` or `imu_x|y|z`.
    pub unit: String,
    pub value: f64,
    /// Bootstrap standard deviation over training windows.
    pub sd: f64,
    /// Held-out gap metric this effect removed, per window (absolute, normalised units).
    pub held_out_reduction: f64,
}

/// One effect kind's result.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct EffectResult {
    pub kind: EffectKind,
    pub parameter: String,
    pub scope: Scope,
    /// Named by the judge.
    pub named: bool,
    /// Relative cut of the held-out gap the effects named before it left (named), or of the best candidate of this
    /// kind at the last step (not named).
    pub reduction: Estimate,
    /// The judge's evidence: held-out log-likelihood gain per window, likewise (absent before `/18`).
    #[serde(default = "Estimate::zero")]
    pub gain: Estimate,
    /// Held-out gap metric with it added.
    pub metric_after: Estimate,
    /// The gain's lower bound a named effect must reach ([`Thresholds::min_gain`]).
    pub noise_floor: f64,
    /// The named unit with its fitted value (for a kind not named: its best candidate at the last step).
    pub params: Vec<FittedParam>,
    /// Why named, or why not.
    pub note: Option<String>,
}

/// The named effects together.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Combination {
    pub effects: Vec<EffectKind>,
    pub metric_after: Estimate,
    pub reduction: Estimate,
}

/// Candidates of a step that the log could not rank apart: the winner and its rivals on the same joints.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct AmbiguousSet {
    /// The winner's kind first.
    pub effects: Vec<EffectKind>,
    /// Each member's unit, in the same order.
    #[serde(default)]
    pub units: Vec<String>,
}

impl AmbiguousSet {
    /// Whether both kinds are members.
    pub fn links(&self, a: EffectKind, b: EffectKind) -> bool {
        self.effects.contains(&a) && self.effects.contains(&b)
    }
}

/// Laps of the diagnosis's stages.
struct Laps {
    last: std::time::Instant,
    done: Vec<StageTime>,
}

impl Laps {
    fn start() -> Self {
        Self { last: std::time::Instant::now(), done: Vec::new() }
    }
    /// Ends stage `stage` now.
    fn lap(&mut self, stage: &str) {
        let now = std::time::Instant::now();
        self.done.push(StageTime { stage: stage.into(), s: (now - self.last).as_secs_f64() });
        self.last = now;
    }
}

/// Runs the diagnosis of `log` against `model` in the chosen engine.
pub fn diagnose(model: &RobotModel, log: &RobotLog, opts: &DiagnoseOptions) -> Result<Report, GapError> {
    let mut laps = Laps::start();
    let t_start = laps.last;
    log.validate(model.nj())?;
    let rig = rig_check::check(model, log)?;
    let Some(plant) = opts.plant.resolve(rig.suspended) else {
        return Ok(rig_violated(model, log, opts, rig, t_start));
    };
    let th = Thresholds::default();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed);
    let windows = windows::cut(model, log, opts, plant)?;
    let tally = windows.tally;
    let stamped = replay::Ctx::new(model, log, opts, plant, windows);
    laps.lap("rig check and windows");
    // How the log is replayed: its stamps, then the simulator's numerics. Neither is ever named as an effect.
    let timing = timing::check(&stamped, &th, &mut rng)?;
    let advanced;
    let log = if timing.applied_advance_ms > 0.0 {
        advanced = timing::advanced(log, 1e-3 * timing.applied_advance_ms);
        &advanced
    } else {
        log
    };
    let timed = stamped.with_log(log);
    laps.lap("timing");
    let (numerics, chosen) = match numerics::choose(&timed, th.min_gain, &mut rng)? {
        Some((n, o)) => (Some(n), o),
        None => (None, opts.clone()),
    };
    let ctx = timed.with_options(&chosen);
    laps.lap("numerics");
    // Where: the baseline residual over every window; its held-out part is what every effect must cut.
    let breakdown = breakdown::breakdown(&ctx)?;
    let baseline = breakdown::Baseline::split(&ctx, &breakdown.scores, opts.bootstrap, &mut rng);
    laps.lap("breakdown");
    // Which: the judge.
    let kinds: Vec<EffectKind> = opts.kinds.clone().unwrap_or_else(|| EffectKind::ALL.to_vec());
    let judgement = judge::judge(&ctx, &kinds, &baseline, &th, &mut rng)?;
    laps.lap("judge");
    let verdict = verdict(&ctx, &kinds, &judgement, &baseline, &th, breakdown.any_contact, &mut rng);
    // Whether the log could show each effect at all: an abstention on an effect it cannot reveal says so.
    let identifiability = identify::identify(&ctx, &breakdown.scores, &kinds, &th)?;
    laps.lap("identifiability");
    let mut abstentions = verdict.abstentions;
    for (kind, why) in &mut abstentions {
        if let Some(note) = identifiability.iter().find(|i| i.kind == *kind).and_then(identify::not_identifiable_note) {
            why.push_str("; ");
            why.push_str(&note);
        }
    }
    let joints: Vec<(&str, f64)> = model.joints.iter().map(|j| (j.motor_name.as_str(), j.torque_limit)).collect();
    let ceilings = ceilings_in_log(log, &joints);
    // What is left: per window, robustly, and where.
    let named_fx = (!judgement.named.is_empty()).then_some(&judgement.fx);
    let rest = remainder::remainder(&ctx, &breakdown.scores, &baseline, named_fx)?;
    laps.lap("remainder");
    Ok(Report {
        schema_version: SCHEMA_VERSION.into(),
        outcome: Outcome::Diagnosed,
        rig_check: rig,
        plant,
        windows_unsettled: tally.unsettled,
        windows_down: tally.down,
        robot: model.name.clone(),
        engine: chosen.engine.name(),
        log_duration_s: log.duration(),
        windows_train: ctx.train.len(),
        windows_held_out: ctx.test.len(),
        window_s: ctx.len as f64 * ctx.dt_state,
        windows_skipped_fraction: tally.skipped_fraction,
        baseline_metric: baseline.metric,
        by_joint: breakdown.by_joint,
        by_group: breakdown.by_group,
        by_phase: breakdown.by_phase,
        by_band: breakdown.by_band,
        thresholds: th,
        timing: Some(timing),
        unexplained: judgement.named.is_empty(),
        effects: verdict.effects,
        ranked: judgement.named.iter().map(|n| n.kind).collect(),
        abstentions,
        best_combination: verdict.combination,
        ambiguous: verdict.ambiguous,
        steps: judgement.steps,
        ceilings_in_log: ceilings,
        window_residuals: rest.windows,
        robust: Some(rest.robust),
        unexplained_residual: Some(rest.unexplained),
        identifiability,
        numerics,
        stages: laps.done,
        elapsed_s: t_start.elapsed().as_secs_f64(),
    })
}

/// The judge's decision in the report's terms.
struct Verdict {
    effects: Vec<EffectResult>,
    abstentions: Vec<(EffectKind, String)>,
    combination: Option<Combination>,
    ambiguous: Vec<AmbiguousSet>,
}

/// Every kind's result: the named ones in selection order, then the others, each with the best candidate of its kind
/// at the last step and the reason it was not named.
fn verdict(
    ctx: &replay::Ctx<'_>,
    kinds: &[EffectKind],
    j: &judge::Judgement,
    baseline: &breakdown::Baseline,
    th: &Thresholds,
    any_contact: bool,
    rng: &mut impl rand::Rng,
) -> Verdict {
    let zero = Estimate::zero();
    let n_test = ctx.test.len().max(1) as f64;
    let mut before: f64 = baseline.test_tot.iter().sum::<f64>() / n_test;
    let mut effects = Vec::new();
    for n in &j.named {
        let after = n.metric_after.value;
        let params = match n.fit.axes {
            Some(a) => ["imu_x", "imu_y", "imu_z"]
                .iter()
                .zip(a)
                .map(|(u, v)| FittedParam {
                    unit: (*u).into(),
                    value: v,
                    sd: n.fit.sd,
                    held_out_reduction: before - after,
                })
                .collect(),
            None => vec![FittedParam {
                unit: n.fit.unit.name().into(),
                value: fit::report_value(n.kind, n.fit.value),
                sd: fit::report_value(n.kind, n.fit.sd),
                held_out_reduction: before - after,
            }],
        };
        let given: Vec<&str> = effects.iter().map(|e: &EffectResult| e.kind.name()).collect();
        let note = if given.is_empty() {
            "named: the largest held-out cut".to_string()
        } else {
            format!("named given {}: the largest cut of what they leave", given.join(" + "))
        };
        effects.push(EffectResult {
            kind: n.kind,
            parameter: n.kind.parameter().into(),
            scope: n.kind.scope(),
            named: true,
            reduction: n.cut,
            gain: n.gain,
            metric_after: n.metric_after,
            noise_floor: th.min_gain,
            params,
            note: Some(note),
        });
        before = after;
    }
    let last = j.steps.last();
    let stop = last.map_or_else(String::new, |s| s.reason.clone());
    let mut abstentions = Vec::new();
    for &kind in kinds {
        if j.named.iter().any(|n| n.kind == kind) {
            continue;
        }
        let why = if ctx.plant == PlantKind::Rig && !kind.identifiable_suspended() {
            if any_contact {
                "foot contact is estimated in this log, but the suspended-rig plant has no ground model to fit it on"
                    .into()
            } else {
                "not identifiable: no foot contact in this log".into()
            }
        } else {
            let best = last.and_then(|s| s.candidates.iter().find(|c| c.kind == kind));
            match best {
                Some(c) if c.invalid.is_some() => format!(
                    "not named: its best fit ({:.4} on {}) is not an estimate: {}",
                    c.value,
                    c.unit,
                    c.invalid.clone().unwrap_or_default()
                ),
                Some(c) => format!(
                    "not named: its best candidate, on {} at {:.4}, gains {} per held-out window; the selection \
                     stopped: {stop}",
                    c.unit,
                    c.value,
                    judge::gain_words(c)
                ),
                None => format!("not named: no candidate of it ranked among those replayed at the last step; {stop}"),
            }
        };
        let best = last.and_then(|s| s.candidates.iter().find(|c| c.kind == kind));
        effects.push(EffectResult {
            kind,
            parameter: kind.parameter().into(),
            scope: kind.scope(),
            named: false,
            reduction: best.map_or(zero, |c| c.cut),
            gain: best.map_or(zero, |c| c.gain),
            metric_after: zero,
            noise_floor: th.min_gain,
            params: best
                .map(|c| vec![FittedParam { unit: c.unit.clone(), value: c.value, sd: c.sd, held_out_reduction: 0.0 }])
                .unwrap_or_default(),
            note: Some(why.clone()),
        });
        abstentions.push((kind, why));
    }
    let combination = (!j.named.is_empty()).then(|| Combination {
        effects: j.named.iter().map(|n| n.kind).collect(),
        metric_after: stats::bootstrap_mean(&j.totals, ctx.opts.bootstrap, rng),
        reduction: stats::bootstrap_ratio(&baseline.test_tot, &j.totals, ctx.opts.bootstrap, rng),
    });
    // The regions the last step could not attribute: each a candidate and its rivals.
    let ambiguous = last
        .map(|s| {
            s.ambiguous
                .iter()
                .map(|region| {
                    let members: Vec<&CandidateResult> = region.iter().filter_map(|&i| s.candidates.get(i)).collect();
                    AmbiguousSet {
                        effects: members.iter().map(|c| c.kind).collect(),
                        units: members.iter().map(|c| c.unit.clone()).collect(),
                    }
                })
                .collect()
        })
        .unwrap_or_default();
    Verdict { effects, abstentions, combination, ambiguous }
}

/// The report of a log that fails the rig-assumption check: no window replayed, no effect fitted, every effect
/// abstained with the check's message.
fn rig_violated(
    model: &RobotModel,
    log: &RobotLog,
    opts: &DiagnoseOptions,
    rig: RigCheck,
    t_start: std::time::Instant,
) -> Report {
    let zero = Estimate::zero();
    let why = format!("not diagnosed: {}", rig.message);
    let kinds: Vec<EffectKind> = opts.kinds.clone().unwrap_or_else(|| EffectKind::ALL.to_vec());
    let effects: Vec<EffectResult> = kinds
        .iter()
        .map(|&kind| EffectResult {
            kind,
            parameter: kind.parameter().into(),
            scope: kind.scope(),
            named: false,
            reduction: zero,
            gain: zero,
            metric_after: zero,
            noise_floor: 0.0,
            params: vec![],
            note: Some(why.clone()),
        })
        .collect();
    Report {
        schema_version: SCHEMA_VERSION.into(),
        outcome: Outcome::RigAssumptionViolated,
        rig_check: rig,
        plant: PlantKind::Rig,
        windows_unsettled: 0,
        windows_down: 0,
        robot: model.name.clone(),
        engine: opts.engine.name(),
        log_duration_s: log.duration(),
        windows_train: 0,
        windows_held_out: 0,
        window_s: opts.window_s,
        windows_skipped_fraction: 0.0,
        baseline_metric: zero,
        by_joint: vec![],
        by_group: vec![],
        by_phase: vec![],
        by_band: vec![],
        abstentions: kinds.iter().map(|&k| (k, why.clone())).collect(),
        effects,
        ranked: vec![],
        best_combination: None,
        unexplained: true,
        thresholds: Thresholds::default(),
        timing: None,
        steps: vec![],
        ceilings_in_log: vec![],
        window_residuals: vec![],
        robust: None,
        unexplained_residual: None,
        identifiability: vec![],
        ambiguous: vec![],
        numerics: None,
        stages: vec![],
        elapsed_s: t_start.elapsed().as_secs_f64(),
    }
}
