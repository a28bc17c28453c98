//! `robot-model`: the project's own kinematic-tree model of a Unitree robot.
//!
//! A model is a URDF (links, inertials, collision primitives, revolute joints) plus a sidecar TOML for what
//! URDF cannot say (armature, joint damping and friction, motor-slot map, PD gains, standing pose, contact
//! parameters, IMU site). [`RobotModel::load`] reads and validates both; [`RobotModel::h1_2`] is the built-in
//! Unitree H1-2 (files embedded, so binaries work from any directory).
//!
//! Conventions used throughout the crate (and by `diff-physics`):
//! - quaternions are `[w, x, y, z]`, rotating body-frame vectors into the parent/world frame;
//! - generalized position `q = [base pos (3, world), base quat (4), joint angles (nj, slot order)]`;
//! - generalized velocity `v = [base linear velocity of the base-link origin in the WORLD frame (3),
//!   base angular velocity in the BASE-LINK frame (3), joint velocities (nj)]` (MuJoCo's free-joint layout);
//! - generalized force is the dual of `v`: force on the base in the world frame, moment about the base-link
//!   origin in the base-link frame, joint torques.
#![forbid(unsafe_code)]

mod contact;
mod dynamics;
mod error;
mod kinematics;
mod load;
mod mjcf;
mod model;

pub use contact::FootContact;
pub use dynamics::{RigidBodyDynamics, GRAVITY_EARTH};
pub use error::ModelError;
pub use kinematics::{quat_wxyz, tilt_from_vertical, FkResult, GenCoords};
pub use load::SidecarFile;
pub use mjcf::{MjcfOptions, ShapeFilter};
pub use model::{Collision, ContactParams, ImuSite, Inertial, Joint, Link, RobotModel, Shape, StandingPose};

/// Built-in robots, by the name used on the command line (`--robot`).
pub const BUILTIN_ROBOTS: &[&str] = &["h1_2"];

/// Loads a built-in robot by name.
pub fn builtin(name: &str) -> Result<RobotModel, ModelError> {
    match name {
        "h1_2" => RobotModel::h1_2(),
        other => Err(ModelError::UnknownRobot(other.to_string())),
    }
}
