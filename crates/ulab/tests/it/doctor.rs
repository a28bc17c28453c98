//! `ulab doctor` against our own peers, each with one planted misconfiguration, and the doctor must name it:
//! * wrong domain: `ulab sim` on one domain, the client's domain another (`wrong-domain`, naming the sim's);
//! * a typed Cyclone 11 writer (XTypes type information, the Python binding) next to a Cyclone 0.10.2 peer
//!   (Debian's libddsc, the C peer of the interop tests): `xtypes-with-0.10`;
//! * nothing publishes rt/lowstate (the 0.10.2 peer as a controller only): `no-lowstate`;
//! * wrong type name (a unitree_go reader of rt/lowstate beside the sim's unitree_hg writer): `type-mismatch`;
//! * QoS that cannot match (a transient-local reader of the sim's volatile writer): `qos-incompatible`;
//! * an interface without multicast (`lo`): `no-multicast`, a warning; with the sim healthy the exit code is 0.
//!
//! What the doctor reports of the peers is checked against what they are: Cyclone 0.10.2 (Debian's library)
//! announces product version 0.10.2 and RTPS 2.1, Cyclone 11 (the Python wheel, our transport) 11.x; the
//! typed Python writer carries type information, our transport's endpoints none. Every test leases its domains
//! and holds the real-time slot (peers run in real time).

use crate::common;

use common::{lease_domain, python, root, spawn_ulab, tail, wait_with_timeout, KillOnDrop, RealtimeSlot, PATIENCE};
use dds_transport::{DomainConfig, EndpointKind, Participant};
use serde_json::Value;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn py11(args: &[&str]) -> KillOnDrop {
    let child = Command::new(python())
        .arg(root().join("crates/dds-transport/tests/peers/py11/peer.py"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start the Python Cyclone 11 peer");
    KillOnDrop(Some(child))
}

fn sim(domain: &str) -> KillOnDrop {
    let child = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["sim", "--domain", domain, "--quiet", "--loco-api", "none"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start ulab sim");
    KillOnDrop(Some(child))
}

/// The Cyclone 0.10.2 C peer (built like the interop tests build it).
fn c010_peer() -> PathBuf {
    let src = root().join("crates/dds-transport/tests/peers/c010");
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("doctor-c010-{}", std::process::id()));
    let status = Command::new("make")
        .arg("-s")
        .arg("-f")
        .arg(src.join("Makefile"))
        .arg(format!("OUT={}", out.display()))
        .status()
        .expect("make");
    assert!(status.success(), "building the Cyclone 0.10.2 peer (needs cyclonedds-dev, cyclonedds-tools)");
    out.join("peer")
}

fn spawn(cmd: &mut Command) -> KillOnDrop {
    KillOnDrop(Some(cmd.stdout(Stdio::null()).stderr(Stdio::null()).spawn().expect("start peer")))
}

/// Waits (in this process, with our transport) until some participant on `domain` announces a `kind` endpoint
/// on `topic`: the peer is up before the doctor looks.
fn wait_for_endpoint(domain: u32, kind: EndpointKind, topic: &str) {
    let p = Participant::new(DomainConfig::loopback(domain)).expect("participant");
    let m = p.discovery().expect("discovery");
    let deadline = Instant::now() + PATIENCE;
    loop {
        let endpoints = m.endpoints().expect("discovery");
        if endpoints.iter().any(|e| !e.local && e.alive && e.kind == kind && e.topic_name == topic) {
            return;
        }
        assert!(Instant::now() < deadline, "no {kind:?} on {topic} appeared on domain {domain}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Runs `ulab doctor --format json` with `args`; (exit code, report).
fn doctor(args: &[&str]) -> (Option<i32>, Value) {
    let mut all = vec!["doctor", "--format", "json", "--seconds", "3"];
    all.extend_from_slice(args);
    let child: Child = spawn_ulab(&all);
    let (status, out, err) = wait_with_timeout(child, Duration::from_secs(120));
    let report: Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("doctor output: {e}\n{}\n{}", tail(&out), tail(&err)));
    (status.and_then(|s| s.code()), report)
}

fn codes(report: &Value) -> Vec<String> {
    report["findings"]
        .as_array()
        .map_or_else(Vec::new, |f| f.iter().filter_map(|x| x["code"].as_str().map(str::to_owned)).collect())
}

fn finding<'a>(report: &'a Value, code: &str) -> &'a Value {
    report["findings"]
        .as_array()
        .and_then(|f| f.iter().find(|x| x["code"] == code))
        .unwrap_or_else(|| panic!("no `{code}` finding in {}", report["findings"]))
}

fn participants(report: &Value) -> &Vec<Value> {
    report["participants"].as_array().expect("participants")
}

/// The participant with an endpoint of `kind` on `topic`.
fn with_endpoint<'a>(ps: &'a [Value], kind: &str, topic: &str) -> &'a Value {
    ps.iter()
        .find(|p| p["endpoints"].as_array().is_some_and(|e| e.iter().any(|e| e["kind"] == kind && e["topic"] == topic)))
        .unwrap_or_else(|| panic!("no participant with a {kind} on {topic}: {ps:?}"))
}

