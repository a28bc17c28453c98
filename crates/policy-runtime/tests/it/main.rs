//! The integration tests of `policy-runtime`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p policy-runtime --test it -- MODULE::`.

mod closed_loop;
mod golden;
mod imu_mujoco;
mod malformed_spec;
mod observation;
mod spec;
mod torchscript;
