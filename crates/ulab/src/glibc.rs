//! The CLI's one FFI module: glibc's `malloc_trim`, so that the long-running commands (`sim`, `record`) give
//! memory that was freed back to the kernel.
//!
//! Why: every DDS participant that comes and goes (a subscriber, a recorder) makes Cyclone allocate and free its
//! discovery state. glibc keeps freed memory inside its arenas, so a bridge whose live heap is flat still grew
//! ~22 KiB/min of resident memory under participant churn; `malloc_trim(0)` returned all of it (BENCHMARKS.md,
//! "Soak": heap profile and trim experiment).
//!
//! # Invariants
//! - `malloc_trim` takes glibc's own arena locks: any thread may call it at any time, concurrently with
//!   allocations on other threads (it only delays them while it walks an arena). It frees nothing that is in use:
//!   it returns whole free pages to the kernel (`MADV_DONTNEED`) and shrinks the heap's top.
//! - On targets without glibc (musl, macOS) this module calls nothing and reports that.
#![allow(unsafe_code)]

use std::time::Duration;

/// Returns the allocator's free pages to the kernel; `true` when some memory was released.
pub fn release_free_memory() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: malloc_trim takes no pointers and locks the allocator itself (see the module's invariants).
        unsafe { libc::malloc_trim(0) != 0 }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

/// How often the long-running commands return freed memory: rare enough to cost nothing measurable (a trim of
/// the bridge's ~20 MiB heap takes well under a millisecond), often enough that resident memory tracks live memory.
pub const TRIM_EVERY: Duration = Duration::from_secs(30);

/// Starts a background thread that calls [`release_free_memory`] every `every` for the rest of the process.
pub fn trim_periodically(every: Duration) {
    // A thread that cannot be spawned only means the memory is not returned early: not worth failing the command.
    let _ = std::thread::Builder::new().name("malloc-trim".into()).spawn(move || loop {
        std::thread::sleep(every);
        release_free_memory();
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Memory freed in the middle of the heap (kept alive around it, so that no shrink of the heap's top could
    /// return it) comes back to the kernel: the process's anonymous resident memory falls by most of it.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[test]
    fn freed_memory_goes_back_to_the_kernel() {
        fn anon_kib() -> u64 {
            let s = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
            s.lines()
                .find_map(|l| l.strip_prefix("RssAnon:")?.split_whitespace().next()?.parse().ok())
                .expect("RssAnon")
        }
        // 64 MiB in 16-KiB blocks (under glibc's mmap threshold: they live in the heap), every page written.
        let mut blocks: Vec<Vec<u8>> = (0..4096).map(|i| vec![(i % 251) as u8 + 1; 16 << 10]).collect();
        let keep_last = blocks.pop();
        let full = anon_kib();
        // Free all but the last block: the freed memory sits below a block that is still in use.
        blocks.clear();
        blocks.shrink_to_fit();
        let freed = anon_kib();
        assert!(release_free_memory(), "malloc_trim released nothing");
        let trimmed = anon_kib();
        assert!(keep_last.is_some());
        eprintln!("anonymous RSS: {full} KiB with the blocks, {freed} KiB after free, {trimmed} KiB after the trim");
        assert!(full >= trimmed + 48 * 1024, "{full} → {trimmed} KiB: the trim did not return the freed 64 MiB");
    }
}
