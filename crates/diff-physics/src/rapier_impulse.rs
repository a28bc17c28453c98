//! Rapier, maximal-coordinate formulation: one free rigid body per link, held together by impulse joints
//! (`ImpulseJointSet`, revolute `GenericJoint`s solved iteratively with the contacts), in `rapier3d-f64`.
//!
//! Conversions (see [`crate::engine`] for the interface conventions):
//! - Every Rapier body frame is its link frame. Rapier body velocities are COM velocities (world) and world
//!   angular velocities; `reset` propagates the generalized velocity down the tree to set them, `state` reads
//!   the pelvis body back (`v_o = v_com − ω × (R c)`, `ω_b = Rᵀ ω`).
//! - Joint angles are read back from relative rotations: `R_rel = (R_parent R_origin)⁻¹ R_child`,
//!   `q = 2 atan2(vec(R_rel)·a, w(R_rel))` with `a` the joint axis; `dq = a_w · (ω_child − ω_parent)`.
//!   Joint drift (the constraint error an iterative solver leaves) shows up as off-axis components and is
//!   ignored by this projection.
//! - Joint torques are equal and opposite world torques `±τ a` on child and parent.
//! - Armature cannot be expressed in maximal coordinates. Approximation: `armature · a aᵀ` is added to the
//!   child link's rotational inertia (a rotor spinning with the child about the joint axis). This reproduces
//!   the joint's own diagonal term but also couples the rotor inertia to every ancestor rotation with a
//!   component along `a` (reduced-coordinate armature does not): a known difference.
//! - Viscous joint damping: an explicit torque `−d·dq` (from the state at the start of the step) added to the
//!   joint torque (stable: d·dt/I ≪ 1 for the model's d = 1 N·m·s/rad and armature-inflated inertias).
//! - Dry joint friction (frictionloss): a velocity motor on the joint with target 0, very high damping and its
//!   force capped at frictionloss (a bounded velocity constraint, like MuJoCo's).
//! - A reset rebuilds the whole Rapier world, so no joint or contact warm start survives it.
use crate::engine::{CommonSettings, Contact, Energy, Engine, EngineError, LinkPose, State};
use crate::rapier_common::{
    add_joint_torque, add_robot, armature_inertia, arr, bodies_com, bodies_energy, check_tau, clear_user_forces,
    iso_from_pose, link_masses, link_poses, link_velocities, new_world, read_contacts, revolute_joint, v_from_r,
    v_to_r, BuiltRobot, RapierSolverSettings, RAPIER_VERSION,
};
use nalgebra::{Isometry3, Point3, Vector3};
use rapier3d_f64::prelude::{ImpulseJointHandle, JointAxis, MotorModel, PhysicsWorld};
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};

/// Every setting of the Rapier impulse-joint engine beyond [`CommonSettings`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RapierImpulseSettings {
    #[serde(flatten)]
    pub solver: RapierSolverSettings,
    /// Warm-start joint impulses from the previous step (`IntegrationParameters::warmstart_joints`).
    pub warmstart_joints: bool,
    /// Joint constraint softness: natural frequency (Hz) and damping ratio of the joint-error correction.
    pub joint_natural_frequency_hz: f64,
    pub joint_damping_ratio: f64,
    /// Damping of the velocity motor that implements dry joint friction (N·m·s/rad; force-based motor).
    pub friction_motor_damping: f64,
    /// Timestep of the contact-free probe step used by [`Engine::generalized_acceleration`] (s).
    pub acceleration_probe_dt: f64,
    /// Number of warm-started probe steps (the joint impulses of a 28-body chain need many Gauss-Seidel sweeps;
    /// each probe step continues from the previous one's impulses). User forces persist across them.
    pub acceleration_probe_steps: usize,
    /// Substeps and PGS sweeps per substep of the probe world (the probe measures the formulation's converged
    /// contact-free dynamics; the per-step solver error of normal stepping is covered by the stepping checks).
    pub acceleration_probe_substeps: usize,
    pub acceleration_probe_pgs_iterations: usize,
    /// Gyroscopic torques `−ω × Iω`. With armature off they are Rapier's own (`RigidBody::gyroscopic_forces`).
    /// With armature on, the rotor-inertia approximation makes light links' inertia up to ~1000:1 anisotropic
    /// and Rapier's gyroscopic term then diverges on impacts (measured: a fall ends at 1e19 m); Rapier's term is
    /// switched off and the gyroscopic torque of the links' own inertia (without the rotor part, which MuJoCo's
    /// armature has no gyroscopic effect for either) is applied explicitly from the state at the step start.
    pub gyroscopic_forces: bool,
}

