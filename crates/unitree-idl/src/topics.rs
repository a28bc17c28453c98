//! DDS topic names used by Unitree SDK2 for low-level control.

/// Whole-body low-level command (LowCmd_), controller to robot.
pub const LOWCMD: &str = "rt/lowcmd";
/// Whole-body low-level state (LowState_), robot to controller, about 500 Hz on the real robot.
pub const LOWSTATE: &str = "rt/lowstate";
/// Arm-only command channel used by Unitree's arm SDK examples (hg LowCmd_).
pub const ARM_SDK: &str = "rt/arm_sdk";
/// Second IMU on the pelvis of humanoids (hg IMUState_).
pub const SECONDARY_IMU: &str = "rt/secondary_imu";
/// State of the sport (high-level) controller, go SportModeState_: body position and velocity in the odometry
/// frame. Simulators publish the simulated pelvis pose on it (Unitree's MuJoCo bridge, `ulab sim`).
pub const SPORTMODESTATE: &str = "rt/sportmodestate";
/// Low-frequency variant of the state topic (prefix `rt/lf/`).
pub const LF_LOWSTATE: &str = "rt/lf/lowstate";

/// DDS domain of real robots. Tools must never use it without an explicit opt-in.
pub const ROBOT_DOMAIN: u32 = 0;
/// DDS domain the public simulator bridges (unitree_mujoco, gz-unitree) use, on interface `lo`.
pub const SIM_DOMAIN: u32 = 1;
