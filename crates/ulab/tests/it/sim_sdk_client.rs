//! `ulab sim` driven by a controller written against Unitree's official Python SDK
//! (unitree_sdk2py on Cyclone DDS 11), on loopback, with every engine:
//! * every LowState the client received has a CRC valid by the SDK's own CRC code and a tick above
//!   the previous one, and the ticks are spaced by the state period of the robot's clock (2 ms);
//! * the bridge's own account: one state per 2 ms of simulated time, the commands it received
//!   accepted or counted, nothing malformed;
//! * joints commanded to targets get there, and a command with a corrupted CRC has no effect (on
//!   the engines where the robot stays up: the impulse-joint Rapier engine tips it over);
//! * LowState samples decoded by the Python Cyclone DDS serializer equal our own decode of the
//!   same wire bytes (captured here with our transport).
//!
//! Nothing here depends on how fast the machine is (issue 21): the client's phases last spans of
//! simulated time (LowState ticks), rates are judged on the robot's clock and the bridge's counters,
//! and the wall-clock rate is only printed. Each engine holds the machine-wide real-time slot, so no
//! two simulators compete for the cores, and leases its own DDS domain.

use crate::common;

use common::{interrupt, lease_domain, python, root, sim_summary, tail, wait_with_timeout, KillOnDrop, RealtimeSlot};
use dds_transport::{DomainConfig, Participant, TopicSpec};
use lowlevel_codec::{cdr, json};
use serde_json::Value;
use std::collections::HashMap;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;
use unitree_idl::hg;

const STATE_RATE: f64 = 500.0;

