//! Rapier, reduced-coordinate formulation: the robot is one `Multibody` of a `MultibodyJointSet` (Featherstone-
//! style articulated body with a free root), in `rapier3d-f64` (f64 reals).
//!
//! Conversions (see [`crate::engine`] for the interface conventions):
//! - Rapier's free root integrates its generalized *COM* velocity as if it were the velocity of the body
//!   frame's origin, so a root body whose centre of mass is off its frame origin drifts when it spins. The
//!   pelvis' Rapier body frame is therefore placed at the pelvis centre of mass (same orientation as the pelvis
//!   link frame); every pelvis collider and child joint frame is shifted accordingly. All other links use their
//!   link frames.
//! - Rapier's root generalized velocity is `[COM velocity (world), angular velocity (world)]`; the interface's
//!   is `[pelvis-origin velocity (world), angular velocity (pelvis frame)]`. `state`, `reset` and
//!   `mass_matrix` convert with `v_com = v_o + ω × (R c)`, `ω_w = R ω_b`.
//! - Joint torques are applied as equal and opposite world torques `±τ a` on child and parent bodies. Rapier
//!   maps body wrenches to generalized forces with the body Jacobians (`Jᵀ w`); child and parent angular
//!   Jacobians differ exactly by the joint's own column, so this is the generalized force `τ` on that joint
//!   and nothing else.
//! - Armature, viscous damping and dry friction are native per-DoF multibody properties in Rapier 0.36
//!   (`Multibody::armature_mut`, `damping_mut` (implicit), `frictions_mut` (a bounded velocity constraint,
//!   like MuJoCo's `frictionloss`)). Rapier's default 0.1 angular damping on every DoF (including the free
//!   root) is removed.
//! - A reset rebuilds the whole Rapier world (bodies, colliders, broad/narrow phase, islands, solver caches),
//!   so no warm start or contact history survives it.
use crate::engine::{CommonSettings, Contact, Energy, Engine, EngineError, LinkPose, State};
use crate::rapier_common::{
    add_joint_torque, add_robot, arr, bodies_com, check_tau, clear_user_forces, iso_from_pose, link_masses, link_poses,
    link_poses_from_bodies, new_world, read_contacts, revolute_joint, v_to_r, wxyz_to_quat, BuiltRobot,
    RapierSolverSettings, RAPIER_VERSION,
};
use nalgebra::{DMatrix, Isometry3, Matrix3, Translation3, Vector3};
use rapier3d_f64::na as rna;
use rapier3d_f64::prelude::{JointAxis, Multibody, MultibodyIndex, PhysicsWorld};
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};

/// Every setting of the Rapier multibody engine beyond [`CommonSettings`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RapierMultibodySettings {
    #[serde(flatten)]
    pub solver: RapierSolverSettings,
    /// Contacts between non-adjacent links of the multibody (`Multibody::self_contacts_enabled`); ANDed with
    /// the model's `self_collision` (collision groups).
    pub self_contacts: bool,
    /// Timestep of the contact-free probe step used by [`Engine::generalized_acceleration`] (s).
    pub acceleration_probe_dt: f64,
}

impl Default for RapierMultibodySettings {
    fn default() -> Self {
        RapierMultibodySettings {
            solver: RapierSolverSettings::default(),
            self_contacts: true,
            acceleration_probe_dt: 1e-6,
        }
    }
}

/// The Rapier reduced-coordinate engine.
pub struct RapierMultibodyEngine {
    model: RobotModel,
    common: CommonSettings,
    settings: RapierMultibodySettings,
    world: PhysicsWorld,
    robot: BuiltRobot,
    mb: MultibodyIndex,
    /// Multibody link id of each joint's child (slot order).
    link_ids: Vec<usize>,
    /// Generalized-velocity index of each joint (slot order).
    dofs: Vec<usize>,
    time: f64,
    /// Contact-free twin used for generalized accelerations (built lazily).
    probe: Option<Box<RapierMultibodyEngine>>,
    /// External wrench on the pelvis (`[force; torque]`, world, at the pelvis origin), see [`Engine::set_base_wrench`].
    base_wrench: Option<[f64; 6]>,
}

