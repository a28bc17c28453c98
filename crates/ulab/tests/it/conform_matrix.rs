//! `ulab conform` against a matrix of defect peers (issue 13): our own `ulab sim`, then the same bridge with exactly
//! one deliberate defect each (test-only switches, `sim_bridge::Defect`), and a Cyclone 11 typed writer relaying its
//! state. For every peer the whole verdict table is asserted: the checks the defect implies fail, every other check
//! passes, nothing is inconclusive. The reason each verdict is implied is written next to it.
//!
//! The counterparts are independent where it matters: the interop verdicts come from a Cyclone DDS 0.10.2 participant
//! (Debian's libddsc, C) and a Cyclone 11 one (the Python binding with Unitree's SDK types); the RTPS vendor and
//! protocol version from the bytes those stacks put on the wire. The defects themselves are ours (the bridge with a
//! protection removed), checked against physics in `sim_bridge`'s tests; the run against a peer nobody here wrote
//! (unitree_mujoco) is recorded in docs/conform/unitree_mujoco.md.
//!
//! One peer at a time, holding the machine-wide real-time slot; each case takes ~16 s of wall time (the matrix ~3.5
//! min). A case whose table differs is run once more and the first mismatch printed: in one of four full matrix runs on
//! the shared 2-core machine the fallen-robot case differed (its reason was not captured) and it did not repeat in
//! 13 further runs, 3 of them with a core kept busy.

use crate::common;

use common::{python, tail, wait_with_timeout, KillOnDrop};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use test_support::{lease_domain, DomainLease, RealtimeSlot};

/// Every check of the default run, in report order.
const ALL_CHECKS: [&str; 23] = [
    "state_crc",
    "state_rate",
    "state_jitter",
    "state_tick",
    "state_fresh",
    "state_finite",
    "state_quaternion",
    "state_joint_limits",
    "discovery_types_qos",
    "interop_cyclone_010",
    "interop_cyclone_11",
    "cmd_valid_moves_joint",
    "cmd_bad_crc_ignored",
    "cmd_mode0_no_torque",
    "cmd_absurd_gains_safe",
    "cmd_non_finite_rejected",
    "cmd_timeout_behaviour",
    "robust_truncated",
    "robust_bad_header",
    "robust_oversize",
    "robust_xcdr2",
    "robust_flood",
    "robust_duplicates_reordering",
];

/// One defect peer and the verdicts it implies: every check not listed must pass.
struct Case {
    name: &'static str,
    /// Extra `ulab sim` arguments.
    sim: &'static [&'static str],
    /// Relay the state through a Cyclone 11 typed writer.
    typed_relay: bool,
    /// (check, expected status, why the defect implies it).
    expect: &'static [(&'static str, &'static str, &'static str)],
}

const CASES: [Case; 13] = [
    Case { name: "our bridge", sim: &[], typed_relay: false, expect: &[] },
    Case {
        name: "no state CRC",
        sim: &["--unsafe-defect", "no-state-crc"],
        typed_relay: false,
        expect: &[("state_crc", "fail", "every LowState carries crc = 0; nothing else reads the CRC")],
    },
    Case {
        name: "tick stuck at 0",
        sim: &["--unsafe-defect", "tick-stuck"],
        typed_relay: false,
        expect: &[("state_tick", "fail", "tick never advances; rate and freshness use reception time and the data")],
    },
    Case {
        name: "state at 200 Hz",
        sim: &["--state-rate", "200"],
        typed_relay: false,
        expect: &[(
            "state_rate",
            "fail",
            "200 Hz < 90 % of the 500 Hz nominal; jitter, robustness and timing use the measured 200 Hz",
        )],
    },
    Case {
        name: "stale state",
        sim: &["--unsafe-defect", "stale-state"],
        typed_relay: false,
        expect: &[("state_fresh", "fail", "9 of 10 samples repeat the previous physics state bit for bit")],
    },
    Case {
        name: "applies bad CRC",
        sim: &["--unsafe-defect", "apply-bad-crc"],
        typed_relay: false,
        expect: &[("cmd_bad_crc_ignored", "fail", "the bad-CRC step's torque shows up in tau_est")],
    },
    Case {
        name: "ignores mode 0",
        sim: &["--unsafe-defect", "ignore-mode0"],
        typed_relay: false,
        expect: &[("cmd_mode0_no_torque", "fail", "mode-0 joints still produce the step's PD torque")],
    },
    Case {
        name: "applies absurd gains",
        sim: &["--unsafe-defect", "apply-absurd-gains"],
        typed_relay: false,
        expect: &[("cmd_absurd_gains_safe", "fail", "kp -500, kd -50 and kp 1e6 act as sent")],
    },
    Case {
        name: "limp on NaN",
        sim: &["--unsafe-defect", "limp-on-non-finite"],
        typed_relay: false,
        expect: &[("cmd_non_finite_rejected", "fail", "a NaN makes every motor give no torque instead of a rejection")],
    },
    Case {
        name: "undefined on NaN",
        sim: &["--unsafe-defect", "undefined-on-non-finite"],
        typed_relay: false,
        expect: &[(
            "cmd_non_finite_rejected",
            "fail",
            "a NaN reaches the physics: the state turns non-finite while it applies (clean-traffic state stays finite)",
        )],
    },
    Case {
        name: "keeps the last command",
        sim: &["--unsafe-defect", "keep-last-command"],
        typed_relay: false,
        expect: &[("cmd_timeout_behaviour", "fail", "tau_est keeps following the last command's PD law after silence")],
    },
    Case {
        name: "fallen, test joints pinned",
        sim: &["--unsafe-defect", "fallen-pinned"],
        typed_relay: false,
        // Lying on its back, both elbows and the left shoulder braked: the commands still reach the motors, whose
        // tau_est shows them, and the right shoulder can move: every property is still decidable and conformant.
        expect: &[],
    },
    Case {
        name: "Cyclone 11 typed writer",
        sim: &["--unsafe-state-topic", "rt/lowstate_raw"],
        typed_relay: true,
        expect: &[(
            "interop_cyclone_010",
            "fail",
            "the 0.10.2 participant crashes on the typed writer's XTypes type information (`invalid type object`)",
        )],
    },
];

