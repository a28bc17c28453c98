//! Control experiments showing that the Cyclone 0.10.2 interop test can fail: each recreates one
//! of the two hazards measured on this machine (default discovery settings find no 0.10.2 peer on
//! `lo`; XTypes type information from a Cyclone 11 participant crashes it). They test Cyclone's
//! behaviour rather than ours: if a distribution update changes the outcome, revisit
//! `c010_interop.rs` rather than deleting these.

use crate::common;

use common::*;
use dds_transport::{topics::Family, DomainConfig, Participant, ParticipantIndex, TopicSpec};
use std::process::Command;
use std::time::Duration;

/// With Cyclone's default discovery settings (no participant index, no peers) our participant
/// and a 0.10.2 peer on `lo` never see each other.
#[test]
fn default_discovery_settings_do_not_find_a_010_peer() {
    let peer_bin = build_c010_peer();
    let domain = lease_domain();
    let cfg = DomainConfig::loopback(domain.id())
        .participant_index(ParticipantIndex::CycloneDefault)
        .peers(Vec::<String>::new());
    let p = Participant::new(cfg).expect("participant");
    let w = p.writer(&TopicSpec::lowcmd(Family::Hg)).expect("writer");
    let peer = Proc::spawn(Command::new(&peer_bin).arg(domain.arg()).arg("lo").arg("4"));
    assert!(!w.wait_for_readers(1, Duration::from_secs(3)).expect("status"), "matched without the discovery settings");
    let _ = peer.wait(Duration::from_secs(10));
}

/// A Cyclone 11 participant that sends XTypes type information (the Python binding with a typed
/// topic) makes the 0.10.2 peer log `invalid type object` and crash.
#[test]
fn typed_cyclone11_writer_crashes_a_010_peer() {
    let peer_bin = build_c010_peer();
    let domain = lease_domain();
    // The peer is expected to crash: no core file (`ulimit -c 0`).
    let peer = Proc::spawn(Command::new("sh").arg("-c").arg("ulimit -c 0; exec \"$0\" \"$@\"").arg(&peer_bin).args([
        domain.arg().as_str(),
        "lo",
        "60",
    ]));
    // The typed writer waits (up to a minute) for the peer's reader, so discovery happens whatever the load; the
    // peer crashes on the writer's discovery data or lives out its 60 s (then the control fails).
    let _writer = Proc::spawn(Command::new(python()).arg(crate_dir().join("tests/peers/py11/peer.py")).args([
        "pub-lowcmd",
        "--domain",
        &domain.arg(),
        "--count",
        "6000",
        "--match-timeout",
        "60",
    ]));
    let (code, out, err) = peer.wait(Duration::from_secs(90));
    let all = format!("{out}\n{err}");
    assert!(code != Some(0) || all.contains("invalid type object"), "0.10.2 peer survived a typed 11.x writer:\n{all}");
}
