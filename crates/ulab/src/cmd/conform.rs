//! `ulab conform`: how a peer that plays the robot side (publishes `rt/lowstate`, consumes
//! `rt/lowcmd`) behaves on good and bad traffic; `ulab conform controller` judges the other side, a controller,
//! with ulab playing the robot (`conform_controller`). The checks, the fuzzer and the reports live in
//! the `conformance` crate; this module parses arguments, applies the safety rules, shows
//! progress and writes files. Exit codes: 0 every check passed (or was inconclusive), 1 a check
//! failed / a failure was found or reproduced, 2 usage or connection error.

use super::recording::NetArgs;
use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use conformance::fuzz::{self, FuzzOptions, Reproducer};
use conformance::interop::InteropOptions;
use conformance::report::{CheckId, CheckResult, Report, Settings, Status, TargetInfo, REPORT_SCHEMA_VERSION};
use conformance::{checks, safety, target::Target};
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Args {
    #[command(subcommand)]
    pub command: Option<Sub>,
    #[command(flatten)]
    pub run: RunArgs,
}

#[derive(Debug, clap::Subcommand)]
pub enum Sub {
    /// Re-run a reproducer saved by `--fuzz` and report whether the failure reproduces.
    Replay(ReplayArgs),
    /// Judge a CONTROLLER instead: ulab plays the robot (simulated, loopback and a non-zero domain by default) and
    /// checks the LowCmd stream of the controller that connects (CRC, mode_machine, motor modes, limits, finite
    /// values, rate and jitter, the start, what it does when LowState stops).
    Controller(super::conform_controller::Args),
}

#[derive(Debug, clap::Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub net: NetArgs,
    /// Robot the target plays (built in): h1_2.
    #[arg(long, default_value = "h1_2")]
    pub robot: String,
    /// Directory for report.md and report.json (and reproducers in fuzz mode).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// What to print on stdout: the Markdown report (text) or report.json (json).
    #[arg(long, value_enum, default_value_t = super::OutputFormat::Text)]
    pub format: super::OutputFormat,
    /// Nominal LowState rate of the target (Hz), what `state_rate` is judged against; the real robot publishes about
    /// 500 Hz. Every other check uses the rate measured at the start.
    #[arg(long, default_value_t = 500.0)]
    pub state_rate: f64,
    /// Only these checks, comma-separated ids or groups (state_stream, discovery, interop, command_handling,
    /// robustness); phases nothing asks for are skipped. Default: all.
    #[arg(long)]
    pub checks: Option<String>,
    /// Python with cyclonedds and unitree_sdk2py for the Cyclone 11 interop probe (default: ULAB_PYTHON, else
    /// python3).
    #[arg(long)]
    pub python: Option<PathBuf>,
    /// Seconds to wait for the target's first LowState.
    #[arg(long, default_value_t = 10.0)]
    pub connect_timeout: f64,
    /// Fuzz mode: mutate LowCmd sequences with state feedback instead of the fixed checks.
    #[arg(long)]
    pub fuzz: bool,
    /// Fuzz mode: wall-time budget in seconds, minimisation included.
    #[arg(long, default_value_t = 60.0)]
    pub budget: f64,
    /// Fuzz mode: random seed (default: from the clock; saved in every reproducer).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Fuzz mode on a non-loopback interface or domain 0 (with --allow-robot): sends deliberately
    /// harmful commands to what may be a real robot.
    #[arg(long)]
    pub allow_robot_fuzz: bool,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Debug, clap::Args)]
pub struct ReplayArgs {
    /// Reproducer file (JSON) written by `ulab conform --fuzz`.
    pub file: PathBuf,
    #[command(flatten)]
    pub net: NetArgs,
    /// Re-runs before concluding that the failure does not reproduce.
    #[arg(long, default_value_t = 3)]
    pub attempts: u32,
    /// Seconds to wait for the target's first LowState.
    #[arg(long, default_value_t = 10.0)]
    pub connect_timeout: f64,
    /// Needed (with --allow-robot) to replay on a non-loopback interface or domain 0.
    #[arg(long)]
    pub allow_robot_fuzz: bool,
    /// Print the outcome as JSON.
    #[arg(long, value_enum, default_value_t = super::OutputFormat::Text)]
    pub format: super::OutputFormat,
}

pub fn run(args: Args) -> Result<Exit> {
    match args.command {
        Some(Sub::Replay(r)) => replay(r),
        Some(Sub::Controller(c)) => super::conform_controller::run(c),
        None => run_target(args.run),
    }
}

fn connect(net: &NetArgs, timeout: f64, fuzzing: bool, allow_robot_fuzz: bool) -> Result<Target> {
    let cfg = net.domain_config()?;
    if fuzzing {
        safety::check_fuzz(&cfg, allow_robot_fuzz).context("fuzzing refused")?;
    }
    anyhow::ensure!(timeout.is_finite() && timeout > 0.0, "--connect-timeout must be positive");
    Target::connect(cfg, Duration::from_secs_f64(timeout)).context("connecting to the target")
}

