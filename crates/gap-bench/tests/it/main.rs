//! The integration tests of `gap-bench`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p gap-bench --test it -- MODULE::`.

mod common;
mod counterfactual;
mod effects_found;
mod floating;
mod floating_bench;
mod floating_diagnose;
mod identifiability;
mod numerics;
mod policy_trials;
mod reference_engines;
mod rig_check;
