//! PhysX 5 (the engine both shipped H1-2 policies were trained in: Isaac Lab and Isaac Gym run PhysX), as a
//! reduced-coordinate articulation (`PxArticulationReducedCoordinate`) built from `robot-model`, through the
//! `physx-sys` crate (PhysX 5.1.3 vendored and compiled by its build script; every foreign call in its `ffi` module).
//!
//! **Precision: PhysX computes and stores everything in f32.** The state comes back in f32 (widened exactly to
//! f64), so every oracle tolerance for this engine is derived from f32 arithmetic ([`f32_tolerance`]), not from
//! what PhysX happened to produce.
//!
//! Model translation (every number from `robot-model`, nothing loaded from a file):
//! - one articulation link per model link, created at its link frame; mass, centre of mass and the inertia
//!   tensor diagonalised in f64 into PhysX's principal moments + principal-axes frame;
//! - revolute joints rotate about the x axis of PhysX joint frames (eTWIST): the parent joint frame is the URDF
//!   joint origin rotated so that x is the joint axis, the child joint frame the same rotation in the child link;
//!   limits as eLIMITED twist limits, armature as PhysX's native per-axis joint armature (added to the ABA);
//! - collision primitives: boxes, spheres, capsules (PhysX capsules lie along x: rotated onto the URDF z axis);
//!   PhysX has no cylinder primitive, so models with cylinders are refused ([`EngineError::Unsupported`]);
//! - ground: a static plane z = 0; one material (the model's friction and restitution) on every shape.
//!
//! Joint effects (which PhysX mechanism, and why):
//! - **joint torques** through the articulation cache (`jointForce`, applied with `applyCache`);
//! - **viscous damping** as an explicit torque `−d·q̇` (state at the start of the step) added to the joint
//!   torque. PhysX 5.1 articulation joints have no damping of their own, and the joint's one drive is used by
//!   dry friction (below). Explicit damping is stable while `d·dt < 2·I` for the smallest joint inertia `I`;
//!   [`PhysxEngine::new`] checks a lower bound of it (the child link alone about the axis, plus armature);
//! - **dry friction** (`frictionloss`, a Coulomb torque) as an implicit velocity drive (PhysX eVELOCITY: target
//!   velocity 0, damping 1e25 inside PhysX) whose force is bounded by `frictionloss` (articulation flag
//!   eDRIVE_LIMITS_ARE_FORCES): a bounded velocity constraint solved with the contacts, as MuJoCo's
//!   `frictionloss`. PhysX's own joint `frictionCoefficient` is NOT a Coulomb torque: it bounds the friction
//!   impulse by coefficient × |spatial force transmitted through the joint| × dt (DyFeatherstoneArticulation.cpp,
//!   `frictionCoefficient * stepDt`), i.e. it grows with the load; it is set to 0.
//!
//! State conversion: PhysX's root velocity is the root link's COM velocity (world) and its angular velocity is
//! world-frame; the interface's is the pelvis-origin velocity (world) and pelvis-frame angular velocity:
//! `v_com = v_o + ω_w × (R c)`, `ω_w = R ω_b`.
//!
//! Reset: the scene is rebuilt (articulation, shapes, broad phase, contact manifolds, friction anchors), so
//! nothing of the previous run survives.
//!
//! PhysX behaviours that differ from textbook rigid-body dynamics (read in the PhysX 5.1.3 source while building
//! this engine; candidates for what a policy trained in PhysX may rely on):
//! - **Root momentum re-projection.** After integrating the joint (internal) forces, PhysX rescales the root's
//!   velocity so that the articulation's linear momentum and the *magnitude* of its angular momentum equal their
//!   values before that step (`computeLinkInternalAcceleration`, DyFeatherstoneForwardDynamic.cpp). The
//!   continuous dynamics conserve both anyway; the projection changes the discrete base motion. Consistent with
//!   it, the base acceleration measured from one PhysX step deviates from the reference by an amount growing
//!   linearly with the step while the joint accelerations do not (see [`PhysxSettings::acceleration_probe_dt`]).
//! - **Speed clamps as damping.** A link faster than `max_link_angular_velocity` / `max_link_linear_velocity`
//!   gets a braking force in the articulation's dynamics (computeZ); Isaac Lab's 1000 deg/s is 17.45 rad/s.
//! - **Joint friction** (`frictionCoefficient`) scales with the force transmitted through the joint (see above),
//!   and drive force limits are impulses per step unless eDRIVE_LIMITS_ARE_FORCES is set.
//! - **Floating-base gravity compensation** (`computeGeneralizedGravityForce`) includes the gyroscopic term of
//!   the root's current angular velocity (computeZ uses the link velocities; only joint velocities are dropped),
//!   so it is "purely gravity" only with a non-rotating root (measured 1.6e-3 of the gravity torques at
//!   |ω| <= 1.7 rad/s; 1.7e-7 at rest). Not used in stepping.
mod dump;
mod ffi;

use crate::engine::{CommonSettings, Contact, Energy, Engine, EngineError, LinkPose, State};
use ffi::{Geometry, JointDesc, LinkDesc, Pose, RawState, ShapeDesc, World, WorldDesc};
use nalgebra::{DMatrix, Matrix3, UnitQuaternion, Vector3};
use robot_model::{RobotModel, Shape};
use serde::{Deserialize, Serialize};
use std::sync::{Arc, Mutex};

/// PhysX's constraint solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PhysxSolver {
    /// Temporal Gauss-Seidel (`PxSolverType::eTGS`): position iterations are sub-steps of the time step.
    Tgs,
    /// Projected Gauss-Seidel (`PxSolverType::ePGS`, PhysX's default).
    Pgs,
}

