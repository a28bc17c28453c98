//! The integration tests of `ulab`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p ulab --test it -- MODULE::`.

mod codec_cli;
mod common;
mod compressed_mcap;
mod conform_cli;
mod conform_controller;
mod conform_matrix;
mod conform_sim;
mod deploy_sim;
mod diff_cli;
mod doctor;
mod gap_cli;
mod gap_hang;
mod model_cli;
mod record_crash;
mod record_replay;
mod render_cli;
mod shard_cli;
mod sim_c010_client;
mod sim_loco_client;
mod sim_motion_switcher_client;
mod sim_robustness;
mod sim_sdk_client;
mod validate_cli;
