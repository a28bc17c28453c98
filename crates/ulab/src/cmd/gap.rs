//! `ulab gap`: sim-to-real gap diagnosis (the work is in the `gap-diagnosis` crate).
//!
//! - `ulab gap diagnose --log real.mcap --robot h1_2 [--engine E] [--plant auto|rig|floating] [--substeps N
//!   [--pd-held]] --out DIR [--format json] [--export-mjcf corrected.xml]`;
//!   exit 0 diagnosed, 3 with `--plant rig` the log is not from a suspended robot (rig-assumption check; report
//!   written, every effect abstained), 2 error. `--plant auto` (default) diagnoses such a log on the floating base.
//! - `ulab gap excite --robot h1_2 --out plan.mcap [--duration S] [--rate HZ]`
//! - `ulab gap simulate --robot h1_2 --out real.mcap [--effect KIND:UNIT:VALUE]... [--engine E]
//!   [--substeps N [--pd-held]]`: a log of the benchmark's reference plant (demo and test logs)
//! - `ulab gap bench [--trials N] [--seed S] [--duration S] [--out DIR] [--policy SPEC.toml]... [--floating]
//!   [--only TRIAL]... [--effects K,..] [--max-windows N] [--shard K/N]`; with `--shard` only the trials dealt to
//!   shard K (the i-th trial of the run to shard i mod N + 1) run, and `OUT/shard-K-of-N.cbor` takes the place of the
//!   bench's table; `ulab merge` ([`merge`]) writes the unsharded run's `seals.json`, `scores.json`, `table.md` and
//!   trial files from the shards.
use anyhow::{bail, Context, Result};
use gap_bench::{self as bench, BenchOptions, Motion, RealConfig};
use gap_diagnosis::diagnose::PlantChoice;
use gap_diagnosis::plant::{joint_groups, EngineChoice, PdUpdate, Stepping, GROUPS};
use gap_diagnosis::{effects::Scope, DiagnoseOptions, EffectKind, Outcome, RobotLog};

use crate::exit::Exit;
use robot_model::RobotModel;
use std::path::{Path, PathBuf};

/// `--plant`: which plant the diagnosis simulates (see `gap_diagnosis::diagnose::PlantChoice`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum PlantArg {
    /// The rig when the log passes the rig-assumption check, floating otherwise.
    Auto,
    /// The suspended robot (pelvis held still).
    Rig,
    /// The robot on flat ground, base state estimated from the log.
    Floating,
}

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: GapCommand,
}

#[derive(Debug, clap::Subcommand)]
enum GapCommand {
    /// Where the gap lies, which unmodelled effect causes it, how far it shrinks (held-out windows).
    Diagnose(DiagnoseArgs),
    /// Write a safe excitation plan (chirps and steps per joint group, suspended robot) as an MCAP of rt/lowcmd.
    Excite(ExciteArgs),
    /// Write a log of the benchmark's reference plant (MuJoCo RK4 on the rig, sensor noise, 50 Hz jitter).
    Simulate(SimulateArgs),
    /// Blind benchmark: hidden effects, sealed labels, scored diagnoses.
    Bench(BenchArgs),
}

#[derive(Debug, clap::Args)]
struct DiagnoseArgs {
    /// Log: MCAP written by `ulab record` (hg LowCmd on rt/lowcmd, hg LowState on rt/lowstate), or the directory
    /// `ulab log export` writes from one (rt_lowcmd.csv, rt_lowstate.csv).
    #[arg(long)]
    log: PathBuf,
    /// Built-in robot name or a sidecar TOML.
    #[arg(long, default_value = "h1_2")]
    robot: String,
    /// Diagnosing simulator: mujoco (implicitfast), mujoco-rk4, mujoco-euler, mujoco-implicit. Only MuJoCo: the
    /// floating plant's contact effect is MuJoCo's solref and the window replay is tuned on it; Bullet, DART and
    /// Rapier serve as independent reference plants (`gap bench --reference-engine`, `gap simulate --engine`).
    #[arg(long, default_value = "mujoco")]
    engine: String,
    /// Plant: rig (suspended robot), floating (standing/walking on flat ground, base state estimated from the log),
    /// or auto: the rig when the log passes the rig-assumption check, floating otherwise.
    #[arg(long, value_enum, default_value_t = PlantArg::Auto)]
    plant: PlantArg,
    /// Output directory (report.md, report.json, SVG plots).
    #[arg(long)]
    out: PathBuf,
    /// What to print: a summary (text) or the whole report (json).
    #[arg(long, value_enum, default_value_t = super::OutputFormat::Text)]
    format: super::OutputFormat,
    /// Window length (s).
    #[arg(long, default_value_t = 0.1)]
    window: f64,
    /// At most this many windows, spread over the log [default: 64 on the rig, 120 on the floating base]; the time of a
    /// diagnosis grows with them.
    #[arg(long)]
    max_windows: Option<usize>,
    /// Training and held-out segments alternate every this many seconds.
    #[arg(long, default_value_t = 1.0)]
    block: f64,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Only these effect kinds, comma-separated (e.g. `damping,friction`) [default: the whole library]. A
    /// shorter list is a faster diagnosis that cannot name, rank against or set aside the kinds left out.
    #[arg(long, value_delimiter = ',')]
    effects: Vec<String>,
    #[command(flatten)]
    stepping: SteppingArgs,
    /// Also write the robot's MJCF corrected by the named effects (armature, damping, frictionloss, motor
    /// ctrlrange, link inertials; the drive's and sensors' effects as `ulab_*` custom numerics, explained in the
    /// file's comment), and beside it FILE with `.nominal.xml` for its extension: the same model uncorrected, so that
    /// a diff of the two shows the corrections.
    #[arg(long, value_name = "FILE")]
    export_mjcf: Option<PathBuf>,
}

