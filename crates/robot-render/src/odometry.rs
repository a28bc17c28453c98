//! A base pose for a robot log that records none (LowState has joint angles and the IMU, not where the robot
//! is): orientation from the IMU, height from the ground contact, horizontal position by kinematic leg odometry.
//!
//! * Orientation: the IMU frame's orientation (LowState's quaternion) times the inverse of the IMU's orientation
//!   in the pelvis frame at the measured joint angles (on the H1-2 the IMU is on the torso, behind the waist joint).
//! * Height: the lowest point of the collision shapes touches the ground (z = 0).
//! * Horizontal position: the foot whose sole is lowest is the stance foot and does not slide; the pelvis moves so
//!   that the stance foot stays where it was put down. The stance passes to the other foot when that foot's sole is
//!   lower by more than [`LegOdometry::SWITCH_M`]. Yaw drift of the IMU and foot slip go straight into the estimate.
use nalgebra::{Isometry3, Quaternion, UnitQuaternion, Vector3};
use robot_model::{GenCoords, ModelError, RobotModel};

/// Pelvis orientation `[w, x, y, z]` (pelvis-to-world) from the IMU orientation `imu_quat` (IMU-to-world) and the
/// joint angles `q` (slot order).
pub fn pelvis_quat_from_imu(model: &RobotModel, imu_quat: [f64; 4], q: &[f64]) -> Result<[f64; 4], ModelError> {
    let fk = model.fk(&GenCoords { base_pos: [0.0; 3], base_quat: [1.0, 0.0, 0.0, 0.0], q: q.to_vec() })?;
    let site = quat(model.imu.quat)?;
    let imu_in_pelvis = fk
        .link_poses
        .get(model.imu.link)
        .map(|p| p.rotation * site)
        .ok_or_else(|| ModelError::Invalid(format!("IMU link index {} out of range", model.imu.link)))?;
    let r = quat(imu_quat)? * imu_in_pelvis.inverse();
    Ok([r.w, r.i, r.j, r.k])
}

fn quat([w, x, y, z]: [f64; 4]) -> Result<UnitQuaternion<f64>, ModelError> {
    let q = Quaternion::new(w, x, y, z);
    let n = q.norm();
    if !(n.is_finite() && n > 1e-9) {
        return Err(ModelError::Invalid(format!("invalid quaternion {:?}", [w, x, y, z])));
    }
    Ok(UnitQuaternion::from_quaternion(q))
}

fn link_lowest(model: &RobotModel, link: usize, pose: &Isometry3<f64>) -> f64 {
    model.links[link].collisions.iter().map(|c| c.shape.lowest_z(&(pose * c.origin))).fold(f64::INFINITY, f64::min)
}

/// Kinematic leg odometry over a sequence of samples (see the module docs).
#[derive(Debug, Clone)]
pub struct LegOdometry {
    feet: Vec<usize>,
    /// The stance foot and where it stands (world x, y of its link origin).
    stance: Option<(usize, [f64; 2])>,
}

impl LegOdometry {
    /// How much lower (m) the other foot's sole must be to take over the stance.
    pub const SWITCH_M: f64 = 0.005;

    /// The feet are the links whose soles touch the ground in the model's standing pose (within 1 cm).
    pub fn new(model: &RobotModel) -> Result<Self, ModelError> {
        let fk = model.fk(&GenCoords::standing(model))?;
        let lows: Vec<f64> = (0..model.links.len()).map(|l| link_lowest(model, l, &fk.link_poses[l])).collect();
        let ground = lows.iter().copied().fold(f64::INFINITY, f64::min);
        let feet: Vec<usize> = (0..lows.len()).filter(|&l| lows[l] < ground + 0.01).collect();
        if !ground.is_finite() || feet.is_empty() {
            return Err(ModelError::Invalid("the model has no collision shapes to stand on".into()));
        }
        Ok(LegOdometry { feet, stance: None })
    }

