//! `ulab sim`: a simulated robot behind Unitree's low-level DDS topics, so that a stock Unitree
//! SDK2 controller drives it exactly as the real robot: it subscribes `rt/lowcmd`, publishes
//! `rt/lowstate`. The protocol logic (gates, PD law, damping timeout, IMU, CRC) is
//! `sim_bridge::SimRobot`; this module adds DDS, pacing and the status line. It also serves the
//! SDK's locomotion RPC (`LocoClient`: stand, walk at a velocity, stop, damp) through
//! `sim_loco` / `sim_bridge::loco`, and beside it the motion switcher Unitree's low-level examples ask to release
//! that service (`sim_bridge::motion_switcher`). Like Unitree's MuJoCo bridge it also publishes the simulator's own pelvis pose
//! on `rt/sportmodestate` (go SportModeState_, `--sport-state-rate`, 100 Hz by default), so that a recording of
//! the run carries the ground-truth base pose (`ulab render` draws it instead of estimating one).

use super::recording::NetArgs;
use super::video::{Video, VideoArgs, VideoThread};
use crate::exit::Exit;
use anyhow::{Context, Result};
use dds_transport::{Participant, TopicSpec};
use diff_physics::mujoco::MujocoSettings;
use diff_physics::{make_engine, CommonSettings, EngineKind, State};
use sim_bridge::suspension::{self, SuspendedMujoco};
use sim_bridge::{BridgeConfig, Defect, SimRobot};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub net: NetArgs,
    /// Robot model (built in): h1_2.
    #[arg(long, default_value = "h1_2")]
    pub robot: String,
    #[arg(long, default_value = "mujoco", value_parser = parse_engine,
          help = super::engines_help("Physics engine (`-` and `_` alike), one of"))]
    pub engine: EngineKind,
    /// LowState publish rate (Hz); the real robot publishes about 500 Hz.
    #[arg(long, default_value_t = 500.0)]
    pub state_rate: f64,
    /// Publish rate (Hz) of `rt/sportmodestate` (go SportModeState_: the simulator's pelvis position, velocity and
    /// orientation, the ground truth of a recording); 0 publishes none. 100 Hz is three samples per frame of a
    /// 30 fps video and a fifth of the LowState traffic.
    #[arg(long, default_value_t = 100.0)]
    pub sport_state_rate: f64,
    /// Physics timestep (s).
    #[arg(long, default_value_t = 0.002)]
    pub dt: f64,
    /// Pace simulated time to the wall clock (default).
    #[arg(long, conflicts_with = "fast")]
    pub realtime: bool,
    /// Run as fast as possible (simulated time runs ahead of the wall clock).
    #[arg(long)]
    pub fast: bool,
    /// Seconds without a valid command before damping mode.
    #[arg(long, default_value_t = 0.1)]
    pub command_timeout: f64,
    /// `mode_machine` reported in LowState (no public H1-2 figure; controllers echo what they read).
    #[arg(long, default_value_t = unitree_idl::h1_2::MODE_MACHINE)]
    pub mode_machine: u8,
    /// Start in damping mode instead of holding the standing pose until the first command.
    #[arg(long)]
    pub no_hold: bool,
    /// Stop after this many seconds of wall time (default: until Ctrl-C).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Hang the robot on a stiff stand (pelvis held still 2 m up, feet in the air), as on a gantry: the
    /// suspension rig of `ulab gap` (sim_bridge::suspension, the same stand its diagnosing plant uses). MuJoCo
    /// only; starts holding the standing pose until the first command.
    #[arg(long)]
    pub hang: bool,
    /// Publish each LowState when the wall clock reaches the time it describes, before the next step (causal and
    /// on time, as a robot's sensors; what a recorded log for `ulab gap` needs), at the cost of one physics step
    /// more command-to-state latency. Default: publish right after each step, as unitree_mujoco does (the state
    /// then describes the end of a step the wall clock has not reached yet).
    #[arg(long)]
    pub on_time_state: bool,
    /// Locomotion RPC services to serve (`LocoClient`): h1 (`rt/api/loco/...`, H1/H1-2 API 2.0.0.0), g1
    /// (`rt/api/sport/...`, G1 API 1.0.0.0), comma-separated, or none.
    #[arg(long, default_value = "h1,g1", value_parser = super::sim_loco::parse_api)]
    pub loco_api: super::sim_loco::LocoApis,
    /// Walking policy spec the locomotion service runs (default: the shipped unitree_rl_gym H1-2 LSTM, weights
    /// from $ULAB_SHARED/reference/policies/).
    #[arg(long)]
    pub loco_policy: Option<std::path::PathBuf>,
    /// Do not serve the motion switcher (`rt/api/motion_switcher/...`: `CheckMode` names the locomotion service
    /// "ai", `ReleaseMode` damps the robot and stops that service, `SelectMode("ai")` stands it back up), served
    /// whenever a locomotion service is.
    #[arg(long)]
    pub no_motion_switcher: bool,
    /// Write a video of the run (H.264 MP4): the simulator's own pelvis pose and joint angles, 30 frames per second
    /// of simulated time, with the time and the engine in the picture (rendered on another thread; needs ffmpeg).
    #[arg(long, value_name = "MP4")]
    pub video: Option<std::path::PathBuf>,
    /// No status line.
    #[arg(long)]
    pub quiet: bool,
    /// TEST ONLY: a deliberate protocol defect, repeatable (lets the conformance checks prove they see exactly it):
    /// no-state-crc, tick-stuck, stale-state, apply-bad-crc, ignore-mode0, apply-absurd-gains, limp-on-non-finite,
    /// undefined-on-non-finite, keep-last-command, fallen-pinned (see sim_bridge::Defect).
    #[arg(long = "unsafe-defect", hide = true, value_parser = parse_defect)]
    pub unsafe_defects: Vec<Defect>,
    /// TEST ONLY: publish LowState on this topic instead of rt/lowstate (a test relay republishes it).
    #[arg(long, hide = true)]
    pub unsafe_state_topic: Option<String>,
}

