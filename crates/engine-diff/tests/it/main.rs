//! The integration tests of `engine-diff`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p engine-diff --test it -- MODULE::`.

mod allowlist_evidence;
mod campaign_triage;
mod determinism;
mod engine_failure;
mod fuzz_regressions;
mod harness;
mod planted_bug;
mod planted_cheat;
mod report_snapshot;
mod validate_verdict;