impl std::fmt::Debug for RapierMultibodyEngine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RapierMultibodyEngine")
            .field("settings", &self.settings)
            .field("common", &self.common)
            .field("time", &self.time)
            .finish_non_exhaustive()
    }
}

impl RapierMultibodyEngine {
    /// Builds the engine at the model's standing pose, at rest.
    pub fn new(
        model: &RobotModel,
        common: &CommonSettings,
        settings: &RapierMultibodySettings,
    ) -> Result<Self, EngineError> {
        let state = State::standing(model);
        Self::build(model, common, settings, &state)
    }

    fn build(
        model: &RobotModel,
        common: &CommonSettings,
        settings: &RapierMultibodySettings,
        state: &State,
    ) -> Result<Self, EngineError> {
        if !(common.timestep.is_finite() && common.timestep > 0.0) {
            return Err(EngineError::Input(format!("timestep {} must be positive", common.timestep)));
        }
        state.validate(model)?;
        let coords = state.coords();
        let fk = model.fk(&coords)?;
        let mut offsets = vec![Vector3::zeros(); model.links.len()];
        offsets[0] = model.links[0].inertial.com;
        let mut world = new_world(common, &settings.solver);
        let robot = add_robot(&mut world, model, common, &fk.link_poses, offsets, &[], true)?;

        // Insert joints in link order (parents before children).
        for link in model.links.iter().skip(1) {
            let (Some(ji), Some(pl)) = (link.parent_joint, link.parent_link) else {
                return Err(EngineError::Build(format!("link {} has no parent joint", link.name)));
            };
            let joint = revolute_joint(
                model,
                ji,
                &robot.frame_offsets,
                common.joint_limits,
                settings.solver.parent_child_contacts,
            );
            let child = robot.bodies[model.joints[ji].child_link];
            world.multibody_joints.insert(robot.bodies[pl], child, joint, true).ok_or_else(|| {
                EngineError::Build(format!("Rapier refused multibody joint {}", model.joints[ji].name))
            })?;
        }
        let root_link = world
            .multibody_joints
            .rigid_body_link(robot.bodies[0])
            .ok_or_else(|| EngineError::Build("pelvis is not in a multibody".into()))?;
        let mb_index = root_link.multibody;
        if root_link.id != 0 {
            return Err(EngineError::Build("pelvis is not the multibody root".into()));
        }
        let mut link_ids = Vec::with_capacity(model.nj());
        for j in &model.joints {
            let l = world
                .multibody_joints
                .rigid_body_link(robot.bodies[j.child_link])
                .ok_or_else(|| EngineError::Build(format!("link of joint {} missing", j.name)))?;
            if l.multibody != mb_index {
                return Err(EngineError::Build(format!("joint {} is not in the pelvis multibody", j.name)));
            }
            link_ids.push(l.id);
        }
        let mut engine = RapierMultibodyEngine {
            model: model.clone(),
            common: common.clone(),
            settings: settings.clone(),
            world,
            robot,
            mb: mb_index,
            dofs: Vec::new(),
            link_ids,
            time: 0.0,
            probe: None,
            base_wrench: None,
        };
        engine.configure_and_set(state)?;
        Ok(engine)
    }

    /// One bare `PhysicsWorld::step` (no state conversion, no torque update: the body torques of the previous
    /// [`Engine::step`] persist). For measuring the overhead of the `Engine` layer only.
    pub fn step_raw(&mut self) {
        self.world.step();
        self.time += self.common.timestep;
    }

    fn multibody(&self) -> Result<&Multibody, EngineError> {
        self.world
            .multibody_joints
            .get_multibody(self.mb)
            .ok_or_else(|| EngineError::Build("multibody vanished".into()))
    }