fn versions() -> BTreeMap<String, String> {
    BTreeMap::from([
        ("ulab".to_owned(), env!("CARGO_PKG_VERSION").to_owned()),
        ("report_schema".to_owned(), REPORT_SCHEMA_VERSION.to_string()),
        ("reproducer_schema".to_owned(), fuzz::REPRODUCER_SCHEMA_VERSION.to_string()),
        ("transport".to_owned(), "Cyclone DDS 11 (cyclors), raw CDR".to_owned()),
    ])
}

/// A spinner with a message on a terminal, or plain lines (or nothing with --quiet).
struct Progress {
    bar: Option<indicatif::ProgressBar>,
    quiet: bool,
}

impl Progress {
    fn new(quiet: bool, len: Option<u64>) -> Progress {
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let b = match len {
                Some(n) => indicatif::ProgressBar::new(n),
                None => indicatif::ProgressBar::new_spinner(),
            };
            if len.is_some() {
                if let Ok(style) =
                    indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} s {msg}")
                {
                    b.set_style(style);
                }
            }
            b.enable_steady_tick(Duration::from_millis(200));
            b
        });
        Progress { bar, quiet }
    }
    fn say(&self, msg: &str) {
        match &self.bar {
            Some(b) => b.set_message(msg.to_owned()),
            None if !self.quiet => eprintln!("conform: {msg}"),
            None => {}
        }
    }
    fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

fn run_target(args: RunArgs) -> Result<Exit> {
    if args.robot != "h1_2" {
        bail!("unsupported robot `{}` (supported: h1_2)", args.robot);
    }
    anyhow::ensure!(args.state_rate.is_finite() && args.state_rate > 0.0, "--state-rate must be positive");
    if args.fuzz {
        anyhow::ensure!(
            args.budget.is_finite() && args.budget > 0.0 && args.budget <= 86_400.0,
            "--budget must be in (0, 86400] s"
        );
    }
    let selection = match &args.checks {
        Some(text) => checks::Selection::parse(text)?,
        None => checks::Selection::all(),
    };
    let cfg = args.net.domain_config()?;
    // A target that may be a real robot: the run prints what it will send first.
    if cfg.may_reach_robot() {
        if args.fuzz {
            safety::check_fuzz(&cfg, args.allow_robot_fuzz).context("fuzzing refused")?;
        }
        eprintln!(
            "conform: target may be a real robot (domain {}, {}). Will send on rt/lowcmd: {}",
            cfg.domain_id(),
            cfg.interface_name(),
            if args.fuzz {
                "a hold command at the measured pose, alternating with mutated LowCmd sequences (non-finite and out-of-limit values, gains up to 1e9, unknown modes, bad CRCs, truncated/oversize/mis-headed samples) for the whole budget"
            } else {
                "a hold command at the measured pose (legs kp 500-600), 0.3 rad steps of up to four free arm joints, bad-CRC / mode-0 / negative- and huge-gain / NaN variants alternating with the hold, malformed samples, a 5 kHz flood, then silence; no Cyclone 11 probe"
            }
        );
    }
    let started = Instant::now();
    let progress = Progress::new(args.quiet, args.fuzz.then(|| args.budget.ceil() as u64));
    progress.say("connecting");
    let mut target = connect(&args.net, args.connect_timeout, args.fuzz, args.allow_robot_fuzz)?;
    let participant = target.remote_endpoints().ok().and_then(|eps| {
        eps.into_iter()
            .find(|e| e.topic_name == "rt/lowstate")
            .map(|e| e.participant_guid.iter().map(|b| format!("{b:02x}")).collect::<String>())
    });

    let seed = args.seed.unwrap_or_else(|| {
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(1, |d| d.as_secs())
    });
    let mut report = Report {
        schema_version: REPORT_SCHEMA_VERSION,
        target: TargetInfo {
            robot: args.robot.clone(),
            domain: cfg.domain_id(),
            interface: cfg.interface_name().to_owned(),
            participant,
            measured_state_rate_hz: None,
            rtps_vendor: None,
            rtps_protocol_version: None,
        },
        settings: Settings {
            mode: if args.fuzz { "fuzz".into() } else { "checks".into() },
            expected_state_rate_hz: args.state_rate,
            budget_s: args.fuzz.then_some(args.budget),
            seed: args.fuzz.then_some(seed),
            checks: if args.fuzz { Vec::new() } else { selection.ids() },
        },
        versions: versions(),
        duration_s: 0.0,
        results: Vec::new(),
        reproducers: Vec::new(),
    };
    let mut files: Vec<(PathBuf, String)> = Vec::new();
    if args.fuzz {
        let opts = FuzzOptions { budget_s: args.budget, seed };
        let outcome = fuzz::run(&mut target, &opts, &mut |p| {
            if let Some(b) = &progress.bar {
                b.set_position(p.elapsed_s.min(p.budget_s) as u64);
                b.set_message(format!(
                    "{} executions, best disturbance {:.2}, {}",
                    p.executions, p.best_score, p.phase
                ));
            }
        })?;
        progress.finish();
        let out_dir = args.out.clone().unwrap_or_else(|| PathBuf::from("conform-fuzz"));
        for (k, rep) in outcome.failures.iter().enumerate() {
            let name = format!("reproducer-{seed}-{k}.json");
            report.reproducers.push(format!("reproducers/{name}"));
            files.push((out_dir.join("reproducers").join(&name), rep.to_json()));
            report.results.push(
                CheckResult::new(
                    CheckId::FuzzFailure(u32::try_from(k).unwrap_or(u32::MAX)),
                    Status::Fail,
                    format!(
                        "{} ({} step(s){})",
                        rep.predicate_text,
                        rep.steps.len(),
                        if rep.minimized { ", minimised" } else { ", budget ran out before minimisation finished" }
                    ),
                )
                .with(
                    "steps",
                    rep.steps.iter().map(|s| format!("x{} {}", s.repeat, s.notes.join(", "))).collect::<Vec<_>>(),
                )
                .with("observed", &rep.observed)
                .with("reproducer", out_dir.join("reproducers").join(&name).display().to_string()),
            );
        }
        if outcome.failures.is_empty() {
            report.results.push(
                CheckResult::new(
                    CheckId::Fuzz,
                    Status::Pass,
                    format!("no failure in {} sequence executions over {:.0} s", outcome.executions, outcome.elapsed_s),
                )
                .with("executions", outcome.executions)
                .with("best_score", f64::from(outcome.best_score))
                .with("most_disturbing_sequence", outcome.best_notes),
            );
        }
        report.settings.mode = "fuzz".into();
        if args.out.is_none() {
            // Reproducers are always saved; reports only where asked.
            for (path, text) in &files {
                write_file(path, text)?;
            }
            files.clear();
            if !report.reproducers.is_empty() {
                eprintln!("conform: reproducers written under {}", out_dir.display());
            }
        }
    } else {
        let opts = checks::Options {
            expected_state_rate_hz: args.state_rate,
            selection,
            interop: InteropOptions { python: args.python.clone(), ..InteropOptions::default() },
            ..checks::Options::default()
        };
        let outcome = checks::run_all(&mut target, &opts, &mut |m| progress.say(m))?;
        report.results = outcome.results;
        report.target.measured_state_rate_hz = outcome.facts.map(|f| (f.rate_hz * 10.0).round() / 10.0);
        report.target.rtps_vendor = outcome.wire.map(|w| w.vendor_text());
        report.target.rtps_protocol_version = outcome.wire.map(|w| w.protocol_text());
        progress.finish();
    }
    report.duration_s = (started.elapsed().as_secs_f64() * 10.0).round() / 10.0;
    if let Some(dir) = &args.out {
        files.push((dir.join("report.json"), report.to_json()));
        files.push((dir.join("report.md"), report.to_markdown()));
        for (path, text) in &files {
            write_file(path, text)?;
        }
    }
    if args.format == super::OutputFormat::Json {
        println!("{}", report.to_json());
    } else {
        print!("{}", report.to_markdown());
    }
    Ok(Exit::failed_if(report.any_fail()))
}

