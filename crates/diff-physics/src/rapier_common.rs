//! Code shared by the two Rapier engines ([`crate::rapier_multibody`], [`crate::rapier_impulse`]):
//! solver settings, building rigid bodies / colliders / joint descriptions from the robot model, state
//! conversion helpers, contact read-out and energy.
//!
//! Precision: both engines use the `rapier3d-f64` crate (Rapier 0.36 compiled with `f64` reals, glam `DVec3` /
//! `DQuat` math). Rapier quaternions are glam `DQuat` stored `[x, y, z, w]`; every conversion to the
//! interface's `[w, x, y, z]` goes through [`quat_to_wxyz`] / [`wxyz_to_quat`].
use crate::engine::{CommonSettings, Contact, EngineError};
use nalgebra::{Isometry3, Matrix3, Quaternion, Translation3, UnitQuaternion, Vector3};
use rapier3d_f64::na as rna;
use rapier3d_f64::prelude::{
    CoefficientCombineRule, ColliderBuilder, FrictionModel, GenericJoint, GenericJointBuilder, Group,
    IntegrationParameters, InteractionGroups, InteractionTestMode, JointAxesMask, JointAxis, MassProperties,
    PhysicsWorld, Pose, RigidBodyBuilder, RigidBodyHandle, Rotation, SpringCoefficients, Vector as RVector,
};
use robot_model::{RobotModel, Shape};
use serde::{Deserialize, Serialize};

/// Rapier's contact friction model, serialisable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RapierFrictionModel {
    /// One Coulomb friction constraint (2 tangent directions) per contact point.
    Coulomb,
    /// One friction constraint per 4 contact points plus one "twist" constraint (faster, less accurate).
    Simplified,
}

/// Solver and contact settings common to both Rapier formulations. Every field is written into reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RapierSolverSettings {
    /// Substeps per timestep (`IntegrationParameters::num_solver_iterations`: Rapier's TGS-soft solver
    /// divides `dt` into this many substeps, each with one PGS + one stabilisation sweep by default).
    pub substeps: usize,
    /// PGS sweeps per substep (`num_internal_pgs_iterations`).
    pub pgs_iterations_per_substep: usize,
    /// Stabilisation (position-bias removal) sweeps per substep (`num_internal_stabilization_iterations`).
    pub stabilization_iterations_per_substep: usize,
    /// Contact constraint softness against the fixed ground (`static_contact_softness`): natural
    /// frequency (Hz) and damping ratio of the penetration-correcting spring.
    pub static_contact_natural_frequency_hz: f64,
    pub static_contact_damping_ratio: f64,
    /// Same for contacts between two dynamic bodies (`contact_softness`; only self-collision uses it).
    pub contact_natural_frequency_hz: f64,
    pub contact_damping_ratio: f64,
    /// Penetration the solver leaves uncorrected (m) (`normalized_allowed_linear_error`, length unit 1 m).
    pub allowed_linear_error_m: f64,
    /// Cap on the penetration-correction velocity (m/s) (`normalized_max_corrective_velocity`).
    pub max_corrective_velocity_mps: f64,
    /// Speculative contact margin (m): contacts are generated up to this distance before touching
    /// (`normalized_prediction_distance`).
    pub prediction_distance_m: f64,
    /// Warm-start coefficient for contact impulses between steps (cleared on reset: the world is rebuilt).
    pub warmstart_coefficient: f64,
    /// Re-use contact points while bodies moved less than a threshold (`contact_recycling`). Off: contact
    /// geometry is recomputed every step.
    pub contact_recycling: bool,
    /// Contact friction model.
    pub friction_model: RapierFrictionModel,
    /// Contacts between a link and its parent link (`GenericJoint::contacts_enabled`).
    pub parent_child_contacts: bool,
    /// Maximum CCD substeps (0 disables continuous collision detection entirely).
    pub max_ccd_substeps: usize,
    /// Time integrator (descriptive; Rapier has one): symplectic (semi-implicit) Euler per substep.
    pub integrator: String,
}