impl Default for RapierImpulseSettings {
    fn default() -> Self {
        RapierImpulseSettings {
            // A 28-body chain solved by Gauss-Seidel needs more sweeps than contacts alone: 8 substeps x 2
            // PGS sweeps (vs 4 x 1 for the multibody, whose joints are exact).
            solver: RapierSolverSettings {
                substeps: 8,
                pgs_iterations_per_substep: 2,
                ..RapierSolverSettings::default()
            },
            warmstart_joints: true,
            // Rapier's joint defaults (1 MHz, critically damped): rigid joints.
            joint_natural_frequency_hz: 1.0e6,
            joint_damping_ratio: 1.0,
            friction_motor_damping: 1.0e6,
            acceleration_probe_dt: 1e-6,
            acceleration_probe_steps: 50,
            acceleration_probe_substeps: 8,
            acceleration_probe_pgs_iterations: 2,
            gyroscopic_forces: true,
        }
    }
}

/// The Rapier impulse-joint engine.
pub struct RapierImpulseEngine {
    model: RobotModel,
    common: CommonSettings,
    settings: RapierImpulseSettings,
    world: PhysicsWorld,
    robot: BuiltRobot,
    joints: Vec<ImpulseJointHandle>,
    /// Last joint angles read back (slot order): branch reference for unwrapping relative-rotation angles
    /// (joint ranges of the H1-2 exceed ±π, e.g. the elbow's [-3.4, 0.38]).
    q_ref: Vec<f64>,
    time: f64,
    probe: Option<Box<RapierImpulseEngine>>,
}

impl std::fmt::Debug for RapierImpulseEngine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RapierImpulseEngine")
            .field("settings", &self.settings)
            .field("common", &self.common)
            .field("time", &self.time)
            .finish_non_exhaustive()
    }
}

impl RapierImpulseEngine {
    /// Builds the engine at the model's standing pose, at rest.
    pub fn new(
        model: &RobotModel,
        common: &CommonSettings,
        settings: &RapierImpulseSettings,
    ) -> Result<Self, EngineError> {
        Self::build(model, common, settings, &State::standing(model))
    }

    fn build(
        model: &RobotModel,
        common: &CommonSettings,
        settings: &RapierImpulseSettings,
        state: &State,
    ) -> Result<Self, EngineError> {
        if !(common.timestep.is_finite() && common.timestep > 0.0) {
            return Err(EngineError::Input(format!("timestep {} must be positive", common.timestep)));
        }
        state.validate(model)?;
        let fk = model.fk(&state.coords())?;
        let mut world = new_world(common, &settings.solver);
        world.integration_parameters.warmstart_joints = settings.warmstart_joints;
        let offsets = vec![Vector3::zeros(); model.links.len()];
        let extra = armature_inertia(model, common.armature);
        let robot = add_robot(
            &mut world,
            model,
            common,
            &fk.link_poses,
            offsets,
            &extra,
            settings.gyroscopic_forces && !common.armature,
        )?;
        let mut joints = Vec::with_capacity(model.nj());
        for (ji, j) in model.joints.iter().enumerate() {
            let mut data = revolute_joint(
                model,
                ji,
                &robot.frame_offsets,
                common.joint_limits,
                settings.solver.parent_child_contacts,
            );
            let _ = data.set_softness(rapier3d_f64::prelude::SpringCoefficients::new(
                settings.joint_natural_frequency_hz,
                settings.joint_damping_ratio,
            ));
            if common.joint_friction && j.frictionloss > 0.0 {
                let _ = data.set_motor_model(JointAxis::AngX, MotorModel::ForceBased);
                let _ = data.set_motor_velocity(JointAxis::AngX, 0.0, settings.friction_motor_damping);
                let _ = data.set_motor_max_force(JointAxis::AngX, j.frictionloss);
            }
            joints.push(world.impulse_joints.insert(
                robot.bodies[j.parent_link],
                robot.bodies[j.child_link],
                data,
                true,
            ));
        }
        // Body velocities from the generalized velocity.
        let vels = link_velocities(
            model,
            &fk.link_poses,
            Vector3::from(state.base_lin_vel),
            Vector3::from(state.base_ang_vel),
            &state.dq,
        );
        for (li, &h) in robot.bodies.iter().enumerate() {
            let (w, v_o) = vels[li];
            let c = fk.link_poses[li] * Point3::from(model.links[li].inertial.com);
            let v_c = v_o + w.cross(&(c.coords - fk.link_poses[li].translation.vector));
            if let Some(rb) = world.bodies.get_mut(h) {
                rb.set_linvel(v_to_r(&v_c), true);
                rb.set_angvel(v_to_r(&w), true);
            }
        }
        Ok(RapierImpulseEngine {
            model: model.clone(),
            common: common.clone(),
            settings: settings.clone(),
            world,
            robot,
            joints,
            q_ref: state.q.clone(),
            time: 0.0,
            probe: None,
        })
    }

