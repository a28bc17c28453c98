//! The diagnosis: replay the logged commands in short windows from the logged state, break the residual down
//! (joint, phase, frequency band), fit every effect on training windows, rank by held-out reduction against a
//! data-derived noise floor, fit the best combination, and attach bootstrap confidence intervals.
//!
//! A pipeline of stages, one module each, run in order by [`diagnose()`]; a stage imports only from the ones
//! below it, so each can be read (and tested) without those above. `options` (what is asked) and `stats` (means,
//! bootstrap, noise floor) are the leaves; `windows` picks the windows, `replay` replays and scores them,
//! `breakdown` says where the gap lies, `fit` fits one effect, `assess` judges each effect alone, `select` builds
//! the best combination (with `unmask`, which refits the effects a first one masked), `confound` says which named effects the log cannot tell apart, `identify` says which
//! effects this log could reveal at all, `numerics` how much of the gap the integrator, timestep or PD rate alone could make,
//! and `remainder` says what is left (per window, robustly, and where). One
//! RNG is threaded through the stages in a fixed order, so a seed fixes the report.
use crate::effects::EffectKind;
use crate::log::RobotLog;
use crate::rig_check::{self, RigCheck};
use crate::GapError;
use rand::SeedableRng;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};

mod assess;
mod breakdown;
mod confound;
mod fit;
mod halves;
mod identify;
mod numerics;
mod options;
mod remainder;
mod replay;
mod select;
mod stats;
mod torque_ceiling;
mod unmask;
mod windows;

