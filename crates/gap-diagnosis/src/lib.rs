//! `gap-diagnosis`: sim-to-real gap diagnosis (issue 6).
//!
//! * [`log`]: the robot log (MCAP as `ulab record` writes it, or CSV);
//! * [`plant`]: engine on a suspension rig + actuator/sensor effect layer + model-level effects;
//! * [`floating`]: the robot on the ground (floating base): base-state estimate from a log sample, plant, windows;
//! * [`effects`]: the effect library (parameters, ranges, scopes); [`noise`]: sensor noise and residual scales;
//! * [`diagnose()`]: the log's timing and numerics, where the gap lies, which effect explains it (one decision
//!   model, [`diagnose::Thresholds`]), how much it shrinks (held-out, with intervals);
//! * [`rig_check`]: does the log fit the rig assumption (pelvis held still)? Otherwise the diagnosis abstains;
//! * [`excite`]: safe excitation plans; [`report`]: Markdown, JSON and SVG plots; [`export`]: the corrected MJCF.
//!
//! The blind benchmark, with the reference plants that generate its logs, is the `gap-bench` crate.
#![forbid(unsafe_code)]

pub mod diagnose;
pub mod effects;
pub mod excite;
pub mod export;
pub mod floating;
pub mod log;
pub mod noise;
pub mod plant;
pub mod report;
pub mod rig_check;

pub use diagnose::{diagnose, DiagnoseOptions, Outcome, Report};
pub use effects::EffectKind;
pub use log::RobotLog;

/// Errors of the diagnosis.
#[derive(Debug, thiserror::Error)]
pub enum GapError {
    #[error("log: {0}")]
    Log(String),
    /// The MCAP file could not be read (its sources say why).
    #[error("reading the MCAP log")]
    Recording(#[from] recording::ReadError),
    /// The physics engine failed (its error is the source).
    #[error("engine")]
    Engine(#[from] diff_physics::EngineError),
    /// Kinematics or dynamics of the robot model failed (its error is the source).
    #[error("robot model")]
    Model(#[from] robot_model::ModelError),
    /// A numerical solve failed (what, and the solver's message).
    #[error("numerics: {0}")]
    Numerics(String),
    #[error("input: {0}")]
    Input(String),
    /// Writing an MCAP log failed (the writer's error is the source).
    #[error("writing the MCAP log")]
    McapWrite(#[from] mcap::McapError),
    /// Reading or writing a file failed.
    #[error("file {}", path.display())]
    File {
        /// The file or directory.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// Drawing a plot failed (the plotting library's error is the source).
    #[error("drawing {}", path.display())]
    Plot {
        /// The picture being drawn.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// Serialising a JSON document failed (the serialiser's error is the source).
    #[error("serialising JSON")]
    Json(#[from] serde_json::Error),
}