    /// The links taken as feet.
    pub fn feet(&self) -> &[usize] {
        &self.feet
    }

    /// The base pose of the next sample: pelvis orientation (`[w, x, y, z]`, e.g. [`pelvis_quat_from_imu`]) and
    /// joint angles. The first sample puts the pelvis above the origin.
    pub fn update(&mut self, model: &RobotModel, pelvis_quat: [f64; 4], q: &[f64]) -> Result<GenCoords, ModelError> {
        let mut c = GenCoords { base_pos: [0.0; 3], base_quat: pelvis_quat, q: q.to_vec() };
        let fk = model.fk(&c)?;
        let low =
            (0..model.links.len()).map(|l| link_lowest(model, l, &fk.link_poses[l])).fold(f64::INFINITY, f64::min);
        let foot = |f: usize| {
            let p: Vector3<f64> = fk.link_poses[f].translation.vector;
            ([p.x, p.y], link_lowest(model, f, &fk.link_poses[f]))
        };
        let lowest_foot = self
            .feet
            .iter()
            .map(|&f| (f, foot(f)))
            .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
            .map(|(f, _)| f)
            .unwrap_or(self.feet[0]);
        let base_xy = match self.stance {
            None => {
                let (rel, _) = foot(lowest_foot);
                self.stance = Some((lowest_foot, rel));
                [0.0, 0.0]
            }
            Some((s, world)) => {
                let (rel, s_low) = foot(s);
                let base = [world[0] - rel[0], world[1] - rel[1]];
                let (new_rel, new_low) = foot(lowest_foot);
                if lowest_foot != s && new_low < s_low - Self::SWITCH_M {
                    self.stance = Some((lowest_foot, [base[0] + new_rel[0], base[1] + new_rel[1]]));
                }
                base
            }
        };
        c.base_pos = [base_xy[0], base_xy[1], -low];
        Ok(c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn standing_still_stays_put_on_the_ground() {
        let model = robot_model::builtin("h1_2").expect("model");
        let mut odo = LegOdometry::new(&model).expect("feet");
        assert_eq!(odo.feet().len(), 2, "two feet: {:?}", odo.feet());
        let q = model.default_q();
        for _ in 0..3 {
            let c = odo.update(&model, [1.0, 0.0, 0.0, 0.0], &q).expect("pose");
            assert!(c.base_pos[0].abs() < 1e-12 && c.base_pos[1].abs() < 1e-12);
            // The sidecar's standing height (independent: checked against the model by robot-model's tests).
            assert!((c.base_pos[2] - model.standing.base_pos[2]).abs() < 2e-3, "{:?}", c.base_pos);
        }
    }

    #[test]
    fn the_torso_imu_gives_the_pelvis_orientation_through_the_waist() {
        let model = robot_model::builtin("h1_2").expect("model");
        let mut q = model.default_q();
        let waist = model.joints.iter().position(|j| j.motor_name.contains("waist") || j.name.contains("torso"));
        let waist = waist.expect("a waist joint");
        q[waist] = 0.5;
        // Pelvis yawed by 0.3 rad: the torso IMU reads 0.8 rad of yaw; the pelvis must come back as 0.3.
        let pelvis = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3);
        let c = GenCoords { base_pos: [0.0; 3], base_quat: [pelvis.w, pelvis.i, pelvis.j, pelvis.k], q: q.clone() };
        let imu = model.fk(&c).expect("fk").link_poses[model.imu.link].rotation;
        let got = pelvis_quat_from_imu(&model, [imu.w, imu.i, imu.j, imu.k], &q).expect("pelvis");
        let got = UnitQuaternion::from_quaternion(Quaternion::new(got[0], got[1], got[2], got[3]));
        assert!((got.euler_angles().2 - 0.3).abs() < 1e-9, "{:?}", got.euler_angles());
        assert!(pelvis_quat_from_imu(&model, [0.0; 4], &q).is_err());
    }
}
