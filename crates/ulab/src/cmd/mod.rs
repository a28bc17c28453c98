//! Subcommands. One module per subcommand; each exposes `Args` and `run(Args) -> anyhow::Result<Exit>`.
pub mod codec;
pub mod conform;
pub mod conform_controller;
pub mod deploy;
pub mod diff;
pub mod doctor;
pub mod gap;
pub mod log;
pub mod merge;
pub mod model;
pub mod record;
pub mod recording;
pub mod render;
pub mod replay;
pub mod sim;
pub mod sim_loco;
pub mod validate;
pub mod video;

/// A help line ending in the engines compiled into this build (they depend on `diff-physics` features), for every
/// flag that names an engine.
pub(crate) fn engines_help(lead: &str) -> String {
    format!("{lead} {}", diff_physics::EngineKind::available_names())
}

/// `--format` of the commands that print a report: a human summary or the whole report as JSON.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OutputFormat {
    Text,
    Json,
}