fn parse_engine(s: &str) -> Result<EngineKind, String> {
    EngineKind::parse_available(s).map_err(|e| e.to_string())
}

fn parse_defect(s: &str) -> Result<Defect, String> {
    Defect::parse(s)
        .ok_or_else(|| format!("unknown defect `{s}` (known: {})", Defect::ALL.map(Defect::name).join(", ")))
}

pub fn run(args: Args) -> Result<Exit> {
    anyhow::ensure!(args.state_rate > 0.0 && args.state_rate.is_finite(), "--state-rate must be positive");
    anyhow::ensure!(args.dt > 0.0 && args.dt <= 0.05, "--dt must be in (0, 0.05] s");
    anyhow::ensure!(
        args.sport_state_rate >= 0.0 && args.sport_state_rate.is_finite(),
        "--sport-state-rate must be 0 (off) or positive"
    );
    // A small Cyclone receive buffer: the bridge receives only discovery traffic and lowcmd, and with the default
    // 1 MiB buffer its anonymous RSS creeps up by the bytes received (about 35 KiB/min under participant churn)
    // until the buffer is full; 256 KiB bounds the creep within minutes.
    let cfg = args.net.domain_config()?.receive_buffer_size(256 * 1024);
    let model = robot_model::builtin(&args.robot).with_context(|| format!("loading robot `{}`", args.robot))?;
    let fallen = args.unsafe_defects.contains(&Defect::FallenPinned);
    anyhow::ensure!(!(fallen && args.hang), "the fallen-pinned defect and --hang exclude each other");
    let (engine, initial): (Box<dyn diff_physics::Engine>, State) = if args.hang {
        anyhow::ensure!(
            args.engine == EngineKind::Mujoco,
            "--hang needs the MuJoCo engine (the stand is an applied base wrench)"
        );
        let engine = SuspendedMujoco::new(&model, args.dt, &MujocoSettings::default())
            .context("building MuJoCo on the suspension stand")?;
        let q0 = model.default_q();
        let initial = suspension::state_on_stand(&q0, &vec![0.0; q0.len()]);
        (Box::new(engine), initial)
    } else {
        let common = CommonSettings { timestep: args.dt, ..CommonSettings::default() };
        let engine = make_engine(args.engine, &model, &common)
            .with_context(|| format!("building the {} engine", args.engine.name()))?;
        let initial = if fallen { sim_bridge::lying_on_back(&model) } else { State::standing(&model) };
        (engine, initial)
    };
    let config = BridgeConfig {
        command_timeout: args.command_timeout,
        // A fallen robot is not held up: it lies limp (damping) until the first command.
        hold_until_first_command: !args.no_hold && !fallen,
        mode_machine: args.mode_machine,
        defects: args.unsafe_defects.iter().copied().collect(),
    };
    if !config.defects.is_empty() || args.unsafe_state_topic.is_some() {
        eprintln!(
            "sim: WARNING test-only defects active: {}{}",
            config.defects.iter().map(|d| d.name()).collect::<Vec<_>>().join(", "),
            args.unsafe_state_topic.as_ref().map(|t| format!(" (LowState on `{t}`)")).unwrap_or_default()
        );
    }
    let holding = config.hold_until_first_command;
    let policy = if args.loco_api.0.is_empty() {
        Err("no locomotion service".to_owned())
    } else {
        super::sim_loco::load_policy(args.loco_policy.as_deref(), &model, args.dt)
    };
    if let (Err(why), false) = (&policy, args.loco_api.0.is_empty()) {
        anyhow::ensure!(args.loco_policy.is_none(), "loading the walking policy: {why}");
        eprintln!("sim: WARNING no walking policy ({why}); the locomotion service refuses Start and moves");
    }
    let mut video = match &args.video {
        Some(path) => {
            let v = Video::create(&model, path, &VideoArgs::default())?;
            let label = format!("{}{}", args.engine.name(), if args.hang { " (hung)" } else { "" });
            Some(VideoThread::start(v, label))
        }
        None => None,
    };
    let mut robot = SimRobot::new(engine, model, config, &initial).context("starting the simulated robot")?;

    let participant = Participant::new(cfg.clone()).context("opening the DDS domain")?;
    let family = dds_transport::Family::Hg;
    let commands = participant.reader(&TopicSpec::lowcmd(family)).context("subscribing rt/lowcmd")?;
    let mut state_topic = TopicSpec::lowstate(family);
    if let Some(name) = &args.unsafe_state_topic {
        state_topic.name.clone_from(name);
    }
    let states = participant.writer(&state_topic).context("creating the rt/lowstate writer")?;
    let sport = if args.sport_state_rate > 0.0 {
        let topic = TopicSpec::new(
            unitree_idl::topics::SPORTMODESTATE,
            unitree_idl::MessageType::GoSportModeState.dds_type_name(),
        );
        let writer = participant.writer(&topic).context("creating the rt/sportmodestate writer")?;
        Some((writer, 1.0 / args.sport_state_rate))
    } else {
        None
    };
    let mut next_sport = 0.0;
    let mut loco = if args.loco_api.0.is_empty() {
        None
    } else {
        let service = sim_bridge::loco::LocoService::new(args.loco_api.0.clone(), policy, holding);
        Some(
            super::sim_loco::LocoEndpoints::open(&participant, service, !args.no_motion_switcher)
                .context("serving the locomotion RPC")?,
        )
    };

    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        if let Err(e) = ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst)) {
            eprintln!("warning: cannot install the Ctrl-C handler ({e}); use --duration");
        }
    }
    if !args.quiet {
        eprintln!(
            "sim: {}{} on {} (domain {}, {}), LowState at {} Hz, dt {} s, {}",
            args.robot,
            if args.hang { " hung on the suspension stand" } else { "" },
            robot.engine().version(),
            cfg.domain_id(),
            cfg.interface_name(),
            args.state_rate,
            args.dt,
            if args.fast { "fast" } else { "real time" }
        );
    }

    let start = Instant::now();
    let publish_period = 1.0 / args.state_rate;
    let mut next_publish = 0.0;
    let mut sim_time = 0.0;
    let mut window = (Instant::now(), 0.0_f64, robot.counters().states_published);
    // The pelvis as the simulator sees it (ground truth for programs that judge a controller: how far it walked,
    // whether it stayed up), sampled every 10 ms of simulated time.
    let mut base = BaseTrack::new(&robot.engine().state());
    let progress = |wall: f64| args.duration.map(|d| (wall / d).min(1.0));
    if let Some(v) = video.as_mut() {
        v.offer(0.0, || robot.engine().state().coords(), progress(0.0));
    }
    loop {
        let wall = start.elapsed().as_secs_f64();
        if stop.load(Ordering::SeqCst) || args.duration.is_some_and(|d| wall >= d) {
            break;
        }
        if !args.fast && sim_time > wall {
            // Ahead of the wall clock: wait, but keep taking commands.
            std::thread::sleep(Duration::from_secs_f64((sim_time - wall).min(0.001)));
            drain(&commands, &mut robot, start);
            if let Some(l) = loco.as_mut() {
                l.serve(&mut robot, sim_time, start.elapsed().as_secs_f64());
            }
            continue;
        }
        // --on-time-state: the state at `sim_time` goes out when the wall clock reaches `sim_time`, before the step
        // that leaves it; by default it goes out right after that step (lower latency, but it describes a time one
        // step ahead of the wall clock). Either way the commands received by now drive the step from `sim_time`.
        if args.on_time_state {
            publish_due(&mut robot, &states, sim_time, &mut next_publish, publish_period)?;
        }
        drain(&commands, &mut robot, start);
        if let Some(l) = loco.as_mut() {
            let now = start.elapsed().as_secs_f64();
            l.serve(&mut robot, sim_time, now);
            l.control(&mut robot, sim_time, now);
            if !args.quiet {
                l.take_events().iter().for_each(|e| eprintln!("sim: t={sim_time:.2}s {e}"));
            }
        }
        robot.step(start.elapsed().as_secs_f64()).context("physics step")?;
        sim_time += args.dt;
        base.sample(sim_time, || robot.engine().state());
        if let Some(v) = video.as_mut() {
            v.offer(sim_time, || robot.engine().state().coords(), progress(start.elapsed().as_secs_f64()));
        }
        if !args.on_time_state {
            publish_due(&mut robot, &states, sim_time, &mut next_publish, publish_period)?;
        }
        if let Some((writer, period)) = &sport {
            if sim_time + 1e-9 >= next_sport {
                if let Err(e) = writer.write(&robot.sport_mode_state_bytes()) {
                    eprintln!("sim: publishing rt/sportmodestate failed: {e}");
                }
                next_sport += period;
            }
        }
        let since = window.0.elapsed().as_secs_f64();
        if since >= 1.0 {
            let c = robot.counters();
            if !args.quiet {
                let now = start.elapsed().as_secs_f64();
                eprintln!(
                    "sim: t={sim_time:.1}s state {:.1} Hz  rtf {:.2}  cmds accepted {} rejected {} bad-crc {} malformed {}{}{}",
                    (c.states_published - window.2) as f64 / since,
                    (sim_time - window.1) / since,
                    c.accepted,
                    c.rejected,
                    c.bad_crc,
                    c.malformed,
                    match (robot.command_active(now), robot.internal_command().is_some()) {
                        (true, _) => "",
                        (false, true) => "  [driven by the locomotion service]",
                        (false, false) => "  [damping/hold: no fresh command]",
                    },
                    loco.as_ref().map(|l| format!("  {}", l.status(sim_time))).unwrap_or_default()
                );
            }
            window = (Instant::now(), sim_time, c.states_published);
        }
    }
    let c = robot.counters();
    eprintln!(
        "sim: stopped after {:.1} s wall, {sim_time:.1} s simulated; states {} cmds received {} accepted {} rejected {} bad-crc {} malformed {}",
        start.elapsed().as_secs_f64(),
        c.states_published,
        c.received,
        c.accepted,
        c.rejected,
        c.bad_crc,
        c.malformed
    );
    // The same account as one JSON line, for programs (tests judge the bridge by its own counters and its
    // simulated time, which do not depend on how fast the machine is).
    let summary = serde_json::json!({
        "engine": args.engine.name(),
        "wall_seconds": start.elapsed().as_secs_f64(),
        "simulated_seconds": sim_time,
        "dt": args.dt,
        "state_rate_hz": args.state_rate,
        "counters": c,
        "loco": loco.as_ref().map(|l| l.summary()),
        "base": base.summary(&robot.engine().state()),
    });
    eprintln!("sim: summary {summary}");
    if let Some(v) = video {
        v.finish().context("writing the video")?;
    }
    Ok(Exit::Success)
}