    /// Sets per-DoF properties, joint coordinates and generalized velocities of a freshly built world.
    fn configure_and_set(&mut self, state: &State) -> Result<(), EngineError> {
        let model = &self.model;
        let common = &self.common;
        let com_local = self.robot.frame_offsets[0];
        let rot = wxyz_to_quat(state.base_quat);
        let w_world = rot * Vector3::from(state.base_ang_vel);
        let v_com = Vector3::from(state.base_lin_vel) + w_world.cross(&(rot * com_local));
        let mb = self
            .world
            .multibody_joints
            .get_multibody_mut(self.mb)
            .ok_or_else(|| EngineError::Build("multibody vanished".into()))?;
        mb.set_self_contacts_enabled(self.settings.self_contacts);
        let nd = mb.ndofs();
        if nd != 6 + model.nj() {
            return Err(EngineError::Build(format!("multibody has {nd} DoFs, expected {}", 6 + model.nj())));
        }
        let mut dofs = Vec::with_capacity(model.nj());
        for &lid in &self.link_ids {
            let link = mb.link(lid).ok_or_else(|| EngineError::Build("multibody link missing".into()))?;
            dofs.push(link.assembly_id());
        }
        mb.damping_mut().fill(0.0);
        mb.armature_mut().fill(0.0);
        mb.frictions_mut().fill(0.0);
        for (ji, j) in model.joints.iter().enumerate() {
            let d = dofs[ji];
            if common.joint_damping {
                mb.damping_mut()[d] = j.damping;
            }
            if common.armature {
                mb.armature_mut()[d] = j.armature;
            }
            if common.joint_friction {
                mb.frictions_mut()[d] = j.frictionloss;
            }
            if let Some(link) = mb.link_mut(self.link_ids[ji]) {
                link.joint.apply_displacement(&[state.q[ji]]);
            }
        }
        {
            let mut gv = mb.generalized_velocity_mut();
            gv.fill(0.0);
            for k in 0..3 {
                gv[k] = v_com[k];
                gv[3 + k] = w_world[k];
            }
            for (ji, &d) in dofs.iter().enumerate() {
                gv[d] = state.dq[ji];
            }
        }
        // The root body was created at the right pose; take it into the multibody and propagate.
        mb.forward_kinematics(&self.world.bodies, true);
        mb.update_rigid_bodies(&mut self.world.bodies, true);
        self.dofs = dofs;
        // Body velocities too (the solver recomputes them from the generalized velocities at each step; this
        // makes energy/momentum of the bodies right straight after a reset).
        let poses = link_poses_from_bodies(&self.world, &self.robot);
        let vels = crate::rapier_common::link_velocities(
            model,
            &poses,
            Vector3::from(state.base_lin_vel),
            Vector3::from(state.base_ang_vel),
            &state.dq,
        );
        for (li, &h) in self.robot.bodies.iter().enumerate() {
            let (w, v_o) = vels[li];
            let c = poses[li] * nalgebra::Point3::from(model.links[li].inertial.com);
            let v_c = v_o + w.cross(&(c.coords - poses[li].translation.vector));
            if let Some(rb) = self.world.bodies.get_mut(h) {
                rb.set_linvel(v_to_r(&v_c), true);
                rb.set_angvel(v_to_r(&w), true);
            }
        }
        Ok(())
    }

    /// Root pose (Rapier body frame at the pelvis COM) -> pelvis origin pose and world rotation.
    fn pelvis_pose(&self) -> Isometry3<f64> {
        match self.world.bodies.get(self.robot.bodies[0]) {
            Some(rb) => iso_from_pose(rb.position()) * Translation3::from(-self.robot.frame_offsets[0]),
            None => Isometry3::identity(),
        }
    }

    /// Generalized mass matrix in Rapier's own coordinates (`[v_com_w, ω_w, dofs]`), including armature.
    fn rapier_mass_matrix(&mut self) -> Result<DMatrix<f64>, EngineError> {
        let bodies = &mut self.world.bodies;
        let mb = self
            .world
            .multibody_joints
            .get_multibody_mut(self.mb)
            .ok_or_else(|| EngineError::Build("multibody vanished".into()))?;
        mb.forward_kinematics(bodies, false);
        mb.update_rigid_bodies(bodies, true);
        // Assembles M + armature (dt = 0 drops damping and springs) and factorises it.
        let _ = mb.dof_inverse_inertia(bodies);
        let n = mb.ndofs();
        let minv = mb
            .inv_augmented_mass()
            .solve(&rna::DMatrix::<f64>::identity(n, n))
            .ok_or_else(|| EngineError::Diverged("singular multibody mass matrix".into()))?;
        let m = minv.try_inverse().ok_or_else(|| EngineError::Diverged("singular inverse mass matrix".into()))?;
        let mut out = DMatrix::zeros(n, n);
        for r in 0..n {
            for c in 0..n {
                out[(r, c)] = 0.5 * (m[(r, c)] + m[(c, r)]);
            }
        }
        Ok(out)
    }