pub(crate) fn write_file(path: &Path, text: &str) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

fn replay(args: ReplayArgs) -> Result<Exit> {
    // A reproducer is fuzz traffic: the fuzz safety rule applies before anything else.
    let cfg = args.net.domain_config()?;
    safety::check_fuzz(&cfg, args.allow_robot_fuzz).context("replay refused")?;
    let text = std::fs::read_to_string(&args.file).with_context(|| format!("reading {}", args.file.display()))?;
    let rep = Reproducer::from_json(&text).with_context(|| format!("{}", args.file.display()))?;
    anyhow::ensure!((1..=100).contains(&args.attempts), "--attempts must be in 1..=100");
    let mut target = connect(&args.net, args.connect_timeout, true, args.allow_robot_fuzz)?;
    let outcome = fuzz::replay(&mut target, &rep, args.attempts)?;
    if args.format == super::OutputFormat::Json {
        println!("{}", serde_json::to_string_pretty(&outcome).context("serialising the outcome")?);
    } else {
        println!(
            "{}: {} (expected: {}; observed now: {}; max deviation {:.3} rad at {}, speed {:.0} % of limit, max LowState gap {:.1} ms)",
            args.file.display(),
            if outcome.reproduced { "REPRODUCED" } else { "not reproduced" },
            rep.predicate_text,
            outcome.observed_failure.map_or("no failure", |f| f.describe()),
            outcome.observation.max_deviation_rad,
            outcome.observation.worst_joint,
            outcome.observation.max_speed_ratio * 100.0,
            outcome.observation.max_gap_s * 1e3
        );
    }
    Ok(Exit::failed_if(outcome.reproduced))
}
