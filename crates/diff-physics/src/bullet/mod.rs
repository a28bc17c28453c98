//! Bullet's Featherstone `btMultiBody` in double precision (Debian's `libbullet-dev` 3.24, `bullet-float64`),
//! the formulation of Gazebo's bullet-featherstone physics plugin, through a small C++ layer
//! (`cpp/bullet_glue.cpp`, FFI in [`ffi`]).
//!
//! # Why this source
//! Two Bullets exist on this machine's package indexes: Debian's `libbullet-dev` (C++ headers and
//! `*-float64` libraries) and the `pybullet` wheel (whose shared library exports the robotics C API). The
//! engine uses Debian's: `f64` like every other engine here (the wheel's robotics API is built single
//! precision), versioned and installed by the distribution, the very `btMultiBody` + `btMultiBodyDynamicsWorld`
//! that gz-physics' bullet-featherstone plugin drives, and no Python at build or run time. Like gz-physics, the
//! model is built from arrays (links, principal inertias, joint frames, limits, collision primitives) rather than
//! by a URDF importer, so Bullet sees exactly the numbers of `robot-model`.
//!
//! # Model translation
//! Bullet puts every body frame at the body's centre of mass along its principal inertia axes (the inertia is
//! a diagonal). Each link's inertia is diagonalised here (nalgebra, f64) and the link frame is recovered from the
//! body frame with that fixed transform. Joint angles are Bullet's (same sign as the model's: a positive angle
//! turns the child about its axis). Bullet's base velocity is the base COM velocity and the angular velocity,
//! both in the world frame; [`BulletEngine`] converts to the interface's conventions (see [`crate::engine`]).
//!
//! # Semantics that differ from the other engines, and what is done (verified on Bullet 3.24)
//! - Bullet's `btMultiBody` creates no joint motors: pybullet does (`createJointMotors`, a velocity motor with
//!   max impulse 1 per joint, to be zeroed before torque control). This engine creates none, so joint torques act
//!   alone (the contact-free accelerations match the model's RNEA, `tests/it/bullet_engine.rs`).
//! - `btMultibodyLink::m_jointDamping` / `m_jointFriction` are stored but unused by Bullet ("todo: implement this
//!   internally", btMultiBodyLink.h). Viscous damping is applied as the explicit torque `-d q̇` at the start of
//!   each step (pybullet does the same in its step). Explicit damping is stable only while `d·dt/I < 2` for each
//!   joint's effective inertia `I`: with the H1-2's armature (0.1 kg·m²) `d·dt/I` is at most 0.02, but a model
//!   with armature 0 puts the wrists (I ≈ 1e-4) near 20, and the robot diverges within 0.1 s (measured with an
//!   armature-0 sidecar: states of 1e28 m; finite with damping 0, and in DART, which damps implicitly). Dry
//!   friction is a velocity motor with target 0 whose impulse per step is bounded by `frictionloss · dt` (the
//!   remedy btMultiBodyLink.h names), solved with the contacts.
//! - `btMultiBody` clamps every generalized velocity to `m_maxCoordinateVelocity` = 100 (rad/s and m/s) whenever
//!   constraint impulses are applied; set to 1e30 here (no clamp, as in the other engines).
//! - `btMultiBody` damps every body's velocity by default (`m_linearDamping` = `m_angularDamping` = 0.04, a
//!   force `m (k + k|v|) v` per body); set to 0 here.
//! - Armature (reflected rotor inertia) does not exist in Bullet. It is approximated by adding
//!   `armature · a aᵀ` to the child link's rotational inertia about the joint axis `a`: the joint's own diagonal
//!   entry of the mass matrix is exact, but the rotor also turns with the parent's rotation (measured differences:
//!   [`known_difference`]).
use crate::engine::*;
use nalgebra::{Isometry3, Matrix3, Quaternion, Translation3, UnitQuaternion, Vector3};
use robot_model::{RobotModel, Shape};
use serde::{Deserialize, Serialize};

pub mod ffi;

/// What the ground is made of in Bullet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BulletGround {
    /// `btStaticPlaneShape` z = 0 (what gz-physics builds for an SDF plane). Convex-plane collision reports one
    /// new point per step (the deepest vertex); the persistent manifold accumulates up to 4 over steps.
    Plane,
    /// A 2 km × 2 km × 2 m `btBoxShape` whose top face is z = 0: box-box contacts come from Bullet's
    /// `btBoxBoxDetector` (face clipping, up to 4 points at once), other shapes from GJK/EPA.
    Box,
}

