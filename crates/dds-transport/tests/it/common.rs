//! Helpers shared by the interop tests: hg LowCmd_/LowState_ payloads through the project's codec
//! (XCDR1 little-endian, as Unitree's SDK sends them), helper-process handling with hard timeouts.
#![allow(dead_code, unused_imports)]

use lowlevel_codec::{cdr, Encoding};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
pub use test_support::{lease_domain, DomainLease, RealtimeSlot, PATIENCE};
use unitree_idl::hg;

/// Serialized size of hg LowCmd_ with its header.
pub const HG_LOWCMD_LEN: usize = 1004;
/// Serialized size of hg LowState_ with its header.
pub const HG_LOWSTATE_LEN: usize = 2092;

/// An hg LowCmd_ (XCDR1 little-endian, as Unitree's SDK sends it): every motor mode 1 with
/// q = q(i), kp of motor 0, mode_machine 6, the given crc.
pub fn hg_lowcmd(q: impl Fn(usize) -> f32, kp0: f32, crc: u32) -> Vec<u8> {
    hg_lowcmd_with(q, kp0, crc, 0)
}

/// An hg LowCmd_ asking the C test peer to exit (reserve[0] = 0xDEADBEEF).
pub fn hg_lowcmd_shutdown() -> Vec<u8> {
    hg_lowcmd_with(|_| 0.0, 0.0, 0, 0xDEAD_BEEF)
}

fn hg_lowcmd_with(q: impl Fn(usize) -> f32, kp0: f32, crc: u32, reserve0: u32) -> Vec<u8> {
    let mut cmd = hg::LowCmd_ { mode_machine: 6, crc, ..Default::default() };
    for (i, m) in cmd.motor_cmd.iter_mut().enumerate() {
        m.mode = 1;
        m.q = q(i);
    }
    cmd.motor_cmd[0].kp = kp0;
    cmd.reserve[0] = reserve0;
    cdr::encode(&cmd, Encoding::UNITREE)
}

fn hg_lowstate(b: &[u8]) -> Option<hg::LowState_> {
    cdr::decode::<hg::LowState_>(b).ok().map(|d| d.value)
}

/// tick of a serialized hg LowState_.
pub fn hg_lowstate_tick(b: &[u8]) -> Option<u32> {
    hg_lowstate(b).map(|s| s.tick)
}

/// motor_state[i].q of a serialized hg LowState_.
pub fn hg_lowstate_q(b: &[u8], i: usize) -> Option<f32> {
    hg_lowstate(b).and_then(|s| s.motor_state.get(i).map(|m| m.q))
}

/// reserve[k] of a serialized hg LowState_.
pub fn hg_lowstate_reserve(b: &[u8], k: usize) -> Option<u32> {
    hg_lowstate(b).and_then(|s| s.reserve.get(k).copied())
}

pub fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn workspace_dir() -> PathBuf {
    let p = crate_dir().join("../..");
    p.canonicalize().unwrap_or(p)
}

/// The project's Python (venv), from ULAB_PYTHON or .venv.
pub fn python() -> PathBuf {
    if let Ok(p) = std::env::var("ULAB_PYTHON") {
        return PathBuf::from(p);
    }
    workspace_dir().join(".venv/bin/python")
}

/// Runs a command to completion with a timeout; returns (success, stdout, stderr).
pub fn run_with_timeout(cmd: &mut Command, timeout: Duration) -> (bool, String, String) {
    let child = cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn();
    let child = match child {
        Ok(c) => c,
        Err(e) => panic!("cannot start {cmd:?}: {e}"),
    };
    let out = Proc::new(child).wait(timeout);
    (out.0 == Some(0), out.1, out.2)
}

/// A helper process whose output is collected on threads and which is killed on drop.
pub struct Proc {
    child: Child,
    out: Option<std::thread::JoinHandle<String>>,
    err: Option<std::thread::JoinHandle<String>>,
}

fn collect(mut r: impl Read + Send + 'static) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = r.read_to_end(&mut v);
        String::from_utf8_lossy(&v).into_owned()
    })
}

impl Proc {
    pub fn new(mut child: Child) -> Self {
        let out = child.stdout.take().map(collect);
        let err = child.stderr.take().map(collect);
        Self { child, out, err }
    }

    pub fn spawn(cmd: &mut Command) -> Self {
        match cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn() {
            Ok(c) => Self::new(c),
            Err(e) => panic!("cannot start {cmd:?}: {e}"),
        }
    }

    /// Whether it has exited.
    pub fn has_exited(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(Some(_)))
    }

    /// The process id.
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// Waits for exit up to `timeout` (then kills). Returns (exit code, stdout, stderr);
    /// exit code None means killed by a signal or by the timeout.
    pub fn wait(mut self, timeout: Duration) -> (Option<i32>, String, String) {
        let deadline = Instant::now() + timeout;
        let mut code = None;
        let mut timed_out = false;
        loop {
            match self.child.try_wait() {
                Ok(Some(st)) => {
                    code = st.code();
                    if code.is_none() {
                        use std::os::unix::process::ExitStatusExt;
                        eprintln!("helper died with signal {:?}", st.signal());
                    }
                    break;
                }
                Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(20)),
                _ => {
                    timed_out = true;
                    let _ = self.child.kill();
                    let _ = self.child.wait();
                    break;
                }
            }
        }
        let out = self.out.take().and_then(|h| h.join().ok()).unwrap_or_default();
        let mut err = self.err.take().and_then(|h| h.join().ok()).unwrap_or_default();
        if timed_out {
            err.push_str("\n[killed: timeout]\n");
        }
        (code, out, err)
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Builds the Cyclone 0.10.2 C peer into the cargo target tmp dir (once per test binary: tests
/// run on parallel threads, and one must not exec the binary while another rewrites it);
/// returns its path.
pub fn build_c010_peer() -> PathBuf {
    static PEER: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    PEER.get_or_init(build_c010_peer_once).clone()
}

fn build_c010_peer_once() -> PathBuf {
    let src = crate_dir().join("tests/peers/c010");
    let tmpdir = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let out = tmpdir.join("c010-peer");
    let target = out.join("peer");
    // Up to date: nothing to do (also keeps concurrent test processes from rebuilding it).
    let mtime = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let newest_src = ["peer.c", "unitree_hg.idl", "Makefile"].iter().filter_map(|f| mtime(&src.join(f))).max();
    if let (Some(t), Some(s)) = (mtime(&target), newest_src) {
        if t >= s {
            return target;
        }
    }
    // Build in a private directory, then move the binary into place atomically: another test
    // process may be executing the old one.
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    let private = tmpdir.join(format!("c010-peer-build-{}-{nanos}", std::process::id()));
    let (ok, stdout, stderr) = run_with_timeout(
        Command::new("make").arg("-s").arg("-f").arg(src.join("Makefile")).arg(format!("OUT={}", private.display())),
        Duration::from_secs(120),
    );
    assert!(
        ok,
        "building the Cyclone 0.10.2 peer failed (needs Debian's cyclonedds-dev and cyclonedds-tools, see scripts/setup.sh):\n{stdout}\n{stderr}"
    );
    std::fs::create_dir_all(&out).expect("peer output directory");
    std::fs::rename(private.join("peer"), &target).expect("move the peer into place");
    let _ = std::fs::remove_dir_all(&private);
    target
}