/// Every PhysX-specific setting, in one place, written into every report (with [`CommonSettings`]).
///
/// The default ([`PhysxSettings::isaac_lab_h12`]) reproduces the configuration the Isaac Lab H1-2 policy
/// (`policies/h1_2_gepetto_demo_rsl.onnx`) was trained with, from the public sources at the commit that added
/// that policy, Gepetto/h1v2-Isaac 8b05f584 (2025-10-15):
/// - `packages/biped_tasks/.../h12_12dof/rsl_env_cfg.py`: robot `H12_12DOF_IDEAL`, `sim.dt = 0.005`,
///   `decimation = 4`, ground material static/dynamic friction 1.0, combine mode multiply;
/// - `packages/biped_assets/biped_assets/robots/h12.py` (`H12_12DOF_IDEAL`): `solver_position_iteration_count=4`,
///   `solver_velocity_iteration_count=4`, `max_linear_velocity=1000.0` (m/s), `max_angular_velocity=1000.0`
///   (deg/s in Isaac Lab), `max_depenetration_velocity=1.0`, `linear_damping=0.0`, `angular_damping=0.0`,
///   `enabled_self_collisions=True`, actuator `armature=0.01`, `friction=0.0`;
/// - `uv.lock` pins `isaaclab==2.1.0`, whose `isaaclab/sim/simulation_cfg.py` `PhysxCfg` defaults apply:
///   `solver_type=1` (TGS), `enable_stabilization=True`, `enable_enhanced_determinism=False`,
///   `bounce_threshold_velocity=0.5`, `friction_offset_threshold=0.04`, `friction_correlation_distance=0.025`,
///   `min/max_position_iteration_count=1/255`, `min/max_velocity_iteration_count=0/255` (so the robot's 4/4
///   stand).
///
/// The robot's collision `contact_offset`/`rest_offset` live in that repository's USD files, which are Git LFS
/// objects (not readable from the public source): the default takes Unitree's Isaac Gym figures instead
/// (unitreerobotics/unitree_rl_gym 276801e, `legged_gym/envs/base/legged_robot_config.py`, `sim.physx`:
/// `contact_offset = 0.01`, `rest_offset = 0.0`).
///
/// Where this differs from the training runs, on purpose: the time step is [`CommonSettings::timestep`]
/// (2 ms by default, Unitree's; Isaac Lab trained at 5 ms, unitree_rl_gym's H1-2 at 2.5 ms); armature, damping,
/// dry friction, self-collision and contact friction come from the robot model like for every other engine
/// (Isaac Lab trained with armature 0.01, no joint friction, self-collisions on, friction randomised 0.1..1.25);
/// PhysX is 5.1.3 here (Isaac Sim 4.5 under Isaac Lab 2.1 ships a later 5.x) and runs on the CPU.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PhysxSettings {
    /// Solver. TGS in both training configurations.
    pub solver: PhysxSolver,
    /// Articulation position iterations (TGS: sub-steps). More iterations resolve contacts and limits
    /// more stiffly per step; fewer leave more penetration/drift — a direct source of divergence.
    pub position_iterations: u32,
    /// Articulation velocity iterations (after the position pass, without position correction).
    pub velocity_iterations: u32,
    /// Shape contact offset (m): contacts are generated when shapes are closer than the sum of offsets
    /// (speculative contacts before touching).
    pub contact_offset: f64,
    /// Shape rest offset (m): the separation the solver drives resting contacts to (0: touching).
    pub rest_offset: f64,
    /// Relative normal velocity (m/s) below which contacts do not bounce (restitution ignored).
    pub bounce_threshold_velocity: f64,
    /// Distance (m) below which contact points take part in friction.
    pub friction_offset_threshold: f64,
    /// Distance (m) within which contact points share a friction anchor (patch friction).
    pub friction_correlation_distance: f64,
    /// Scene flag eENABLE_STABILIZATION: slow bodies get an extra stabilisation pass (it damps residual
    /// motion of nearly resting bodies: changes standing dynamics).
    pub enable_stabilization: bool,
    /// Scene flag eENABLE_ENHANCED_DETERMINISM (results independent of actor insertion order).
    pub enhanced_determinism: bool,
    /// Per-link linear speed clamp (m/s, PhysX damps links above it).
    pub max_link_linear_velocity: f64,
    /// Per-link angular speed clamp (rad/s). Isaac Lab's 1000 deg/s = 17.45 rad/s: a swinging foot or hand can
    /// reach it, and PhysX then damps the link — an engine effect a policy can learn to live with.
    pub max_link_angular_velocity: f64,
    /// Cap on the velocity the solver introduces to resolve penetration (m/s).
    pub max_depenetration_velocity: f64,
    /// PhysX per-joint velocity clamp (rad/s; PhysX's default 100).
    pub max_joint_velocity: f64,
    /// [`Engine::generalized_acceleration`] splits `a(f) = a(0) + M⁻¹f` (exact: the dynamics are affine in the
    /// applied force) and measures both parts with contact-free probe steps of PhysX itself. `a(0)` (velocity
    /// terms, gravity, damping) comes from one step of this length (s) from the current state. Two errors
    /// compete: the f32 rounding of `(v₁ − v₀)/dt`, ~u·|v|/dt, and an O(dt) term in the floating root's update,
    /// which is not one explicit evaluation (the joint accelerations of the same step match the reference to
    /// f32 precision; PhysX re-projects the root velocity after the joint-force step, see the module docs).
    /// Measured on the H1-2 with armature (relative error of accelerations): 8e-5 at 1e-5 s, 3e-6 at 3e-4 s,
    /// 1e-4 at 1e-2 s.
    pub acceleration_probe_dt: f64,
    /// `M⁻¹f` comes from one step of this length (s) from the current configuration AT REST without gravity:
    /// `v₀ = 0`, so the f32 rounding is relative (no cancellation) and a short step removes the configuration
    /// change within the step. Measured (M rebuilt from accelerations vs the reference, with armature): 4e-7 at
    /// 1e-6 s, 7e-7 at 1e-4 s, 4e-4 at 1e-2 s, 4e-2 at 0.1 s.
    pub force_probe_dt: f64,
}

