//! Noise and scales shared by the plants, the rig check and the diagnosis: a leaf module (it imports nothing from
//! the crate), so that the modules using them do not import each other for a constant.

/// Residual scales of the diagnosis (what counts as "one unit" of gap per channel): joint position (rad).
pub const SIGMA_Q: f64 = 2e-3;
/// Joint velocity (rad/s).
pub const SIGMA_DQ: f64 = 0.1;
/// Torque scale as a fraction of each joint's torque limit.
pub const SIGMA_TAU_FRAC: f64 = 0.01;
/// IMU orientation (quaternion components).
pub const SIGMA_QUAT: f64 = 5e-3;
/// IMU angular velocity (rad/s).
pub const SIGMA_GYRO: f64 = 0.02;

/// State intervals outside `[TIMING_LO, TIMING_HI]` x the median interval are irregular (the rig check's
/// differentiated accelerometer prediction skips them).
pub const TIMING_LO: f64 = 0.5;
/// Upper bound of a regular state interval, as a multiple of the median (see [`TIMING_LO`]).
pub const TIMING_HI: f64 = 2.0;
