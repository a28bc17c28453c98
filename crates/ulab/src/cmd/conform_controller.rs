//! `ulab conform controller`: the other direction of `ulab conform`. ulab plays the robot (the simulated H1-2 of
//! `ulab sim`: publishes `rt/lowstate`, applies `rt/lowcmd` through the same gates) and judges the controller that
//! connects. The run has four phases, counted from the controller's first command: observe (LowState at the
//! nominal rate), silence (LowState withheld, physics running), resume (LowState again) and fall (the robot tipped
//! onto its back, LowState published); the robot is stood up again at the start of the resume. Every command is
//! recorded with its phase, the controller's send timestamp and the pose the robot had just reported; the verdicts
//! come from `conformance::controller::judge`, whose table holds every threshold.

use super::conform::write_file;
use super::recording::NetArgs;
use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use conformance::controller::{self, Phase, Received, Trace};
use conformance::report::{CheckId, Report, Settings, TargetInfo, REPORT_SCHEMA_VERSION};
use dds_transport::{Participant, TopicSpec};
use diff_physics::{make_engine, CommonSettings, EngineKind, State};
use lowlevel_codec::cdr;
use sim_bridge::{BridgeConfig, SimRobot};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use unitree_idl::{h1_2, hg};

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub net: NetArgs,
    /// Robot ulab plays (built in): h1_2.
    #[arg(long, default_value = "h1_2")]
    pub robot: String,
    #[arg(long, default_value = "mujoco", value_parser = parse_engine,
          help = super::engines_help("Physics engine of the simulated robot, one of"))]
    pub engine: EngineKind,
    /// Directory for report.md and report.json.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// What to print on stdout: the Markdown report (text) or report.json (json).
    #[arg(long, value_enum, default_value_t = super::OutputFormat::Text)]
    pub format: super::OutputFormat,
    /// LowState publish rate (Hz); the real robot publishes about 500 Hz.
    #[arg(long, default_value_t = 500.0)]
    pub state_rate: f64,
    /// `mode_machine` reported in LowState, which the controller must echo.
    #[arg(long, default_value_t = h1_2::MODE_MACHINE)]
    pub mode_machine: u8,
    /// Seconds to wait for the controller's first LowCmd.
    #[arg(long, default_value_t = 30.0)]
    pub connect_timeout: f64,
    /// Seconds of normal operation observed from the first command (rate, jitter and the start are judged here).
    #[arg(long, default_value_t = 4.0)]
    pub observe: f64,
    /// Seconds LowState is withheld to see what the controller does without it.
    #[arg(long, default_value_t = 2.0)]
    pub silence: f64,
    /// Seconds of LowState again after the silence (recorded; its last half second shows whether the controller
    /// was commanding when the robot fell).
    #[arg(long, default_value_t = 1.0)]
    pub resume: f64,
    /// Seconds the robot lies on its back after the resume (the judge tips it over) to see what the controller does
    /// when the robot falls; 0 skips the fall (`ctl_fall` is then inconclusive).
    #[arg(long, default_value_t = 2.0)]
    pub fall: f64,
    /// Seconds without a valid command before the simulated robot damps.
    #[arg(long, default_value_t = 0.1)]
    pub command_timeout: f64,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

fn parse_engine(s: &str) -> Result<EngineKind, String> {
    EngineKind::parse_available(s).map_err(|e| e.to_string())
}

/// Where the run is, on the judge's clock.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Stage {
    Waiting,
    Running(Phase, Instant),
}

