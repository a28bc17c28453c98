//! The [`Engine`] interface: one robot in generalized coordinates, whatever the engine's own formulation.
//!
//! # Conventions (the only place they are stated)
//! - **Quaternions** are `[w, x, y, z]` and rotate base(pelvis)-frame vectors into the world frame.
//! - **Joint vectors** (`q`, `dq`, torques) have `model.nj()` entries in motor-slot order, i.e. the order of
//!   `robot_model::RobotModel::joints` (H1-2: 27 entries = slots 0..=26).
//! - **Base linear velocity** is the velocity of the pelvis ORIGIN (not its COM), in the WORLD frame.
//! - **Base angular velocity** is expressed in the PELVIS (body) frame.
//!   Together: `v = [lin_vel_world(3), ang_vel_body(3), dq(nj)]`, exactly MuJoCo's free-joint `qvel` layout,
//!   and `q = [pos(3), quat wxyz(4), q(nj)]` is MuJoCo's `qpos`. Engines that store body-COM velocities or
//!   world angular velocities (Rapier) convert inside `reset`/`state`.
//! - **Generalized forces** are the dual of `v`: `[force on the base (world, through the pelvis origin)(3),
//!   moment about the pelvis origin (pelvis frame)(3), joint torques(nj)]`.
//! - **Gravity** points along `CommonSettings::gravity` (default `[0, 0, -9.81]`); the ground plane is z = 0.
//! - **Link order** for poses and masses is `model.links` order (pelvis first, parents before children).
use robot_model::{GenCoords, RobotModel};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Errors from engines.
#[derive(Debug, Error)]
pub enum EngineError {
    #[error("engine {0} is not compiled into this build (its cargo feature is off, e.g. PhysX: `cargo build -p ulab --features physx`; this build has: {names})", names = EngineKind::available_names())]
    Unavailable(String),
    #[error("model cannot be built in the engine: {0}")]
    Build(String),
    #[error("bad input: {0}")]
    Input(String),
    #[error("simulation diverged: {0}")]
    Diverged(String),
    #[error("not supported by this engine: {0}")]
    Unsupported(String),
    #[error(transparent)]
    Model(#[from] robot_model::ModelError),
}

/// Engines known to the project. Every kind exists in every build; [`EngineKind::available`] lists the ones
/// whose cargo feature is compiled in (the others give [`EngineError::Unavailable`] from `make_engine`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EngineKind {
    /// MuJoCo (generalized coordinates, soft contacts), feature `mujoco`.
    Mujoco,
    /// Rapier reduced-coordinate multibody, feature `rapier`.
    RapierMultibody,
    /// Rapier rigid bodies held by impulse joints, feature `rapier`.
    RapierImpulse,
    /// Bullet's Featherstone `btMultiBody` in double precision, feature `bullet`.
    Bullet,
    /// DART (Featherstone articulated bodies, LCP contacts), feature `dart`.
    Dart,
    /// PhysX reduced-coordinate articulation (f32), feature `physx`.
    Physx,
    /// Newton's `SolverFeatherstone` (f32, Python server), feature `newton`.
    #[cfg(feature = "newton")]
    NewtonFeatherstone,
    /// Newton's experimental `SolverSteel`, feature `newton`.
    #[cfg(feature = "newton")]
    NewtonSteel,
    /// Newton's `SolverXPBD`: only when named (see [`EngineKind::EXPLICIT_ONLY`]).
    #[cfg(feature = "newton")]
    NewtonXpbd,
    /// Newton's `SolverSemiImplicit`: only when named.
    #[cfg(feature = "newton")]
    NewtonSemiImplicit,
    /// Newton's `SolverMuJoCo` (MuJoCo Warp): only when named.
    #[cfg(feature = "newton")]
    NewtonMujoco,
}