impl Default for PhysxSettings {
    fn default() -> Self {
        Self::isaac_lab_h12()
    }
}

impl PhysxSettings {
    /// Isaac Lab 2.1 H1-2 training configuration (Gepetto/h1v2-Isaac); see the type's docs for every source.
    pub fn isaac_lab_h12() -> Self {
        PhysxSettings {
            solver: PhysxSolver::Tgs,
            position_iterations: 4,
            velocity_iterations: 4,
            contact_offset: 0.01,
            rest_offset: 0.0,
            bounce_threshold_velocity: 0.5,
            friction_offset_threshold: 0.04,
            friction_correlation_distance: 0.025,
            enable_stabilization: true,
            enhanced_determinism: false,
            max_link_linear_velocity: 1000.0,
            max_link_angular_velocity: 1000.0_f64.to_radians(),
            max_depenetration_velocity: 1.0,
            max_joint_velocity: 100.0,
            acceleration_probe_dt: 3e-4,
            force_probe_dt: 1e-6,
        }
    }

    /// Unitree's Isaac Gym configuration (unitreerobotics/unitree_rl_gym 276801e,
    /// `legged_gym/envs/base/legged_robot_config.py`: `solver_type = 1`, `num_position_iterations = 4`,
    /// `num_velocity_iterations = 0`, `contact_offset = 0.01`, `rest_offset = 0.0`,
    /// `bounce_threshold_velocity = 0.5`, `max_depenetration_velocity = 1.0`; asset `max_angular_velocity =
    /// 1000.`, `max_linear_velocity = 1000.` (Isaac Gym: rad/s, m/s)). Friction offset/correlation and
    /// stabilisation are not set there: PhysX's defaults (PxSceneDesc.h: 0.04 m, 0.025 m; stabilisation off).
    pub fn unitree_rl_gym() -> Self {
        PhysxSettings {
            velocity_iterations: 0,
            enable_stabilization: false,
            max_link_angular_velocity: 1000.0,
            ..Self::isaac_lab_h12()
        }
    }

    fn validate(&self) -> Result<(), EngineError> {
        let pos = [
            ("contact_offset", self.contact_offset),
            ("max_link_linear_velocity", self.max_link_linear_velocity),
            ("max_link_angular_velocity", self.max_link_angular_velocity),
            ("max_joint_velocity", self.max_joint_velocity),
            ("acceleration_probe_dt", self.acceleration_probe_dt),
            ("force_probe_dt", self.force_probe_dt),
        ];
        for (n, v) in pos {
            if !(v.is_finite() && v > 0.0) {
                return Err(EngineError::Input(format!("PhysX setting {n} = {v} must be positive")));
            }
        }
        let nonneg = [
            ("rest_offset", self.rest_offset),
            ("bounce_threshold_velocity", self.bounce_threshold_velocity),
            ("friction_offset_threshold", self.friction_offset_threshold),
            ("friction_correlation_distance", self.friction_correlation_distance),
            ("max_depenetration_velocity", self.max_depenetration_velocity),
        ];
        for (n, v) in nonneg {
            if !(v.is_finite() && v >= 0.0) {
                return Err(EngineError::Input(format!("PhysX setting {n} = {v} must be >= 0")));
            }
        }
        if self.rest_offset >= self.contact_offset {
            return Err(EngineError::Input("PhysX needs rest_offset < contact_offset".into()));
        }
        if !(1..=255).contains(&self.position_iterations) || self.velocity_iterations > 255 {
            return Err(EngineError::Input("PhysX iterations: position 1..=255, velocity 0..=255".into()));
        }
        Ok(())
    }
}

/// Engine library and version string.
pub fn version() -> String {
    let (a, b, c) = ffi::PHYSX_VERSION;
    format!("PhysX {a}.{b}.{c} (CPU, f32) via physx-sys 0.11.5, reduced-coordinate articulation")
}

/// Unit roundoff of f32, the arithmetic PhysX computes and stores in.
pub const F32_UNIT_ROUNDOFF: f64 = f32::EPSILON as f64 / 2.0;

/// The PhysX engine.
pub struct PhysxEngine {
    model: RobotModel,
    common: CommonSettings,
    settings: PhysxSettings,
    desc: WorldDesc,
    world: World,
    /// State after the last reset/step, PhysX coordinates.
    raw: RawState,
    /// Joint index (slot) of each PhysX DoF (`model.links[1..]` order).
    joint_of_dof: Vec<usize>,
    /// Root COM in the root link frame as PhysX stores it (f32, widened): every world of this engine has it.
    root_com: Vector3<f64>,
    time: f64,
    /// Contact-free twins for generalized accelerations (built lazily): with the scene's gravity, and without.
    probe: Option<(World, World)>,
    /// Scene dump being recorded ([`PhysxEngine::record_scene`]) and the steps since the last reset.
    recording: Option<(Arc<Mutex<String>>, usize)>,
}

impl std::fmt::Debug for PhysxEngine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PhysxEngine")
            .field("settings", &self.settings)
            .field("common", &self.common)
            .field("time", &self.time)
            .finish_non_exhaustive()
    }
}

fn build_err(e: String) -> EngineError {
    EngineError::Build(e)
}
fn sim_err(e: String) -> EngineError {
    EngineError::Diverged(e)
}

fn pose_of(iso: &nalgebra::Isometry3<f64>) -> Pose {
    let q = iso.rotation;
    Pose { p: [iso.translation.x, iso.translation.y, iso.translation.z], q: [q.w, q.i, q.j, q.k] }
}
fn quat_of(p: &Pose) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(p.q[0], p.q[1], p.q[2], p.q[3]))
}
fn v3(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}
fn arr(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// Rotation taking the x axis onto `axis` (unit).
fn x_to(axis: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(&Vector3::x(), axis)
        .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI))
}

