//! Robustness of `ulab sim --engine mujoco` on its DDS interface (issue 7, item 5):
//! * a flood of valid commands at 10x the normal rate (5 kHz);
//! * malformed samples published raw through our transport (truncated, too long, bad or
//!   unsupported encapsulation header, header only), and well-formed commands with unsafe content
//!   under a valid CRC (NaN, infinity, absurd gains, targets and torques, unknown mode);
//! * subscribers (readers and whole participants, best-effort and reliable) joining and leaving.
//!
//! Throughout, our own reader checks that the bridge keeps publishing LowState (ticks increasing,
//! spaced by the 2 ms state period of the robot's clock), and that every LowState decodes, has a
//! valid CRC and only finite values. At the end the bridge is stopped as Ctrl-C would and must exit
//! 0 without a panic; its own account (`sim: summary {json}`) must show one state per 2 ms of
//! simulated time and counters that account for what was sent.
//!
//! Nothing here depends on the machine's speed (issue 21): the stream is judged on the robot's
//! clock and the bridge's counters; wall-clock rates are printed, never judged (they are benchmark
//! figures: BENCHMARKS.md). Best-effort DDS may drop samples when a loaded machine deschedules the
//! bridge, so counts are judged as "never more than sent, and at least a share", while the exact
//! classification of every malformed and unsafe sample is tested transport-free in
//! `sim-bridge/tests/it/bridge.rs`. Each test holds the machine-wide real-time slot and leases its
//! DDS domain.

use crate::common;

