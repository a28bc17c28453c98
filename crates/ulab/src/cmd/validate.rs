//! `ulab validate --policy SPEC [--train-engine E] [--engines ...] [--episodes N] [--seconds T] --out DIR`:
//! cross-engine validation of a policy (issue 15). Closed-loop episodes in every engine over a grid of commands
//! and seeds; per engine the task score, falls, tracking, energy per metre, foot slip and joint-limit time, the
//! score drop against the training engine with a paired significance test, and a verdict (transfers / degrades /
//! fails) with the windowed divergence that points at where it degrades. The computation is
//! `engine_diff::validate`.
//!
//! `--video OUT.mp4` renders one rollout side by side, the training engine leftmost: the first command of
//! `--commands` with the first seed (`--seed`), recomputed after the validation with the same function
//! (`engine_diff::validate::episode_score_recorded`, so the same deterministic rollout), every engine's panel
//! captioned with its divergence from the training engine (`super::video::render_trajectories`).
//!
//! `--shard K/N` runs only the grid's episodes dealt to shard K (grid order: engine, command, seed; episode i to
//! shard i mod N + 1) and writes `DIR/shard-K-of-N.cbor`; `ulab merge` summarises every shard's episodes into
//! the unsharded run's report.
//!
//! Exit codes: 0 report written, 1 some engine degrades or fails and `--fail-on-degrade` was given, 2 errors.
use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use engine_diff::harness::{builtin_factories, HarnessConfig};
use engine_diff::triage::AllowList;
use engine_diff::validate::{
    report as validation_report, run_tasks, standard_commands, tasks, validate as run_validation, write_validation,
    CommandCase, EpisodeScore, ValidateSetup, ValidationReport,
};
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Built-in robot name, or a path to a sidecar TOML.
    #[arg(long, default_value = "h1_2")]
    robot: String,
    /// Policy spec TOML (robots/h1_2/policies/*.toml).
    #[arg(long, required_unless_present = "gait_search", conflicts_with = "gait_search")]
    policy: Option<PathBuf>,
    /// Instead of a policy, optimise the built-in parameterised gait (`engine_diff::gait`, 16 parameters,
    /// cross-entropy method) for the forward command in the training engine alone, save it as `gait.json` and
    /// validate it: a probe of how much a controller tuned in that engine leans on it.
    #[arg(long)]
    gait_search: bool,
    /// Iterations of the gait search (16 candidates and 2 seeds each).
    #[arg(long, default_value_t = 10, requires = "gait_search")]
    gait_iterations: usize,
    /// The engine the policy was trained in: the scores of every other engine are compared with its scores.
    /// Both shipped H1-2 policies were trained in PhysX (Isaac Lab, Isaac Gym).
    #[arg(long, default_value = "physx")]
    train_engine: String,
    #[arg(long, help = super::engines_help("Engines (comma-separated; the training engine is added if missing); default: every engine of this build:"))]
    engines: Option<String>,
    /// Commands of the grid (comma-separated names: stand, forward, lateral, turn).
    #[arg(long, default_value = "stand,forward,lateral,turn")]
    commands: String,
    /// Episodes (seeds S, S+1, ...) per command and engine.
    #[arg(long, default_value_t = 3)]
    episodes: u64,
    /// Seconds per episode (the command starts after 1 s of standing).
    #[arg(long, default_value_t = 6.0)]
    seconds: f64,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output directory (report.md, report.json, scores.svg).
    #[arg(long)]
    out: PathBuf,
    /// Skip the windowed-divergence evidence for engines that degrade (faster).
    #[arg(long)]
    no_evidence: bool,
    /// Exit 1 when some engine degrades or fails.
    #[arg(long)]
    fail_on_degrade: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    jobs: Option<usize>,
    /// Also render the first command's first-seed rollout in every engine side by side (H.264 MP4).
    #[arg(long)]
    video: Option<PathBuf>,
    #[command(flatten)]
    video_args: super::video::VideoArgs,
    /// Run only the grid's episodes dealt to shard K of N (episode i of the engine x command x seed grid to shard
    /// i mod N + 1) and write `OUT/shard-K-of-N.cbor`; `ulab merge` turns the N shards into this run's report.
    #[arg(long, value_name = "K/N", conflicts_with_all = ["video", "gait_search"])]
    shard: Option<campaign::Shard>,
}

/// The shard files' kind of `ulab validate` campaigns.
pub(crate) const SHARD_KIND: &str = "validate";

/// Everything that decides a `ulab validate` report: what the shards of one campaign share.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct ValidateCampaign {
    robot: String,
    model_hash: String,
    policy: PathBuf,
    train_engine: String,
    /// Canonical engine names, the training engine among them.
    engines: Vec<String>,
    commands: Vec<String>,
    episodes: u64,
    seconds: f64,
    seed: u64,
    evidence: bool,
    fail_on_degrade: bool,
}