    /// `T` with `v_rapier = T v_interface` at the current configuration.
    fn velocity_map(&self) -> Result<DMatrix<f64>, EngineError> {
        let nv = self.model.nv();
        let pose = self.pelvis_pose();
        let r = pose.rotation.to_rotation_matrix().into_inner();
        let rc = r * self.robot.frame_offsets[0];
        let skew = Matrix3::new(0.0, -rc.z, rc.y, rc.z, 0.0, -rc.x, -rc.y, rc.x, 0.0);
        let mut t = DMatrix::zeros(nv, nv);
        // v_com = v_o + ω_w × (R c) = v_o - [R c]× R ω_b ; ω_w = R ω_b ; joint dofs map to their Rapier index.
        let blk = -skew * r;
        for i in 0..3 {
            t[(i, i)] = 1.0;
            for k in 0..3 {
                t[(i, 3 + k)] = blk[(i, k)];
                t[(3 + i, 3 + k)] = r[(i, k)];
            }
        }
        for (ji, &d) in self.dofs.iter().enumerate() {
            t[(d, 6 + ji)] = 1.0;
        }
        Ok(t)
    }

    /// Adds the base wrench (if any) to the root body, whose Rapier frame sits at the pelvis' centre of mass: the
    /// force as it is, the torque plus the moment of the force about the COM (the force acts at the pelvis origin).
    fn apply_base_wrench(&mut self) {
        let Some(w) = self.base_wrench else { return };
        let f = Vector3::new(w[0], w[1], w[2]);
        let pose = self.pelvis_pose();
        let origin_from_com = -(pose.rotation * self.robot.frame_offsets[0]);
        let t = Vector3::new(w[3], w[4], w[5]) + origin_from_com.cross(&f);
        if let Some(rb) = self.world.bodies.get_mut(self.robot.bodies[0]) {
            rb.add_force(v_to_r(&f), true);
            rb.add_torque(v_to_r(&t), true);
        }
    }

    fn apply_joint_torques(&mut self, tau: &[f64]) {
        clear_user_forces(&mut self.world, &self.robot);
        for (j, &t) in self.model.joints.iter().zip(tau) {
            add_joint_torque(&mut self.world, &self.robot, j, t);
        }
    }
}

