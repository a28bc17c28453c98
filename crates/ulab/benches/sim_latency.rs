//! Benchmark of the simulator bridge `ulab sim` (issue 7, item 6), per engine:
//! * command-to-state latency at 500 Hz LowState, real-time mode: a LowCmd published until the
//!   first LowState that reflects it, p50/p99;
//! * CPU use of the bridge process in real-time mode (utime + stime from /proc/PID/stat);
//! * real-time factor at dt = 2 ms with `--fast`.
//!
//!   source scripts/env.sh && cargo bench -p ulab --bench sim_latency [-- ENGINE...]
//!
//! How a command is recognised in LowState: the bridge does not echo reserve fields, but it
//! reports the torque it applied as `tau_est`. Every probe command sets, on one motor in mode 1
//! with kp = kd = 0, a feed-forward torque that no other probe uses; the PD law then applies
//! exactly `tau_ff` (0 * error adds nothing) and LowState carries it bit for bit. The other 26
//! joints hold the standing pose. Probes go out at 500 Hz, like a controller's loop, each at a
//! random point of its 2 ms slot (the bridge steps on its own clock). When two probes reach the
//! bridge between the same two physics steps, only the newer is applied (latest command wins,
//! as on the robot); the older one's latency is then taken to the first LowState reflecting the
//! newer one, which is the first state computed after the bridge took the older one in.
//!
//! Prints a markdown table (ratios against the targets) for BENCHMARKS.md.

mod common;

use common::{clock_ticks, collect_stderr, cpu_seconds, loadavg, percentile, wait_bounded, Killed};
use dds_transport::{DomainConfig, Family, Participant, TopicSpec};
use lowlevel_codec::{cdr, crc, Encoding};
use rand::{Rng, SeedableRng};
use std::collections::HashMap;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use unitree_idl::{h1_2, hg};

const ENGINES: [&str; 4] = ["mujoco", "rapier-multibody", "rapier-impulse", "physx"];
const STATE_RATE: f64 = 500.0;
/// Probe motor: left wrist yaw (slot 19), a light joint far from the balance.
const PROBE: usize = 19;
const WARMUP_S: f64 = 1.5;
const PROBE_S: f64 = 10.0;
const FAST_S: f64 = 6.0;
/// Targets from the issue.
const P99_TARGET_MS: f64 = 1.0 + 1000.0 / STATE_RATE;
const RTF_TARGET_MUJOCO: f64 = 5.0;

fn ulab() -> &'static str {
    env!("CARGO_BIN_EXE_ulab")
}

struct Latency {
    p50_ms: f64,
    p99_ms: f64,
    max_ms: f64,
    probes: usize,
    superseded: usize,
    unresolved: usize,
    state_hz: f64,
    cpu_pct: f64,
}

/// Feed-forward torque of probe `k`: distinct f32 values in [0.5, 2.3] N·m for k < 18000.
fn probe_tau(k: usize) -> f32 {
    0.5 + 0.0001 * (k % 18000) as f32
}

