use nalgebra::{Isometry3, Matrix3, Unit, Vector3};
use serde::Serialize;

/// Mass properties of a link: mass, centre of mass and rotational inertia about the centre of mass,
/// both expressed in the link frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Inertial {
    pub mass: f64,
    pub com: Vector3<f64>,
    pub inertia: Matrix3<f64>,
}

/// Primitive collision shapes. Capsules and cylinders have their axis along the shape frame's z axis,
/// centred at its origin (URDF convention); `half_length` is half the cylindrical part.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Shape {
    Box { half_extents: [f64; 3] },
    Sphere { radius: f64 },
    Capsule { radius: f64, half_length: f64 },
    Cylinder { radius: f64, half_length: f64 },
}

impl Shape {
    /// Lowest world z of the shape placed at `w` (world pose of its frame): its support in direction -z, the centre's
    /// z minus the shape's extent along world z.
    pub fn lowest_z(&self, w: &Isometry3<f64>) -> f64 {
        let r = w.rotation.to_rotation_matrix();
        let m = r.matrix();
        let ext = match *self {
            Shape::Box { half_extents: h } => (0..3).map(|k| h[k] * m[(2, k)].abs()).sum::<f64>(),
            Shape::Sphere { radius } => radius,
            Shape::Capsule { radius, half_length } => half_length * m[(2, 2)].abs() + radius,
            Shape::Cylinder { radius, half_length } => {
                half_length * m[(2, 2)].abs() + radius * (1.0 - m[(2, 2)] * m[(2, 2)]).max(0.0).sqrt()
            }
        };
        w.translation.vector.z - ext
    }
}

/// A collision shape placed in its link's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Collision {
    pub origin: Isometry3<f64>,
    pub shape: Shape,
}

/// A rigid link of the tree. `links[0]` is the floating base; parents always precede children.
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    pub name: String,
    /// Index into [`RobotModel::joints`] of the joint whose child this link is (`None` for the base).
    pub parent_joint: Option<usize>,
    /// Index into [`RobotModel::links`] of the parent link (`None` for the base).
    pub parent_link: Option<usize>,
    pub inertial: Inertial,
    pub collisions: Vec<Collision>,
}

/// An actuated revolute joint. `joints` is sorted by motor slot.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    pub name: String,
    /// Motor name in the slot map (e.g. `left_knee`).
    pub motor_name: String,
    /// Index in the robot's LowCmd/LowState motor array.
    pub slot: usize,
    pub parent_link: usize,
    pub child_link: usize,
    /// Child joint frame in the parent link frame at zero angle.
    pub origin: Isometry3<f64>,
    /// Rotation axis in the joint (= child link) frame, unit length.
    pub axis: Unit<Vector3<f64>>,
    pub lower: f64,
    pub upper: f64,
    pub torque_limit: f64,
    pub speed_limit: f64,
    pub armature: f64,
    pub damping: f64,
    pub frictionloss: f64,
    pub kp: f64,
    pub kd: f64,
    pub default_q: f64,
}

/// Standing pose: base pose in the world and joint angles (slot order).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StandingPose {
    pub base_pos: [f64; 3],
    /// `[w, x, y, z]`, base-to-world.
    pub base_quat: [f64; 4],
    pub q: Vec<f64>,
}

/// Robot-ground contact parameters.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContactParams {
    pub friction: f64,
    pub torsional_friction: f64,
    pub rolling_friction: f64,
    pub restitution: f64,
    pub self_collision: bool,
}

/// The IMU site (LowState IMU) in a link frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImuSite {
    pub link: usize,
    pub link_name: String,
    pub pos: [f64; 3],
    pub quat: [f64; 4],
}

/// A validated robot model.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotModel {
    pub name: String,
    pub links: Vec<Link>,
    pub joints: Vec<Joint>,
    pub slot_count: usize,
    pub standing: StandingPose,
    pub contact: ContactParams,
    pub imu: ImuSite,
}

impl RobotModel {
    /// Number of actuated joints.
    pub fn nj(&self) -> usize {
        self.joints.len()
    }
    /// Generalized position size: 7 + nj.
    pub fn nq(&self) -> usize {
        7 + self.nj()
    }
    /// Generalized velocity size: 6 + nj.
    pub fn nv(&self) -> usize {
        6 + self.nj()
    }
    pub fn total_mass(&self) -> f64 {
        self.links.iter().map(|l| l.inertial.mass).sum()
    }
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.links.iter().position(|l| l.name == name)
    }
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }
    /// Joint angles of the standing pose (slot order).
    pub fn default_q(&self) -> Vec<f64> {
        self.joints.iter().map(|j| j.default_q).collect()
    }
    /// Children joints of a link, in slot order.
    pub fn child_joints(&self, link: usize) -> Vec<usize> {
        (0..self.joints.len()).filter(|&j| self.joints[j].parent_link == link).collect()
    }
}