use common::{interrupt, lease_domain, sim_summary, wait_with_timeout, KillOnDrop, RealtimeSlot};
use dds_transport::{DomainConfig, Family, Participant, RawWriter, ReaderOptions, Reliability, TopicSpec};
use lowlevel_codec::{cdr, crc, validate, Encoding, Endianness, Representation};
use std::process::{Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use unitree_idl::{h1_2, hg};

const STATE_RATE: f64 = 500.0;
/// Left elbow: light, so a wrongly applied command moves it quickly and visibly.
const ELBOW: usize = 16;

// ---------------------------------------------------------------------------------------------
// The bridge process.

/// The bridge process; killed on drop if a test panics. It runs with `--quiet`, so its stderr is
/// a few lines at most and is collected when it ends.
struct Sim(KillOnDrop);

impl Sim {
    /// Starts `ulab sim --engine mujoco` on `domain`, until [`Sim::finish`].
    fn start(domain: u32, extra: &[&str]) -> Sim {
        let child = Command::new(env!("CARGO_BIN_EXE_ulab"))
            .args(["sim", "--engine", "mujoco", "--domain", &domain.to_string(), "--quiet"])
            .args(extra)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start ulab sim");
        Sim(KillOnDrop(Some(child)))
    }

    fn alive(&mut self) -> bool {
        self.0 .0.as_mut().is_some_and(|c| matches!(c.try_wait(), Ok(None)))
    }

    /// Stops the bridge as Ctrl-C would and waits (bounded) for it to end; returns its status and stderr.
    fn finish(mut self, timeout: Duration) -> (Option<ExitStatus>, String) {
        let child = self.0 .0.take().expect("child");
        interrupt(&child);
        let (status, _, err) = wait_with_timeout(child, timeout);
        (status, err)
    }
}

/// The bridge's final account (its `sim: summary` line).
#[derive(Debug, Default)]
struct Counters {
    /// LowState the bridge published over its whole run, and the simulated and wall time of that run (s).
    states: u64,
    simulated_s: f64,
    wall_s: f64,
    received: u64,
    accepted: u64,
    rejected: u64,
    bad_crc: u64,
    malformed: u64,
}

fn counters(stderr: &str) -> Counters {
    let v = sim_summary(stderr).unwrap_or_else(|| panic!("no summary line in:\n{stderr}"));
    let c = &v["counters"];
    let get = |key: &str| c[key].as_u64().unwrap_or_else(|| panic!("`{key}` in {v}"));
    Counters {
        states: get("states_published"),
        simulated_s: v["simulated_seconds"].as_f64().unwrap_or_else(|| panic!("simulated_seconds in {v}")),
        wall_s: v["wall_seconds"].as_f64().unwrap_or_else(|| panic!("wall_seconds in {v}")),
        received: get("received"),
        accepted: get("accepted"),
        rejected: get("rejected"),
        bad_crc: get("bad_crc"),
        malformed: get("malformed"),
    }
}

/// Common end-of-run checks: exits 0 when stopped, no panic, one state per period of simulated time; returns the
/// counters.
fn finish_ok(sim: Sim, timeout: Duration) -> Counters {
    let (status, err) = sim.finish(timeout);
    assert!(!err.contains("panicked"), "bridge panicked:\n{err}");
    assert!(status.is_some_and(|s| s.success()), "bridge did not exit 0 when stopped ({status:?}):\n{err}");
    let c = counters(&err);
    let per_simulated_second = c.states as f64 / c.simulated_s;
    assert!(
        (per_simulated_second - STATE_RATE).abs() <= 0.01 * STATE_RATE,
        "bridge published {} LowState in {:.2} s of simulated time ({per_simulated_second:.1} per simulated second)",
        c.states,
        c.simulated_s
    );
    eprintln!(
        "bridge: {} LowState in {:.2} s simulated, {:.2} s wall ({:.1} Hz wall, {:.2}x real time)",
        c.states,
        c.simulated_s,
        c.wall_s,
        c.states as f64 / c.wall_s,
        c.simulated_s / c.wall_s
    );
    c
}

// ---------------------------------------------------------------------------------------------
// Our own LowState monitor.

#[derive(Debug, Default)]
struct Report {
    /// Arrival time of every LowState.
    arrivals: Vec<Instant>,
    undecodable: usize,
    bad_crc: usize,
    non_finite: usize,
    /// (arrival, left elbow q) of every LowState.
    elbow: Vec<(Instant, f32)>,
    /// (arrival, tick) of every LowState.
    ticks: Vec<(Instant, u32)>,
}

struct Monitor {
    stop: Arc<AtomicBool>,
    latest: Arc<Mutex<Option<hg::LowState_>>>,
    handle: Option<JoinHandle<Report>>,
}

impl Monitor {
    /// Takes every LowState on `participant` until stopped, checking each one.
    fn start(participant: &Participant) -> Monitor {
        let reader = participant.reader(&TopicSpec::lowstate(Family::Hg)).expect("LowState reader");
        let stop = Arc::new(AtomicBool::new(false));
        let latest = Arc::new(Mutex::new(None));
        let (s, l) = (stop.clone(), latest.clone());
        let handle = std::thread::spawn(move || {
            let mut r = Report::default();
            while !s.load(Ordering::SeqCst) {
                let Some(sample) = reader.take(Duration::from_millis(20)) else { continue };
                let now = Instant::now();
                r.arrivals.push(now);
                let Ok(d) = cdr::decode::<hg::LowState_>(&sample.data) else {
                    r.undecodable += 1;
                    continue;
                };
                if !crc::verify(&d.value) {
                    r.bad_crc += 1;
                }
                if !validate::non_finite(&d.value).is_empty() {
                    r.non_finite += 1;
                }
                r.elbow.push((now, d.value.motor_state[ELBOW].q));
                r.ticks.push((now, d.value.tick));
                *l.lock().unwrap_or_else(|e| e.into_inner()) = Some(d.value);
            }
            r
        });
        Monitor { stop, latest, handle: Some(handle) }
    }

    /// Waits (bounded) for the first LowState and returns it.
    fn first(&self, timeout: Duration) -> hg::LowState_ {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            if let Some(s) = self.latest() {
                return s;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        panic!("no LowState from the bridge within {timeout:?}");
    }

    fn latest(&self) -> Option<hg::LowState_> {
        self.latest.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    fn stop(mut self) -> Report {
        self.stop.store(true, Ordering::SeqCst);
        self.handle.take().expect("handle").join().expect("monitor thread")
    }
}

impl Report {
    /// Every LowState decoded, had a valid CRC and only finite values.
    fn assert_clean(&self) {
        assert!(!self.arrivals.is_empty(), "no LowState at all");
        assert_eq!(
            (self.undecodable, self.bad_crc, self.non_finite),
            (0, 0, 0),
            "of {} LowState: undecodable, bad CRC, non-finite",
            self.arrivals.len()
        );
    }

    /// The bridge kept publishing over [from, to): LowState arrived, their ticks increase, and they are spaced by
    /// the state period on the robot's clock (a lost sample gives a multiple of it, a wrong rate another gcd). The
    /// wall-clock rate is printed only.
    fn assert_stream(&self, from: Instant, to: Instant, what: &str) {
        let ticks: Vec<u32> = self.ticks.iter().filter(|(t, _)| *t >= from && *t < to).map(|(_, k)| *k).collect();
        assert!(ticks.len() >= 10, "{what}: only {} LowState", ticks.len());
        assert!(ticks.windows(2).all(|w| w[1] > w[0]), "{what}: LowState ticks not increasing");
        let gcd = ticks.windows(2).map(|w| w[1] - w[0]).fold(0, gcd);
        let period_ms = (1000.0 / STATE_RATE) as u32;
        assert_eq!(gcd, period_ms, "{what}: LowState ticks spaced by a gcd of {gcd} ms, period {period_ms} ms");
        let span = ticks[ticks.len() - 1] - ticks[0];
        eprintln!(
            "{what}: {} LowState over {span} ms of simulated time ({:.0} % of the states published), {:.1} Hz wall",
            ticks.len(),
            100.0 * (ticks.len() - 1) as f64 / (f64::from(span) / f64::from(period_ms)).max(1.0),
            ticks.len() as f64 / (to - from).as_secs_f64()
        );
    }

    /// Largest |elbow q - reference| over LowState that arrived before `to` and describe a time at least
    /// `settle_ms` of simulated time after the first LowState that arrived at or after `from`.
    fn elbow_excursion(&self, from: Instant, settle_ms: u32, to: Instant, reference: f32) -> f32 {
        let Some(&(_, tick0)) = self.ticks.iter().find(|(t, _)| *t >= from) else { return f32::NAN };
        self.elbow
            .iter()
            .zip(&self.ticks)
            .filter(|((t, _), (_, k))| *t < to && k.wrapping_sub(tick0) >= settle_ms && *k >= tick0)
            .map(|((_, q), _)| (q - reference).abs())
            .fold(0.0, f32::max)
    }
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

// ---------------------------------------------------------------------------------------------
// Commands.

/// A valid hold command for the current pose `q` (first 27 slots), with gains that keep the
/// H1-2 standing (same as the Python SDK client test), CRC sealed.
fn hold_command(q: &[f32], mode_machine: u8) -> hg::LowCmd_ {
    const LEG_KP: [f32; 6] = [500.0, 500.0, 500.0, 500.0, 600.0, 600.0];
    const LEG_KD: [f32; 6] = [5.0, 5.0, 5.0, 6.0, 10.0, 10.0];
    let mut cmd = hg::LowCmd_ { mode_machine, ..Default::default() };
    for (i, m) in cmd.motor_cmd.iter_mut().take(h1_2::NUM_JOINTS).enumerate() {
        m.mode = 1;
        m.q = q[i];
        (m.kp, m.kd) = match i {
            0..=11 => (LEG_KP[i % 6], LEG_KD[i % 6]),
            12 => (300.0, 5.0),
            _ => (120.0, 3.0),
        };
    }
    crc::seal(&mut cmd);
    cmd
}

fn current_q(s: &hg::LowState_) -> Vec<f32> {
    s.motor_state.iter().take(h1_2::NUM_JOINTS).map(|m| m.q).collect()
}

fn xcdr1(cmd: &hg::LowCmd_) -> Vec<u8> {
    cdr::encode(cmd, Encoding::UNITREE)
}

/// Sends `make(i)` for every i below `rate` x `seconds`, paced at `rate` Hz. It catches up after oversleeping, so
/// every sample is sent however loaded the machine is; only the wall time it takes varies. Returns samples sent.
fn send_at(writer: &RawWriter, rate: f64, seconds: f64, mut make: impl FnMut(u64) -> Vec<u8>) -> u64 {
    let total = (rate * seconds).round() as u64;
    let start = Instant::now();
    let mut sent = 0u64;
    while sent < total {
        let due = ((start.elapsed().as_secs_f64() * rate).floor() as u64 + 1).min(total);
        while sent < due {
            writer.write(&make(sent)).expect("write LowCmd");
            sent += 1;
        }
        if sent < total {
            std::thread::sleep(Duration::from_secs_f64((due as f64 / rate - start.elapsed().as_secs_f64()).max(0.0)));
        }
    }
    sent
}

/// Sends `bytes` at 500 Hz until the robot's clock (LowState tick) has advanced `sim_ms` past `from_tick`, so that a
/// bridge running slower than real time on a loaded machine gets the same simulated time to act (bounded by a
/// generous wall-clock limit that only turns a stalled bridge into a failure).
fn hold_until_tick(writer: &RawWriter, monitor: &Monitor, bytes: &[u8], from_tick: u32, sim_ms: u32) {
    let give_up = Instant::now() + Duration::from_secs(120);
    while monitor.latest().is_some_and(|s| s.tick.wrapping_sub(from_tick) < sim_ms) {
        assert!(Instant::now() < give_up, "the bridge's clock did not advance {sim_ms} ms in 120 s");
        send_at(writer, 500.0, 0.02, |_| bytes.to_vec());
    }
}

/// Our participant on `domain` with a LowState monitor and a raw LowCmd writer matched to the
/// bridge's reader; waits (bounded) for the first LowState.
fn connect(domain: u32) -> (Participant, Monitor, RawWriter, hg::LowState_) {
    let p = Participant::new(DomainConfig::loopback(domain)).expect("participant");
    let monitor = Monitor::start(&p);
    let writer = p.writer(&TopicSpec::lowcmd(Family::Hg)).expect("LowCmd writer");
    let first = monitor.first(common::PATIENCE);
    assert!(
        writer.wait_for_readers(1, common::PATIENCE).expect("matched status"),
        "bridge's rt/lowcmd reader never matched"
    );
    (p, monitor, writer, first)
}

// ---------------------------------------------------------------------------------------------
// Tests.

/// 5 kHz of valid commands (10x Unitree's 500 Hz control loop) for 3 s.
#[test]
fn flood_of_valid_commands_at_10x_rate() {
    const FLOOD_HZ: f64 = 5000.0;
    const FLOOD_S: f64 = 3.0;
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let mut sim = Sim::start(domain.id(), &[]);
    let (_p, monitor, writer, first) = connect(domain.id());

    // The flood holds the pose but moves the left elbow by +0.3 rad: where the elbow ends
    // shows that the bridge kept applying the flood rather than just surviving it.
    let mut q = current_q(&first);
    let elbow_target = q[ELBOW] + 0.3;
    q[ELBOW] = elbow_target;
    let bytes = xcdr1(&hold_command(&q, first.mode_machine));
    let t0 = Instant::now();
    let tick0 = monitor.latest().map_or(first.tick, |s| s.tick);
    let sent = send_at(&writer, FLOOD_HZ, FLOOD_S, |_| bytes.clone());
    let t1 = Instant::now();
    let achieved = sent as f64 / (t1 - t0).as_secs_f64();
    // At least 1.5 s of simulated time since the flood began, for the elbow to get there (kp 120: ~0.3 s).
    hold_until_tick(&writer, &monitor, &bytes, tick0, 1500);
    let elbow_end = monitor.latest().map(|s| s.motor_state[ELBOW].q).unwrap_or(f32::NAN);
    assert!(sim.alive(), "bridge died during the flood");
    let report = monitor.stop();

    // `send_at` catches up after oversleeping, so the count is FLOOD_HZ x FLOOD_S whatever the machine's load;
    // the achieved wall rate is printed only.
    assert!(sent as f64 >= FLOOD_HZ * FLOOD_S, "the flood sent only {sent} commands");
    report.assert_clean();
    report.assert_stream(t0, t1, "during a 5 kHz flood");
    assert!((elbow_end - elbow_target).abs() < 0.08, "elbow at {elbow_end:.3}, flood target {elbow_target:.3}");

    let c = finish_ok(sim, Duration::from_secs(20));
    eprintln!("flood: sent {sent} at {achieved:.0}/s; bridge {c:?}");
    // Only valid commands were sent: none may be rejected; they were taken (the elbow reached the flood's
    // target above), never more than sent (the bridge's best-effort reader may drop some of a 5 kHz stream,
    // which the protocol allows; the share is printed).
    assert_eq!((c.rejected, c.bad_crc, c.malformed), (0, 0, 0), "{c:?}");
    assert!(c.accepted > 0 && c.accepted <= sent, "accepted {} of {sent} flood commands", c.accepted);
    eprintln!("flood: {:.1} % of the flood accepted", 100.0 * c.accepted as f64 / sent as f64);
}

/// Malformed samples and unsafe commands with a valid CRC: none applied, all counted.
#[test]
fn malformed_and_unsafe_commands_are_counted_and_never_applied() {
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    // A long command timeout keeps the last valid hold active while only bad samples arrive,
    // so that the elbow would visibly move if any of them were applied.
    let mut sim = Sim::start(domain.id(), &["--command-timeout", "30"]);
    let (_p, monitor, writer, first) = connect(domain.id());
    let q = current_q(&first);
    let hold = hold_command(&q, first.mode_machine);

    // Phase 1 (1.5 s): valid hold at 500 Hz, alternately XCDR1 and XCDR2. Unitree's SDK sends
    // XCDR1, but XCDR2 (header 00 07, DHEADER before the motor_cmd array) is a standard
    // encoding of the same @final type that the bridge's codec decodes to the same value: such
    // a sample is a valid command and must be accepted, not counted as malformed (and it must
    // not be misread: were it, the elbow check below would see the pose move).
    let xcdr2 = Encoding { representation: Representation::Xcdr2, endianness: Endianness::Little };
    let (hold1, hold2) = (xcdr1(&hold), cdr::encode(&hold, xcdr2));
    assert_ne!(hold1[4..], hold2[4..], "XCDR2 and XCDR1 bodies of hg LowCmd_ differ (DHEADER)");
    assert_eq!(cdr::decode::<hg::LowCmd_>(&hold2).expect("XCDR2 decodes").value, hold);
    let t_valid = Instant::now();
    let valid_sent = send_at(&writer, 500.0, 1.5, |i| if i % 2 == 0 { hold1.clone() } else { hold2.clone() });

    // Phase 2 (2 s): only unsafe commands, each with a valid CRC and the left elbow sent 0.8 rad
    // away from the hold: applying any of them would move the elbow.
    let away = q[ELBOW] - 0.8;
    type Mutation = fn(&mut hg::MotorCmd_, &mut hg::LowCmd_);
    let unsafe_kinds: [(&str, Mutation); 9] = [
        ("NaN target", |e, _| e.q = f32::NAN),
        ("NaN gain elsewhere", |_, c| c.motor_cmd[3].kd = f32::NAN),
        ("infinite velocity", |e, _| e.dq = f32::INFINITY),
        ("absurd kp", |e, _| e.kp = 1.0e6),
        ("negative kd", |e, _| e.kd = -5.0),
        ("absurd feed-forward torque", |e, _| e.tau = 1.0e4),
        ("target beyond the joint range", |e, _| e.q = 50.0),
        ("unknown motor mode", |e, _| e.mode = 7),
        ("NaN in an unused slot", |_, c| c.motor_cmd[30].q = f32::NAN),
    ];
    let unsafe_samples: Vec<(&str, Vec<u8>)> = unsafe_kinds
        .iter()
        .map(|(name, mutate)| {
            let mut c = hold.clone();
            c.motor_cmd[ELBOW].q = away;
            let mut elbow = c.motor_cmd[ELBOW].clone();
            mutate(&mut elbow, &mut c);
            c.motor_cmd[ELBOW] = elbow;
            crc::seal(&mut c);
            // Each must really be unsafe by the project's own rules, or the test proves nothing.
            assert!(!validate::h1_2_lowcmd(&c).is_empty(), "{name} passes validation");
            (*name, xcdr1(&c))
        })
        .collect();
    let t_unsafe = Instant::now();
    let unsafe_sent = send_at(&writer, 200.0, 2.0, |i| unsafe_samples[i as usize % unsafe_samples.len()].1.clone());

    // Phase 3 (2 s): malformed byte strings, interleaved with valid holds at 250 Hz.
    let mut long = hold1.clone();
    long.extend_from_slice(&[0; 8]);
    let mut pl_cdr = hold1.clone();
    pl_cdr[..2].copy_from_slice(&[0x00, 0x03]);
    let mut unknown = hold1.clone();
    unknown[..2].copy_from_slice(&[0x12, 0x34]);
    let mut xcdr2_truncated = hold2.clone();
    xcdr2_truncated.truncate(hold2.len() - 5);
    let mut bad_padding = hold1.clone();
    bad_padding[..4].copy_from_slice(&[0x00, 0x01, 0x00, 0x03]); // claims 3 padding bytes it lacks
    bad_padding.truncate(4 + 2);
    // (name, bytes, reaches the application): Cyclone DDS itself drops a DATA submessage whose
    // encapsulation identifier it does not know (it logs "malformed packet received" on the
    // bridge's stderr), so those samples never reach the bridge's counters; every other byte
    // string is delivered as is and must be counted as malformed.
    let malformed: Vec<(&str, Vec<u8>, bool)> = vec![
        ("truncated to half", hold1[..hold1.len() / 2].to_vec(), true),
        ("header only", hold1[..4].to_vec(), true),
        ("8 trailing bytes", long, true),
        ("PL_CDR header", pl_cdr, true),
        ("XCDR2 truncated", xcdr2_truncated, true),
        ("bad padding option", bad_padding, true),
        ("unknown encapsulation", unknown, false),
    ];
    for (name, bytes, _) in &malformed {
        assert!(cdr::decode::<hg::LowCmd_>(bytes).is_err(), "{name} decodes");
    }
    let (mut malformed_sent, mut dropped_by_dds_sent, mut valid_sent_3) = (0u64, 0u64, 0u64);
    send_at(&writer, 500.0, 2.0, |i| {
        if i % 2 == 0 {
            valid_sent_3 += 1;
            hold1.clone()
        } else {
            let (_, bytes, reaches) = &malformed[(i / 2) as usize % malformed.len()];
            if *reaches {
                malformed_sent += 1;
            } else {
                dropped_by_dds_sent += 1;
            }
            bytes.clone()
        }
    });
    let t_end = Instant::now();
    assert!(sim.alive(), "bridge died");
    let report = monitor.stop();

    report.assert_clean();
    report.assert_stream(t_unsafe, t_end, "during unsafe and malformed commands");
    // Elbow held throughout (after 0.3 s for the switch from the bridge's initial standing
    // hold to this controller's gains): an applied unsafe command would pull it 0.8 rad away.
    let excursion = report.elbow_excursion(t_valid, 300, t_end, q[ELBOW]);
    eprintln!("elbow excursion from the hold: {excursion:.4} rad");
    assert!(
        excursion < 0.05,
        "elbow moved {excursion:.3} rad from the hold while XCDR2/unsafe/malformed commands arrived"
    );

    let c = finish_ok(sim, Duration::from_secs(20));
    eprintln!(
        "sent valid {} unsafe {unsafe_sent} malformed {malformed_sent} (+{dropped_by_dds_sent} with an unknown encapsulation); bridge {c:?}",
        valid_sent + valid_sent_3
    );
    let valid = valid_sent + valid_sent_3;
    // At 200-500 Hz on a quiet loopback nothing is lost; a loaded machine that deschedules the bridge may drop
    // best-effort samples, so each counter must hold at least half of what was sent (a bridge that loses or
    // misfiles a whole kind fails) and never more (a counting bug). The exact per-sample classification is
    // tested without DDS in sim-bridge/tests/it/bridge.rs.
    let near = |got: u64, sent: u64| got <= sent && got * 2 >= sent;
    assert!(near(c.rejected, unsafe_sent), "rejected {} of {unsafe_sent} unsafe commands", c.rejected);
    assert!(near(c.malformed, malformed_sent), "malformed {} of {malformed_sent} malformed samples", c.malformed);
    assert!(near(c.accepted, valid), "accepted {} of {valid} valid commands (half of phase 1 in XCDR2)", c.accepted);
    assert_eq!(c.bad_crc, 0);
    assert_eq!(c.received, c.accepted + c.rejected + c.bad_crc + c.malformed, "{c:?}");
}

/// Readers and participants join and leave while the bridge publishes.
#[test]
fn subscribers_joining_and_leaving() {
    const CHURN_S: f64 = 5.0;
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let mut sim = Sim::start(domain.id(), &[]);
    let (p, monitor, writer, first) = connect(domain.id());
    let hold = xcdr1(&hold_command(&current_q(&first), first.mode_machine));

    // Valid commands keep flowing at 500 Hz during the churn (a controller stays connected).
    let stop = Arc::new(AtomicBool::new(false));
    let commander = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            let mut n = 0u64;
            while !stop.load(Ordering::SeqCst) {
                n += send_at(&writer, 500.0, 0.1, |_| hold.clone());
            }
            n
        })
    };

    // A second process whose whole DDS participants join and leave (a subscriber process
    // starting and stopping): this test binary again, running `churn_helper`.
    let helper = Command::new(std::env::current_exe().expect("test binary"))
        .args(["--ignored", "--exact", "sim_robustness::churn_helper", "--nocapture", "--test-threads", "1"])
        .env("ULAB_CHURN_DOMAIN", domain.arg())
        .env("ULAB_CHURN_SECONDS", CHURN_S.to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("start the churn helper process");

    let t0 = Instant::now();
    let mut cycles = 0u32;
    let mut received_by_churners = 0usize;
    while t0.elapsed().as_secs_f64() < CHURN_S {
        // Alternate: a reader on our participant, a reliable reader (the bridge's writer is
        // reliable and must keep state for it), a new participant with its own reader, and a
        // reader that never takes anything (a stalled subscriber).
        let reliable = ReaderOptions { reliability: Reliability::Reliable, ..ReaderOptions::default() };
        match cycles % 4 {
            0 => {
                let r = p.reader(&TopicSpec::lowstate(Family::Hg)).expect("reader");
                received_by_churners += usize::from(r.take(Duration::from_secs(5)).is_some());
            }
            1 => {
                let r = p.reader_with(&TopicSpec::lowstate(Family::Hg), reliable).expect("reliable reader");
                received_by_churners += usize::from(r.take(Duration::from_secs(5)).is_some());
            }
            2 => {
                let q = Participant::new(DomainConfig::loopback(domain.id())).expect("second participant");
                let r = q.reader_with(&TopicSpec::lowstate(Family::Hg), reliable).expect("reader");
                received_by_churners += usize::from(r.take(Duration::from_secs(5)).is_some());
            }
            _ => {
                let _r = p.reader(&TopicSpec::lowstate(Family::Hg)).expect("reader");
                std::thread::sleep(Duration::from_millis(100));
            }
        }
        cycles += 1;
    }
    let t1 = Instant::now();
    stop.store(true, Ordering::SeqCst);
    let commands = commander.join().expect("commander");
    let (_, helper_out, _) = wait_with_timeout(helper, Duration::from_secs(120));
    assert!(sim.alive(), "bridge died during subscriber churn");
    let report = monitor.stop();

    report.assert_clean();
    // Known, measured on a quiet machine: our monitor sees ~480/s during this churn while the bridge publishes
    // 500/s. Each reliable reader created or deleted in *this* process on the same domain costs the existing
    // best-effort reader about one sample (receive side, our transport / Cyclone 11; churning a reliable reader
    // every 2 ms starves it to a few samples/s). Churn in another process (the helper) costs nothing measurable.
    report.assert_stream(t0, t1, "while subscribers join and leave");
    // Readers that take were created 3 times in 4 cycles; nearly each must have got data (within a patient
    // wait: on a healthy run the first sample arrives in milliseconds).
    let takers = (0..cycles).filter(|c| c % 4 != 3).count();
    assert!(
        received_by_churners * 10 >= takers * 9,
        "only {received_by_churners} of {takers} new readers got a LowState within 5 s"
    );

    // "CHURN cycles N got M": participants created in the helper, and how many got a LowState.
    let helper_line = helper_out
        .lines()
        .find_map(|l| l.find("CHURN ").map(|i| &l[i..]))
        .unwrap_or_else(|| panic!("churn helper output: {helper_out}"));
    let nums: Vec<usize> = helper_line.split_whitespace().filter_map(|w| w.parse().ok()).collect();
    let (helper_cycles, helper_got) = (nums.first().copied().unwrap_or(0), nums.get(1).copied().unwrap_or(0));
    assert!(helper_cycles >= 2 && helper_got * 10 >= helper_cycles * 9, "churn helper: {helper_line}");

    let c = finish_ok(sim, Duration::from_secs(20));
    eprintln!("churn: {cycles} cycles here, {helper_line} in a second process, {commands} commands; bridge {c:?}");
    assert!(cycles >= 4, "only {cycles} join/leave cycles");
    assert_eq!((c.rejected, c.bad_crc, c.malformed), (0, 0, 0), "{c:?}");
    assert!(c.accepted * 2 >= commands && c.accepted <= commands, "accepted {} of {commands}", c.accepted);
}

/// Not a test by itself: `subscribers_joining_and_leaving` runs this test binary again with
/// `--ignored --exact sim_robustness::churn_helper` and `ULAB_CHURN_DOMAIN` set, as a second process in which
/// whole DDS participants (a new Cyclone domain instance each time) join, read one LowState
/// and leave, alternately best-effort and reliable. Without the variable it does nothing.
#[test]
#[ignore = "helper process of subscribers_joining_and_leaving"]
fn churn_helper() {
    let Some(domain) = std::env::var("ULAB_CHURN_DOMAIN").ok().and_then(|d| d.parse::<u32>().ok()) else { return };
    let seconds: f64 = std::env::var("ULAB_CHURN_SECONDS").ok().and_then(|s| s.parse().ok()).unwrap_or(5.0);
    let t0 = Instant::now();
    let (mut cycles, mut got) = (0usize, 0usize);
    while t0.elapsed().as_secs_f64() < seconds {
        let reliability = if cycles % 2 == 0 { Reliability::BestEffort } else { Reliability::Reliable };
        let p = Participant::new(DomainConfig::loopback(domain)).expect("participant");
        let r = p
            .reader_with(&TopicSpec::lowstate(Family::Hg), ReaderOptions { reliability, ..ReaderOptions::default() })
            .expect("reader");
        got += usize::from(r.take(Duration::from_secs(10)).is_some());
        cycles += 1;
    }
    println!("CHURN cycles {cycles} got {got}");
}