/// The pelvis over the run: start and end positions, lowest height and largest tilt (sampled).
struct BaseTrack {
    start: [f64; 3],
    min_height: f64,
    max_tilt_rad: f64,
    next_sample: f64,
}

impl BaseTrack {
    const SAMPLE_S: f64 = 0.01;

    fn new(s: &State) -> Self {
        BaseTrack { start: s.base_pos, min_height: s.base_pos[2], max_tilt_rad: tilt(s.base_quat), next_sample: 0.0 }
    }

    fn sample(&mut self, sim_time: f64, state: impl FnOnce() -> State) {
        if sim_time < self.next_sample {
            return;
        }
        self.next_sample = sim_time + Self::SAMPLE_S;
        let s = state();
        self.min_height = self.min_height.min(s.base_pos[2]);
        self.max_tilt_rad = self.max_tilt_rad.max(tilt(s.base_quat));
    }

    fn summary(&self, end: &State) -> serde_json::Value {
        serde_json::json!({
            "start": self.start,
            "end": end.base_pos,
            "end_yaw_rad": yaw(end.base_quat),
            "min_height": self.min_height,
            "max_tilt_rad": self.max_tilt_rad,
        })
    }
}

/// Angle (rad) between the pelvis z axis and the world's vertical, from `[w, x, y, z]`.
fn tilt(q: [f64; 4]) -> f64 {
    let [_, x, y, _] = q;
    (1.0 - 2.0 * (x * x + y * y)).clamp(-1.0, 1.0).acos()
}

/// Heading (rad) of the pelvis x axis, from `[w, x, y, z]`.
fn yaw(q: [f64; 4]) -> f64 {
    let [w, x, y, z] = q;
    (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z))
}

/// Publishes the robot's LowState when `sim_time` has reached the next publication time.
fn publish_due(
    robot: &mut SimRobot,
    states: &dds_transport::RawWriter,
    sim_time: f64,
    next_publish: &mut f64,
    period: f64,
) -> Result<()> {
    if sim_time + 1e-9 >= *next_publish {
        let bytes = robot.lowstate_bytes().context("building LowState")?;
        if let Err(e) = states.write(&bytes) {
            eprintln!("sim: publishing rt/lowstate failed: {e}");
        }
        *next_publish += period;
    }
    Ok(())
}

/// Hands every pending command sample to the robot, stamped with the bridge's clock.
fn drain(reader: &dds_transport::RawReader, robot: &mut SimRobot, start: Instant) {
    while let Some(sample) = reader.try_take() {
        robot.handle_lowcmd(&sample.data, start.elapsed().as_secs_f64());
    }
}
