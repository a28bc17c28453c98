//! DART 6.12 (Debian's `libdart6.12`) behind the [`Engine`] interface, through a small C++ layer
//! (`cpp/dart_glue.cpp`, FFI and its invariants in [`ffi`]).
//!
//! # Model
//! The skeleton is built from `robot-model`'s arrays, as gz-physics builds its models, not with DART's URDF
//! loader: one `BodyNode` per link (frame = link frame, full inertia tensor about the COM, no re-diagonalisation),
//! a `FreeJoint` root, one `RevoluteJoint` per joint (parent-to-joint transform = the model's joint origin,
//! child-to-joint = identity, so the joint frame is the child link frame), primitive collision shapes, and a
//! fixed ground plane z = 0 as a second skeleton. The URDF loader is used only in the tests, as an independent
//! route to the same mass matrix.
//!
//! # Coordinates (converted here, in safe code)
//! DART's free-joint coordinates are `[rotation vector, translation]` and its velocities
//! `[ω (pelvis frame), v (pelvis origin, pelvis frame)]`; the interface's are `[v_world, ω_pelvis]`. With `R`
//! the pelvis rotation: `v_dart = [ω_b, Rᵀ v_w]`, forces `f_dart = [M_b, Rᵀ F_w]` (power duality), and
//! accelerations `a_w = R (v̇_b + ω_b × v_b)`. Joint dofs are in link order in DART and in slot order here.
//!
//! # What DART 6.12 offers and what is done with it (verified on the installed library)
//! - **Joint limits** are off unless switched on (`Joint::Properties::mIsPositionLimitEnforced` defaults to
//!   false, and DART's URDF loader leaves it false too: tested). `CommonSettings::joint_limits` switches them on
//!   (`JointLimitConstraint`, velocity-level rows of the same LCP as contacts).
//! - **Viscous damping**: `setDampingCoefficient` per dof, applied *implicitly* inside DART's articulated-body
//!   algorithm (the projected articulated inertia gets `dt·d`, the force `−d·q̇`).
//! - **Coulomb joint friction**: `setCoulombFriction` per dof, a `JointCoulombFrictionConstraint` (an LCP row
//!   bounded by `friction·dt`), like MuJoCo's `frictionloss`.
//! - **Armature: DART 6.12 has none** (no `setArmature`, no rotor inertia in `Joint`/`DegreeOfFreedom`). The
//!   glue's `ArmatureRevoluteJoint` adds it where Featherstone's algorithm puts it: the joint's projected
//!   articulated inertia `SᵀIᴬS + a`, in both of DART's recursions (the smooth step's and the impulse step's),
//!   so contacts, limits and joint friction see it too. DART's `getMassMatrix` (composite-body route) does not
//!   go through that function; `a` is added to its joint diagonal here.
//!   (A first attempt carried armature as extra implicit damping `a/dt` with the force `(a/dt)·q̇` added back:
//!   exact for the smooth dynamics, but DART's impulse recursion uses the non-implicit inertia, so contacts saw
//!   the robot without armature and the standing robot sagged 4 cm in 0.2 s and fell. Kept as a warning.)
//! - **Collision detector: ODE** (`dart::collision::OdeCollisionDetector`, Debian `libdart-collision-ode6.12`),
//!   the detector gz-physics' dartsim plugin installs in every world; ODE's primitive colliders give the full
//!   box-plane contact patch (up to 4 points per foot). FCL (DART's own default) and DART's detector are
//!   selectable ([`DartCollisionDetector`]).
//! - **LCP solver: Dantzig** (`DantzigBoxedLcpSolver`, the pivoting boxed-LCP solver from ODE) with DART's PGS
//!   fallback when it fails: DART's and the dartsim plugin's default. Contacts are hard (velocity-level
//!   complementarity, 2 friction directions = friction pyramid; robot shapes and ground both carry the model's
//!   friction and restitution, so any combination rule gives the model's values), penetration is corrected by
//!   DART's error reduction (process-wide statics, defaults kept: ERP 0.01 capped at 1 mm/s).
//!
//! # Divergence
//! Debian builds DART with its assertions on, and DART asserts on any non-finite transform or inertia: a
//! simulation blowing up inside DART aborts the whole process instead of returning. The engine therefore keeps
//! DART away from non-finite numbers: it refuses states and forces beyond [`MAX_SPEED`], [`MAX_COORDINATE`] and
//! [`MAX_FORCE`] (typed input errors), and after every step it checks the state against the same bounds; once a
//! step leaves them the engine returns [`EngineError::Diverged`] and refuses to step until the next reset.
//! Measured on the H1-2 (an elbow driven at 5 N·m with limits off in zero gravity): joint speeds passed
//! 1e3 rad/s at 0.53 s and reached 1e91 rad/s nine steps later, growing at most ~quadratically per step, so a
//! state within the bounds cannot reach overflow in one step.
//!
//! # Reset
//! A reset rebuilds the whole DART world (skeletons, collision detector and its ODE geoms, LCP solvers): no
//! warm start, contact result or solver buffer survives it.

