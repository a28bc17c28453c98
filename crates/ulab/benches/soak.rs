//! Soak of the simulator bridge and the recorder (issue 19, item 3): a bench command, not a timed test.
//!
//!   source scripts/env.sh && cargo bench -p ulab --bench soak                       # 60 minutes, 10-minute windows
//!   ULAB_SOAK_MINUTES=3 ULAB_SOAK_WINDOW_S=60 cargo bench -p ulab --bench soak      # a short rehearsal
//!
//! What runs, all on `lo` (domain `ULAB_SOAK_DOMAIN`, default 91):
//! * `ulab sim --engine mujoco` (LowState at 500 Hz, dt 2 ms, real time);
//! * a 500 Hz controller (this process) holding the standing pose; each command carries a feed-forward torque on the
//!   left wrist yaw (kp = kd = 0) unique within 36 s, so the first LowState whose `tau_est` equals it times the
//!   command-to-state latency (as `sim_latency` does);
//! * a flood from a second participant: copies of the controller's latest command at 5 kHz (10x) during the middle
//!   fifth of every window (copies, so that the flood loads the bridge without changing what it applies);
//! * subscribers joining and leaving: every 30 s a new participant reads LowState for 10 s and leaves;
//! * a recorder (`ulab record`, both topics, the flood included) for the whole run, split into files of
//!   `ULAB_SOAK_SPLIT_MINUTES` (default 10; 0 = one file), and short recorders of 60 s joining and leaving three
//!   times per window;
//! * every 10 s, RSS, anonymous RSS and open file descriptors of the bridge and of the long recorder.
//!
//! Samples lost are counted from LowState `tick` (milliseconds of simulated time, +2 per state): a missing tick
//! between two received ones is a lost sample. A recording is also compared, tick by tick, with what this process's
//! own reader received over the same span (a sample the reader has and the file lacks was lost by the recorder).
//! Memory is judged by the least-squares slope of anonymous RSS (heap, stacks: what a leak grows) after the first
//! window, with its standard error; total RSS is shown beside it (it also counts executable pages as they are
//! touched or reclaimed).

mod common;

use common::{
    clock_ticks, collect_stderr, cpu_seconds, loadavg, open_fds, percentile, rss_anon_kib, rss_kib, wait_bounded,
    Killed,
};
use dds_transport::{DomainConfig, Family, Participant, TopicSpec};
use lowlevel_codec::{cdr, crc, Encoding};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use unitree_idl::MessageType;
use unitree_idl::{h1_2, hg};

/// Probe motor: left wrist yaw (slot 19), a light joint far from the balance.
const PROBE: usize = 19;
const PERIOD_S: f64 = 1.0 / 500.0;
/// Distinct probe torques before they repeat (36 s at 500 Hz).
const PROBE_CYCLE: usize = 18_000;
const FLOOD_HZ: f64 = 5_000.0;
const SUBSCRIBER_EVERY_S: f64 = 30.0;
const SUBSCRIBER_FOR_S: f64 = 10.0;
const SHORT_RECORDING_S: f64 = 60.0;
const MONITOR_EVERY_S: f64 = 10.0;

