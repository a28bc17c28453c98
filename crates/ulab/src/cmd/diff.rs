//! `ulab diff`: differential testing of physics engines driven by policy rollouts (issue 5).
//!
//! - `ulab diff --robot h1_2 [--policy SPEC] --engines mujoco,rapier-multibody,rapier-impulse [--episodes N]
//!   [--seconds T] [--seed S] --out DIR`: windowed divergence, invariants, outcome distributions, triaged and
//!   minimized entries; writes `DIR/report.md`, `report.json`, SVG plots and `repro_*.json`. Without
//!   `--policy` the built-in excitation input drives the robot. `--video OUT.mp4` also renders the first
//!   episode's free runs (every engine closed-loop from the same start) side by side, with the divergence from
//!   the lead written in each panel (`super::video::render_trajectories`).
//! - `ulab diff fuzz ... --out DIR [--iterations N] [--corpus DIR] [--lanes L]`: feedback-driven perturbation
//!   search in rounds of `--batch` inputs, as L independent lanes, then the same report over what it found; the
//!   corpus goes to `DIR/corpus/`. Its `--shard K/N` deals lanes, not inputs.
//! - `ulab diff replay FILE`: recomputes a reproducer; exit 0 if bit-identical, 1 if not.
//! - `ulab diff bench`: rollouts per second per engine, on one thread and on all cores.
//! - `ulab diff search [--budget N] [--methods cem,mutation,random]`: CEM over perturbations of the rollout
//!   against the mutation fuzzer and uniform random inputs, at equal compute.
//! - `ulab diff hash [--check TABLE|DIR] [--write TABLE]`: every engine's hash of a fixed episode
//!   (`engine_diff::determinism`), compared with the committed table of this machine class: bit-for-bit
//!   reproducibility, measured.
//!
//! `--shard K/N` runs only the episodes dealt to shard K (`campaign`: episode i goes to shard i mod N + 1) and
//! writes `DIR/shard-K-of-N.cbor` instead of the report; `ulab merge` (`super::merge`) runs the analysis on every
//! shard's episodes in the unsharded order and writes the unsharded run's report.
//!
//! Exit codes: 0 report written (or replay identical), 1 candidate engine bugs with `--fail-on-bug` (or a
//! replay that differs), 2 errors.
use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use engine_diff::harness::{
    builtin_factories, excitation_factory, ControllerFactory, EngineFactory, EpisodeResult, HarnessConfig,
};
use engine_diff::report::{analyse, write_outputs, Analysis};
use engine_diff::scenario::Scenario;
use engine_diff::triage::{AllowList, Class};
use rayon::prelude::*;
use robot_model::RobotModel;
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Args {
    #[command(subcommand)]
    command: Option<Sub>,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(Debug, clap::Subcommand)]
enum Sub {
    /// Search perturbations for the largest divergence per unit of perturbation, then report.
    Fuzz(FuzzArgs),
    /// Recompute a reproducer file and compare bit for bit (exit 1 if it differs).
    Replay(ReplayArgs),
    /// Rollouts per second per engine (one thread and all cores), time outside the engines.
    Bench(BenchArgs),
    /// Compare search methods at equal compute: CEM over perturbations of the rollout, the mutation fuzzer,
    /// uniform random perturbations (findings, largest normalised divergence, divergence per unit).
    Search(SearchArgs),
    /// Hash every step's state of a fixed episode per engine; compare with a committed table (exit 1 when an
    /// engine of the same version on the same machine class gives another hash).
    Hash(HashArgs),
}

#[derive(Debug, clap::Args)]
struct HashArgs {
    /// Built-in robot name.
    #[arg(long, default_value = "h1_2")]
    robot: String,
    #[arg(long, help = super::engines_help("Engines (comma-separated); default: every engine of this build:"))]
    engines: Option<String>,
    /// Seed of the fixed episode (built-in excitation input).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Length of the fixed episode (s).
    #[arg(long, default_value_t = 2.0)]
    seconds: f64,
    /// Worker threads (engines run in parallel); the hashes must not depend on it.
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// Committed table to compare with: a file, or a directory of tables (corpus/determinism/), of which the one
    /// of this robot and machine class is used.
    #[arg(long)]
    check: Option<PathBuf>,
    /// Write this run's table here (JSON).
    #[arg(long)]
    write: Option<PathBuf>,
}

