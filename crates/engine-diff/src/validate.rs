//! Cross-engine policy validation (issue 15): a controller trained in one engine runs closed-loop in every
//! engine over a grid of velocity commands and seeds; each episode gets a task score; each engine's scores are
//! compared with the training engine's on the same (command, seed) pairs; each engine gets a verdict, and
//! where the policy degrades, the windowed divergence of [`crate::harness`] between the training engine and
//! that engine says where it concentrates.
//!
//! Why paired: an episode's noise, push and command are the same in every engine (the scenario's random
//! streams), so the score difference of one (command, seed) pair isolates the engine. The test is a sign-flip
//! permutation test on the paired differences (no distributional assumption; exact below 16 pairs).
use crate::harness::{
    free_run_recorded, initial_state, run_episode, scenario_model, ControllerFactory, EngineFactory, HarnessConfig,
    Outcome, Trajectory,
};
use crate::scenario::{CommandSegment, Scenario};
use crate::triage::AllowList;
use crate::DiffError;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Version of `validate.json`.
pub const VALIDATE_SCHEMA_VERSION: u32 = 1;
/// Width of the velocity-tracking kernel of the task score, exp(−e²/σ) with σ in (m/s)²: legged_gym's
/// `tracking_sigma` (0.25), the value both shipped policies' training rewards use for velocity tracking.
pub const TRACKING_SIGMA: f64 = 0.25;
/// Seconds of standing before the commanded velocity starts (the policy settles from the initial pose).
pub const SETTLE_S: f64 = 1.0;
/// A score drop smaller than this (score units, 0..1) is not a degradation even when significant.
pub const MIN_DROP: f64 = 0.1;
/// Significance level of the paired test.
pub const ALPHA: f64 = 0.05;
/// An engine in which the robot falls in at least this fraction of the episodes fails.
pub const FAIL_FALL_RATE: f64 = 0.5;
/// A distance below this (m) gives no energy-per-metre figure (standing episodes).
const MIN_DISTANCE_M: f64 = 0.5;
const BOOTSTRAP_RESAMPLES: usize = 2000;
const PERMUTATIONS: usize = 20_000;

/// A velocity command of the grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CommandCase {
    pub name: String,
    /// `(vx m/s, vy m/s, wz rad/s)`, base frame.
    pub command: [f64; 3],
}

/// The default grid: standing, forward, lateral, turning (inside the training ranges of both shipped policies).
pub fn standard_commands() -> Vec<CommandCase> {
    let c = |name: &str, command| CommandCase { name: name.into(), command };
    vec![
        c("stand", [0.0, 0.0, 0.0]),
        c("forward", [0.5, 0.0, 0.0]),
        c("lateral", [0.0, 0.3, 0.0]),
        c("turn", [0.0, 0.0, 0.5]),
    ]
}

/// The episode of one (command, seed): [`Scenario::policy`] (its noise and mid-episode push) with the command
/// switched on after [`SETTLE_S`].
pub fn scenario_for(case: &CommandCase, seed: u64, seconds: f64) -> Scenario {
    Scenario {
        commands: vec![
            CommandSegment { t: 0.0, command: [0.0; 3] },
            CommandSegment { t: SETTLE_S.min(0.5 * seconds), command: case.command },
        ],
        ..Scenario::policy(seed, seconds)
    }
}

/// The task score of an episode, in 0..1: the fraction of the episode survived times the velocity-tracking
/// kernel exp(−e²/σ) of the RMS tracking error e.
pub fn task_score(o: &Outcome, seconds: f64) -> f64 {
    let survival = if seconds > 0.0 { (o.survived_s / seconds).clamp(0.0, 1.0) } else { 0.0 };
    survival * (-(o.velocity_tracking_rms.powi(2)) / TRACKING_SIGMA).exp()
}

/// One episode in one engine.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EpisodeScore {
    pub engine: String,
    pub case: String,
    pub seed: u64,
    pub score: f64,
    pub outcome: Outcome,
}

/// Mean and 95 % bootstrap interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Interval {
    pub mean: f64,
    pub lo: f64,
    pub hi: f64,
    pub n: usize,
}

