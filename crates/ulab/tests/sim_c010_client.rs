//! `ulab sim` driven by a controller on Cyclone DDS **0.10.2** (Debian's libddsc, the version
//! inside Unitree's C++ SDK and on the robots), written in C against idlc-generated hg types
//! (tests/clients/c010/sim_client.c), on loopback, with MuJoCo and with PhysX:
//! * the 0.10.2 participant, configured like Unitree SDK2 (interface only), discovers the bridge;
//! * LowState arrives at >= 90 % of the set rate, every CRC valid by a C implementation of
//!   Unitree's CRC over the idlc C struct, every value finite, ticks increasing;
//! * a joint commanded to a target gets there (so the bridge accepted CRCs sealed in C);
//! * a command with a corrupted CRC has no effect, and the bridge counts it as bad-CRC;
//! * the 0.10.2 client neither crashes nor logs `invalid type object` (its reaction to the
//!   XTypes type information a Cyclone 11 participant sends by default).
//!
//! Needs `make`, a C compiler, Debian's cyclonedds-dev and cyclonedds-tools (idlc) 0.10.2.

mod common;

use common::{root, wait_with_timeout, KillOnDrop};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

/// One simulator at a time: the 2-core machines cannot run two in real time.
static SERIAL: Mutex<()> = Mutex::new(());

/// DDS domain of this test (distinct from every other test's).
const DOMAIN: u32 = 71;
const STATE_RATE: f64 = 500.0;
/// How long the bridge runs; the client needs about 8 s after discovery.
const SIM_SECONDS: u32 = 13;

/// Builds the C client once per test binary, into cargo's per-target scratch directory.
fn client_binary() -> PathBuf {
    static CLIENT: OnceLock<PathBuf> = OnceLock::new();
    CLIENT
        .get_or_init(|| {
            let src = root().join("tests/clients/c010");
            let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("c010-sim-client");
            let child = Command::new("make")
                .arg("-s")
                .arg("-f")
                .arg(src.join("Makefile"))
                .arg(format!("OUT={}", out.display()))
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .expect("run make (needs make and a C compiler)");
            let (status, stdout, stderr) = wait_with_timeout(child, Duration::from_secs(120));
            assert!(
                status.is_some_and(|s| s.success()),
                "building the Cyclone 0.10.2 client failed (needs Debian's cyclonedds-dev and cyclonedds-tools):\n{stdout}\n{stderr}"
            );
            out.join("sim_client")
        })
        .clone()
}

/// The number after `key ` in the bridge's final status line.
fn counter(line: &str, key: &str) -> u64 {
    let pat = format!("{key} ");
    let at = line.find(&pat).unwrap_or_else(|| panic!("`{key}` not in {line:?}")) + pat.len();
    line[at..]
        .split_whitespace()
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("`{key}` value in {line:?}"))
}