impl Default for RapierSolverSettings {
    fn default() -> Self {
        RapierSolverSettings {
            // Rapier's default is 4 substeps; at dt = 2 ms this gives 0.5 ms substeps, enough for stiff
            // joint/contact constraints of a 50 kg robot without turning every step into a 30-body LU x 8.
            substeps: 4,
            pgs_iterations_per_substep: 1,
            stabilization_iterations_per_substep: 1,
            // Ground contacts: Rapier's default static contact spring (60 Hz, heavily damped: no bounce).
            static_contact_natural_frequency_hz: 60.0,
            static_contact_damping_ratio: 10.0,
            contact_natural_frequency_hz: 30.0,
            contact_damping_ratio: 10.0,
            // Robotics, not games: 1 mm allowed penetration instead of Rapier's 5 mm.
            allowed_linear_error_m: 0.001,
            max_corrective_velocity_mps: 3.0,
            // 5 mm speculative margin: at 2 ms steps a foot at 2.5 m/s moves 5 mm per step.
            prediction_distance_m: 0.005,
            warmstart_coefficient: 1.0,
            contact_recycling: false,
            friction_model: RapierFrictionModel::Coulomb,
            parent_child_contacts: false,
            max_ccd_substeps: 0,
            integrator: "symplectic Euler per substep (Rapier TGS-soft: velocity solve, then position update)".into(),
        }
    }
}

impl RapierSolverSettings {
    /// Rapier's integration parameters for these settings.
    pub fn integration_parameters(&self, dt: f64) -> IntegrationParameters {
        IntegrationParameters {
            dt,
            num_solver_iterations: self.substeps.max(1),
            num_internal_pgs_iterations: self.pgs_iterations_per_substep.max(1),
            num_internal_stabilization_iterations: self.stabilization_iterations_per_substep,
            static_contact_softness: SpringCoefficients::new(
                self.static_contact_natural_frequency_hz,
                self.static_contact_damping_ratio,
            ),
            contact_softness: SpringCoefficients::new(self.contact_natural_frequency_hz, self.contact_damping_ratio),
            normalized_allowed_linear_error: self.allowed_linear_error_m,
            normalized_max_corrective_velocity: self.max_corrective_velocity_mps,
            normalized_prediction_distance: self.prediction_distance_m,
            normalized_max_linear_velocity: f64::MAX,
            warmstart_coefficient: self.warmstart_coefficient,
            contact_recycling: self.contact_recycling,
            contact_clustering: false,
            max_ccd_substeps: self.max_ccd_substeps,
            friction_model: match self.friction_model {
                RapierFrictionModel::Coulomb => FrictionModel::Coulomb,
                RapierFrictionModel::Simplified => FrictionModel::Simplified,
            },
            length_unit: 1.0,
            ..IntegrationParameters::default()
        }
    }
}

/// `rapier3d-f64` version string for reports.
pub const RAPIER_VERSION: &str = "rapier3d-f64 0.36.1 (Rapier 0.36 with f64 reals)";

// ---------------------------------------------------------------------------------------------------------
// Math conversions (nalgebra 0.33 of the model <-> glam of Rapier).

pub fn v_to_r(v: &Vector3<f64>) -> RVector {
    RVector::new(v.x, v.y, v.z)
}
pub fn v_from_r(v: RVector) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}
pub fn q_to_r(q: &UnitQuaternion<f64>) -> Rotation {
    // nalgebra stores [i, j, k, w]; glam DQuat::from_xyzw takes (x, y, z, w).
    Rotation::from_xyzw(q.i, q.j, q.k, q.w)
}
pub fn q_from_r(q: Rotation) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q.w, q.x, q.y, q.z))
}
pub fn iso_to_pose(iso: &Isometry3<f64>) -> Pose {
    Pose::from_parts(v_to_r(&iso.translation.vector), q_to_r(&iso.rotation))
}
pub fn iso_from_pose(p: &Pose) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::from(v_from_r(p.translation)), q_from_r(p.rotation))
}
/// `[w, x, y, z]` from a Rapier (glam) quaternion.
pub fn quat_to_wxyz(q: Rotation) -> [f64; 4] {
    [q.w, q.x, q.y, q.z]
}
/// A unit Rapier quaternion from `[w, x, y, z]` (normalised).
pub fn wxyz_to_quat(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
}
pub fn arr(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// The rotation taking Rapier's revolute axis (local X of the joint frames) onto `axis` (unit).
pub fn align_x_to(axis: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(&Vector3::x(), axis).unwrap_or_else(|| {
        // axis = -x: half turn about z.
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI)
    })
}

