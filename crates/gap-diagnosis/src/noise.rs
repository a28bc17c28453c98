//! Noise and scales shared by the plants, the rig check and the diagnosis: a leaf module (it imports nothing from
//! the crate), so that the modules using them do not import each other for a constant.
use serde::{Deserialize, Serialize};

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

/// Standard deviations of the sensor noise of a reference plant (the blind benchmark's "real" robot).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SensorNoise {
    /// Joint position (rad).
    pub q: f64,
    /// Joint velocity (rad/s).
    pub dq: f64,
    /// Estimated joint torque (N·m).
    pub tau: f64,
    /// IMU angular velocity (rad/s).
    pub gyro: f64,
    /// IMU quaternion components.
    pub quat: f64,
    /// Accelerometer (m/s²).
    #[serde(default)]
    pub acc: f64,
}

impl Default for SensorNoise {
    fn default() -> Self {
        SensorNoise { q: 2e-4, dq: 0.01, tau: 0.1, gyro: 0.003, quat: 5e-4, acc: 0.05 }
    }
}