#[derive(Debug, clap::Args)]
struct SearchArgs {
    #[command(flatten)]
    common: Common,
    /// Rollouts per method (equal compute).
    #[arg(long, default_value_t = 64)]
    budget: usize,
    /// CEM population per generation.
    #[arg(long, default_value_t = 16)]
    population: usize,
    /// Seconds per rollout.
    #[arg(long, default_value_t = 0.4)]
    seconds: f64,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Methods to run (comma-separated: cem, mutation, random).
    #[arg(long, value_delimiter = ',', default_value = "cem,mutation,random", value_parser = trimmed_method)]
    methods: Vec<MethodArg>,
    /// Writes every outcome (with its best scenario and progress curve) as JSON here.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// `--methods`: a search method of `engine_diff::search`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum MethodArg {
    Cem,
    Mutation,
    Random,
}

/// A `--methods` entry with the spaces around it ignored (`cem, random`).
fn trimmed_method(s: &str) -> Result<MethodArg, String> {
    <MethodArg as clap::ValueEnum>::from_str(s.trim(), false)
        .map_err(|_| format!("unknown method {:?} (cem, mutation, random)", s.trim()))
}

#[derive(Debug, Clone, clap::Args)]
struct Common {
    /// Built-in robot name, or a path to a sidecar TOML.
    #[arg(long, default_value = "h1_2")]
    robot: String,
    /// Policy spec TOML (robots/h1_2/policies/*.toml); default: the built-in excitation input.
    #[arg(long)]
    policy: Option<PathBuf>,
    #[arg(long, help = super::engines_help("Engines, lead first (comma-separated); default: every engine of this build, MuJoCo first:"))]
    engines: Option<String>,
    /// Steps per divergence window (k of the k-step divergence).
    #[arg(long, default_value_t = 50)]
    window: usize,
    /// Worker threads (default: all cores).
    #[arg(long)]
    jobs: Option<usize>,
}

#[derive(Debug, clap::Args)]
struct RunArgs {
    #[command(flatten)]
    common: Common,
    /// Episodes (one seed each: S, S+1, ...).
    #[arg(long, default_value_t = 4)]
    episodes: usize,
    /// Seconds per episode.
    #[arg(long, default_value_t = 1.0)]
    seconds: f64,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output directory.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Entries to minimize (the largest; the rest are triaged only).
    #[arg(long, default_value_t = 8)]
    minimize: usize,
    /// Exit 1 when an entry is triaged as a candidate engine bug.
    #[arg(long)]
    fail_on_bug: bool,
    /// Also render the first episode (seed S) as a video: one panel per engine, lead leftmost, every camera
    /// following the lead's pelvis, each panel's divergence from the lead in its caption (H.264 MP4).
    #[arg(long)]
    video: Option<PathBuf>,
    #[command(flatten)]
    video_args: super::video::VideoArgs,
    /// Run only the episodes dealt to shard K of N (episode i to shard i mod N + 1) and write
    /// `OUT/shard-K-of-N.cbor`; `ulab merge` turns the N shards into this run's report.
    #[arg(long, value_name = "K/N", conflicts_with = "video")]
    shard: Option<campaign::Shard>,
}

/// The shard files' kind of `ulab diff` campaigns.
pub(crate) const SHARD_KIND: &str = "diff";
/// The shard files' kind of `ulab diff fuzz` campaigns.
pub(crate) const FUZZ_SHARD_KIND: &str = "diff-fuzz";

/// The `Common` arguments a campaign's shards share (`--jobs` is each machine's own).
fn campaign_common(robot: &str, policy: &Option<PathBuf>, engines: &[String], window: usize) -> Common {
    Common { robot: robot.to_owned(), policy: policy.clone(), engines: Some(engines.join(",")), window, jobs: None }
}

/// Everything that decides a `ulab diff fuzz` campaign (`--jobs` and `--out` do not change a result).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct FuzzCampaign {
    robot: String,
    model_hash: String,
    policy: Option<PathBuf>,
    /// Canonical engine names, lead first.
    engines: Vec<String>,
    window: usize,
    seconds: f64,
    seed: u64,
    iterations: usize,
    batch: usize,
    lanes: usize,
    minimize: usize,
    fail_on_bug: bool,
    /// The seed corpus of `--corpus` (its scenarios, so that every shard starts from the same inputs).
    corpus: Option<Vec<Scenario>>,
}

