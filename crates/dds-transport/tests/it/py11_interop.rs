//! Interop with Cyclone DDS 11 through its Python binding (typed topics with XTypes type
//! information, Unitree's generated Python types), in both directions.

use crate::common;

use common::*;
use dds_transport::{topics::Family, DomainConfig, Participant, TopicSpec};
use std::process::Command;
use std::time::{Duration, Instant};

fn py_peer() -> Command {
    let mut c = Command::new(python());
    c.arg(crate_dir().join("tests/peers/py11/peer.py"));
    c
}

fn json_lines(out: &str) -> Vec<serde_json::Value> {
    out.lines().filter_map(|l| serde_json::from_str(l).ok()).collect()
}

fn echo_round_trip(domain: u32, sdk_config: bool) {
    let p = Participant::new(DomainConfig::loopback(domain)).expect("participant");
    let cmd_w = p.writer(&TopicSpec::lowcmd(Family::Hg)).expect("writer");
    let state_r = p.reader(&TopicSpec::lowstate(Family::Hg)).expect("reader");
    let mut cmd = py_peer();
    cmd.args(["echo", "--domain", &domain.to_string(), "--seconds", "120"]);
    if sdk_config {
        cmd.arg("--sdk");
    }
    let peer = Proc::spawn(&mut cmd);
    assert!(cmd_w.wait_for_readers(1, PATIENCE).expect("status"), "Python reader never matched");
    let q = |i: usize| -1.0 + i as f32 * 0.03125;
    let payload = hg_lowcmd(q, 7.0, 77);
    let deadline = Instant::now() + PATIENCE;
    let mut echoed = None;
    while Instant::now() < deadline && echoed.is_none() {
        cmd_w.write(&payload).expect("write");
        std::thread::sleep(Duration::from_millis(10));
        while let Some(s) = state_r.try_take() {
            assert_eq!(s.data.len(), HG_LOWSTATE_LEN);
            if hg_lowstate_reserve(&s.data, 0).unwrap_or(0) > 0 {
                echoed = Some(s);
            }
        }
    }
    let echoed = echoed.expect("Python peer never echoed our command");
    assert_eq!(hg_lowstate_q(&echoed.data, 0), Some(q(0)));
    assert_eq!(hg_lowstate_q(&echoed.data, 34), Some(q(34)));
    assert_eq!(hg_lowstate_reserve(&echoed.data, 1), Some(77));
    drop(peer); // killed: it has proven what it had to
}

#[test]
fn py11_peer_decodes_our_lowcmd_and_we_receive_its_lowstate() {
    echo_round_trip(lease_domain().id(), false);
}

/// The Python peer configured exactly as unitree_sdk2py's ChannelFactoryInitialize(D, "lo") does.
#[test]
fn py11_peer_with_unitree_sdk_config_is_discovered() {
    echo_round_trip(lease_domain().id(), true);
}

#[test]
fn py11_typed_writer_to_our_reader() {
    let domain = lease_domain();
    let p = Participant::new(DomainConfig::loopback(domain.id())).expect("participant");
    let r = p.reader(&TopicSpec::lowcmd(Family::Hg)).expect("reader");
    // The Python writer waits (up to a minute) for our reader before it publishes.
    let peer = Proc::spawn(py_peer().args([
        "pub-lowcmd",
        "--domain",
        &domain.arg(),
        "--count",
        "50",
        "--rate",
        "100",
        "--match-timeout",
        "60",
    ]));
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(120);
    while Instant::now() < deadline && got.len() < 20 {
        if let Some(s) = r.take(Duration::from_millis(50)) {
            got.push(s);
        }
    }
    let (code, out, err) = peer.wait(Duration::from_secs(120));
    assert_eq!(code, Some(0), "python peer failed:\n{out}\n{err}");
    assert!(json_lines(&out).iter().any(|v| v["event"] == "done"));
    assert!(got.len() >= 20, "received only {} samples", got.len());
    for s in &got {
        assert_eq!(s.data.len(), HG_LOWCMD_LEN);
        assert_eq!(&s.data[..4], &[0, 1, 0, 0]);
        let crc = u32::from_le_bytes(s.data[1000..1004].try_into().expect("4 bytes"));
        let kp0 = f32::from_le_bytes(s.data[20..24].try_into().expect("4 bytes"));
        assert_eq!(crc, 1000 + kp0 as u32, "sample fields consistent");
        let q34 = f32::from_le_bytes(s.data[4 + 28 * 34 + 4..4 + 28 * 34 + 8].try_into().expect("4 bytes"));
        assert_eq!(q34, (0.5f64 + 0.01 * 34.0) as f32);
    }
}