/// `--commands`: the named commands of the standard grid.
fn resolve_commands(list: &str) -> Result<Vec<CommandCase>> {
    let grid = standard_commands();
    let mut commands = Vec::new();
    for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let c = grid.iter().find(|c| c.name == name).with_context(|| {
            format!(
                "--commands: unknown command {name} (known: {})",
                grid.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", ")
            )
        })?;
        commands.push(c.clone());
    }
    if commands.is_empty() {
        bail!("--commands names no command");
    }
    Ok(commands)
}

/// Writes the report and prints a line per engine.
fn write_and_print(out: &Path, report: &ValidationReport) -> Result<()> {
    write_validation(out, report).with_context(|| format!("writing {}", out.display()))?;
    for e in &report.engines {
        println!(
            "{:<18} {:<15} score {:.3}  drop {}  falls {:.0} %",
            e.engine,
            e.verdict.label(),
            e.score.map_or(f64::NAN, |s| s.mean),
            e.drop.map_or("-".into(), |d| format!("{:+.3} (p {:.3})", d.mean, e.p_value.unwrap_or(1.0))),
            100.0 * e.fall_rate
        );
    }
    println!("report in {}", out.join("report.md").display());
    Ok(())
}

/// `ulab merge` of `ulab validate --shard` files: the unsharded run's summary of the shards' episodes.
pub(crate) fn merge(files: &[PathBuf], out: &Path) -> Result<Exit> {
    let (c, episodes): (ValidateCampaign, Vec<EpisodeScore>) = super::merge::read_shards(files, SHARD_KIND)?;
    let model = super::diff::load_model(&c.robot)?;
    if engine_diff::model_hash(&model) != c.model_hash {
        bail!("robot {}: not the model the shards ran (its hash differs)", c.robot);
    }
    let commands = resolve_commands(&c.commands.join(","))?;
    let factories = builtin_factories(&c.engines).context("engines of the shards")?;
    let cfg = HarnessConfig::default();
    let (ctrl_name, ctrl) = super::diff::policy_factory(&c.policy)?;
    let seeds: Vec<u64> = (0..c.episodes).map(|i| c.seed + i).collect();
    let allow = AllowList::builtin().context("allow-list")?;
    let setup = ValidateSetup {
        model: &model,
        factories: &factories,
        train_engine: &c.train_engine,
        controller: ctrl.as_ref(),
        controller_name: &ctrl_name,
        commands: &commands,
        seeds: &seeds,
        seconds: c.seconds,
        cfg: &cfg,
        allow: &allow,
        evidence: c.evidence,
    };
    let report = validation_report(&setup, episodes).context("summarising the shards' episodes")?;
    write_and_print(out, &report)?;
    Ok(Exit::failed_if(c.fail_on_degrade && !report.flagged().is_empty()))
}

pub fn run(a: Args) -> Result<Exit> {
    if !(a.seconds.is_finite() && a.seconds >= 2.0 && a.seconds <= 600.0) {
        bail!("--seconds must be in [2, 600] (the command starts after 1 s)");
    }
    if a.episodes == 0 || a.episodes > 1000 {
        bail!("--episodes must be in 1..=1000");
    }
    if a.gait_iterations == 0 || a.gait_iterations > 1000 {
        bail!("--gait-iterations must be in 1..=1000");
    }
    super::diff::set_jobs(a.jobs)?;
    let commands = resolve_commands(&a.commands)?;
    let model = super::diff::load_model(&a.robot)?;
    // Canonical engine names (`rapier-multibody` is `rapier_multibody`): reports and the pairing use them.
    let canonical = |n: &str| -> Result<String> {
        Ok(diff_physics::EngineKind::parse_available(n).with_context(|| format!("engine {n}"))?.name().to_string())
    };
    let train = canonical(&a.train_engine).context("--train-engine")?;
    let mut names: Vec<String> = Vec::new();
    for n in super::diff::engine_names(a.engines.as_deref()) {
        let n = canonical(&n).context("--engines")?;
        if !names.contains(&n) {
            names.push(n);
        }
    }
    if !names.contains(&train) {
        names.insert(0, train.clone());
    }
    if names.len() < 2 {
        bail!("--engines needs at least one engine besides the training engine");
    }
    let factories = builtin_factories(&names).context("--engines / --train-engine")?;
    let cfg = HarnessConfig::default();
    let (ctrl_name, ctrl) = match &a.policy {
        Some(p) => super::diff::policy_factory(p)?,
        None => gait_controller(&a, &model, &factories, &train, &cfg)?,
    };
    let seeds: Vec<u64> = (0..a.episodes).map(|i| a.seed + i).collect();
    let allow = AllowList::builtin().context("allow-list")?;
    let setup = ValidateSetup {
        model: &model,
        factories: &factories,
        train_engine: &train,
        controller: ctrl.as_ref(),
        controller_name: &ctrl_name,
        commands: &commands,
        seeds: &seeds,
        seconds: a.seconds,
        cfg: &cfg,
        allow: &allow,
        evidence: !a.no_evidence,
    };
    if let Some(shard) = a.shard {
        // A gait search is not dealt to shards (clap refuses both): a shard campaign names its policy file.
        let policy = a.policy.clone().context("--shard needs --policy")?;
        let campaign = ValidateCampaign {
            robot: a.robot.clone(),
            model_hash: engine_diff::model_hash(&model),
            policy,
            train_engine: train.clone(),
            engines: names.clone(),
            commands: commands.iter().map(|c| c.name.clone()).collect(),
            episodes: a.episodes,
            seconds: a.seconds,
            seed: a.seed,
            evidence: !a.no_evidence,
            fail_on_degrade: a.fail_on_degrade,
        };
        let grid = tasks(&setup).context("the validation grid")?;
        let mine: Vec<usize> = shard.items(grid.len()).collect();
        let dealt: Vec<_> = mine.iter().map(|&i| grid[i]).collect();
        let episodes = run_tasks(&setup, &dealt).context("running the validation episodes")?;
        let results = mine.into_iter().zip(episodes).collect();
        return super::merge::write_shard(&a.out, SHARD_KIND, shard, grid.len(), campaign, results);
    }
    let report = run_validation(&setup).context("running the validation episodes")?;
    write_and_print(&a.out, &report)?;
    if let Some(path) = &a.video {
        render_rollout(&setup, path, &a.video_args).with_context(|| format!("rendering {}", path.display()))?;
    }
    Ok(Exit::failed_if(a.fail_on_degrade && !report.flagged().is_empty()))
}