impl Interval {
    /// Percentile bootstrap of the mean (deterministic: seeded).
    pub fn of(v: &[f64], seed: u64) -> Option<Interval> {
        let v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        let n = v.len();
        let mean = v.iter().sum::<f64>() / n as f64;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut means: Vec<f64> =
            (0..BOOTSTRAP_RESAMPLES).map(|_| (0..n).map(|_| v[rng.gen_range(0..n)]).sum::<f64>() / n as f64).collect();
        means.sort_by(f64::total_cmp);
        let at = |p: f64| means[((p * (means.len() - 1) as f64).round() as usize).min(means.len() - 1)];
        Some(Interval { mean, lo: at(0.025), hi: at(0.975), n })
    }
}

/// Two-sided sign-flip permutation test of "the paired differences have mean 0": exact for up to 16 pairs,
/// else `PERMUTATIONS` random sign vectors (p includes the observed one, so it is never 0).
pub fn paired_p_value(diffs: &[f64], seed: u64) -> f64 {
    let n = diffs.len();
    if n == 0 {
        return 1.0;
    }
    let obs = diffs.iter().sum::<f64>().abs();
    // Ties within rounding count as "at least as extreme".
    let tol = 1e-12 * (1.0 + obs);
    let flipped = |mask: u64| -> f64 {
        diffs.iter().enumerate().map(|(i, d)| if mask >> i & 1 == 1 { -d } else { *d }).sum::<f64>().abs()
    };
    if n <= 16 {
        let total = 1u64 << n;
        let extreme = (0..total).filter(|&m| flipped(m) >= obs - tol).count();
        return extreme as f64 / total as f64;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let extreme = (0..PERMUTATIONS)
        .filter(|_| diffs.iter().map(|d| if rng.gen_bool(0.5) { -d } else { *d }).sum::<f64>().abs() >= obs - tol)
        .count();
    (extreme + 1) as f64 / (PERMUTATIONS + 1) as f64
}

/// The verdict for one engine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The engine the scores are compared with.
    TrainingEngine,
    /// No significant drop of at least [`MIN_DROP`].
    Transfers,
    /// A significant drop of at least [`MIN_DROP`], the robot mostly stays up.
    Degrades,
    /// The robot falls in at least [`FAIL_FALL_RATE`] of the episodes (and does not in the training engine).
    Fails,
    /// The policy falls in its training engine too: nothing to compare with.
    Inconclusive,
}

impl Verdict {
    pub const fn label(self) -> &'static str {
        match self {
            Verdict::TrainingEngine => "training engine",
            Verdict::Transfers => "transfers",
            Verdict::Degrades => "degrades",
            Verdict::Fails => "fails",
            Verdict::Inconclusive => "inconclusive",
        }
    }
}

/// Where the divergence between the training engine and a degrading engine concentrates, in the windows of
/// one episode of the command with the largest drop.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Evidence {
    pub case: String,
    pub seed: u64,
    /// Contact phase holding the largest share of the k-step link-position divergence, and that share.
    pub phase: String,
    pub phase_share: f64,
    /// Joint holding the largest share of the k-step joint-angle divergence, and that share.
    pub joint: String,
    pub joint_share: f64,
    /// Largest bound excess of that episode: (kind, quantity, phase, ratio to bound), if any exceeded.
    pub worst_finding: Option<(String, String, String, f64)>,
    /// The allow-list entry that covers that finding (for this lead), if one does.
    pub covered_by: Option<String>,
    /// Allow-list entries recorded for this engine (against MuJoCo): its known modelling differences.
    pub known_differences: Vec<String>,
    /// Mean RMS velocity-tracking error per component (forward m/s, lateral m/s, yaw rate rad/s) over this engine's
    /// episodes, and over the training engine's: which part of the task the score drop comes from.
    pub tracking_error: [f64; 3],
    pub train_tracking_error: [f64; 3],
}

/// One engine's figures.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EngineSummary {
    pub engine: String,
    pub episodes: usize,
    /// Episodes the engine itself failed (error); counted as falls in the score, listed here.
    pub engine_errors: usize,
    pub score: Option<Interval>,
    pub fall_rate: f64,
    pub survived_s: Option<Interval>,
    pub velocity_tracking_rms: Option<Interval>,
    /// Positive joint work per metre travelled (J/m), over episodes that travelled at least 0.5 m.
    pub energy_per_m: Option<Interval>,
    pub foot_slip_mps: Option<Interval>,
    /// Fraction of the steps with a joint within 0.01 rad of a position limit.
    pub joint_limit_fraction: Option<Interval>,
    /// Training-engine score minus this engine's, paired over (command, seed).
    pub drop: Option<Interval>,
    pub p_value: Option<f64>,
    /// Mean score per command (grid order).
    pub score_per_case: Vec<(String, f64)>,
    pub verdict: Verdict,
    pub evidence: Option<Evidence>,
}

