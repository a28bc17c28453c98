//! `ulab deploy` walks the robot in `ulab sim` (issue 17): the shipped unitree_rl_gym LSTM policy, steered by keys
//! (`--keyboard`, piped), runs outside the
//! simulator, over DDS, as the robot's low-level controller (LowState in, LowCmd with CRC out at 500 Hz), and the
//! simulator, not the deployer, says what happened: how far the pelvis went, whether it stayed up, how many commands
//! it accepted with a valid CRC. Bad arguments exit 2 without sending anything.
//!
//! What is independent here: the physics (MuJoCo) and the simulator's own account of the pelvis; the CRC is checked by
//! the bridge's gate, which is this project's code (the same CRC was checked against Unitree's Python SDK in the codec
//! tests). Skips without `$ULAB_SHARED` (the policy's weights live there).
mod common;

use common::{interrupt, lease_domain, run_ulab, sim_summary, tail, wait_with_timeout, KillOnDrop, RealtimeSlot};
use serde_json::Value;
use std::io::Write;
use std::process::{Command, Stdio};
use std::time::Duration;

const SPEC: &str = "robots/h1_2/policies/unitree_rl_gym_lstm.toml";
const WALK_S: f64 = 6.0;

fn summary(stderr: &str, prefix: &str) -> Option<Value> {
    stderr.lines().rev().find_map(|l| l.strip_prefix(prefix)).and_then(|j| serde_json::from_str(j).ok())
}

#[test]
fn deploy_walks_the_lstm_policy_in_ulab_sim() {
    if std::env::var("ULAB_SHARED").map_or(true, |v| v.is_empty()) {
        eprintln!("SKIPPED: ULAB_SHARED is not set (the walking policy's weights live there)");
        return;
    }
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let sim = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["sim", "--engine", "mujoco", "--domain", &domain.arg(), "--loco-api", "none", "--quiet"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab sim");
    let mut sim = KillOnDrop(Some(sim));
    let spec = common::root().join(SPEC);
    // The 0.5 m/s forward command comes from five `w` key presses on a piped stdin (`--keyboard`): the walk below is
    // then also the evidence that keys reach the policy (the command would otherwise be 0).
    let mut deploy = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["deploy", "--domain", &domain.arg(), "--policy"])
        .arg(&spec)
        .args(["--keyboard", "--duration", &WALK_S.to_string(), "--damp-seconds", "0"])
        // A loaded CI machine may delay a LowState by more than the default 0.1 s; the stale stop itself is tested
        // in policy-deploy's unit tests.
        .args(["--stale-seconds", "0.5"])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab deploy");
    // Written at once and closed: the keys are read before the policy starts, and the end of input changes nothing.
    deploy.stdin.take().expect("stdin").write_all(b"wwwww").expect("keys");
    let (status, _, deploy_err) = wait_with_timeout(deploy, Duration::from_secs(180));
    // Stop the simulator at once: without commands it damps and the robot sits down.
    let sim_child = sim.0.take().expect("sim child");
    interrupt(&sim_child);
    let (_, _, sim_err) = wait_with_timeout(sim_child, Duration::from_secs(60));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "deploy exit\n{}\nsim:\n{}", tail(&deploy_err), tail(&sim_err));

    let d =
        summary(&deploy_err, "deploy: summary ").unwrap_or_else(|| panic!("no deploy summary:\n{}", tail(&deploy_err)));
    let s = sim_summary(&sim_err).unwrap_or_else(|| panic!("no sim summary:\n{}", tail(&sim_err)));
    eprintln!("deploy: {d}\nsim: {s}");
    assert_eq!(d["key_presses"], 5, "{d}");
    assert_eq!(d["final_command"], serde_json::json!([0.5, 0.0, 0.0]), "{d}");
    assert_eq!(d["safety_stop"], false, "{d}");
    assert_eq!(d["stop"]["reason"], "requested", "{d}");
    assert_eq!(d["counters"]["bad_crc"], 0, "{d}");
    assert_eq!(d["malformed_states"], 0, "{d}");
    let policy_steps = d["counters"]["policy_steps"].as_f64().unwrap_or(0.0);
    assert!(policy_steps >= 0.9 * WALK_S / 0.02, "50 Hz policy for {WALK_S} s: {policy_steps} steps");

    // The simulator's account: every command it received passed its CRC and limit gates.
    let c = &s["counters"];
    let sent = d["counters"]["commands"].as_f64().unwrap_or(0.0);
    assert_eq!(c["bad_crc"], 0, "{s}");
    assert_eq!(c["rejected"], 0, "{s}");
    assert_eq!(c["malformed"], 0, "{s}");
    assert!(c["accepted"].as_f64().unwrap_or(0.0) >= 0.99 * sent, "sim accepted {} of {sent}", c["accepted"]);
    // The pelvis: up throughout, walked forward at about the commanded 0.5 m/s.
    let b = &s["base"];
    let xyz = |k: &str| -> [f64; 3] { [0, 1, 2].map(|i| b[k][i].as_f64().unwrap_or(f64::NAN)) };
    let (start, end) = (xyz("start"), xyz("end"));
    let min_h = b["min_height"].as_f64().unwrap_or(0.0);
    let tilt = b["max_tilt_rad"].as_f64().unwrap_or(f64::NAN);
    assert!(min_h > 0.7, "pelvis went down to {min_h:.2} m: {b}");
    assert!(tilt < 0.5, "pelvis tilted {tilt:.2} rad: {b}");
    let (dx, dy) = (end[0] - start[0], end[1] - start[1]);
    let speed = dx / WALK_S;
    eprintln!("walked {dx:.2} m forward, {dy:.2} m sideways in {WALK_S} s: {speed:.2} m/s for 0.5 commanded");
    assert!((0.3..=0.65).contains(&speed), "forward speed {speed:.2} m/s for 0.5 commanded: {b}");
    assert!(dy.abs() < 0.25 * WALK_S, "lateral drift {dy:.2} m: {b}");
}

#[test]
fn bad_arguments_exit_2_before_sending() {
    let spec = common::root().join(SPEC);
    let spec = spec.to_str().expect("utf-8 path");
    for (args, expect) in [
        (vec!["deploy", "--policy", spec, "--domain", "0"], "--allow-robot"),
        (vec!["deploy", "--policy", spec, "--interface", "eth0"], "--allow-robot"),
        (vec!["deploy", "--policy", spec, "--command", "0.5,0"], "three finite numbers"),
        (vec!["deploy", "--policy", spec, "--command", "9,0,0"], "three finite numbers"),
        (vec!["deploy", "--policy", spec, "--rate", "5"], "--rate"),
        (vec!["deploy", "--policy", "/nonexistent.toml"], "loading policy spec"),
        (vec!["deploy", "--policy", spec, "--domain", "93", "--wait-seconds", "0.5"], "no valid LowState"),
    ] {
        let (code, out, err) = run_ulab(&args, Duration::from_secs(60));
        assert_eq!(code, Some(2), "{args:?}\n{out}\n{err}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}
