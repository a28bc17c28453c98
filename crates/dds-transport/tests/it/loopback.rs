//! In-process round trips on loopback: writer and reader of this crate talk to each other.

use dds_transport::{topics::Family, DomainConfig, Error, Participant, ReaderOptions, TopicSpec};
use std::sync::mpsc;
use test_support::{lease_domain, PATIENCE};

#[test]
fn raw_bytes_round_trip_in_process() {
    let domain = lease_domain();
    let p = Participant::new(DomainConfig::loopback(domain.id())).expect("participant");
    let topic = TopicSpec::lowstate(Family::Hg);
    let r = p.reader_with(&topic, ReaderOptions { queue_capacity: 64, ..ReaderOptions::default() }).expect("reader");
    let w = p.writer(&topic).expect("writer");
    assert!(w.wait_for_readers(1, PATIENCE).expect("status"));
    // Arbitrary bytes, including a large fragmented one and garbage behind a valid header.
    let payloads: Vec<Vec<u8>> = vec![
        vec![0, 1, 0, 0],
        vec![0, 1, 0, 0, 1, 2, 3],
        (0..5000u32).map(|i| (i % 251) as u8).collect(),
        vec![0xff; 17],
    ];
    for pl in &payloads {
        w.write(pl).expect("write");
        let s = r.take(PATIENCE).expect("sample");
        assert_eq!(&s.data, pl);
        assert!(s.reception_ns > 0);
        let ts = s.source_timestamp_ns.expect("source timestamp");
        assert!((s.reception_ns - ts).abs() < 5_000_000_000);
    }
    assert!(matches!(w.write(&[0, 1, 0]), Err(Error::PayloadTooShort { len: 3 })));
}

#[test]
fn callback_reader_receives() {
    let domain = lease_domain();
    let p = Participant::new(DomainConfig::loopback(domain.id())).expect("participant");
    let topic = TopicSpec::lowcmd(Family::Go);
    let (tx, rx) = mpsc::channel();
    let r = p
        .reader_with_callback(&topic, ReaderOptions::default(), move |s| {
            let _ = tx.send(s.data);
        })
        .expect("reader");
    let w = p.writer(&topic).expect("writer");
    assert!(w.wait_for_readers(1, PATIENCE).expect("status"));
    w.write(&[0, 1, 0, 0, 9, 9]).expect("write");
    assert_eq!(rx.recv_timeout(PATIENCE).expect("callback"), vec![0, 1, 0, 0, 9, 9]);
    assert_eq!(r.received(), 1);
    drop(r);
}

#[test]
fn safety_rule_enforced() {
    assert!(matches!(Participant::new(DomainConfig::loopback(0)), Err(Error::RobotNotAllowed { .. })));
    // Same domain, different configuration in one process: refused.
    let lease = lease_domain();
    let d = lease.id();
    let _a = Participant::new(DomainConfig::loopback(d)).expect("participant");
    let b = Participant::new(DomainConfig::loopback(d).peers(Vec::<String>::new()));
    assert!(matches!(b, Err(Error::DomainConfigConflict { domain }) if domain == d));
    // Same configuration: shared.
    let _c = Participant::new(DomainConfig::loopback(d)).expect("second participant");
}

#[test]
fn discovery_shows_our_endpoints_without_type_information() {
    use dds_transport::{Durability, EndpointKind, Reliability};
    let domain = lease_domain();
    let p = Participant::new(DomainConfig::loopback(domain.id())).expect("participant");
    let mon = p.discovery().expect("discovery");
    let _w = p.writer(&TopicSpec::lowstate(Family::Hg)).expect("writer");
    let _r = p.reader(&TopicSpec::lowcmd(Family::Hg)).expect("reader");
    let w = mon
        .wait_for(PATIENCE, |e| e.kind == EndpointKind::Publication && e.topic_name == "rt/lowstate")
        .expect("read")
        .expect("our writer is announced");
    assert!(w.local && w.alive);
    assert_eq!(w.type_name, "unitree_hg::msg::dds_::LowState_");
    assert!(!w.has_type_information);
    assert_eq!(
        (w.reliability, w.history_depth, w.durability),
        (Some(Reliability::Reliable), Some(1), Some(Durability::Volatile))
    );
    let r = mon
        .wait_for(PATIENCE, |e| e.kind == EndpointKind::Subscription && e.topic_name == "rt/lowcmd")
        .expect("read")
        .expect("our reader is announced");
    assert!(!r.has_type_information);
    assert_eq!((r.reliability, r.history_depth), (Some(Reliability::BestEffort), Some(1)));
}
