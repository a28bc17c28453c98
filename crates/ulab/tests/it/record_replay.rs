//! `ulab record`, `ulab replay` and `ulab log export` against Cyclone DDS 11 peers (Python):
//! a session published by the Python peer is recorded, read back with the official Python
//! `mcap` package (every message decoded by the Cyclone serializer), replayed to a Python
//! subscriber with its original timing, and exported to CSV.
//!
//! Nothing depends on the machine's speed (issue 21): publishers start only once the recorder's reader has
//! matched, the recorder is stopped as Ctrl-C would once they are done, the replayer waits for its subscriber,
//! and DDS domains are leased (`test-support`).

#[path = "../../../dds-transport/tests/it/common.rs"]
mod common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;
use test_support::{lease_domain, RealtimeSlot};

fn ulab() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ulab"))
}

fn py_peer() -> Command {
    let mut c = Command::new(python());
    c.arg(workspace_dir().join("crates/dds-transport/tests/peers/py11/peer.py"));
    c
}

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ulab-record-tests");
    let _ = std::fs::create_dir_all(&d);
    let p = d.join(name);
    let _ = std::fs::remove_file(&p);
    let _ = std::fs::remove_dir_all(&p);
    p
}

fn read_mcap(path: &Path) -> serde_json::Value {
    let (ok, out, err) = run_with_timeout(
        Command::new(python()).arg(crate_dir().join("tests/py/read_mcap.py")).arg(path),
        Duration::from_secs(60),
    );
    assert!(ok, "Python mcap reader failed:\n{out}\n{err}");
    serde_json::from_str(&out).expect("reader prints JSON")
}

/// The publisher's `ready` event said its writer had matched a reader (the recorder's) before it published.
fn assert_matched(out: &str) {
    let ready = out
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|j| j["event"] == "ready")
        .unwrap_or_else(|| panic!("publisher printed no ready event:\n{out}"));
    assert_eq!(ready["matched"], true, "the publisher started before the recorder's reader matched:\n{out}");
}

/// Records a session (LowState at 100 Hz with one outage, LowCmd at 50 Hz) on `domain`. The publishers wait (up
/// to a generous minute) for the recorder's readers before they publish; the recorder is then stopped as Ctrl-C
/// would, so that nothing depends on how long a loaded machine takes to start the processes.
fn record_session(domain: u32, out: &Path) -> String {
    let d = domain.to_string();
    let rec = Proc::spawn(ulab().args(["record", "--domain", &d, "--out"]).arg(out));
    let st = Proc::spawn(py_peer().args([
        "pub-lowstate",
        "--domain",
        &d,
        "--count",
        "200",
        "--rate",
        "100",
        "--gap-at",
        "120",
        "--match-timeout",
        "60",
    ]));
    let cmd = Proc::spawn(py_peer().args([
        "pub-lowcmd",
        "--domain",
        &d,
        "--count",
        "60",
        "--rate",
        "50",
        "--match-timeout",
        "60",
    ]));
    let (c1, o1, e1) = st.wait(Duration::from_secs(120));
    let (c2, o2, e2) = cmd.wait(Duration::from_secs(120));
    assert_eq!(c1, Some(0), "publisher failed:\n{o1}\n{e1}");
    assert_eq!(c2, Some(0), "publisher failed:\n{o2}\n{e2}");
    assert_matched(&o1);
    assert_matched(&o2);
    let (ok, o, e) =
        run_with_timeout(Command::new("kill").args(["-INT", &rec.id().to_string()]), Duration::from_secs(5));
    assert!(ok, "{o}\n{e}");
    let (code, stdout, stderr) = rec.wait(Duration::from_secs(60));
    assert_eq!(code, Some(0), "ulab record failed:\n{stdout}\n{stderr}");
    stdout
}