impl EngineKind {
    /// Every engine the project knows, compiled in or not: the default set of commands that run "every engine".
    /// The Newton kinds exist only with feature `newton` (a build without it lists exactly what it did before).
    #[cfg(not(feature = "newton"))]
    pub const ALL: [EngineKind; 6] = [
        EngineKind::Mujoco,
        EngineKind::RapierMultibody,
        EngineKind::RapierImpulse,
        EngineKind::Bullet,
        EngineKind::Dart,
        EngineKind::Physx,
    ];
    #[cfg(feature = "newton")]
    pub const ALL: [EngineKind; 8] = [
        EngineKind::Mujoco,
        EngineKind::RapierMultibody,
        EngineKind::RapierImpulse,
        EngineKind::Bullet,
        EngineKind::Dart,
        EngineKind::Physx,
        EngineKind::NewtonFeatherstone,
        EngineKind::NewtonSteel,
    ];
    /// Engines that run only when named (`--engines newton-xpbd`): never in a default list. Newton's XPBD and
    /// SemiImplicit diverge on this robot within 0.01 s with torques in `joint_f`; SolverMuJoCo would duplicate
    /// the MuJoCo engine in every campaign.
    #[cfg(not(feature = "newton"))]
    pub const EXPLICIT_ONLY: [EngineKind; 0] = [];
    #[cfg(feature = "newton")]
    pub const EXPLICIT_ONLY: [EngineKind; 3] =
        [EngineKind::NewtonXpbd, EngineKind::NewtonSemiImplicit, EngineKind::NewtonMujoco];
    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            EngineKind::Mujoco => "mujoco",
            EngineKind::RapierMultibody => "rapier_multibody",
            EngineKind::RapierImpulse => "rapier_impulse",
            EngineKind::Bullet => "bullet",
            EngineKind::Dart => "dart",
            EngineKind::Physx => "physx",
            #[cfg(feature = "newton")]
            EngineKind::NewtonFeatherstone => "newton_featherstone",
            #[cfg(feature = "newton")]
            EngineKind::NewtonSteel => "newton_steel",
            #[cfg(feature = "newton")]
            EngineKind::NewtonXpbd => "newton_xpbd",
            #[cfg(feature = "newton")]
            EngineKind::NewtonSemiImplicit => "newton_semi_implicit",
            #[cfg(feature = "newton")]
            EngineKind::NewtonMujoco => "newton_mujoco",
        }
    }
    /// Parses a command-line name (`rapier_multibody` and `rapier-multibody` alike).
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().chain(Self::EXPLICIT_ONLY).find(|k| k.name() == s || k.name().replace('_', "-") == s)
    }
    /// Parses an engine named by a user into one compiled into this build: an unknown name or an engine this build
    /// lacks is an error that lists the engines it has.
    pub fn parse_available(s: &str) -> Result<Self, EngineError> {
        let kind = Self::parse(s).ok_or_else(|| {
            EngineError::Input(format!("unknown engine {s:?} (this build has: {})", Self::available_names()))
        })?;
        if !kind.is_available() {
            return Err(EngineError::Unavailable(kind.name().to_string()));
        }
        Ok(kind)
    }
    /// Whether this build contains the engine (its cargo feature of `diff-physics` is on).
    pub fn is_available(self) -> bool {
        match self {
            EngineKind::Mujoco => cfg!(feature = "mujoco"),
            EngineKind::RapierMultibody | EngineKind::RapierImpulse => cfg!(feature = "rapier"),
            EngineKind::Bullet => cfg!(feature = "bullet"),
            EngineKind::Dart => cfg!(feature = "dart"),
            EngineKind::Physx => cfg!(feature = "physx"),
            #[cfg(feature = "newton")]
            EngineKind::NewtonFeatherstone
            | EngineKind::NewtonSteel
            | EngineKind::NewtonXpbd
            | EngineKind::NewtonSemiImplicit
            | EngineKind::NewtonMujoco => true,
        }
    }
    /// The engines compiled into this build, in [`EngineKind::ALL`] order: the default set of every command
    /// that runs "every engine".
    pub fn available() -> Vec<EngineKind> {
        Self::ALL.into_iter().filter(|k| k.is_available()).collect()
    }
    /// Comma-separated names of [`EngineKind::available`], for help texts and error messages.
    pub fn available_names() -> String {
        Self::available().iter().map(|k| k.name()).collect::<Vec<_>>().join(", ")
    }
}