#[derive(Debug, clap::Args)]
struct ExciteArgs {
    #[arg(long, default_value = "h1_2")]
    robot: String,
    #[arg(long)]
    out: PathBuf,
    /// Plan length (s).
    #[arg(long, default_value_t = 60.0)]
    duration: f64,
    /// Command rate (Hz).
    #[arg(long, default_value_t = 500.0)]
    rate: f64,
    /// Overwrite the output file.
    #[arg(long)]
    force: bool,
}

#[derive(Debug, clap::Args)]
struct SimulateArgs {
    #[arg(long, default_value = "h1_2")]
    robot: String,
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value_t = 20.0)]
    duration: f64,
    /// Injected effect KIND:UNIT:VALUE (UNIT: a group left_leg|right_leg|torso|left_arm|right_arm, a motor
    /// name, `robot` for latency (VALUE in ms) or imu_x|imu_y|imu_z). Repeatable.
    #[arg(long)]
    effect: Vec<String>,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Engine of the simulated robot on the rig: mujoco-rk4 (default), mujoco, mujoco-euler, mujoco-implicit,
    /// bullet, dart, rapier_multibody (with another engine than MuJoCo, damping and Coulomb friction effects go
    /// through the engine's own joint parameters).
    #[arg(long, default_value = "mujoco-rk4")]
    engine: String,
    #[command(flatten)]
    stepping: SteppingArgs,
    /// Overwrite the output file.
    #[arg(long)]
    force: bool,
}

/// How a rig plant integrates each 2 ms control step (`gap simulate`: the simulated robot; `gap diagnose`: the
/// diagnosing simulator, e.g. to re-diagnose with the stepping the report's numerics section found the log to fit).
#[derive(Debug, clap::Args)]
struct SteppingArgs {
    /// Physics steps per 2 ms control step (2: 1 ms steps, as a 1 kHz simulator runs). Rig only.
    #[arg(long, default_value_t = 1)]
    substeps: u32,
    /// With `--substeps` above 1: evaluate the PD law once per control step and hold it, instead of at every
    /// physics step.
    #[arg(long)]
    pd_held: bool,
}

impl SteppingArgs {
    fn stepping(&self) -> Result<Stepping> {
        let pd = if self.pd_held { PdUpdate::PerControlStep } else { PdUpdate::PerPhysicsStep };
        Stepping::new(self.substeps, pd).context("--substeps")
    }
}

