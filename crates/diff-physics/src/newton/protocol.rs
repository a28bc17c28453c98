//! The pipe to `python/newton_server.py`: a child process speaking length-prefixed binary frames on
//! stdin/stdout (layout in the server's docstring). Every read has a deadline, so a hung or crashed server is a
//! typed error, never a hang or a panic.
use std::collections::VecDeque;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use thiserror::Error;

pub const OP_INIT: u8 = 1;
pub const OP_RESET: u8 = 2;
pub const OP_STEP: u8 = 3;
pub const OP_ENERGY: u8 = 6;
pub const OP_KINEMATICS: u8 = 7;
pub const OP_MASS_MATRIX: u8 = 8;
pub const OP_BIAS: u8 = 9;
pub const OP_ACCEL: u8 = 10;
pub const OP_WRENCH: u8 = 11;
pub const OP_QUIT: u8 = 12;

/// Largest frame accepted from the server (a 33 × 33 mass matrix is 8.7 kB; contacts a few kB).
const MAX_FRAME: u32 = 64 << 20;
/// Lines of the server's stderr kept for error messages.
const STDERR_LINES: usize = 30;

/// What can go wrong between the engine and its Python server.
#[derive(Debug, Error)]
pub enum NewtonError {
    #[error("Newton server cannot start: interpreter {python} / script {script}: {reason} (install Newton with `bash scripts/setup.sh --newton`, or set ULAB_NEWTON_PYTHON)")]
    ServerMissing { python: PathBuf, script: PathBuf, reason: String },
    #[error("Newton server protocol error: {0}")]
    Protocol(String),
    #[error("Newton server died ({status}) during {during}; its last output:\n{stderr}")]
    ServerDied { status: String, during: String, stderr: String },
    #[error("Newton server gave no answer to {during} within {seconds} s (killed); its last output:\n{stderr}")]
    Timeout { during: String, seconds: f64, stderr: String },
    #[error("Newton server refused {during}: {message}")]
    Remote { during: String, message: String },
    #[error("Newton simulation diverged: {0}")]
    Diverged(String),
}

/// A reply frame: status byte and payload.
type Frame = (u8, Vec<u8>);

/// The running server.
#[derive(Debug)]
pub struct Server {
    child: Child,
    stdin: BufWriter<ChildStdin>,
    replies: Receiver<Result<Frame, String>>,
    stderr: Arc<Mutex<VecDeque<String>>>,
    dead: bool,
}

fn read_frame(r: &mut impl Read) -> Result<Frame, String> {
    let mut head = [0u8; 4];
    r.read_exact(&mut head).map_err(|e| format!("end of stream: {e}"))?;
    let n = u32::from_le_bytes(head);
    if n == 0 || n > MAX_FRAME {
        return Err(format!("frame length {n} out of range"));
    }
    let mut body = vec![0u8; n as usize];
    r.read_exact(&mut body).map_err(|e| format!("truncated frame: {e}"))?;
    let status = body[0];
    body.remove(0);
    Ok((status, body))
}