/// Settings every engine honours; engine-specific ones (solver, iterations, margins, ...) live in each
/// engine's own settings struct, reported by [`Engine::settings`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CommonSettings {
    /// Physics timestep (s). Default 0.002 (Unitree's simulator and SDK loop rate).
    pub timestep: f64,
    /// World gravity (m/s²).
    pub gravity: [f64; 3],
    /// Ground plane z = 0 with the model's contact parameters.
    pub ground: bool,
    /// Robot collision shapes present (false: no contacts at all, also not with the ground).
    pub collisions: bool,
    /// Apply the model's joint armature (reflected rotor inertia).
    pub armature: bool,
    /// Apply the model's viscous joint damping.
    pub joint_damping: bool,
    /// Apply the model's dry joint friction (frictionloss).
    pub joint_friction: bool,
    /// Enforce joint range limits.
    pub joint_limits: bool,
}

impl Default for CommonSettings {
    /// The full robot: ground, collisions, armature, damping, friction, limits, dt = 2 ms, Earth gravity.
    fn default() -> Self {
        CommonSettings {
            timestep: 0.002,
            gravity: [0.0, 0.0, -robot_model::GRAVITY_EARTH],
            ground: true,
            collisions: true,
            armature: true,
            joint_damping: true,
            joint_friction: true,
            joint_limits: true,
        }
    }
}

impl CommonSettings {
    /// Pure rigid-body dynamics: no ground, no collisions, no armature/damping/friction/limits. This is the
    /// configuration in which engines must agree with the model crate's RNEA/CRBA reference.
    pub fn rigid_body_only() -> Self {
        CommonSettings {
            ground: false,
            collisions: false,
            armature: false,
            joint_damping: false,
            joint_friction: false,
            joint_limits: false,
            ..Self::default()
        }
    }
}

/// Full generalized state. See the module docs for frames and conventions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct State {
    /// Pelvis origin, world frame (m).
    pub base_pos: [f64; 3],
    /// Pelvis orientation `[w, x, y, z]`, pelvis-to-world.
    pub base_quat: [f64; 4],
    /// Joint angles (rad), slot order.
    pub q: Vec<f64>,
    /// Velocity of the pelvis origin, world frame (m/s).
    pub base_lin_vel: [f64; 3],
    /// Angular velocity of the pelvis, pelvis frame (rad/s).
    pub base_ang_vel: [f64; 3],
    /// Joint velocities (rad/s), slot order.
    pub dq: Vec<f64>,
}

impl State {
    /// At rest in the model's standing pose.
    pub fn standing(model: &RobotModel) -> Self {
        let g = GenCoords::standing(model);
        State::at_rest(g)
    }
    /// At rest at the given configuration.
    pub fn at_rest(g: GenCoords) -> Self {
        let nj = g.q.len();
        State {
            base_pos: g.base_pos,
            base_quat: g.base_quat,
            q: g.q,
            base_lin_vel: [0.0; 3],
            base_ang_vel: [0.0; 3],
            dq: vec![0.0; nj],
        }
    }
    /// Configuration part.
    pub fn coords(&self) -> GenCoords {
        GenCoords { base_pos: self.base_pos, base_quat: self.base_quat, q: self.q.clone() }
    }
    /// Generalized velocity `[lin_world, ang_body, dq]`.
    pub fn v(&self) -> Vec<f64> {
        let mut v = Vec::with_capacity(6 + self.dq.len());
        v.extend_from_slice(&self.base_lin_vel);
        v.extend_from_slice(&self.base_ang_vel);
        v.extend_from_slice(&self.dq);
        v
    }
    /// Generalized position `[pos, quat wxyz, q]` (MuJoCo `qpos` layout).
    pub fn qpos(&self) -> Vec<f64> {
        let mut q = Vec::with_capacity(7 + self.q.len());
        q.extend_from_slice(&self.base_pos);
        q.extend_from_slice(&self.base_quat);
        q.extend_from_slice(&self.q);
        q
    }
    /// Builds a state from `qpos` and `qvel` (MuJoCo layouts). Errors on wrong lengths.
    pub fn from_qpos_qvel(qpos: &[f64], qvel: &[f64]) -> Result<Self, EngineError> {
        if qpos.len() < 7 || qvel.len() < 6 || qpos.len() - 7 != qvel.len() - 6 {
            return Err(EngineError::Input(format!("qpos/qvel lengths {} / {} do not match", qpos.len(), qvel.len())));
        }
        let a3 = |s: &[f64]| [s[0], s[1], s[2]];
        Ok(State {
            base_pos: a3(&qpos[0..3]),
            base_quat: [qpos[3], qpos[4], qpos[5], qpos[6]],
            q: qpos[7..].to_vec(),
            base_lin_vel: a3(&qvel[0..3]),
            base_ang_vel: a3(&qvel[3..6]),
            dq: qvel[6..].to_vec(),
        })
    }
    /// Checks lengths against the model and finiteness; normalises nothing.
    pub fn validate(&self, model: &RobotModel) -> Result<(), EngineError> {
        let nj = model.nj();
        if self.q.len() != nj || self.dq.len() != nj {
            return Err(EngineError::Input(format!(
                "state has {} / {} joint entries, model has {nj}",
                self.q.len(),
                self.dq.len()
            )));
        }
        let all = self.qpos().into_iter().chain(self.v());
        if all.into_iter().any(|x| !x.is_finite()) {
            return Err(EngineError::Input("non-finite state entry".into()));
        }
        let n: f64 = self.base_quat.iter().map(|x| x * x).sum::<f64>().sqrt();
        if (n - 1.0).abs() > 1e-6 {
            return Err(EngineError::Input(format!("base quaternion norm {n} is not 1")));
        }
        Ok(())
    }
}