pub fn run(args: Args) -> Result<Exit> {
    if args.robot != "h1_2" {
        bail!("unsupported robot `{}` (supported: h1_2)", args.robot);
    }
    anyhow::ensure!(args.state_rate.is_finite() && args.state_rate > 0.0, "--state-rate must be positive");
    for (name, v) in [
        ("--connect-timeout", args.connect_timeout),
        ("--observe", args.observe),
        ("--silence", args.silence),
        ("--command-timeout", args.command_timeout),
    ] {
        anyhow::ensure!(v.is_finite() && v > 0.0 && v <= 3600.0, "{name} must be in (0, 3600] s");
    }
    for (name, v) in [("--resume", args.resume), ("--fall", args.fall)] {
        anyhow::ensure!(v.is_finite() && (0.0..=3600.0).contains(&v), "{name} must be in [0, 3600] s");
    }
    let cfg = args.net.domain_config()?.receive_buffer_size(256 * 1024);
    let model = robot_model::builtin(&args.robot).with_context(|| format!("loading robot `{}`", args.robot))?;
    let dt = 0.002;
    let common = CommonSettings { timestep: dt, ..CommonSettings::default() };
    let engine = make_engine(args.engine, &model, &common)
        .with_context(|| format!("building the {} engine", args.engine.name()))?;
    let initial = State::standing(&model);
    let config = BridgeConfig {
        command_timeout: args.command_timeout,
        hold_until_first_command: true,
        mode_machine: args.mode_machine,
        defects: Default::default(),
    };
    let mut robot = SimRobot::new(engine, model, config, &initial).context("starting the simulated robot")?;
    let participant = Participant::new(cfg.clone()).context("opening the DDS domain")?;
    let family = dds_transport::Family::Hg;
    let commands = participant.reader(&TopicSpec::lowcmd(family)).context("subscribing rt/lowcmd")?;
    let states = participant.writer(&TopicSpec::lowstate(family)).context("creating the rt/lowstate writer")?;
    let say = |m: &str| {
        if !args.quiet {
            eprintln!("conform controller: {m}");
        }
    };
    say(&format!(
        "playing {} on {} (domain {}, {}), LowState at {} Hz, mode_machine {}; waiting up to {} s for a controller",
        args.robot,
        robot.engine().version(),
        cfg.domain_id(),
        cfg.interface_name(),
        args.state_rate,
        args.mode_machine,
        args.connect_timeout
    ));

    let start = Instant::now();
    let period = 1.0 / args.state_rate;
    let mut next_publish = 0.0;
    let mut sim_time = 0.0;
    let mut stage = Stage::Waiting;
    let mut pose = [0.0_f32; h1_2::NUM_JOINTS];
    let mut trace = Trace { mode_machine: args.mode_machine, silence_s: args.silence, ..Trace::default() };
    let mut fell = false;
    let mut last_iter = Instant::now();
    let mut observe_states = (0u64, 0.0_f64);
    loop {
        let now = Instant::now();
        // The judge's own stalls (from the first command on): a measure of how loaded the machine is.
        if matches!(stage, Stage::Running(..)) {
            trace.judge_max_stall_s = trace.judge_max_stall_s.max(now.duration_since(last_iter).as_secs_f64());
        }
        last_iter = now;
        let wall = start.elapsed().as_secs_f64();
        stage = match stage {
            Stage::Waiting if wall > args.connect_timeout => bail!(
                "no LowCmd from a controller on rt/lowcmd within {} s (is it running on domain {} / {}?)",
                args.connect_timeout,
                cfg.domain_id(),
                cfg.interface_name()
            ),
            Stage::Running(Phase::Observe, t0) if t0.elapsed().as_secs_f64() >= args.observe => {
                observe_states.1 = t0.elapsed().as_secs_f64();
                say("withholding LowState");
                Stage::Running(Phase::Silence, Instant::now())
            }
            Stage::Running(Phase::Silence, t0) if t0.elapsed().as_secs_f64() >= args.silence => {
                // A controller that damps through the silence lets the robot collapse, and its fall watch would
                // then see a fallen robot before the judge tips it over: the robot is stood up again first, as an
                // operator would.
                say("standing the robot up and publishing LowState again");
                robot.reset(&initial).context("standing the robot up")?;
                Stage::Running(Phase::Resume, Instant::now())
            }
            Stage::Running(Phase::Resume, t0) if t0.elapsed().as_secs_f64() >= args.resume => {
                if args.fall == 0.0 {
                    break;
                }
                say("tipping the robot onto its back");
                robot.reset(&on_its_back(&robot.engine().state())).context("tipping the robot over")?;
                fell = true;
                trace.fall_at_s = start.elapsed().as_secs_f64();
                Stage::Running(Phase::Fall, Instant::now())
            }
            Stage::Running(Phase::Fall, t0) if t0.elapsed().as_secs_f64() >= args.fall => break,
            s => s,
        };
        drain(&commands, &mut robot, &mut stage, &mut trace, &pose, start, &say);
        if sim_time > wall {
            std::thread::sleep(Duration::from_secs_f64((sim_time - wall).min(0.001)));
            continue;
        }
        robot.step(start.elapsed().as_secs_f64()).context("physics step")?;
        sim_time += dt;
        if sim_time + 1e-9 >= next_publish {
            next_publish += period;
            if !matches!(stage, Stage::Running(Phase::Silence, _)) {
                let s = robot.lowstate().context("building LowState")?;
                for (slot, q) in pose.iter_mut().enumerate() {
                    *q = s.motor_state[slot].q;
                }
                if let Err(e) = states.write(&cdr::encode(&s, lowlevel_codec::Encoding::UNITREE)) {
                    eprintln!("conform controller: publishing rt/lowstate failed: {e}");
                }
                if matches!(stage, Stage::Running(Phase::Observe, _)) {
                    observe_states.0 += 1;
                }
            }
        }
    }
    if fell {
        trace.fall_s = args.fall;
    }
    let results = controller::judge(&trace);
    let c = robot.counters();
    say(&format!(
        "done: {} commands received, {} accepted, {} rejected, {} bad CRC, {} malformed",
        c.received, c.accepted, c.rejected, c.bad_crc, c.malformed
    ));
    let report = Report {
        schema_version: REPORT_SCHEMA_VERSION,
        target: TargetInfo {
            robot: args.robot.clone(),
            domain: cfg.domain_id(),
            interface: cfg.interface_name().to_owned(),
            participant: None,
            measured_state_rate_hz: (observe_states.1 > 0.0)
                .then(|| (observe_states.0 as f64 / observe_states.1 * 10.0).round() / 10.0),
            rtps_vendor: None,
            rtps_protocol_version: None,
        },
        settings: Settings {
            mode: "controller".into(),
            expected_state_rate_hz: args.state_rate,
            budget_s: None,
            seed: None,
            checks: CheckId::CONTROLLER_RUN.to_vec(),
        },
        versions: BTreeMap::from([
            ("ulab".to_owned(), env!("CARGO_PKG_VERSION").to_owned()),
            ("report_schema".to_owned(), REPORT_SCHEMA_VERSION.to_string()),
            ("transport".to_owned(), "Cyclone DDS 11 (cyclors), raw CDR".to_owned()),
            ("robot_engine".to_owned(), robot.engine().version()),
        ]),
        duration_s: (start.elapsed().as_secs_f64() * 10.0).round() / 10.0,
        results,
        reproducers: Vec::new(),
    };
    if let Some(dir) = &args.out {
        write_file(&dir.join("report.json"), &report.to_json())?;
        write_file(&dir.join("report.md"), &report.to_markdown())?;
    }
    if args.format == super::OutputFormat::Json {
        println!("{}", report.to_json());
    } else {
        print!("{}", report.to_markdown());
    }
    Ok(Exit::failed_if(report.any_fail()))
}

