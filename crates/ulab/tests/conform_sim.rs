//! `ulab conform` against our own `ulab sim` (issue 4, item 6): the normal bridge passes every
//! check; with each test-only switch that disables one of its protections, exactly the checks
//! about that protection fail. Plus a fuzz smoke run whose reproducer must replay.
//!
//! Domains 80-84. One simulator at a time: the 2-core machines cannot run two in real time.

mod common;

use common::{run_ulab, tail, KillOnDrop};
use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::time::Duration;

static SERIAL: Mutex<()> = Mutex::new(());

/// Every check of the default run, by id (a check that disappears must fail this test).
const ALL_CHECKS: [&str; 22] = [
    "state_crc",
    "state_rate",
    "state_jitter",
    "state_tick",
    "state_fresh",
    "state_finite",
    "state_quaternion",
    "state_joint_limits",
    "discovery_types_qos",
    "discovery_type_information",
    "cmd_valid_moves_joint",
    "cmd_bad_crc_ignored",
    "cmd_mode0_no_torque",
    "cmd_absurd_gains_safe",
    "cmd_non_finite_rejected",
    "robust_truncated",
    "robust_bad_header",
    "robust_oversize",
    "robust_xcdr2",
    "robust_flood",
    "robust_duplicates_reordering",
    "cmd_timeout_behaviour",
];

fn sim(domain: u32, extra: &[&str]) -> KillOnDrop {
    let child = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(["sim", "--engine", "mujoco", "--domain", &domain.to_string(), "--duration", "120", "--quiet"])
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start ulab sim");
    KillOnDrop(Some(child))
}

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ulab-conform-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Runs `ulab conform ARGS`; returns (exit code, stdout, stderr).
fn conform(args: &[&str], timeout_s: u64) -> (Option<i32>, String, String) {
    run_ulab(&[&["conform"], args].concat(), Duration::from_secs(timeout_s))
}

/// Runs the default checks against a bridge with `switches` and returns the failing ids.
fn failing_checks(domain: u32, switches: &[&str]) -> BTreeSet<String> {
    let _bridge = sim(domain, switches);
    let dir = out_dir(&format!("d{domain}"));
    let d = domain.to_string();
    let (code, out, err) =
        conform(&["--domain", &d, "--format", "json", "--quiet", "--out", dir.to_str().expect("utf-8 path")], 150);
    let report: serde_json::Value = serde_json::from_str(&out)
        .unwrap_or_else(|e| panic!("stdout is not JSON ({e}); exit {code:?}\nstderr:\n{}", tail(&err)));
    // The files match what was printed.
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).expect("report.json"))
            .expect("report.json is JSON");
    assert_eq!(file, report);
    assert!(std::fs::read_to_string(dir.join("report.md")).expect("report.md").contains("# Conformance report"));
    let _ = std::fs::remove_dir_all(&dir);

    // The report's layout (schema version 1).
    assert_eq!(report["schema_version"], 1);
    assert_eq!(report["target"]["robot"], "h1_2");
    assert_eq!(report["target"]["domain"], domain);
    assert_eq!(report["target"]["interface"], "lo");
    assert_eq!(report["settings"]["mode"], "checks");
    assert_eq!(report["settings"]["expected_state_rate_hz"], 500.0);
    assert!(report["versions"]["ulab"].is_string(), "{report}");
    let results = report["results"].as_array().expect("results");
    for r in results {
        for key in ["id", "group", "status", "summary", "evidence"] {
            assert!(r.get(key).is_some(), "result without `{key}`: {r}");
        }
        assert!(["pass", "fail", "inconclusive"].contains(&r["status"].as_str().unwrap_or("")), "{r}");
    }
    let ids: BTreeSet<&str> = results.iter().filter_map(|r| r["id"].as_str()).collect();
    let expected: BTreeSet<&str> = ALL_CHECKS.iter().copied().collect();
    assert_eq!(ids, expected, "set of checks");
    let status = |s: &str| -> BTreeSet<String> {
        results.iter().filter(|r| r["status"] == s).filter_map(|r| r["id"].as_str().map(str::to_owned)).collect()
    };
    let fails = status("fail");
    let inconclusive = status("inconclusive");
    let dump = serde_json::to_string_pretty(&report).unwrap_or_default();
    assert!(inconclusive.is_empty(), "inconclusive checks against our bridge {switches:?}: {inconclusive:?}\n{dump}");
    assert_eq!(code, Some(if fails.is_empty() { 0 } else { 1 }), "exit code; failing {fails:?}\n{}", tail(&err));
    // Evidence is present for every check.
    for r in results {
        assert!(
            r["evidence"].as_object().is_some_and(|e| !e.is_empty()) || r["id"] == "discovery_type_information",
            "no evidence: {r}"
        );
    }
    println!("{switches:?}: failing {fails:?}");
    if !fails.is_empty() {
        println!("{dump}");
    }
    fails
}

fn set(ids: &[&str]) -> BTreeSet<String> {
    ids.iter().map(|s| (*s).to_owned()).collect()
}

#[test]
fn our_bridge_passes_and_each_disabled_protection_fails_exactly_its_checks() {
    let _g = SERIAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let mut problems = Vec::new();
    for (domain, switches, expected) in [
        (80u32, &[][..], set(&[])),
        (81, &["--unsafe-skip-crc-check"][..], set(&["cmd_bad_crc_ignored"])),
        (82, &["--unsafe-skip-limit-check"][..], set(&["cmd_absurd_gains_safe", "cmd_non_finite_rejected"])),
        (83, &["--unsafe-stale-state"][..], set(&["state_fresh"])),
    ] {
        let got = failing_checks(domain, switches);
        if got != expected {
            problems.push(format!("{switches:?}: expected failing {expected:?}, got {got:?}"));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn fuzz_finds_a_failure_in_the_unprotected_bridge_and_its_reproducer_replays() {
    let _g = SERIAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let _bridge = sim(84, &["--unsafe-skip-limit-check"]);
    let dir = out_dir("fuzz");
    let (code, out, err) = conform(
        &[
            "--domain",
            "84",
            "--fuzz",
            "--budget",
            "30",
            "--seed",
            "3",
            "--quiet",
            "--format",
            "json",
            "--out",
            dir.to_str().expect("utf-8 path"),
        ],
        120,
    );
    assert_eq!(code, Some(1), "fuzz should find a failure\n{out}\n{}", tail(&err));
    let report: serde_json::Value = serde_json::from_str(&out).expect("report JSON");
    let repros = report["reproducers"].as_array().expect("reproducers");
    assert_eq!(repros.len(), 1, "{out}");
    let file = dir.join(repros[0].as_str().expect("path"));
    let rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).expect("reproducer file")).expect("reproducer JSON");
    assert_eq!(rep["schema_version"], 1);
    assert!(rep["steps"].as_array().is_some_and(|s| !s.is_empty() && s.len() <= 6), "{rep}");
    let (code, out, err) = conform(&["replay", file.to_str().expect("utf-8 path"), "--domain", "84"], 60);
    assert_eq!(code, Some(1), "the failure should reproduce:\n{out}\n{}", tail(&err));
    assert!(out.contains("REPRODUCED"), "{out}");
    let _ = std::fs::remove_dir_all(&dir);
}
