//! Process handling shared by the `ulab` end-to-end tests: every wait has a hard timeout and
//! child output is read on threads, so a full pipe can never block a child.
#![allow(dead_code)]

use std::io::Read;
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The project's Python (the venv from scripts/setup.sh, or ULAB_PYTHON).
pub fn python() -> PathBuf {
    std::env::var_os("ULAB_PYTHON").map(PathBuf::from).unwrap_or_else(|| root().join(".venv/bin/python"))
}

/// Waits for a child with a hard timeout (killed after it), reading its output on threads so
/// that a full pipe never blocks it. Returns (exit status if it exited in time, stdout, stderr).
pub fn wait_with_timeout(mut child: Child, timeout: Duration) -> (Option<ExitStatus>, String, String) {
    // A stream that was not piped reads as empty.
    let mut stdout = child.stdout.take();
    let mut stderr = child.stderr.take();
    let out = std::thread::spawn(move || {
        let mut s = String::new();
        if let Some(p) = &mut stdout {
            let _ = p.read_to_string(&mut s);
        }
        s
    });
    let err = std::thread::spawn(move || {
        let mut s = String::new();
        if let Some(p) = &mut stderr {
            let _ = p.read_to_string(&mut s);
        }
        s
    });
    let end = Instant::now() + timeout;
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break Some(status),
            Ok(None) if Instant::now() < end => std::thread::sleep(Duration::from_millis(50)),
            _ => {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
        }
    };
    (status, out.join().unwrap_or_default(), err.join().unwrap_or_default())
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

/// The last 2000 characters of a long text, for failure messages.
pub fn tail(s: &str) -> &str {
    let start = s.len().saturating_sub(2000);
    let start = (start..s.len()).find(|&i| s.is_char_boundary(i)).unwrap_or(s.len());
    &s[start..]
}

/// Kills a child process when dropped (a panicking test must not leave a simulator running).
pub struct KillOnDrop(pub Option<Child>);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        if let Some(c) = &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}
