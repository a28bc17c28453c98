//! Interop probes: participants of the robot's own DDS stacks, brought by the tester, try to read the peer's
//! LowState.
//!
//! * **Cyclone DDS 0.10.2** (`interop_cyclone_010`), the version in Unitree's SDK2 and on the robots: a small C
//!   program ([`C010_SOURCE`]) compiled on first use against the system's `libddsc` (Debian's `cyclonedds-dev`) with
//!   its `idlc`, configured as Unitree's SDK configures it (interface only) and subscribed with an idlc-generated
//!   type. It runs beside the whole check run (it only listens).
//! * **Cyclone DDS 11** (`interop_cyclone_11`), as Unitree's Python SDK uses it: a script ([`CYCLONE11_SOURCE`])
//!   run by a Python that has `cyclonedds` and `unitree_sdk2py`, joining with `ChannelFactoryInitialize` and reading
//!   with the SDK's typed LowState_. Its XTypes type information is known to crash Cyclone 0.10 peers, so it runs
//!   last, is followed by a check that the peer still publishes, and never runs against what may be a robot.
//!
//! Each probe reports whether it discovered (matched) the peer's writer, how many samples it received and decoded,
//! and whether it survived; a probe that cannot be built or run gives an inconclusive result with the reason.

use crate::report::{CheckId, CheckResult, Status};
use crate::target::Target;
use crate::timing::Timing;
use crate::ConformError;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Source of the Cyclone DDS 0.10.2 probe.
pub const C010_SOURCE: &str = include_str!("../probes/c010_probe.c");
/// IDL of the hg LowState the 0.10.2 probe subscribes with.
pub const LOWSTATE_IDL: &str = include_str!("../probes/lowstate.idl");
/// Source of the Cyclone 11 (Python) probe.
pub const CYCLONE11_SOURCE: &str = include_str!("../probes/cyclone11_probe.py");

/// Settings of the probes.
#[derive(Debug, Clone, PartialEq)]
pub struct InteropOptions {
    /// Where the 0.10.2 probe is built and the Python probe written (default: `ULAB_CACHE_DIR`, else
    /// `$XDG_CACHE_HOME/ulab`, else `~/.cache/ulab`, else the temporary directory).
    pub cache_dir: Option<PathBuf>,
    /// Python with `cyclonedds` and `unitree_sdk2py` (default: `ULAB_PYTHON`, else `python3`).
    pub python: Option<PathBuf>,
    /// Longest a probe listens (s).
    pub seconds: f64,
    /// Samples a probe must receive to pass.
    pub min_samples: u32,
}

impl Default for InteropOptions {
    fn default() -> Self {
        InteropOptions { cache_dir: None, python: None, seconds: 6.0, min_samples: 20 }
    }
}

impl InteropOptions {
    fn cache(&self) -> PathBuf {
        if let Some(d) = &self.cache_dir {
            return d.clone();
        }
        if let Some(d) = std::env::var_os("ULAB_CACHE_DIR") {
            return PathBuf::from(d);
        }
        if let Some(d) = std::env::var_os("XDG_CACHE_HOME") {
            return PathBuf::from(d).join("ulab");
        }
        if let Some(h) = std::env::var_os("HOME") {
            return PathBuf::from(h).join(".cache/ulab");
        }
        std::env::temp_dir().join("ulab-cache")
    }

    fn python(&self) -> PathBuf {
        self.python
            .clone()
            .or_else(|| std::env::var_os("ULAB_PYTHON").map(PathBuf::from))
            .unwrap_or_else(|| "python3".into())
    }
}

/// What a probe printed, as JSON.
#[derive(Debug, Clone, Default, serde::Deserialize, serde::Serialize)]
struct ProbeReport {
    version: String,
    matched_writers: u32,
    samples: u64,
    first_sample_ms: f64,
    elapsed_ms: f64,
}

/// A running probe process with its output collected on threads.
#[derive(Debug)]
struct Running {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: mpsc::Receiver<String>,
    stderr: Option<std::thread::JoinHandle<String>>,
    started: Instant,
}