/// The validation of one controller.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ValidationReport {
    pub schema_version: u32,
    pub controller: String,
    pub robot: String,
    pub train_engine: String,
    /// Allow-list entries recorded for the training engine: its known modelling differences, what a policy
    /// trained there may exploit (named when every other engine flags the policy).
    #[serde(default)]
    pub train_known_differences: Vec<String>,
    pub seconds: f64,
    pub seeds: Vec<u64>,
    pub commands: Vec<CommandCase>,
    pub engines: Vec<EngineSummary>,
    pub episodes: Vec<EpisodeScore>,
}

/// What to run.
pub struct ValidateSetup<'a> {
    pub model: &'a RobotModel,
    /// Every engine, the training engine among them.
    pub factories: &'a [Arc<dyn EngineFactory>],
    pub train_engine: &'a str,
    pub controller: &'a ControllerFactory,
    pub controller_name: &'a str,
    pub commands: &'a [CommandCase],
    pub seeds: &'a [u64],
    pub seconds: f64,
    pub cfg: &'a HarnessConfig,
    pub allow: &'a AllowList,
    /// Collect evidence for engines that degrade or fail (one windowed episode each).
    pub evidence: bool,
}

impl std::fmt::Debug for ValidateSetup<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ValidateSetup")
            .field("train_engine", &self.train_engine)
            .field("controller", &self.controller_name)
            .field("commands", &self.commands)
            .field("seeds", &self.seeds)
            .field("seconds", &self.seconds)
            .finish_non_exhaustive()
    }
}

fn run_one(
    s: &ValidateSetup<'_>,
    f: &Arc<dyn EngineFactory>,
    case: &CommandCase,
    seed: u64,
) -> Result<EpisodeScore, DiffError> {
    episode_score(s.model, f.as_ref(), s.controller, case, seed, s.seconds, s.cfg)
}

/// One closed-loop episode of (command, seed) in one engine, scored. An engine that cannot be built for the
/// model scores as a fall at t = 0 (with its error), so that one engine's failure does not hide the others.
pub fn episode_score(
    model: &RobotModel,
    f: &dyn EngineFactory,
    controller: &ControllerFactory,
    case: &CommandCase,
    seed: u64,
    seconds: f64,
    cfg: &HarnessConfig,
) -> Result<EpisodeScore, DiffError> {
    episode_score_recorded(model, f, controller, case, seed, seconds, cfg, None)
}

/// [`episode_score`], also sampling the episode's states into `traj` when given (`ulab validate --video`
/// recomputes one episode this way: the same function, so the same rollout).
#[allow(clippy::too_many_arguments)]
pub fn episode_score_recorded(
    model: &RobotModel,
    f: &dyn EngineFactory,
    controller: &ControllerFactory,
    case: &CommandCase,
    seed: u64,
    seconds: f64,
    cfg: &HarnessConfig,
    traj: Option<&mut Trajectory>,
) -> Result<EpisodeScore, DiffError> {
    let sc = scenario_for(case, seed, seconds);
    sc.validate()?;
    let m = scenario_model(model, &sc);
    let dt = cfg.common.timestep;
    let steps = (seconds / dt).round() as usize;
    let name = f.name();
    let outcome = match f.build(&m, &cfg.common) {
        Ok(mut e) => free_run_recorded(e.as_mut(), &name, &m, controller, &sc, dt, steps, traj)?.0 .0,
        Err(err) => {
            Outcome { fell: true, fall_time: Some(0.0), error: Some(err.to_string()), ..Outcome::before_start(&name) }
        }
    };
    let score = task_score(&outcome, seconds);
    Ok(EpisodeScore { engine: name, case: case.name.clone(), seed, score, outcome })
}

/// One episode of the grid: engine (index into [`ValidateSetup::factories`]), command (index into
/// [`ValidateSetup::commands`]) and seed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Task {
    pub engine: usize,
    pub command: usize,
    pub seed: u64,
}

/// Runs every (engine, command, seed) episode in parallel and summarises.
pub fn validate(s: &ValidateSetup<'_>) -> Result<ValidationReport, DiffError> {
    let tasks = tasks(s)?;
    let episodes = run_tasks(s, &tasks)?;
    report(s, episodes)
}