// The crate's only unsafe code for DART: the C ABI of cpp/dart_glue.cpp, invariants stated in the module.
#[allow(unsafe_code)]
pub mod ffi;

use crate::engine::{CommonSettings, Contact, Energy, Engine, EngineError, EngineKind, LinkPose, State};
use ffi::{LinkSpec, RawShape, RawState, RawWorldSettings, World};
use nalgebra::{DMatrix, DVector, Matrix3, Quaternion, UnitQuaternion, Vector3};
use robot_model::{RobotModel, Shape};
use serde::{Deserialize, Serialize};

/// Largest |velocity| component (m/s, rad/s) DART is stepped from: 30× the fastest H1-2 motor.
pub const MAX_SPEED: f64 = 1e3;
/// Largest |position| component (m) or |joint angle| (rad) DART is stepped from.
pub const MAX_COORDINATE: f64 = 1e4;
/// Largest |generalized force| component (N, N·m) handed to DART: 300× the strongest H1-2 motor.
pub const MAX_FORCE: f64 = 1e5;

/// DART's collision detectors available here.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DartCollisionDetector {
    /// ODE's primitive colliders (gz-physics' dartsim default).
    Ode,
    /// FCL (DART's own default).
    Fcl,
    /// DART's built-in detector (boxes and spheres only: capsules do not collide; the ground is a slab).
    Dart,
}

/// DART's boxed LCP solvers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DartLcpSolver {
    /// Dantzig pivoting (exact up to rounding; DART's and Gazebo's default).
    Dantzig,
    /// Projected Gauss-Seidel (iterative).
    Pgs,
}

/// Every DART-specific setting. Which of them matter for divergence: the detector decides how many contact
/// points a foot gets and where (ODE: the box-plane patch corners; FCL: fewer, jumpier points); the LCP
/// solver decides how exactly the complementarity conditions hold (Dantzig exact, PGS approximate after
/// `pgs_iterations`); the error-reduction parameters decide how fast penetration is pushed out (slowly:
/// DART's defaults let a foot that landed 2 mm deep rise at most 1 mm/s).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DartSettings {
    pub collision_detector: DartCollisionDetector,
    pub lcp_solver: DartLcpSolver,
    /// Use PGS when the primary solver fails (DART's default: on).
    pub pgs_fallback: bool,
    /// Maximum PGS sweeps (DART's default 30).
    pub pgs_iterations: u32,
    /// `CollisionOption::maxNumContacts` (DART's default 1000).
    pub max_contacts: u32,
    /// `ContactConstraint` statics (process-wide in DART; the first engine of a process sets them, a later
    /// engine asking for other values is refused). Defaults are DART's: penetration left uncorrected (m),
    pub contact_error_allowance: f64,
    /// fraction of the remaining penetration removed per step,
    pub contact_error_reduction: f64,
    /// cap on the correction velocity (m/s),
    pub contact_max_error_reduction_velocity: f64,
    /// and constraint force mixing (regularisation of the LCP diagonal).
    pub contact_constraint_force_mixing: f64,
}

