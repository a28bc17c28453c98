//! Crash safety of `ulab record` (issue 19, item 4): a recorder killed with SIGKILL while `ulab sim` publishes
//! rt/lowstate at 500 Hz leaves an unfinished file; the official Python `mcap` streaming reader (independent code)
//! reads it up to the cut; `ulab log recover` copies exactly those messages into a finished file that the official
//! reader opens with its summary; and no more than one chunk was lost.
use crate::common;

use common::{lease_domain, python, root, run_ulab, tail, wait_with_timeout, KillOnDrop, PATIENCE};
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Chunk size given to the recorder: 64 KiB, about 31 hg LowState samples (~2.1 KiB each, ~0.06 s at 500 Hz).
const CHUNK: u64 = 64 * 1024;

fn python_json(script: &str, file: &Path) -> Value {
    let child = Command::new(python())
        .arg(root().join("crates/ulab/tests/py").join(script))
        .arg(file)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn python");
    let (status, out, err) = wait_with_timeout(child, Duration::from_secs(120));
    assert!(status.is_some_and(|s| s.success()), "{script} failed:\n{}\n{}", tail(&out), tail(&err));
    serde_json::from_str(out.lines().last().unwrap_or("")).expect("the script prints JSON")
}

/// `ulab sim` (MuJoCo, LowState at 500 Hz) on the leased domain, killed when the guard drops.
fn start_sim(domain: &test_support::DomainLease) -> KillOnDrop {
    let sim = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["sim", "--engine", "mujoco", "--domain", &domain.arg(), "--loco-api", "none", "--quiet"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start ulab sim");
    KillOnDrop(Some(sim))
}

#[test]
fn a_killed_recording_is_readable_up_to_its_last_chunk_and_recovers() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ulab-record-crash");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    let file = dir.join("killed.mcap");
    let domain = lease_domain();
    let _sim = start_sim(&domain);
    let rec = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["record", "--domain", &domain.arg(), "--quiet", "--chunk-size", &CHUNK.to_string(), "--out"])
        .arg(&file)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start ulab record");
    let mut rec = KillOnDrop(Some(rec));
    // Kill once the file holds several chunks (judged by its size, not by the clock: a slow machine only waits longer).
    let deadline = Instant::now() + PATIENCE;
    while std::fs::metadata(&file).map_or(0, |m| m.len()) < 6 * CHUNK {
        assert!(Instant::now() < deadline, "the recorder wrote {:?} bytes", std::fs::metadata(&file).map(|m| m.len()));
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_millis(137)); // somewhere inside a chunk
    let mut child = rec.0.take().expect("recorder");
    child.kill().expect("SIGKILL");
    let _ = child.wait();
    let size = std::fs::metadata(&file).expect("killed file").len();

    // The official streaming reader on the killed file: messages up to the cut, then an error (no footer).
    let killed = python_json("count_mcap_stream.py", &file);
    let readable = killed["messages"].as_u64().expect("count");
    assert!(killed["error"].is_string(), "an unfinished file ends in an error: {killed}");
    // At most the chunk being filled was lost (the `mcap` writer streams a chunk into the file with a placeholder
    // length and patches it when the chunk is complete, so an unfinished chunk is unreadable as a whole), plus the
    // recorder's 8 KiB output buffer, which never reached the file.
    let lowstate = killed["per_topic"]["rt/lowstate"].as_u64().unwrap_or(0);
    let readable_bytes = killed["readable_bytes"].as_u64().unwrap_or(0);
    assert!(
        lowstate > 0 && size - readable_bytes <= CHUNK + 4096,
        "{size} bytes, readable up to {readable_bytes}: {killed}"
    );

    let out = dir.join("recovered.mcap");
    let (code, stdout, stderr) =
        run_ulab(&["log", "recover", file.to_str().expect("utf-8"), "--out", out.to_str().expect("utf-8")], PATIENCE);
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    assert!(stderr.contains("truncated"), "{stderr}");
    // The copy is a finished file: the official reader opens it through its summary and decodes every message
    // with Unitree's types; it holds exactly what could be read before the cut.
    let v = python_json("read_mcap.py", &out);
    assert_eq!(v["errors"].as_array().map(Vec::len), Some(0), "{}", v["errors"]);
    assert_eq!(v["message_count"].as_u64(), Some(readable), "{v}");
    assert_eq!(v["topics"]["rt/lowstate"]["count"].as_u64(), Some(lowstate));
    let ticks: Vec<u64> =
        v["topics"]["rt/lowstate"]["ticks"].as_array().expect("ticks").iter().filter_map(Value::as_u64).collect();
    assert!(ticks.windows(2).all(|w| w[1] > w[0]), "ticks increase: nothing reordered or duplicated");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn recover_refuses_what_is_not_mcap() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ulab-record-crash-bad");
    std::fs::create_dir_all(&dir).expect("temp dir");
    let bad = dir.join("not.mcap");
    std::fs::write(&bad, b"definitely not an mcap file").expect("write");
    let (code, _, err) = run_ulab(&["log", "recover", bad.to_str().expect("utf-8")], Duration::from_secs(60));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("not an MCAP file") && !err.contains("panicked"), "{err}");
}

