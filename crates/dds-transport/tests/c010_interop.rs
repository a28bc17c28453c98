//! Interop with a real Cyclone DDS 0.10.2 peer (Debian's libddsc, the version in Unitree's SDK
//! and robots), which configures itself like Unitree SDK2 (interface only, all else default).
//!
//! Proves: discovery in both directions on `lo`; our LowCmd reaches it and decodes with its own
//! idlc-generated type; its LowState reaches us; and the 0.10.2 peer neither crashes nor logs
//! `invalid type object` (it did both with a Cyclone 11 participant that sends XTypes type info).

mod common;

use common::*;
use dds_transport::{topics::Family, DomainConfig, Durability, EndpointKind, Participant, Reliability, TopicSpec};
use std::process::Command;
use std::time::{Duration, Instant};

const DOMAIN: u32 = 161;

#[test]
fn c010_peer_exchanges_lowcmd_and_lowstate_both_ways() {
    let peer_bin = build_c010_peer();
    let p = Participant::new(DomainConfig::loopback(DOMAIN)).expect("participant");
    let cmd_w = p.writer(&TopicSpec::lowcmd(Family::Hg)).expect("writer");
    let state_r = p.reader(&TopicSpec::lowstate(Family::Hg)).expect("reader");

    let discovery = p.discovery().expect("discovery");
    let mut peer = Proc::spawn(Command::new(&peer_bin).arg(DOMAIN.to_string()).arg("lo").arg("30"));

    assert!(
        cmd_w.wait_for_readers(1, Duration::from_secs(15)).expect("status"),
        "0.10.2 reader never matched our writer"
    );
    assert!(
        state_r.wait_for_writers(1, Duration::from_secs(15)).expect("status"),
        "0.10.2 writer never matched our reader"
    );

    // Send commands with a distinctive pattern until the peer echoes them back in LowState.
    let q = |i: usize| 0.25 + i as f32 * 0.01;
    let cmd = hg_lowcmd(q, 42.5, 0xC0FFEE);
    let deadline = Instant::now() + Duration::from_secs(15);
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
    assert_eq!(hg_lowstate_reserve(&echoed.data, 1), Some(0xC0FFEE), "crc echoed");

    // What the 0.10.2 peer (default QoS, like Unitree's SDK) announces in discovery.
    let find = |kind: EndpointKind, topic: &str| {
        discovery
            .wait_for(Duration::from_secs(5), |e| {
                e.alive && !e.local && e.kind == kind && e.topic_name == topic
            })
            .expect("endpoints")
            .unwrap_or_else(|| panic!("0.10.2 {kind:?} on {topic} not in discovery"))
    };
    let peer_reader = find(EndpointKind::Subscription, "rt/lowcmd");
    assert_eq!(peer_reader.type_name, "unitree_hg::msg::dds_::LowCmd_");
    assert_eq!(
        (peer_reader.reliability, peer_reader.history_depth),
        (Some(Reliability::BestEffort), Some(1))
    );
    let peer_writer = find(EndpointKind::Publication, "rt/lowstate");
    assert_eq!(peer_writer.reliability, Some(Reliability::Reliable));
    assert_eq!(
        (peer_writer.history_depth, peer_writer.durability),
        (Some(1), Some(Durability::Volatile))
    );
    // 0.10.2's own type information (from idlc) is harmless to us: we got here.
    assert!(peer_writer.has_type_information);

    // Ask the peer to exit (best effort: repeat until it has).
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline && !peer.has_exited() {
        cmd_w.write(&hg_lowcmd_shutdown()).expect("write");
        std::thread::sleep(Duration::from_millis(50));
    }
    let (code, out, err) = peer.wait(Duration::from_secs(5));
    let all = format!("{out}\n{err}");
    assert!(
        !all.contains("invalid type object"),
        "0.10.2 peer rejected type information:\n{all}"
    );
    assert_eq!(code, Some(0), "0.10.2 peer did not exit cleanly:\n{all}");
    assert!(
        out.contains("CMD n=1 mode_pr=0 mode_machine=6 m0.mode=1 m0.q=0.250000 m0.kp=42.500"),
        "{all}"
    );
    assert!(out.contains("m34.q=0.590000 crc=12648430"), "{all}");
    assert!(out.contains("SHUTDOWN"), "{all}");
}