impl Default for DartSettings {
    fn default() -> Self {
        DartSettings {
            collision_detector: DartCollisionDetector::Ode,
            lcp_solver: DartLcpSolver::Dantzig,
            pgs_fallback: true,
            pgs_iterations: 30,
            max_contacts: 1000,
            contact_error_allowance: 0.0,
            contact_error_reduction: 0.01,
            contact_max_error_reduction_velocity: 1e-3,
            contact_constraint_force_mixing: 1e-5,
        }
    }
}

/// The robot in DART.
#[derive(Debug)]
pub struct DartEngine {
    model: RobotModel,
    common: CommonSettings,
    settings: DartSettings,
    links: Vec<LinkSpec>,
    raw_settings: RawWorldSettings,
    world: World,
    /// DART dof index of each joint (slot order): `6 + child link − 1`.
    dof_of_joint: Vec<usize>,
    /// Armature of each joint (slot order; zeros when armature is off).
    armature: Vec<f64>,
    /// Set when a step left the bounds DART can be stepped from (see the module docs); cleared by reset.
    diverged: Option<String>,
    /// The base quaternion last reported (or reset to): DART keeps a rotation matrix, whose quaternion has
    /// either sign; the reported one is the one continuous with this (as an integrated quaternion would be).
    quat_ref: [f64; 4],
    /// External wrench on the pelvis (`[force; torque]`, world, at the pelvis origin), see
    /// [`Engine::set_base_wrench`]; cleared by reset.
    base_wrench: Option<[f64; 6]>,
}

/// Checks a DART state against the bounds within which a step cannot overflow (see the module docs).
fn within_bounds(r: &RawState) -> Result<(), String> {
    let pos = r.base_pose[0..3].iter().chain(&r.q);
    if let Some(x) = pos.into_iter().find(|x| !x.is_finite() || x.abs() > MAX_COORDINATE) {
        return Err(format!("coordinate {x} beyond ±{MAX_COORDINATE}"));
    }
    if let Some(v) = r.vel.iter().find(|v| !v.is_finite() || v.abs() > MAX_SPEED) {
        return Err(format!("speed {v} beyond ±{MAX_SPEED}"));
    }
    if r.base_pose[3..7].iter().any(|x| !x.is_finite()) {
        return Err("non-finite base orientation".into());
    }
    Ok(())
}

fn check_forces(f: &[f64]) -> Result<(), EngineError> {
    match f.iter().find(|x| !x.is_finite() || x.abs() > MAX_FORCE) {
        Some(x) => {
            Err(EngineError::Input(format!("generalized force {x} beyond ±{MAX_FORCE} (DART aborts on overflow)")))
        }
        None => Ok(()),
    }
}

fn shape_of(c: &robot_model::Collision) -> RawShape {
    let (kind, a, b, cc) = match c.shape {
        Shape::Box { half_extents: e } => (0, e[0], e[1], e[2]),
        Shape::Sphere { radius } => (1, radius, 0.0, 0.0),
        Shape::Capsule { radius, half_length } => (2, radius, half_length, 0.0),
        Shape::Cylinder { radius, half_length } => (3, radius, half_length, 0.0),
    };
    let t = c.origin.translation.vector;
    let r = c.origin.rotation;
    RawShape { kind, a, b, c: cc, pos: [t.x, t.y, t.z], quat: [r.w, r.i, r.j, r.k] }
}