fn env_f64(name: &str, default: f64) -> f64 {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn probe_tau(k: usize) -> f32 {
    0.5 + 0.0001 * (k % PROBE_CYCLE) as f32
}

/// Index in the probe cycle of a torque, if it is a probe torque.
fn probe_index(bits: u32) -> Option<usize> {
    let tau = f32::from_bits(bits);
    let k = ((tau - 0.5) / 0.0001).round();
    (k >= 0.0 && (k as usize) < PROBE_CYCLE && probe_tau(k as usize).to_bits() == bits).then_some(k as usize)
}

/// Whether the flood runs at `t` seconds: the middle fifth of each window.
fn flooding(t: f64, window: f64) -> bool {
    let phase = (t % window) / window;
    (0.4..0.6).contains(&phase)
}

/// Missing ticks between consecutive samples of a stream whose ticks advance by `step`.
fn missing_ticks(ticks: &[u32], step: u32) -> u64 {
    ticks.windows(2).map(|w| u64::from(w[1].saturating_sub(w[0]) / step).saturating_sub(1)).sum()
}

/// Least-squares slope of y over x, with its standard error and the residuals' standard deviation.
fn slope(points: &[(f64, f64)]) -> (f64, f64, f64) {
    let n = points.len() as f64;
    if points.len() < 3 {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let b = sxy / sxx;
    let resid: f64 = points.iter().map(|p| (p.1 - my - b * (p.0 - mx)).powi(2)).sum();
    let sigma = (resid / (n - 2.0)).sqrt();
    (b, sigma / sxx.sqrt(), sigma)
}

fn spawn_recorder(domain: u32, out: &Path, seconds: f64, split_minutes: Option<f64>) -> std::io::Result<Child> {
    Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["record", "--domain", &domain.to_string(), "--quiet", "--force", "--duration", &seconds.to_string()])
        .args(split_minutes.map(|m| ["--split-minutes".to_owned(), m.to_string()]).into_iter().flatten())
        .arg("--out")
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
}

/// One monitor reading.
#[derive(Clone, Copy)]
struct Reading {
    t: f64,
    sim_rss: Option<u64>,
    sim_anon: Option<u64>,
    sim_fds: Option<usize>,
    rec_rss: Option<u64>,
    rec_anon: Option<u64>,
    rec_fds: Option<usize>,
}

/// A subscriber's visit.
struct Visit {
    joined_s: f64,
    samples: usize,
    missing: u64,
    dropped: u64,
}

/// What a recording holds.
struct RecordingCheck {
    name: String,
    started_s: f64,
    exit: String,
    lowstate: usize,
    lowcmd: usize,
    missing_ticks: u64,
    /// Samples our reader received within the recording's tick span that the file lacks.
    lost_vs_reader: usize,
    /// Controller commands missing between the first and the last one the file holds (each carries its own probe
    /// torque; the flood's copies repeat one).
    lost_commands: usize,
    error: Option<String>,
}

/// Checks a recording made of one or more files (a split recording's segments, in order).
fn check_recording(
    name: &str,
    started_s: f64,
    exit: String,
    paths: &[PathBuf],
    reader: &BTreeSet<u32>,
) -> RecordingCheck {
    let mut r = RecordingCheck {
        name: name.to_owned(),
        started_s,
        exit,
        lowstate: 0,
        lowcmd: 0,
        missing_ticks: 0,
        lost_vs_reader: 0,
        lost_commands: 0,
        error: None,
    };
    let mut ticks = Vec::new();
    let (mut probe, mut probes) = (None, BTreeSet::new());
    if paths.is_empty() {
        r.error = Some("no file".into());
    }
    'files: for path in paths {
        let bytes = match std::fs::read(path) {
            Ok(b) => b,
            Err(e) => {
                r.error = Some(e.to_string());
                break;
            }
        };
        let messages = match recording::messages(&bytes) {
            Ok(m) => m,
            Err(e) => {
                r.error = Some(e.to_string());
                break;
            }
        };
        for m in messages {
            match m {
                Ok(m) => match recording::channel_type_name(&m.channel).as_deref().and_then(recording::kind_of) {
                    Some(MessageType::HgLowState) => {
                        r.lowstate += 1;
                        if let Some(t) = recording::lowstate_tick(MessageType::HgLowState, &m.data) {
                            ticks.push(t);
                        }
                    }
                    Some(MessageType::HgLowCmd) => {
                        r.lowcmd += 1;
                        if let Ok(d) = cdr::decode::<hg::LowCmd_>(&m.data) {
                            if let Some(idx) = probe_index(d.value.motor_cmd[PROBE].tau.to_bits()) {
                                // Unwrap the cycle: the probe nearest the last one seen (the flood's copies of an older
                                // command may arrive after a newer one from the controller).
                                let k = probe.map_or(idx as i64, |k: i64| {
                                    let (c, half) = (PROBE_CYCLE as i64, PROBE_CYCLE as i64 / 2);
                                    k + (idx as i64 - k.rem_euclid(c) + c + half).rem_euclid(c) - half
                                });
                                probe = Some(k);
                                probes.insert(k);
                            }
                        }
                    }
                    _ => {}
                },
                Err(e) => {
                    r.error = Some(e.to_string());
                    break 'files;
                }
            }
        }
    }
    r.missing_ticks = missing_ticks(&ticks, 2);
    if let (Some(&a), Some(&b)) = (probes.first(), probes.last()) {
        r.lost_commands = usize::try_from(b - a + 1).unwrap_or(0).saturating_sub(probes.len());
    }
    if let (Some(&first), Some(&last)) = (ticks.first(), ticks.last()) {
        let held: BTreeSet<u32> = ticks.iter().copied().collect();
        r.lost_vs_reader = reader.range(first..=last).filter(|t| !held.contains(t)).count();
    }
    r
}