#[test]
fn healthy_sim_exits_0_and_lo_has_no_multicast() {
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let _sim = sim(&domain.arg());
    wait_for_endpoint(domain.id(), EndpointKind::Publication, "rt/lowstate");
    let (code, r) = doctor(&["--domain", &domain.arg()]);
    assert_eq!(code, Some(0), "findings: {}", r["findings"]);
    let f = finding(&r, "no-multicast");
    assert_eq!(f["severity"], "warning");
    assert!(f["message"].as_str().is_some_and(|m| m.contains("interface lo is not multicast-capable")), "{f}");
    let lo = r["interfaces"].as_array().and_then(|i| i.iter().find(|i| i["name"] == "lo")).expect("lo listed");
    assert_eq!((lo["loopback"].as_bool(), lo["multicast_flag"].as_bool()), (Some(true), Some(false)));
    // Our sim: Cyclone 11 (cyclors), its writer without type information, the hg types.
    let p = with_endpoint(participants(&r), "writer", "rt/lowstate");
    assert_eq!(p["vendor"], "Eclipse Cyclone DDS");
    assert!(p["product_version"].as_str().is_some_and(|v| v.starts_with("0.11") || v.starts_with("11")), "{p}");
    let w = p["endpoints"].as_array().and_then(|e| e.iter().find(|e| e["topic"] == "rt/lowstate")).expect("writer");
    assert_eq!(w["type_name"], "unitree_hg::msg::dds_::LowState_");
    assert_eq!((w["reliability"].as_str(), w["type_information"].as_bool()), (Some("reliable"), Some(false)));
}

#[test]
fn wrong_domain_is_named() {
    let _slot = RealtimeSlot::acquire();
    let (robot, client) = (lease_domain(), lease_domain());
    let _sim = sim(&robot.arg());
    wait_for_endpoint(robot.id(), EndpointKind::Publication, "rt/lowstate");
    let (code, r) = doctor(&["--domain", &client.arg(), "--scan-domains", &robot.arg()]);
    assert_eq!(code, Some(1));
    let msg = finding(&r, "wrong-domain")["message"].as_str().expect("message").to_owned();
    assert!(
        msg.contains(&format!("nothing publishes rt/lowstate on domain {}", client.id()))
            && msg.contains(&format!("a participant on domain {} does", robot.id())),
        "{msg}"
    );
    assert!(codes(&r).contains(&"no-participants".to_owned()), "{:?}", codes(&r));
}

