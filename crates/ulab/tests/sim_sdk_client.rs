//! `ulab sim` driven by a controller written against Unitree's official Python SDK
//! (unitree_sdk2py on Cyclone DDS 11), on loopback, with every engine:
//! * LowState arrives at >= 90 % of the set rate, every CRC valid by the SDK's own CRC code;
//! * joints commanded to targets get there, and a command with a corrupted CRC has no effect (on
//!   the engines where the robot stays up: the impulse-joint Rapier engine tips it over);
//! * LowState samples decoded by the Python Cyclone DDS serializer equal our own decode of the
//!   same wire bytes (captured here with our transport).

mod common;

use common::{python, root, tail, wait_with_timeout, KillOnDrop};
use dds_transport::{DomainConfig, Participant, TopicSpec};
use lowlevel_codec::{cdr, json};
use serde_json::Value;
use std::collections::HashMap;
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};
use unitree_idl::hg;

/// One simulator at a time: the 2-core machines cannot run two in real time.
static SERIAL: Mutex<()> = Mutex::new(());

const STATE_RATE: f64 = 500.0;

/// `may_fall`: the engine is known to tip the robot over under this client's gains.
fn check_engine(engine: &str, domain: u32, may_fall: bool) {
    let _guard = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let sim = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["sim", "--engine", engine, "--domain", &domain.to_string(), "--duration", "30", "--quiet"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab sim");
    let mut sim = KillOnDrop(Some(sim));

    // Our own raw reader on the same domain captures the wire bytes, keyed by tick.
    let participant = Participant::new(DomainConfig::loopback(domain)).expect("participant");
    let reader = participant.reader(&TopicSpec::lowstate(dds_transport::Family::Hg)).expect("reader");
    let capture = std::thread::spawn(move || {
        let mut by_tick = HashMap::new();
        let end = Instant::now() + Duration::from_secs(12);
        while Instant::now() < end {
            if let Some(s) = reader.take(Duration::from_millis(50)) {
                if let Ok(d) = cdr::decode::<hg::LowState_>(&s.data) {
                    by_tick.insert(d.value.tick, d.value);
                }
            }
        }
        by_tick
    });

    let client = Command::new(python())
        .arg(root().join("tests/clients/sdk_lowlevel_client.py"))
        .args(["--domain", &domain.to_string(), "--dump", "20"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start the Python SDK client");
    let (status, out, err) = wait_with_timeout(client, Duration::from_secs(60));
    if !status.is_some_and(|s| s.success()) {
        eprintln!("{engine}: client failed ({status:?}): {}", tail(&err));
    }
    drop(sim.0.take().map(|mut c| c.kill()));
    let report: Value = serde_json::from_str(out.lines().last().unwrap_or(""))
        .unwrap_or_else(|e| panic!("{engine}: client output ...{}: {e}", tail(&out)));
    assert!(report.get("error").is_none(), "{engine}: {}", report["error"]);

    let rate = report["rate_hz"].as_f64().expect("rate");
    assert!(rate >= 0.9 * STATE_RATE, "{engine}: LowState at {rate:.1} Hz, set {STATE_RATE}");
    assert_eq!(report["crc_ok"], report["states"], "{engine}: LowState CRCs rejected by the SDK's CRC");
    assert_eq!(report["ticks_increasing"], true, "{engine}");

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
    check_engine("mujoco", 61, false);
}

#[test]
fn python_sdk_drives_rapier_multibody() {
    check_engine("rapier-multibody", 62, false);
}

#[test]
fn python_sdk_drives_rapier_impulse() {
    check_engine("rapier-impulse", 63, true);
}

#[test]
fn python_sdk_drives_physx() {
    let domain = test_support::lease_domain();
    let _slot = test_support::RealtimeSlot::acquire();
    check_engine("physx", domain.id(), false);
}
