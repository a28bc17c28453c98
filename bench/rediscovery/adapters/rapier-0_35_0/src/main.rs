//! Rediscovery benchmark: the harness run against rapier3d =0.35.0 (see ../../README.md).
#![forbid(unsafe_code)]

include!("../../shared/glam_era.rs");

fn main() -> std::process::ExitCode {
    rediscovery_harness::print_verdicts(&mut Rapier { version: "0.35.0" })
}