#[test]
fn typed_cyclone11_writer_next_to_a_010_peer_is_named() {
    let peer_bin = c010_peer();
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    // The 0.10.2 peer plays the robot (rt/lowstate out, rt/lowcmd in); no core file when it crashes.
    let _robot = spawn(Command::new("sh").arg("-c").arg("ulimit -c 0; exec \"$0\" \"$@\"").arg(&peer_bin).args([
        domain.arg().as_str(),
        "lo",
        "60",
    ]));
    wait_for_endpoint(domain.id(), EndpointKind::Publication, "rt/lowstate");
    // The doctor starts first (its probe answers within a few hundred ms); the typed writer a moment later.
    let doctor_child = spawn_ulab(&["doctor", "--format", "json", "--seconds", "6", "--domain", &domain.arg()]);
    std::thread::sleep(Duration::from_millis(500));
    let _typed = py11(&["pub-lowcmd", "--domain", &domain.arg(), "--count", "3000", "--match-timeout", "30"]);
    let (status, out, err) = wait_with_timeout(doctor_child, Duration::from_secs(120));
    let r: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("doctor: {e}\n{}\n{}", tail(&out), tail(&err)));
    assert_eq!(status.and_then(|s| s.code()), Some(1));
    let ps = participants(&r);
    let old = ps.iter().find(|p| p["product_version"] == "0.10.2").unwrap_or_else(|| panic!("no 0.10.2 peer: {ps:?}"));
    assert_eq!((old["vendor_id"].as_str(), old["protocol_version"].as_str()), (Some("01.10"), Some("2.1")));
    let msg = finding(&r, "xtypes-with-0.10")["message"].as_str().expect("message").to_owned();
    assert!(msg.contains("runs Cyclone DDS 0.10.2") && msg.contains("rt/lowcmd") && msg.contains("python"), "{msg}");
}

#[test]
fn nothing_publishing_lowstate_is_named() {
    let peer_bin = c010_peer();
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    // The 0.10.2 peer as a controller: it reads rt/lowstate and writes rt/lowcmd; no robot side anywhere.
    let _controller =
        spawn(Command::new(&peer_bin).args([domain.arg().as_str(), "lo", "30", "controller", "3", "0.4", "60", "2"]));
    wait_for_endpoint(domain.id(), EndpointKind::Subscription, "rt/lowstate");
    let (code, r) = doctor(&["--domain", &domain.arg()]);
    assert_eq!(code, Some(1));
    assert!(finding(&r, "no-lowstate")["message"]
        .as_str()
        .is_some_and(|m| m.contains("nothing publishes rt/lowstate")));
    let p = with_endpoint(participants(&r), "reader", "rt/lowstate");
    assert_eq!((p["product_version"].as_str(), p["process"].as_str()), (Some("0.10.2"), Some("peer")));
    // idlc-generated types carry (0.10-style) type information.
    let e = p["endpoints"].as_array().and_then(|e| e.iter().find(|e| e["topic"] == "rt/lowcmd")).expect("writer");
    assert_eq!((e["kind"].as_str(), e["type_information"].as_bool()), (Some("writer"), Some(true)));
    assert!(!codes(&r).contains(&"xtypes-with-0.10".to_owned()), "0.10.2's own type information is harmless");
}

#[test]
fn wrong_type_name_is_named() {
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let _sim = sim(&domain.arg());
    let _go = py11(&["sub", "--domain", &domain.arg(), "--topic", "rt/lowstate", "--go", "--seconds", "60"]);
    wait_for_endpoint(domain.id(), EndpointKind::Subscription, "rt/lowstate");
    let (code, r) = doctor(&["--domain", &domain.arg()]);
    assert_eq!(code, Some(1));
    let msg = finding(&r, "type-mismatch")["message"].as_str().expect("message").to_owned();
    assert!(
        msg.contains("unitree_hg::msg::dds_::LowState_") && msg.contains("unitree_go::msg::dds_::LowState_"),
        "{msg}"
    );
}

#[test]
fn qos_that_cannot_match_is_named() {
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let _sim = sim(&domain.arg());
    let _reader = py11(&[
        "sub",
        "--domain",
        &domain.arg(),
        "--topic",
        "rt/lowstate",
        "--reader-qos",
        "transient-local",
        "--seconds",
        "60",
    ]);
    wait_for_endpoint(domain.id(), EndpointKind::Subscription, "rt/lowstate");
    let (code, r) = doctor(&["--domain", &domain.arg()]);
    assert_eq!(code, Some(1));
    let msg = finding(&r, "qos-incompatible")["message"].as_str().expect("message").to_owned();
    assert!(msg.contains("transient-local durability") && msg.contains("offers volatile"), "{msg}");
}

#[test]
fn domain_0_needs_allow_robot() {
    let start = Instant::now();
    let (status, _, err) = wait_with_timeout(spawn_ulab(&["doctor", "--domain", "0"]), Duration::from_secs(60));
    assert_eq!(status.and_then(|s| s.code()), Some(2), "{err}");
    assert!(err.contains("--allow-robot"), "{err}");
    eprintln!("refused in {:.1} s", start.elapsed().as_secs_f64());
}
