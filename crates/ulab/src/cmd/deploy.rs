//! `ulab deploy --policy SPEC [--domain D] [--command vx,vy,wz] [--keyboard] [--duration S]`: a policy as the robot's low-level
//! controller over DDS (issue 17). Reads `rt/lowstate`, runs the policy at its rate and writes `rt/lowcmd` at
//! `--rate` (500 Hz) with a sealed CRC; the logic (start sequence, limits, safety stops) is
//! `policy_deploy::Deployer`, this module only does the I/O and the clock.
//!
//! Safety: loopback and a non-zero domain by default; domain 0 or a real interface only with `--allow-robot`,
//! and then the command prints what it will send and waits `--confirm-seconds` before sending. Stale or
//! non-finite state, a policy error or Ctrl-C lead to damping (zero stiffness) for `--damp-seconds`, then exit.
//!
//! `--keyboard` steers the velocity command from the keys (`policy_deploy::keyboard`: w/s, a/d, q/e or arrows,
//! space to stand, Esc or Ctrl-C to stop): from a terminal in raw mode, or byte by byte from a piped stdin, so that
//! scripts and tests drive it the same way.
//!
//! Exit codes: 0 the run ended as asked (duration or Ctrl-C), 1 a safety stop, 2 errors (no state, bad input).
use super::recording::NetArgs;
use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use dds_transport::{Family, Participant, TopicSpec};
use lowlevel_codec::{cdr, Encoding};
use policy_deploy::keyboard::{self, Key, KeyEffect};
use policy_deploy::{DeployConfig, Deployer, Phase, StopReason};
use std::io::{IsTerminal, Read};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};
use unitree_idl::hg;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub net: NetArgs,
    /// Robot model (built in): h1_2.
    #[arg(long, default_value = "h1_2")]
    robot: String,
    /// Policy spec TOML (robots/h1_2/policies/*.toml).
    #[arg(long)]
    policy: PathBuf,
    /// Velocity command `vx,vy,wz` (m/s, m/s, rad/s) given to the policy.
    #[arg(long, default_value = "0,0,0", value_parser = parse_command, allow_hyphen_values = true)]
    command: [f64; 3],
    /// Steer the velocity command from the keyboard (w/s forward, a/d sideways, q/e or arrows turn, space stands,
    /// Esc stops); `--command` is the starting value. Reads a terminal in raw mode, or a piped stdin byte by byte.
    #[arg(long)]
    keyboard: bool,
    /// Seconds of policy control after the start sequence (default: until Ctrl-C).
    #[arg(long)]
    duration: Option<f64>,
    /// Seconds to move to the standing pose before the policy takes over.
    #[arg(long, default_value_t = 2.0)]
    ramp_seconds: f64,
    /// LowCmd rate (Hz).
    #[arg(long, default_value_t = 500.0)]
    rate: f64,
    /// Seconds of damping after a stop, before exiting.
    #[arg(long, default_value_t = 1.0)]
    damp_seconds: f64,
    /// A LowState older than this (s) when a command is due stops the policy (damping).
    #[arg(long, default_value_t = 0.1)]
    stale_seconds: f64,
    /// While the policy runs, a torso tilt (from the IMU) beyond this many degrees from vertical is a fall: damping,
    /// exit 1.
    #[arg(long, default_value_t = policy_deploy::DEFAULT_MAX_TILT_RAD.to_degrees().round())]
    max_tilt_deg: f64,
    /// No fall check (a robot on a gantry tilted on purpose, a policy that rolls over).
    #[arg(long, conflicts_with = "max_tilt_deg")]
    no_fall_check: bool,
    /// Seconds to wait for the first LowState.
    #[arg(long, default_value_t = 10.0)]
    wait_seconds: f64,
    /// With --allow-robot: seconds between printing what will be sent and sending it (Ctrl-C to abort).
    #[arg(long, default_value_t = 5.0)]
    confirm_seconds: f64,
}

fn parse_command(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> =
        s.split(',').map(|p| p.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|e| e.to_string())?;
    match v.as_slice() {
        [a, b, c] if v.iter().all(|x| x.is_finite() && x.abs() <= 3.0) => Ok([*a, *b, *c]),
        _ => Err(format!("`{s}`: three finite numbers vx,vy,wz within ±3")),
    }
}