/// One run of the 0.10.2 client against `ulab sim --engine <engine>` on `domain`.
fn drive(engine: &str, domain: u32) {
    let _guard = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let client_bin = client_binary();
    let sim = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args([
            "sim",
            "--engine",
            engine,
            "--domain",
            &domain.to_string(),
            "--duration",
            &SIM_SECONDS.to_string(),
            "--quiet",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab sim");
    let mut sim = KillOnDrop(Some(sim));

    let client = Command::new(&client_bin)
        .args([&domain.to_string(), "lo"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start the 0.10.2 client");
    let (status, out, err) = wait_with_timeout(client, Duration::from_secs(45));
    let all = format!("{out}\n{err}");
    // The 0.10.2 failure mode with a Cyclone 11 peer: this log line, then a segfault.
    assert!(!all.contains("invalid type object"), "0.10.2 client rejected type information:\n{all}");
    assert!(status.is_some_and(|s| s.success()), "0.10.2 client did not exit cleanly ({status:?}):\n{all}");

    // Let the bridge finish its --duration: it must exit 0 and report its counters.
    let sim_child = sim.0.take().expect("sim child");
    let (sim_status, _, sim_err) = wait_with_timeout(sim_child, Duration::from_secs(u64::from(SIM_SECONDS) + 20));
    assert!(sim_status.is_some_and(|s| s.success()), "ulab sim failed ({sim_status:?}):\n{sim_err}");
    assert!(!sim_err.contains("panicked"), "{sim_err}");

    let line =
        out.lines().rev().find_map(|l| l.strip_prefix("RESULT ")).unwrap_or_else(|| panic!("no RESULT line:\n{all}"));
    let r: Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("RESULT is not JSON ({e}): {line}"));
    assert!(r.get("error").is_none(), "{}\n{all}", r["error"]);
    assert_eq!(r["version"], "0.10.2", "the client must run on Cyclone DDS 0.10.2");

    let rate = r["rate_hz"].as_f64().expect("rate_hz");
    assert!(rate >= 0.9 * STATE_RATE, "LowState at {rate:.1} Hz, set {STATE_RATE}");
    let states = r["states"].as_i64().expect("states");
    assert!(states > 0);
    assert_eq!(r["crc_ok"].as_i64(), Some(states), "LowState CRCs rejected by the C implementation of Unitree's CRC");
    assert_eq!(r["total_crc_bad"].as_i64(), Some(0), "a LowState with a bad CRC during the run");
    assert_eq!(r["total_nonfinite"].as_i64(), Some(0), "a LowState with non-finite values");
    assert_eq!(r["ticks_increasing"], true);
    assert_eq!(r["tick_regressions"].as_i64(), Some(0));
    assert_eq!(r["mode_machine"].as_u64(), Some(u64::from(unitree_idl::h1_2::MODE_MACHINE)));

    // The robot must still stand for joint tracking to mean anything.
    let rpy: Vec<f64> = r["rpy"].as_array().expect("rpy").iter().map(|v| v.as_f64().unwrap_or(f64::NAN)).collect();
    assert!(rpy.iter().all(|a| a.abs() < 0.3), "robot fell: rpy {rpy:?}");
    // Left elbow, kp 120: steady-state error from gravity and friction stays below ~0.05 rad.
    let m = &r["move"];
    let (start, target, fin) = (
        m["start"].as_f64().expect("start"),
        m["target"].as_f64().expect("target"),
        m["final"].as_f64().expect("final"),
    );
    assert!((fin - target).abs() < 0.08, "elbow ended at {fin:.3}, target {target:.3} (start {start:.3})");
    let c = &r["corrupted"];
    let (held, bad, fin) = (
        c["held_target"].as_f64().expect("held"),
        c["corrupt_target"].as_f64().expect("corrupt"),
        c["final"].as_f64().expect("final"),
    );
    assert!(
        (fin - held).abs() < 0.08 && (fin - bad).abs() > 0.5,
        "corrupted-CRC command moved the elbow to {fin:.3} (held {held:.3}, corrupt {bad:.3})"
    );

    // The bridge's own account: the C-sealed commands were accepted (its Rust CRC agrees with
    // ours in C), the corrupted ones counted as bad CRC, nothing else. Loopback may lose a few
    // best-effort samples, hence the 90 % floor; more than sent would be a counting bug.
    let summary = sim_err
        .lines()
        .rev()
        .find(|l| l.contains("cmds received"))
        .unwrap_or_else(|| panic!("no summary line:\n{sim_err}"));
    let valid = r["valid_writes"].as_u64().expect("valid_writes");
    let corrupt = r["corrupt_writes"].as_u64().expect("corrupt_writes");
    let (accepted, bad_crc) = (counter(summary, "accepted"), counter(summary, "bad-crc"));
    assert!(
        accepted * 10 >= valid * 9 && accepted <= valid,
        "accepted {accepted} of {valid} valid commands: {summary}"
    );
    assert!(
        bad_crc * 10 >= corrupt * 9 && bad_crc <= corrupt,
        "bad-crc {bad_crc} of {corrupt} corrupted commands: {summary}"
    );
    assert_eq!((counter(summary, "rejected"), counter(summary, "malformed")), (0, 0), "{summary}");
    eprintln!(
        "{engine}, 0.10.2 client: {rate:.1} Hz, {states} states, elbow {start:.3} -> {target:.3} reached {:.3}; {summary}",
        m["final"]
    );
}

#[test]
fn cyclone_0_10_2_client_drives_mujoco() {
    drive("mujoco", DOMAIN);
}

#[test]
fn cyclone_0_10_2_client_drives_physx() {
    let domain = test_support::lease_domain();
    let _slot = test_support::RealtimeSlot::acquire();
    drive("physx", domain.id());
}
