//! Interop with a real Cyclone DDS 0.10.2 peer (Debian's libddsc, the version in Unitree's SDK
//! and robots), which configures itself like Unitree SDK2 (interface only, all else default).
//!
//! Proves: discovery in both directions on `lo`; our LowCmd reaches it and decodes with its own
//! idlc-generated type; its LowState reaches us; and the 0.10.2 peer neither crashes nor logs
//! `invalid type object` (it did both with a Cyclone 11 participant that sends XTypes type info).

use crate::common;

use common::*;
use dds_transport::{topics::Family, DomainConfig, Durability, EndpointKind, Participant, Reliability, TopicSpec};
use lowlevel_codec::Encoding;
use std::process::Command;
use std::time::{Duration, Instant};
use unitree_idl::hg;

#[test]
fn c010_peer_exchanges_lowcmd_and_lowstate_both_ways() {
    let peer_bin = build_c010_peer();
    let domain = lease_domain();
    let p = Participant::new(DomainConfig::loopback(domain.id())).expect("participant");
    let cmd_w = p.writer(&TopicSpec::lowcmd(Family::Hg)).expect("writer");
    let state_r = p.reader(&TopicSpec::lowstate(Family::Hg)).expect("reader");

    let discovery = p.discovery().expect("discovery");
    let mut peer = Proc::spawn(Command::new(&peer_bin).arg(domain.arg()).arg("lo").arg("120"));

    assert!(cmd_w.wait_for_readers(1, PATIENCE).expect("status"), "0.10.2 reader never matched our writer");
    assert!(state_r.wait_for_writers(1, PATIENCE).expect("status"), "0.10.2 writer never matched our reader");

    // Send commands with a distinctive pattern until the peer echoes them back in LowState.
    // A command built and sealed by our codec; the peer checks the CRC with Unitree's algorithm.
    let q = |i: usize| 0.25 + i as f32 * 0.01;
    let mut c = hg::LowCmd_ { mode_machine: 6, ..Default::default() };
    for (i, m) in c.motor_cmd.iter_mut().enumerate() {
        m.mode = 1;
        m.q = q(i);
    }
    c.motor_cmd[0].kp = 42.5;
    lowlevel_codec::seal(&mut c);
    let sealed_crc = c.crc;
    let cmd = lowlevel_codec::encode(&c, Encoding::UNITREE);
    let deadline = Instant::now() + PATIENCE;
    let mut states = 0usize;
    let mut last_tick = None;
    let mut echoed = None;
    while Instant::now() < deadline && echoed.is_none() {
        cmd_w.write(&cmd).expect("write");
        std::thread::sleep(Duration::from_millis(10));
        while let Some(s) = state_r.try_take() {
            assert_eq!(s.data.len(), HG_LOWSTATE_LEN, "LowState size");
            assert_eq!(&s.data[..4], &[0, 1, 0, 0], "encapsulation header CDR_LE");
            assert!(s.source_timestamp_ns.is_some());
            states += 1;
            last_tick = hg_lowstate_tick(&s.data);
            if hg_lowstate_reserve(&s.data, 0).unwrap_or(0) > 0 {
                echoed = Some(s);
            }
        }
    }
    let echoed = echoed.expect("the 0.10.2 peer never echoed a command");
    assert!(states > 0 && last_tick.unwrap_or(0) > 0);
    for i in [0usize, 1, 17, 34] {
        assert_eq!(hg_lowstate_q(&echoed.data, i), Some(q(i)), "motor {i} q echoed");
    }
    assert_eq!(hg_lowstate_reserve(&echoed.data, 1), Some(sealed_crc), "crc echoed");
    // Its state decodes with our codec and its CRC (computed in C) verifies with ours.
    let state = lowlevel_codec::decode::<hg::LowState_>(&echoed.data).expect("decode").value;
    assert!(lowlevel_codec::verify(&state), "0.10.2 peer's LowState CRC");
    assert!(state.reserve[2] >= 1 && state.reserve[2] == state.reserve[0], "peer found our command CRCs valid");

    // What the 0.10.2 peer (default QoS, like Unitree's SDK) announces in discovery.
    let find = |kind: EndpointKind, topic: &str| {
        discovery
            .wait_for(PATIENCE, |e| e.alive && !e.local && e.kind == kind && e.topic_name == topic)
            .expect("endpoints")
            .unwrap_or_else(|| panic!("0.10.2 {kind:?} on {topic} not in discovery"))
    };
    let peer_reader = find(EndpointKind::Subscription, "rt/lowcmd");
    assert_eq!(peer_reader.type_name, "unitree_hg::msg::dds_::LowCmd_");
    assert_eq!((peer_reader.reliability, peer_reader.history_depth), (Some(Reliability::BestEffort), Some(1)));
    let peer_writer = find(EndpointKind::Publication, "rt/lowstate");
    assert_eq!(peer_writer.reliability, Some(Reliability::Reliable));
    assert_eq!((peer_writer.history_depth, peer_writer.durability), (Some(1), Some(Durability::Volatile)));
    // 0.10.2's own type information (from idlc) is harmless to us: we got here.
    assert!(peer_writer.has_type_information);

    // Ask the peer to exit (best effort: repeat until it has).
    let deadline = Instant::now() + PATIENCE;
    while Instant::now() < deadline && !peer.has_exited() {
        cmd_w.write(&hg_lowcmd_shutdown()).expect("write");
        std::thread::sleep(Duration::from_millis(50));
    }
    let (code, out, err) = peer.wait(Duration::from_secs(30));
    let all = format!("{out}\n{err}");
    assert!(!all.contains("invalid type object"), "0.10.2 peer rejected type information:\n{all}");
    assert_eq!(code, Some(0), "0.10.2 peer did not exit cleanly:\n{all}");
    assert!(out.contains("CMD n=1 mode_pr=0 mode_machine=6 m0.mode=1 m0.q=0.250000 m0.kp=42.500"), "{all}");
    assert!(out.contains(&format!("m34.q=0.590000 crc={sealed_crc} crc_ok=1")), "{all}");
    assert!(out.contains("SHUTDOWN"), "{all}");
}