impl Running {
    fn spawn(mut cmd: Command) -> Result<Running, String> {
        let mut child = cmd
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| format!("cannot start {cmd:?}: {e}"))?;
        let (tx, rx) = mpsc::channel();
        let stdout = child.stdout.take();
        std::thread::spawn(move || {
            if let Some(out) = stdout {
                for line in BufReader::new(out).lines().map_while(Result::ok) {
                    if tx.send(line).is_err() {
                        break;
                    }
                }
            }
        });
        let mut stderr = child.stderr.take();
        let stderr = std::thread::spawn(move || {
            let mut s = String::new();
            if let Some(e) = &mut stderr {
                let _ = e.read_to_string(&mut s);
            }
            s
        });
        Ok(Running { stdin: child.stdin.take(), child, lines: rx, stderr: Some(stderr), started: Instant::now() })
    }

    /// Waits for a line starting with `prefix`; `None` on timeout or exit.
    fn wait_line(&self, prefix: &str, timeout: Duration) -> Option<String> {
        let end = Instant::now() + timeout;
        loop {
            let left = end.checked_duration_since(Instant::now())?;
            match self.lines.recv_timeout(left) {
                Ok(l) if l.starts_with(prefix) => return Some(l),
                Ok(_) => {}
                Err(_) => return None,
            }
        }
    }

    /// Waits for exit (killed after `timeout`): (exit code, signal, stdout lines, stderr).
    fn finish(mut self, timeout: Duration) -> Finished {
        let end = Instant::now() + timeout;
        let mut killed = false;
        let status = loop {
            match self.child.try_wait() {
                Ok(Some(s)) => break Some(s),
                Ok(None) if Instant::now() < end => std::thread::sleep(Duration::from_millis(20)),
                _ => {
                    killed = true;
                    let _ = self.child.kill();
                    break self.child.wait().ok();
                }
            }
        };
        drop(self.stdin.take());
        let mut lines = Vec::new();
        while let Ok(l) = self.lines.recv_timeout(Duration::from_millis(200)) {
            lines.push(l);
        }
        use std::os::unix::process::ExitStatusExt;
        Finished {
            code: status.and_then(|s| s.code()),
            signal: if killed { None } else { status.and_then(|s| s.signal()) },
            killed,
            lines,
            stderr: self.stderr.take().and_then(|h| h.join().ok()).unwrap_or_default(),
            elapsed_s: self.started.elapsed().as_secs_f64(),
        }
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

#[derive(Debug)]
struct Finished {
    code: Option<i32>,
    signal: Option<i32>,
    killed: bool,
    lines: Vec<String>,
    stderr: String,
    elapsed_s: f64,
}

impl Finished {
    fn report(&self) -> Option<ProbeReport> {
        self.lines.iter().rev().find_map(|l| serde_json::from_str::<ProbeReport>(l).ok())
    }
    fn log(&self) -> String {
        let mut all = self.lines.join("\n");
        all.push('\n');
        all.push_str(&self.stderr);
        all
    }
}

fn fnv64(parts: &[&str]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in parts {
        for b in p.bytes().chain([0u8]) {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

fn run_tool(cmd: &mut Command, what: &str) -> Result<(), String> {
    let out = cmd.output().map_err(|e| format!("{what}: cannot run {:?}: {e}", cmd.get_program()))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "{what} failed ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr).lines().take(5).collect::<Vec<_>>().join(" / ")
        ))
    }
}

/// Builds the 0.10.2 probe into the cache (once per source version; concurrent builders each build privately and
/// move the result into place). Needs `idlc` and a C compiler (`CC`, default `cc`) and `libddsc`.
pub fn c010_probe_binary(opts: &InteropOptions) -> Result<PathBuf, String> {
    let cache = opts.cache();
    let dir = cache.join(format!("c010-probe-{:016x}", fnv64(&[C010_SOURCE, LOWSTATE_IDL])));
    let bin = dir.join("c010_probe");
    if bin.is_file() {
        return Ok(bin);
    }
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    let tmp = cache.join(format!("c010-probe-build-{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&tmp).map_err(|e| format!("creating {}: {e}", tmp.display()))?;
    let result = (|| {
        std::fs::write(tmp.join("c010_probe.c"), C010_SOURCE).map_err(|e| e.to_string())?;
        std::fs::write(tmp.join("lowstate.idl"), LOWSTATE_IDL).map_err(|e| e.to_string())?;
        run_tool(
            Command::new("idlc").current_dir(&tmp).args(["-Wno-implicit-extensibility", "lowstate.idl"]),
            "idlc (Debian package cyclonedds-tools)",
        )?;
        let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
        run_tool(
            Command::new(cc).current_dir(&tmp).args([
                "-O1",
                "-I.",
                "-o",
                "c010_probe",
                "c010_probe.c",
                "lowstate.c",
                "-lddsc",
            ]),
            "compiling the probe against libddsc (Debian package cyclonedds-dev)",
        )?;
        Ok::<(), String>(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    if std::fs::rename(&tmp, &dir).is_err() {
        // Another process finished first: use its build.
        let _ = std::fs::remove_dir_all(&tmp);
    }
    if bin.is_file() {
        Ok(bin)
    } else {
        Err(format!("the probe build left no {}", bin.display()))
    }
}

/// The Cyclone DDS 0.10.2 probe, started beside the check run.
#[derive(Debug)]
pub struct C010Probe {
    running: Result<Running, String>,
    seconds: f64,
}

/// Starts the 0.10.2 probe on the target's domain and interface (a build or start failure is kept for the result).
pub fn start_c010(target: &Target, opts: &InteropOptions) -> C010Probe {
    let cfg = target.config();
    let running = c010_probe_binary(opts).and_then(|bin| {
        let mut cmd = Command::new(bin);
        cmd.args([
            cfg.domain_id().to_string(),
            cfg.interface_name().to_owned(),
            format!("{}", opts.seconds),
            opts.min_samples.to_string(),
        ]);
        Running::spawn(cmd)
    });
    C010Probe { running, seconds: opts.seconds }
}

/// Waits for the 0.10.2 probe and judges what it saw.
pub fn finish_c010(probe: C010Probe, target: &Target) -> CheckResult {
    let id = CheckId::InteropCyclone010;
    let running = match probe.running {
        Ok(r) => r,
        Err(e) => {
            return CheckResult::new(id, Status::Inconclusive, format!("no Cyclone DDS 0.10.2 probe: {e}"))
                .with("error", e)
        }
    };
    let done = running.finish(Duration::from_secs_f64(probe.seconds + 20.0));
    judge(id, "a Cyclone DDS 0.10.2 participant configured as Unitree's SDK (the robot's stack)", &done, target)
}

/// The Cyclone 11 probe: started early (its imports take a while), joins the domain when told.
#[derive(Debug)]
pub struct Cyclone11Probe {
    running: Result<Running, String>,
    seconds: f64,
}

/// Starts the Python probe (it imports, then waits).
pub fn start_cyclone11(target: &Target, opts: &InteropOptions) -> Cyclone11Probe {
    if target.config().may_reach_robot() {
        return Cyclone11Probe {
            running: Err("not run against what may be a robot (domain 0 or a real interface): a Cyclone 11 participant's XTypes type information can crash Cyclone DDS 0.10 stacks".into()),
            seconds: opts.seconds,
        };
    }
    let cfg = target.config();
    let running = (|| {
        let dir = opts.cache();
        std::fs::create_dir_all(&dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
        let script = dir.join(format!("cyclone11_probe-{:016x}.py", fnv64(&[CYCLONE11_SOURCE])));
        if !script.is_file() {
            let tmp = dir.join(format!("cyclone11_probe-{}.tmp", std::process::id()));
            std::fs::write(&tmp, CYCLONE11_SOURCE).map_err(|e| format!("writing {}: {e}", tmp.display()))?;
            std::fs::rename(&tmp, &script).map_err(|e| format!("writing {}: {e}", script.display()))?;
        }
        let mut cmd = Command::new(opts.python());
        cmd.arg(&script).args([
            cfg.domain_id().to_string(),
            cfg.interface_name().to_owned(),
            format!("{}", opts.seconds),
            opts.min_samples.to_string(),
        ]);
        Running::spawn(cmd)
    })();
    Cyclone11Probe { running, seconds: opts.seconds }
}

/// Lets the Cyclone 11 probe join, judges what it saw, then checks that the peer still publishes.
pub fn finish_cyclone11(
    probe: Cyclone11Probe,
    target: &mut Target,
    timing: Timing,
) -> Result<CheckResult, ConformError> {
    let id = CheckId::InteropCyclone11;
    let mut running = match probe.running {
        Ok(r) => r,
        Err(e) => {
            return Ok(CheckResult::new(id, Status::Inconclusive, format!("no Cyclone 11 probe: {e}")).with("error", e))
        }
    };
    if running.wait_line("READY", Duration::from_secs(60)).is_none() {
        let done = running.finish(Duration::from_secs(5));
        let why = done
            .lines
            .iter()
            .find_map(|l| {
                serde_json::from_str::<serde_json::Value>(l).ok().and_then(|v| v["error"].as_str().map(str::to_owned))
            })
            .unwrap_or_else(|| done.stderr.lines().last().unwrap_or("no output").to_owned());
        return Ok(CheckResult::new(
            id,
            Status::Inconclusive,
            format!("the Cyclone 11 probe did not start (needs a Python with cyclonedds and unitree_sdk2py): {why}"),
        )
        .with("error", why));
    }
    let go = running.stdin.as_mut().map(|s| s.write_all(b"go\n").and_then(|()| s.flush()));
    if !matches!(go, Some(Ok(()))) {
        let done = running.finish(Duration::from_secs(5));
        return Ok(CheckResult::new(
            id,
            Status::Inconclusive,
            "the Cyclone 11 probe exited before it was told to join",
        )
        .with("log", done.log()));
    }
    // Our own reader watches the stream while the probe is on the domain and after it leaves.
    let before = target.samples.len();
    let done = running.finish(Duration::from_secs_f64(probe.seconds + 20.0));
    target.drain();
    let during = target.samples.len() - before;
    let after = target.observe((20.0 * timing.period).max(0.5))?;
    let mut r = judge(id, "a Cyclone 11 participant as Unitree's Python SDK sets it up", &done, target);
    if after.is_empty() && r.status != Status::Inconclusive {
        r = CheckResult::new(
            id,
            Status::Fail,
            format!("the peer stopped publishing LowState after a Cyclone 11 participant joined (crashed on its discovery data?); {}", r.summary),
        )
        .with("probe", r.evidence.clone());
    }
    Ok(r.with("our_samples_while_probing", during).with("our_samples_after", after.len()))
}

fn judge(id: CheckId, who: &str, done: &Finished, target: &Target) -> CheckResult {
    let log = done.log();
    let invalid_type = log.contains("invalid type object");
    let report = done.report();
    let mut r = if let Some(sig) = done.signal {
        CheckResult::new(
            id,
            Status::Fail,
            format!(
                "{who} crashed (signal {sig}){} while the peer was on the domain",
                if invalid_type {
                    " on XTypes type information it could not parse (`invalid type object`)"
                } else {
                    ""
                }
            ),
        )
    } else if done.killed {
        CheckResult::new(id, Status::Fail, format!("{who} hung (killed after {:.0} s)", done.elapsed_s))
    } else if done.code == Some(4) || report.is_none() {
        CheckResult::new(
            id,
            Status::Inconclusive,
            format!("{who} could not run: {}", log.lines().rfind(|l| !l.trim().is_empty()).unwrap_or("no output")),
        )
    } else if let Some(p) = &report {
        let ours = target.samples.len();
        if p.samples > 0 {
            CheckResult::new(
                id,
                Status::Pass,
                format!(
                    "{who} (Cyclone {}) discovered the peer's rt/lowstate writer and received {} LowState samples it decodes with its own type, first after {:.0} ms{}",
                    p.version,
                    p.samples,
                    p.first_sample_ms,
                    if invalid_type { " (it logged `invalid type object` but survived)" } else { "" }
                ),
            )
        } else if p.matched_writers > 0 {
            CheckResult::new(
                id,
                Status::Fail,
                format!(
                    "{who} (Cyclone {}) matched the peer's rt/lowstate writer but received no sample it could decode in {:.1} s (we received {ours} meanwhile){}",
                    p.version,
                    p.elapsed_ms / 1e3,
                    if invalid_type { "; it logged `invalid type object`" } else { "" }
                ),
            )
        } else {
            CheckResult::new(
                id,
                Status::Fail,
                format!(
                    "{who} (Cyclone {}) never discovered the peer's rt/lowstate writer in {:.1} s, although the peer published {ours} samples to us{}",
                    p.version,
                    p.elapsed_ms / 1e3,
                    if invalid_type { "; it logged `invalid type object`" } else { "" }
                ),
            )
        }
    } else {
        CheckResult::new(id, Status::Inconclusive, format!("{who}: no report"))
    };
    if let Some(p) = report {
        r = r.with("probe", p);
    }
    r.with("exit_code", done.code)
        .with("signal", done.signal)
        .with("invalid_type_object_logged", invalid_type)
        .with("log_tail", log.lines().rev().take(6).collect::<Vec<_>>().into_iter().rev().collect::<Vec<_>>())
}