/// Every Bullet-specific setting; all of them are passed to Bullet explicitly and written into reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BulletSettings {
    /// Ground geometry.
    pub ground: BulletGround,
    /// Sequential-impulse (projected Gauss-Seidel) sweeps per step over contacts, limits and friction motors
    /// (`btContactSolverInfo::m_numIterations`; Bullet 10, gz-physics 50).
    pub solver_iterations: u32,
    /// Baumgarte error reduction of contact penetration per step (`m_erp2`; Bullet 0.2, gz-physics 0.02 to
    /// avoid the large impulses of deep penetrations). Multibody contacts have no split impulse in Bullet 3.24,
    /// so this velocity bias is the only penetration recovery.
    pub contact_erp: f64,
    /// Error reduction of joint-limit violations (`m_erp`, Bullet default 0.2).
    pub joint_limit_erp: f64,
    /// Constraint force mixing of contacts (`m_globalCfm`, 0 = hard contacts).
    pub global_cfm: f64,
    /// Error reduction of friction anchors (`m_frictionERP`, Bullet default 0.2).
    pub friction_erp: f64,
    /// Warm start rigid-body constraints from the previous step's impulses (`SOLVER_USE_WARMSTARTING`, on in
    /// Bullet; multibody contacts are warm-started only with `SOLVER_USE_ARTICULATED_WARMSTARTING`, off). Every
    /// reset rebuilds the world, so nothing carries over a reset.
    pub warmstarting: bool,
    pub warmstarting_factor: f64,
    /// Convex margin (m) of boxes and cylinders. Bullet's default 0.04 m exceeds the H1-2 sole's half height
    /// (0.0375 m), which would leave a negative inner box; spheres and capsules use their radius.
    pub collision_margin_m: f64,
    /// Clamp of every generalized velocity when impulses are applied (Bullet default 100; 1e30 = off).
    pub max_coordinate_velocity: f64,
    /// Largest impulse (N·s) a joint-limit constraint may apply per step (Bullet default 100 N·s, i.e.
    /// 50 kN·m at 2 ms; 1e30 = unbounded like the other engines' limits).
    pub joint_limit_max_impulse: f64,
    /// Gyroscopic term `ω × Iω` of every body (`setUseGyroTerm`, on by default).
    pub gyroscopic: bool,
    /// Rolling and torsional contact friction from the model's contact parameters (`setRollingFriction`,
    /// `setSpinningFriction`). Off: sliding friction only, like MuJoCo's condim 3 and Rapier.
    pub rolling_friction: bool,
    /// Two friction directions per contact point (`SOLVER_USE_2_FRICTION_DIRECTIONS`), solved as one implicit
    /// (elliptic) cone. Off (Bullet's default) there is a single friction row along the sliding velocity of the
    /// moment, so a foot at rest creeps sideways (measured: 11 cm in 0.8 s of PD standing).
    pub two_friction_directions: bool,
}

impl Default for BulletSettings {
    fn default() -> Self {
        BulletSettings {
            ground: BulletGround::Plane,
            solver_iterations: 50,
            contact_erp: 0.02,
            joint_limit_erp: 0.2,
            global_cfm: 0.0,
            friction_erp: 0.2,
            warmstarting: true,
            warmstarting_factor: 0.85,
            collision_margin_m: 0.001,
            max_coordinate_velocity: 1e30,
            joint_limit_max_impulse: 1e30,
            gyroscopic: true,
            rolling_friction: false,
            two_friction_directions: true,
        }
    }
}

/// Bullet's `btSolverMode` bits used here (btContactSolverInfo.h).
const SOLVER_USE_WARMSTARTING: i32 = 4;
const SOLVER_USE_2_FRICTION_DIRECTIONS: i32 = 16;
const SOLVER_SIMD: i32 = 256;

