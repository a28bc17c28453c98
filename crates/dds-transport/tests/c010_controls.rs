//! Control experiments showing that the Cyclone 0.10.2 interop test can fail: each recreates one
//! of the two hazards measured on this machine (default discovery settings find no 0.10.2 peer on
//! `lo`; XTypes type information from a Cyclone 11 participant crashes it). They test Cyclone's
//! behaviour rather than ours: if a distribution update changes the outcome, revisit
//! `c010_interop.rs` rather than deleting these.

mod common;

use common::*;
use dds_transport::{topics::Family, DomainConfig, Participant, ParticipantIndex, TopicSpec};
use std::process::Command;
use std::time::Duration;

/// With Cyclone's default discovery settings (no participant index, no peers) our participant
/// and a 0.10.2 peer on `lo` never see each other.
#[test]
fn default_discovery_settings_do_not_find_a_010_peer() {
    let peer_bin = build_c010_peer();
    let cfg =
        DomainConfig::loopback(162).participant_index(ParticipantIndex::CycloneDefault).peers(Vec::<String>::new());
    let p = Participant::new(cfg).expect("participant");
    let w = p.writer(&TopicSpec::lowcmd(Family::Hg)).expect("writer");
    let peer = Proc::spawn(Command::new(&peer_bin).arg("162").arg("lo").arg("4"));
    assert!(!w.wait_for_readers(1, Duration::from_secs(3)).expect("status"), "matched without the discovery settings");
    let _ = peer.wait(Duration::from_secs(10));
}

/// A Cyclone 11 participant that sends XTypes type information (the Python binding with a typed
/// topic) makes the 0.10.2 peer log `invalid type object` and crash.
#[test]
fn typed_cyclone11_writer_crashes_a_010_peer() {
    let peer_bin = build_c010_peer();
    // The peer is expected to crash: no core file (`ulimit -c 0`).
    let peer = Proc::spawn(
        Command::new("sh").arg("-c").arg("ulimit -c 0; exec \"$0\" \"$@\"").arg(&peer_bin).args(["163", "lo", "20"]),
    );
    std::thread::sleep(Duration::from_millis(300));
    let (_ok, _o, _e) = run_with_timeout(
        Command::new(python()).arg(crate_dir().join("tests/peers/py11/peer.py")).args([
            "pub-lowcmd",
            "--domain",
            "163",
            "--count",
            "200",
        ]),
        Duration::from_secs(20),
    );
    let (code, out, err) = peer.wait(Duration::from_secs(15));
    let all = format!("{out}\n{err}");
    assert!(code != Some(0) || all.contains("invalid type object"), "0.10.2 peer survived a typed 11.x writer:\n{all}");
}