    /// One bare `PhysicsWorld::step` (no state conversion, no torque update: the body torques of the previous
    /// [`Engine::step`] persist). For measuring the overhead of the `Engine` layer only.
    pub fn step_raw(&mut self) {
        self.world.step();
        self.time += self.common.timestep;
    }

    fn body_pose(&self, li: usize) -> Isometry3<f64> {
        match self.world.bodies.get(self.robot.bodies[li]) {
            Some(rb) => iso_from_pose(rb.position()),
            None => Isometry3::identity(),
        }
    }

    fn body_angvel(&self, li: usize) -> Vector3<f64> {
        self.world.bodies.get(self.robot.bodies[li]).map(|rb| v_from_r(rb.angvel())).unwrap_or_else(Vector3::zeros)
    }

    /// Applies `tau` (+ explicit viscous damping) as equal and opposite body torques; clears other user forces.
    fn apply_joint_torques(&mut self, tau: &[f64], dq: &[f64]) {
        clear_user_forces(&mut self.world, &self.robot);
        if self.settings.gyroscopic_forces && self.common.armature {
            for (li, link) in self.model.links.iter().enumerate() {
                let pose = self.body_pose(li);
                let w = self.body_angvel(li);
                let r = pose.rotation.to_rotation_matrix().into_inner();
                let i_w = r * link.inertial.inertia * r.transpose();
                let gyro = -w.cross(&(i_w * w));
                if let Some(rb) = self.world.bodies.get_mut(self.robot.bodies[li]) {
                    rb.add_torque(v_to_r(&gyro), true);
                }
            }
        }
        for (ji, j) in self.model.joints.iter().enumerate() {
            let mut t = tau[ji];
            if self.common.joint_damping {
                t -= j.damping * dq.get(ji).copied().unwrap_or(0.0);
            }
            add_joint_torque(&mut self.world, &self.robot, j, t);
        }
    }
}

