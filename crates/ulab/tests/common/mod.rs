//! Shared by the `ulab` end-to-end tests: the binary, the repository, the project's Python, and (from
//! `test-support`) leased DDS domains, the machine-wide real-time slot and child processes with hard timeouts.
#![allow(dead_code, unused_imports)]

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;
pub use test_support::process::{interrupt, tail, wait_with_timeout, KillOnDrop};
pub use test_support::{lease_domain, DomainLease, RealtimeSlot, PATIENCE};

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The project's Python (the venv from scripts/setup.sh, or ULAB_PYTHON).
pub fn python() -> PathBuf {
    std::env::var_os("ULAB_PYTHON").map(PathBuf::from).unwrap_or_else(|| root().join(".venv/bin/python"))
}

/// Runs the `ulab` binary with `args`, output piped, killed after `timeout`: (exit code if it exited in time,
/// stdout, stderr).
pub fn run_ulab(args: &[&str], timeout: Duration) -> (Option<i32>, String, String) {
    let (status, out, err) = wait_with_timeout(spawn_ulab(args), timeout);
    (status.and_then(|s| s.code()), out, err)
}

/// Starts the `ulab` binary with `args`, stdout and stderr piped (read them with [`wait_with_timeout`]).
pub fn spawn_ulab(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab")
}

/// The bridge's final account (`sim: summary {json}` on its stderr), if it printed one.
pub fn sim_summary(stderr: &str) -> Option<serde_json::Value> {
    stderr.lines().rev().find_map(|l| l.strip_prefix("sim: summary ")).and_then(|j| serde_json::from_str(j).ok())
}