// ---------------------------------------------------------------------------------------------------------
// Building.

/// Collision groups: robot shapes are in group 1, the ground in group 2.
const ROBOT_GROUP: Group = Group::GROUP_1;
const GROUND_GROUP: Group = Group::GROUP_2;

/// A robot built in a Rapier world: one dynamic rigid body per model link.
#[derive(Debug)]
pub struct BuiltRobot {
    /// Rigid body of every model link (`model.links` order).
    pub bodies: Vec<RigidBodyHandle>,
    /// Rapier body frame of each link relative to the link frame (a pure translation). Only the multibody
    /// root uses a non-zero offset (see `rapier_multibody`), everything else is the link frame itself.
    pub frame_offsets: Vec<Vector3<f64>>,
    /// The fixed ground body, if any.
    pub ground: Option<RigidBodyHandle>,
}

/// A fresh Rapier world with the settings' integration parameters and gravity.
pub fn new_world(common: &CommonSettings, solver: &RapierSolverSettings) -> PhysicsWorld {
    let mut world = PhysicsWorld::new();
    world.gravity = RVector::new(common.gravity[0], common.gravity[1], common.gravity[2]);
    world.integration_parameters = solver.integration_parameters(common.timestep);
    world
}

/// Mass properties of a link in its Rapier body frame (link frame shifted by `offset`). The full inertia
/// matrix (including products of inertia, i.e. rotated inertia frames) is diagonalised by Rapier.
pub fn link_mass_properties(model: &RobotModel, li: usize, offset: &Vector3<f64>) -> MassProperties {
    let inertial = &model.links[li].inertial;
    mass_properties(&(inertial.com - offset), inertial.mass, &inertial.inertia)
}

/// Rapier mass properties from a full inertia matrix about the COM. The principal frame is computed here with
/// nalgebra's f64 symmetric eigen-solver (converged to machine precision) rather than with
/// `MassProperties::with_inertia_matrix`, whose glam eigen-solver reconstructs the H1-2 inertias only to
/// ~1e-7 relative (measured: mass-matrix error 2e-7, acceleration error 4e-4 on the light wrist links).
pub fn mass_properties(com: &Vector3<f64>, mass: f64, inertia: &Matrix3<f64>) -> MassProperties {
    let (rot, vals) = crate::engine::principal_frame(inertia);
    MassProperties::with_principal_inertia_frame(
        v_to_r(com),
        mass,
        RVector::new(vals[0].max(0.0), vals[1].max(0.0), vals[2].max(0.0)),
        q_to_r(&rot),
    )
}