impl Engine for RapierImpulseEngine {
    fn name(&self) -> &'static str {
        "rapier_impulse"
    }
    fn version(&self) -> String {
        format!("{RAPIER_VERSION}, impulse joints (maximal coordinates)")
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::json!({
            "common": self.common,
            "specific": self.settings,
            "precision": "f64 (rapier3d-f64)",
            "formulation": "maximal coordinates: free rigid bodies + revolute impulse joints",
            "joint_torques": "equal and opposite body torques on child/parent",
            "armature": "approximated: armature * a a^T added to the child link inertia",
            "gyroscopic": if self.settings.gyroscopic_forces && self.common.armature { "explicit -w x (I_link w), link inertia only (Rapier's term off: unstable with the anisotropic rotor inertia)" } else if self.settings.gyroscopic_forces { "Rapier's own" } else { "off" },
            "joint_damping": "explicit torque -d*dq from the state at the start of the step",
            "joint_friction": "velocity motor (target 0, force-based, damping friction_motor_damping) capped at frictionloss",
            "contact_torsional_rolling_friction": "not supported by Rapier (ignored)",
            "energy": "kinetic energy of the simulated bodies (including the armature approximation)",
            "mass_matrix_method": "none (not exposed in maximal coordinates)",
            "acceleration_method": "finite difference of the last of acceleration_probe_steps warm-started contact-free probe steps (no ground, collisions or limits) of acceleration_probe_dt",
            "integration_parameters": format!("{:?}", self.world.integration_parameters),
        })
    }
    fn common(&self) -> &CommonSettings {
        &self.common
    }

    fn reset(&mut self, state: &State) -> Result<(), EngineError> {
        let probe = self.probe.take();
        *self = Self::build(&self.model, &self.common, &self.settings, state)?;
        self.probe = probe;
        Ok(())
    }

    fn step(&mut self, tau: &[f64]) -> Result<(), EngineError> {
        check_tau(&self.model, tau)?;
        let dq = if self.common.joint_damping { self.state().dq } else { Vec::new() };
        self.apply_joint_torques(tau, &dq);
        self.world.step();
        self.time += self.common.timestep;
        self.q_ref = self.state().q;
        for &h in &self.robot.bodies {
            if let Some(rb) = self.world.bodies.get(h) {
                if !(rb.linvel().is_finite() && rb.angvel().is_finite() && rb.translation().is_finite()) {
                    return Err(EngineError::Diverged(format!("non-finite body state at t = {}", self.time)));
                }
            }
        }
        Ok(())
    }

    fn state(&self) -> State {
        let nj = self.model.nj();
        let pelvis = self.body_pose(0);
        let mut st = State {
            base_pos: arr(&pelvis.translation.vector),
            base_quat: [pelvis.rotation.w, pelvis.rotation.i, pelvis.rotation.j, pelvis.rotation.k],
            q: vec![0.0; nj],
            base_lin_vel: [0.0; 3],
            base_ang_vel: [0.0; 3],
            dq: vec![0.0; nj],
        };
        if let Some(rb) = self.world.bodies.get(self.robot.bodies[0]) {
            let w = v_from_r(rb.angvel());
            let v_c = v_from_r(rb.linvel());
            let rc = pelvis.rotation * self.model.links[0].inertial.com;
            st.base_lin_vel = arr(&(v_c - w.cross(&rc)));
            st.base_ang_vel = arr(&(pelvis.rotation.inverse() * w));
        }
        for (ji, j) in self.model.joints.iter().enumerate() {
            let parent = self.body_pose(j.parent_link);
            let child = self.body_pose(j.child_link);
            let frame = parent * j.origin;
            let rel = frame.rotation.inverse() * child.rotation;
            let a = j.axis.into_inner();
            let v = Vector3::new(rel.i, rel.j, rel.k);
            let raw = 2.0 * v.dot(&a).atan2(rel.w);
            // Unwrap to the branch nearest the previous reading (a joint moves far less than π per step).
            let two_pi = 2.0 * std::f64::consts::PI;
            let r = self.q_ref.get(ji).copied().unwrap_or(0.0);
            st.q[ji] = raw + two_pi * ((r - raw) / two_pi).round();
            let a_w = child.rotation * a;
            st.dq[ji] = a_w.dot(&(self.body_angvel(j.child_link) - self.body_angvel(j.parent_link)));
        }
        st
    }

    fn time(&self) -> f64 {
        self.time
    }

    fn contacts(&self) -> Vec<Contact> {
        read_contacts(&self.model, &self.world, self.common.timestep)
    }

    fn energy(&mut self) -> Energy {
        let (kinetic, potential) = bodies_energy(&self.world, &self.robot.bodies, self.common.gravity);
        Energy { kinetic, potential }
    }

    fn link_masses(&self) -> Vec<f64> {
        link_masses(&self.world, &self.robot)
    }

    fn link_poses(&mut self) -> Vec<LinkPose> {
        link_poses(&self.world, &self.robot)
    }

    fn com(&mut self) -> [f64; 3] {
        bodies_com(&self.world, &self.robot.bodies)
    }

    fn joint_axes(&mut self) -> Vec<[f64; 3]> {
        self.model.joints.iter().map(|j| arr(&(self.body_pose(j.child_link).rotation * j.axis.into_inner()))).collect()
    }

    fn joint_limits(&self) -> Vec<(f64, f64)> {
        self.joints
            .iter()
            .map(|&h| {
                self.world
                    .impulse_joints
                    .get(h)
                    .and_then(|j| j.data.limits(JointAxis::AngX).map(|l| (l.min, l.max)))
                    .unwrap_or((f64::NEG_INFINITY, f64::INFINITY))
            })
            .collect()
    }

    fn generalized_acceleration(&mut self, f: &[f64]) -> Result<Vec<f64>, EngineError> {
        let nv = self.model.nv();
        if f.len() != nv || f.iter().any(|x| !x.is_finite()) {
            return Err(EngineError::Input(format!("expected {nv} finite generalized forces")));
        }
        let state = self.state();
        if self.probe.is_none() {
            let common = CommonSettings {
                timestep: self.settings.acceleration_probe_dt,
                ground: false,
                collisions: false,
                joint_limits: false,
                ..self.common.clone()
            };
            let mut settings = self.settings.clone();
            settings.solver.substeps = self.settings.acceleration_probe_substeps;
            settings.solver.pgs_iterations_per_substep = self.settings.acceleration_probe_pgs_iterations;
            self.probe = Some(Box::new(Self::build(&self.model, &common, &settings, &state)?));
        }
        let probe = self.probe.as_mut().ok_or_else(|| EngineError::Build("probe missing".into()))?;
        probe.reset(&state)?;
        probe.apply_joint_torques(&f[6..], &state.dq);
        let pelvis = probe.body_pose(0);
        let force = Vector3::new(f[0], f[1], f[2]);
        let moment_w = pelvis.rotation * Vector3::new(f[3], f[4], f[5]);
        let origin_minus_com = -(pelvis.rotation * probe.model.links[0].inertial.com);
        if let Some(rb) = probe.world.bodies.get_mut(probe.robot.bodies[0]) {
            rb.add_force(v_to_r(&force), true);
            rb.add_torque(v_to_r(&(moment_w + origin_minus_com.cross(&force))), true);
        }
        // Warm-started probe: repeat the tiny step with the same forces so that the joint impulses converge
        // (each step starts from the previous one's impulses); the last step's velocity change is reported.
        let mut before = state.v();
        let steps = self.settings.acceleration_probe_steps.max(1);
        for k in 0..steps {
            if k > 0 {
                before = probe.state().v();
            }
            probe.world.step();
        }
        let after = probe.state();
        let dt = probe.common.timestep;
        Ok(before.iter().zip(after.v()).map(|(a, b)| (b - a) / dt).collect())
    }
}