/// The training engine's index among the factories, after checking the setup.
fn check(s: &ValidateSetup<'_>) -> Result<usize, DiffError> {
    if !(s.seconds.is_finite() && s.seconds > 0.0) {
        return Err(DiffError::Input(format!("episode length {} s must be positive", s.seconds)));
    }
    if s.commands.is_empty() || s.seeds.is_empty() {
        return Err(DiffError::Input("at least one command and one seed are needed".into()));
    }
    let names: Vec<String> = s.factories.iter().map(|f| f.name()).collect();
    if let Some(dup) = names.iter().enumerate().find(|(i, n)| names[..*i].contains(n)).map(|(_, n)| n) {
        return Err(DiffError::Input(format!("engine {dup} is listed twice")));
    }
    names.iter().position(|n| n == s.train_engine).ok_or_else(|| {
        DiffError::Input(format!("training engine {} is not among the engines ({})", s.train_engine, names.join(", ")))
    })
}

/// The grid's episodes in the order of [`ValidationReport::episodes`]: engine, then command, then seed. A sharded
/// validation deals these.
pub fn tasks(s: &ValidateSetup<'_>) -> Result<Vec<Task>, DiffError> {
    check(s)?;
    // Check once that the initial state is valid for the model (a bad model fails here, not in every task).
    initial_state(s.model, &scenario_for(&s.commands[0], s.seeds[0], s.seconds))?;
    Ok((0..s.factories.len())
        .flat_map(|engine| {
            (0..s.commands.len())
                .flat_map(move |command| s.seeds.iter().map(move |&seed| Task { engine, command, seed }))
        })
        .collect())
}

/// The episodes of `tasks`, in parallel, in the order given.
pub fn run_tasks(s: &ValidateSetup<'_>, tasks: &[Task]) -> Result<Vec<EpisodeScore>, DiffError> {
    tasks
        .par_iter()
        .map(|t| {
            let (f, c) = s
                .factories
                .get(t.engine)
                .zip(s.commands.get(t.command))
                .ok_or_else(|| DiffError::Input(format!("task {t:?} outside the grid")))?;
            run_one(s, f, c, t.seed)
        })
        .collect()
}

/// The report from every episode of [`tasks`] in its order (an unsharded run's, or merged shards').
pub fn report(s: &ValidateSetup<'_>, episodes: Vec<EpisodeScore>) -> Result<ValidationReport, DiffError> {
    let train_ix = check(s)?;
    let names: Vec<String> = s.factories.iter().map(|f| f.name()).collect();
    let grid = tasks(s)?;
    let matches = |t: &Task, e: &EpisodeScore| {
        names.get(t.engine) == Some(&e.engine)
            && s.commands.get(t.command).is_some_and(|c| c.name == e.case)
            && t.seed == e.seed
    };
    if grid.len() != episodes.len() || !grid.iter().zip(&episodes).all(|(t, e)| matches(t, e)) {
        return Err(DiffError::Input(format!(
            "{} episode results do not match the grid of {} (engine, command, seed) episodes",
            episodes.len(),
            grid.len()
        )));
    }
    let train = &names[train_ix];
    let train_scores: Vec<&EpisodeScore> = episodes.iter().filter(|e| &e.engine == train).collect();
    let train_fall_rate = fall_rate(&train_scores);
    let mut engines = Vec::new();
    for (i, name) in names.iter().enumerate() {
        let mine: Vec<&EpisodeScore> = episodes.iter().filter(|e| &e.engine == name).collect();
        let mut summary = summarise(name, &mine, s.commands, s.cfg.common.timestep, 0x5C0 + i as u64);
        if i == train_ix {
            summary.verdict = Verdict::TrainingEngine;
        } else {
            let diffs: Vec<f64> = paired_drops(&train_scores, &mine).map(|(d, _)| d).collect();
            summary.drop = Interval::of(&diffs, 0xD0 + i as u64);
            let p = paired_p_value(&diffs, 0x9E + i as u64);
            summary.p_value = Some(p);
            let drop = summary.drop.map_or(0.0, |d| d.mean);
            summary.verdict = if train_fall_rate >= FAIL_FALL_RATE {
                Verdict::Inconclusive
            } else if summary.fall_rate >= FAIL_FALL_RATE {
                Verdict::Fails
            } else if drop >= MIN_DROP && p < ALPHA {
                Verdict::Degrades
            } else {
                Verdict::Transfers
            };
            if s.evidence && matches!(summary.verdict, Verdict::Degrades | Verdict::Fails) {
                summary.evidence = Some(evidence(s, train_ix, i, &train_scores, &mine)?);
            }
        }
        engines.push(summary);
    }
    Ok(ValidationReport {
        schema_version: VALIDATE_SCHEMA_VERSION,
        controller: s.controller_name.into(),
        robot: s.model.name.clone(),
        train_engine: train.clone(),
        train_known_differences: known_differences(s.allow, train),
        seconds: s.seconds,
        seeds: s.seeds.to_vec(),
        commands: s.commands.to_vec(),
        engines,
        episodes,
    })
}

