//! `engine-diff`: differential testing of physics engines driven by policy rollouts (issue 5).
//!
//! The same controller (an RL policy or the built-in [`excitation`] input) drives every engine with the same
//! commands and perturbations ([`scenario::Scenario`]). Divergence is measured in short WINDOWS that start
//! from identical states: at each window start the lead engine's state is loaded into every engine (the lead
//! included, so that every engine starts the window equally cold), the lead's control targets are replayed in
//! all of them, and the others are compared with the lead after one step and after k steps ([`harness`]).
//! Episode outcomes (falls, tracking error) come from free closed-loop runs per engine and are compared as
//! distributions over seeds. Findings are triaged ([`triage`]: translation problem, allow-listed modelling
//! difference, candidate engine bug), minimized, written as reports ([`report`]) and reproducers
//! ([`repro`]) that replay bit for bit. [`fuzz`] searches perturbations for the largest divergence per unit
//! of perturbation.
//!
//! Engines come from [`harness::EngineFactory`]s, so a different engine build (e.g. an older Rapier) can be
//! plugged in beside the built-in kinds.
#![forbid(unsafe_code)]

pub mod bench;
pub mod determinism;
pub mod excitation;
pub mod fuzz;
pub mod gait;
pub mod harness;
pub mod phase;
pub mod report;
pub mod repro;
pub mod scenario;
pub mod search;
pub mod triage;
pub mod validate;

use thiserror::Error;

/// Errors of the harness.
#[derive(Debug, Error)]
pub enum DiffError {
    #[error(transparent)]
    Engine(#[from] diff_physics::EngineError),
    /// An engine failed while it ran an input (diverged, or refused a state the others took): which, and when.
    #[error("{engine} failed at t = {t:.4} s")]
    EngineFailed {
        engine: String,
        t: f64,
        #[source]
        source: Box<diff_physics::EngineError>,
    },
    #[error(transparent)]
    Policy(#[from] policy_runtime::PolicyError),
    #[error(transparent)]
    Model(#[from] robot_model::ModelError),
    #[error("bad input: {0}")]
    Input(String),
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("json: {0}")]
    Json(#[from] serde_json::Error),
    /// The allow-list is not valid TOML (the parser's error is the source).
    #[error("allow-list")]
    AllowListSyntax(#[source] toml::de::Error),
    /// An allow-list entry is malformed (which, and why).
    #[error("allow-list: {0}")]
    AllowList(String),
    /// Drawing a plot failed (the plotting library's error is the source).
    #[error("plot")]
    Plot(#[source] Box<dyn std::error::Error + Send + Sync>),
}

/// Version of the JSON formats written here (`report.json`, reproducers, corpus entries).
pub const SCHEMA_VERSION: u32 = 1;

/// A stable hash of a robot model (sha256 of its full debug rendering, which prints every f64 exactly), so
/// that a reproducer can tell whether it is replayed on the same model.
pub fn model_hash(model: &robot_model::RobotModel) -> String {
    use sha2::{Digest, Sha256};
    let h = Sha256::digest(format!("{model:?}").as_bytes());
    h.iter().map(|b| format!("{b:02x}")).collect()
}

pub(crate) fn io_err(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> DiffError + '_ {
    move |source| DiffError::Io { path: path.display().to_string(), source }
}