/// The 0.10.2 peer as a Unitree-style low-level controller, our transport as the robot: it reads
/// our LowState (CRC and ticks checked in C), drives one joint, and its sealed LowCmd decodes and
/// verifies with our codec. The toy robot runs until the controller has ended (10 s of its own time,
/// discovery included), so a loaded machine only makes it slower; the controller's wall-clock state rate
/// is printed, never judged.
#[test]
fn c010_controller_drives_a_robot_on_our_transport() {
    const JOINT: usize = 3;
    const TARGET: f32 = 0.4;
    let peer_bin = build_c010_peer();
    let domain = lease_domain();
    let _slot = RealtimeSlot::acquire();
    let p = Participant::new(DomainConfig::loopback(domain.id())).expect("participant");
    let state_w = p.writer(&TopicSpec::lowstate(Family::Hg)).expect("writer");
    let cmd_r = p.reader(&TopicSpec::lowcmd(Family::Hg)).expect("reader");
    let mut peer = Proc::spawn(Command::new(&peer_bin).args([
        domain.arg().as_str(),
        "lo",
        "10",
        "controller",
        "3",
        "0.4",
        "60",
        "2",
    ]));

    // A toy robot at 500 Hz: joint JOINT moves 2% of the way to a valid command's target per tick.
    let mut state = hg::LowState_ { mode_machine: 6, ..Default::default() };
    state.imu_state.quaternion[0] = 1.0;
    let (mut cmds, mut bad_crc) = (0u32, 0u32);
    let start = Instant::now();
    let mut next = start;
    while !peer.has_exited() && start.elapsed() < Duration::from_secs(120) {
        while let Some(s) = cmd_r.try_take() {
            match lowlevel_codec::decode::<hg::LowCmd_>(&s.data) {
                Ok(d) if lowlevel_codec::verify(&d.value) => {
                    cmds += 1;
                    let m = &d.value.motor_cmd[JOINT];
                    assert_eq!((d.value.mode_machine, m.mode, m.q, m.kp), (6, 1, TARGET, 60.0));
                    state.motor_state[JOINT].q += 0.02 * (m.q - state.motor_state[JOINT].q);
                }
                _ => bad_crc += 1,
            }
        }
        state.tick = state.tick.wrapping_add(2);
        lowlevel_codec::seal(&mut state);
        state_w.write(&lowlevel_codec::encode(&state, Encoding::UNITREE)).expect("write");
        next += Duration::from_millis(2);
        if let Some(d) = next.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
    }
    let (code, out, err) = peer.wait(Duration::from_secs(15));
    assert_eq!(code, Some(0), "{out}\n{err}");
    let report: serde_json::Value = out
        .lines()
        .rev()
        .find_map(|l| serde_json::from_str(l).ok())
        .unwrap_or_else(|| panic!("no report:\n{out}\n{err}"));
    let states = report["states"].as_u64().expect("states");
    assert!(states > 200, "{report}");
    assert_eq!(report["crc_ok"].as_u64(), Some(states), "our LowState CRCs verified in C: {report}");
    assert_eq!(report["ticks_increasing"], true);
    // The joint converged: 0.98^n of the way left after n applied commands, so at least ~185 reached the robot.
    assert!((report["last_q"].as_f64().unwrap_or(0.0) - f64::from(TARGET)).abs() < 0.01, "{report}");
    assert!(cmds > 200 && bad_crc == 0, "commands {cmds}, bad CRC {bad_crc}");
    eprintln!("0.10.2 controller: {states} states at {} Hz wall, {cmds} commands", report["rate_hz"]);
}