/// (training-engine score − this engine's score, this engine's episode) for every (command, seed) both ran.
fn paired_drops<'a>(
    train: &'a [&EpisodeScore],
    mine: &'a [&'a EpisodeScore],
) -> impl Iterator<Item = (f64, &'a EpisodeScore)> + 'a {
    mine.iter().filter_map(move |e| {
        train.iter().find(|t| t.case == e.case && t.seed == e.seed).map(|t| (t.score - e.score, *e))
    })
}

fn fall_rate(v: &[&EpisodeScore]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.iter().filter(|e| e.outcome.fell).count() as f64 / v.len() as f64
}

fn summarise(name: &str, mine: &[&EpisodeScore], commands: &[CommandCase], dt: f64, seed: u64) -> EngineSummary {
    let col = |f: &dyn Fn(&EpisodeScore) -> Option<f64>| mine.iter().filter_map(|e| f(e)).collect::<Vec<f64>>();
    EngineSummary {
        engine: name.into(),
        episodes: mine.len(),
        engine_errors: mine.iter().filter(|e| e.outcome.error.is_some()).count(),
        score: Interval::of(&col(&|e| Some(e.score)), seed),
        fall_rate: fall_rate(mine),
        survived_s: Interval::of(&col(&|e| Some(e.outcome.survived_s)), seed + 1),
        velocity_tracking_rms: Interval::of(&col(&|e| Some(e.outcome.velocity_tracking_rms)), seed + 2),
        energy_per_m: Interval::of(
            &col(&|e| (e.outcome.distance_m >= MIN_DISTANCE_M).then(|| e.outcome.energy_j / e.outcome.distance_m)),
            seed + 3,
        ),
        foot_slip_mps: Interval::of(&col(&|e| Some(e.outcome.foot_slip_mps)), seed + 4),
        joint_limit_fraction: Interval::of(
            &col(&|e| {
                (e.outcome.survived_s > 0.0).then(|| e.outcome.joint_limit_steps as f64 * dt / e.outcome.survived_s)
            }),
            seed + 5,
        ),
        drop: None,
        p_value: None,
        score_per_case: commands
            .iter()
            .map(|c| {
                let v = col(&|e| (e.case == c.name).then_some(e.score));
                (c.name.clone(), if v.is_empty() { f64::NAN } else { v.iter().sum::<f64>() / v.len() as f64 })
            })
            .collect(),
        verdict: Verdict::Transfers,
        evidence: None,
    }
}

/// Windowed divergence (training engine as lead) of the (command, seed) with the largest score drop.
fn evidence(
    s: &ValidateSetup<'_>,
    train_ix: usize,
    engine_ix: usize,
    train_scores: &[&EpisodeScore],
    mine: &[&EpisodeScore],
) -> Result<Evidence, DiffError> {
    let worst = paired_drops(train_scores, mine)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, e)| e)
        .ok_or_else(|| DiffError::Input("no paired episode".into()))?;
    let case = s
        .commands
        .iter()
        .find(|c| c.name == worst.case)
        .ok_or_else(|| DiffError::Input(format!("unknown command {}", worst.case)))?;
    let sc = scenario_for(case, worst.seed, s.seconds);
    let pair = [s.factories[train_ix].clone(), s.factories[engine_ix].clone()];
    let cfg = HarnessConfig { free_runs: false, ..s.cfg.clone() };
    let ep = run_episode(s.model, &pair, s.controller, &sc, &cfg)?;
    let mut by_phase: std::collections::BTreeMap<crate::phase::ContactPhase, f64> = Default::default();
    let mut by_joint = vec![0.0; s.model.nj()];
    for w in &ep.windows {
        for d in &w.divs {
            *by_phase.entry(w.phase).or_default() += d.k_step.max_link();
            for (j, q) in d.k_step.q.iter().enumerate() {
                if let Some(slot) = by_joint.get_mut(j) {
                    *slot += q;
                }
            }
        }
    }
    let share = |v: f64, total: f64| if total > 0.0 { v / total } else { 0.0 };
    let phase_total: f64 = by_phase.values().sum();
    let (phase, pv) =
        by_phase.iter().max_by(|a, b| a.1.total_cmp(b.1)).map_or((String::new(), 0.0), |(k, v)| (k.to_string(), *v));
    let joint_total: f64 = by_joint.iter().sum();
    let (jix, jv) = by_joint.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).map_or((0, 0.0), |(i, v)| (i, *v));
    let worst_f = ep.findings.iter().max_by(|a, b| a.ratio().total_cmp(&b.ratio()));
    let mean_err = |v: &[&EpisodeScore]| -> [f64; 3] {
        std::array::from_fn(|k| v.iter().map(|e| e.outcome.velocity_error_rms[k]).sum::<f64>() / v.len().max(1) as f64)
    };
    let engine_name = s.factories[engine_ix].name();
    Ok(Evidence {
        case: case.name.clone(),
        seed: worst.seed,
        phase,
        phase_share: share(pv, phase_total),
        joint: s.model.joints.get(jix).map_or_else(String::new, |j| j.name.clone()),
        joint_share: share(jv, joint_total),
        worst_finding: worst_f.map(|f| (f.kind.clone(), f.quantity.clone(), f.phase.to_string(), f.ratio())),
        covered_by: worst_f.and_then(|f| s.allow.covering(f)).map(|c| c.id()),
        known_differences: known_differences(s.allow, &engine_name),
        tracking_error: mean_err(mine),
        train_tracking_error: mean_err(train_scores),
    })
}

