//! Test-only helpers shared by every test suite of the workspace (a dev-dependency, never published).
//!
//! - [`DomainLease`]: DDS domains for tests come from one place. Each lease holds an exclusive lock on a file per
//!   domain id, so test binaries running at the same time on one machine (threads of one binary, two checkouts,
//!   two CI jobs) never share a domain and never see each other's samples.
//! - [`RealtimeSlot`]: a machine-wide lock for tests that run a simulator or a DDS peer in real time, so that two of
//!   them never compete for the cores (on a 2-core machine two real-time simulators starve each other).
//! - [`process`]: child processes with hard timeouts and output read on threads.
#![forbid(unsafe_code)]

pub mod process;

use std::fs::{File, OpenOptions};
use std::path::PathBuf;
use std::time::Duration;

/// First and last domain id handed out to tests. Cyclone DDS accepts ids up to 232 (its port mapping); 0 is the
/// real robots' domain and 1 the public simulator bridges' default, both never leased; the low range stays free for
/// people running `ulab sim` by hand beside a test run.
pub const TEST_DOMAINS: std::ops::RangeInclusive<u32> = 100..=230;

fn lock_dir() -> PathBuf {
    let dir = std::env::temp_dir().join("ulab-test-locks");
    // Best effort: a failure shows up as a clear panic when the lock file is opened.
    let _ = std::fs::create_dir_all(&dir);
    dir
}

fn open_lock(name: &str) -> File {
    let path = lock_dir().join(name);
    OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .unwrap_or_else(|e| panic!("test-support: cannot open lock file {}: {e}", path.display()))
}

/// A DDS domain id held exclusively by this test until the lease is dropped (machine-wide: an advisory file lock,
/// released by the OS when the process dies, so a crashed test never leaks a domain).
#[derive(Debug)]
pub struct DomainLease {
    domain: u32,
    _lock: File,
}

impl DomainLease {
    /// Leases the first free domain of [`TEST_DOMAINS`]. Panics (a test-setup failure) when all are taken.
    pub fn new() -> Self {
        for domain in TEST_DOMAINS {
            let file = open_lock(&format!("dds-domain-{domain}.lock"));
            if file.try_lock().is_ok() {
                return DomainLease { domain, _lock: file };
            }
        }
        panic!("test-support: every test DDS domain {TEST_DOMAINS:?} is leased");
    }

    /// The leased domain id.
    pub fn id(&self) -> u32 {
        self.domain
    }

    /// The domain id as a command-line argument.
    pub fn arg(&self) -> String {
        self.domain.to_string()
    }
}

impl Default for DomainLease {
    fn default() -> Self {
        Self::new()
    }
}

/// Leases a DDS domain for one test (see [`DomainLease`]).
pub fn lease_domain() -> DomainLease {
    DomainLease::new()
}

/// The one real-time test of the machine (a simulator with its clients, a DDS rate measurement): no other real-time
/// test runs beside it; ordinary tests may (nextest gives it a core of its own, `.config/nextest.toml`).
/// Machine-wide and blocking: waits for the slot, released on drop or when the process dies.
#[derive(Debug)]
pub struct RealtimeSlot {
    _lock: File,
}

impl RealtimeSlot {
    /// Waits until no other real-time test on this machine runs, then holds the slot.
    pub fn acquire() -> Self {
        let file = open_lock("realtime.lock");
        file.lock().unwrap_or_else(|e| panic!("test-support: cannot take the real-time lock: {e}"));
        RealtimeSlot { _lock: file }
    }
}

/// How long a test may wait for something a healthy run does in well under a second (a peer's discovery, the
/// first sample): generous, because a loaded machine can be 10-50x slower than a quiet one and a timeout here only
/// turns a hang into a failure, it never decides a pass.
pub const PATIENCE: Duration = Duration::from_secs(60);