#[derive(Debug, clap::Args)]
struct BenchArgs {
    #[arg(long, default_value = "h1_2")]
    robot: String,
    #[arg(long, default_value_t = 12)]
    trials: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Length of each generated log (s).
    #[arg(long, default_value_t = 20.0)]
    duration: f64,
    /// Directory for the logs, seals, reports and the table (default: a temporary directory).
    #[arg(long)]
    out: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t = super::OutputFormat::Text)]
    format: super::OutputFormat,
    /// Policy spec TOML (e.g. robots/h1_2/policies/gepetto_demo_rsl.toml); repeatable. With policies, half the
    /// trials are driven by a policy rollout (legs; torso and arms follow the excitation plan), the others by the
    /// excitation plan.
    #[arg(long)]
    policy: Vec<PathBuf>,
    /// Floating-base benchmark: every trial is a walking log on the ground (MuJoCo RK4 with contact), driven by the
    /// policies in turn (at least one --policy); the diagnosis must choose the floating plant by itself.
    #[arg(long)]
    floating: bool,
    /// Engine of the reference ("real") plant on the rig: mujoco-rk4 (default), mujoco, mujoco-euler,
    /// mujoco-implicit, or an engine independent of the diagnosing MuJoCo: bullet, dart, rapier_multibody (their
    /// damping and Coulomb friction effects are then applied through the engine's own joint parameters).
    #[arg(long, default_value = "mujoco-rk4")]
    reference_engine: String,
    /// Drive the scripted trials (and the joints a policy does not drive) with a gentle chirp (slow sweeps at a
    /// third of the plan's amplitude, no steps: what a user records anyway) instead of the excitation plan.
    #[arg(long)]
    gentle_chirp: bool,
    /// Out-of-library trials after the regular ones: each hides an effect the diagnosis cannot fit (torque ripple
    /// periodic in the joint angle, friction proportional to the transmitted torque, in turn); scored as their own
    /// class (any named effect is a confident attribution).
    #[arg(long, default_value_t = 0)]
    out_of_library: usize,
    /// Run only this trial of the bench (an index into the --trials regular then --out-of-library trials);
    /// repeatable. Each trial draws from --seed and its index alone, so it gives the same log and report as in the
    /// full run: re-run one row of a recorded table without the others.
    #[arg(long = "only", value_name = "TRIAL")]
    only: Vec<usize>,
    /// Diagnose with only these effect kinds, comma-separated (as `gap diagnose --effects`) [default: the whole
    /// library]: a faster bench (smoke runs, tests) whose diagnoses cannot name the kinds left out, so its table
    /// scores those trials as missed.
    #[arg(long, value_delimiter = ',')]
    effects: Vec<String>,
    /// Diagnose each log on at most this many windows (as `gap diagnose --max-windows`, at least 4) [default:
    /// the diagnosis's]: a faster, less certain bench.
    #[arg(long)]
    max_windows: Option<usize>,
    /// Run only the trials dealt to shard K of N (the i-th trial of the run, counted from 0 over --only's trials
    /// or all of them, to shard i mod N + 1) and write `OUT/shard-K-of-N.cbor` beside their logs and reports
    /// instead of the table; `ulab merge` turns the N shards into this run's seals.json, scores.json and table.md
    /// (docs/campaigns.md). Each trial draws from --seed and its index alone, so its log and score are the
    /// unsharded run's.
    #[arg(long, value_name = "K/N", requires = "out")]
    shard: Option<campaign::Shard>,
    /// Write each trial's log and, for each effect it hides, the log the same plant writes without that effect
    /// (`trial_NNN.without_K.mcap`, K counted from 0 in the trial's order, with the removed effect in
    /// `trial_NNN.without_K.json`, with what the effect shows to a perfect replay in the diagnosis's windows:
    /// `gap_bench::oracle_differences`); no diagnosis, no table. For scoring which hidden effects a log can show at
    /// all (bench/gap-eval/visibility.py). Rig only.
    #[arg(long, requires = "out", conflicts_with_all = ["floating", "shard"])]
    counterfactuals: bool,
}

/// The shard files' kind of `ulab gap bench` campaigns.
pub(crate) const SHARD_KIND: &str = "gap-bench";

/// Everything that decides a `ulab gap bench` table: what the shards of one campaign share (`--out` and
/// `--format` do not).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct BenchCampaign {
    robot: String,
    model_hash: String,
    trials: usize,
    seed: u64,
    duration: f64,
    /// `--policy` paths as given.
    policies: Vec<PathBuf>,
    floating: bool,
    /// Canonical name ([`EngineChoice::name`]).
    reference_engine: String,
    gentle_chirp: bool,
    out_of_library: usize,
    only: Vec<usize>,
    /// `--effects`, as given.
    effects: Vec<String>,
    max_windows: Option<usize>,
}

impl BenchCampaign {
    /// The bench's trials in run order (the campaign's items): `--only`'s, or all of them.
    fn selected(&self) -> Vec<usize> {
        (0..self.trials + self.out_of_library).filter(|i| self.only.is_empty() || self.only.contains(i)).collect()
    }
}

/// One trial's result: what the table and the summary files are made of.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct BenchTrial {
    seal: bench::Seal,
    score: bench::TrialScore,
}

pub fn run(args: Args) -> Result<Exit> {
    match args.command {
        GapCommand::Diagnose(a) => diagnose(a),
        GapCommand::Excite(a) => excite(a),
        GapCommand::Simulate(a) => simulate(a),
        GapCommand::Bench(a) => bench_cmd(a),
    }
}

fn load(robot: &str) -> Result<RobotModel> {
    if robot_model::BUILTIN_ROBOTS.contains(&robot) {
        robot_model::builtin(robot).with_context(|| format!("loading built-in robot {robot}"))
    } else {
        RobotModel::load(Path::new(robot)).with_context(|| format!("loading robot model {robot}"))
    }
}

fn write_log(path: &Path, log: &RobotLog, model: &RobotModel, force: bool) -> Result<()> {
    if path.exists() && !force {
        bail!("{} exists (use --force to overwrite)", path.display());
    }
    let f = std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    log.write_mcap(std::io::BufWriter::new(f), model).with_context(|| format!("writing {}", path.display()))
}