/// The video of `--video`: the first command's first-seed rollout recomputed in every engine, the training
/// engine first (the lead the others are compared with).
fn render_rollout(s: &ValidateSetup<'_>, path: &std::path::Path, args: &super::video::VideoArgs) -> Result<()> {
    use engine_diff::harness::Trajectory;
    let (Some(case), Some(&seed)) = (s.commands.first(), s.seeds.first()) else { bail!("no rollout to render") };
    let mut order: Vec<_> = s.factories.iter().collect();
    order.sort_by_key(|f| f.name() != s.train_engine);
    let mut trajs = Vec::new();
    for f in order {
        let mut t = Trajectory::new(&f.name(), args.fps);
        let e = engine_diff::validate::episode_score_recorded(
            s.model,
            f.as_ref(),
            s.controller,
            case,
            seed,
            s.seconds,
            s.cfg,
            Some(&mut t),
        )
        .with_context(|| format!("{} in {}", case.name, f.name()))?;
        if t.samples.is_empty() {
            bail!("{} did not run: {}", f.name(), e.outcome.error.unwrap_or_default());
        }
        trajs.push(t);
    }
    let ends = super::video::render_trajectories(s.model, path, args, &trajs)?;
    for (t, d) in trajs.iter().zip(ends).skip(1) {
        println!("video ({} seed {seed}): {} ends {d:.3} m from {} (pelvis)", case.name, t.engine, s.train_engine);
    }
    Ok(())
}

/// Optimises the gait in the training engine (on search seeds the validation does not use) and writes
/// `gait.json` (parameters, fitness history) into the output directory.
fn gait_controller(
    a: &Args,
    model: &robot_model::RobotModel,
    factories: &[std::sync::Arc<dyn engine_diff::harness::EngineFactory>],
    train: &str,
    cfg: &HarnessConfig,
) -> Result<(String, Box<engine_diff::harness::ControllerFactory>)> {
    use engine_diff::gait::{optimise, GaitController, GaitSearchConfig};
    let forward = standard_commands().into_iter().find(|c| c.name == "forward").context("forward command")?;
    let engine = factories.iter().find(|f| f.name() == train).context("training engine")?;
    let seeds = vec![a.seed.wrapping_add(100_000), a.seed.wrapping_add(100_001)];
    let search = GaitSearchConfig { iterations: a.gait_iterations, seeds, ..GaitSearchConfig::default() };
    let opt = optimise(model, engine.as_ref(), &forward, &search, cfg).context("gait search")?;
    println!("gait search in {train}: {} episodes, fitness {:.3}", opt.episodes, opt.fitness);
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let path = a.out.join("gait.json");
    std::fs::write(&path, serde_json::to_string_pretty(&opt).context("gait.json")?)
        .with_context(|| format!("writing {}", path.display()))?;
    let ctrl = GaitController::factory(model, opt.params).context("gait")?;
    Ok((format!("gait optimised in {train}"), ctrl))
}