impl PhysxEngine {
    /// Builds the engine at the model's standing pose, at rest.
    pub fn new(model: &RobotModel, common: &CommonSettings, settings: &PhysxSettings) -> Result<Self, EngineError> {
        if !(common.timestep.is_finite() && common.timestep > 0.0) {
            return Err(EngineError::Input(format!("timestep {} must be positive", common.timestep)));
        }
        if common.gravity.iter().any(|g| !g.is_finite()) {
            return Err(EngineError::Input("gravity must be finite".into()));
        }
        settings.validate()?;
        check_explicit_damping(model, common)?;
        let desc = world_desc(model, common, settings)?;
        let mut joint_of_dof = Vec::with_capacity(model.nj());
        for (li, l) in model.links.iter().enumerate().skip(1) {
            joint_of_dof.push(l.parent_joint.ok_or_else(|| EngineError::Build(format!("link {li} has no joint")))?);
        }
        let mut seen = vec![false; model.nj()];
        for &j in &joint_of_dof {
            if let Some(slot) = seen.get_mut(j) {
                *slot = true;
            }
        }
        if seen.iter().any(|&x| !x) || joint_of_dof.len() != model.nj() {
            return Err(EngineError::Build("every joint must be the inbound joint of exactly one link".into()));
        }
        let world = World::new(&desc).map_err(build_err)?;
        let root_com = world.mass_props().first().map(|m| v3(m.mass_frame.p)).unwrap_or_else(Vector3::zeros);
        let raw = RawState {
            root: desc.links[0].pose,
            root_lin_vel: [0.0; 3],
            root_ang_vel: [0.0; 3],
            q: vec![],
            dq: vec![],
        };
        let mut e = PhysxEngine {
            model: model.clone(),
            common: common.clone(),
            settings: settings.clone(),
            desc,
            world,
            raw,
            joint_of_dof,
            root_com,
            time: 0.0,
            probe: None,
            recording: None,
        };
        e.set_world_state(&State::standing(model))?;
        Ok(e)
    }

    /// Records what this engine hands PhysX, as text, into `into`: at every reset the text is replaced by the
    /// world description, the time step and the state set, and every step appends its joint forces (format in
    /// `physx/dump.rs`). For standalone reproducers that use `physx-sys` alone; costs nothing when not called.
    pub fn record_scene(&mut self, into: Arc<Mutex<String>>) {
        self.recording = Some((into, 0));
    }

    /// The settings in force.
    pub fn physx_settings(&self) -> &PhysxSettings {
        &self.settings
    }

    /// Raw access for benchmarks (the `Engine` layer's overhead is measured against it): joint positions and
    /// velocities in PhysX's DoF order ([`PhysxEngine::dof_joints`] gives each DoF's slot), straight from the
    /// articulation cache. Use with [`PhysxEngine::raw_step`] only.
    pub fn raw_joints(&mut self, q: &mut [f64], dq: &mut [f64]) -> Result<(), EngineError> {
        self.world.joints_into(q, dq).map_err(sim_err)
    }

    /// Raw access for benchmarks: applies joint torques (PhysX DoF order) as they are (no damping) and steps,
    /// without reading the state back. [`Engine::state`] is stale until the next [`Engine::step`] or reset.
    pub fn raw_step(&mut self, tau_dof: &[f64]) -> Result<(), EngineError> {
        self.world.set_joint_forces(tau_dof).map_err(sim_err)?;
        self.world.step(self.common.timestep).map_err(sim_err)?;
        self.time += self.common.timestep;
        Ok(())
    }

    /// Joint (slot) of each PhysX DoF.
    pub fn dof_joints(&self) -> &[usize] {
        &self.joint_of_dof
    }