/// The glue's link arrays for `model` under `common`.
fn link_specs(model: &RobotModel, common: &CommonSettings) -> Result<Vec<LinkSpec>, EngineError> {
    let mut out = Vec::with_capacity(model.links.len());
    for (li, link) in model.links.iter().enumerate() {
        let i = &link.inertial;
        let m = &i.inertia;
        let mut spec = LinkSpec {
            name: link.name.clone(),
            joint_name: String::new(),
            parent: link.parent_link,
            mass: i.mass,
            com: [i.com.x, i.com.y, i.com.z],
            inertia: [
                m[(0, 0)],
                m[(0, 1)],
                m[(0, 2)],
                m[(1, 0)],
                m[(1, 1)],
                m[(1, 2)],
                m[(2, 0)],
                m[(2, 1)],
                m[(2, 2)],
            ],
            joint_pos: [0.0; 3],
            joint_quat: [1.0, 0.0, 0.0, 0.0],
            axis: [0.0, 0.0, 1.0],
            lower: f64::NEG_INFINITY,
            upper: f64::INFINITY,
            armature: 0.0,
            damping: 0.0,
            coulomb_friction: 0.0,
            shapes: if common.collisions { link.collisions.iter().map(shape_of).collect() } else { Vec::new() },
        };
        if li == 0 {
            if link.parent_link.is_some() {
                return Err(EngineError::Build("link 0 is not the floating base".into()));
            }
        } else {
            let (Some(ji), Some(pl)) = (link.parent_joint, link.parent_link) else {
                return Err(EngineError::Build(format!("link {} has no parent joint", link.name)));
            };
            if pl >= li {
                return Err(EngineError::Build(format!("link {} precedes its parent", link.name)));
            }
            let j = &model.joints[ji];
            let t = j.origin.translation.vector;
            let r = j.origin.rotation;
            let a = j.axis.into_inner();
            spec.joint_name = j.name.clone();
            spec.joint_pos = [t.x, t.y, t.z];
            spec.joint_quat = [r.w, r.i, r.j, r.k];
            spec.axis = [a.x, a.y, a.z];
            spec.lower = j.lower;
            spec.upper = j.upper;
            spec.armature = if common.armature { j.armature } else { 0.0 };
            spec.damping = if common.joint_damping { j.damping } else { 0.0 };
            spec.coulomb_friction = if common.joint_friction { j.frictionloss } else { 0.0 };
        }
        out.push(spec);
    }
    Ok(out)
}

/// Interface state -> DART coordinates (`dof_of_joint`: DART dof of each joint, slot order).
fn to_raw(dof_of_joint: &[usize], nlinks: usize, s: &State) -> RawState {
    let r = quat(s.base_quat);
    let v_b = r.inverse() * Vector3::from(s.base_lin_vel);
    let mut q = vec![0.0; nlinks - 1];
    let mut vel = vec![0.0; 6 + nlinks - 1];
    vel[0..3].copy_from_slice(&s.base_ang_vel);
    vel[3..6].copy_from_slice(&[v_b.x, v_b.y, v_b.z]);
    for (ji, &d) in dof_of_joint.iter().enumerate() {
        q[d - 6] = s.q[ji];
        vel[d] = s.dq[ji];
    }
    let u = r.quaternion();
    RawState { base_pose: [s.base_pos[0], s.base_pos[1], s.base_pos[2], u.w, u.i, u.j, u.k], q, vel }
}

fn quat(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
}

impl DartEngine {
    /// Builds the engine at the model's standing pose, at rest.
    pub fn new(model: &RobotModel, common: &CommonSettings, settings: &DartSettings) -> Result<Self, EngineError> {
        if !(common.timestep.is_finite() && common.timestep > 0.0) {
            return Err(EngineError::Input(format!("timestep {} must be positive", common.timestep)));
        }
        if common.gravity.iter().any(|g| !g.is_finite()) {
            return Err(EngineError::Input("non-finite gravity".into()));
        }
        let links = link_specs(model, common)?;
        let raw_settings = RawWorldSettings {
            timestep: common.timestep,
            gravity: common.gravity,
            ground: i32::from(common.ground),
            limits: i32::from(common.joint_limits),
            self_collision: i32::from(common.collisions && model.contact.self_collision),
            friction: model.contact.friction,
            restitution: model.contact.restitution,
            collision_detector: match settings.collision_detector {
                DartCollisionDetector::Ode => 0,
                DartCollisionDetector::Fcl => 1,
                DartCollisionDetector::Dart => 2,
            },
            lcp_solver: match settings.lcp_solver {
                DartLcpSolver::Dantzig => 0,
                DartLcpSolver::Pgs => 1,
            },
            secondary_pgs: i32::from(settings.pgs_fallback),
            pgs_iterations: settings.pgs_iterations,
            max_contacts: settings.max_contacts,
            error_allowance: settings.contact_error_allowance,
            error_reduction: settings.contact_error_reduction,
            max_error_reduction_velocity: settings.contact_max_error_reduction_velocity,
            constraint_force_mixing: settings.contact_constraint_force_mixing,
        };
        let dof_of_joint: Vec<usize> = model.joints.iter().map(|j| 6 + j.child_link - 1).collect();
        let armature = model.joints.iter().map(|j| if common.armature { j.armature } else { 0.0 }).collect();
        let standing = State::standing(model);
        standing.validate(model)?;
        let raw = to_raw(&dof_of_joint, model.links.len(), &standing);
        within_bounds(&raw).map_err(EngineError::Input)?;
        let world = World::new(&links, &raw_settings, &raw).map_err(EngineError::Build)?;
        Ok(DartEngine {
            model: model.clone(),
            common: common.clone(),
            settings: settings.clone(),
            links,
            raw_settings,
            world,
            dof_of_joint,
            armature,
            diverged: None,
            quat_ref: standing.base_quat,
            base_wrench: None,
        })
    }

