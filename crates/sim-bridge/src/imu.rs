//! The LowState IMU, synthesised from the physics state like a strapdown IMU would measure it.
//!
//! Velocities of the IMU frame come from forward kinematics differentiated along the
//! generalized velocity (exact to O(ε)); the linear acceleration of the IMU point is the
//! difference of that velocity across one physics step, so the accelerometer reads the
//! specific force `R^T (a - g)` including centripetal and contact effects.

use diff_physics::State;
use nalgebra::{Isometry3, Quaternion, UnitQuaternion, Vector3};
use robot_model::{GenCoords, ModelError, RobotModel};

/// One IMU sample in the IMU frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuReading {
    /// Orientation `[w, x, y, z]`, IMU-to-world.
    pub quaternion: [f64; 4],
    /// Angular velocity, IMU frame (rad/s).
    pub gyroscope: [f64; 3],
    /// Specific force, IMU frame (m/s²): +g upwards at rest.
    pub accelerometer: [f64; 3],
    /// Roll, pitch, yaw (rad), Z-Y-X convention.
    pub rpy: [f64; 3],
}

#[derive(Debug)]
pub(crate) struct ImuTracker {
    link: usize,
    site: Isometry3<f64>,
    gravity: Vector3<f64>,
    /// World velocity of the IMU point at the last update.
    velocity: Vector3<f64>,
    reading: ImuReading,
}

/// World pose of the IMU frame, its world linear velocity and world angular velocity.
type ImuKinematics = (Isometry3<f64>, Vector3<f64>, Vector3<f64>);

/// Step along the velocity used to differentiate forward kinematics (s).
const EPS: f64 = 1e-7;

impl ImuTracker {
    /// The robot's IMU (the model's IMU site: the H1-2's is on the torso).
    pub(crate) fn new(model: &RobotModel) -> Result<Self, ModelError> {
        let imu = &model.imu;
        Self::at(model, imu.link, imu.pos, imu.quat)
    }

    /// An IMU at the origin of the base link (the pelvis), axes along the pelvis's: what reports the pelvis pose.
    pub(crate) fn on_base(model: &RobotModel) -> Result<Self, ModelError> {
        let base = model
            .links
            .iter()
            .position(|l| l.parent_link.is_none())
            .ok_or_else(|| ModelError::Invalid("the model has no base link".into()))?;
        Self::at(model, base, [0.0; 3], [1.0, 0.0, 0.0, 0.0])
    }

    fn at(model: &RobotModel, link: usize, pos: [f64; 3], q: [f64; 4]) -> Result<Self, ModelError> {
        if link >= model.links.len() {
            return Err(ModelError::Invalid(format!("IMU link index {link} out of range")));
        }
        let site = Isometry3::from_parts(
            Vector3::from(pos).into(),
            UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3])),
        );
        Ok(ImuTracker {
            link,
            site,
            gravity: Vector3::zeros(),
            velocity: Vector3::zeros(),
            reading: ImuReading {
                quaternion: [1.0, 0.0, 0.0, 0.0],
                gyroscope: [0.0; 3],
                accelerometer: [0.0; 3],
                rpy: [0.0; 3],
            },
        })
    }

    /// World pose of the IMU frame, and its world linear and angular velocity.
    fn kinematics(&self, model: &RobotModel, state: &State) -> Result<ImuKinematics, ModelError> {
        let pose = |c: &GenCoords| -> Result<Isometry3<f64>, ModelError> {
            Ok(model.fk(c)?.link_poses[self.link] * self.site)
        };
        let c0 = state.coords();
        let p0 = pose(&c0)?;
        // Advance the configuration by EPS along the generalized velocity.
        let base_rot = c0.base_iso()?.rotation;
        let w_body = Vector3::from(state.base_ang_vel);
        let rot1 = base_rot * UnitQuaternion::from_scaled_axis(w_body * EPS);
        let c1 = GenCoords {
            base_pos: [0, 1, 2].map(|i| c0.base_pos[i] + state.base_lin_vel[i] * EPS),
            base_quat: [rot1.w, rot1.i, rot1.j, rot1.k],
            q: c0.q.iter().zip(&state.dq).map(|(q, dq)| q + dq * EPS).collect(),
        };
        let p1 = pose(&c1)?;
        let v = (p1.translation.vector - p0.translation.vector) / EPS;
        let w = (p1.rotation * p0.rotation.inverse()).scaled_axis() / EPS;
        Ok((p0, v, w))
    }

    pub(crate) fn reset(&mut self, model: &RobotModel, state: &State, gravity: [f64; 3]) -> Result<(), ModelError> {
        self.gravity = Vector3::from(gravity);
        let (pose, v, w) = self.kinematics(model, state)?;
        self.velocity = v;
        self.set(&pose, &w, &Vector3::zeros());
        Ok(())
    }

    pub(crate) fn update(&mut self, model: &RobotModel, state: &State, dt: f64) -> Result<(), ModelError> {
        let (pose, v, w) = self.kinematics(model, state)?;
        let a = (v - self.velocity) / dt;
        self.velocity = v;
        self.set(&pose, &w, &a);
        Ok(())
    }

    fn set(&mut self, pose: &Isometry3<f64>, w_world: &Vector3<f64>, a_world: &Vector3<f64>) {
        let r = pose.rotation;
        let gyro = r.inverse() * w_world;
        let specific_force = r.inverse() * (a_world - self.gravity);
        let (roll, pitch, yaw) = r.euler_angles();
        self.reading = ImuReading {
            quaternion: [r.w, r.i, r.j, r.k],
            gyroscope: gyro.into(),
            accelerometer: specific_force.into(),
            rpy: [roll, pitch, yaw],
        };
    }

    pub(crate) fn reading(&self) -> ImuReading {
        self.reading
    }
}
