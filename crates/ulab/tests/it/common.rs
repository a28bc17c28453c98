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

/// The Cyclone DDS 0.10.2 C clients of `tests/clients/c010` (`sim_client`, `controller`), built once per test binary
/// into cargo's per-target scratch directory (tests run on parallel threads: one build, then every test reads it).
/// Needs `make`, a C compiler, Debian's cyclonedds-dev and cyclonedds-tools (idlc) 0.10.2.
pub fn c010_client(name: &str) -> PathBuf {
    static DIR: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let src = root().join("tests/clients/c010");
        let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("c010-clients");
        let child = Command::new("make")
            .arg("-s")
            .arg("-f")
            .arg(src.join("Makefile"))
            .arg(format!("OUT={}", out.display()))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run make (needs make and a C compiler)");
        let (status, stdout, stderr) = wait_with_timeout(child, Duration::from_secs(120));
        assert!(
            status.is_some_and(|s| s.success()),
            "building the Cyclone 0.10.2 clients failed (needs Debian's cyclonedds-dev and cyclonedds-tools):\n{stdout}\n{stderr}"
        );
        out
    })
    .join(name)
}

/// Runs the `ulab` binary with `args`, output piped, killed after `timeout`: (exit code if it exited in time,
/// stdout, stderr).
pub fn run_ulab(args: &[&str], timeout: Duration) -> (Option<i32>, String, String) {
    let (status, out, err) = wait_with_timeout(spawn_ulab(args), timeout);
    (status.and_then(|s| s.code()), out, err)
}

/// [`run_ulab`] with the repository root as working directory (where relative policy and robot paths resolve),
/// killed after 300 s.
pub fn run_ulab_from_root(args: &[&str]) -> (Option<i32>, String, String) {
    let child = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(args)
        .current_dir(root())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab");
    let (status, out, err) = wait_with_timeout(child, Duration::from_secs(300));
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

/// A report as a refactoring safety net (issue 18): every number rounded to `sig` significant digits (so that
/// a change in the last bits of a sum does not count, a change of behaviour does) and the named keys replaced
/// by `"[redacted]"` wherever they occur (wall-clock times, temporary paths).
#[allow(dead_code)]
pub fn pinned(v: &serde_json::Value, sig: i32, redact: &[&str]) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::Number(n) => match (n.as_i64(), n.as_f64()) {
            (Some(i), _) => Value::String(i.to_string()),
            // Numbers as strings (floats with `sig` significant digits): the snapshot holds no float noise, and serde_json's
            // arbitrary_precision (on in this workspace) cannot change how they print.
            (None, Some(f)) => Value::String(format!("{f:.*e}", (sig - 1).max(0) as usize)),
            _ => v.clone(),
        },
        Value::Array(a) => Value::Array(a.iter().map(|x| pinned(x, sig, redact)).collect()),
        Value::Object(o) => Value::Object(
            o.iter()
                .map(|(k, x)| {
                    let x =
                        if redact.contains(&k.as_str()) { Value::from("[redacted]") } else { pinned(x, sig, redact) };
                    (k.clone(), x)
                })
                .collect(),
        ),
        _ => v.clone(),
    }
}

/// Robot pixels of an RGB picture from `robot-render`: every robot colour is warm (red well above blue); the ground is
/// grey and the sky blue.
pub fn robot_pixels(rgb: &[u8]) -> usize {
    rgb.chunks(3).filter(|p| i32::from(p[0]) - i32::from(p[2]) > 40).count()
}

/// What a client script run beside `ulab sim` left: its exit status and output, and the simulator's stderr.
pub struct ClientBesideSim {
    pub status: Option<std::process::ExitStatus>,
    pub out: String,
    pub err: String,
    pub sim_err: String,
}

impl ClientBesideSim {
    /// The client's report (the JSON object on its last stdout line), which must hold no `error`; a failed client is
    /// reported on stderr first (its report says what failed). `what` names the run in the messages.
    pub fn report(&self, what: &str) -> serde_json::Value {
        if !self.status.is_some_and(|s| s.success()) {
            eprintln!("{what}: client failed ({:?}): {}", self.status, tail(&self.err));
        }
        let report: serde_json::Value = serde_json::from_str(self.out.lines().last().unwrap_or(""))
            .unwrap_or_else(|e| panic!("{what}: client output ...{}: {e}\n{}", tail(&self.out), tail(&self.err)));
        assert!(report.get("error").is_none(), "{what}: {} (sim: {})", report["error"], tail(&self.sim_err));
        report
    }
}

/// Starts `ulab sim` with `sim_args`, runs the Python client `tests/clients/<script>` with `client_args` beside it
/// (at most `timeout`), then stops the simulator as Ctrl-C would, so that it prints its own account.
pub fn client_beside_sim(sim_args: &[&str], script: &str, client_args: &[&str], timeout: Duration) -> ClientBesideSim {
    let sim = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(sim_args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start ulab sim");
    let mut sim = KillOnDrop(Some(sim));
    let client = Command::new(python())
        .arg(root().join("tests/clients").join(script))
        .args(client_args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start the Python SDK client");
    let (status, out, err) = wait_with_timeout(client, timeout);
    let sim_child = sim.0.take().expect("sim child");
    interrupt(&sim_child);
    let (_, _, sim_err) = wait_with_timeout(sim_child, Duration::from_secs(60));
    ClientBesideSim { status, out, err, sim_err }
}