    /// DART's own state, read from the world.
    fn raw_state(&self) -> Result<RawState, EngineError> {
        self.world.state().map_err(EngineError::Diverged)
    }

    /// DART coordinates -> interface state.
    fn state_of_raw(&self, r: &RawState) -> State {
        let p = &r.base_pose;
        let rot = quat([p[3], p[4], p[5], p[6]]);
        let v_w = rot * Vector3::new(r.vel[3], r.vel[4], r.vel[5]);
        let q = [p[3], p[4], p[5], p[6]];
        let dot: f64 = q.iter().zip(&self.quat_ref).map(|(a, b)| a * b).sum();
        let base_quat = if dot < 0.0 { q.map(|x| -x) } else { q };
        State {
            base_pos: [p[0], p[1], p[2]],
            base_quat,
            q: self.dof_of_joint.iter().map(|&d| r.q[d - 6]).collect(),
            base_lin_vel: [v_w.x, v_w.y, v_w.z],
            base_ang_vel: [r.vel[0], r.vel[1], r.vel[2]],
            dq: self.dof_of_joint.iter().map(|&d| r.vel[d]).collect(),
        }
    }

    /// Generalized force in the interface's coordinates -> DART's.
    fn to_dart_forces(&self, f: &[f64], raw: &RawState) -> Vec<f64> {
        let p = &raw.base_pose;
        let rot = quat([p[3], p[4], p[5], p[6]]);
        let f_b = rot.inverse() * Vector3::new(f[0], f[1], f[2]);
        let mut out = vec![0.0; raw.vel.len()];
        out[0..3].copy_from_slice(&f[3..6]);
        out[3..6].copy_from_slice(&[f_b.x, f_b.y, f_b.z]);
        for (ji, &d) in self.dof_of_joint.iter().enumerate() {
            out[d] = f[6 + ji];
        }
        out
    }

    /// `T` with `v_dart = T v_interface` at the pelvis rotation of `raw`.
    fn velocity_map(&self, raw: &RawState) -> DMatrix<f64> {
        let nv = raw.vel.len();
        let p = &raw.base_pose;
        let rt = quat([p[3], p[4], p[5], p[6]]).inverse().to_rotation_matrix().into_inner();
        let mut t = DMatrix::zeros(nv, nv);
        for i in 0..3 {
            t[(i, 3 + i)] = 1.0;
            for k in 0..3 {
                t[(3 + i, k)] = rt[(i, k)];
            }
        }
        for (ji, &d) in self.dof_of_joint.iter().enumerate() {
            t[(d, 6 + ji)] = 1.0;
        }
        t
    }

    fn mass_matrix_checked(&mut self) -> Result<DMatrix<f64>, EngineError> {
        let raw = self.raw_state()?;
        let nv = raw.vel.len();
        let m = DMatrix::from_row_slice(nv, nv, &self.world.mass_matrix().map_err(EngineError::Diverged)?);
        let t = self.velocity_map(&raw);
        let mut out = t.transpose() * m * &t;
        for (ji, a) in self.armature.iter().enumerate() {
            out[(6 + ji, 6 + ji)] += a;
        }
        Ok(out)
    }