/// What a Cyclone 11 peer sees of our endpoints in discovery: Unitree's QoS and no XTypes type
/// information, while its own typed control writer does carry type information.
#[test]
fn our_endpoints_advertise_unitree_qos_and_no_type_information() {
    let lease = lease_domain();
    let domain = lease.id();
    let p = Participant::new(DomainConfig::loopback(domain)).expect("participant");
    let _w = p.writer(&TopicSpec::lowcmd(Family::Hg)).expect("writer");
    let _r = p.reader(&TopicSpec::lowstate(Family::Hg)).expect("reader");
    let (ok, out, err) = run_with_timeout(
        py_peer().args(["discover", "--domain", &domain.to_string(), "--seconds", "10"]),
        Duration::from_secs(120),
    );
    assert!(ok, "{out}\n{err}");
    let eps: Vec<serde_json::Value> = json_lines(&out).into_iter().filter(|v| v["event"] == "endpoint").collect();
    let find = |kind: &str, topic: &str, local: bool| {
        eps.iter()
            .find(|e| e["kind"] == kind && e["topic"] == topic && e["local"] == local)
            .unwrap_or_else(|| panic!("no {kind} {topic} local={local} in:\n{out}"))
            .clone()
    };
    let w = find("publication", "rt/lowcmd", false);
    assert_eq!(w["type"], "unitree_hg::msg::dds_::LowCmd_");
    assert_eq!(w["has_type_info"], false, "{w}");
    assert!(w["qos"]["reliability"].as_str().unwrap_or("").contains("Reliable"), "{w}");
    assert_eq!(w["qos"]["history"], "Policy.History.KeepLast(depth=1)");
    assert_eq!(w["qos"]["durability"], "Policy.Durability.Volatile");
    let r = find("subscription", "rt/lowstate", false);
    assert_eq!(r["type"], "unitree_hg::msg::dds_::LowState_");
    assert_eq!(r["has_type_info"], false, "{r}");
    assert_eq!(r["qos"]["reliability"], "Policy.Reliability.BestEffort");
    assert_eq!(r["qos"]["history"], "Policy.History.KeepLast(depth=1)");
    // Control: the peer's own typed writer carries type information, so the check can fail.
    assert_eq!(find("publication", "rt/lowcmd", true)["has_type_info"], true);
}

/// Our discovery monitor sees a remote typed (Cyclone 11, Python) writer with its type
/// information and QoS.
#[test]
fn discovery_monitor_sees_remote_type_information() {
    use dds_transport::{EndpointKind, Reliability};
    let lease = lease_domain();
    let domain = lease.id();
    let p = Participant::new(DomainConfig::loopback(domain)).expect("participant");
    let mon = p.discovery().expect("discovery");
    let _r = p.reader(&TopicSpec::lowcmd(Family::Hg)).expect("reader");
    let peer = Proc::spawn(py_peer().args([
        "pub-lowcmd",
        "--domain",
        &domain.to_string(),
        "--count",
        "3000",
        "--rate",
        "100",
    ]));
    let w = mon
        .wait_for(PATIENCE, |e| {
            e.alive && !e.local && e.kind == EndpointKind::Publication && e.topic_name == "rt/lowcmd"
        })
        .expect("read");
    drop(peer);
    let w = w.expect("the Python writer shows up in discovery");
    assert_eq!(w.type_name, "unitree_hg::msg::dds_::LowCmd_");
    assert!(w.has_type_information, "a typed Cyclone 11 writer carries type information");
    assert_eq!(w.reliability, Some(Reliability::Reliable));
}
