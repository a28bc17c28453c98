//! Blind mode (issue 63) against rapier3d =0.35.0: runs the harness's generated scenes (see ../../README.md).
#![forbid(unsafe_code)]

fn main() -> std::process::ExitCode {
    blind_main("0.35.0")
}

include!("../../shared/glam_blind.rs");