    fn bias_checked(&mut self) -> Result<DVector<f64>, EngineError> {
        let raw = self.raw_state()?;
        let nv = raw.vel.len();
        let m = DMatrix::from_row_slice(nv, nv, &self.world.mass_matrix().map_err(EngineError::Diverged)?);
        let b = DVector::from_vec(self.world.bias_forces().map_err(EngineError::Diverged)?);
        // v_dart's linear part is Rᵀ v_w, whose derivative at zero interface acceleration is −ω_b × v_b.
        let w = Vector3::new(raw.vel[0], raw.vel[1], raw.vel[2]);
        let v = Vector3::new(raw.vel[3], raw.vel[4], raw.vel[5]);
        let mut tdot_v = DVector::zeros(nv);
        let c = -w.cross(&v);
        for k in 0..3 {
            tdot_v[3 + k] = c[k];
        }
        let t = self.velocity_map(&raw);
        Ok(t.transpose() * (b + m * tdot_v))
    }

    fn check_len(&self, what: &str, x: &[f64], n: usize) -> Result<(), EngineError> {
        if x.len() != n || x.iter().any(|v| !v.is_finite()) {
            return Err(EngineError::Input(format!("{what}: expected {n} finite values, got {}", x.len())));
        }
        Ok(())
    }

    /// The DART world itself, in DART's coordinates (no conversion, no checks): for measuring the overhead of
    /// the `Engine` layer only. Stepping it past the bounds of the module docs can abort the process.
    pub fn raw_world(&mut self) -> &mut World {
        &mut self.world
    }

    /// DART's own `Skeleton::computePotentialEnergy`, which (DART 6.12) takes `−m g·p` at each body's frame
    /// origin `p`, not at its centre of mass; [`Engine::energy`] does not use it.
    pub fn dart_potential_energy(&self) -> f64 {
        self.world.energy().1
    }

    /// DART dof index of each joint (slot order).
    pub fn dof_of_joint(&self) -> &[usize] {
        &self.dof_of_joint
    }

    /// How many joints have DART's limit enforcement switched on (as built).
    pub fn limits_enforced(&self) -> usize {
        self.world.joint_limits().1
    }
}