/// Ids of the allow-list entries recorded for `engine`.
fn known_differences(allow: &AllowList, engine: &str) -> Vec<String> {
    allow.entries.iter().filter(|e| e.engines.iter().any(|x| x == engine)).map(|e| e.id.clone()).collect()
}

fn fmt_interval(i: &Option<Interval>) -> String {
    match i {
        Some(i) => format!("{} [{}, {}]", crate::report::g3(i.mean), crate::report::g3(i.lo), crate::report::g3(i.hi)),
        None => "–".into(),
    }
}

impl ValidationReport {
    /// The engines whose verdict is `degrades` or `fails`.
    pub fn flagged(&self) -> Vec<&EngineSummary> {
        self.engines.iter().filter(|e| matches!(e.verdict, Verdict::Degrades | Verdict::Fails)).collect()
    }

    /// `report.md`.
    pub fn markdown(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "# Cross-engine validation of {} on {}\n", self.controller, self.robot);
        let flagged = self.flagged();
        let verdict = if self.engines.iter().any(|e| e.verdict == Verdict::Inconclusive) {
            format!(
                "**Inconclusive**: the policy falls in its training engine ({}) in at least {:.0} % of the episodes.",
                self.train_engine,
                100.0 * FAIL_FALL_RATE
            )
        } else if flagged.is_empty() {
            format!(
                "**Transfers**: no engine scores significantly lower than the training engine ({}).",
                self.train_engine
            )
        } else {
            let list: Vec<String> = flagged.iter().map(|e| format!("{} ({})", e.engine, e.verdict.label())).collect();
            let agree: Vec<&str> =
                self.engines.iter().filter(|e| e.verdict == Verdict::Transfers).map(|e| e.engine.as_str()).collect();
            let mut v = format!(
                "**Degrades outside its training engine ({})**: {}. A policy that scores well only in the engine it was trained in may exploit that engine; \
                 where other independent engines agree with the training engine ({}), the flagged engines' own modelling differences are the first suspect.",
                self.train_engine,
                list.join(", "),
                if agree.is_empty() { "none here".to_string() } else { agree.join(", ") }
            );
            if agree.is_empty() && flagged.len() >= 2 {
                let _ = write!(
                    v,
                    " Here every other engine ({}) flags it: the policy most likely relies on its training engine's own modelling \
                     (known modelling differences of {}: {}).",
                    flagged.len(),
                    self.train_engine,
                    if self.train_known_differences.is_empty() {
                        "none recorded".to_string()
                    } else {
                        self.train_known_differences.join(", ")
                    }
                );
            }
            v
        };
        let _ = writeln!(s, "{verdict}\n");
        let cmds: Vec<String> = self
            .commands
            .iter()
            .map(|c| format!("{} ({}, {}, {})", c.name, c.command[0], c.command[1], c.command[2]))
            .collect();
        let _ = writeln!(
            s,
            "Episodes: {} s each, commands {} after {SETTLE_S} s of standing, seeds {:?}; the same noise and push in every engine. \
             Task score = survived fraction × exp(−e²/{TRACKING_SIGMA}) of the RMS velocity-tracking error e (0..1). \
             Drop = training-engine score − engine score, paired over (command, seed), mean and 95 % bootstrap interval; \
             p from a sign-flip permutation test. Verdicts: fails = falls in ≥ {:.0} % of episodes; degrades = drop ≥ {MIN_DROP} with p < {ALPHA}.\n",
            self.seconds,
            cmds.join(", "),
            self.seeds,
            100.0 * FAIL_FALL_RATE
        );
        let _ = writeln!(
            s,
            "| engine | verdict | score | drop | p | falls | tracking RMS | energy (J/m) | foot slip (m/s) | at joint limit |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
        for e in &self.engines {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {:.0} %{} | {} | {} | {} | {} |",
                e.engine,
                e.verdict.label(),
                fmt_interval(&e.score),
                fmt_interval(&e.drop),
                e.p_value.map_or("–".into(), crate::report::g3),
                100.0 * e.fall_rate,
                if e.engine_errors > 0 { format!(" ({} engine errors)", e.engine_errors) } else { String::new() },
                fmt_interval(&e.velocity_tracking_rms),
                fmt_interval(&e.energy_per_m),
                fmt_interval(&e.foot_slip_mps),
                fmt_interval(&e.joint_limit_fraction),
            );
        }
        let _ = writeln!(s, "\n## Score per command\n");
        let _ = writeln!(
            s,
            "| engine | {} |",
            self.commands.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(" | ")
        );
        let _ = writeln!(s, "|---|{}", "---|".repeat(self.commands.len()));
        for e in &self.engines {
            let cells: Vec<String> = e.score_per_case.iter().map(|(_, v)| crate::report::g3(*v)).collect();
            let _ = writeln!(s, "| {} | {} |", e.engine, cells.join(" | "));
        }
        let with_evidence: Vec<&EngineSummary> = self.engines.iter().filter(|e| e.evidence.is_some()).collect();
        if !with_evidence.is_empty() {
            let _ = writeln!(s, "\n## Where it degrades\n");
            let _ = writeln!(
                s,
                "Windowed divergence (0.1 s windows from identical states, {} as lead) of the episode with the largest drop:\n",
                self.train_engine
            );
            for e in with_evidence {
                let Some(ev) = &e.evidence else { continue };
                let finding = match &ev.worst_finding {
                    Some((kind, q, phase, r)) => format!(
                        "largest bound excess: {q} ({kind}) in phase {phase}, {}× its bound, {}",
                        crate::report::g3(*r),
                        ev.covered_by
                            .as_ref()
                            .map_or("covered by no allow-list entry for this lead".into(), |id| format!(
                                "covered by allow-list entry `{id}`"
                            ))
                    ),
                    None => "no bound exceeded".into(),
                };
                let [a, b, c] = ev.tracking_error;
                let [ta, tb, tc] = ev.train_tracking_error;
                let _ = writeln!(
                    s,
                    "- **{}**: velocity-tracking error RMS forward {a:.3} m/s, lateral {b:.3} m/s, yaw rate {c:.3} rad/s \
                     (in {}: {ta:.3}, {tb:.3}, {tc:.3}). In {} seed {}: {:.0} % of the link divergence in phase `{}`, {:.0} % of the joint divergence at {}; {}; known modelling differences of this engine: {}.",
                    e.engine,
                    self.train_engine,
                    ev.case,
                    ev.seed,
                    100.0 * ev.phase_share,
                    ev.phase,
                    100.0 * ev.joint_share,
                    ev.joint,
                    finding,
                    if ev.known_differences.is_empty() { "none".into() } else { ev.known_differences.join(", ") }
                );
            }
        }
        s
    }
}