fn read_log(path: &Path, model: &RobotModel) -> Result<RobotLog> {
    // A directory: the CSV pair `ulab log export` writes (rt_lowcmd.csv, rt_lowstate.csv).
    let log = if path.is_dir() {
        let read = |name: &str| {
            std::fs::read_to_string(path.join(name)).with_context(|| format!("reading {}", path.join(name).display()))
        };
        RobotLog::from_export_csv(&read("rt_lowcmd.csv")?, &read("rt_lowstate.csv")?, model)
    } else {
        let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        RobotLog::from_mcap(&bytes, model)
    };
    log.with_context(|| format!("reading the log {}", path.display()))
}

/// The effect kinds `--effects` names (None: all of them).
fn effect_kinds(names: &[String]) -> Result<Option<Vec<EffectKind>>> {
    if names.is_empty() {
        return Ok(None);
    }
    let mut kinds = Vec::new();
    for name in names {
        let kind = EffectKind::parse(name.trim()).with_context(|| {
            let all: Vec<&str> = EffectKind::ALL.iter().map(|k| k.name()).collect();
            format!("--effects: unknown effect kind `{name}` (one of: {})", all.join(", "))
        })?;
        if !kinds.contains(&kind) {
            kinds.push(kind);
        }
    }
    Ok(Some(kinds))
}

fn diagnose(a: DiagnoseArgs) -> Result<Exit> {
    let model = load(&a.robot)?;
    let engine = EngineChoice::parse(&a.engine).context("--engine")?;
    engine.mujoco_integrator().context("--engine")?;
    if !(a.window.is_finite() && a.window > 0.0 && a.block.is_finite() && a.block > 0.0) {
        bail!("--window and --block must be positive numbers of seconds");
    }
    let kinds = effect_kinds(&a.effects)?;
    let log = read_log(&a.log, &model)?;
    let plant = match a.plant {
        PlantArg::Auto => PlantChoice::Auto,
        PlantArg::Rig => PlantChoice::Rig,
        PlantArg::Floating => PlantChoice::Floating,
    };
    let opts = DiagnoseOptions {
        engine,
        window_s: a.window,
        max_windows: a.max_windows.map(|n| n.max(4)),
        block_s: a.block,
        seed: a.seed,
        plant,
        stepping: a.stepping.stepping()?,
        kinds,
        ..Default::default()
    };
    let report = gap_diagnosis::diagnose(&model, &log, &opts).context("diagnosing")?;
    gap_diagnosis::report::write_all(&report, &a.out).context("writing the report")?;
    if let Some(path) = &a.export_mjcf {
        let xml = gap_diagnosis::export::corrected_mjcf(&model, &report).context("writing the corrected model")?;
        std::fs::write(path, xml).with_context(|| format!("writing {}", path.display()))?;
        let nominal = path.with_extension("nominal.xml");
        let xml = gap_diagnosis::export::nominal_mjcf(&model, &report).context("writing the nominal model")?;
        std::fs::write(&nominal, xml).with_context(|| format!("writing {}", nominal.display()))?;
    }
    let violated = report.outcome == Outcome::RigAssumptionViolated;
    if violated {
        eprintln!("gap diagnose: ABSTAINED (exit {}): {}", Exit::Abstained.code(), report.rig_check.message);
    }
    if a.format == super::OutputFormat::Json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        if !violated {
            let why = if report.rig_check.suspended {
                "the log passes the rig-assumption check"
            } else {
                "the log is not from a suspended robot"
            };
            println!(
                "plant {} ({why}); {} training + {} held-out windows{}{}",
                report.plant.name(),
                report.windows_train,
                report.windows_held_out,
                if report.windows_unsettled > 0 {
                    format!(" ({} starts in touchdown transients dropped)", report.windows_unsettled)
                } else {
                    String::new()
                },
                if report.windows_down > 0 {
                    format!(" ({} windows with the robot down dropped)", report.windows_down)
                } else {
                    String::new()
                }
            );
        }
        println!(
            "baseline held-out gap metric {:.3} [{:.3}, {:.3}]",
            report.baseline_metric.value, report.baseline_metric.lo, report.baseline_metric.hi
        );
        if let Some(t) = &report.timing {
            println!("timing: {}", t.finding);
        }
        if let Some(n) = &report.numerics {
            println!("numerics: {}", n.finding);
        }
        if report.unexplained {
            let why = report.steps.last().map(|s| s.reason.as_str()).unwrap_or("");
            println!("no effect is named: the gap is unexplained (abstention): {why}");
        }
        for e in report.effects.iter().filter(|e| e.named) {
            let top = e.params.iter().max_by(|x, y| x.held_out_reduction.total_cmp(&y.held_out_reduction));
            println!(
                "{:18} reduction {:5.1} % [{:.1}, {:.1}]  {}",
                e.kind.name(),
                100.0 * e.reduction.value,
                100.0 * e.reduction.lo,
                100.0 * e.reduction.hi,
                top.map(|p| format!("{} = {:.4} ± {:.4}", p.unit, p.value, p.sd)).unwrap_or_default()
            );
        }
        for set in &report.ambiguous {
            let n: Vec<String> =
                set.effects.iter().zip(&set.units).map(|(k, u)| format!("{} on {u}", k.name())).collect();
            println!("cannot tell apart on this log: {}", n.join(", "));
        }
        println!("report: {}", a.out.join("report.md").display());
    }
    Ok(if violated { Exit::Abstained } else { Exit::Success })
}