impl FuzzCampaign {
    /// Lane `lane`'s starting inputs: the seed corpus, or two built-in inputs from the lane's seed.
    fn lane_inputs(&self, lane: usize, is_policy: bool) -> Vec<Scenario> {
        if let Some(c) = &self.corpus {
            return c.clone();
        }
        let seed = engine_diff::fuzz::lane_seed(self.seed, lane);
        (0..2u64)
            .map(|i| {
                if is_policy {
                    Scenario::policy(seed + i, self.seconds)
                } else {
                    Scenario::excitation(seed + i, self.seconds)
                }
            })
            .collect()
    }

    fn lane_config(&self, lane: usize) -> engine_diff::fuzz::FuzzConfig {
        engine_diff::fuzz::FuzzConfig {
            iterations: engine_diff::fuzz::lane_iterations(self.iterations, self.lanes, lane),
            batch: self.batch,
            seed: engine_diff::fuzz::lane_seed(self.seed, lane),
        }
    }
}

/// Everything that decides a `ulab diff` report: what the shards of one campaign share (`--jobs` and `--out` do
/// not change a result).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct DiffCampaign {
    robot: String,
    /// The model the episodes ran on (a sidecar path may name another model on another machine).
    model_hash: String,
    policy: Option<PathBuf>,
    /// Canonical engine names, lead first.
    engines: Vec<String>,
    window: usize,
    episodes: usize,
    seconds: f64,
    seed: u64,
    minimize: usize,
    fail_on_bug: bool,
}

impl DiffCampaign {
    /// The episodes' inputs, in report order.
    fn scenarios(&self, is_policy: bool) -> Vec<Scenario> {
        (0..self.episodes as u64)
            .map(|i| {
                if is_policy {
                    Scenario::policy(self.seed + i, self.seconds)
                } else {
                    Scenario::excitation(self.seed + i, self.seconds)
                }
            })
            .collect()
    }

    fn common(&self) -> Common {
        campaign_common(&self.robot, &self.policy, &self.engines, self.window)
    }
}

#[derive(Debug, clap::Args)]
struct FuzzArgs {
    #[command(flatten)]
    common: Common,
    /// Inputs to evaluate.
    #[arg(long, default_value_t = 32)]
    iterations: usize,
    /// Inputs per round: the corpus learns from a round's results before the next round is drawn. Part of what
    /// decides the campaign (unlike `--jobs`, which only sets how many threads run a round).
    #[arg(long, default_value_t = engine_diff::fuzz::DEFAULT_BATCH)]
    batch: usize,
    /// Seconds per input.
    #[arg(long, default_value_t = 0.4)]
    seconds: f64,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Seed corpus: a folder of scenario JSON files (default: built-in seeds).
    #[arg(long)]
    corpus: Option<PathBuf>,
    /// Independent fuzzers the campaign is made of, the iterations spread over them (lane 0 keeps `--seed`; a lane
    /// is what `--shard` deals out). One lane is the plain fuzzer.
    #[arg(long, default_value_t = 1)]
    lanes: usize,
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value_t = 6)]
    minimize: usize,
    #[arg(long)]
    fail_on_bug: bool,
    /// Run only the lanes dealt to shard K of N (lane l to shard l mod N + 1) and write `OUT/shard-K-of-N.cbor`;
    /// `ulab merge` turns the N shards into this campaign's corpus and report.
    #[arg(long, value_name = "K/N")]
    shard: Option<campaign::Shard>,
}

#[derive(Debug, clap::Args)]
struct ReplayArgs {
    /// A `repro_*.json` written by `ulab diff` or `ulab diff fuzz`.
    file: PathBuf,
    #[arg(long, default_value = "h1_2")]
    robot: String,
}

#[derive(Debug, clap::Args)]
struct BenchArgs {
    #[command(flatten)]
    common: Common,
    #[arg(long, default_value_t = 0.5)]
    seconds: f64,
    /// Rollouts per measurement.
    #[arg(long, default_value_t = 4)]
    rollouts: usize,
}