pub use assess::{
    pinned_at_bound, EffectResult, FittedParam, MIN_WINDOWS_OFF_LIMIT, PINNED_FRAC, SINGLE_JOINT_CANDIDATES,
    UNIT_FLOOR_FRAC,
};
pub use breakdown::Share;
pub use confound::{leading_set, Ambiguity, AmbiguousSet, AMBIGUOUS_COSINE};
pub use fit::RESOLUTION_FRAC;
pub use halves::{HalvesRefit, SplitBy, LOAD_CHECKED, MIN_SPLIT_RATIO, POWER_CHECKED, SCALE_RATIO, SPEED_CHECKED};
pub use identify::{Identifiability, UnitSignal};
pub use numerics::{Numerics, NumericsVariant, INTEGRATORS, STEPPINGS};
pub use options::{DiagnoseOptions, PlantChoice, PlantKind, FLOATING_MAX_WINDOWS, RIG_MAX_WINDOWS};
pub use remainder::{
    RobustGap, Unexplained, WindowFlag, WindowResidual, FAST_FRAC, SATURATED_FRAC, UNEXPLAINED_FACTOR,
};
pub use select::{Combination, MAX_COMBINATION, REFIT_CANDIDATES};
pub use stats::{Estimate, Judged, EFFECT_FLOOR_FRAC, TRIM_FRAC};
pub use torque_ceiling::{
    ceilings_in_log, LogCeiling, CEILING_MARGIN, DEMAND_OVER, FOLLOW_BELOW, FOLLOW_TOL, MAX_COMMAND_DELAY,
    MAX_FRACTION_ABOVE, MAX_SCALE_IN_LOG, MAX_TORQUE_LAG, MIN_FOLLOW, MIN_PINNED, PLATEAU_BAND,
};
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
pub const SCHEMA_VERSION: &str = "ulab-gap-report/17";

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
    /// Every effect tried: named ones first, each group by its own held-out reduction.
    pub effects: Vec<EffectResult>,
    /// The named effects in rank order: the best combination's selection order (each adds the most held-out
    /// explanatory power given the ones before it), then the effects this log cannot tell apart from a member
    /// ([`Report::ambiguous`]). Effects that cut the gap alone but add nothing given the combination are explained
    /// away (not named; their abstention says so).
    pub ranked: Vec<EffectKind>,
    /// Effects not named, with the reason.
    pub abstentions: Vec<(EffectKind, String)>,
    pub best_combination: Option<Combination>,
    /// No effect was named: the gap is reported as unexplained.
    pub unexplained: bool,
    /// Every window's gap metric without effects and with the best combination, flagged by cause (torque at its
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
    /// Named effects this log cannot tell apart (nearly collinear predicted changes), each set in rank order.
    #[serde(default)]
    pub ambiguous: Vec<AmbiguousSet>,
    /// What MuJoCo's other integrators, a finer timestep and a faster PD rate do to the prediction and the held-out
    /// gap (a baseline mismatch of numerics).
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
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed);
    let windows = windows::cut(model, log, opts, plant)?;
    let tally = windows.tally;
    let ctx = replay::Ctx::new(model, log, opts, plant, windows);
    laps.lap("rig check and windows");
    // Where: the baseline residual over every window; its held-out part is what every effect must beat.
    let breakdown = breakdown::breakdown(&ctx)?;
    let baseline = breakdown::Baseline::split(&ctx, &breakdown.scores, opts.bootstrap, &mut rng);
    laps.lap("breakdown");
    // Which: every effect alone, then the best combination given the effects already in.
    let kinds: Vec<EffectKind> = opts.kinds.clone().unwrap_or_else(|| EffectKind::ALL.to_vec());
    let assessment = assess::assess(&ctx, kinds.clone(), &baseline, breakdown.any_contact, &mut rng)?;
    laps.lap("each effect alone");
    let fitted: Vec<(EffectKind, crate::plant::Effects)> =
        assessment.candidates.iter().map(|c| (c.kind, c.fx.clone())).collect();
    let mut selection = select::select(&ctx, assessment, &baseline, &mut rng)?;
    laps.lap("selection");
    // Which named effects the log cannot tell apart.
    let fitted: Vec<(EffectKind, crate::plant::Effects)> =
        fitted.into_iter().chain(selection.unmasked.iter().cloned()).collect();
    let named: Vec<(EffectKind, crate::plant::Effects)> =
        selection.ranked.iter().filter_map(|k| fitted.iter().find(|(f, _)| f == k).cloned()).collect();
    let mut ambiguous = confound::ambiguous_sets(&ctx, &named, &baseline.test_tot, &mut rng)?;
    ambiguous.append(&mut selection.equal_cut);
    confound::mark_range_edges(&mut ambiguous, &selection.effects);
    // Named effects that add nothing once the best combination is in, and that the log can tell apart from its
    // members, are not named.
    select::explain_away(&mut selection, &mut ambiguous);
    laps.lap("ambiguous sets");
    let ranked = selection.ranked;
    // Whether the log could show each effect at all: an abstention on an effect it cannot reveal says so.
    let identifiability = identify::identify(&ctx, &breakdown.scores, &kinds)?;
    laps.lap("identifiability");
    let mut abstentions = selection.abstentions;
    for (kind, why) in &mut abstentions {
        if let Some(note) = identifiability.iter().find(|i| i.kind == *kind).and_then(identify::not_identifiable_note) {
            why.push_str("; ");
            why.push_str(&note);
        }
    }
    // How much of the gap the simulator's own numerics could make.
    let numerics = numerics::numerics(&ctx, &baseline.test_tot, &mut rng)?;
    laps.lap("numerics");
    // What is left: per window, robustly, and where.
    let rest = remainder::remainder(&ctx, &breakdown.scores, &baseline, selection.combo_fx.as_ref())?;
    laps.lap("remainder");
    Ok(Report {
        schema_version: SCHEMA_VERSION.into(),
        outcome: Outcome::Diagnosed,
        rig_check: rig,
        plant,
        windows_unsettled: tally.unsettled,
        windows_down: tally.down,
        robot: model.name.clone(),
        engine: opts.engine.name(),
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
        unexplained: ranked.is_empty(),
        effects: selection.effects,
        ranked,
        abstentions,
        best_combination: selection.best_combination,
        window_residuals: rest.windows,
        robust: Some(rest.robust),
        unexplained_residual: Some(rest.unexplained),
        identifiability,
        ambiguous,
        numerics,
        stages: laps.done,
        elapsed_s: t_start.elapsed().as_secs_f64(),
    })
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
    let zero = Estimate { value: 0.0, lo: 0.0, hi: 0.0 };
    let why = format!("not diagnosed: {}", rig.message);
    let kinds: Vec<EffectKind> = opts.kinds.clone().unwrap_or_else(|| EffectKind::ALL.to_vec());
    let effects: Vec<EffectResult> =
        kinds.iter().map(|&kind| EffectResult::not_fitted(kind, zero, why.clone())).collect();
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