fn excite(a: ExciteArgs) -> Result<Exit> {
    let model = load(&a.robot)?;
    if !(a.duration.is_finite() && a.duration > 0.0 && a.duration <= 3600.0) {
        bail!("--duration must be in (0, 3600] s");
    }
    if !(a.rate.is_finite() && a.rate >= 1.0 && a.rate <= 2000.0) {
        bail!("--rate must be in [1, 2000] Hz");
    }
    let plan = gap_diagnosis::excite::plan(&model, a.duration, a.rate);
    let log = RobotLog { commands: plan, states: Vec::new() };
    write_log(&a.out, &log, &model, a.force)?;
    eprintln!(
        "{}: {} commands over {:.1} s (suspended robot: chirps 0.3-3 Hz and steps per group {:?}, then all together)",
        a.out.display(),
        log.commands.len(),
        a.duration,
        GROUPS
    );
    Ok(Exit::Success)
}

/// Parses KIND:UNIT:VALUE into the effect set.
fn parse_effect(text: &str, model: &RobotModel, fx: &mut gap_diagnosis::plant::Effects) -> Result<()> {
    let parts: Vec<&str> = text.split(':').collect();
    let [kind, unit, value] = parts[..] else { bail!("--effect {text:?}: expected KIND:UNIT:VALUE") };
    let kind = EffectKind::parse(kind).with_context(|| {
        format!("--effect {text:?}: unknown kind (one of {})", EffectKind::ALL.map(|k| k.name()).join(", "))
    })?;
    let value: f64 =
        value.parse().ok().filter(|v: &f64| v.is_finite()).with_context(|| format!("--effect {text:?}: bad value"))?;
    let (lo, hi, _) = kind.range();
    let internal = if kind == EffectKind::Latency { value / 2.0 } else { value };
    if !kind.identifiable_suspended() {
        bail!("--effect {text:?}: {} needs ground contact, which the suspended rig does not have", kind.name());
    }
    if kind != EffectKind::ImuBias && kind != EffectKind::ImuMisalignment && !(lo..=hi).contains(&internal) {
        bail!("--effect {text:?}: value outside the supported range [{lo}, {hi}]");
    }
    let groups = joint_groups(model);
    match kind.scope() {
        Scope::Global => kind.set(fx, 0, internal),
        Scope::Imu => {
            let axis = ["imu_x", "imu_y", "imu_z"]
                .iter()
                .position(|a| *a == unit)
                .with_context(|| format!("--effect {text:?}: unit must be imu_x|imu_y|imu_z"))?;
            kind.set(fx, axis, internal);
        }
        Scope::Joint | Scope::Group => {
            if let Some(g) = GROUPS.iter().position(|g| *g == unit) {
                (0..model.nj()).filter(|&j| groups[j] == g).for_each(|j| kind.set(fx, j, internal));
            } else if let Some(j) = model.joints.iter().position(|j| j.motor_name == unit) {
                kind.set(fx, j, internal);
            } else {
                bail!("--effect {text:?}: unknown unit {unit:?} (a group {GROUPS:?} or a motor name)");
            }
        }
    }
    Ok(())
}

fn simulate(a: SimulateArgs) -> Result<Exit> {
    let model = load(&a.robot)?;
    if !(a.duration.is_finite() && a.duration >= 1.0 && a.duration <= 600.0) {
        bail!("--duration must be in [1, 600] s");
    }
    let mut cfg = RealConfig::new(&model, a.duration, a.seed);
    cfg.engine = EngineChoice::parse(&a.engine).context("--engine")?;
    cfg.stepping = a.stepping.stepping()?;
    for e in &a.effect {
        parse_effect(e, &model, &mut cfg.effects)?;
    }
    let log = bench::generate_log(&model, &cfg).context("running the reference plant")?;
    write_log(&a.out, &log, &model, a.force)?;
    eprintln!(
        "{}: {:.1} s, {} commands, {} states",
        a.out.display(),
        log.duration(),
        log.commands.len(),
        log.states.len()
    );
    Ok(Exit::Success)
}

