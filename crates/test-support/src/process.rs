//! Child processes for end-to-end tests: every wait has a hard timeout and child output is read on threads, so a
//! full pipe can never block a child and a hung child fails the test instead of hanging it.
use std::io::Read;
use std::process::{Child, ExitStatus};
use std::time::{Duration, Instant};

/// Waits for a child with a hard timeout (killed after it), reading its output on threads so that a full pipe
/// never blocks it. Returns (exit status if it exited in time, stdout, stderr).
pub fn wait_with_timeout(mut child: Child, timeout: Duration) -> (Option<ExitStatus>, String, String) {
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

/// Kills a child process when dropped (a panicking test must not leave a simulator running).
#[derive(Debug)]
pub struct KillOnDrop(pub Option<Child>);

impl KillOnDrop {
    /// Takes ownership of a running child.
    pub fn new(child: Child) -> Self {
        KillOnDrop(Some(child))
    }
}

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        if let Some(c) = &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// The last 2000 characters of a long text, for failure messages.
pub fn tail(s: &str) -> &str {
    let start = s.len().saturating_sub(2000);
    let start = (start..s.len()).find(|&i| s.is_char_boundary(i)).unwrap_or(s.len());
    &s[start..]
}

/// Asks a child to stop as Ctrl-C would (SIGINT through `kill -INT`, so that no unsafe signal code is needed here),
/// so that it can print its final account; returns whether the signal was delivered.
pub fn interrupt(child: &Child) -> bool {
    std::process::Command::new("kill").args(["-INT", &child.id().to_string()]).status().is_ok_and(|s| s.success())
}