/// `may_fall`: the engine is known to tip the robot over under this client's gains.
fn check_engine(engine: &str, may_fall: bool) {
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    // A generous command timeout: the client is a Python process that a loaded machine can pause for a
    // while; the default 0.1 s would put the robot into damping and test the scheduler, not the bridge.
    let sim = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["sim", "--engine", engine, "--domain", &domain.arg(), "--command-timeout", "1.0", "--quiet"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab sim");
    let mut sim = KillOnDrop(Some(sim));

    // Our own raw reader on the same domain captures the wire bytes, keyed by tick, until the client is done.
    let participant = Participant::new(DomainConfig::loopback(domain.id())).expect("participant");
    let reader = participant.reader(&TopicSpec::lowstate(dds_transport::Family::Hg)).expect("reader");
    let done = Arc::new(AtomicBool::new(false));
    let capture = {
        let done = done.clone();
        std::thread::spawn(move || {
            let mut by_tick = HashMap::new();
            while !done.load(Ordering::SeqCst) {
                if let Some(s) = reader.take(Duration::from_millis(50)) {
                    if let Ok(d) = cdr::decode::<hg::LowState_>(&s.data) {
                        by_tick.insert(d.value.tick, d.value);
                    }
                }
            }
            by_tick
        })
    };

    let client = Command::new(python())
        .arg(root().join("tests/clients/sdk_lowlevel_client.py"))
        .args(["--domain", &domain.arg(), "--dump", "20"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start the Python SDK client");
    let (status, out, err) = wait_with_timeout(client, Duration::from_secs(300));
    done.store(true, Ordering::SeqCst);
    if !status.is_some_and(|s| s.success()) {
        eprintln!("{engine}: client failed ({status:?}): {}", tail(&err));
    }
    // Stop the bridge as Ctrl-C would, so that it prints its own account.
    let sim_child = sim.0.take().expect("sim child");
    interrupt(&sim_child);
    let (_, _, sim_err) = wait_with_timeout(sim_child, Duration::from_secs(60));
    let report: Value = serde_json::from_str(out.lines().last().unwrap_or(""))
        .unwrap_or_else(|e| panic!("{engine}: client output ...{}: {e}", tail(&out)));
    assert!(report.get("error").is_none(), "{engine}: {}", report["error"]);

    // The stream as the client saw it: every CRC valid by the SDK's code, ticks strictly increasing and spaced by
    // the state period on the robot's clock (lost samples would give multiples of it; a wrong rate another gcd).
    let states = report["states"].as_u64().expect("states");
    assert!(states >= 20, "{engine}: only {states} LowState samples in the client's window");
    assert_eq!(report["crc_ok"], report["states"], "{engine}: LowState CRCs rejected by the SDK's CRC");
    assert_eq!(report["ticks_increasing"], true, "{engine}");
    let period_ms = 1000.0 / STATE_RATE;
    assert_eq!(
        report["tick_gcd_ms"].as_f64(),
        Some(period_ms),
        "{engine}: LowState ticks not spaced by {period_ms} ms"
    );
    // The bridge's own account: one state per period of simulated time, every command accounted for.
    let summary =
        sim_summary(&sim_err).unwrap_or_else(|| panic!("{engine}: no summary from ulab sim:\n{}", tail(&sim_err)));
    let c = &summary["counters"];
    let simulated = summary["simulated_seconds"].as_f64().expect("simulated_seconds");
    let published = c["states_published"].as_f64().expect("states_published");
    assert!(
        (published / simulated - STATE_RATE).abs() <= 0.01 * STATE_RATE,
        "{engine}: {published} states in {simulated:.2} s of simulated time, set {STATE_RATE} Hz"
    );
    assert_eq!(c["malformed"], 0, "{engine}: {summary}");
    assert_eq!(c["rejected"], 0, "{engine}: {summary}");
    assert!(c["bad_crc"].as_u64().is_some_and(|n| n > 0), "{engine}: corrupted commands never counted: {summary}");
    let wall = summary["wall_seconds"].as_f64().unwrap_or(f64::NAN);
    eprintln!(
        "{engine}: {states} states in the client's window at {:.1} Hz wall ({:.2}x real time over the run); {summary}",
        report["rate_hz"].as_f64().unwrap_or(f64::NAN),
        simulated / wall
    );
    for phase in ["hold_sim_seconds", "corrupt_sim_seconds"] {
        assert!(report[phase].as_f64().is_some_and(|s| s >= 1.0), "{engine}: {phase} {} (stalled?)", report[phase]);
    }

    // Python's decode of the bridge's samples equals ours, field by field, bit for bit.
    let ours = capture.join().expect("capture thread");
    let samples = report["samples"].as_array().expect("samples");
    let mut compared = 0;
    for sample in samples {
        let tick = sample["tick"].as_u64().expect("tick") as u32;
        let Some(own) = ours.get(&tick) else { continue };
        let theirs: hg::LowState_ =
            json::value_from_json(sample).unwrap_or_else(|e| panic!("{engine}: python sample: {e}"));
        assert_eq!(
            cdr::encode(&theirs, lowlevel_codec::Encoding::UNITREE),
            cdr::encode(own, lowlevel_codec::Encoding::UNITREE),
            "{engine}: tick {tick}"
        );
        compared += 1;
    }
    assert!(compared >= 10, "{engine}: only {compared} samples matched by tick");

    // Known engine difference (issue 5 material): under this client's gains the impulse-joint Rapier engine tips
    // over backwards where MuJoCo and Rapier multibody stand. A robot lying on its back can rest its arms on the
    // ground, so where it fell (only allowed for that engine) the joint-space checks below would test the contact,
    // not the bridge: they are skipped there, and the state-stream and decode checks above still apply.
    let rpy = report["rpy_after_moves"].as_array().expect("rpy");
    let upright = rpy.iter().take(2).all(|a| a.as_f64().is_some_and(|a| a.abs() < 0.3));
    if !upright {
        assert!(may_fall, "{engine}: the robot fell (torso rpy {rpy:?}); it stands on this engine");
        eprintln!(
            "{engine}: robot fell (torso rpy {rpy:?}); joint tracking and corrupted-CRC checks skipped on this engine"
        );
        return;
    }
    // Arm joints with kp 120: gravity on the arm (< 5 N·m) and joint friction (0.2 N·m) leave
    // at most ~0.05 rad of steady-state error; 0.08 allows for the motion still settling.
    for m in report["moves"].as_array().expect("moves") {
        let (target, fin) = (m["target"].as_f64().expect("t"), m["final"].as_f64().expect("f"));
        assert!((fin - target).abs() < 0.08, "{engine}: slot {} ended at {fin:.3}, target {target:.3}", m["slot"]);
    }
    let c = &report["corrupted"];
    let (held, bad, fin) = (
        c["held_target"].as_f64().expect("h"),
        c["corrupt_target"].as_f64().expect("c"),
        c["final"].as_f64().expect("f"),
    );
    assert!(
        (fin - held).abs() < 0.08 && (fin - bad).abs() > 0.5,
        "{engine}: corrupted-CRC command moved the elbow to {fin:.3} (held {held:.3}, corrupt {bad:.3})"
    );
}

#[test]
fn python_sdk_drives_mujoco() {
    check_engine("mujoco", false);
}

#[test]
fn python_sdk_drives_rapier_multibody() {
    check_engine("rapier-multibody", false);
}

#[test]
fn python_sdk_drives_rapier_impulse() {
    check_engine("rapier-impulse", true);
}

#[test]
fn python_sdk_drives_bullet() {
    check_engine("bullet", false);
}

#[test]
fn python_sdk_drives_dart() {
    check_engine("dart", false);
}

// PhysX is opt-in (`--features physx`, `scripts/nightly.sh`): its SDK build does not fit the CI budget.
#[cfg(feature = "physx")]
#[test]
fn python_sdk_drives_physx() {
    check_engine("physx", false);
}