impl Server {
    /// Starts `python script` with piped stdin/stdout/stderr.
    pub fn spawn(python: &Path, script: &Path) -> Result<Self, NewtonError> {
        let missing = |reason: String| NewtonError::ServerMissing {
            python: python.to_path_buf(),
            script: script.to_path_buf(),
            reason,
        };
        if !script.is_file() {
            return Err(missing("script not found".into()));
        }
        let mut child = Command::new(python)
            .arg("-u")
            .arg(script)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| missing(e.to_string()))?;
        let (Some(stdin), Some(stdout), Some(stderr)) = (child.stdin.take(), child.stdout.take(), child.stderr.take())
        else {
            let _ = child.kill();
            return Err(missing("no pipes".into()));
        };
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut r = BufReader::new(stdout);
            loop {
                let f = read_frame(&mut r);
                let end = f.is_err();
                if tx.send(f).is_err() || end {
                    break;
                }
            }
        });
        let lines = Arc::new(Mutex::new(VecDeque::new()));
        let sink = Arc::clone(&lines);
        std::thread::spawn(move || {
            use std::io::BufRead;
            for line in BufReader::new(stderr).lines() {
                let Ok(line) = line else { break };
                if let Ok(mut q) = sink.lock() {
                    if q.len() == STDERR_LINES {
                        q.pop_front();
                    }
                    q.push_back(line);
                }
            }
        });
        Ok(Server { child, stdin: BufWriter::new(stdin), replies: rx, stderr: lines, dead: false })
    }

    fn stderr_tail(&self) -> String {
        // Give the stderr thread a moment to drain what a dying process wrote last.
        std::thread::sleep(Duration::from_millis(50));
        self.stderr.lock().map(|q| q.iter().cloned().collect::<Vec<_>>().join("\n")).unwrap_or_default()
    }

    fn died(&mut self, during: &str) -> NewtonError {
        self.dead = true;
        // A server that broke the protocol may still be running: a second's grace to exit, then it is killed.
        let mut status = None;
        for _ in 0..20 {
            if let Ok(Some(s)) = self.child.try_wait() {
                status = Some(s.to_string());
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let status = status.unwrap_or_else(|| {
            let _ = self.child.kill();
            let _ = self.child.wait();
            "killed after breaking the protocol".into()
        });
        NewtonError::ServerDied { status, during: during.into(), stderr: self.stderr_tail() }
    }

    /// Sends one request and waits up to `timeout` for its reply payload.
    pub fn request(&mut self, op: u8, payload: &[u8], timeout: Duration, during: &str) -> Result<Vec<u8>, NewtonError> {
        if self.dead {
            return Err(NewtonError::ServerDied {
                status: "exited earlier".into(),
                during: during.into(),
                stderr: self.stderr_tail(),
            });
        }
        let len = u32::try_from(payload.len() + 1).map_err(|_| NewtonError::Protocol("request too large".into()))?;
        let sent = self
            .stdin
            .write_all(&len.to_le_bytes())
            .and_then(|_| self.stdin.write_all(&[op]))
            .and_then(|_| self.stdin.write_all(payload))
            .and_then(|_| self.stdin.flush());
        if sent.is_err() {
            return Err(self.died(during));
        }
        match self.replies.recv_timeout(timeout) {
            Ok(Ok((0, body))) => Ok(body),
            Ok(Ok((2, body))) => Err(NewtonError::Diverged(String::from_utf8_lossy(&body).into_owned())),
            Ok(Ok((1, body))) => {
                Err(NewtonError::Remote { during: during.into(), message: String::from_utf8_lossy(&body).into_owned() })
            }
            Ok(Ok((s, _))) => Err(NewtonError::Protocol(format!("unknown status {s} in reply to {during}"))),
            Ok(Err(_)) | Err(RecvTimeoutError::Disconnected) => Err(self.died(during)),
            Err(RecvTimeoutError::Timeout) => {
                self.dead = true;
                let _ = self.child.kill();
                let _ = self.child.wait();
                Err(NewtonError::Timeout {
                    during: during.into(),
                    seconds: timeout.as_secs_f64(),
                    stderr: self.stderr_tail(),
                })
            }
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if !self.dead {
            let _ = self.request(OP_QUIT, &[], Duration::from_secs(5), "quit");
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Little-endian f64 array.
pub fn f64_bytes(x: &[f64]) -> Vec<u8> {
    x.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// Reads `n` f64 from the front of `b` (`None` when too short).
pub fn take_f64(b: &mut &[u8], n: usize) -> Option<Vec<f64>> {
    if b.len() < 8 * n {
        return None;
    }
    let (head, rest) = b.split_at(8 * n);
    *b = rest;
    Some(head.chunks_exact(8).map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]])).collect())
}

/// Reads a u32 from the front of `b`.
pub fn take_u32(b: &mut &[u8]) -> Option<u32> {
    if b.len() < 4 {
        return None;
    }
    let (head, rest) = b.split_at(4);
    *b = rest;
    Some(u32::from_le_bytes([head[0], head[1], head[2], head[3]]))
}

/// Reads a u32-length-prefixed UTF-8 string.
pub fn take_str(b: &mut &[u8]) -> Option<String> {
    let n = take_u32(b)? as usize;
    if b.len() < n {
        return None;
    }
    let (head, rest) = b.split_at(n);
    *b = rest;
    String::from_utf8(head.to_vec()).ok()
}