/// Adds one dynamic body per link at the given world link poses, with mass properties and collision shapes
/// (density 0: mass comes only from the model's inertials), and the ground plane if enabled.
pub fn add_robot(
    world: &mut PhysicsWorld,
    model: &RobotModel,
    common: &CommonSettings,
    link_poses: &[Isometry3<f64>],
    frame_offsets: Vec<Vector3<f64>>,
    extra_inertia: &[Matrix3<f64>],
    gyroscopic: bool,
) -> Result<BuiltRobot, EngineError> {
    if link_poses.len() != model.links.len() || frame_offsets.len() != model.links.len() {
        return Err(EngineError::Build("link pose / offset count does not match the model".into()));
    }
    let self_collision = model.contact.self_collision;
    let robot_filter = if self_collision { ROBOT_GROUP | GROUND_GROUP } else { GROUND_GROUP };
    let robot_groups = InteractionGroups::new(ROBOT_GROUP, robot_filter, InteractionTestMode::And);
    let mut bodies = Vec::with_capacity(model.links.len());
    for (li, link) in model.links.iter().enumerate() {
        let off = frame_offsets[li];
        let body_pose = link_poses[li] * Translation3::from(off);
        let mut mprops = link_mass_properties(model, li, &off);
        if let Some(extra) = extra_inertia.get(li) {
            if extra.iter().any(|x| *x != 0.0) {
                let inertial = &link.inertial;
                mprops = mass_properties(&(inertial.com - off), inertial.mass, &(inertial.inertia + extra));
            }
        }
        let rb = RigidBodyBuilder::dynamic()
            .pose(iso_to_pose(&body_pose))
            .additional_mass_properties(mprops)
            .can_sleep(false)
            .linear_damping(0.0)
            .angular_damping(0.0)
            .gyroscopic_forces_enabled(gyroscopic)
            .user_data(li as u128 + 1)
            .build();
        let h = world.insert_body(rb);
        if common.collisions {
            for col in &link.collisions {
                let shape_pose = Translation3::from(-off) * col.origin;
                let builder = match col.shape {
                    Shape::Box { half_extents: e } => ColliderBuilder::cuboid(e[0], e[1], e[2]),
                    Shape::Sphere { radius } => ColliderBuilder::ball(radius),
                    Shape::Capsule { radius, half_length } => ColliderBuilder::capsule_z(half_length, radius),
                    // Rapier cylinders are along local y; URDF's are along z: rotate +90° about x.
                    Shape::Cylinder { radius, half_length } => ColliderBuilder::cylinder(half_length, radius),
                };
                let shape_pose = match col.shape {
                    Shape::Cylinder { .. } => {
                        shape_pose * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2)
                    }
                    _ => shape_pose,
                };
                let c = builder
                    .position(iso_to_pose(&shape_pose))
                    .density(0.0)
                    .friction(model.contact.friction)
                    .friction_combine_rule(CoefficientCombineRule::Average)
                    .restitution(model.contact.restitution)
                    .restitution_combine_rule(CoefficientCombineRule::Average)
                    .collision_groups(robot_groups)
                    .build();
                world.insert_collider(c, Some(h));
            }
        }
        bodies.push(h);
    }
    // Mass properties are otherwise only computed inside the first step; FK/mass-matrix queries right after a
    // reset need them now.
    for &h in &bodies {
        let colliders = &world.colliders;
        if let Some(rb) = world.bodies.get_mut(h) {
            rb.recompute_mass_properties_from_colliders(colliders);
        }
    }
    let ground = if common.ground {
        let g = world.insert_body(RigidBodyBuilder::fixed().user_data(0).build());
        let normal = rna::Unit::new_unchecked(RVector::Z);
        let c = ColliderBuilder::halfspace(normal)
            .friction(model.contact.friction)
            .friction_combine_rule(CoefficientCombineRule::Average)
            .restitution(model.contact.restitution)
            .restitution_combine_rule(CoefficientCombineRule::Average)
            .collision_groups(InteractionGroups::new(GROUND_GROUP, ROBOT_GROUP, InteractionTestMode::And))
            .build();
        world.insert_collider(c, Some(g));
        Some(g)
    } else {
        None
    };
    Ok(BuiltRobot { bodies, frame_offsets, ground })
}

/// The Rapier joint description of model joint `ji`: a revolute joint whose local X axis is the model axis,
/// anchored at the child link origin, with frames expressed in the Rapier body frames (link frames shifted by
/// the frame offsets). The joint's generalized coordinate is the model's joint angle, same sign.
pub fn revolute_joint(
    model: &RobotModel,
    ji: usize,
    offsets: &[Vector3<f64>],
    limits: bool,
    parent_child_contacts: bool,
) -> GenericJoint {
    let j = &model.joints[ji];
    let align = align_x_to(&j.axis.into_inner());
    let frame1 = Translation3::from(-offsets[j.parent_link]) * j.origin * align;
    let frame2 = Translation3::from(-offsets[j.child_link]) * Isometry3::from_parts(Translation3::identity(), align);
    let mut b = GenericJointBuilder::new(JointAxesMask::LOCKED_REVOLUTE_AXES)
        .local_frame1(iso_to_pose(&frame1))
        .local_frame2(iso_to_pose(&frame2))
        .contacts_enabled(parent_child_contacts);
    if limits {
        b = b.limits(JointAxis::AngX, [j.lower, j.upper]);
    }
    b.build()
}

// ---------------------------------------------------------------------------------------------------------
// Kinematics helpers.