/// `gap bench --counterfactuals`: each selected trial's log, and the log without each of its hidden effects.
fn write_counterfactuals(model: &RobotModel, trials: &[usize], opts: &BenchOptions, dir: &Path) -> Result<Exit> {
    for &i in trials {
        let input = if i >= opts.trials { None } else { bench::trial_policy(i, opts) };
        let (cfg, labels) = bench::trial_config(model, i, opts);
        let log = bench::generate_log_with(model, &cfg, input.as_ref()).with_context(|| format!("trial {i}"))?;
        let path = dir.join(format!("trial_{i:03}.mcap"));
        write_log(&path, &log, model, true)?;
        // The oracle replays start from the states as the diagnosis reads them back.
        let trial_log = read_log(&path, model)?;
        for (k, removed) in labels.injected.iter().enumerate() {
            let Some(cfg) = bench::trial_config_without(model, i, opts, k) else { continue };
            let log = bench::generate_log_with(model, &cfg, input.as_ref())
                .with_context(|| format!("trial {i} without its effect {k}"))?;
            write_log(&dir.join(format!("trial_{i:03}.without_{k}.mcap")), &log, model, true)?;
            let differences =
                bench::oracle_differences(model, i, opts, &trial_log, k).with_context(|| format!("trial {i}"))?;
            let removed = serde_json::json!({
                "kind": removed.kind.name(),
                "unit": removed.unit,
                "value": removed.value,
                "window_s": bench::ORACLE_WINDOW_S,
                "oracle_differences": differences,
            });
            let p = dir.join(format!("trial_{i:03}.without_{k}.json"));
            std::fs::write(&p, serde_json::to_string(&removed)?).with_context(|| format!("writing {}", p.display()))?;
        }
        eprintln!("trial {i}: its log and {} without one hidden effect", labels.injected.len());
    }
    Ok(Exit::Success)
}

fn bench_cmd(a: BenchArgs) -> Result<Exit> {
    let model = load(&a.robot)?;
    if a.trials + a.out_of_library == 0 {
        bail!("--trials (or --out-of-library) must be at least 1");
    }
    if !(a.duration.is_finite() && a.duration >= 4.0 && a.duration <= 600.0) {
        bail!("--duration must be in [4, 600] s");
    }
    let dir = match &a.out {
        Some(d) => d.clone(),
        None => std::env::temp_dir().join(format!("ulab-gap-bench-{}", std::process::id())),
    };
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let policies = a
        .policy
        .iter()
        .map(|p| {
            let spec =
                policy_runtime::PolicySpec::load(p).with_context(|| format!("loading policy spec {}", p.display()))?;
            spec.check_robot(&model)
                .with_context(|| format!("policy spec {} does not fit {}", p.display(), a.robot))?;
            // Fail now rather than mid-benchmark when the model file is missing or unsupported.
            policy_runtime::PolicyController::from_spec(spec.clone())
                .with_context(|| format!("loading the policy of {}", p.display()))?;
            Ok(spec)
        })
        .collect::<Result<Vec<_>>>()?;
    if a.floating && policies.is_empty() {
        bail!("--floating needs at least one --policy (the walking controller)");
    }
    let reference = EngineChoice::parse(&a.reference_engine).context("--reference-engine")?;
    if a.floating && !reference.is_mujoco() {
        bail!("--floating: the walking reference plant is MuJoCo only (its contact effects are MuJoCo's); --reference-engine works on the rig");
    }
    if a.floating && a.gentle_chirp {
        bail!("--gentle-chirp: the floating-base benchmark is driven by policies only");
    }
    let motion = if a.gentle_chirp { Motion::GentleChirp } else { Motion::Plan };
    if a.floating && a.out_of_library > 0 {
        bail!("--out-of-library: the out-of-library trials run on the rig");
    }
    let mut opts = BenchOptions {
        policies,
        reference,
        motion,
        out_of_library: a.out_of_library,
        ..BenchOptions::new(a.trials, a.seed, a.duration)
    };
    opts.diagnose.kinds = effect_kinds(&a.effects)?;
    opts.diagnose.max_windows = a.max_windows.map(|n| n.max(4));
    if let Some(&k) = a.only.iter().find(|&&k| k >= a.trials + a.out_of_library) {
        bail!(
            "--only {k}: the bench has {} trials (0 to {})",
            a.trials + a.out_of_library,
            a.trials + a.out_of_library - 1
        );
    }
    let campaign = BenchCampaign {
        robot: a.robot.clone(),
        model_hash: engine_diff::model_hash(&model),
        trials: a.trials,
        seed: a.seed,
        duration: a.duration,
        policies: a.policy.clone(),
        floating: a.floating,
        reference_engine: opts.reference.name(),
        gentle_chirp: a.gentle_chirp,
        out_of_library: a.out_of_library,
        only: a.only.clone(),
        effects: a.effects.clone(),
        max_windows: a.max_windows.map(|n| n.max(4)),
    };
    let selected = campaign.selected();
    if a.counterfactuals {
        return write_counterfactuals(&model, &selected, &opts, &dir);
    }
    let mine: Vec<usize> = match a.shard {
        Some(shard) => shard.items(selected.len()).collect(),
        None => (0..selected.len()).collect(),
    };
    let mut results = Vec::new();
    let started = std::time::Instant::now();
    for item in mine {
        let i = selected[item];
        // Each generated log goes to disk as MCAP and is read back: the diagnosis sees exactly what a recording gives.
        let mut via_mcap = |i: usize, log: &RobotLog| -> Result<RobotLog, gap_diagnosis::GapError> {
            let p = dir.join(format!("trial_{i:03}.mcap"));
            let write_err = |source| gap_diagnosis::GapError::File { path: p.clone(), source };
            let f = std::fs::File::create(&p).map_err(write_err)?;
            log.write_mcap(std::io::BufWriter::new(f), &model)?;
            let bytes = std::fs::read(&p).map_err(write_err)?;
            RobotLog::from_mcap(&bytes, &model)
        };
        let (seal, score, report) = if a.floating {
            // The seal is written before the diagnosis runs.
            let mut via_mcap_sealed =
                |i: usize, log: &RobotLog, seal: &bench::Seal| -> Result<RobotLog, gap_diagnosis::GapError> {
                    let p = dir.join(format!("trial_{i:03}.seal.json"));
                    let json = serde_json::to_string_pretty(seal)?;
                    std::fs::write(&p, json).map_err(|source| gap_diagnosis::GapError::File { path: p, source })?;
                    via_mcap(i, log)
                };
            bench::run_floating_trial(&model, i, &opts, &mut via_mcap_sealed).with_context(|| format!("trial {i}"))?
        } else {
            bench::run_trial(&model, i, &opts, &mut via_mcap).with_context(|| format!("trial {i}"))?
        };
        gap_diagnosis::report::write_all(&report, &dir.join(format!("trial_{i:03}")))
            .context("writing a trial report")?;
        eprintln!(
            "trial {i} ({}): injected [{}] -> ranked [{}] ({:.1} s{})",
            score.policy.as_deref().unwrap_or(match opts.motion {
                Motion::Plan => "excitation plan",
                Motion::GentleChirp => "gentle chirp",
            }),
            score
                .injected
                .iter()
                .map(|x| format!("{}@{}={:.3}", x.kind.name(), x.unit, x.value))
                .chain(
                    score
                        .out_of_library
                        .iter()
                        .map(|o| format!("{} (outside the library)@{}={:.3}", o.kind, o.unit, o.value))
                )
                .collect::<Vec<_>>()
                .join(", "),
            score.ranked.iter().map(|k| k.name()).collect::<Vec<_>>().join(", "),
            score.diagnose_s,
            match (score.plant, score.redraws) {
                (Some(p), Some(r)) => format!("; plant {p:?}, {r} redraws").to_lowercase(),
                _ => String::new(),
            }
        );
        results.push((item, BenchTrial { seal, score }));
    }
    if let Some(shard) = a.shard {
        return super::merge::write_shard(&dir, SHARD_KIND, shard, selected.len(), campaign, results);
    }
    let trials: Vec<BenchTrial> = results.into_iter().map(|(_, t)| t).collect();
    write_bench(&dir, &campaign, trials, a.format, &format!("{:.0} s total", started.elapsed().as_secs_f64()))?;
    Ok(Exit::Success)
}

