//! Noise and scales shared by the plants, the rig check and the diagnosis, and the gap metric's joint term: it
//! imports only the log's measurement type, so that the modules using them do not import each other for a constant.

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

/// Each joint's torque scale of the gap metric (N·m): [`SIGMA_TAU_FRAC`] of its torque limit, at least of 1 N·m.
pub fn torque_scales(model: &robot_model::RobotModel) -> Vec<f64> {
    model.joints.iter().map(|j| SIGMA_TAU_FRAC * j.torque_limit.max(1.0)).collect()
}

/// Adds one sample's normalised squared difference of `m` and `p` per joint (angle, speed and torque over their
/// scales, averaged) to `s[j]`: the gap metric's joint term.
pub fn add_joint_terms(sigma_tau: &[f64], m: &crate::log::Measurement, p: &crate::log::Measurement, s: &mut [f64]) {
    for (j, x) in s.iter_mut().enumerate().take(sigma_tau.len()) {
        let eq = (m.q[j] - p.q[j]) / SIGMA_Q;
        let edq = (m.dq[j] - p.dq[j]) / SIGMA_DQ;
        let et = (m.tau[j] - p.tau[j]) / sigma_tau[j];
        *x += (eq * eq + edq * edq + et * et) / 3.0;
    }
}