/// One contact between two bodies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Contact {
    /// Link name, or `"ground"`.
    pub body_a: String,
    /// Link name, or `"ground"`.
    pub body_b: String,
    /// Contact point, world frame (m).
    pub point: [f64; 3],
    /// Unit normal, world frame, pointing from `body_a` towards `body_b` (the direction of the normal force
    /// that `body_a` exerts on `body_b`). Engines put `"ground"` in `body_a` for robot-ground contacts, so the
    /// normal points up out of the floor.
    pub normal: [f64; 3],
    /// Normal force magnitude (N) over the last step (>= 0).
    pub normal_force: f64,
    /// Penetration depth (m, >= 0 when overlapping; negative = separated but within the margin).
    pub depth: f64,
}

/// Mechanical energy (J). Kinetic energy is `½ vᵀ M v` with the engine's mass matrix (it includes armature
/// when armature is enabled); potential energy is gravitational, `−m g·com`, zero at the world origin.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Energy {
    pub kinetic: f64,
    pub potential: f64,
}

impl Energy {
    pub fn total(&self) -> f64 {
        self.kinetic + self.potential
    }
}

/// World pose of a link frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinkPose {
    pub pos: [f64; 3],
    /// `[w, x, y, z]`, link-to-world.
    pub quat: [f64; 4],
}

/// A physics engine simulating one robot model.
///
/// Engines are built with `EngineType::new(model: &RobotModel, common: &CommonSettings, specific: &TheirSettings)`
/// and are then used through this trait. All vectors follow the conventions in the module docs.
pub trait Engine: std::fmt::Debug {
    /// Short engine name, e.g. `"mujoco"` (= [`EngineKind::name`]).
    fn name(&self) -> &'static str;
    /// Engine library and version, e.g. `"MuJoCo 3.17.0 via mujoco-rs 7.0.0"`.
    fn version(&self) -> String;
    /// Every setting in force (common + specific), as JSON for reports.
    fn settings(&self) -> serde_json::Value;
    /// The common settings the engine was built with.
    fn common(&self) -> &CommonSettings;