fn measure_latency(engine: &str, domain: u32) -> Latency {
    let total = WARMUP_S + PROBE_S + 4.0;
    let mut child = Command::new(ulab())
        .args(["sim", "--engine", engine, "--domain", &domain.to_string(), "--duration", &total.to_string(), "--quiet"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab sim");
    let stderr = collect_stderr(&mut child);
    let pid = child.id();
    let mut child = Killed(child);

    let p = Participant::new(DomainConfig::loopback(domain)).expect("participant");
    let reader = p.reader(&TopicSpec::lowstate(Family::Hg)).expect("reader");
    let writer = p.writer(&TopicSpec::lowcmd(Family::Hg)).expect("writer");

    // Receiver thread: (arrival, probe tau bits) of every LowState, stamped as soon as taken.
    let stop = Arc::new(AtomicBool::new(false));
    let first: Arc<Mutex<Option<hg::LowState_>>> = Arc::new(Mutex::new(None));
    let rx = {
        let (stop, first) = (stop.clone(), first.clone());
        std::thread::spawn(move || {
            let mut seen = Vec::with_capacity(10_000);
            while !stop.load(Ordering::SeqCst) {
                let Some(s) = reader.take(Duration::from_millis(20)) else { continue };
                let now = Instant::now();
                if let Ok(d) = cdr::decode::<hg::LowState_>(&s.data) {
                    seen.push((now, d.value.motor_state[PROBE].tau_est.to_bits()));
                    let mut f = first.lock().unwrap_or_else(|e| e.into_inner());
                    if f.is_none() {
                        *f = Some(d.value);
                    }
                }
            }
            seen
        })
    };
    let end = Instant::now() + Duration::from_secs(20);
    let state = loop {
        if let Some(s) = first.lock().unwrap_or_else(|e| e.into_inner()).clone() {
            break s;
        }
        assert!(Instant::now() < end, "{engine}: no LowState");
        std::thread::sleep(Duration::from_millis(10));
    };
    assert!(writer.wait_for_readers(1, Duration::from_secs(10)).expect("status"), "{engine}: lowcmd not matched");

    // Hold command (same gains as the client tests), probe motor in pure torque mode.
    let mut cmd = hg::LowCmd_ { mode_machine: state.mode_machine, ..Default::default() };
    for (i, m) in cmd.motor_cmd.iter_mut().take(h1_2::NUM_JOINTS).enumerate() {
        m.mode = 1;
        m.q = state.motor_state[i].q;
        (m.kp, m.kd) = match i {
            0..=11 => ([500.0, 500.0, 500.0, 500.0, 600.0, 600.0][i % 6], [5.0, 5.0, 5.0, 6.0, 10.0, 10.0][i % 6]),
            12 => (300.0, 5.0),
            _ => (120.0, 3.0),
        };
    }
    cmd.motor_cmd[PROBE].kp = 0.0;
    cmd.motor_cmd[PROBE].kd = 0.0;

    let period = 1.0 / 500.0;
    let mut sends: Vec<Instant> = Vec::new();
    let mut index: HashMap<u32, usize> = HashMap::new();
    let mut cpu_start = None;
    let mut measure_from = None;
    // Fixed seed: the same send phases on every run.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let start = Instant::now();
    let mut k = 0usize;
    loop {
        let t = start.elapsed().as_secs_f64();
        if t >= WARMUP_S + PROBE_S {
            break;
        }
        if t >= WARMUP_S && measure_from.is_none() {
            measure_from = Some(k);
            cpu_start = Some((Instant::now(), cpu_seconds(pid, clock_ticks()).unwrap_or(f64::NAN)));
        }
        let tau = probe_tau(k);
        cmd.motor_cmd[PROBE].tau = tau;
        crc::seal(&mut cmd);
        let bytes = cdr::encode(&cmd, Encoding::UNITREE);
        index.insert(tau.to_bits(), k);
        let now = Instant::now();
        writer.write(&bytes).expect("write");
        sends.push(now);
        k += 1;
        // Probe k goes out at a random point of its 2 ms slot: the bridge steps on its own
        // 500 Hz clock, and a sender locked to one phase of it would measure that phase only.
        let next = start + Duration::from_secs_f64((k as f64 + 0.9 * rng.gen::<f64>()) * period);
        if let Some(d) = next.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
    }
    // Let the last probes come back, then read the CPU counters while the bridge still runs.
    std::thread::sleep(Duration::from_millis(100));
    let (cpu_t0, cpu0) = cpu_start.expect("measurement window");
    let cpu1 = cpu_seconds(pid, clock_ticks()).unwrap_or(f64::NAN);
    let cpu_pct = 100.0 * (cpu1 - cpu0) / cpu_t0.elapsed().as_secs_f64();
    stop.store(true, Ordering::SeqCst);
    let seen = rx.join().expect("receiver");
    let status = wait_bounded(&mut child.0, Duration::from_secs(30));
    let err = stderr.join().unwrap_or_default();
    assert!(status.is_some_and(|s| s.success()), "{engine}: ulab sim failed: {err}");

    // Resolve: each state reflecting probe j settles every pending probe <= j.
    let from = measure_from.unwrap_or(0);
    let mut latency: Vec<Option<f64>> = vec![None; sends.len()];
    let mut reflected = vec![false; sends.len()];
    let mut settled = 0usize; // probes < settled are resolved
    let mut states_in_window = 0usize;
    let (w0, w1) = (sends.get(from).copied(), sends.last().copied());
    for &(at, bits) in &seen {
        if let (Some(a), Some(b)) = (w0, w1) {
            if at >= a && at <= b {
                states_in_window += 1;
            }
        }
        let Some(&j) = index.get(&bits) else { continue };
        if j < settled {
            continue;
        }
        reflected[j] = true;
        for (i, slot) in latency.iter_mut().enumerate().take(j + 1).skip(settled) {
            *slot = Some(at.saturating_duration_since(sends[i]).as_secs_f64() * 1000.0);
        }
        settled = j + 1;
    }
    let window: Vec<(Option<f64>, bool)> = latency.iter().copied().zip(reflected.iter().copied()).skip(from).collect();
    let mut ms: Vec<f64> = window.iter().filter_map(|(l, _)| *l).collect();
    ms.sort_by(f64::total_cmp);
    let state_hz = match (w0, w1) {
        (Some(a), Some(b)) if b > a => states_in_window as f64 / (b - a).as_secs_f64(),
        _ => f64::NAN,
    };
    Latency {
        p50_ms: percentile(&ms, 50.0),
        p99_ms: percentile(&ms, 99.0),
        max_ms: ms.last().copied().unwrap_or(f64::NAN),
        probes: window.len(),
        superseded: window.iter().filter(|(l, r)| l.is_some() && !r).count(),
        unresolved: window.iter().filter(|(l, _)| l.is_none()).count(),
        state_hz,
        cpu_pct,
    }
}

struct Rtf {
    median: f64,
    overall: f64,
}

/// `ulab sim --fast` for FAST_S s of wall time: real-time factor from its status lines (median
/// of the per-second values) and from its final line (simulated / wall over the whole run).
fn measure_rtf(engine: &str, domain: u32) -> Rtf {
    let mut child = Command::new(ulab())
        .args([
            "sim",
            "--engine",
            engine,
            "--domain",
            &domain.to_string(),
            "--fast",
            "--dt",
            "0.002",
            "--duration",
            &FAST_S.to_string(),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab sim --fast");
    let stderr = collect_stderr(&mut child);
    let status = wait_bounded(&mut child, Duration::from_secs_f64(FAST_S + 30.0));
    let err = stderr.join().unwrap_or_default();
    assert!(status.is_some_and(|s| s.success()), "{engine}: ulab sim --fast failed: {err}");
    let mut per_second: Vec<f64> =
        err.lines().filter_map(|l| l.split("rtf ").nth(1)?.split_whitespace().next()?.parse().ok()).collect();
    per_second.sort_by(f64::total_cmp);
    let overall = err
        .lines()
        .rev()
        .find_map(|l| {
            let rest = l.strip_prefix("sim: stopped after ")?;
            let wall: f64 = rest.split(" s wall").next()?.parse().ok()?;
            let sim: f64 = rest.split(", ").nth(1)?.split(" s simulated").next()?.parse().ok()?;
            Some(sim / wall)
        })
        .unwrap_or(f64::NAN);
    Rtf { median: percentile(&per_second, 50.0), overall }
}

fn main() {
    // `cargo bench` passes `--bench`; other arguments select engines.
    let wanted: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with('-')).collect();
    let engines: Vec<&str> =
        ENGINES.iter().copied().filter(|e| wanted.is_empty() || wanted.iter().any(|w| w == e)).collect();
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let mut rows = Vec::new();
    for (i, engine) in engines.iter().enumerate() {
        let load_before = loadavg();
        eprintln!("{engine}: latency at {STATE_RATE} Hz, real time ({PROBE_S} s of probes at 500 Hz)...");
        let lat = measure_latency(engine, 80 + i as u32);
        eprintln!("{engine}: real-time factor with --fast, dt 2 ms ({FAST_S} s)...");
        let rtf = measure_rtf(engine, 84 + i as u32);
        rows.push((engine.to_string(), lat, rtf, load_before, loadavg()));
    }

    println!("| engine | latency p50 | latency p99 (max) | p99 / target {P99_TARGET_MS:.0} ms | probes (superseded, unresolved) | LowState rate | bridge CPU, real time | RTF `--fast` median (whole run) | RTF / target | load avg before → after |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    for (engine, l, r, before, after) in &rows {
        let rtf_ratio = if engine == "mujoco" {
            format!("{:.2} (target {RTF_TARGET_MUJOCO})", r.median / RTF_TARGET_MUJOCO)
        } else {
            "— (no target)".to_owned()
        };
        println!(
            "| {engine} | {:.2} ms | {:.2} ms ({:.2}) | {:.2} | {} ({}, {}) | {:.1} Hz | {:.0} % of a core | {:.2} ({:.2}) | {rtf_ratio} | {before} → {after} |",
            l.p50_ms,
            l.p99_ms,
            l.max_ms,
            l.p99_ms / P99_TARGET_MS,
            l.probes,
            l.superseded,
            l.unresolved,
            l.state_hz,
            l.cpu_pct,
            r.median,
            r.overall
        );
    }
    println!();
    println!("{cores} cores; ratios below 1 (latency) or above 1 (RTF) meet the target.");
}