    /// Interface state -> PhysX state.
    fn to_raw(&self, s: &State) -> RawState {
        let r = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            s.base_quat[0],
            s.base_quat[1],
            s.base_quat[2],
            s.base_quat[3],
        ));
        let c = self.root_com;
        let w_world = r * v3(s.base_ang_vel);
        let v_com = v3(s.base_lin_vel) + w_world.cross(&(r * c));
        RawState {
            root: Pose { p: s.base_pos, q: [r.w, r.i, r.j, r.k] },
            root_lin_vel: arr(&v_com),
            root_ang_vel: arr(&w_world),
            q: self.joint_of_dof.iter().map(|&j| s.q[j]).collect(),
            dq: self.joint_of_dof.iter().map(|&j| s.dq[j]).collect(),
        }
    }

    /// PhysX state -> interface state.
    fn state_of_raw(&self, raw: &RawState) -> State {
        let r = quat_of(&raw.root);
        let w_world = v3(raw.root_ang_vel);
        let v_o = v3(raw.root_lin_vel) - w_world.cross(&(r * self.root_com));
        let nj = self.model.nj();
        let mut q = vec![0.0; nj];
        let mut dq = vec![0.0; nj];
        for (d, &j) in self.joint_of_dof.iter().enumerate() {
            q[j] = raw.q.get(d).copied().unwrap_or(f64::NAN);
            dq[j] = raw.dq.get(d).copied().unwrap_or(f64::NAN);
        }
        State {
            base_pos: raw.root.p,
            base_quat: [r.w, r.i, r.j, r.k],
            q,
            base_lin_vel: arr(&v_o),
            base_ang_vel: arr(&(r.inverse() * w_world)),
            dq,
        }
    }

    fn set_world_state(&mut self, s: &State) -> Result<(), EngineError> {
        s.validate(&self.model)?;
        let raw = self.to_raw(s);
        self.world.set_state(&raw).map_err(EngineError::Input)?;
        self.raw = self.world.state().map_err(sim_err)?;
        Ok(())
    }

    /// Joint forces in PhysX DoF order: torques plus explicit viscous damping `−d·q̇`.
    fn dof_forces(&self, tau: &[f64], dq_dof: &[f64]) -> Vec<f64> {
        self.joint_of_dof
            .iter()
            .enumerate()
            .map(|(d, &j)| {
                let damp = if self.common.joint_damping { self.model.joints[j].damping * dq_dof[d] } else { 0.0 };
                tau[j] - damp
            })
            .collect()
    }

    /// `T` with `v_physx = T v_interface` at the current configuration (PhysX: root COM velocity and angular
    /// velocity in the world, then DoFs in link order).
    fn velocity_map(&self) -> DMatrix<f64> {
        let nv = self.model.nv();
        let r = quat_of(&self.raw.root).to_rotation_matrix().into_inner();
        let rc = r * self.root_com;
        let skew = Matrix3::new(0.0, -rc.z, rc.y, rc.z, 0.0, -rc.x, -rc.y, rc.x, 0.0);
        let blk = -skew * r;
        let mut t = DMatrix::zeros(nv, nv);
        for i in 0..3 {
            t[(i, i)] = 1.0;
            for k in 0..3 {
                t[(i, 3 + k)] = blk[(i, k)];
                t[(3 + i, 3 + k)] = r[(i, k)];
            }
        }
        for (d, &j) in self.joint_of_dof.iter().enumerate() {
            t[(6 + d, 6 + j)] = 1.0;
        }
        t
    }

    /// Mass matrix in PhysX coordinates, `Σ Jᵀ diag(m, I_world) J` over the links with PhysX's dense Jacobian and
    /// PhysX's stored masses and inertias, plus the stored joint armature.
    fn physx_mass_matrix(&mut self) -> Result<DMatrix<f64>, EngineError> {
        let jac = self.world.dense_jacobian().map_err(sim_err)?;
        let nv = self.model.nv();
        let props = self.world.mass_props();
        let poses = self.world.link_poses();
        let mut m = DMatrix::<f64>::zeros(nv, nv);
        for (li, (mp, pose)) in props.iter().zip(&poses).enumerate() {
            let rot = (quat_of(pose) * quat_of(&mp.mass_frame)).to_rotation_matrix().into_inner();
            let iw = rot * Matrix3::from_diagonal(&v3(mp.principal_inertia)) * rot.transpose();
            let rows = |k: usize| -> nalgebra::DVectorView<'_, f64> {
                nalgebra::DVectorView::from_slice(&jac[(6 * li + k) * nv..(6 * li + k + 1) * nv], nv)
            };
            // Linear rows: m Σ_k J_k J_kᵀ; angular rows: Σ_ab I_ab J_a J_bᵀ.
            for k in 0..3 {
                let jk = rows(k);
                m.ger(mp.mass, &jk, &jk, 1.0);
            }
            for a in 0..3 {
                for b in 0..3 {
                    let (ja, jb) = (rows(3 + a), rows(3 + b));
                    m.ger(iw[(a, b)], &ja, &jb, 1.0);
                }
            }
        }
        for (d, a) in self.world.joint_armature().into_iter().enumerate() {
            m[(6 + d, 6 + d)] += a;
        }
        Ok((&m + m.transpose()) * 0.5)
    }

    /// PhysX's own inverse-dynamics quantities at the current state (floating base, base left free), for the
    /// PhysX-specific oracle checks: see [`PhysxNative`].
    pub fn native_dynamics(&mut self, tau: &[f64]) -> Result<PhysxNative, EngineError> {
        if tau.len() != self.model.nj() {
            return Err(EngineError::Input(format!("expected {} torques", self.model.nj())));
        }
        let f: Vec<f64> = self.joint_of_dof.iter().map(|&j| tau[j]).collect();
        let id = self.world.inverse_dynamics(&f).map_err(sim_err)?;
        let nj = self.model.nj();
        let mut mass = vec![0.0; nj * nj];
        let (mut gravity, mut coriolis, mut acceleration) = (vec![0.0; nj], vec![0.0; nj], vec![0.0; nj]);
        for (r, &jr) in self.joint_of_dof.iter().enumerate() {
            gravity[jr] = id.gravity[r];
            coriolis[jr] = id.coriolis[r];
            acceleration[jr] = id.acceleration[r];
            for (c, &jc) in self.joint_of_dof.iter().enumerate() {
                mass[jr * nj + jc] = id.mass[r * nj + c];
            }
        }
        Ok(PhysxNative { mass, gravity, coriolis, acceleration })
    }

    /// Builds the two probe worlds: contact-free (no ground, collisions, limits or dry friction) with PhysX's
    /// speed clamps and stabilisation lifted (the probes measure the smooth dynamics), with the scene's gravity
    /// and without.
    fn build_probes(&self) -> Result<(World, World), EngineError> {
        let common = CommonSettings {
            ground: false,
            collisions: false,
            joint_limits: false,
            joint_friction: false,
            ..self.common.clone()
        };
        let settings = PhysxSettings {
            max_link_linear_velocity: 1e7,
            max_link_angular_velocity: 1e7,
            max_joint_velocity: 1e7,
            // Stabilisation acts on bodies below a kinetic-energy threshold, as a probe from rest is.
            enable_stabilization: false,
            ..self.settings.clone()
        };
        let with_g = World::new(&world_desc(&self.model, &common, &settings)?).map_err(build_err)?;
        let common0 = CommonSettings { gravity: [0.0; 3], ..common };
        let without_g = World::new(&world_desc(&self.model, &common0, &settings)?).map_err(build_err)?;
        Ok((with_g, without_g))
    }

    /// One probe step of `dt` from `state` with joint forces (DoF order) and a base wrench (interface
    /// convention), differentiated in PhysX's coordinates (where the step is `v₁ = v₀ + dt·a`) and mapped to the
    /// interface's at the start state: `a_o = a_com − α × r − ω × (ω × r)`, `ω̇_b = Rᵀ α`, `r = R c`.
    fn probe_acceleration(
        &self,
        probe: &mut World,
        state: &State,
        joint_forces: &[f64],
        wrench: &[f64],
        dt: f64,
    ) -> Result<Vec<f64>, EngineError> {
        let raw = self.to_raw(state);
        probe.set_state(&raw).map_err(EngineError::Input)?;
        let v0 = probe.state().map_err(sim_err)?;
        probe.set_joint_forces(joint_forces).map_err(sim_err)?;
        // Force through the pelvis origin (world) and moment about it (pelvis frame) -> force at the root COM
        // and world torque about the COM.
        let r = quat_of(&v0.root);
        let rc = r * self.root_com;
        let force = Vector3::new(wrench[0], wrench[1], wrench[2]);
        let torque = r * Vector3::new(wrench[3], wrench[4], wrench[5]) + (-rc).cross(&force);
        probe.add_root_wrench(arr(&force), arr(&torque)).map_err(sim_err)?;
        probe.step(dt).map_err(sim_err)?;
        let v1 = probe.state().map_err(sim_err)?;
        let d = |a: [f64; 3], b: [f64; 3]| (v3(b) - v3(a)) / dt;
        let a_com = d(v0.root_lin_vel, v1.root_lin_vel);
        let alpha = d(v0.root_ang_vel, v1.root_ang_vel);
        let w = v3(v0.root_ang_vel);
        let a_o = a_com - alpha.cross(&rc) - w.cross(&w.cross(&rc));
        let mut out = vec![0.0; self.model.nv()];
        out[0..3].copy_from_slice(&arr(&a_o));
        out[3..6].copy_from_slice(&arr(&(r.inverse() * alpha)));
        for (k, &j) in self.joint_of_dof.iter().enumerate() {
            out[6 + j] = (v1.dq[k] - v0.dq[k]) / dt;
        }
        Ok(out)
    }
}