pub fn run(a: Args) -> Result<Exit> {
    let positive = |x: f64, lo: f64, hi: f64| x.is_finite() && x >= lo && x <= hi;
    if !positive(a.rate, 50.0, 2000.0) {
        bail!("--rate must be in [50, 2000] Hz");
    }
    if a.duration.is_some_and(|d| !positive(d, 0.0, 86_400.0)) {
        bail!("--duration must be in [0, 86400] s");
    }
    if !positive(a.stale_seconds, 0.004, 5.0) {
        bail!("--stale-seconds must be in [0.004, 5] s");
    }
    if !positive(a.ramp_seconds, 0.0, 60.0)
        || !positive(a.damp_seconds, 0.0, 60.0)
        || !positive(a.wait_seconds, 0.1, 600.0)
    {
        bail!("--ramp-seconds and --damp-seconds must be in [0, 60] s, --wait-seconds in [0.1, 600] s");
    }
    if !positive(a.max_tilt_deg, 1.0, 179.0) {
        bail!("--max-tilt-deg must be in [1, 179] degrees");
    }
    let cfg = a.net.domain_config()?;
    let model = robot_model::builtin(&a.robot).with_context(|| format!("loading robot `{}`", a.robot))?;
    let policy = policy_runtime::PolicyController::load(&a.policy)
        .with_context(|| format!("loading policy spec {}", a.policy.display()))?;
    let name = policy_runtime::Controller::name(&policy).to_string();
    let deploy_cfg = DeployConfig {
        command: a.command,
        ramp_s: a.ramp_seconds,
        stale_s: a.stale_seconds,
        max_tilt_rad: (!a.no_fall_check).then(|| a.max_tilt_deg.to_radians()),
    };
    let mut deployer = Deployer::new(model, Box::new(policy), deploy_cfg).context("setting up the deployment")?;

    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        if let Err(e) = ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst)) {
            eprintln!("warning: cannot install the Ctrl-C handler ({e}); use --duration");
        }
    }
    eprintln!(
        "deploy: policy {name} on domain {} ({}): reads rt/lowstate, writes rt/lowcmd (unitree_hg, every joint mode 1, \
         CRC sealed) at {} Hz; {} s to the standing pose, then the policy with command {:?}",
        cfg.domain_id(),
        cfg.interface_name(),
        a.rate,
        a.ramp_seconds,
        a.command
    );
    if cfg.may_reach_robot() {
        eprintln!(
            "deploy: WARNING this may reach a real robot. Hang it on its gantry. Sending starts in {} s; Ctrl-C aborts.",
            a.confirm_seconds
        );
        let until = Instant::now() + Duration::from_secs_f64(a.confirm_seconds.clamp(0.0, 60.0));
        while Instant::now() < until {
            if stop.load(Ordering::SeqCst) {
                eprintln!("deploy: aborted before sending anything");
                return Ok(Exit::Success);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    let keys = a.keyboard.then(KeyReader::start).transpose()?;
    if keys.is_some() {
        say(keys.as_ref(), "deploy: keyboard: w/s forward, a/d sideways, q/e turn, space stands, Esc stops");
    }
    let participant = Participant::new(cfg.clone()).context("opening the DDS domain")?;
    let states = participant.reader(&TopicSpec::lowstate(Family::Hg)).context("subscribing rt/lowstate")?;
    let commands = participant.writer(&TopicSpec::lowcmd(Family::Hg)).context("creating the rt/lowcmd writer")?;
    let start = Instant::now();
    let period = Duration::from_secs_f64(1.0 / a.rate);
    let mut next = start;
    let mut malformed = 0u64;
    let mut running_since: Option<f64> = None;
    let mut stopped_at: Option<f64> = None;
    let mut first_state: Option<f64> = None;
    let mut key_presses = 0u64;
    loop {
        let now = start.elapsed().as_secs_f64();
        while let Some(sample) = states.try_take() {
            match cdr::decode::<hg::LowState_>(&sample.data) {
                Ok(s) => {
                    first_state.get_or_insert(now);
                    deployer.on_state(&s.value, now);
                }
                Err(_) => malformed += 1,
            }
        }
        if first_state.is_none() && now > a.wait_seconds {
            bail!(
                "no valid LowState on domain {} ({}) within {} s: is the robot or `ulab sim` running there?",
                cfg.domain_id(),
                cfg.interface_name(),
                a.wait_seconds
            );
        }
        for key in keys.iter().flat_map(|k| k.pressed.try_iter()) {
            key_presses += 1;
            match keyboard::apply(key, deployer.velocity_command()) {
                KeyEffect::Command(c) => {
                    if deployer.set_velocity_command(c).is_ok() {
                        say(
                            keys.as_ref(),
                            &format!("deploy: t={now:.2} s command vx {:.1} vy {:.1} wz {:.1}", c[0], c[1], c[2]),
                        );
                    }
                }
                KeyEffect::Stop => stop.store(true, Ordering::SeqCst),
                KeyEffect::Ignored => {}
            }
        }
        if deployer.phase() == Phase::Running && running_since.is_none() {
            running_since = Some(now);
            say(keys.as_ref(), &format!("deploy: t={now:.2} s policy running"));
        }
        let done = running_since.zip(a.duration).is_some_and(|(t0, d)| now - t0 >= d);
        if stop.load(Ordering::SeqCst) || done {
            deployer.stop(StopReason::Requested);
        }
        if deployer.phase() == Phase::Damping && stopped_at.is_none() {
            stopped_at = Some(now);
            say(keys.as_ref(), &format!("deploy: t={now:.2} s damping: {:?}", deployer.stop_reason()));
        }
        if stopped_at.is_some_and(|t| now - t >= a.damp_seconds) {
            break;
        }
        if let Some(cmd) = deployer.command(now) {
            if let Err(e) = commands.write(&cdr::encode(&cmd, Encoding::UNITREE)) {
                eprintln!("deploy: writing rt/lowcmd failed: {e}");
            }
        }
        next += period;
        let now_i = Instant::now();
        if next > now_i {
            std::thread::sleep(next - now_i);
        } else if now_i - next > 10 * period {
            // Far behind (a suspended process): resume the cadence from now rather than bursting.
            next = now_i;
        }
    }
    // The terminal back in its normal mode before the summary.
    drop(keys);
    let safety_stop = !matches!(deployer.stop_reason(), Some(StopReason::Requested) | None);
    let summary = serde_json::json!({
        "policy": name,
        "command": a.command,
        "final_command": deployer.velocity_command(),
        "key_presses": key_presses,
        "wall_seconds": start.elapsed().as_secs_f64(),
        "policy_seconds": running_since.map(|t0| stopped_at.unwrap_or(t0) - t0),
        "stop": deployer.stop_reason(),
        "safety_stop": safety_stop,
        "counters": deployer.counters(),
        "malformed_states": malformed,
    });
    eprintln!("deploy: summary {summary}");
    Ok(Exit::failed_if(safety_stop))
}

/// Prints a status line; a terminal in raw mode needs the carriage return spelled out.
fn say(keys: Option<&KeyReader>, line: &str) {
    if keys.is_some_and(|k| k.raw) {
        eprint!("{line}\r\n");
    } else {
        eprintln!("{line}");
    }
}

/// Keys from the terminal (raw mode, restored on drop) or from a piped stdin, delivered on a channel by a thread.
struct KeyReader {
    pressed: mpsc::Receiver<Key>,
    raw: bool,
    stop: Arc<AtomicBool>,
}

impl KeyReader {
    fn start() -> Result<KeyReader> {
        let (tx, pressed) = mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let raw = std::io::stdin().is_terminal();
        if raw {
            crossterm::terminal::enable_raw_mode().context("--keyboard: switching the terminal to raw mode")?;
            let stop = stop.clone();
            std::thread::spawn(move || {
                use crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
                while !stop.load(Ordering::SeqCst) {
                    if !event::poll(Duration::from_millis(50)).unwrap_or(false) {
                        continue;
                    }
                    let Ok(Event::Key(k)) = event::read() else { continue };
                    if k.kind == KeyEventKind::Release {
                        continue;
                    }
                    let key = match k.code {
                        KeyCode::Char('c') if k.modifiers.contains(KeyModifiers::CONTROL) => Key::CtrlC,
                        KeyCode::Char(c) => Key::Char(c),
                        KeyCode::Up => Key::Up,
                        KeyCode::Down => Key::Down,
                        KeyCode::Left => Key::Left,
                        KeyCode::Right => Key::Right,
                        KeyCode::Esc => Key::Esc,
                        _ => continue,
                    };
                    if tx.send(key).is_err() {
                        break;
                    }
                }
            });
        } else {
            // A pipe: every byte is a key; the end of the input leaves the command as it is.
            std::thread::spawn(move || {
                let mut stdin = std::io::stdin().lock();
                let mut byte = [0u8; 1];
                while let Ok(1) = stdin.read(&mut byte) {
                    if tx.send(Key::from_byte(byte[0])).is_err() {
                        break;
                    }
                }
            });
        }
        Ok(KeyReader { pressed, raw, stop })
    }
}

impl Drop for KeyReader {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if self.raw {
            let _ = crossterm::terminal::disable_raw_mode();
        }
    }
}
