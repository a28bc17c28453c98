//! The CI demo of issue 17: `ulab deploy` walks the robot in `ulab sim` for 10 s with each shipped policy (the
//! unitree_rl_gym LSTM, also steered by keys on a piped stdin, and Gepetto's Isaac Lab MLP) on MuJoCo, Bullet, DART
//! and Rapier's multibody, over DDS, as the robot's low-level controller (LowState in, LowCmd with CRC out at
//! 500 Hz); the simulator, not the deployer, says what happened: how far the pelvis went, whether it stayed up, how
//! many commands it accepted with a valid CRC. Where the robot falls (Rapier's impulse joints) the deployer must stop.
//! Bad arguments exit 2 without sending anything. The Cyclone 0.10.2 client path is `sim_c010_client.rs`. Every walk
//! leaves the simulator's video (`ulab sim --video`) in `target/tmp/ci-demo/ENGINE-POLICY.mp4`, checked with
//! ffmpeg's decoder (frame count, the robot in every sampled picture, the picture changing as it walks).
//!
//! What is independent here: the physics (four engines nobody here wrote), the policies (unitree_rl_gym, Gepetto), and
//! the simulator's own account of the pelvis; the CRC is checked by
//! the bridge's gate, which is this project's code (the same CRC was checked against Unitree's Python SDK in the codec
//! tests). Skips without `$ULAB_SHARED` (the policy's weights live there).
use crate::common;

use common::{
    interrupt, lease_domain, robot_pixels, run_ulab, sim_summary, tail, wait_with_timeout, KillOnDrop, RealtimeSlot,
};
use serde_json::Value;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

const SPEC: &str = "robots/h1_2/policies/unitree_rl_gym_lstm.toml";
const GEPETTO: &str = "robots/h1_2/policies/gepetto_demo_rsl.toml";
/// Seconds of policy control in each walk (after the 2 s ramp to the standing pose).
const WALK_S: f64 = 10.0;
/// Forward command (m/s) of every walk.
const VX: f64 = 0.5;

fn summary(stderr: &str, prefix: &str) -> Option<Value> {
    stderr.lines().rev().find_map(|l| l.strip_prefix(prefix)).and_then(|j| serde_json::from_str(j).ok())
}

fn shared_missing() -> bool {
    if std::env::var("ULAB_SHARED").map_or(true, |v| v.is_empty()) {
        eprintln!("SKIPPED: ULAB_SHARED is not set (the walking policies' weights live there)");
        return true;
    }
    false
}

/// How the deployer is given its 0.5 m/s forward command.
#[derive(Clone, Copy)]
enum Steer {
    /// Five `w` key presses on a piped stdin (`--keyboard`): the walk is then also the evidence that keys reach the
    /// policy (the command would otherwise be 0).
    Keys,
    /// `--command 0.5,0,0`.
    Flag,
}

/// What one `ulab sim --engine E` + `ulab deploy --policy P` run left: both summaries and the deployer's exit code.
struct Walk {
    label: String,
    /// The simulator's video of the run (`ulab sim --video`).
    video: PathBuf,
    code: Option<i32>,
    deploy: Value,
    sim: Value,
}

