//! Rediscovery benchmark: the harness run against rapier3d =0.20.0 (see ../../README.md).
#![forbid(unsafe_code)]

/// This version's broad phase.
type Broad = rapier3d::prelude::DefaultBroadPhase;

include!("../../shared/nalgebra_era.rs");

fn main() -> std::process::ExitCode {
    rediscovery_harness::print_verdicts(&mut Rapier { version: "0.20.0" })
}