impl Engine for DartEngine {
    fn name(&self) -> &'static str {
        EngineKind::Dart.name()
    }

    fn version(&self) -> String {
        ffi::version()
    }

    fn settings(&self) -> serde_json::Value {
        let p = ffi::constraint_params();
        serde_json::json!({
            "engine": self.name(),
            "version": self.version(),
            "common": self.common,
            "dart": self.settings,
            "precision": "f64",
            "model_source": "Skeleton built from robot-model arrays (FreeJoint root, RevoluteJoints, full inertia tensors, primitive shapes, ground plane skeleton); not DART's URDF loader",
            "formulation": "reduced coordinates, Featherstone articulated-body algorithm",
            "integrator": "semi-implicit Euler: ABA accelerations (joint damping implicit), velocity update, boxed-LCP impulses (contacts, limits, joint friction) detected at the step's start pose, then position update",
            "collision_filtering": "robot-ground only unless the model enables self-collision (then adjacent bodies excluded)",
            "contact_model": "hard contacts, velocity-level boxed LCP, 2 friction directions per point (pyramid); every shape and the ground carry the model's friction and restitution",
            "contact_params_in_force": {"error_allowance": p[0], "error_reduction": p[1], "max_error_reduction_velocity": p[2], "constraint_force_mixing": p[3]},
            "joint_limits": if self.common.joint_limits { "Joint::setLimitEnforcement(true): JointLimitConstraint rows in the LCP (DART's default is off)" } else { "off (DART's default)" },
            "joint_limit_params_in_force": {"error_allowance": p[4], "error_reduction": p[5], "max_error_reduction_velocity": p[6], "constraint_force_mixing": p[7]},
            "armature": "DART 6.12 has none: a RevoluteJoint subclass adds it to the projected articulated inertia (SᵀIᴬS + a) in both ABA recursions (smooth step and constraint impulses)",
            "joint_damping": "DegreeOfFreedom damping coefficient, implicit in DART's ABA",
            "joint_friction": "DegreeOfFreedom Coulomb friction: JointCoulombFrictionConstraint (LCP row bounded by friction·dt)",
            "velocity_limits": "none (DART's default ±inf)",
            "acceleration_method": "analytic: DART's articulated-body forward dynamics (Skeleton::computeForwardDynamics), armature as above",
            "mass_matrix": "Skeleton::getMassMatrix, plus armature on the joint diagonal",
            "energy": "Skeleton::computeKineticEnergy + ½ Σ armature·q̇²; potential −m g·Skeleton::getCOM (DART's computePotentialEnergy uses body frame origins, not COMs)",
            "reset": "rebuilds the DART world (skeletons, collision detector, LCP solvers)",
        })
    }

    fn common(&self) -> &CommonSettings {
        &self.common
    }

    fn reset(&mut self, state: &State) -> Result<(), EngineError> {
        state.validate(&self.model)?;
        let raw = to_raw(&self.dof_of_joint, self.model.links.len(), state);
        within_bounds(&raw).map_err(|e| EngineError::Input(format!("{e} (DART aborts on overflow)")))?;
        // The new world is built before the old one is dropped (see ffi: ODE stays initialised).
        let world = World::new(&self.links, &self.raw_settings, &raw).map_err(EngineError::Build)?;
        self.world = world;
        self.diverged = None;
        self.base_wrench = None;
        let n = state.base_quat.iter().map(|x| x * x).sum::<f64>().sqrt();
        self.quat_ref = state.base_quat.map(|x| x / n);
        Ok(())
    }

    fn set_base_wrench(&mut self, wrench: [f64; 6]) -> Result<(), EngineError> {
        check_forces(&wrench)?;
        self.base_wrench = Some(wrench);
        Ok(())
    }

    fn step(&mut self, tau: &[f64]) -> Result<(), EngineError> {
        self.check_len("joint torques", tau, self.model.nj())?;
        check_forces(tau)?;
        if let Some(why) = &self.diverged {
            return Err(EngineError::Diverged(format!("{why}; reset first")));
        }
        let raw = self.raw_state()?;
        let mut f = vec![0.0; 6];
        if let Some(w) = self.base_wrench {
            // The interface's base force is [F_world, M_pelvis] at the pelvis origin.
            let p = &raw.base_pose;
            let m_b = quat([p[3], p[4], p[5], p[6]]).inverse() * Vector3::new(w[3], w[4], w[5]);
            f[..3].copy_from_slice(&w[..3]);
            f[3..].copy_from_slice(m_b.as_slice());
        }
        f.extend_from_slice(tau);
        let forces = self.to_dart_forces(&f, &raw);
        self.world.step(&forces).map_err(EngineError::Diverged)?;
        let after = self.raw_state()?;
        if let Err(e) = within_bounds(&after) {
            let why = format!("state left DART's safe range at t = {}: {e}", self.world.time());
            self.diverged = Some(why.clone());
            return Err(EngineError::Diverged(why));
        }
        self.quat_ref = self.state_of_raw(&after).base_quat;
        Ok(())
    }

    fn state(&self) -> State {
        match self.world.state() {
            Ok(r) => self.state_of_raw(&r),
            Err(_) => {
                let nj = self.model.nj();
                State {
                    base_pos: [f64::NAN; 3],
                    base_quat: [f64::NAN; 4],
                    q: vec![f64::NAN; nj],
                    base_lin_vel: [f64::NAN; 3],
                    base_ang_vel: [f64::NAN; 3],
                    dq: vec![f64::NAN; nj],
                }
            }
        }
    }

    fn time(&self) -> f64 {
        self.world.time()
    }

    fn contacts(&self) -> Vec<Contact> {
        let name =
            |l: i32| -> String {
                usize::try_from(l)
                    .ok()
                    .and_then(|i| self.model.links.get(i))
                    .map(|l| l.name.clone())
                    .unwrap_or_else(|| if l == -1 { "ground".into() } else { "unknown".into() })
            };
        self.world
            .contacts()
            .into_iter()
            .map(|c| {
                // DART: normal from body 2 to body 1, force on body 1. Interface: normal from body_a to body_b,
                // the ground first. In both orientations the normal force is force · DART normal.
                let n = Vector3::from(c.normal);
                let normal_force = Vector3::from(c.force).dot(&n).max(0.0);
                let (a, b, normal) = if c.link1 == -1 { (c.link1, c.link2, -n) } else { (c.link2, c.link1, n) };
                Contact {
                    body_a: name(a),
                    body_b: name(b),
                    point: c.point,
                    normal: [normal.x, normal.y, normal.z],
                    normal_force,
                    depth: c.depth,
                }
            })
            .collect()
    }

    fn energy(&mut self) -> Energy {
        let (kinetic, _) = self.world.energy();
        // Not Skeleton::computePotentialEnergy: DART 6.12 evaluates each body's gravitational energy at its frame
        // origin instead of its centre of mass (see `dart_potential_energy`); −m g·com from DART's own COM.
        let (m, c, g) = (self.world.link_masses().iter().sum::<f64>(), self.world.com(), self.common.gravity);
        let potential = -m * (g[0] * c[0] + g[1] * c[1] + g[2] * c[2]);
        let arm = match self.raw_state() {
            Ok(r) => self.dof_of_joint.iter().zip(&self.armature).map(|(&d, a)| 0.5 * a * r.vel[d] * r.vel[d]).sum(),
            Err(_) => f64::NAN,
        };
        Energy { kinetic: kinetic + arm, potential }
    }

    fn link_masses(&self) -> Vec<f64> {
        self.world.link_masses()
    }

    fn link_poses(&mut self) -> Vec<LinkPose> {
        self.world
            .link_poses()
            .into_iter()
            .map(|p| LinkPose { pos: [p[0], p[1], p[2]], quat: [p[3], p[4], p[5], p[6]] })
            .collect()
    }

    fn com(&mut self) -> [f64; 3] {
        self.world.com()
    }

    fn joint_axes(&mut self) -> Vec<[f64; 3]> {
        let axes = self.world.joint_axes();
        self.dof_of_joint.iter().map(|&d| axes[d - 6]).collect()
    }

    fn joint_limits(&self) -> Vec<(f64, f64)> {
        let lim = self.world.joint_limits().0;
        self.dof_of_joint.iter().map(|&d| lim[d - 6]).collect()
    }

    fn generalized_acceleration(&mut self, f: &[f64]) -> Result<Vec<f64>, EngineError> {
        self.check_len("generalized force", f, self.model.nv())?;
        check_forces(f)?;
        if let Some(why) = &self.diverged {
            return Err(EngineError::Diverged(format!("{why}; reset first")));
        }
        let raw = self.raw_state()?;
        let forces = self.to_dart_forces(f, &raw);
        let a = self.world.forward_dynamics(&forces).map_err(EngineError::Diverged)?;
        let p = &raw.base_pose;
        let rot = quat([p[3], p[4], p[5], p[6]]);
        let w = Vector3::new(raw.vel[0], raw.vel[1], raw.vel[2]);
        let v = Vector3::new(raw.vel[3], raw.vel[4], raw.vel[5]);
        let a_w = rot * (Vector3::new(a[3], a[4], a[5]) + w.cross(&v));
        let mut out = vec![a_w.x, a_w.y, a_w.z, a[0], a[1], a[2]];
        out.extend(self.dof_of_joint.iter().map(|&d| a[d]));
        Ok(out)
    }

    fn mass_matrix(&mut self) -> Option<Vec<f64>> {
        let m = self.mass_matrix_checked().ok()?;
        let n = m.nrows();
        Some((0..n * n).map(|k| m[(k / n, k % n)]).collect())
    }

    fn bias_forces(&mut self) -> Option<Vec<f64>> {
        self.bias_checked().ok().map(|b| b.iter().copied().collect())
    }
}

/// Known engine differences of DART, with the measured figure and the reason (reported instead of failing).
pub fn known_difference(check: &str) -> Option<&'static str> {
    let _ = check;
    None
}

/// The rotation matrix of a `[w, x, y, z]` quaternion (used by tests converting DART-coordinate matrices).
pub fn rotation(q: [f64; 4]) -> Matrix3<f64> {
    quat(q).to_rotation_matrix().into_inner()
}
