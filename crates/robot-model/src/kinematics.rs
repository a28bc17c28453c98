//! Forward kinematics and centre of mass.
use crate::error::ModelError;
use crate::model::RobotModel;
use nalgebra::{Isometry3, Quaternion, Translation3, Unit, UnitQuaternion, Vector3};

/// Generalized position of a floating-base robot.
#[derive(Debug, Clone, PartialEq)]
pub struct GenCoords {
    /// Base-link origin in the world frame.
    pub base_pos: [f64; 3],
    /// Base orientation `[w, x, y, z]`, base-to-world (need not be normalised; it is normalised on use).
    pub base_quat: [f64; 4],
    /// Joint angles in slot order (`model.joints` order).
    pub q: Vec<f64>,
}

impl GenCoords {
    /// All joints at zero, base at the origin with identity orientation.
    pub fn zero(model: &RobotModel) -> Self {
        GenCoords { base_pos: [0.0; 3], base_quat: [1.0, 0.0, 0.0, 0.0], q: vec![0.0; model.nj()] }
    }
    /// The sidecar's standing pose.
    pub fn standing(model: &RobotModel) -> Self {
        GenCoords {
            base_pos: model.standing.base_pos,
            base_quat: model.standing.base_quat,
            q: model.standing.q.clone(),
        }
    }
    /// Base pose as an isometry. Errors on a zero or non-finite quaternion.
    pub fn base_iso(&self) -> Result<Isometry3<f64>, ModelError> {
        let [w, x, y, z] = self.base_quat;
        let q = Quaternion::new(w, x, y, z);
        let n = q.norm();
        if !(n.is_finite() && n > 1e-9) || self.base_pos.iter().any(|v| !v.is_finite()) {
            return Err(ModelError::Invalid(format!("invalid base pose {:?} {:?}", self.base_pos, self.base_quat)));
        }
        let [px, py, pz] = self.base_pos;
        Ok(Isometry3::from_parts(Translation3::new(px, py, pz), UnitQuaternion::from_quaternion(q)))
    }
}

/// Result of forward kinematics.
#[derive(Debug, Clone)]
pub struct FkResult {
    /// World pose of every link frame (`model.links` order).
    pub link_poses: Vec<Isometry3<f64>>,
    /// World-frame unit axis of every joint (slot order).
    pub joint_axes: Vec<Unit<Vector3<f64>>>,
    /// World position of every joint (a point on its axis = child link origin).
    pub joint_points: Vec<Vector3<f64>>,
}

/// Angle (rad) between the world vertical and the z axis of a frame whose orientation is the unit quaternion
/// `q = [w, x, y, z]` (body-to-world): how far a pelvis is tilted from upright.
pub fn tilt_from_vertical(q: [f64; 4]) -> f64 {
    let [_, x, y, _] = q;
    (1.0 - 2.0 * (x * x + y * y)).clamp(-1.0, 1.0).acos()
}

/// `[w, x, y, z]` of a unit quaternion.
pub fn quat_wxyz(q: &UnitQuaternion<f64>) -> [f64; 4] {
    [q.w, q.i, q.j, q.k]
}

impl RobotModel {
    /// Forward kinematics at `c`.
    pub fn fk(&self, c: &GenCoords) -> Result<FkResult, ModelError> {
        if c.q.len() != self.nj() {
            return Err(ModelError::Invalid(format!("expected {} joint angles, got {}", self.nj(), c.q.len())));
        }
        if c.q.iter().any(|v| !v.is_finite()) {
            return Err(ModelError::Invalid("non-finite joint angle".into()));
        }
        let mut poses = vec![Isometry3::identity(); self.links.len()];
        poses[0] = c.base_iso()?;
        let mut axes = vec![Vector3::z_axis(); self.nj()];
        let mut points = vec![Vector3::zeros(); self.nj()];
        for (li, link) in self.links.iter().enumerate().skip(1) {
            let Some(ji) = link.parent_joint else {
                return Err(ModelError::Invalid(format!("link {:?} has no parent joint", link.name)));
            };
            let j = &self.joints[ji];
            let frame = poses[j.parent_link] * j.origin;
            let rot = UnitQuaternion::from_axis_angle(&j.axis, c.q[ji]);
            poses[li] = frame * rot;
            axes[ji] = Unit::new_normalize(frame.rotation * j.axis.into_inner());
            points[ji] = frame.translation.vector;
        }
        Ok(FkResult { link_poses: poses, joint_axes: axes, joint_points: points })
    }

    /// World centre of mass of every link at `c`.
    pub fn link_coms(&self, c: &GenCoords) -> Result<Vec<Vector3<f64>>, ModelError> {
        let fk = self.fk(c)?;
        Ok(self
            .links
            .iter()
            .zip(&fk.link_poses)
            .map(|(l, p)| p * nalgebra::Point3::from(l.inertial.com))
            .map(|p| p.coords)
            .collect())
    }

    /// Whole-body centre of mass in the world frame at `c`.
    pub fn com(&self, c: &GenCoords) -> Result<Vector3<f64>, ModelError> {
        let coms = self.link_coms(c)?;
        let m = self.total_mass();
        Ok(self.links.iter().zip(coms).map(|(l, p)| p * l.inertial.mass).sum::<Vector3<f64>>() / m)
    }

    /// Lowest world z over all collision shapes at `c` (exact for boxes, spheres, capsules and cylinders).
    pub fn lowest_point_z(&self, c: &GenCoords) -> Result<f64, ModelError> {
        let fk = self.fk(c)?;
        let mut low = f64::INFINITY;
        for (l, pose) in self.links.iter().zip(&fk.link_poses) {
            for col in &l.collisions {
                low = low.min(col.shape.lowest_z(&(pose * col.origin)));
            }
        }
        Ok(low)
    }
}