/// Checks of [`crate::oracle`] this engine cannot meet for reasons inside the formulation, with the reason and
/// the figure `ulab model check --robot h1_2` measures (seed 1, 5 samples).
pub fn known_difference(check: &str) -> Option<&'static str> {
    match check {
        "accelerations under random (q,v,tau)" | "mass matrix from accelerations" => Some(
            "maximal coordinates: joints are velocity-level constraints without the J̇·v (centripetal) term, \
             whose drift is removed by position stabilisation, solved by a finite number of Gauss-Seidel sweeps; \
             the error grows with joint speed (measured 1.4e-2 accelerations, 6.1e-2 M from accelerations, at \
             |dq| <= 2 rad/s; 1e-3 at |dq| <= 1 rad/s)",
        ),
        "accelerations under random (q,v,tau) (with armature)" | "mass matrix from accelerations (with armature)" => Some(
            "armature cannot be expressed in maximal coordinates: approximated by armature·a·aᵀ rotor inertia on the \
             child link, which also couples to every ancestor rotation (measured 1.9 rel. accelerations, 0.19 M)",
        ),
        "kinetic energy at reset" => Some(
            "the armature approximation's rotor inertia spins with the child link's absolute angular velocity, not \
             the joint's relative one, so ½vᵀMv differs (measured 8.4e-2 rel.)",
        ),
        _ => None,
    }
}