/// Reasons for documented differences of this engine in `ulab model check`, with their measured figures.
pub fn known_difference(check: &str) -> Option<&'static str> {
    match check {
        "accelerations under random (q,v,tau) (with armature)" | "mass matrix from accelerations (with armature)" => {
            Some(
                "Bullet has no armature: it is approximated by armature·a·aᵀ rotor inertia on the child link, which \
                 also couples to every ancestor rotation",
            )
        }
        "kinetic energy at reset" => Some(
            "the armature approximation's rotor inertia spins with the child link's absolute angular velocity, not \
             the joint's relative one, so ½vᵀMv differs",
        ),
        _ => None,
    }
}

/// The Bullet frame of one link: body frame (COM, principal axes) in the link frame.
#[derive(Debug, Clone, Copy)]
struct BodyFrame {
    com: Vector3<f64>,
    rot: UnitQuaternion<f64>,
}

impl BodyFrame {
    fn iso(&self) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::from(self.com), self.rot)
    }
}

fn xyzw(q: &UnitQuaternion<f64>) -> [f64; 4] {
    [q.i, q.j, q.k, q.w]
}
fn from_xyzw(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]))
}
fn arr(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// The H1-2 (or any tree model) in Bullet.
#[derive(Debug)]
pub struct BulletEngine {
    model: RobotModel,
    common: CommonSettings,
    settings: BulletSettings,
    sim: ffi::Sim,
    /// Body frame of every link in its link frame (`model.links` order; Bullet body `i` = model link `i`).
    frames: Vec<BodyFrame>,
    /// Joint axis of every link in its body frame (index = link; unused for the base).
    body_axes: Vec<Vector3<f64>>,
    /// Bullet body (= model link) of every joint, slot order.
    joint_body: Vec<usize>,
    /// Viscous damping per Bullet link (0 when disabled), applied as explicit torques.
    damping: Vec<f64>,
    time: f64,
    /// External wrench on the pelvis (`[force; torque]`, world, at the pelvis origin), see
    /// [`Engine::set_base_wrench`]; cleared by reset.
    base_wrench: Option<[f64; 6]>,
}

impl BulletEngine {
    /// Builds the engine at the model's standing pose.
    pub fn new(model: &RobotModel, common: &CommonSettings, settings: &BulletSettings) -> Result<Self, EngineError> {
        if !(common.timestep.is_finite() && common.timestep > 0.0) {
            return Err(EngineError::Input(format!("timestep {} must be positive", common.timestep)));
        }
        let nl = model.links.len();
        if nl < 1 || model.nj() != nl - 1 {
            return Err(EngineError::Build(format!(
                "Bullet needs one revolute joint per link besides the base ({} links, {} joints)",
                nl,
                model.nj()
            )));
        }
        // Extra rotational inertia of the armature approximation, in each child link frame.
        let mut extra = vec![Matrix3::zeros(); nl];
        if common.armature {
            for j in &model.joints {
                let a = j.axis.into_inner();
                extra[j.child_link] += j.armature * a * a.transpose();
            }
        }
        let mut frames = Vec::with_capacity(nl);
        let mut moments = Vec::with_capacity(nl);
        for (li, l) in model.links.iter().enumerate() {
            let (rot, m) = principal_frame(&(l.inertial.inertia + extra[li]));
            if !(l.inertial.mass > 0.0) || m.iter().any(|x| !(*x > 0.0)) {
                return Err(EngineError::Build(format!(
                    "link {} has mass {} and principal inertia {m:?}: Bullet needs both positive",
                    l.name, l.inertial.mass
                )));
            }
            frames.push(BodyFrame { com: l.inertial.com, rot });
            moments.push(m);
        }
        let mut bodies = vec![ffi::UbtBody::default(); nl];
        bodies[0] =
            ffi::UbtBody { parent: -1, mass: model.links[0].inertial.mass, inertia: moments[0], ..Default::default() };
        let mut body_axes = vec![Vector3::zeros(); nl];
        let mut damping = vec![0.0; nl - 1];
        let mut joint_body = vec![0usize; model.nj()];
        for (li, l) in model.links.iter().enumerate().skip(1) {
            let (Some(ji), Some(pl)) = (l.parent_joint, l.parent_link) else {
                return Err(EngineError::Build(format!("link {} has no parent joint", l.name)));
            };
            if pl >= li {
                return Err(EngineError::Build(format!("link {} comes before its parent", l.name)));
            }
            let j = &model.joints[ji];
            let (fp, fc) = (frames[pl], frames[li]);
            // Child body orientation in the parent link frame at q = 0, and the parent body's.
            let rc = j.origin.rotation * fc.rot;
            let rot_parent_to_this = rc.inverse() * fp.rot;
            let axis = fc.rot.inverse() * j.axis.into_inner();
            body_axes[li] = axis;
            joint_body[ji] = li;
            if common.joint_damping {
                damping[li - 1] = j.damping;
            }
            bodies[li] = ffi::UbtBody {
                parent: i32::try_from(pl).map_err(|_| EngineError::Build("too many links".into()))?,
                reserved: 0,
                mass: l.inertial.mass,
                inertia: moments[li],
                rot_parent_to_this: xyzw(&rot_parent_to_this),
                axis: arr(&axis),
                parent_com_to_pivot: arr(&(fp.rot.inverse() * (j.origin.translation.vector - fp.com))),
                pivot_to_com: arr(&(fc.rot.inverse() * fc.com)),
                lower: j.lower,
                upper: j.upper,
                friction_torque: if common.joint_friction { j.frictionloss } else { 0.0 },
            };
        }
        let mut shapes = Vec::new();
        for (li, l) in model.links.iter().enumerate() {
            for col in &l.collisions {
                let pose = frames[li].iso().inverse() * col.origin;
                let (kind, dims) = match col.shape {
                    Shape::Box { half_extents } => (0, half_extents),
                    Shape::Sphere { radius } => (1, [radius, 0.0, 0.0]),
                    Shape::Capsule { radius, half_length } => (2, [radius, half_length, 0.0]),
                    Shape::Cylinder { radius, half_length } => (3, [radius, half_length, 0.0]),
                };
                shapes.push(ffi::UbtShape {
                    body: li as i32,
                    kind,
                    dims,
                    pos: arr(&pose.translation.vector),
                    quat: xyzw(&pose.rotation),
                });
            }
        }
        let c = &model.contact;
        let cfg = ffi::UbtConfig {
            timestep: common.timestep,
            gravity: common.gravity,
            ground: match (common.ground, settings.ground) {
                (false, _) => 0,
                (true, BulletGround::Plane) => 1,
                (true, BulletGround::Box) => 2,
            },
            collisions: i32::from(common.collisions),
            joint_limits: i32::from(common.joint_limits),
            self_collision: i32::from(c.self_collision),
            solver_iterations: i32::try_from(settings.solver_iterations.max(1)).unwrap_or(i32::MAX),
            gyroscopic: i32::from(settings.gyroscopic),
            friction: c.friction,
            restitution: c.restitution,
            rolling_friction: if settings.rolling_friction { c.rolling_friction } else { 0.0 },
            spinning_friction: if settings.rolling_friction { c.torsional_friction } else { 0.0 },
            erp: settings.joint_limit_erp,
            erp2: settings.contact_erp,
            global_cfm: settings.global_cfm,
            friction_erp: settings.friction_erp,
            warmstarting_factor: settings.warmstarting_factor,
            articulated_warmstarting_factor: settings.warmstarting_factor,
            solver_mode: SOLVER_SIMD
                | if settings.warmstarting { SOLVER_USE_WARMSTARTING } else { 0 }
                | if settings.two_friction_directions { SOLVER_USE_2_FRICTION_DIRECTIONS } else { 0 },
            reserved: 0,
            collision_margin: settings.collision_margin_m,
            max_coordinate_velocity: settings.max_coordinate_velocity,
            joint_limit_max_impulse: settings.joint_limit_max_impulse,
            linear_damping: 0.0,
            angular_damping: 0.0,
        };
        let sim = ffi::Sim::new(&cfg, &bodies, &shapes).map_err(EngineError::Build)?;
        let mut e = BulletEngine {
            model: model.clone(),
            common: common.clone(),
            settings: settings.clone(),
            sim,
            frames,
            body_axes,
            joint_body,
            damping,
            time: 0.0,
            base_wrench: None,
        };
        e.reset(&State::standing(model))?;
        Ok(e)
    }

    /// Joint positions and velocities in Bullet's link order, straight from the multibody (no conversion). With
    /// [`BulletEngine::joint_of_link`] and [`BulletEngine::step_raw`]: the loop the `Engine` layer's overhead is
    /// measured against.
    pub fn raw_joint_state(&self) -> (Vec<f64>, Vec<f64>) {
        let (_, q, qd) = self.sim.state();
        (q, qd)
    }

    /// Slot index of the joint of every Bullet link (link order, base excluded).
    pub fn joint_of_link(&self) -> Vec<usize> {
        let mut out = vec![0; self.joint_body.len()];
        for (ji, &b) in self.joint_body.iter().enumerate() {
            out[b - 1] = ji;
        }
        out
    }

    /// One bare Bullet step with the given per-link torques (no state conversion, no damping).
    pub fn step_raw(&mut self, tau_links: &[f64]) -> Result<(), EngineError> {
        self.sim.step(tau_links, None).map_err(EngineError::Diverged)?;
        self.time += self.common.timestep;
        Ok(())
    }

    /// Joint torques in Bullet link order from slot-order torques, plus explicit viscous damping.
    fn link_torques(&self, tau: &[f64], dq_links: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.sim.nlinks()];
        for (ji, &t) in tau.iter().enumerate() {
            out[self.joint_body[ji] - 1] = t;
        }
        for (k, o) in out.iter_mut().enumerate() {
            *o -= self.damping[k] * dq_links[k];
        }
        out
    }

    /// Link-frame world poses from Bullet's body poses.
    fn link_isos(&mut self) -> Vec<Isometry3<f64>> {
        self.sim
            .body_poses()
            .iter()
            .zip(&self.frames)
            .map(|((p, q), f)| {
                Isometry3::from_parts(Translation3::new(p[0], p[1], p[2]), from_xyzw(*q)) * f.iso().inverse()
            })
            .collect()
    }

    fn check_tau(&self, tau: &[f64]) -> Result<(), EngineError> {
        if tau.len() != self.model.nj() {
            return Err(EngineError::Input(format!("expected {} joint torques, got {}", self.model.nj(), tau.len())));
        }
        if tau.iter().any(|t| !t.is_finite()) {
            return Err(EngineError::Input("non-finite joint torque".into()));
        }
        Ok(())
    }
}