/// PhysX's own floating-base inverse dynamics at one state (slot order; see
/// `PxArticulationReducedCoordinate::computeGeneralizedMassMatrix` & co. in PhysX 5.1): with a floating base these
/// are the joint-space quantities with the base left free (a Schur complement of the full ones), not the full
/// `nv × nv` ones, and the mass matrix excludes armature.
#[derive(Debug, Clone, PartialEq)]
pub struct PhysxNative {
    /// `M_jj − M_jb M_bb⁻¹ M_bj` (nj × nj, row-major).
    pub mass: Vec<f64>,
    /// Joint forces cancelling gravity with the base free (zero for uniform gravity).
    pub gravity: Vec<f64>,
    /// Joint forces cancelling Coriolis/centrifugal effects with the base free.
    pub coriolis: Vec<f64>,
    /// Joint accelerations under the given joint torques, gravity and the current velocities (ABA, base free,
    /// armature included).
    pub acceleration: Vec<f64>,
}

/// Explicit damping is stable while `d·dt < 2·I` (explicit Euler on `I q̈ = −d q̇`); the joint's effective inertia
/// is at least the child link's own inertia about the joint axis (through the joint origin) plus armature.
/// Refuses configurations within a factor 2 of the bound.
fn check_explicit_damping(model: &RobotModel, common: &CommonSettings) -> Result<(), EngineError> {
    if !common.joint_damping {
        return Ok(());
    }
    for j in &model.joints {
        let l = &model.links[j.child_link].inertial;
        let a = j.axis.into_inner();
        let c = l.com;
        let i_origin = l.inertia + l.mass * (Matrix3::identity() * c.dot(&c) - c * c.transpose());
        let lower = a.dot(&(i_origin * a)) + if common.armature { j.armature } else { 0.0 };
        if j.damping * common.timestep >= lower {
            return Err(EngineError::Unsupported(format!(
                "PhysX applies joint damping explicitly: joint {} (d = {}, inertia >= {lower:.3e} kg·m²) needs \
                 dt < {:.3e} s for a safe margin, got {}",
                j.name,
                j.damping,
                lower / j.damping,
                common.timestep
            )));
        }
    }
    Ok(())
}