/// Writes `report.md`, `report.json` and `scores.svg` (mean score per command and engine) into `dir`.
pub fn write_validation(dir: &std::path::Path, r: &ValidationReport) -> Result<(), DiffError> {
    use plotters::prelude::*;
    std::fs::create_dir_all(dir).map_err(crate::io_err(dir))?;
    let w = |name: &str, text: String| {
        let p = dir.join(name);
        std::fs::write(&p, text).map_err(crate::io_err(&p))
    };
    w("report.md", r.markdown())?;
    w("report.json", serde_json::to_string_pretty(r)?)?;
    let path = dir.join("scores.svg");
    let plot = |e: DrawingAreaErrorKind<std::io::Error>| DiffError::Plot(Box::new(e));
    let root = SVGBackend::new(&path, (800, 400)).into_drawing_area();
    root.fill(&WHITE).map_err(plot)?;
    let ne = r.engines.len().max(1);
    let nc = r.commands.len().max(1);
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .caption("mean task score per command (bars: engines in report order)", ("sans-serif", 16))
        .x_label_area_size(30)
        .y_label_area_size(40)
        .build_cartesian_2d(0f64..nc as f64, 0f64..1.05f64)
        .map_err(|e| DiffError::Plot(Box::new(e)))?;
    chart
        .configure_mesh()
        .x_labels(nc)
        .x_label_formatter(&|x| r.commands.get(x.floor() as usize).map_or(String::new(), |c| c.name.clone()))
        .draw()
        .map_err(|e| DiffError::Plot(Box::new(e)))?;
    for (i, e) in r.engines.iter().enumerate() {
        let colour = crate::report::palette(i);
        let bars = e.score_per_case.iter().enumerate().filter(|(_, (_, v))| v.is_finite()).map(|(c, (_, v))| {
            let x0 = c as f64 + 0.1 + 0.8 * i as f64 / ne as f64;
            Rectangle::new([(x0, 0.0), (x0 + 0.8 / ne as f64, *v)], colour.filled())
        });
        chart
            .draw_series(bars)
            .map_err(|e| DiffError::Plot(Box::new(e)))?
            .label(e.engine.clone())
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], colour.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| DiffError::Plot(Box::new(e)))?;
    root.present().map_err(plot)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sign_flip_p_values_match_their_closed_forms() {
        // All n differences of one sign: only the all-plus and all-minus sign vectors are as extreme, p = 2 / 2^n.
        assert_eq!(paired_p_value(&[0.3, 0.1, 0.2, 0.5, 0.4], 1), 2.0 / 32.0);
        assert_eq!(paired_p_value(&[1.0; 12], 1), 2.0 / 4096.0);
        // Symmetric differences: every sign vector is at least as extreme as a zero sum.
        assert_eq!(paired_p_value(&[1.0, -1.0, 2.0, -2.0], 1), 1.0);
        // {2, 2, -1} (observed |sum| 3): the 8 sign vectors give ±5, ±3, ±1, ±1; |sum| >= 3 in 4 of them.
        assert_eq!(paired_p_value(&[2.0, 2.0, -1.0], 1), 4.0 / 8.0);
        // Above 16 pairs the test samples: 20 equal differences are as extreme only at 2 of 2^20 vectors.
        let p = paired_p_value(&[0.2; 20], 7);
        assert!(p < 1e-3, "{p}");
        assert_eq!(paired_p_value(&[], 1), 1.0);
    }

    #[test]
    fn bootstrap_interval_brackets_the_mean() {
        let c = Interval::of(&[0.4; 6], 1).expect("values");
        assert_eq!(c.n, 6);
        assert!([c.mean, c.lo, c.hi].iter().all(|x| (x - 0.4).abs() < 1e-12), "{c:?}");
        let v: Vec<f64> = (0..40).map(|i| f64::from(i) / 40.0).collect();
        let i = Interval::of(&v, 1).expect("values");
        assert!(i.lo < i.mean && i.mean < i.hi, "{i:?}");
        // The standard error of the mean of U(0,1)-like data of 40 is ~0.046: a 95 % interval of about ±0.09.
        assert!(i.hi - i.lo > 0.12 && i.hi - i.lo < 0.24, "{i:?}");
        assert!(Interval::of(&[f64::NAN], 1).is_none());
    }

    #[test]
    fn task_score_combines_survival_and_tracking() {
        let o = |survived_s: f64, e: f64| Outcome {
            fell: survived_s < 4.0,
            velocity_tracking_rms: e,
            survived_s,
            ..Outcome::before_start("x")
        };
        assert_eq!(task_score(&o(4.0, 0.0), 4.0), 1.0);
        assert_eq!(task_score(&o(2.0, 0.0), 4.0), 0.5);
        assert!((task_score(&o(4.0, 0.5), 4.0) - (-1.0f64).exp()).abs() < 1e-12);
    }

    #[test]
    fn the_grid_starts_commands_after_standing() {
        let s = scenario_for(&standard_commands()[1], 3, 6.0);
        assert_eq!(s.command_at(0.5), [0.0; 3]);
        assert_eq!(s.command_at(SETTLE_S + 0.01), [0.5, 0.0, 0.0]);
        assert!(s.validate().is_ok());
    }
}