fn walk(engine: &str, spec: &str, steer: Steer, seconds: f64, sim_args: &[&str]) -> Walk {
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let policy = spec.rsplit('/').next().unwrap_or(spec).trim_end_matches(".toml");
    let label = format!("{engine} / {policy}");
    let video = demo_dir().join(format!("{engine}-{policy}.mp4"));
    let sim = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["sim", "--engine", engine, "--domain", &domain.arg(), "--loco-api", "none", "--quiet", "--video"])
        .arg(&video)
        .args(sim_args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab sim");
    let mut sim = KillOnDrop(Some(sim));
    let spec = common::root().join(spec);
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_ulab"));
    cmd.args(["deploy", "--domain", &domain.arg(), "--policy"]).arg(&spec);
    match steer {
        Steer::Keys => cmd.arg("--keyboard"),
        Steer::Flag => cmd.args(["--command", &format!("{VX},0,0")]),
    };
    let mut deploy = cmd
        .args(["--duration", &seconds.to_string(), "--damp-seconds", "0"])
        // A loaded CI machine may delay a LowState by more than the default 0.1 s; the stale stop itself is tested
        // in policy-deploy's unit tests.
        .args(["--stale-seconds", "0.5"])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab deploy");
    // Written at once and closed: the keys are read before the policy starts, and the end of input changes nothing.
    let keys: &[u8] = if matches!(steer, Steer::Keys) { b"wwwww" } else { b"" };
    deploy.stdin.take().expect("stdin").write_all(keys).expect("keys");
    let (status, _, deploy_err) = wait_with_timeout(deploy, Duration::from_secs(180));
    // Stop the simulator at once: without commands it damps and the robot sits down.
    let sim_child = sim.0.take().expect("sim child");
    interrupt(&sim_child);
    let (_, _, sim_err) = wait_with_timeout(sim_child, Duration::from_secs(60));
    let code = status.and_then(|s| s.code());
    let deploy = summary(&deploy_err, "deploy: summary ")
        .unwrap_or_else(|| panic!("{label}: no deploy summary (exit {code:?}):\n{}", tail(&deploy_err)));
    let sim = sim_summary(&sim_err).unwrap_or_else(|| panic!("{label}: no sim summary:\n{}", tail(&sim_err)));
    eprintln!("{label}\n  deploy: {deploy}\n  sim: {sim}");
    Walk { label, video, code, deploy, sim }
}

/// Where the demo's videos go: the test output (`target/tmp/ci-demo/`), listed at the end of each test.
fn demo_dir() -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ci-demo");
    std::fs::create_dir_all(&d).expect("ci-demo dir");
    d
}