/// Spatial velocity of every link from a generalized state: `(angular velocity world, velocity of the link
/// ORIGIN world)`, propagated down the tree with the model's joints at the given link poses.
pub fn link_velocities(
    model: &RobotModel,
    link_poses: &[Isometry3<f64>],
    base_lin_world: Vector3<f64>,
    base_ang_body: Vector3<f64>,
    dq: &[f64],
) -> Vec<(Vector3<f64>, Vector3<f64>)> {
    let mut out = vec![(Vector3::zeros(), Vector3::zeros()); model.links.len()];
    out[0] = (link_poses[0].rotation * base_ang_body, base_lin_world);
    for (li, link) in model.links.iter().enumerate().skip(1) {
        let (Some(ji), Some(pl)) = (link.parent_joint, link.parent_link) else {
            continue;
        };
        let j = &model.joints[ji];
        let axis_w = link_poses[li].rotation * j.axis.into_inner();
        let (w_p, v_p) = out[pl];
        let r = link_poses[li].translation.vector - link_poses[pl].translation.vector;
        // Revolute joint through the child origin: no linear velocity contribution at the child origin.
        out[li] = (w_p + axis_w * dq.get(ji).copied().unwrap_or(0.0), v_p + w_p.cross(&r));
    }
    out
}

/// Extra rotational inertia approximating armature on rigid bodies: `armature · a aᵀ` about the
/// joint axis, added to the child link (used by the impulse-joint engine only).
pub fn armature_inertia(model: &RobotModel, enabled: bool) -> Vec<Matrix3<f64>> {
    let mut extra = vec![Matrix3::zeros(); model.links.len()];
    if enabled {
        for j in &model.joints {
            let a = j.axis.into_inner();
            extra[j.child_link] += j.armature * a * a.transpose();
        }
    }
    extra
}

// ---------------------------------------------------------------------------------------------------------
// Contacts and energy.

fn body_name(model: &RobotModel, world: &PhysicsWorld, h: Option<RigidBodyHandle>) -> String {
    match h.and_then(|h| world.bodies.get(h)) {
        Some(rb) if rb.user_data > 0 => {
            let li = (rb.user_data - 1) as usize;
            model.links.get(li).map(|l| l.name.clone()).unwrap_or_else(|| "unknown".into())
        }
        _ => "ground".into(),
    }
}

/// Contacts of the last step: every solver contact point (within the speculative margin or penetrating) with
/// its normal force (accumulated normal impulse / dt). Robot-ground contacts are oriented ground -> robot.
pub fn read_contacts(model: &RobotModel, world: &PhysicsWorld, dt: f64) -> Vec<Contact> {
    let mut out = Vec::new();
    for pair in world.narrow_phase.contact_pairs() {
        let (Some(c1), Some(c2)) = (world.colliders.get(pair.collider1), world.colliders.get(pair.collider2)) else {
            continue;
        };
        let name1 = body_name(model, world, c1.parent());
        let name2 = body_name(model, world, c2.parent());
        // Put the ground first so the normal points up out of the floor.
        let flip = name2 == "ground" && name1 != "ground";
        for m in pair.solver_manifolds() {
            let n = m.data.normal; // world, from collider 1 to collider 2
            for pt in &m.points {
                let impulse = pt.data.impulse;
                if pt.dist > 0.0 && impulse <= 0.0 {
                    continue; // speculative point that did not engage
                }
                let p1 = *c1.position() * pt.local_p1;
                let p2 = *c2.position() * pt.local_p2;
                let mid = (p1 + p2) * 0.5;
                let normal = if flip { -n } else { n };
                let (a, b) = if flip { (name2.clone(), name1.clone()) } else { (name1.clone(), name2.clone()) };
                out.push(Contact {
                    body_a: a,
                    body_b: b,
                    point: [mid.x, mid.y, mid.z],
                    normal: [normal.x, normal.y, normal.z],
                    normal_force: if dt > 0.0 { impulse.max(0.0) / dt } else { 0.0 },
                    depth: -pt.dist,
                });
            }
        }
    }
    out
}