/// The PhysX description of the model under the given settings (links created at the zero-joint-angle pose of
/// the standing base; `reset` then applies the real state).
fn world_desc(model: &RobotModel, common: &CommonSettings, s: &PhysxSettings) -> Result<WorldDesc, EngineError> {
    let mut zero = robot_model::GenCoords::standing(model);
    zero.q.iter_mut().for_each(|q| *q = 0.0);
    let fk = model.fk(&zero)?;
    let capsule_to_z = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -std::f64::consts::FRAC_PI_2);
    let mut links = Vec::with_capacity(model.links.len());
    for (li, link) in model.links.iter().enumerate() {
        let inertial = &link.inertial;
        if !(inertial.mass.is_finite() && inertial.mass > 0.0) {
            return Err(EngineError::Build(format!(
                "link {}: PhysX reads a zero mass as infinite; mass {} is not supported",
                link.name, inertial.mass
            )));
        }
        let (axes, moments) = crate::engine::principal_frame(&inertial.inertia);
        if moments.iter().any(|m| !(m.is_finite() && *m > 0.0)) {
            return Err(EngineError::Build(format!(
                "link {}: principal inertia {moments:?} must be positive (PhysX reads 0 as infinite)",
                link.name
            )));
        }
        let mut shapes = Vec::new();
        if common.collisions {
            for c in &link.collisions {
                let (geometry, local) = match c.shape {
                    Shape::Box { half_extents } => (Geometry::Box { half_extents }, c.origin),
                    Shape::Sphere { radius } => (Geometry::Sphere { radius }, c.origin),
                    Shape::Capsule { radius, half_length } => (
                        Geometry::Capsule { radius, half_height: half_length },
                        c.origin * nalgebra::Isometry3::from_parts(nalgebra::Translation3::identity(), capsule_to_z),
                    ),
                    Shape::Cylinder { .. } => {
                        return Err(EngineError::Unsupported(format!(
                            "link {}: PhysX has no cylinder primitive (a convex mesh would be needed)",
                            link.name
                        )))
                    }
                };
                shapes.push(ShapeDesc { geometry, local: pose_of(&local) });
            }
        }
        let joint = match link.parent_joint {
            None => None,
            Some(ji) => {
                let j = &model.joints[ji];
                let a = x_to(&j.axis.into_inner());
                let frame = nalgebra::Isometry3::from_parts(nalgebra::Translation3::identity(), a);
                Some(JointDesc {
                    parent_pose: pose_of(&(j.origin * frame)),
                    child_pose: pose_of(&frame),
                    limits: if common.joint_limits { Some((j.lower, j.upper)) } else { None },
                    armature: if common.armature { j.armature } else { 0.0 },
                    friction_drive: if common.joint_friction && j.frictionloss > 0.0 {
                        Some(j.frictionloss)
                    } else {
                        None
                    },
                    max_joint_velocity: s.max_joint_velocity,
                })
            }
        };
        links.push(LinkDesc {
            parent: link.parent_link,
            pose: pose_of(&fk.link_poses[li]),
            mass: inertial.mass,
            mass_frame: Pose { p: arr(&inertial.com), q: [axes.w, axes.i, axes.j, axes.k] },
            principal_inertia: moments,
            shapes,
            joint,
        });
    }
    Ok(WorldDesc {
        gravity: common.gravity,
        tgs: s.solver == PhysxSolver::Tgs,
        position_iterations: s.position_iterations,
        velocity_iterations: s.velocity_iterations,
        bounce_threshold_velocity: s.bounce_threshold_velocity,
        friction_offset_threshold: s.friction_offset_threshold,
        friction_correlation_distance: s.friction_correlation_distance,
        stabilization: s.enable_stabilization,
        enhanced_determinism: s.enhanced_determinism,
        ground: common.ground,
        static_friction: model.contact.friction,
        dynamic_friction: model.contact.friction,
        restitution: model.contact.restitution,
        contact_offset: s.contact_offset,
        rest_offset: s.rest_offset,
        self_collision: model.contact.self_collision,
        max_linear_velocity: s.max_link_linear_velocity,
        max_angular_velocity: s.max_link_angular_velocity,
        max_depenetration_velocity: s.max_depenetration_velocity,
        links,
    })
}

