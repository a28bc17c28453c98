//! From the H1-2's LowState IMU (on the torso) to the pelvis-frame quantities policies are trained on.
//!
//! Convention: the torso hangs on the pelvis through the waist joint (motor slot 12, `torso_joint`), a pure
//! rotation about the pelvis z axis at angle `q_w` (the joint origin carries no rotation in the H1-2 model), so
//! `R_torso = R_pelvis · Rz(q_w)`. The IMU frame is the torso frame (identity mounting, `robots/h1_2/h1_2.toml`
//! `[imu]`). Hence
//!
//! * `R_pelvis = R_torso · Rz(q_w)ᵀ`;
//! * `ω_pelvis (pelvis frame) = Rz(q_w) · ω_torso (torso frame) − (0, 0, q̇_w)`,
//!
//! because the torso's angular velocity is the pelvis's plus `q̇_w` about the shared z axis. This is the
//! transform of unitree_rl_gym's `deploy/deploy_real/common/rotation_helper.py` (`transform_imu_data`).

use crate::{PolicyError, RobotObservation};

/// Motor slot of the waist (torso yaw) joint on the H1-2.
pub const WAIST_SLOT: usize = 12;

/// Pelvis orientation and angular velocity derived from the torso IMU.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PelvisImu {
    /// `[w, x, y, z]`, pelvis-to-world.
    pub quat: [f64; 4],
    /// Pelvis angular velocity, pelvis frame (rad/s).
    pub ang_vel: [f64; 3],
}

fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    let [aw, ax, ay, az] = a;
    let [bw, bx, by, bz] = b;
    [
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ]
}

/// Pelvis orientation and angular velocity from the torso IMU quaternion (`[w, x, y, z]`, torso-to-world),
/// its gyroscope (torso frame) and the waist joint angle and velocity. See the module docs.
pub fn pelvis_imu_from_torso(torso_quat: [f64; 4], torso_gyro: [f64; 3], waist_q: f64, waist_dq: f64) -> PelvisImu {
    let (s, c) = (0.5 * waist_q).sin_cos();
    // q_pelvis = q_torso ⊗ conj(q_z(waist)), with q_z = (cos q/2, 0, 0, sin q/2).
    let quat = quat_mul(torso_quat, [c, 0.0, 0.0, -s]);
    let (sw, cw) = waist_q.sin_cos();
    let [gx, gy, gz] = torso_gyro;
    let ang_vel = [cw * gx - sw * gy, sw * gx + cw * gy, gz - waist_dq];
    PelvisImu { quat, ang_vel }
}

impl RobotObservation {
    /// A pelvis-frame observation from LowState-style readings: torso IMU quaternion and gyroscope, joint
    /// angles and velocities in slot order (the waist at [`WAIST_SLOT`]).
    pub fn from_torso_imu(
        time: f64,
        torso_quat: [f64; 4],
        torso_gyro: [f64; 3],
        q: Vec<f64>,
        dq: Vec<f64>,
        command: [f64; 3],
    ) -> Result<Self, PolicyError> {
        let (waist_q, waist_dq) = match (q.get(WAIST_SLOT), dq.get(WAIST_SLOT)) {
            (Some(&a), Some(&b)) => (a, b),
            _ => {
                return Err(PolicyError::Observation(format!(
                    "need the waist joint (slot {WAIST_SLOT}): q has {} and dq {} entries",
                    q.len(),
                    dq.len()
                )))
            }
        };
        let pelvis = pelvis_imu_from_torso(torso_quat, torso_gyro, waist_q, waist_dq);
        Ok(RobotObservation { time, base_quat: pelvis.quat, base_ang_vel: pelvis.ang_vel, q, dq, command })
    }
}