    /// A true reset: sets the exact state, zeroes time, clears warm starts, contact caches and any
    /// solver history, so that two resets to the same state followed by the same inputs give identical results.
    fn reset(&mut self, state: &State) -> Result<(), EngineError>;
    /// Advances one timestep with the given joint torques (slot order, N·m), applied as they are (no clamping:
    /// clamp with [`crate::pd`] beforehand).
    fn step(&mut self, tau: &[f64]) -> Result<(), EngineError>;
    /// An external wrench on the base link, applied at every following [`Engine::step`] until set again:
    /// `[force; torque]`, both in the world frame, the force acting at the base frame's origin (the pelvis link
    /// frame, not its centre of mass). It exists for holding the pelvis on a stand (the suspension rig of the gap
    /// diagnosis, [`crate::suspension`]) in any engine. A reset clears it. Engines without it return
    /// [`EngineError::Unsupported`].
    fn set_base_wrench(&mut self, wrench: [f64; 6]) -> Result<(), EngineError> {
        let _ = wrench;
        Err(EngineError::Unsupported(format!("{}: external base wrench", self.name())))
    }
    /// Current state.
    fn state(&self) -> State;
    /// Simulated time since the last reset (s).
    fn time(&self) -> f64;
    /// Active contacts after the last step (or after reset: contacts of the reset configuration if the engine
    /// computes them at reset, else empty).
    fn contacts(&self) -> Vec<Contact>;
    /// Mechanical energy of the current state.
    fn energy(&mut self) -> Energy;

    /// Mass of every link as built in the engine (`model.links` order).
    fn link_masses(&self) -> Vec<f64>;
    /// World pose of every link frame at the current state (`model.links` order).
    fn link_poses(&mut self) -> Vec<LinkPose>;
    /// World centre of mass of the whole robot at the current state.
    fn com(&mut self) -> [f64; 3];
    /// World-frame joint axes at the current state (slot order).
    fn joint_axes(&mut self) -> Vec<[f64; 3]>;
    /// Joint limits `(lower, upper)` as built in the engine (slot order).
    fn joint_limits(&self) -> Vec<(f64, f64)>;

    /// Contact-free generalized acceleration (nv, see module docs) at the current state under the full
    /// generalized force `f` (nv entries: base wrench + joint torques), with the engine's own dynamics
    /// (including armature and viscous damping as configured; excluding contacts, joint limits and dry
    /// friction, which are constraints in most engines). Must not
    /// change the state. Engines without an analytic route may reset-step-restore and finite-difference the
    /// velocity; they say so in [`Engine::settings`] under `"acceleration_method"`.
    fn generalized_acceleration(&mut self, f: &[f64]) -> Result<Vec<f64>, EngineError>;
    /// The engine's own joint-space mass matrix (nv × nv, row-major), if it exposes one.
    fn mass_matrix(&mut self) -> Option<Vec<f64>> {
        None
    }
    /// The engine's own bias forces `C(q,v) v + g(q)` (nv), if it exposes them.
    fn bias_forces(&mut self) -> Option<Vec<f64>> {
        None
    }
}

/// Rotation angle between two unit quaternions, from the relative rotation `conj(a)·b` with atan2 (exactly 0
/// for equal inputs; acos of the dot product would resolve only ~1e-8 rad).
pub fn quat_angle(a: [f64; 4], b: [f64; 4]) -> f64 {
    let [aw, ax, ay, az] = a;
    let [bw, bx, by, bz] = b;
    let w = aw * bw + ax * bx + ay * by + az * bz;
    let x = aw * bx - bw * ax - (ay * bz - az * by);
    let y = aw * by - bw * ay - (az * bx - ax * bz);
    let z = aw * bz - bw * az - (ax * by - ay * bx);
    2.0 * (x * x + y * y + z * z).sqrt().atan2(w.abs())
}

/// Principal frame of a symmetric inertia matrix: a proper rotation `R` (right-handed eigenvector basis, from
/// nalgebra's f64 symmetric eigen-solver) and the moments `λ` with `I = R diag(λ) Rᵀ`. Every engine that puts a
/// body frame on the principal axes (Rapier, Bullet, PhysX) takes it from here.
pub fn principal_frame(inertia: &nalgebra::Matrix3<f64>) -> (nalgebra::UnitQuaternion<f64>, [f64; 3]) {
    let sym = (inertia + inertia.transpose()) * 0.5;
    let eig = sym.symmetric_eigen();
    let mut vecs = eig.eigenvectors;
    let mut vals = eig.eigenvalues;
    if vecs.determinant() < 0.0 {
        vecs.swap_columns(1, 2);
        vals.swap_rows(1, 2);
    }
    let rot = nalgebra::UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(vecs));
    (rot, [vals[0], vals[1], vals[2]])
}