fn main() {
    let minutes = env_f64("ULAB_SOAK_MINUTES", 60.0);
    let window = env_f64("ULAB_SOAK_WINDOW_S", 600.0);
    let domain = env_f64("ULAB_SOAK_DOMAIN", 91.0) as u32;
    let total = minutes * 60.0;
    let dir = std::env::temp_dir().join(format!("ulab-soak-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    eprintln!("soak: {minutes} min, windows of {window} s, domain {domain}, files in {}", dir.display());
    let load_before = loadavg();

    let mut sim = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["sim", "--engine", "mujoco", "--domain", &domain.to_string()])
        .args(["--duration", &(total + 30.0).to_string(), "--quiet"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab sim");
    let sim_err = collect_stderr(&mut sim);
    let sim_pid = sim.id();
    let mut sim = Killed(sim);

    let p = Participant::new(DomainConfig::loopback(domain)).expect("participant");
    let reader = p.reader(&TopicSpec::lowstate(Family::Hg)).expect("reader");
    let writer = p.writer(&TopicSpec::lowcmd(Family::Hg)).expect("writer");
    let start = Instant::now();
    let stop = Arc::new(AtomicBool::new(false));

    // Our reader: (arrival s, probe tau bits, tick) of every LowState.
    let first: Arc<Mutex<Option<hg::LowState_>>> = Arc::new(Mutex::new(None));
    let rx = {
        let (stop, first) = (stop.clone(), first.clone());
        std::thread::spawn(move || {
            let mut seen: Vec<(f64, u32, u32)> = Vec::with_capacity(2_000_000);
            while !stop.load(Ordering::SeqCst) {
                let Some(s) = reader.take(Duration::from_millis(20)) else { continue };
                let at = start.elapsed().as_secs_f64();
                if let Ok(d) = cdr::decode::<hg::LowState_>(&s.data) {
                    seen.push((at, d.value.motor_state[PROBE].tau_est.to_bits(), d.value.tick));
                    let mut f = first.lock().unwrap_or_else(|e| e.into_inner());
                    if f.is_none() {
                        *f = Some(d.value);
                    }
                }
            }
            (seen, reader.dropped())
        })
    };
    let deadline = Instant::now() + Duration::from_secs(30);
    let state = loop {
        if let Some(s) = first.lock().unwrap_or_else(|e| e.into_inner()).clone() {
            break s;
        }
        assert!(Instant::now() < deadline, "no LowState from ulab sim");
        std::thread::sleep(Duration::from_millis(10));
    };
    assert!(writer.wait_for_readers(1, Duration::from_secs(10)).expect("status"), "rt/lowcmd not matched");

    // The hold command (gains as in sim_latency), probe motor in pure torque mode.
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
    let latest: Arc<Mutex<Vec<u8>>> = Arc::new(Mutex::new(Vec::new()));

    // The flood: a second participant republishing the latest command at 5 kHz in its windows.
    let flood_writes = Arc::new(AtomicU64::new(0));
    let flood = {
        let (stop, latest, count) = (stop.clone(), latest.clone(), flood_writes.clone());
        std::thread::spawn(move || {
            let p = Participant::new(DomainConfig::loopback(domain)).expect("flood participant");
            let w = p.writer(&TopicSpec::lowcmd(Family::Hg)).expect("flood writer");
            let mut next = Instant::now();
            while !stop.load(Ordering::SeqCst) {
                if !flooding(start.elapsed().as_secs_f64(), window) {
                    std::thread::sleep(Duration::from_millis(20));
                    next = Instant::now();
                    continue;
                }
                let bytes = latest.lock().unwrap_or_else(|e| e.into_inner()).clone();
                if !bytes.is_empty() && w.write(&bytes).is_ok() {
                    count.fetch_add(1, Ordering::Relaxed);
                }
                next += Duration::from_secs_f64(1.0 / FLOOD_HZ);
                if let Some(d) = next.checked_duration_since(Instant::now()) {
                    std::thread::sleep(d);
                }
            }
        })
    };

    // Subscribers joining and leaving.
    let churn = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            let mut visits = Vec::new();
            let mut k = 1.0;
            while !stop.load(Ordering::SeqCst) {
                if start.elapsed().as_secs_f64() < k * SUBSCRIBER_EVERY_S {
                    std::thread::sleep(Duration::from_millis(100));
                    continue;
                }
                k += 1.0;
                let joined_s = start.elapsed().as_secs_f64();
                let p = Participant::new(DomainConfig::loopback(domain)).expect("subscriber participant");
                let r = p.reader(&TopicSpec::lowstate(Family::Hg)).expect("subscriber reader");
                let mut ticks = Vec::new();
                let until = Instant::now() + Duration::from_secs_f64(SUBSCRIBER_FOR_S);
                while Instant::now() < until {
                    if let Some(s) = r.take(Duration::from_millis(20)) {
                        if let Ok(d) = cdr::decode::<hg::LowState_>(&s.data) {
                            ticks.push(d.value.tick);
                        }
                    }
                }
                visits.push(Visit {
                    joined_s,
                    samples: ticks.len(),
                    missing: missing_ticks(&ticks, 2),
                    dropped: r.dropped(),
                });
            }
            visits
        })
    };

    // Recorders: one for the whole run, short ones joining and leaving.
    let long_path = dir.join("long.mcap");
    let long_started = start.elapsed().as_secs_f64();
    // Stopped with Ctrl-C (SIGINT) after the controller stops, as a user stops it.
    // Split into files of ULAB_SOAK_SPLIT_MINUTES (default 10; 0: one file), which bounds the writer's chunk index.
    let split = Some(env_f64("ULAB_SOAK_SPLIT_MINUTES", 10.0)).filter(|m| *m > 0.0);
    let long = spawn_recorder(domain, &long_path, total + 60.0, split).expect("start ulab record");
    let long_pid = long.id();
    let mut long = Killed(long);
    let shorts = {
        let (stop, dir) = (stop.clone(), dir.clone());
        std::thread::spawn(move || {
            let mut done: Vec<(String, f64, String, PathBuf)> = Vec::new();
            let every = window / 3.0;
            let mut k = 0.0;
            while !stop.load(Ordering::SeqCst) {
                let t = start.elapsed().as_secs_f64();
                if t < k * every + every / 2.0 || t + SHORT_RECORDING_S + 5.0 > total {
                    std::thread::sleep(Duration::from_millis(200));
                    continue;
                }
                k += 1.0;
                let name = format!("short-{k:.0}");
                let path = dir.join(format!("{name}.mcap"));
                let exit = match spawn_recorder(domain, &path, SHORT_RECORDING_S, None) {
                    Ok(mut child) => wait_bounded(&mut child, Duration::from_secs_f64(SHORT_RECORDING_S + 30.0))
                        .map_or("hung (killed)".into(), |s| s.to_string()),
                    Err(e) => format!("did not start: {e}"),
                };
                done.push((name, t, exit, path));
            }
            done
        })
    };

    // Monitor.
    let monitor = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            let mut readings = Vec::new();
            let mut next = 0.0;
            while !stop.load(Ordering::SeqCst) {
                let t = start.elapsed().as_secs_f64();
                if t >= next {
                    readings.push(Reading {
                        t,
                        sim_rss: rss_kib(sim_pid),
                        sim_anon: rss_anon_kib(sim_pid),
                        sim_fds: open_fds(sim_pid),
                        rec_rss: rss_kib(long_pid),
                        rec_anon: rss_anon_kib(long_pid),
                        rec_fds: open_fds(long_pid),
                    });
                    next += MONITOR_EVERY_S;
                }
                std::thread::sleep(Duration::from_millis(200));
            }
            readings
        })
    };

    // The controller: 500 Hz, each probe at its slot's start (the bridge steps on its own clock, so the phase
    // between the two drifts over the run).
    let cpu0 = cpu_seconds(sim_pid, clock_ticks()).unwrap_or(f64::NAN);
    let t0 = start.elapsed().as_secs_f64();
    let mut sends: Vec<f64> = Vec::with_capacity((total / PERIOD_S) as usize + 10);
    let mut k = 0usize;
    let mut write_errors = 0usize;
    let mut last_report = 0.0;
    loop {
        let t = start.elapsed().as_secs_f64();
        if t >= total {
            break;
        }
        if t - last_report >= window {
            last_report = t;
            eprintln!("soak: {:.0} min of {minutes}, load {}", t / 60.0, loadavg());
        }
        cmd.motor_cmd[PROBE].tau = probe_tau(k);
        crc::seal(&mut cmd);
        let bytes = cdr::encode(&cmd, Encoding::UNITREE);
        sends.push(start.elapsed().as_secs_f64());
        if writer.write(&bytes).is_err() {
            write_errors += 1;
        }
        *latest.lock().unwrap_or_else(|e| e.into_inner()) = bytes;
        k += 1;
        let next = start + Duration::from_secs_f64(t0 + k as f64 * PERIOD_S);
        if let Some(d) = next.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
    }
    std::thread::sleep(Duration::from_millis(200));
    let sim_cpu_pct = 100.0 * (cpu_seconds(sim_pid, clock_ticks()).unwrap_or(f64::NAN) - cpu0) / (total - t0);
    stop.store(true, Ordering::SeqCst);
    let (seen, reader_dropped) = rx.join().expect("reader");
    let readings = monitor.join().expect("monitor");
    let visits = churn.join().expect("subscribers");
    let short_runs = shorts.join().expect("short recorders");
    flood.join().expect("flood");
    let _ = Command::new("kill").args(["-INT", &long_pid.to_string()]).status();
    let long_status = wait_bounded(&mut long.0, Duration::from_secs(60));
    // Ctrl-C makes the bridge print its counters and exit.
    let _ = Command::new("kill").args(["-INT", &sim_pid.to_string()]).status();
    let sim_status = wait_bounded(&mut sim.0, Duration::from_secs(60));
    let err = sim_err.join().unwrap_or_default();
    let summary: Option<serde_json::Value> =
        err.lines().rev().find_map(|l| serde_json::from_str(l.strip_prefix("sim: summary ")?).ok());
    let counter = |name: &str| summary.as_ref().and_then(|s| s["counters"][name].as_u64()).unwrap_or(0);

    // Latency: each state reflecting probe j resolves every pending probe up to j.
    let mut latency: Vec<Option<f64>> = vec![None; sends.len()];
    let mut settled = 0usize;
    for &(at, bits, _) in &seen {
        let Some(idx) = probe_index(bits) else { continue };
        // The probe with this torque at or after `settled` (torques repeat every PROBE_CYCLE probes).
        let j = settled + (idx + PROBE_CYCLE - settled % PROBE_CYCLE) % PROBE_CYCLE;
        if j >= sends.len() || sends[j] > at {
            continue;
        }
        for (i, slot) in latency.iter_mut().enumerate().take(j + 1).skip(settled) {
            *slot = Some((at - sends[i]) * 1000.0);
        }
        settled = j + 1;
    }

    let reader_ticks: BTreeSet<u32> = seen.iter().map(|s| s.2).collect();
    let windows = (total / window).ceil() as usize;
    println!(
        "## Soak: `ulab sim` (MuJoCo) + recorders, {minutes} min (load average before {load_before}, after {})\n",
        loadavg()
    );
    println!("| window | LowState rate (our reader) | lost ticks (our reader) | cmd→state p50 / p99 / max | probes (unresolved) | bridge RSS (anon) / fds at end | recorder RSS (anon) / fds at end |");
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for w in 0..windows {
        let (a, b) = (w as f64 * window, ((w + 1) as f64 * window).min(total));
        let in_w: Vec<&(f64, u32, u32)> = seen.iter().filter(|s| s.0 >= a && s.0 < b).collect();
        let ticks: Vec<u32> = in_w.iter().map(|s| s.2).collect();
        let mut ms: Vec<f64> =
            sends.iter().zip(&latency).filter(|(t, _)| **t >= a && **t < b).filter_map(|(_, l)| *l).collect();
        let probes = sends.iter().filter(|t| **t >= a && **t < b).count();
        ms.sort_by(f64::total_cmp);
        let last = readings.iter().rev().find(|r| r.t < b);
        let fmt = |rss: Option<u64>, anon: Option<u64>, fds: Option<usize>| {
            let mib = |v: Option<u64>| v.map_or("—".into(), |k| format!("{:.1}", k as f64 / 1024.0));
            format!("{} ({}) MiB / {}", mib(rss), mib(anon), fds.map_or("—".into(), |n| n.to_string()))
        };
        println!(
            "| {:.1}–{:.1} min | {:.1} Hz | {} | {:.2} / {:.2} / {:.1} ms | {} ({}) | {} | {} |",
            a / 60.0,
            b / 60.0,
            in_w.len() as f64 / (b - a),
            missing_ticks(&ticks, 2),
            percentile(&ms, 50.0),
            percentile(&ms, 99.0),
            ms.last().copied().unwrap_or(f64::NAN),
            probes,
            probes - ms.len(),
            last.map_or("—".into(), |r| fmt(r.sim_rss, r.sim_anon, r.sim_fds)),
            last.map_or("—".into(), |r| fmt(r.rec_rss, r.rec_anon, r.rec_fds)),
        );
    }
    println!();
    let flood_total = flood_writes.load(Ordering::Relaxed);
    println!(
        "Bridge counters: {} states published, {} commands received ({} accepted, {} rejected, {} malformed); sent: {} by the controller ({write_errors} write errors) and {flood_total} by the flood (5 kHz in the middle fifth of every window). Bridge CPU {sim_cpu_pct:.0} % of a core. Exit: bridge {}, long recorder {}.\n",
        counter("states_published"),
        counter("received"),
        counter("accepted"),
        counter("rejected"),
        counter("malformed"),
        sends.len(),
        sim_status.map_or("hung (killed)".into(), |s| s.to_string()),
        long_status.map_or("hung (killed)".into(), |s| s.to_string()),
    );
    println!(
        "Our reader: {} LowState, {} missing ticks over the run, {} dropped from its queue.\n",
        seen.len(),
        missing_ticks(&seen.iter().map(|s| s.2).collect::<Vec<_>>(), 2),
        reader_dropped
    );

    // Memory and descriptors after the first window (warm-up: allocator pools, DDS discovery).
    let after = window.min(total / 4.0);
    let series = |f: &dyn Fn(&Reading) -> Option<f64>| -> Vec<(f64, f64)> {
        readings.iter().filter(|r| r.t >= after).filter_map(|r| Some((r.t / 60.0, f(r)?))).collect()
    };
    println!("| process | quantity | first → last (after {:.0} min) | slope per minute (± s.e.) | over the run | flat (|slope| < 2 s.e. or drift < 1 MiB / 1 fd) |", after / 60.0);
    println!("|---|---|---:|---:|---:|---|");
    // Anonymous memory is what a leak grows; RSS also moves with pages of the executable touched or reclaimed.
    let rows: [(&str, &str, Box<dyn Fn(&Reading) -> Option<f64>>, f64); 6] = [
        ("bridge", "anonymous KiB", Box::new(|r| r.sim_anon.map(|v| v as f64)), 1024.0),
        ("bridge", "RSS KiB", Box::new(|r| r.sim_rss.map(|v| v as f64)), 1024.0),
        ("bridge", "open fds", Box::new(|r| r.sim_fds.map(|v| v as f64)), 1.0),
        ("long recorder", "anonymous KiB", Box::new(|r| r.rec_anon.map(|v| v as f64)), 1024.0),
        ("long recorder", "RSS KiB", Box::new(|r| r.rec_rss.map(|v| v as f64)), 1024.0),
        ("long recorder", "open fds", Box::new(|r| r.rec_fds.map(|v| v as f64)), 1.0),
    ];
    for (who, what, f, tolerance) in &rows {
        let s = series(f.as_ref());
        let (b, se, _) = slope(&s);
        let span = s.last().map_or(0.0, |l| l.0) - s.first().map_or(0.0, |f| f.0);
        let flat = b.abs() < 2.0 * se || (b * span).abs() < *tolerance;
        println!(
            "| {who} | {what} | {} → {} | {b:.2} (± {se:.2}) | {:.1} | {} |",
            s.first().map_or("—".into(), |p| format!("{:.0}", p.1)),
            s.last().map_or("—".into(), |p| format!("{:.0}", p.1)),
            b * span,
            if flat { "yes" } else { "NO" }
        );
    }
    println!();

    // The long recording's files: OUT itself, or its segments long_000.mcap, long_001.mcap, ...
    let long_files: Vec<PathBuf> = if split.is_none() {
        vec![long_path.clone()]
    } else {
        (0..).map(|i| dir.join(format!("long_{i:03}.mcap"))).take_while(|p| p.exists()).collect()
    };
    println!("Long recording: {} file(s) (--split-minutes {split:?}).", long_files.len());
    println!("| recording | started | exit | LowState | LowCmd | missing ticks in file | LowState lost vs our reader | controller commands lost | error |");
    println!("|---|---:|---|---:|---:|---:|---:|---:|---|");
    let mut checks = vec![check_recording(
        "long",
        long_started,
        long_status.map_or("hung (killed)".into(), |s| s.to_string()),
        &long_files,
        &reader_ticks,
    )];
    checks.extend(
        short_runs.iter().map(|(n, t, e, p)| check_recording(n, *t, e.clone(), std::slice::from_ref(p), &reader_ticks)),
    );
    for c in &checks {
        println!(
            "| {} | {:.0} s | {} | {} | {} | {} | {} | {} | {} |",
            c.name,
            c.started_s,
            c.exit,
            c.lowstate,
            c.lowcmd,
            c.missing_ticks,
            c.lost_vs_reader,
            c.lost_commands,
            c.error.as_deref().unwrap_or("—")
        );
    }
    println!();
    let lost: u64 = visits.iter().map(|v| v.missing).sum();
    println!(
        "Subscribers joining and leaving: {} visits (one every {SUBSCRIBER_EVERY_S:.0} s, {SUBSCRIBER_FOR_S:.0} s each), {} samples in all (min {} per visit), {lost} missing ticks, {} dropped from their queues; first joined at {:.0} s.",
        visits.len(),
        visits.iter().map(|v| v.samples).sum::<usize>(),
        visits.iter().map(|v| v.samples).min().unwrap_or(0),
        visits.iter().map(|v| v.dropped).sum::<u64>(),
        visits.first().map_or(f64::NAN, |v| v.joined_s),
    );
    let _ = std::fs::remove_dir_all(&dir);
}