fn cache_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("ulab-cache")
}

fn spawn_sim(domain: &DomainLease, extra: &[&str]) -> KillOnDrop {
    let child = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["sim", "--engine", "mujoco", "--domain", &domain.arg(), "--duration", "150", "--quiet"])
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start ulab sim");
    KillOnDrop(Some(child))
}

fn spawn_relay(domain: &DomainLease) -> KillOnDrop {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/py/typed_relay.py");
    let child = Command::new(python())
        .arg(script)
        .args([&domain.arg(), "150"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start the typed relay");
    KillOnDrop(Some(child))
}

/// Runs `ulab conform` against the case's peer; returns the report and the wall time.
fn conform(case: &Case) -> (serde_json::Value, f64) {
    let domain = lease_domain();
    let _sim = spawn_sim(&domain, case.sim);
    let _relay = case.typed_relay.then(|| spawn_relay(&domain));
    let dir = std::env::temp_dir().join(format!("ulab-conform-matrix-{}-{}", std::process::id(), domain.id()));
    let _ = std::fs::remove_dir_all(&dir);
    let started = Instant::now();
    let child = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["conform", "--domain", &domain.arg(), "--format", "json", "--quiet", "--out"])
        .arg(&dir)
        .arg("--python")
        .arg(python())
        .env("ULAB_CACHE_DIR", cache_dir())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab conform");
    let (status, out, err) = wait_with_timeout(child, Duration::from_secs(180));
    let wall = started.elapsed().as_secs_f64();
    let report: serde_json::Value = serde_json::from_str(&out).unwrap_or_else(|e| {
        panic!("{}: stdout is not JSON ({e}); exit {status:?}\nstderr:\n{}", case.name, tail(&err))
    });
    // The files hold what was printed.
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).expect("report.json"))
            .expect("report.json is JSON");
    assert_eq!(file, report, "{}", case.name);
    assert!(std::fs::read_to_string(dir.join("report.md")).expect("report.md").contains("# Conformance report"));
    let _ = std::fs::remove_dir_all(&dir);
    let fails = report["results"].as_array().is_some_and(|r| r.iter().any(|x| x["status"] == "fail"));
    assert_eq!(
        status.and_then(|s| s.code()),
        Some(if fails { 1 } else { 0 }),
        "{}: exit code\n{}",
        case.name,
        tail(&err)
    );
    (report, wall)
}

/// What a failing check's summary must name, per case: the non-finite check tells a limp robot from undefined
/// physics (issue 13, item 2), so the two peers whose verdicts are the same must be told apart in the words.
const SUMMARY_MUST_SAY: [(&str, &str, &str); 2] = [
    ("limp on NaN", "cmd_non_finite_rejected", "limp:"),
    ("undefined on NaN", "cmd_non_finite_rejected", "undefined:"),
];