impl Engine for BulletEngine {
    fn name(&self) -> &'static str {
        EngineKind::Bullet.name()
    }

    fn version(&self) -> String {
        let v = ffi::version();
        format!(
            "Bullet {}.{:02} btMultiBody (Featherstone), double precision (Debian libbullet-dev, bullet-float64)",
            v / 100,
            v % 100
        )
    }

    fn settings(&self) -> serde_json::Value {
        serde_json::json!({
            "engine": self.name(),
            "version": self.version(),
            "common": self.common,
            "bullet": self.settings,
            "precision": "f64 (BT_USE_DOUBLE_PRECISION)",
            "formulation": "reduced coordinates: btMultiBody (floating base) in btMultiBodyDynamicsWorld, btMultiBodyConstraintSolver",
            "model_source": "built from robot-model arrays (principal inertia frames, joint frames), no URDF importer",
            "integrator": "semi-implicit Euler: articulated-body accelerations, constraint impulses, then positions",
            "joint_torques": "btMultiBody::addJointTorque before each step",
            "armature": "approximated: armature·a·aᵀ added to the child link's rotational inertia",
            "joint_damping": "explicit torque -d·q̇ at the start of each step",
            "joint_friction": "btMultiBodyJointMotor, target velocity 0, max impulse frictionloss·dt",
            "joint_limits": "btMultiBodyJointLimitConstraint per joint (unilateral, Baumgarte joint_limit_erp)",
            "joint_motors": "none (pybullet's default velocity motors are not created)",
            "body_damping": "btMultiBody linear/angular damping 0 (Bullet default 0.04)",
            "contact_friction": "Coulomb, two directions per point; combined friction = robot × ground with ground 1",
            "contact_filtering": "collision groups: robot shapes touch the ground only unless the model enables self-collision",
            "reset": "the whole Bullet world is rebuilt (no manifold, warm start or broadphase history survives)",
            "acceleration_method": "analytic: Bullet's articulated-body algorithm (computeAccelerationsArticulatedBodyAlgorithmMultiDof, dt = 0) at the current state",
            "energy": "kinetic from Bullet's body velocities and inertias (compTreeLinkVelocities), potential -Σ m g·com",
        })
    }

    fn common(&self) -> &CommonSettings {
        &self.common
    }

    fn reset(&mut self, s: &State) -> Result<(), EngineError> {
        s.validate(&self.model)?;
        let rot = UnitQuaternion::from_quaternion(Quaternion::new(
            s.base_quat[0],
            s.base_quat[1],
            s.base_quat[2],
            s.base_quat[3],
        ));
        let f0 = self.frames[0];
        let r_com = rot * f0.com;
        let w_world = rot * Vector3::from(s.base_ang_vel);
        let base = ffi::UbtBaseState {
            pos: arr(&(Vector3::from(s.base_pos) + r_com)),
            quat: xyzw(&(rot * f0.rot)),
            lin_vel: arr(&(Vector3::from(s.base_lin_vel) + w_world.cross(&r_com))),
            ang_vel: arr(&w_world),
        };
        let mut q = vec![0.0; self.sim.nlinks()];
        let mut qd = vec![0.0; self.sim.nlinks()];
        for (ji, &b) in self.joint_body.iter().enumerate() {
            q[b - 1] = s.q[ji];
            qd[b - 1] = s.dq[ji];
        }
        self.sim.reset(&base, &q, &qd).map_err(EngineError::Build)?;
        self.time = 0.0;
        self.base_wrench = None;
        Ok(())
    }

    fn set_base_wrench(&mut self, wrench: [f64; 6]) -> Result<(), EngineError> {
        if wrench.iter().any(|x| !x.is_finite()) {
            return Err(EngineError::Input(format!("non-finite base wrench {wrench:?}")));
        }
        self.base_wrench = Some(wrench);
        Ok(())
    }

    fn step(&mut self, tau: &[f64]) -> Result<(), EngineError> {
        self.check_tau(tau)?;
        let (b, _, qd) = self.sim.state();
        let t = self.link_torques(tau, &qd);
        let base = self.base_wrench.map(|w| {
            // Bullet's base force acts through the base COM: add the moment of the force applied at the origin.
            let f0 = self.frames[0];
            let r_com = from_xyzw(b.quat) * f0.rot.inverse() * f0.com;
            let f = Vector3::new(w[0], w[1], w[2]);
            let t = Vector3::new(w[3], w[4], w[5]) + (-r_com).cross(&f);
            ([w[0], w[1], w[2]], arr(&t))
        });
        self.sim.step(&t, base).map_err(EngineError::Diverged)?;
        self.time += self.common.timestep;
        let (b, q, qd) = self.sim.state();
        let finite =
            b.pos.iter().chain(&b.quat).chain(&b.lin_vel).chain(&b.ang_vel).chain(&q).chain(&qd).all(|x| x.is_finite());
        if !finite {
            return Err(EngineError::Diverged(format!("non-finite state at t = {}", self.time)));
        }
        Ok(())
    }

    fn state(&self) -> State {
        let (b, q, qd) = self.sim.state();
        let f0 = self.frames[0];
        let rot_body = from_xyzw(b.quat);
        let rot = rot_body * f0.rot.inverse();
        let r_com = rot * f0.com;
        let w_world = Vector3::from(b.ang_vel);
        let nj = self.model.nj();
        let mut st = State {
            base_pos: arr(&(Vector3::from(b.pos) - r_com)),
            base_quat: [rot.w, rot.i, rot.j, rot.k],
            q: vec![0.0; nj],
            base_lin_vel: arr(&(Vector3::from(b.lin_vel) - w_world.cross(&r_com))),
            base_ang_vel: arr(&(rot.inverse() * w_world)),
            dq: vec![0.0; nj],
        };
        for (ji, &body) in self.joint_body.iter().enumerate() {
            st.q[ji] = q[body - 1];
            st.dq[ji] = qd[body - 1];
        }
        st
    }

    fn time(&self) -> f64 {
        self.time
    }

    fn contacts(&self) -> Vec<Contact> {
        let dt = self.common.timestep;
        let name = |u: i32| -> String {
            usize::try_from(u)
                .ok()
                .and_then(|i| self.model.links.get(i))
                .map(|l| l.name.clone())
                .unwrap_or_else(|| "ground".into())
        };
        let mut out = Vec::new();
        for c in self.sim.contacts() {
            if c.distance > 0.0 && c.impulse <= 0.0 {
                continue; // within the breaking threshold but not touching and not pushed on
            }
            let n = Vector3::from(c.normal_on_b);
            // normal_on_b points from b towards a. Put the ground first so the normal points up out of it.
            let (a, b, normal) = if c.user_a < 0 && c.user_b >= 0 {
                (name(c.user_a), name(c.user_b), -n)
            } else {
                (name(c.user_b), name(c.user_a), n)
            };
            let mid = (Vector3::from(c.point_a) + Vector3::from(c.point_b)) * 0.5;
            out.push(Contact {
                body_a: a,
                body_b: b,
                point: arr(&mid),
                normal: arr(&normal),
                normal_force: c.impulse.max(0.0) / dt,
                depth: -c.distance,
            });
        }
        out
    }

    fn energy(&mut self) -> Energy {
        let kinetic = self.sim.kinetic_energy();
        let masses = self.sim.masses();
        let g = Vector3::from(self.common.gravity);
        let potential =
            self.sim.body_poses().iter().zip(&masses).map(|((p, _), m)| -m * g.dot(&Vector3::from(*p))).sum();
        Energy { kinetic, potential }
    }

    fn link_masses(&self) -> Vec<f64> {
        self.sim.masses()
    }

    fn link_poses(&mut self) -> Vec<LinkPose> {
        self.link_isos()
            .iter()
            .map(|p| LinkPose {
                pos: arr(&p.translation.vector),
                quat: [p.rotation.w, p.rotation.i, p.rotation.j, p.rotation.k],
            })
            .collect()
    }

    fn com(&mut self) -> [f64; 3] {
        let masses = self.sim.masses();
        let total: f64 = masses.iter().sum();
        let c: Vector3<f64> = self.sim.body_poses().iter().zip(&masses).map(|((p, _), m)| Vector3::from(*p) * *m).sum();
        arr(&(c / total))
    }

    fn joint_axes(&mut self) -> Vec<[f64; 3]> {
        let poses = self.sim.body_poses();
        self.joint_body.iter().map(|&b| arr(&(from_xyzw(poses[b].1) * self.body_axes[b]))).collect()
    }

    fn joint_limits(&self) -> Vec<(f64, f64)> {
        let built = self.sim.joint_limits();
        self.joint_body
            .iter()
            .map(|&b| built.as_ref().map(|l| l[b - 1]).unwrap_or((f64::NEG_INFINITY, f64::INFINITY)))
            .collect()
    }

    fn generalized_acceleration(&mut self, f: &[f64]) -> Result<Vec<f64>, EngineError> {
        let nv = self.model.nv();
        if f.len() != nv || f.iter().any(|x| !x.is_finite()) {
            return Err(EngineError::Input(format!("expected {nv} finite generalized forces")));
        }
        let st = self.state();
        let (_, _, qd) = self.sim.state();
        let tau = self.link_torques(&f[6..], &qd);
        let rot = UnitQuaternion::from_quaternion(Quaternion::new(
            st.base_quat[0],
            st.base_quat[1],
            st.base_quat[2],
            st.base_quat[3],
        ));
        let r_com = rot * self.frames[0].com;
        // Force through the pelvis origin (world) and moment about it (pelvis frame) -> force and torque at the COM.
        let force = Vector3::new(f[0], f[1], f[2]);
        let torque = rot * Vector3::new(f[3], f[4], f[5]) + (-r_com).cross(&force);
        let a = self.sim.accelerations(&tau, arr(&force), arr(&torque)).map_err(EngineError::Diverged)?;
        let w_dot = Vector3::new(a[0], a[1], a[2]);
        let vc_dot = Vector3::new(a[3], a[4], a[5]);
        let w = rot * Vector3::from(st.base_ang_vel);
        // v_o = v_com - ω × r  =>  v̇_o = v̇_com - ω̇ × r - ω × (ω × r);  ω_b = Rᵀω  =>  ω̇_b = Rᵀ ω̇.
        let vo_dot = vc_dot - w_dot.cross(&r_com) - w.cross(&w.cross(&r_com));
        let wb_dot = rot.inverse() * w_dot;
        let mut out = Vec::with_capacity(nv);
        out.extend_from_slice(&arr(&vo_dot));
        out.extend_from_slice(&arr(&wb_dot));
        for &b in &self.joint_body {
            out.push(a[6 + b - 1]);
        }
        Ok(out)
    }
}
