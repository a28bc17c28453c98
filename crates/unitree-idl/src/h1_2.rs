//! H1-2 (H1v2) motor-slot map of `unitree_hg` LowCmd/LowState, with per-joint limits.
//!
//! Sources (public facts): slot order, torque and speed limits from Unitree's published
//! H1-2 documentation as summarised in the project's reference sheet; position ranges from
//! Unitree's MuJoCo model of the H1-2 (`unitree_mujoco`, `h1_2_handless.xml`, joint `range`).
//! 27 of the 35 slots are used; slots 27..35 must stay zero.

/// One actuated joint of the H1-2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Joint {
    /// Motor slot in LowCmd.motor_cmd / LowState.motor_state.
    pub slot: usize,
    /// Joint name as in Unitree's robot models.
    pub name: &'static str,
    /// Peak torque (N·m).
    pub torque_limit: f32,
    /// Peak speed (rad/s).
    pub speed_limit: f32,
    /// Lower end of the position range (rad).
    pub lower: f32,
    /// Upper end of the position range (rad).
    pub upper: f32,
}

/// Number of actuated joints (used slots).
pub const NUM_JOINTS: usize = 27;

/// Slots of the ankles' pitch and roll joints (left, then right): the two motors of each ankle's parallel linkage in
/// the A/B mode (`LowCmd.mode_pr` = 1).
pub const ANKLE_SLOTS: [usize; 4] = [4, 5, 10, 11];

/// Index of the waist (torso yaw) joint, which carries the LowState IMU.
pub const TORSO_SLOT: usize = 12;

/// `mode_machine` the simulated H1-2 reports in LowState. Unitree's controllers read it from
/// the first LowState and echo it in LowCmd, so any value works with them; no public figure for
/// the H1-2 is known to us (G1 variants report 4, 5, 6 or 10 depending on hardware). 6 is the
/// project's placeholder; `ulab sim --mode-machine` overrides it.
pub const MODE_MACHINE: u8 = 6;

/// Largest stiffness the project accepts for any joint (N·m/rad). No public limit exists; this
/// is a sanity bound about 3x the stiffest gain in Unitree's own H1-2 code (knee, 300).
pub const KP_MAX: f32 = 1000.0;
/// Largest damping the project accepts for any joint (N·m·s/rad): about 10x Unitree's largest
/// (5); beyond it the discrete PD loop at 500 Hz is unstable on the light wrist joints.
pub const KD_MAX: f32 = 50.0;

const fn j(slot: usize, name: &'static str, torque: f32, speed: f32, lower: f32, upper: f32) -> Joint {
    Joint { slot, name, torque_limit: torque, speed_limit: speed, lower, upper }
}

/// The 27 joints in slot order.
// Figures as Unitree publishes them: 3.14 is their limit, not an approximation of pi.
#[allow(clippy::approx_constant)]
pub const JOINTS: [Joint; NUM_JOINTS] = [
    j(0, "left_hip_yaw_joint", 200.0, 23.0, -0.43, 0.43),
    j(1, "left_hip_pitch_joint", 200.0, 23.0, -3.14, 2.5),
    j(2, "left_hip_roll_joint", 200.0, 23.0, -0.43, 3.14),
    j(3, "left_knee_joint", 300.0, 14.0, -0.12, 2.19),
    j(4, "left_ankle_pitch_joint", 60.0, 9.0, -0.897334, 0.523598),
    j(5, "left_ankle_roll_joint", 40.0, 9.0, -0.261799, 0.261799),
    j(6, "right_hip_yaw_joint", 200.0, 23.0, -0.43, 0.43),
    j(7, "right_hip_pitch_joint", 200.0, 23.0, -3.14, 2.5),
    j(8, "right_hip_roll_joint", 200.0, 23.0, -3.14, 0.43),
    j(9, "right_knee_joint", 300.0, 14.0, -0.12, 2.19),
    j(10, "right_ankle_pitch_joint", 60.0, 9.0, -0.897334, 0.523598),
    j(11, "right_ankle_roll_joint", 40.0, 9.0, -0.261799, 0.261799),
    j(12, "torso_joint", 200.0, 23.0, -2.35, 2.35),
    j(13, "left_shoulder_pitch_joint", 40.0, 9.0, -3.14, 1.57),
    j(14, "left_shoulder_roll_joint", 40.0, 9.0, -0.38, 3.4),
    j(15, "left_shoulder_yaw_joint", 18.0, 20.0, -2.66, 3.01),
    j(16, "left_elbow_joint", 18.0, 20.0, -0.95, 3.18),
    j(17, "left_wrist_roll_joint", 19.0, 31.4, -3.01, 2.75),
    j(18, "left_wrist_pitch_joint", 19.0, 31.4, -0.4625, 0.4625),
    j(19, "left_wrist_yaw_joint", 19.0, 31.4, -1.27, 1.27),
    j(20, "right_shoulder_pitch_joint", 40.0, 9.0, -3.14, 1.57),
    j(21, "right_shoulder_roll_joint", 40.0, 9.0, -3.4, 0.38),
    j(22, "right_shoulder_yaw_joint", 18.0, 20.0, -3.01, 2.66),
    j(23, "right_elbow_joint", 18.0, 20.0, -0.95, 3.18),
    j(24, "right_wrist_roll_joint", 19.0, 31.4, -2.75, 3.01),
    j(25, "right_wrist_pitch_joint", 19.0, 31.4, -0.4625, 0.4625),
    j(26, "right_wrist_yaw_joint", 19.0, 31.4, -1.27, 1.27),
];

/// Looks a joint up by name.
pub fn joint_by_name(name: &str) -> Option<&'static Joint> {
    JOINTS.iter().find(|j| j.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_are_dense_and_in_order() {
        for (i, joint) in JOINTS.iter().enumerate() {
            assert_eq!(joint.slot, i, "{}", joint.name);
            assert!(joint.lower < joint.upper, "{}", joint.name);
        }
    }

    #[test]
    fn left_and_right_share_limits() {
        for (l, r) in JOINTS[0..6].iter().zip(&JOINTS[6..12]).chain(JOINTS[13..20].iter().zip(&JOINTS[20..27])) {
            assert_eq!(l.name.replacen("left", "right", 1), r.name);
            assert_eq!((l.torque_limit, l.speed_limit), (r.torque_limit, r.speed_limit));
        }
    }
}