/// Writes the bench's summary files (seals.json, scores.json, table.md) into `dir` and prints the table (or, with
/// `--format json`, the summary and every trial's score); `how` ends the table's title line.
fn write_bench(
    dir: &Path,
    c: &BenchCampaign,
    trials: Vec<BenchTrial>,
    format: super::OutputFormat,
    how: &str,
) -> Result<()> {
    let (seals, scores): (Vec<bench::Seal>, Vec<bench::TrialScore>) =
        trials.into_iter().map(|t| (t.seal, t.score)).unzip();
    let reference = EngineChoice::parse(&c.reference_engine).context("the reference engine")?;
    let summary = bench::summarize(&scores);
    let mut table = bench::table_by_input(&scores);
    if c.floating {
        let floating = scores.iter().filter(|s| s.plant == Some(gap_diagnosis::diagnose::PlantKind::Floating)).count();
        let redraws: usize = scores.iter().filter_map(|s| s.redraws).sum();
        let redrawn = scores.iter().filter(|s| s.redraws.unwrap_or(0) > 0).count();
        table += &format!(
            "\nplant chosen by the diagnosis (auto): floating in {floating} of {} trials; effect magnitudes redrawn after a fall: {redraws} times in {redrawn} trials\n",
            scores.len()
        );
    }
    std::fs::write(dir.join("seals.json"), serde_json::to_string_pretty(&seals)?)?;
    std::fs::write(dir.join("scores.json"), serde_json::to_string_pretty(&scores)?)?;
    std::fs::write(dir.join("table.md"), &table)?;
    if format == super::OutputFormat::Json {
        println!("{}", serde_json::to_string_pretty(&serde_json::json!({"summary": summary, "trials": scores}))?);
    } else {
        let (flag, what) = if c.floating {
            (
                " --floating",
                "walking logs, reference plant MuJoCo RK4 with ground contact + noise + 50 Hz commands with 0-2 ms jitter; diagnosing engine MuJoCo implicitfast, plant auto",
            )
        } else {
            (
                "",
                if reference.is_mujoco() {
                    "logs, reference plant MuJoCo + noise + 50 Hz jitter; diagnosing engine MuJoCo implicitfast"
                } else {
                    "logs, reference plant in another engine (damping and Coulomb friction through its own joint parameters) + noise + 50 Hz jitter; diagnosing engine MuJoCo implicitfast"
                },
            )
        };
        let reference = if c.floating { String::new() } else { format!(" --reference-engine {}", c.reference_engine) };
        println!(
            "ulab gap bench{flag}{reference} --trials {} --seed {} --duration {}{}{}{}{} ({} s {what}; {how})\n",
            c.trials,
            c.seed,
            c.duration,
            c.policies.iter().map(|p| format!(" --policy {}", p.display())).collect::<String>(),
            if c.gentle_chirp { " --gentle-chirp" } else { "" },
            if c.out_of_library > 0 { format!(" --out-of-library {}", c.out_of_library) } else { String::new() },
            c.only.iter().map(|k| format!(" --only {k}")).collect::<String>()
                + &if c.effects.is_empty() { String::new() } else { format!(" --effects {}", c.effects.join(",")) }
                + &c.max_windows.map(|n| format!(" --max-windows {n}")).unwrap_or_default(),
            c.duration,
        );
        print!("{table}");
        println!("\nfiles: {}", dir.display());
    }
    Ok(())
}