/// Height of the pelvis origin (m) when the judge lays the robot on its back: the pelvis is about 0.2 m deep, so the
/// robot starts a few centimetres above the floor and settles on it.
const FALLEN_PELVIS_HEIGHT_M: f64 = 0.3;

/// `state` with the robot lying on its back, at rest: the pelvis pitched back by 90° (its forward axis pointing up),
/// the joints where they were.
fn on_its_back(state: &State) -> State {
    let half = std::f64::consts::FRAC_PI_4;
    State {
        base_pos: [state.base_pos[0], state.base_pos[1], FALLEN_PELVIS_HEIGHT_M],
        base_quat: [half.cos(), 0.0, -half.sin(), 0.0],
        q: state.q.clone(),
        base_lin_vel: [0.0; 3],
        base_ang_vel: [0.0; 3],
        dq: vec![0.0; state.dq.len()],
    }
}

/// Takes every pending LowCmd: records it (the first one starts the observation) and hands it to the robot.
fn drain(
    reader: &dds_transport::RawReader,
    robot: &mut SimRobot,
    stage: &mut Stage,
    trace: &mut Trace,
    pose: &[f32; h1_2::NUM_JOINTS],
    start: Instant,
    say: &dyn Fn(&str),
) {
    while let Some(sample) = reader.try_take() {
        let now = Instant::now();
        if *stage == Stage::Waiting {
            say("first command: observing");
            *stage = Stage::Running(Phase::Observe, now);
        }
        let Stage::Running(phase, t0) = *stage else { continue };
        let cmd = cdr::decode::<hg::LowCmd_>(&sample.data).ok().map(|d| d.value);
        trace.commands.push(Received {
            t: now.duration_since(start).as_secs_f64(),
            t_in_phase: now.duration_since(t0).as_secs_f64(),
            phase,
            sent_s: sample.source_timestamp_ns.map(|ns| ns as f64 * 1e-9),
            cmd,
            pose: *pose,
        });
        robot.handle_lowcmd(&sample.data, start.elapsed().as_secs_f64());
    }
}