/// `--split-minutes`: a long recording becomes finished, indexed files (what keeps the recorder's memory bounded);
/// the official reader opens each through its summary, and together they hold every sample the recorder counted,
/// in order, none twice.
#[test]
fn a_split_recording_loses_nothing_at_the_seams() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ulab-record-split");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    let domain = lease_domain();
    let _sim = start_sim(&domain);
    let out = dir.join("run.mcap");
    // A new file every 0.9 s for 4 s: four or five files (the first may start before the simulator publishes).
    let (code, stdout, stderr) = run_ulab(
        &[
            "record",
            "--domain",
            &domain.arg(),
            "--quiet",
            "--topics",
            "rt/lowstate",
            "--duration",
            "4",
            "--split-minutes",
            "0.015",
            "--out",
            out.to_str().expect("utf-8"),
        ],
        PATIENCE,
    );
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    assert!(!out.exists(), "with --split-minutes OUT itself is not written");
    // The recorder's own count of what it received and stored.
    let counted: u64 = stdout
        .lines()
        .find_map(|l| l.strip_prefix("rt/lowstate: ")?.split(' ').next()?.parse().ok())
        .unwrap_or_else(|| panic!("no rt/lowstate count in the report:\n{stdout}"));
    let mut files = Vec::new();
    for i in 0.. {
        let f = dir.join(format!("run_{i:03}.mcap"));
        if !f.exists() {
            break;
        }
        files.push(f);
    }
    assert!(files.len() >= 4, "{} files: {files:?}", files.len());
    let (mut total, mut ticks) = (0u64, Vec::new());
    for f in &files {
        let v = python_json("read_mcap.py", f);
        assert_eq!(v["errors"].as_array().map(Vec::len), Some(0), "{}: {}", f.display(), v["errors"]);
        let n = v["topics"]["rt/lowstate"]["count"].as_u64().unwrap_or(0);
        // Finished and indexed: the summary's statistics agree with the messages read.
        assert_eq!(v["message_count"].as_u64(), Some(n), "{}: {v}", f.display());
        total += n;
        ticks.extend(v["topics"]["rt/lowstate"]["ticks"].as_array().expect("ticks").iter().filter_map(Value::as_u64));
        assert!(v["metadata"]["ulab.record"]["segment"].is_string(), "{}: segment metadata", f.display());
    }
    assert!(counted > 1000, "the simulator published too little ({counted})");
    assert_eq!(total, counted, "the files hold {total} LowState, the recorder stored {counted}");
    assert!(ticks.windows(2).all(|w| w[1] > w[0]), "ticks increase across the files: nothing reordered or duplicated");
    let last = python_json("read_mcap.py", files.last().expect("files"));
    assert!(last["metadata"]["ulab.record"]["report"].is_string(), "the last file carries the report");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Records rt/lowstate from a running simulator for `seconds`, stopping the recorder (SIGSTOP) for `stall`