/// `ulab merge` of `ulab gap bench --shard` files: the unsharded run's seals.json, scores.json and table.md from
/// the shards' trials in run order, with each trial's files (log, seal, report) copied from beside the shard file
/// that holds the trial.
pub(crate) fn merge(files: &[PathBuf], out: &Path) -> Result<Exit> {
    let (c, trials): (BenchCampaign, Vec<BenchTrial>) = super::merge::read_shards(files, SHARD_KIND)?;
    let model = load(&c.robot)?;
    if engine_diff::model_hash(&model) != c.model_hash {
        bail!("robot {}: not the model the shards ran (its hash differs)", c.robot);
    }
    let selected = c.selected();
    if trials.len() != selected.len() {
        bail!("the shards hold {} trials, their campaign {}", trials.len(), selected.len());
    }
    for (t, &i) in trials.iter().zip(&selected) {
        if t.seal.trial != i || t.score.trial != i {
            bail!("the shards hold trial {} where their campaign runs trial {i}", t.score.trial);
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    // The directory of each shard holds its trials' files; `read_shards` checked that every shard is there once.
    let mut beside = Vec::new();
    for f in files {
        let h = campaign::read_header(f)?;
        let dir = f.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        beside.push((h.shard, dir.to_owned()));
    }
    let count = beside.first().map_or(1, |(s, _)| s.count());
    let same_dir = |d: &Path| match (d.canonicalize(), out.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    };
    let mut absent = Vec::new();
    for (item, &i) in selected.iter().enumerate() {
        let (_, src) = beside.iter().find(|(s, _)| s.owns(item)).context("a shard's directory")?;
        if same_dir(src) {
            continue;
        }
        let names = [format!("trial_{i:03}.mcap"), format!("trial_{i:03}.seal.json"), format!("trial_{i:03}")];
        if !names.iter().any(|n| src.join(n).exists()) {
            absent.push(i);
            continue;
        }
        for n in &names {
            copy_tree(&src.join(n), &out.join(n))?;
        }
    }
    if !absent.is_empty() {
        eprintln!(
            "gap bench merge: the logs and reports of trial(s) {absent:?} are not beside their shard files; {} holds the bench's tables without them",
            out.display()
        );
    }
    write_bench(out, &c, trials, super::OutputFormat::Text, &format!("merged from {count} shards"))?;
    Ok(Exit::Success)
}

/// Copies a file, or a directory with everything in it, from `src` to `dst`; nothing when `src` does not exist.
fn copy_tree(src: &Path, dst: &Path) -> Result<()> {
    if src.is_dir() {
        std::fs::create_dir_all(dst).with_context(|| format!("creating {}", dst.display()))?;
        for e in std::fs::read_dir(src).with_context(|| format!("reading {}", src.display()))? {
            let e = e.with_context(|| format!("reading {}", src.display()))?;
            copy_tree(&e.path(), &dst.join(e.file_name()))?;
        }
    } else if src.exists() {
        std::fs::copy(src, dst).with_context(|| format!("copying {} to {}", src.display(), dst.display()))?;
    }
    Ok(())
}
