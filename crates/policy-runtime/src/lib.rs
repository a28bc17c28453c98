//! `policy-runtime`: RL policies for the H1-2 (ONNX via tract, unitree_rl_gym LSTM from arrays) behind one
//! controller interface, so that the engine-diff harness, the simulator and the gap benchmark drive robots the
//! same way whatever produced the actions.
//!
//! * [`spec`]: policy spec files (TOML) — observation terms, history, action scale, joints, gains, period.
//! * [`network`]: [`OnnxPolicy`] (tract) and [`LstmPolicy`] (rsl_rl recurrent actor from `.npz` arrays, or
//!   from the TorchScript `.pt` via [`torchscript`]).
//! * [`observation`]: projected gravity, gait phase, the observation history.
//! * [`PolicyController`]: a spec and its network as a [`Controller`].
//! * [`imu`]: torso IMU (LowState) → pelvis-frame [`RobotObservation`].
#![forbid(unsafe_code)]

pub mod controller;
pub mod imu;
pub mod network;
pub mod observation;
pub mod spec;
pub mod torchscript;

pub use controller::PolicyController;
pub use imu::{pelvis_imu_from_torso, PelvisImu, WAIST_SLOT};
pub use network::{LstmPolicy, OnnxPolicy, PolicyNetwork};
pub use spec::{
    HistoryLayout, JointSpec, LstmInitialState, ObservationTerm, PolicyKind, PolicySpec, SpecError, TermKind,
};

use diff_physics::PdTarget;
use thiserror::Error;

/// Errors from loading or running a controller.
#[derive(Debug, Error)]
pub enum PolicyError {
    #[error("policy spec: {0}")]
    Spec(String),
    #[error("policy model {path}: {reason}")]
    Model { path: String, reason: String },
    #[error("observation: {0}")]
    Observation(String),
    #[error("inference: {0}")]
    Inference(String),
    /// A spec that is malformed or does not fit its model (typed, see [`SpecError`]).
    #[error(transparent)]
    InvalidSpec(#[from] SpecError),
}

/// What a controller sees at one control step. Everything is in the PELVIS frame and motor-slot order
/// (`model.joints` order), the conventions of `diff_physics::engine`; sources that measure on the torso (the
/// LowState IMU) convert before building this.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotObservation {
    /// Time since the controller's reset (s).
    pub time: f64,
    /// Pelvis orientation, `[w, x, y, z]`, pelvis-to-world.
    pub base_quat: [f64; 4],
    /// Pelvis angular velocity in the pelvis frame (rad/s).
    pub base_ang_vel: [f64; 3],
    /// Joint positions (rad), slot order, `model.nj()` entries.
    pub q: Vec<f64>,
    /// Joint velocities (rad/s), slot order.
    pub dq: Vec<f64>,
    /// Velocity command `(vx, vy, wz)` in the pelvis heading frame (m/s, m/s, rad/s).
    pub command: [f64; 3],
}

/// A controller: called once per control period with the latest observation, answers with PD targets for
/// every joint (slot order; joints it does not command hold their default pose with its gains).
pub trait Controller: Send + std::fmt::Debug {
    /// Short stable name (reports, reproducers).
    fn name(&self) -> &str;
    /// Control period (s), e.g. 0.02 for a 50 Hz policy.
    fn period(&self) -> f64;
    /// Clears internal state (history, recurrent state, last action) before an episode.
    fn reset(&mut self);
    /// One control step.
    fn act(&mut self, obs: &RobotObservation) -> Result<PdTarget, PolicyError>;
}