impl Engine for PhysxEngine {
    fn name(&self) -> &'static str {
        "physx"
    }
    fn version(&self) -> String {
        version()
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::json!({
            "common": self.common,
            "specific": self.settings,
            "precision": "f32 (PhysX computes and stores in single precision)",
            "formulation": "reduced coordinates (PxArticulationReducedCoordinate, floating base)",
            "friction_model": "patch friction (PxFrictionType::ePATCH), PCM contact generation (PhysX defaults)",
            "material": "one material on every shape: static = dynamic = model friction, restitution = model's, combine average",
            "self_collision": "articulation eDISABLE_SELF_COLLISION unless the model enables self-collision",
            "joint_torques": "articulation cache jointForce (applyCache eFORCE)",
            "armature": "native per-axis joint armature (PxArticulationJointReducedCoordinate::setArmature)",
            "joint_damping": "explicit torque −d·q̇ from the state at the start of the step",
            "joint_friction": "implicit eVELOCITY drive, target 0, |force| <= frictionloss (eDRIVE_LIMITS_ARE_FORCES); PhysX frictionCoefficient = 0",
            "contact_torsional_rolling_friction": "not modelled by PhysX primitives here (ignored)",
            "sleeping": "disabled (sleep threshold 0)",
            "stabilization_threshold": self.world.stabilization_threshold(),
            "mass_matrix_method": "Σ Jᵀ diag(m, I) J over links with PhysX's dense Jacobian (computeDenseJacobian) and stored inertias, + stored armature; mapped to interface coordinates",
            "acceleration_method": "finite differences of contact-free PhysX probe steps (no ground/collisions/limits/dry friction, speed clamps and stabilisation lifted), a(f) = a(0) + M⁻¹f: a(0) from the current state over acceleration_probe_dt, M⁻¹f from the configuration at rest without gravity over force_probe_dt; differentiated in PhysX coordinates, mapped analytically",
        })
    }
    fn common(&self) -> &CommonSettings {
        &self.common
    }

    fn reset(&mut self, state: &State) -> Result<(), EngineError> {
        state.validate(&self.model)?;
        // A fresh scene: no contact manifold, friction anchor or solver history survives.
        self.world = World::new(&self.desc).map_err(build_err)?;
        self.time = 0.0;
        self.set_world_state(state)?;
        if self.recording.is_some() {
            let dump = dump::scene(&self.desc, self.common.timestep) + &dump::state(&self.to_raw(state));
            if let Some((text, steps)) = &mut self.recording {
                *text.lock().unwrap_or_else(|p| p.into_inner()) = dump;
                *steps = 0;
            }
        }
        Ok(())
    }

    fn step(&mut self, tau: &[f64]) -> Result<(), EngineError> {
        let nj = self.model.nj();
        if tau.len() != nj || tau.iter().any(|t| !t.is_finite()) {
            return Err(EngineError::Input(format!("expected {nj} finite torques, got {}", tau.len())));
        }
        let f = self.dof_forces(tau, &self.raw.dq);
        if let Some((text, steps)) = &mut self.recording {
            text.lock().unwrap_or_else(|p| p.into_inner()).push_str(&dump::forces(*steps, &f));
            *steps += 1;
        }
        self.world.set_joint_forces(&f).map_err(sim_err)?;
        self.world.step(self.common.timestep).map_err(sim_err)?;
        self.time += self.common.timestep;
        self.raw = self.world.state().map_err(sim_err)?;
        let r = &self.raw;
        let finite =
            r.q.iter().chain(&r.dq).chain(&r.root.p).chain(&r.root.q).chain(&r.root_lin_vel).all(|x| x.is_finite());
        if !finite {
            return Err(EngineError::Diverged(format!("non-finite state at t = {}", self.time)));
        }
        Ok(())
    }

    fn state(&self) -> State {
        self.state_of_raw(&self.raw)
    }

    fn time(&self) -> f64 {
        self.time
    }

    fn contacts(&self) -> Vec<Contact> {
        let name = |l: Option<usize>| match l {
            None => "ground".to_string(),
            Some(i) => self.model.links.get(i).map(|l| l.name.clone()).unwrap_or_else(|| "?".into()),
        };
        let dt = self.common.timestep;
        let mut out = Vec::new();
        for c in self.world.contacts() {
            let impulse = v3(c.impulse).norm();
            if c.separation > 0.0 && impulse <= 0.0 {
                continue; // speculative point (within the contact offset) that did not engage
            }
            // PhysX's normal points from the pair's second shape towards the first.
            let n = v3(c.normal);
            let (a, b, normal) = match (c.link0, c.link1) {
                (Some(l0), None) => (None, Some(l0), n),
                (None, l1) => (None, l1, -n),
                (l0, l1) => (l0, l1, -n),
            };
            out.push(Contact {
                body_a: name(a),
                body_b: name(b),
                point: c.position,
                normal: arr(&normal),
                normal_force: impulse / dt,
                depth: -c.separation,
            });
        }
        out
    }

    fn energy(&mut self) -> Energy {
        let st = self.state();
        let v = nalgebra::DVector::from_vec(st.v());
        let kinetic = match self.physx_mass_matrix() {
            Ok(m) => {
                let t = self.velocity_map();
                let vp = &t * &v;
                0.5 * vp.dot(&(&m * &vp))
            }
            Err(_) => f64::NAN,
        };
        let com = self.com();
        let g = self.common.gravity;
        let mass: f64 = self.link_masses().iter().sum();
        Energy { kinetic, potential: -mass * (g[0] * com[0] + g[1] * com[1] + g[2] * com[2]) }
    }

    fn link_masses(&self) -> Vec<f64> {
        self.world.mass_props().iter().map(|m| m.mass).collect()
    }

    fn link_poses(&mut self) -> Vec<LinkPose> {
        self.world.link_poses().into_iter().map(|p| LinkPose { pos: p.p, quat: p.q }).collect()
    }

    fn com(&mut self) -> [f64; 3] {
        let (mut m, mut c) = (0.0, Vector3::zeros());
        for (mp, pose) in self.world.mass_props().iter().zip(self.world.link_poses()) {
            let x = v3(pose.p) + quat_of(&pose) * v3(mp.mass_frame.p);
            c += x * mp.mass;
            m += mp.mass;
        }
        if m > 0.0 {
            arr(&(c / m))
        } else {
            [f64::NAN; 3]
        }
    }

    fn joint_axes(&mut self) -> Vec<[f64; 3]> {
        // PhysX rotates about the x axis of the child joint frame: world axis = R_child · R_childframe · x.
        let poses = self.world.link_poses();
        let frames = self.world.joint_child_frames();
        let mut out = vec![[f64::NAN; 3]; self.model.nj()];
        for (d, &j) in self.joint_of_dof.iter().enumerate() {
            let link = self.model.joints[j].child_link;
            if let (Some(p), Some(f)) = (poses.get(link), frames.get(d)) {
                out[j] = arr(&(quat_of(p) * quat_of(f) * Vector3::x()));
            }
        }
        out
    }

    fn joint_limits(&self) -> Vec<(f64, f64)> {
        let lim = self.world.joint_limits();
        let mut out = vec![(f64::NEG_INFINITY, f64::INFINITY); self.model.nj()];
        for (d, &j) in self.joint_of_dof.iter().enumerate() {
            if let Some(Some(l)) = lim.get(d) {
                out[j] = *l;
            }
        }
        out
    }

    fn generalized_acceleration(&mut self, f: &[f64]) -> Result<Vec<f64>, EngineError> {
        let nv = self.model.nv();
        if f.len() != nv || f.iter().any(|x| !x.is_finite()) {
            return Err(EngineError::Input(format!("expected {nv} finite generalized forces")));
        }
        let state = self.state();
        let (mut with_g, mut without_g) = match self.probe.take() {
            Some(p) => p,
            None => self.build_probes()?,
        };
        let result = (|| -> Result<Vec<f64>, EngineError> {
            // a(0): velocity terms, gravity and viscous damping (the explicit −d·q̇ the engine applies).
            let damping = self.dof_forces(&vec![0.0; self.model.nj()], &self.raw.dq);
            let a0 =
                self.probe_acceleration(&mut with_g, &state, &damping, &[0.0; 6], self.settings.acceleration_probe_dt)?;
            // M⁻¹f: the same configuration at rest, no gravity.
            let rest = State::at_rest(state.coords());
            let tau: Vec<f64> = self.joint_of_dof.iter().map(|&j| f[6 + j]).collect();
            let af = self.probe_acceleration(&mut without_g, &rest, &tau, &f[0..6], self.settings.force_probe_dt)?;
            Ok(a0.iter().zip(&af).map(|(a, b)| a + b).collect())
        })();
        self.probe = Some((with_g, without_g));
        result
    }

    fn mass_matrix(&mut self) -> Option<Vec<f64>> {
        let m = self.physx_mass_matrix().ok()?;
        let t = self.velocity_map();
        let mi = t.transpose() * m * &t;
        // nalgebra stores column-major: the transpose's storage is the row-major matrix.
        Some(mi.transpose().as_slice().to_vec())
    }
}

/// Tolerance of an oracle check for PhysX: its state is f32 ([`crate::precision::f32_state_tolerance`]).
pub fn f32_tolerance(check: &str, _f64_tolerance: f64) -> Option<f64> {
    crate::precision::f32_state_tolerance(check)
}

/// Checks PhysX cannot meet for a reason inside the engine (filled from measurements; see the reasons).
pub fn known_difference(_check: &str) -> Option<&'static str> {
    None
}