impl Engine for RapierMultibodyEngine {
    fn name(&self) -> &'static str {
        "rapier_multibody"
    }
    fn version(&self) -> String {
        format!("{RAPIER_VERSION}, reduced-coordinate Multibody")
    }
    fn settings(&self) -> serde_json::Value {
        let mut v = serde_json::json!({
            "common": self.common,
            "specific": self.settings,
            "precision": "f64 (rapier3d-f64)",
            "formulation": "reduced coordinates (MultibodyJointSet, free root)",
            "root_body_frame": "pelvis COM (translation offset from the pelvis link frame)",
            "joint_torques": "equal and opposite body torques on child/parent (= generalized joint force)",
            "armature": "native per-DoF Multibody::armature",
            "joint_damping": "native per-DoF implicit damping (Multibody::damping)",
            "joint_friction": "native per-DoF bounded velocity constraint (Multibody::frictions)",
            "contact_torsional_rolling_friction": "not supported by Rapier (ignored)",
            "mass_matrix_method": "Rapier's factorised augmented mass (dt = 0: M + armature), inverted, mapped to interface coordinates",
            "acceleration_method": "finite difference of one contact-free probe step (no ground, collisions or limits) of acceleration_probe_dt",
        });
        if let Some(o) = v.as_object_mut() {
            o.insert(
                "integration_parameters".into(),
                serde_json::Value::String(format!("{:?}", self.world.integration_parameters)),
            );
        }
        v
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
        self.apply_joint_torques(tau);
        self.apply_base_wrench();
        self.world.step();
        self.time += self.common.timestep;
        let mb = self.multibody()?;
        if mb.generalized_velocity().iter().any(|x| !x.is_finite()) {
            return Err(EngineError::Diverged(format!("non-finite velocity at t = {}", self.time)));
        }
        Ok(())
    }

    fn set_base_wrench(&mut self, wrench: [f64; 6]) -> Result<(), EngineError> {
        if wrench.iter().any(|x| !x.is_finite()) {
            return Err(EngineError::Input(format!("non-finite base wrench {wrench:?}")));
        }
        self.base_wrench = Some(wrench);
        Ok(())
    }

    fn state(&self) -> State {
        let nj = self.model.nj();
        let pose = self.pelvis_pose();
        let mut st = State {
            base_pos: arr(&pose.translation.vector),
            base_quat: [pose.rotation.w, pose.rotation.i, pose.rotation.j, pose.rotation.k],
            q: vec![0.0; nj],
            base_lin_vel: [0.0; 3],
            base_ang_vel: [0.0; 3],
            dq: vec![0.0; nj],
        };
        let Ok(mb) = self.multibody() else { return st };
        let gv = mb.generalized_velocity();
        let v_com = Vector3::new(gv[0], gv[1], gv[2]);
        let w_world = Vector3::new(gv[3], gv[4], gv[5]);
        let rc = pose.rotation * self.robot.frame_offsets[0];
        st.base_lin_vel = arr(&(v_com - w_world.cross(&rc)));
        st.base_ang_vel = arr(&(pose.rotation.inverse() * w_world));
        for ji in 0..nj {
            if let Some(link) = mb.link(self.link_ids[ji]) {
                st.q[ji] = link.joint().coords()[3];
            }
            st.dq[ji] = gv[self.dofs[ji]];
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
        let st = self.state();
        let v = nalgebra::DVector::from_vec(st.v());
        let kinetic = match (self.rapier_mass_matrix(), self.velocity_map()) {
            (Ok(m), Ok(t)) => {
                let vr = &t * &v;
                0.5 * vr.dot(&(&m * &vr))
            }
            _ => f64::NAN,
        };
        let com = bodies_com(&self.world, &self.robot.bodies);
        let g = self.common.gravity;
        let potential = -self.model.total_mass() * (g[0] * com[0] + g[1] * com[1] + g[2] * com[2]);
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
        let poses = link_poses_from_bodies(&self.world, &self.robot);
        self.model.joints.iter().map(|j| arr(&(poses[j.child_link].rotation * j.axis.into_inner()))).collect()
    }

    fn joint_limits(&self) -> Vec<(f64, f64)> {
        let Ok(mb) = self.multibody() else { return vec![] };
        self.link_ids
            .iter()
            .map(|&lid| {
                mb.link(lid)
                    .and_then(|l| l.joint().data.limits(JointAxis::AngX).map(|lim| (lim.min, lim.max)))
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
            self.probe = Some(Box::new(Self::build(&self.model, &common, &self.settings, &state)?));
        }
        let probe = self.probe.as_mut().ok_or_else(|| EngineError::Build("probe missing".into()))?;
        probe.reset(&state)?;
        probe.apply_joint_torques(&f[6..]);
        // Base wrench: force through the pelvis origin (world), moment about the pelvis origin (pelvis frame).
        let pose = probe.pelvis_pose();
        let force = Vector3::new(f[0], f[1], f[2]);
        let moment_w = pose.rotation * Vector3::new(f[3], f[4], f[5]);
        let origin_minus_com = -(pose.rotation * probe.robot.frame_offsets[0]);
        if let Some(rb) = probe.world.bodies.get_mut(probe.robot.bodies[0]) {
            rb.add_force(v_to_r(&force), true);
            rb.add_torque(v_to_r(&(moment_w + origin_minus_com.cross(&force))), true);
        }
        probe.world.step();
        let after = probe.state();
        let dt = probe.common.timestep;
        let (v0, v1) = (state.v(), after.v());
        Ok(v0.iter().zip(&v1).map(|(a, b)| (b - a) / dt).collect())
    }

    fn mass_matrix(&mut self) -> Option<Vec<f64>> {
        let m = self.rapier_mass_matrix().ok()?;
        let t = self.velocity_map().ok()?;
        let mi = t.transpose() * m * &t;
        // nalgebra stores column-major: the transpose's storage is the row-major matrix.
        Some(mi.transpose().as_slice().to_vec())
    }
}