/// Compares a report with the case's expected table; returns the mismatches.
fn mismatches(case: &Case, report: &serde_json::Value) -> Vec<String> {
    let mut problems = Vec::new();
    assert_eq!(report["schema_version"], conformance::report::REPORT_SCHEMA_VERSION);
    assert_eq!(report["target"]["robot"], "h1_2");
    let results = report["results"].as_array().expect("results");
    let got: BTreeMap<&str, (&str, &str)> = results
        .iter()
        .filter_map(|r| Some((r["id"].as_str()?, (r["status"].as_str()?, r["summary"].as_str().unwrap_or("")))))
        .collect();
    let ids: Vec<&str> = results.iter().filter_map(|r| r["id"].as_str()).collect();
    if ids != ALL_CHECKS {
        problems.push(format!("{}: checks {ids:?}", case.name));
    }
    for id in ALL_CHECKS {
        let (want, why) = case
            .expect
            .iter()
            .find(|(c, _, _)| *c == id)
            .map_or(("pass", "the peer has no defect touching it"), |(_, s, w)| (*s, *w));
        match got.get(id) {
            Some((status, _)) if *status == want => {}
            // Arrival times carry this host's scheduling delays as well as the peer's: under load (CI shares 2 cores)
            // a conformant peer's p99 interval can exceed the limit. No defect peer here touches jitter; it must still
            // be decided, and its failure is printed.
            Some((status, summary)) if id == "state_jitter" && want == "pass" && *status == "fail" => {
                println!("{}: state_jitter failed on this host's timing: {summary}", case.name)
            }
            Some((status, summary)) => {
                problems.push(format!("{}: {id} is {status}, expected {want} ({why}): {summary}", case.name))
            }
            None => problems.push(format!("{}: {id} missing", case.name)),
        }
    }
    for (name, id, words) in SUMMARY_MUST_SAY.iter().filter(|(n, _, _)| *n == case.name) {
        match got.get(id) {
            Some((_, summary)) if summary.contains(words) => {}
            other => problems.push(format!("{name}: {id}'s summary does not say `{words}`: {other:?}")),
        }
    }
    for r in results {
        if r["evidence"].as_object().is_none_or(serde_json::Map::is_empty) {
            problems.push(format!("{}: {} has no evidence", case.name, r["id"]));
        }
    }
    // What was measured about the peer itself.
    let rate = report["target"]["measured_state_rate_hz"].as_f64().unwrap_or(0.0);
    let nominal = if case.sim.contains(&"200") { 200.0 } else { 500.0 };
    if !(rate > 0.5 * nominal && rate < 1.5 * nominal) {
        problems.push(format!("{}: measured rate {rate} Hz for a {nominal} Hz peer", case.name));
    }
    if report["target"]["rtps_vendor"] != "1.16 Eclipse Cyclone DDS" {
        problems.push(format!("{}: vendor {}", case.name, report["target"]["rtps_vendor"]));
    }
    problems
}

/// Keys of the report and of its target, and per check its id, group, fields, verdict and evidence keys.
fn report_shape(report: &serde_json::Value) -> serde_json::Value {
    let keys = |v: &serde_json::Value| -> Vec<String> {
        v.as_object().map(|o| o.keys().cloned().collect()).unwrap_or_default()
    };
    let results: Vec<serde_json::Value> = report["results"]
        .as_array()
        .map(|r| {
            r.iter()
                .map(|x| {
                    let status = if x["id"] == "state_jitter" { "[host timing]".into() } else { x["status"].clone() };
                    serde_json::json!({
                        "id": x["id"],
                        "group": x["group"],
                        "fields": keys(x),
                        "status": status,
                        "evidence": keys(&x["evidence"]),
                    })
                })
                .collect()
        })
        .unwrap_or_default();
    serde_json::json!({
        "keys": keys(report),
        "schema_version": report["schema_version"].to_string(),
        "target": keys(&report["target"]),
        "results": results,
    })
}

#[test]
fn each_defect_peer_fails_exactly_the_checks_its_defect_implies() {
    let _slot = RealtimeSlot::acquire();
    let only = std::env::var("ULAB_CONFORM_CASES").ok();
    let mut problems = Vec::new();
    let mut times = Vec::new();
    let mut reruns = 0;
    for case in CASES.iter().filter(|c| only.as_deref().is_none_or(|o| o.split(',').any(|n| c.name.contains(n)))) {
        // A real-time case whose table differs is run once more (a peer and a tester sharing two loaded cores); the
        // first mismatch is printed in full. A wrong verdict the defect implies repeats and fails the test.
        for attempt in 0..2 {
            let (report, wall) = conform(case);
            let p = mismatches(case, &report);
            if case.name == "our bridge" && p.is_empty() {
                // Safety net for refactoring (issue 18): the report's shape for the conformant peer. Its figures are
                // measured on a live peer and vary run to run; ids, verdicts and what each check gives as evidence
                // do not (jitter's verdict depends on this host's load, see `mismatches`).
                insta::assert_json_snapshot!("our_bridge_report_shape", report_shape(&report));
            }
            println!("{:<28} {:>5.1} s  {}", case.name, wall, if p.is_empty() { "as expected" } else { "MISMATCH" });
            times.push(wall);
            if p.is_empty() {
                break;
            }
            println!("{}\n{}", p.join("\n"), serde_json::to_string_pretty(&report).unwrap_or_default());
            if attempt == 1 {
                problems.extend(p);
            } else {
                reruns += 1;
            }
        }
    }
    println!("reruns after a mismatch: {reruns}");
    println!("matrix: {} runs, {:.1} s of conformance runs", times.len(), times.iter().sum::<f64>());
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