pub fn run(args: Args) -> Result<Exit> {
    match args.command {
        Some(Sub::Fuzz(a)) => fuzz(a),
        Some(Sub::Replay(a)) => replay(a),
        Some(Sub::Bench(a)) => bench(a),
        Some(Sub::Search(a)) => search(a),
        Some(Sub::Hash(a)) => hash(a),
        None => diff(args.run),
    }
}

pub(crate) fn load_model(robot: &str) -> Result<RobotModel> {
    if robot_model::BUILTIN_ROBOTS.contains(&robot) {
        robot_model::builtin(robot).with_context(|| format!("loading built-in robot {robot}"))
    } else {
        RobotModel::load(Path::new(robot)).with_context(|| format!("loading robot model {robot}"))
    }
}

/// A policy spec as a controller factory (loaded once, cloned per episode and engine).
pub(crate) fn policy_factory(spec: &Path) -> Result<(String, Box<ControllerFactory>)> {
    let pc = policy_runtime::PolicyController::load(spec)
        .with_context(|| format!("loading policy spec {}", spec.display()))?;
    let name = policy_runtime::Controller::name(&pc).to_string();
    let f: Box<ControllerFactory> =
        Box::new(move |_s: &Scenario| Ok(Box::new(pc.clone()) as Box<dyn policy_runtime::Controller>));
    Ok((name, f))
}

struct Setup {
    model: RobotModel,
    factories: Vec<Arc<dyn EngineFactory>>,
    ctrl: Box<ControllerFactory>,
    ctrl_name: String,
    cfg: HarnessConfig,
    is_policy: bool,
}

/// `--jobs`: the size of rayon's global pool (default: all cores).
pub(crate) fn set_jobs(jobs: Option<usize>) -> Result<()> {
    if let Some(j) = jobs {
        if j == 0 {
            bail!("--jobs must be at least 1");
        }
        // Only the first call configures the global pool; later ones (tests in one process) keep it.
        let _ = rayon::ThreadPoolBuilder::new().num_threads(j).build_global();
    }
    Ok(())
}

/// `--engines`: the comma-separated names as given, or every engine of this build.
pub(crate) fn engine_names(list: Option<&str>) -> Vec<String> {
    list.map_or_else(default_engines, str::to_string)
        .split(',')
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .collect()
}

fn setup(c: &Common) -> Result<Setup> {
    set_jobs(c.jobs)?;
    if c.window == 0 || c.window > 10_000 {
        bail!("--window must be in 1..=10000 steps");
    }
    let model = load_model(&c.robot)?;
    let names = engine_names(c.engines.as_deref());
    if names.len() < 2 {
        bail!("--engines needs at least two engines (the first is the lead)");
    }
    let factories = builtin_factories(&names).context("--engines")?;
    let (ctrl_name, ctrl, is_policy) = match &c.policy {
        Some(p) => {
            let (n, f) = policy_factory(p)?;
            (n, f, true)
        }
        None => ("excitation".to_string(), excitation_factory(&model), false),
    };
    let cfg = HarnessConfig { window_steps: c.window, ..HarnessConfig::default() };
    Ok(Setup { model, factories, ctrl, ctrl_name, cfg, is_policy })
}

fn check_seconds(s: f64) -> Result<()> {
    if !(s.is_finite() && s > 0.0 && s <= 600.0) {
        bail!("--seconds must be in (0, 600]");
    }
    Ok(())
}

fn summarize(out: &Path, report: &engine_diff::report::Report, fail_on_bug: bool) -> Exit {
    let failures = report.engine_failures.len();
    let bugs = report.entries.iter().filter(|e| e.triage == Class::CandidateEngineBug).count() + failures;
    let expected = report.entries.iter().filter(|e| matches!(e.triage, Class::ExpectedDifference { .. })).count();
    let translation = report.entries.len() + failures - bugs - expected;
    let of_which = if failures > 0 { format!(" ({failures} of them engine failures)") } else { String::new() };
    println!(
        "{} entries: {bugs} candidate engine bug(s){of_which}, {expected} expected difference(s), {translation} translation problem(s); report in {}",
        report.entries.len() + failures,
        out.join("report.md").display()
    );
    if fail_on_bug && bugs > 0 {
        Exit::Failed
    } else {
        Exit::Success
    }
}

