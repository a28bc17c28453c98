//! The crate's error type.

/// Why a frame could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The pose does not fit the model (wrong joint count, non-finite values).
    #[error("the pose does not fit the robot model")]
    Model(#[from] robot_model::ModelError),
    /// Unusable render options.
    #[error("invalid render options: {0}")]
    Options(String),
}