/// seconds in the middle; returns the LowState missing by tick (the official reader reads the file).
fn stalled_recording(dir: &Path, domain: &test_support::DomainLease, stall: f64, socket_buffer: u64) -> u64 {
    let file = dir.join(format!("stalled-{socket_buffer}.mcap"));
    let seconds = stall + 4.0;
    let rec = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["record", "--domain", &domain.arg(), "--quiet", "--topics", "rt/lowstate", "--force"])
        .args(["--duration", &seconds.to_string(), "--socket-buffer", &socket_buffer.to_string(), "--out"])
        .arg(&file)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start ulab record");
    let pid = rec.id().to_string();
    let rec = KillOnDrop(Some(rec));
    std::thread::sleep(Duration::from_secs(2));
    let signal = |s: &str| Command::new("kill").args([s, &pid]).status().expect("kill").success();
    assert!(signal("-STOP"), "SIGSTOP");
    std::thread::sleep(Duration::from_secs_f64(stall));
    assert!(signal("-CONT"), "SIGCONT");
    let mut rec = rec;
    let (status, _, err) = wait_with_timeout(rec.0.take().expect("recorder"), PATIENCE);
    assert!(status.is_some_and(|s| s.success()), "recorder: {}", tail(&err));
    let v = python_json("read_mcap.py", &file);
    let ticks: Vec<u64> =
        v["topics"]["rt/lowstate"]["ticks"].as_array().expect("ticks").iter().filter_map(Value::as_u64).collect();
    assert!(ticks.len() > 1000, "{} LowState", ticks.len());
    // Ticks are milliseconds of simulated time, +2 per state.
    ticks.windows(2).map(|w| (w[1].saturating_sub(w[0]) / 2).saturating_sub(1)).sum()
}

/// A recorder descheduled for a while (a loaded machine, a debugger, a laptop's power management) finds the
/// samples of that while in its socket's receive buffer: `--socket-buffer` (default 8 MiB, capped by the kernel's
/// net.core.rmem_max) decides how long it can be away without losing any. Measured on loopback (BENCHMARKS.md):
/// about 0.95 s of hg LowState at 500 Hz per MiB granted; Cyclone's default 1 MiB loses samples from a 1-s stall.
#[test]
fn a_stalled_recorder_loses_nothing_its_socket_buffer_can_hold() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ulab-record-stall");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    let domain = lease_domain();
    let _sim = start_sim(&domain);
    std::thread::sleep(Duration::from_secs(1));
    // What the kernel grants of the default request, and the stall it should hold with a wide margin.
    let rmem_max: u64 = std::fs::read_to_string("/proc/sys/net/core/rmem_max")
        .ok()
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or(212_992);
    let granted = rmem_max.min(8 << 20);
    let held_s = granted as f64 / (1u64 << 20) as f64 * 0.95;
    let stall = (0.5 * held_s).min(1.5);
    // Control: a 64-KiB buffer holds ~0.06 s, so the same stall loses samples: the measurement can fail.
    let lost_small = stalled_recording(&dir, &domain, stall.max(0.5), 64 * 1024);
    assert!(lost_small > 10, "a 64-KiB socket buffer lost only {lost_small} LowState over a {stall:.2}-s stall");
    if held_s < 1.0 {
        eprintln!("net.core.rmem_max is {rmem_max} bytes: too small to show the default buffer holding a stall");
        return;
    }
    let lost = stalled_recording(&dir, &domain, stall, 8 << 20);
    eprintln!("{stall:.2}-s stall: {lost} LowState lost with the default buffer, {lost_small} with 64 KiB");
    assert_eq!(lost, 0, "the default socket buffer lost LowState over a {stall:.2}-s stall (rmem_max {rmem_max})");
    let _ = std::fs::remove_dir_all(&dir);
}