fn diff(a: RunArgs) -> Result<Exit> {
    let Some(out) = a.out.clone() else { bail!("--out DIR is required") };
    check_seconds(a.seconds)?;
    if a.episodes == 0 || a.episodes > 10_000 {
        bail!("--episodes must be in 1..=10000");
    }
    let s = setup(&a.common)?;
    let campaign = DiffCampaign {
        robot: a.common.robot.clone(),
        model_hash: engine_diff::model_hash(&s.model),
        policy: a.common.policy.clone(),
        engines: s.factories.iter().map(|f| f.name()).collect(),
        window: a.common.window,
        episodes: a.episodes,
        seconds: a.seconds,
        seed: a.seed,
        minimize: a.minimize,
        fail_on_bug: a.fail_on_bug,
    };
    let scenarios = campaign.scenarios(s.is_policy);
    let items: Vec<usize> = match a.shard {
        Some(shard) => shard.items(scenarios.len()).collect(),
        None => (0..scenarios.len()).collect(),
    };
    // The video's episode keeps its free runs' states (the windowed runs restart every engine from the lead's
    // state each window, so only the free runs show how far the engines drift apart).
    let video_cfg = HarnessConfig { record_fps: Some(a.video_args.fps), ..s.cfg.clone() };
    let episodes = items
        .par_iter()
        .map(|&i| {
            let cfg = if i == 0 && a.video.is_some() { &video_cfg } else { &s.cfg };
            engine_diff::harness::run_episode(&s.model, &s.factories, s.ctrl.as_ref(), &scenarios[i], cfg)
        })
        .collect::<Result<Vec<_>, _>>()
        .context("running episodes")?;
    if let Some(shard) = a.shard {
        let results = items.into_iter().zip(episodes).collect();
        return super::merge::write_shard(&out, SHARD_KIND, shard, scenarios.len(), campaign, results);
    }
    let report = report(&out, &s, a.minimize, &episodes, Vec::new())?;
    if let (Some(path), Some(first)) = (&a.video, episodes.first()) {
        let ends = super::video::render_trajectories(&s.model, path, &a.video_args, &first.trajectories)
            .with_context(|| format!("rendering {}", path.display()))?;
        for (t, d) in first.trajectories.iter().zip(ends).skip(1) {
            println!("video: {} ends {d:.3} m from {} (pelvis)", t.engine, first.engines[0]);
        }
    }
    Ok(summarize(&out, &report, a.fail_on_bug))
}

/// Analyses every episode of a run (in report order) and writes the report into `out`.
fn report(
    out: &Path,
    s: &Setup,
    minimize: usize,
    episodes: &[EpisodeResult],
    failures: Vec<engine_diff::harness::EngineFailure>,
) -> Result<engine_diff::report::Report> {
    let allow = AllowList::builtin().context("allow-list")?;
    let an = Analysis {
        model: &s.model,
        factories: &s.factories,
        controller: s.ctrl.as_ref(),
        controller_name: &s.ctrl_name,
        cfg: &s.cfg,
        allow: &allow,
        minimize_limit: minimize,
    };
    let (mut report, repros) = analyse(&an, episodes).context("analysing")?;
    report.engine_failures = failures;
    write_outputs(out, &report, &repros, episodes).with_context(|| format!("writing {}", out.display()))?;
    Ok(report)
}

/// `ulab merge` of `ulab diff --shard` files: the analysis of the unsharded run on the shards' episodes.
pub(crate) fn merge(files: &[PathBuf], out: &Path) -> Result<Exit> {
    let (c, episodes): (DiffCampaign, Vec<EpisodeResult>) = super::merge::read_shards(files, SHARD_KIND)?;
    let s = setup(&c.common())?;
    if engine_diff::model_hash(&s.model) != c.model_hash {
        bail!("robot {}: not the model the shards ran (its hash differs)", c.robot);
    }
    if episodes.len() != c.episodes {
        bail!("the shards hold {} episodes, their campaign {}", episodes.len(), c.episodes);
    }
    // The shards ran the campaign's inputs: each episode is the one the configuration makes.
    for (i, (e, sc)) in episodes.iter().zip(c.scenarios(s.is_policy)).enumerate() {
        if e.scenario != sc {
            bail!("episode {i} of the shards is not the input the campaign makes (seed {})", e.scenario.seed);
        }
    }
    let report = report(out, &s, c.minimize, &episodes, Vec::new())?;
    Ok(summarize(out, &report, c.fail_on_bug))
}