/// Checks the run's video with ffmpeg's own decoder: as many frames as 30 per second of simulated time, and one
/// picture per second (decoded by ffmpeg at 1 fps) that shows the robot and differs from the one before (the robot
/// walks and the ground scrolls under the following camera). Returns the number of frames.
fn check_video(w: &Walk) -> u64 {
    let ffmpeg = robot_render::find_ffmpeg().unwrap_or_else(|e| panic!("the CI demo needs ffmpeg: {e}"));
    let l = &w.label;
    let count = Command::new(&ffmpeg)
        .args(["-hide_banner", "-nostdin", "-i"])
        .arg(&w.video)
        .args(["-map", "0:v", "-f", "null", "-"])
        .output()
        .expect("run ffmpeg");
    let err = String::from_utf8_lossy(&count.stderr);
    assert!(count.status.success(), "{l}: ffmpeg cannot read {}: {err}", w.video.display());
    assert!(err.contains("Video: h264") && err.contains("yuv420p"), "{l}: not H.264 yuv420p: {err}");
    let frames: u64 = err
        .rsplit("frame=")
        .next()
        .and_then(|t| t.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{l}: no frame count in {err}"));
    let simulated = w.sim["simulated_seconds"].as_f64().unwrap_or(0.0);
    assert!(
        (frames as f64 - 30.0 * simulated).abs() <= 0.03 * 30.0 * simulated + 2.0,
        "{l}: {frames} frames for {simulated:.1} s"
    );
    let pics = Command::new(&ffmpeg)
        .args(["-hide_banner", "-nostdin", "-i"])
        .arg(&w.video)
        .args(["-vf", "fps=1", "-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
        .output()
        .expect("run ffmpeg");
    assert!(pics.status.success(), "{l}: {}", String::from_utf8_lossy(&pics.stderr));
    let n = 640 * 360 * 3;
    assert!(
        pics.stdout.len().is_multiple_of(n) && pics.stdout.len() >= 5 * n,
        "{l}: {} bytes of pictures",
        pics.stdout.len()
    );
    let pictures: Vec<&[u8]> = pics.stdout.chunks(n).collect();
    for (k, p) in pictures.iter().enumerate() {
        assert!(robot_pixels(p) > 1000, "{l}: no robot in the picture at {k} s");
    }
    // From the end of the ramp (2 s) on, the robot walks: every picture differs from the one a second before.
    for k in 3..pictures.len() {
        let diff: u64 = pictures[k].iter().zip(pictures[k - 1]).map(|(a, b)| u64::from(a.abs_diff(*b))).sum();
        let mean = diff as f64 / n as f64;
        assert!(mean > 0.5, "{l}: the picture at {k} s is the one at {} s (mean difference {mean:.2})", k - 1);
    }
    frames
}

/// Lists the demo's videos (the CI log keeps the list; the files stay in the test output).
fn list_videos() {
    let Ok(entries) = std::fs::read_dir(demo_dir()) else { return };
    let mut v: Vec<String> = entries
        .flatten()
        .filter_map(|e| Some(format!("{} ({} KiB)", e.path().display(), e.metadata().ok()?.len() / 1024)))
        .collect();
    v.sort();
    eprintln!("ci-demo videos:\n  {}", v.join("\n  "));
}

impl Walk {
    /// The demo's behavioural checks, from the simulator's account wherever it has one: exit 0 after a requested
    /// stop, the policy at its 50 Hz, every command received with a valid CRC and accepted, the pelvis up and
    /// upright throughout, and the distance walked along the command within a tolerance.
    fn assert_walked(&self) {
        let (l, d, s) = (&self.label, &self.deploy, &self.sim);
        assert_eq!(self.code, Some(0), "{l}: deploy exit\n{d}\n{s}");
        assert_eq!(d["safety_stop"], false, "{l}: {d}");
        assert_eq!(d["stop"]["reason"], "requested", "{l}: {d}");
        assert_eq!(d["counters"]["bad_crc"], 0, "{l}: {d}");
        assert_eq!(d["malformed_states"], 0, "{l}: {d}");
        let policy_s = d["policy_seconds"].as_f64().unwrap_or(0.0);
        let policy_steps = d["counters"]["policy_steps"].as_f64().unwrap_or(0.0);
        assert!(policy_steps >= 0.9 * policy_s / 0.02, "{l}: 50 Hz policy for {policy_s:.1} s: {policy_steps} steps");

        // The simulator's account: every command it received passed its CRC and limit gates.
        let c = &s["counters"];
        let sent = d["counters"]["commands"].as_f64().unwrap_or(0.0);
        assert_eq!(c["bad_crc"], 0, "{l}: {s}");
        assert_eq!(c["rejected"], 0, "{l}: {s}");
        assert_eq!(c["malformed"], 0, "{l}: {s}");
        assert!(c["accepted"].as_f64().unwrap_or(0.0) >= 0.99 * sent, "{l}: sim accepted {} of {sent}", c["accepted"]);
        // The pelvis: up throughout, walked forward at about the commanded speed. The walk's simulated length is
        // the deployer's policy time scaled by the simulator's own simulated/wall ratio (a loaded machine may run
        // the simulator slower than real time).
        let b = &s["base"];
        let xyz = |k: &str| -> [f64; 3] { [0, 1, 2].map(|i| b[k][i].as_f64().unwrap_or(f64::NAN)) };
        let (start, end) = (xyz("start"), xyz("end"));
        let min_h = b["min_height"].as_f64().unwrap_or(0.0);
        let tilt = b["max_tilt_rad"].as_f64().unwrap_or(f64::NAN);
        assert!(min_h > 0.7, "{l}: pelvis went down to {min_h:.2} m: {b}");
        assert!(tilt < 0.5, "{l}: pelvis tilted {tilt:.2} rad: {b}");
        let ratio =
            s["simulated_seconds"].as_f64().unwrap_or(f64::NAN) / s["wall_seconds"].as_f64().unwrap_or(f64::NAN);
        let walked_s = policy_s * ratio.min(1.0);
        let (dx, dy) = (end[0] - start[0], end[1] - start[1]);
        let speed = dx / walked_s;
        eprintln!(
            "{l}: walked {dx:.2} m forward, {dy:.2} m sideways in {walked_s:.1} s: {speed:.2} m/s for {VX} commanded"
        );
        // From standing, both shipped policies average 0.7-1.05x the command over 10 s on the engines here.
        assert!((0.55 * VX..=1.3 * VX).contains(&speed), "{l}: forward speed {speed:.2} m/s for {VX} commanded: {b}");
        assert!(dy.abs() < 0.25 * walked_s, "{l}: lateral drift {dy:.2} m: {b}");
        let frames = check_video(self);
        eprintln!("{l}: video {} ({frames} frames)", self.video.display());
    }
}

/// The CI demo on MuJoCo: the LSTM policy steered by keys, and Gepetto's Isaac Lab policy.
#[test]
fn deploy_walks_both_policies_in_ulab_sim_on_mujoco() {
    if shared_missing() {
        return;
    }
    let w = walk("mujoco", SPEC, Steer::Keys, WALK_S, &[]);
    assert_eq!(w.deploy["key_presses"], 5, "{}", w.deploy);
    assert_eq!(w.deploy["final_command"], serde_json::json!([VX, 0.0, 0.0]), "{}", w.deploy);
    w.assert_walked();
    walk("mujoco", GEPETTO, Steer::Flag, WALK_S, &[]).assert_walked();
    list_videos();
}

/// The same walks on the other engines that can walk them (PhysX runs in `scripts/nightly.sh`: its build is slow).
#[test]
fn deploy_walks_both_policies_in_ulab_sim_on_bullet_dart_and_rapier() {
    if shared_missing() {
        return;
    }
    for engine in ["bullet", "dart", "rapier-multibody"] {
        for spec in [SPEC, GEPETTO] {
            walk(engine, spec, Steer::Flag, WALK_S, &[]).assert_walked();
        }
    }
    list_videos();
}

/// A robot lying on its back (the simulator's `fallen-pinned` start, a test-only switch) when the policy would take
/// over: the deployer must see the fall from the torso IMU, damp instead of running the policy, and exit 1. (On
/// Rapier's impulse joints the robot sometimes falls during the start sequence and sometimes walks, depending on
/// timing, so that engine is no reliable fall.)
#[test]
fn deploy_damps_and_exits_1_when_the_robot_is_down() {
    if shared_missing() {
        return;
    }
    let w = walk("mujoco", SPEC, Steer::Flag, 4.0, &["--unsafe-defect", "fallen-pinned"]);
    let (d, b) = (&w.deploy, &w.sim["base"]);
    let sim_tilt = b["max_tilt_rad"].as_f64().unwrap_or(0.0);
    assert!(sim_tilt > 1.0, "the simulator's robot was expected to lie down: {b}");
    assert_eq!(w.code, Some(1), "{d}");
    assert_eq!(d["safety_stop"], true, "{d}");
    assert_eq!(d["stop"]["reason"], "fallen", "{d}");
    assert_eq!(d["counters"]["policy_steps"], 0, "no policy step on a robot that is down: {d}");
    let seen = d["stop"]["tilt_rad"].as_f64().unwrap_or(f64::NAN);
    assert!(seen > 0.69 && seen <= sim_tilt + 0.05, "the deployer's tilt {seen} vs the simulator's maximum {sim_tilt}");
}

#[test]
fn bad_arguments_exit_2_before_sending() {
    // A leased domain nobody publishes on (the "no valid LowState" case).
    let domain = lease_domain();
    let quiet = domain.arg();
    let spec = common::root().join(SPEC);
    let spec = spec.to_str().expect("utf-8 path");
    for (args, expect) in [
        (vec!["deploy", "--policy", spec, "--domain", "0"], "--allow-robot"),
        (vec!["deploy", "--policy", spec, "--interface", "eth0"], "--allow-robot"),
        (vec!["deploy", "--policy", spec, "--command", "0.5,0"], "three finite numbers"),
        (vec!["deploy", "--policy", spec, "--command", "9,0,0"], "three finite numbers"),
        (vec!["deploy", "--policy", spec, "--rate", "5"], "--rate"),
        (vec!["deploy", "--policy", spec, "--max-tilt-deg", "0"], "--max-tilt-deg"),
        (vec!["deploy", "--policy", spec, "--max-tilt-deg", "200"], "--max-tilt-deg"),
        (vec!["deploy", "--policy", "/nonexistent.toml"], "loading policy spec"),
        (vec!["deploy", "--policy", spec, "--domain", &quiet, "--wait-seconds", "0.5"], "no valid LowState"),
    ] {
        let (code, out, err) = run_ulab(&args, Duration::from_secs(60));
        assert_eq!(code, Some(2), "{args:?}\n{out}\n{err}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}
