//! `ulab conform` argument and safety handling, without a target: refusals exit 2 before any
//! DDS traffic, a missing target is a connection error (2), a bad reproducer is a usage error (2).

use crate::common;

use common::run_ulab;
use std::time::Duration;
use test_support::lease_domain;

fn conform(args: &[&str]) -> (Option<i32>, String) {
    let (code, _out, err) = run_ulab(&[&["conform"], args].concat(), Duration::from_secs(60));
    (code, err)
}

#[test]
fn domain_zero_is_refused_without_allow_robot() {
    let (code, err) = conform(&["--domain", "0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--allow-robot"), "{err}");
}

#[test]
fn non_loopback_interface_is_refused_without_allow_robot() {
    let lease = lease_domain();
    let (code, err) = conform(&["--domain", &lease.arg(), "--interface", "eth0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--allow-robot"), "{err}");
}

#[test]
fn fuzzing_a_robot_needs_the_second_flag_and_says_what_it_sends() {
    let (code, err) = conform(&["--domain", "0", "--allow-robot", "--fuzz", "--budget", "1"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--allow-robot-fuzz"), "{err}");
    // Replaying a reproducer is fuzz traffic too.
    let dir = std::env::temp_dir().join(format!("ulab-conform-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("tmp dir");
    let file = dir.join("r.json");
    std::fs::write(&file, "{}").expect("write");
    let (code, err) = conform(&["replay", file.to_str().expect("utf-8"), "--domain", "0", "--allow-robot"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--allow-robot-fuzz"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn missing_target_is_a_connection_error() {
    let lease = lease_domain();
    let (code, err) = conform(&["--domain", &lease.arg(), "--connect-timeout", "1.5", "--quiet"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("no LowState"), "{err}");
}

#[test]
fn bad_reproducer_and_bad_arguments_are_usage_errors() {
    let lease = lease_domain();
    let d = lease.arg();
    let dir = std::env::temp_dir().join(format!("ulab-conform-cli2-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("tmp dir");
    let file = dir.join("bad.json");
    std::fs::write(&file, r#"{"schema_version": 99}"#).expect("write");
    let (code, err) = conform(&["replay", file.to_str().expect("utf-8"), "--domain", &d]);
    assert_eq!(code, Some(2), "{err}");
    let (code, err) = conform(&["replay", dir.join("missing.json").to_str().expect("utf-8"), "--domain", &d]);
    assert_eq!(code, Some(2), "{err}");
    let (code, err) = conform(&["--robot", "g1", "--domain", &d]);
    assert_eq!(code, Some(2), "{err}");
    let (code, err) = conform(&["--domain", &d, "--fuzz", "--budget", "-1"]);
    assert_eq!(code, Some(2), "{err}");
    let (code, err) = conform(&["--domain", &d, "--checks", "state_crc,no_such_check"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("no_such_check"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