fn read_corpus(dir: &Path) -> Result<Vec<Scenario>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("reading corpus {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    let mut out = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).with_context(|| format!("reading {}", f.display()))?;
        // Corpus files hold either a scenario or a corpus entry (with its feedback).
        let v: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("parsing {}", f.display()))?;
        let sc: Scenario = serde_json::from_value(v.get("scenario").cloned().unwrap_or(v))
            .with_context(|| format!("{} is not a scenario", f.display()))?;
        sc.validate().with_context(|| format!("{}", f.display()))?;
        out.push(sc);
    }
    if out.is_empty() {
        bail!("corpus {} holds no scenario (*.json)", dir.display());
    }
    Ok(out)
}

fn fuzz(a: FuzzArgs) -> Result<Exit> {
    check_seconds(a.seconds)?;
    if a.iterations == 0 {
        bail!("--iterations must be at least 1");
    }
    if a.batch == 0 {
        bail!("--batch must be at least 1");
    }
    if a.lanes == 0 || a.lanes > a.iterations {
        bail!("--lanes must be in 1..=--iterations ({})", a.iterations);
    }
    let s = setup(&a.common)?;
    let corpus = match &a.corpus {
        Some(d) => Some(
            read_corpus(d)?
                .into_iter()
                .map(|mut x| {
                    x.seconds = a.seconds;
                    x
                })
                .collect(),
        ),
        None => None,
    };
    let campaign = FuzzCampaign {
        robot: a.common.robot.clone(),
        model_hash: engine_diff::model_hash(&s.model),
        policy: a.common.policy.clone(),
        engines: s.factories.iter().map(|f| f.name()).collect(),
        window: a.common.window,
        seconds: a.seconds,
        seed: a.seed,
        iterations: a.iterations,
        batch: a.batch,
        lanes: a.lanes,
        minimize: a.minimize,
        fail_on_bug: a.fail_on_bug,
        corpus,
    };
    let lanes: Vec<usize> = match a.shard {
        Some(shard) => shard.items(a.lanes).collect(),
        None => (0..a.lanes).collect(),
    };
    let inputs: usize = lanes.iter().map(|&l| campaign.lane_config(l).iterations).sum();
    let bar = indicatif::ProgressBar::new(inputs as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("fuzz {bar:40} {pos}/{len} inputs {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut outcomes = Vec::new();
    let mut before = 0;
    for &lane in &lanes {
        let progress = |n: usize| bar.set_position((before + n) as u64);
        let o = engine_diff::fuzz::fuzz(
            &s.model,
            &s.factories,
            s.ctrl.as_ref(),
            &s.cfg,
            &campaign.lane_config(lane),
            campaign.lane_inputs(lane, s.is_policy),
            &progress,
        )
        .with_context(|| format!("fuzzing lane {lane}"))?;
        before += o.evaluated;
        outcomes.push((lane, o));
    }
    bar.finish_and_clear();
    if let Some(shard) = a.shard {
        return super::merge::write_shard(&a.out, FUZZ_SHARD_KIND, shard, a.lanes, campaign, outcomes);
    }
    fuzz_report(&a.out, &s, &campaign, outcomes.into_iter().map(|(_, o)| o).collect())
}

/// Writes a fuzzing campaign's corpus and report from its lanes' outcomes (in lane order).
fn fuzz_report(out: &Path, s: &Setup, c: &FuzzCampaign, lanes: Vec<engine_diff::fuzz::FuzzOutcome>) -> Result<Exit> {
    let outcome = engine_diff::fuzz::combine_lanes(lanes);
    let corpus_dir = out.join("corpus");
    std::fs::create_dir_all(&corpus_dir).with_context(|| format!("creating {}", corpus_dir.display()))?;
    for (i, e) in outcome.corpus.iter().enumerate() {
        let p = corpus_dir.join(format!("{i:04}.json"));
        std::fs::write(&p, serde_json::to_string_pretty(e)?).with_context(|| format!("writing {}", p.display()))?;
    }
    println!(
        "fuzz: {} inputs evaluated ({} failed in an engine), corpus {}, {} contact patterns, best divergence/unit {:.3}",
        outcome.evaluated,
        outcome.failed,
        outcome.corpus.len(),
        outcome.patterns.len(),
        outcome.corpus.first().map(|c| c.score).unwrap_or(0.0)
    );
    let report = report(out, s, c.minimize, &outcome.episodes, outcome.failures)?;
    Ok(summarize(out, &report, c.fail_on_bug))
}

/// `ulab merge` of `ulab diff fuzz --shard` files: the unsharded campaign's corpus and report from the shards' lanes.
pub(crate) fn merge_fuzz(files: &[PathBuf], out: &Path) -> Result<Exit> {
    let (c, lanes): (FuzzCampaign, Vec<engine_diff::fuzz::FuzzOutcome>) =
        super::merge::read_shards(files, FUZZ_SHARD_KIND)?;
    let s = setup(&campaign_common(&c.robot, &c.policy, &c.engines, c.window))?;
    if engine_diff::model_hash(&s.model) != c.model_hash {
        bail!("robot {}: not the model the shards ran (its hash differs)", c.robot);
    }
    if lanes.len() != c.lanes {
        bail!("the shards hold {} lanes, their campaign {}", lanes.len(), c.lanes);
    }
    fuzz_report(out, &s, &c, lanes)
}

fn replay(a: ReplayArgs) -> Result<Exit> {
    let text = std::fs::read_to_string(&a.file).with_context(|| format!("reading {}", a.file.display()))?;
    let r: engine_diff::repro::Reproducer =
        serde_json::from_str(&text).with_context(|| format!("parsing reproducer {}", a.file.display()))?;
    let model = load_model(&a.robot)?;
    let o = r.replay(&model).context("replaying")?;
    println!(
        "{} {} / {} {}: value {:e} (bound {:e}) after {} step(s)",
        r.finding.kind, r.finding.engine, r.finding.lead, r.finding.quantity, o.value, r.finding.bound, r.steps
    );
    if o.identical {
        println!("identical: every state entry and the value match bit for bit");
        Ok(Exit::Success)
    } else {
        for m in &o.mismatches {
            println!("DIFFERS: {m}");
        }
        Ok(Exit::Failed)
    }
}

fn bench(a: BenchArgs) -> Result<Exit> {
    check_seconds(a.seconds)?;
    if a.rollouts == 0 {
        bail!("--rollouts must be at least 1");
    }
    let s = setup(&a.common)?;
    let threads = a.common.jobs.unwrap_or_else(rayon::current_num_threads);
    let rows = engine_diff::bench::run(&s.model, &s.factories, s.ctrl.as_ref(), &s.cfg, a.seconds, a.rollouts, threads)
        .context("benchmark")?;
    println!(
        "{:<52} {:>7} {:>9} {:>12} {:>12} {:>14}",
        "rollout", "threads", "rollouts", "rollouts/s", "steps/s", "outside engine"
    );
    for r in rows {
        println!(
            "{:<52} {:>7} {:>9} {:>12.3} {:>12.0} {:>13.1}%",
            format!("{} ({} s, {})", r.what, r.seconds_per_rollout, s.ctrl_name),
            r.threads,
            r.rollouts,
            r.rollouts_per_s,
            r.steps_per_s,
            100.0 * r.outside_engine
        );
    }
    Ok(Exit::Success)
}

fn search(a: SearchArgs) -> Result<Exit> {
    use engine_diff::search::{Method, SearchConfig, SearchSetup};
    check_seconds(a.seconds)?;
    if a.budget == 0 || a.budget > 100_000 || a.population < 2 {
        bail!("--budget must be in 1..=100000 and --population at least 2");
    }
    let methods = a.methods.iter().map(|m| match m {
        MethodArg::Cem => Method::Cem,
        MethodArg::Mutation => Method::Mutation,
        MethodArg::Random => Method::Random,
    });
    let s = setup(&a.common)?;
    let allow = AllowList::builtin().context("allow-list")?;
    let base = if s.is_policy { Scenario::policy(a.seed, a.seconds) } else { Scenario::excitation(a.seed, a.seconds) };
    // The base input without its own perturbations: every method starts from the plain rollout.
    let base = Scenario { commands: vec![], pushes: vec![], action_noise: 0.0, init_q_offset: 0.0, ..base };
    let setup = SearchSetup {
        model: &s.model,
        factories: &s.factories,
        controller: s.ctrl.as_ref(),
        cfg: &s.cfg,
        allow: &allow,
        base,
    };
    let c = SearchConfig { budget: a.budget, population: a.population, seed: a.seed, ..SearchConfig::default() };
    println!(
        "{:<9} {:>9} {:>7} {:>16} {:>16} {:>14} {:>12} {:>8}",
        "method", "rollouts", "failed", "best div/unit", "max norm. div", "finding groups", "unexplained", "wall s"
    );
    let mut outcomes = Vec::new();
    for m in methods {
        let o = engine_diff::search::search(&setup, m, &c).with_context(|| format!("search {}", m.name()))?;
        println!(
            "{:<9} {:>9} {:>7} {:>16.4} {:>16.3} {:>14} {:>12} {:>8.1}",
            m.name(),
            o.evaluated,
            o.failed,
            o.best_score,
            o.max_divergence,
            o.finding_groups,
            o.unexplained_groups,
            o.wall_s
        );
        outcomes.push(o);
    }
    if let Some(p) = &a.out {
        std::fs::write(p, serde_json::to_string_pretty(&outcomes)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(Exit::Success)
}

/// Every engine compiled into this build, MuJoCo (the lead) first.
pub(crate) fn default_engines() -> String {
    diff_physics::EngineKind::available().iter().map(|k| k.name()).collect::<Vec<_>>().join(",")
}

fn hash(a: HashArgs) -> Result<Exit> {
    use engine_diff::determinism::{compare, hash_table, read_tables, table_for, Comparison, HashTable, Probe};
    check_seconds(a.seconds)?;
    if !robot_model::BUILTIN_ROBOTS.contains(&a.robot.as_str()) {
        bail!("--robot must be a built-in robot ({})", robot_model::BUILTIN_ROBOTS.join(", "));
    }
    let model = load_model(&a.robot)?;
    let factories = builtin_factories(&engine_names(a.engines.as_deref())).context("--engines")?;
    let ctrl = excitation_factory(&model);
    let probe = Probe { seed: a.seed, seconds: a.seconds };
    let run = hash_table(&factories, &a.robot, &model, ctrl.as_ref(), probe, a.threads).context("hashing")?;
    println!("machine class {}; {} over {} s, seed {}", run.machine, run.robot, probe.seconds, probe.seed);
    for e in &run.engines {
        println!("{:<18} {:>5} steps  {}  {}", e.engine, e.steps, e.sha256, e.version);
    }
    if let Some(path) = &a.write {
        let text = serde_json::to_string_pretty(&run)? + "\n";
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    let Some(path) = &a.check else { return Ok(Exit::Success) };
    let table: HashTable = if path.is_dir() {
        let tables = read_tables(path).with_context(|| format!("reading the tables in {}", path.display()))?;
        let Some(t) = table_for(&tables, &run.robot, &run.machine) else {
            let measured: Vec<String> =
                tables.iter().filter(|t| t.robot == run.robot).map(|t| t.machine.to_string()).collect();
            for e in &run.engines {
                println!(
                    "{}: not compared: {} has no table for {} on {} (only for: {})",
                    e.engine,
                    path.display(),
                    run.robot,
                    run.machine,
                    measured.join(", ")
                );
            }
            return Ok(Exit::Success);
        };
        t.clone()
    } else {
        let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))?
    };
    let mut differs = 0;
    for (engine, c) in compare(&table, &run).with_context(|| format!("comparing with {}", path.display()))? {
        match c {
            Comparison::Reproduced => println!("{engine}: reproduced"),
            Comparison::Differs { expected, got } => {
                differs += 1;
                println!("{engine}: DIFFERS: table {expected}, this run {got}");
            }
            Comparison::NotCompared { why } => println!("{engine}: not compared: {why}"),
        }
    }
    Ok(Exit::failed_if(differs > 0))
}