/// Gravitational potential energy `−Σ m g·c` of the rigid bodies (zero at the world origin) and their kinetic
/// energy `Σ ½ m |v_c|² + ½ ωᵀ I ω` as simulated (world-frame COM velocities and inertias of the bodies).
pub fn bodies_energy(world: &PhysicsWorld, bodies: &[RigidBodyHandle], gravity: [f64; 3]) -> (f64, f64) {
    let g = RVector::new(gravity[0], gravity[1], gravity[2]);
    let mut kin = 0.0;
    let mut pot = 0.0;
    for &h in bodies {
        let Some(rb) = world.bodies.get(h) else { continue };
        kin += rb.kinetic_energy();
        pot -= rb.mass() * g.dot(rb.center_of_mass());
    }
    (kin, pot)
}

/// Whole-robot centre of mass from the simulated bodies.
pub fn bodies_com(world: &PhysicsWorld, bodies: &[RigidBodyHandle]) -> [f64; 3] {
    let mut m = 0.0;
    let mut c = RVector::ZERO;
    for &h in bodies {
        if let Some(rb) = world.bodies.get(h) {
            m += rb.mass();
            c += rb.center_of_mass() * rb.mass();
        }
    }
    if m > 0.0 {
        c /= m;
    }
    [c.x, c.y, c.z]
}

/// Link-frame world poses from the simulated bodies (undoing the frame offsets).
pub fn link_poses_from_bodies(world: &PhysicsWorld, robot: &BuiltRobot) -> Vec<Isometry3<f64>> {
    robot
        .bodies
        .iter()
        .zip(&robot.frame_offsets)
        .map(|(&h, off)| match world.bodies.get(h) {
            Some(rb) => iso_from_pose(rb.position()) * Translation3::from(-off),
            None => Isometry3::identity(),
        })
        .collect()
}

/// Mass of every simulated link body (`model.links` order); NaN for a missing body.
pub fn link_masses(world: &PhysicsWorld, robot: &BuiltRobot) -> Vec<f64> {
    robot.bodies.iter().map(|&h| world.bodies.get(h).map(|rb| rb.mass()).unwrap_or(f64::NAN)).collect()
}

/// World poses of the link frames in the `Engine` convention (`[w, x, y, z]` quaternions).
pub fn link_poses(world: &PhysicsWorld, robot: &BuiltRobot) -> Vec<crate::engine::LinkPose> {
    link_poses_from_bodies(world, robot)
        .iter()
        .map(|p| crate::engine::LinkPose {
            pos: arr(&p.translation.vector),
            quat: [p.rotation.w, p.rotation.i, p.rotation.j, p.rotation.k],
        })
        .collect()
}

/// Clears the user forces and torques of every robot body (they persist across steps in Rapier).
pub fn clear_user_forces(world: &mut PhysicsWorld, robot: &BuiltRobot) {
    for &h in &robot.bodies {
        if let Some(rb) = world.bodies.get_mut(h) {
            rb.reset_forces(false);
            rb.reset_torques(false);
        }
    }
}

/// Applies a joint torque `t` as equal and opposite body torques about the joint's world axis
/// (child +, parent -): the generalized force of a revolute joint in any formulation.
pub fn add_joint_torque(world: &mut PhysicsWorld, robot: &BuiltRobot, joint: &robot_model::Joint, t: f64) {
    if t == 0.0 {
        return;
    }
    let child = robot.bodies[joint.child_link];
    let parent = robot.bodies[joint.parent_link];
    let Some(rb) = world.bodies.get(child) else {
        return;
    };
    let axis_w = q_from_r(rb.position().rotation) * joint.axis.into_inner();
    let torque = v_to_r(&(axis_w * t));
    if let Some(rb) = world.bodies.get_mut(child) {
        rb.add_torque(torque, true);
    }
    if let Some(rb) = world.bodies.get_mut(parent) {
        rb.add_torque(-torque, true);
    }
}

/// Checks a torque vector's length and finiteness.
pub fn check_tau(model: &RobotModel, tau: &[f64]) -> Result<(), EngineError> {
    if tau.len() != model.nj() {
        return Err(EngineError::Input(format!("expected {} joint torques, got {}", model.nj(), tau.len())));
    }
    if tau.iter().any(|t| !t.is_finite()) {
        return Err(EngineError::Input("non-finite joint torque".into()));
    }
    Ok(())
}
