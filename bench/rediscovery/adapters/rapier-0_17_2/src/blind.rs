//! Blind mode (issue 63) against rapier3d =0.17.2: runs the harness's generated scenes (see ../../README.md).
#![forbid(unsafe_code)]

/// This version's broad phase.
type Broad = rapier3d::prelude::BroadPhase;
/// This version's name of the linear joint axis along x.
const SLIDE_AXIS: rapier3d::prelude::JointAxis = rapier3d::prelude::JointAxis::X;

fn main() -> std::process::ExitCode {
    blind_main("0.17.2")
}

include!("../../shared/nalgebra_blind.rs");