#[test]
fn record_then_read_with_python_mcap_then_replay_then_export() {
    let _slot = RealtimeSlot::acquire();
    let file = tmp("session.mcap");
    let report = record_session(lease_domain().id(), &file);

    // The report counts messages and finds the outage (tick jump + arrival gap).
    assert!(report.contains("rt/lowstate: 200 messages") || report.contains("rt/lowstate: 199 messages"), "{report}");
    assert!(report.contains("tick step 2, 1 tick jumps, about 15 samples missing by tick"), "{report}");
    assert!(report.contains("gap: tick jump 240 -> 272"), "{report}");
    assert!(report.contains("gap: arrival gap of"), "{report}");

    // Python mcap reader: schemas, channels, every message decodes with Cyclone's serializer.
    let v = read_mcap(&file);
    assert_eq!(v["errors"].as_array().map(Vec::len), Some(0), "{v}");
    let st = &v["topics"]["rt/lowstate"];
    let n_state = st["count"].as_u64().expect("count");
    assert!(n_state >= 199, "{n_state}");
    let ticks: Vec<u64> = st["ticks"].as_array().expect("ticks").iter().filter_map(|t| t.as_u64()).collect();
    assert_eq!(ticks.len() as u64, n_state);
    assert!(ticks.windows(2).all(|w| w[1] > w[0]), "ticks increase");
    assert_eq!(ticks.last(), Some(&430));
    assert!(v["topics"]["rt/lowcmd"]["count"].as_u64().expect("count") >= 59);
    assert_eq!(st["publish_le_log"], true);
    let schema = &v["schemas"]["unitree_hg::msg::dds_::LowState_"];
    assert_eq!(schema["encoding"], "omgidl");
    assert!(schema["idl"].as_str().expect("idl").contains("struct LowState_"));
    assert_eq!(v["channels"]["rt/lowstate"]["encoding"], "cdr");
    assert!(v["metadata"]["ulab.record"]["report"].as_str().expect("report").contains("tick jump"));

    // Replay at 2x to a Python subscriber: everything arrives, in order, in about half the time. The replayer
    // waits (up to a minute) for the subscriber before it starts.
    let replay_domain = lease_domain();
    let sub = Proc::spawn(
        py_peer()
            .args(["sub", "--domain", &replay_domain.arg(), "--topic", "rt/lowstate", "--seconds", "120", "--count"])
            .arg(n_state.to_string()),
    );
    let (ok, out, err) = run_with_timeout(
        ulab().arg("replay").arg(&file).args([
            "--domain",
            &replay_domain.arg(),
            "--speed",
            "2",
            "--topics",
            "rt/lowstate",
            "--wait-readers",
            "60",
        ]),
        Duration::from_secs(120),
    );
    assert!(ok, "ulab replay failed:\n{out}\n{err}");
    assert!(out.contains(&format!("rt/lowstate: {n_state} messages sent")), "{out}");
    let (code, sub_out, sub_err) = sub.wait(Duration::from_secs(120));
    assert_eq!(code, Some(0), "{sub_out}\n{sub_err}");
    let samples: Vec<serde_json::Value> = sub_out
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|j| j["event"] == "sample")
        .collect();
    assert_eq!(samples.len() as u64, n_state, "subscriber got every replayed sample");
    let got: Vec<u64> = samples.iter().filter_map(|s| s["tick"].as_u64()).collect();
    assert_eq!(got, ticks, "same samples, same order");
    let t0 = samples[0]["t"].as_f64().expect("t");
    let t1 = samples[samples.len() - 1]["t"].as_f64().expect("t");
    let logs: Vec<u64> = st["log_times"].as_array().expect("log times").iter().filter_map(|t| t.as_u64()).collect();
    let recorded_span = (logs[logs.len() - 1] - logs[0]) as f64 / 1e9;
    let replay_span = t1 - t0;
    // Never early (a replayer that ignored the timing would send everything at once; load can only make it
    // later), and clearly faster than at speed 1 (a 1 s light replay is not stretched by a busy core).
    assert!(
        replay_span >= recorded_span / 2.0 - 0.05 && replay_span < 0.85 * recorded_span,
        "replay span {replay_span:.3} s vs recorded {recorded_span:.3} s at speed 2"
    );

    // CSV export: one row per message, named columns, values from our codec.
    let dir = tmp("session_csv");
    let (ok, out, err) = run_with_timeout(
        ulab().args(["log", "export"]).arg(&file).args(["--format", "csv", "--out"]).arg(&dir),
        Duration::from_secs(30),
    );
    assert!(ok, "export failed:\n{out}\n{err}");
    let csv = std::fs::read_to_string(dir.join("rt_lowstate.csv")).expect("csv");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let tick_col = header.iter().position(|c| *c == "tick").expect("tick column");
    assert!(header.contains(&"motor_state[34].tau_est") && header.contains(&"imu_state.quaternion[0]"));
    let csv_ticks: Vec<u64> =
        lines.map(|l| l.split(',').nth(tick_col).and_then(|t| t.parse().ok()).expect("tick")).collect();
    assert_eq!(csv_ticks, ticks);
    let cmd_csv = std::fs::read_to_string(dir.join("rt_lowcmd.csv")).expect("csv");
    assert!(cmd_csv.lines().next().expect("header").contains("motor_cmd[0].kp"));
}

#[test]
fn ctrl_c_finishes_the_file() {
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let file = tmp("interrupted.mcap");
    let rec = Proc::spawn(ulab().args(["record", "--domain", &domain.arg(), "--out"]).arg(&file));
    let pid = rec.id();
    let (ok, o, e) = run_with_timeout(
        py_peer().args([
            "pub-lowstate",
            "--domain",
            &domain.arg(),
            "--count",
            "100",
            "--rate",
            "100",
            "--match-timeout",
            "60",
        ]),
        Duration::from_secs(120),
    );
    assert!(ok, "{o}\n{e}");
    assert_matched(&o);
    let (ok, o, e) = run_with_timeout(Command::new("kill").args(["-INT", &pid.to_string()]), Duration::from_secs(5));
    assert!(ok, "{o}\n{e}");
    let (code, out, err) = rec.wait(Duration::from_secs(60));
    assert_eq!(code, Some(0), "{out}\n{err}");
    let v = read_mcap(&file);
    assert!(v["topics"]["rt/lowstate"]["count"].as_u64().expect("count") >= 99, "{v}");
    assert!(v["message_count"].as_u64().expect("summary statistics present") >= 99);
}

#[test]
fn refuses_the_robot_network_without_the_flag() {
    let file = tmp("never.mcap");
    for args in [["--domain", "0", "--interface", "lo"], ["--domain", "5", "--interface", "eth0"]] {
        let (ok, out, err) = run_with_timeout(
            ulab().arg("record").args(args).args(["--duration", "1", "--out"]).arg(&file),
            Duration::from_secs(20),
        );
        assert!(!ok, "{out}");
        assert!(err.contains("allow_robot") || err.contains("allow-robot"), "{err}");
        assert!(!file.exists());
    }
}
