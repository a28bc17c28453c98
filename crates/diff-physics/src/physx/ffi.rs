//! The one FFI module of the PhysX engine: every call into `physx-sys` (the generated C API over the vendored
//! PhysX 5.1.3 SDK, compiled by its build script) lives here, behind a small safe interface.
//!
//! # Invariants
//! - **One SDK per process.** PhysX allows a single `PxFoundation` per process. [`sdk`] creates the foundation
//!   and the `PxPhysics` object once (never released: they live as long as the process) and hands out the
//!   `PxPhysics` pointer. Object creation and release through it (scenes, materials, articulations, shapes,
//!   dispatchers) is serialised by [`SDK_LOCK`]: PhysX guards its object registries, but not every path
//!   (material tables, scene lists) is documented as thread-safe, so we do not rely on it.
//! - **One scene per [`World`].** A `World` owns its scene, CPU dispatcher, material, ground actor, articulation,
//!   articulation cache and contact-report callback, and releases them in `Drop` (articulation and ground
//!   before the scene, the scene before its dispatcher and callback). Raw pointers never leave this module; the
//!   engine refers to links by their index in `model.links` order.
//! - **Single-threaded simulation.** The dispatcher has zero worker threads, so PhysX runs every task, and calls
//!   our error and contact callbacks, on the thread that calls `simulate`/`fetchResults`. A `World` is `Send`
//!   (PhysX scenes may be used from any thread, one at a time) but not `Sync`: every method takes `&mut self`
//!   or only reads data that no simulation is writing (there is no simulation in flight outside `step`).
//! - **Errors.** PhysX reports errors through its error callback and carries on. The callback stores them per
//!   thread; every entry point of this module drains them and turns them into `Err(String)`.
//! - **Precision.** PhysX computes and stores in f32. The narrowing from the f64 model happens here, once, in
//!   the `to_px*` helpers; values read back are widened exactly (every f32 is an f64).
#![allow(unsafe_code)]

use physx_sys as px;
use std::cell::RefCell;
use std::ffi::{c_void, CStr};
use std::ptr::null_mut;
use std::sync::{Mutex, OnceLock};

/// PhysX SDK version compiled in (physx-sys 0.11.5 vendors 5.1.3).
pub const PHYSX_VERSION: (u32, u32, u32) = (5, 1, 3);

thread_local! {
    /// PhysX errors reported on this thread since the last drain.
    static ERRORS: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
}

unsafe extern "C" fn on_error(
    code: px::PxErrorCode,
    message: *const std::ffi::c_char,
    file: *const std::ffi::c_char,
    line: u32,
    _user: *const c_void,
) {
    // Warnings and debug output are not errors; everything from InvalidParameter up is.
    let severe = matches!(
        code,
        px::PxErrorCode::InvalidParameter
            | px::PxErrorCode::InvalidOperation
            | px::PxErrorCode::OutOfMemory
            | px::PxErrorCode::InternalError
            | px::PxErrorCode::Abort
    );
    if !severe {
        return;
    }
    // SAFETY: PhysX passes NUL-terminated strings (or null) that live for the duration of the call.
    let text = |p: *const std::ffi::c_char| {
        if p.is_null() {
            String::new()
        } else {
            unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
        }
    };
    let msg = format!("PhysX {code:?}: {} ({}:{line})", text(message), text(file));
    ERRORS.with(|e| e.borrow_mut().push(msg));
}

/// Drains this thread's PhysX errors into one `Err`.
fn check(what: &str) -> Result<(), String> {
    let errs = ERRORS.with(|e| std::mem::take(&mut *e.borrow_mut()));
    if errs.is_empty() {
        Ok(())
    } else {
        Err(format!("{what}: {}", errs.join("; ")))
    }
}

struct Sdk {
    physics: *mut px::PxPhysics,
}
// SAFETY: the PxPhysics pointer is created once and never released; all creation/release calls through it are
// serialised by SDK_LOCK (see module docs).
unsafe impl Send for Sdk {}
unsafe impl Sync for Sdk {}

static SDK: OnceLock<Result<Sdk, String>> = OnceLock::new();
/// Serialises object creation and release through `PxPhysics`.
static SDK_LOCK: Mutex<()> = Mutex::new(());

fn sdk_lock() -> std::sync::MutexGuard<'static, ()> {
    // A panic while holding the lock leaves no PhysX state half-changed that we depend on: recover the guard.
    SDK_LOCK.lock().unwrap_or_else(|p| p.into_inner())
}

fn sdk() -> Result<*mut px::PxPhysics, String> {
    let sdk = SDK.get_or_init(|| {
        let (ma, mi, bf) = PHYSX_VERSION;
        let version = px::version(ma, mi, bf);
        // SAFETY: called once per process (OnceLock); the allocator and error callback objects are never freed.
        unsafe {
            let alloc = px::get_default_allocator() as *mut px::PxAllocatorCallback;
            let err_cb = px::create_error_callback(on_error, null_mut());
            let foundation = px::phys_PxCreateFoundation(version, alloc, err_cb);
            if foundation.is_null() {
                return Err("PxCreateFoundation failed".to_string());
            }
            let scale = px::PxTolerancesScale_new(1.0, 10.0);
            let physics = px::phys_PxCreatePhysics(version, foundation, &scale, false, null_mut(), null_mut());
            if physics.is_null() {
                return Err("PxCreatePhysics failed".to_string());
            }
            Ok(Sdk { physics })
        }
    });
    match sdk {
        Ok(s) => Ok(s.physics),
        Err(e) => Err(e.clone()),
    }
}

/// A rigid transform in f64 (narrowed to f32 when handed to PhysX): position and unit quaternion `[w, x, y, z]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub p: [f64; 3],
    pub q: [f64; 4],
}

fn to_vec3(v: [f64; 3]) -> px::PxVec3 {
    px::PxVec3 { x: v[0] as f32, y: v[1] as f32, z: v[2] as f32 }
}
fn from_vec3(v: px::PxVec3) -> [f64; 3] {
    [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
}
fn to_transform(p: &Pose) -> px::PxTransform {
    // Renormalise in f32 so that PhysX's isValid() (|q| = 1 within 1e-3) holds and the rotation is exact-unit.
    let q = [p.q[0] as f32, p.q[1] as f32, p.q[2] as f32, p.q[3] as f32];
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let n = if n > 0.0 { n } else { 1.0 };
    px::PxTransform { q: px::PxQuat { w: q[0] / n, x: q[1] / n, y: q[2] / n, z: q[3] / n }, p: to_vec3(p.p) }
}
/// The f32 values PhysX receives for a pose: position, then quaternion in PhysX's order `x y z w` (renormalised
/// as [`to_transform`] does). For scene dumps ([`super::dump`]).
pub fn f32_pose(p: &Pose) -> [f32; 7] {
    let t = to_transform(p);
    [t.p.x, t.p.y, t.p.z, t.q.x, t.q.y, t.q.z, t.q.w]
}
fn from_transform(t: px::PxTransform) -> Pose {
    Pose { p: from_vec3(t.p), q: [f64::from(t.q.w), f64::from(t.q.x), f64::from(t.q.y), f64::from(t.q.z)] }
}

/// Collision primitive, PhysX conventions (capsule axis along the shape's x axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Geometry {
    Box { half_extents: [f64; 3] },
    Sphere { radius: f64 },
    Capsule { radius: f64, half_height: f64 },
}

#[derive(Debug, Clone, PartialEq)]
pub struct ShapeDesc {
    pub geometry: Geometry,
    /// Shape pose in the link (actor) frame.
    pub local: Pose,
}

/// The inbound revolute joint of a link (rotation about the x axis of the joint frames, PhysX's eTWIST).
#[derive(Debug, Clone, PartialEq)]
pub struct JointDesc {
    /// Joint frame in the parent link frame.
    pub parent_pose: Pose,
    /// Joint frame in the child link frame.
    pub child_pose: Pose,
    /// `Some((lower, upper))`: eLIMITED; `None`: eFREE.
    pub limits: Option<(f64, f64)>,
    pub armature: f64,
    /// Dry friction as an implicit velocity drive (target velocity 0) bounded by this torque (N·m); `None`: no drive.
    pub friction_drive: Option<f64>,
    /// PhysX's per-joint velocity clamp (rad/s).
    pub max_joint_velocity: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct LinkDesc {
    /// Index of the parent in the `links` list (parents precede children); `None` for the root.
    pub parent: Option<usize>,
    /// Link frame in the world at creation.
    pub pose: Pose,
    pub mass: f64,
    /// Centre-of-mass frame (principal axes) in the link frame.
    pub mass_frame: Pose,
    /// Principal moments of inertia about the centre of mass.
    pub principal_inertia: [f64; 3],
    pub shapes: Vec<ShapeDesc>,
    /// Inbound joint (`None` for the root).
    pub joint: Option<JointDesc>,
}

/// Everything PhysX needs for one world: the scene and one articulation.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldDesc {
    pub gravity: [f64; 3],
    pub tgs: bool,
    pub position_iterations: u32,
    pub velocity_iterations: u32,
    pub bounce_threshold_velocity: f64,
    pub friction_offset_threshold: f64,
    pub friction_correlation_distance: f64,
    pub stabilization: bool,
    pub enhanced_determinism: bool,
    pub ground: bool,
    pub static_friction: f64,
    pub dynamic_friction: f64,
    pub restitution: f64,
    pub contact_offset: f64,
    pub rest_offset: f64,
    pub self_collision: bool,
    pub max_linear_velocity: f64,
    pub max_angular_velocity: f64,
    pub max_depenetration_velocity: f64,
    pub links: Vec<LinkDesc>,
}

/// One contact point as PhysX reports it.
#[derive(Debug, Clone, PartialEq)]
pub struct RawContact {
    /// Link index (`model.links` order) of the pair's first actor, `None` for the ground.
    pub link0: Option<usize>,
    pub link1: Option<usize>,
    pub position: [f64; 3],
    /// PhysX: points from the second shape towards the first.
    pub normal: [f64; 3],
    /// Negative when penetrating.
    pub separation: f64,
    /// Normal impulse over the step (N·s), world frame.
    pub impulse: [f64; 3],
}

/// Root and joint state in PhysX's own coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct RawState {
    /// Root link frame (actor frame) in the world.
    pub root: Pose,
    /// Root COM linear velocity, world frame.
    pub root_lin_vel: [f64; 3],
    /// Root angular velocity, world frame.
    pub root_ang_vel: [f64; 3],
    /// Joint positions and velocities, `model.links[1..]` order (one DoF per link).
    pub q: Vec<f64>,
    pub dq: Vec<f64>,
}

/// Mass properties of a link as stored by PhysX.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassProps {
    pub mass: f64,
    pub mass_frame: Pose,
    pub principal_inertia: [f64; 3],
}

/// Data the contact callback writes into during `fetchResults` (same thread, see module docs).
struct ContactSink {
    ground: usize,
    links: Vec<usize>,
    contacts: Vec<RawContact>,
    scratch: Vec<px::PxContactPairPoint>,
}

unsafe extern "C" fn on_contact(
    user: *mut c_void,
    header: *const px::PxContactPairHeader,
    pairs: *const px::PxContactPair,
    nb_pairs: u32,
) {
    if user.is_null() || header.is_null() || pairs.is_null() {
        return;
    }
    // SAFETY: `user` is the Box<Mutex<ContactSink>> owned by the World whose scene is being fetched; it outlives
    // the scene (released after it). `header` and `pairs` are valid for the duration of the callback.
    let sink = unsafe { &*(user as *const Mutex<ContactSink>) };
    let Ok(mut sink) = sink.lock() else { return };
    let header = unsafe { &*header };
    if !(header.flags & (px::PxContactPairHeaderFlags::RemovedActor0 | px::PxContactPairHeaderFlags::RemovedActor1))
        .is_empty()
    {
        return;
    }
    let who = |a: *mut px::PxActor, s: &ContactSink| -> Result<Option<usize>, ()> {
        let a = a as usize;
        if a == s.ground {
            Ok(None)
        } else {
            s.links.iter().position(|&l| l == a).map(Some).ok_or(())
        }
    };
    let (Ok(l0), Ok(l1)) = (who(header.actors[0], &sink), who(header.actors[1], &sink)) else { return };
    for i in 0..nb_pairs as usize {
        let pair = unsafe { &*pairs.add(i) };
        let n = usize::from(pair.contactCount);
        if n == 0 {
            continue;
        }
        let mut buf = std::mem::take(&mut sink.scratch);
        buf.resize(n, unsafe { std::mem::zeroed() });
        let got = unsafe { px::PxContactPair_extractContacts(pair, buf.as_mut_ptr(), n as u32) } as usize;
        for p in buf.iter().take(got.min(n)) {
            sink.contacts.push(RawContact {
                link0: l0,
                link1: l1,
                position: from_vec3(p.position),
                normal: from_vec3(p.normal),
                separation: f64::from(p.separation),
                impulse: from_vec3(p.impulse),
            });
        }
        sink.scratch = buf;
    }
}

unsafe extern "C" fn filter_shader(info: *mut px::FilterShaderCallbackInfo) -> px::PxFilterFlags {
    // The default shader ran first (eCONTACT_DEFAULT); add the reports we read every step.
    if !info.is_null() {
        // SAFETY: PhysX passes a valid info block whose pairFlags pointer is writable for this call.
        let pf = unsafe { (*info).pairFlags };
        if !pf.is_null() {
            unsafe {
                *pf |= px::PxPairFlags::SolveContact
                    | px::PxPairFlags::DetectDiscreteContact
                    | px::PxPairFlags::NotifyTouchFound
                    | px::PxPairFlags::NotifyTouchPersists
                    | px::PxPairFlags::NotifyContactPoints;
            }
        }
    }
    px::PxFilterFlags::empty()
}

/// One PhysX scene with one articulation (the robot) and optionally a ground plane.
pub struct World {
    scene: *mut px::PxScene,
    dispatcher: *mut px::PxDefaultCpuDispatcher,
    material: *mut px::PxMaterial,
    callback: *mut px::PxSimulationEventCallback,
    sink: Box<Mutex<ContactSink>>,
    ground: *mut px::PxRigidStatic,
    articulation: *mut px::PxArticulationReducedCoordinate,
    links: Vec<*mut px::PxArticulationLink>,
    joints: Vec<*mut px::PxArticulationJointReducedCoordinate>,
    cache: *mut px::PxArticulationCache,
    /// DoF index of link `i`'s inbound joint (`links[1..]`), in PhysX's cache order.
    dof: Vec<usize>,
    /// PhysX low-level index of each link.
    low_level: Vec<usize>,
    ndofs: usize,
}

// SAFETY: a World exclusively owns its PhysX objects; PhysX scenes may be driven from any thread, one thread at
// a time, which `&mut self` guarantees. The shared PxPhysics is only touched under SDK_LOCK.
unsafe impl Send for World {}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("physx::World").field("links", &self.links.len()).field("dofs", &self.ndofs).finish()
    }
}

impl Drop for World {
    fn drop(&mut self) {
        let _g = sdk_lock();
        // SAFETY: every pointer is owned by this World and released exactly once, children before parents.
        unsafe {
            if !self.cache.is_null() {
                px::PxArticulationCache_release_mut(self.cache);
            }
            if !self.articulation.is_null() {
                px::PxArticulationReducedCoordinate_release_mut(self.articulation);
            }
            if !self.ground.is_null() {
                px::PxActor_release_mut(self.ground as *mut px::PxActor);
            }
            if !self.scene.is_null() {
                px::PxScene_release_mut(self.scene);
            }
            if !self.dispatcher.is_null() {
                px::PxDefaultCpuDispatcher_release_mut(self.dispatcher);
            }
            if !self.material.is_null() {
                px::PxBase_release_mut(self.material as *mut px::PxBase);
            }
            if !self.callback.is_null() {
                px::destroy_simulation_event_callbacks(self.callback);
            }
        }
        let _ = check("release");
    }
}

fn geometry_ptr<T>(g: &T) -> *const px::PxGeometry {
    g as *const T as *const px::PxGeometry
}

impl World {
    /// Builds the scene and the articulation.
    pub fn new(desc: &WorldDesc) -> Result<World, String> {
        let physics = sdk()?;
        let sink = Box::new(Mutex::new(ContactSink {
            ground: 0,
            links: Vec::new(),
            contacts: Vec::new(),
            scratch: Vec::new(),
        }));
        let mut w = World {
            scene: null_mut(),
            dispatcher: null_mut(),
            material: null_mut(),
            callback: null_mut(),
            sink,
            ground: null_mut(),
            articulation: null_mut(),
            links: Vec::new(),
            joints: Vec::new(),
            cache: null_mut(),
            dof: Vec::new(),
            low_level: Vec::new(),
            ndofs: 0,
        };
        let built = {
            let _g = sdk_lock();
            let _ = check("before build"); // drop stale errors of this thread
            w.build(physics, desc)
        };
        // On error `w` is dropped here, after the lock guard (Drop takes the lock again).
        built?;
        Ok(w)
    }

    /// Creates every PhysX object of the world (under SDK_LOCK, held by the caller).
    fn build(&mut self, physics: *mut px::PxPhysics, desc: &WorldDesc) -> Result<(), String> {
        let w = self;
        // SAFETY: `physics` is valid for the process; every object created is stored in `w` at once so that
        // Drop releases it on any early return.
        unsafe {
            let scale = px::PxPhysics_getTolerancesScale(physics);
            let mut sd = px::PxSceneDesc_new(scale);
            sd.gravity = to_vec3(desc.gravity);
            w.dispatcher = px::phys_PxDefaultCpuDispatcherCreate(
                0,
                null_mut(),
                px::PxDefaultCpuDispatcherWaitForWorkMode::WaitForWork,
                0,
            );
            if w.dispatcher.is_null() {
                return Err("PxDefaultCpuDispatcherCreate failed".into());
            }
            sd.cpuDispatcher = w.dispatcher as *mut px::PxCpuDispatcher;
            px::enable_custom_filter_shader(&mut sd, filter_shader, 1);
            let info = px::SimulationEventCallbackInfo {
                collision_callback: Some(on_contact),
                collision_user_data: &*w.sink as *const Mutex<ContactSink> as *mut c_void,
                ..Default::default()
            };
            w.callback = px::create_simulation_event_callbacks(&info);
            sd.simulationEventCallback = w.callback;
            sd.solverType = if desc.tgs { px::PxSolverType::Tgs } else { px::PxSolverType::Pgs };
            sd.bounceThresholdVelocity = desc.bounce_threshold_velocity as f32;
            sd.frictionOffsetThreshold = desc.friction_offset_threshold as f32;
            sd.frictionCorrelationDistance = desc.friction_correlation_distance as f32;
            sd.flags.set(px::PxSceneFlags::EnableStabilization, desc.stabilization);
            sd.flags.set(px::PxSceneFlags::EnableEnhancedDeterminism, desc.enhanced_determinism);
            w.scene = px::PxPhysics_createScene_mut(physics, &sd);
            check("createScene")?;
            if w.scene.is_null() {
                return Err("PxPhysics::createScene failed".into());
            }
            w.material = px::PxPhysics_createMaterial_mut(
                physics,
                desc.static_friction as f32,
                desc.dynamic_friction as f32,
                desc.restitution as f32,
            );
            if w.material.is_null() {
                return Err("createMaterial failed".into());
            }
            // One material on every shape: the combined coefficient is the model's, whatever the combine mode.
            px::PxMaterial_setFrictionCombineMode_mut(w.material, px::PxCombineMode::Average);
            px::PxMaterial_setRestitutionCombineMode_mut(w.material, px::PxCombineMode::Average);
            if desc.ground {
                let plane = px::PxPlane_new_1(0.0, 0.0, 1.0, 0.0);
                w.ground = px::phys_PxCreatePlane(physics, &plane, w.material);
                if w.ground.is_null() {
                    return Err("PxCreatePlane failed".into());
                }
                let mut shape: *mut px::PxShape = null_mut();
                px::PxRigidActor_getShapes(w.ground as *const px::PxRigidActor, &mut shape, 1, 0);
                if !shape.is_null() {
                    px::PxShape_setContactOffset_mut(shape, desc.contact_offset as f32);
                    px::PxShape_setRestOffset_mut(shape, desc.rest_offset as f32);
                }
                px::PxScene_addActor_mut(w.scene, w.ground as *mut px::PxActor, std::ptr::null());
            }
            check("scene and ground")?;

            let art = px::PxPhysics_createArticulationReducedCoordinate_mut(physics);
            if art.is_null() {
                return Err("createArticulationReducedCoordinate failed".into());
            }
            w.articulation = art;
            px::PxArticulationReducedCoordinate_setArticulationFlag_mut(
                art,
                px::PxArticulationFlag::DisableSelfCollision,
                !desc.self_collision,
            );
            // Drive maxForce in N·m (not N·m·s per step): the friction drive's bound is a torque.
            px::PxArticulationReducedCoordinate_setArticulationFlag_mut(
                art,
                px::PxArticulationFlag::DriveLimitsAreForces,
                true,
            );
            px::PxArticulationReducedCoordinate_setSolverIterationCounts_mut(
                art,
                desc.position_iterations,
                desc.velocity_iterations,
            );
            // Never sleep: a sleeping robot would freeze between identical inputs and break reset equivalence.
            px::PxArticulationReducedCoordinate_setSleepThreshold_mut(art, 0.0);

            let flags = px::PxShapeFlags::SimulationShape;
            for (i, l) in desc.links.iter().enumerate() {
                let parent = match l.parent {
                    None => null_mut(),
                    Some(p) => *w.links.get(p).ok_or_else(|| format!("link {i}: parent {p} not built yet"))?,
                };
                let link = px::PxArticulationReducedCoordinate_createLink_mut(art, parent, &to_transform(&l.pose));
                if link.is_null() {
                    check(&format!("createLink {i}"))?;
                    return Err(format!("createLink {i} failed"));
                }
                w.links.push(link);
                let body = link as *mut px::PxRigidBody;
                px::PxRigidBody_setMass_mut(body, l.mass as f32);
                px::PxRigidBody_setCMassLocalPose_mut(body, &to_transform(&l.mass_frame));
                px::PxRigidBody_setMassSpaceInertiaTensor_mut(body, &to_vec3(l.principal_inertia));
                px::PxRigidBody_setLinearDamping_mut(body, 0.0);
                px::PxRigidBody_setAngularDamping_mut(body, 0.0);
                px::PxRigidBody_setMaxLinearVelocity_mut(body, desc.max_linear_velocity as f32);
                px::PxRigidBody_setMaxAngularVelocity_mut(body, desc.max_angular_velocity as f32);
                px::PxRigidBody_setMaxDepenetrationVelocity_mut(body, desc.max_depenetration_velocity as f32);
                for s in &l.shapes {
                    let actor = link as *mut px::PxRigidActor;
                    let shape = match s.geometry {
                        Geometry::Box { half_extents: h } => {
                            let g = px::PxBoxGeometry_new(h[0] as f32, h[1] as f32, h[2] as f32);
                            px::PxRigidActorExt_createExclusiveShape_1(actor, geometry_ptr(&g), w.material, flags)
                        }
                        Geometry::Sphere { radius } => {
                            let g = px::PxSphereGeometry_new(radius as f32);
                            px::PxRigidActorExt_createExclusiveShape_1(actor, geometry_ptr(&g), w.material, flags)
                        }
                        Geometry::Capsule { radius, half_height } => {
                            let g = px::PxCapsuleGeometry_new(radius as f32, half_height as f32);
                            px::PxRigidActorExt_createExclusiveShape_1(actor, geometry_ptr(&g), w.material, flags)
                        }
                    };
                    if shape.is_null() {
                        check(&format!("shape of link {i}"))?;
                        return Err(format!("createExclusiveShape on link {i} failed"));
                    }
                    px::PxShape_setLocalPose_mut(shape, &to_transform(&s.local));
                    px::PxShape_setContactOffset_mut(shape, desc.contact_offset as f32);
                    px::PxShape_setRestOffset_mut(shape, desc.rest_offset as f32);
                }
                match (&l.joint, l.parent) {
                    (Some(j), Some(_)) => {
                        let jt = px::PxArticulationLink_getInboundJoint(link);
                        if jt.is_null() {
                            return Err(format!("link {i} has no inbound joint"));
                        }
                        px::PxArticulationJointReducedCoordinate_setJointType_mut(
                            jt,
                            px::PxArticulationJointType::Revolute,
                        );
                        px::PxArticulationJointReducedCoordinate_setParentPose_mut(jt, &to_transform(&j.parent_pose));
                        px::PxArticulationJointReducedCoordinate_setChildPose_mut(jt, &to_transform(&j.child_pose));
                        let tw = px::PxArticulationAxis::Twist;
                        match j.limits {
                            Some((lo, hi)) => {
                                px::PxArticulationJointReducedCoordinate_setMotion_mut(
                                    jt,
                                    tw,
                                    px::PxArticulationMotion::Limited,
                                );
                                let lim = px::PxArticulationLimit { low: lo as f32, high: hi as f32 };
                                px::PxArticulationJointReducedCoordinate_setLimitParams_mut(jt, tw, &lim);
                            }
                            None => px::PxArticulationJointReducedCoordinate_setMotion_mut(
                                jt,
                                tw,
                                px::PxArticulationMotion::Free,
                            ),
                        }
                        px::PxArticulationJointReducedCoordinate_setArmature_mut(jt, tw, j.armature as f32);
                        px::PxArticulationJointReducedCoordinate_setFrictionCoefficient_mut(jt, 0.0);
                        px::PxArticulationJointReducedCoordinate_setMaxJointVelocity_mut(
                            jt,
                            j.max_joint_velocity as f32,
                        );
                        if let Some(f) = j.friction_drive {
                            // eVELOCITY: PhysX sets stiffness 0 and damping 1e25 internally (the damping given
                            // here only has to be > 0 for the row to exist); target velocity 0; bound f (N·m).
                            let drive = px::PxArticulationDrive {
                                stiffness: 0.0,
                                damping: 1.0,
                                maxForce: f as f32,
                                driveType: px::PxArticulationDriveType::Velocity,
                            };
                            px::PxArticulationJointReducedCoordinate_setDriveParams_mut(jt, tw, &drive);
                            px::PxArticulationJointReducedCoordinate_setDriveVelocity_mut(jt, tw, 0.0, false);
                        }
                        w.joints.push(jt);
                    }
                    (None, None) => {}
                    _ => return Err(format!("link {i}: a joint exactly when it has a parent")),
                }
                check(&format!("link {i}"))?;
            }
            if !px::PxScene_addArticulation_mut(w.scene, art) {
                check("addArticulation")?;
                return Err("PxScene::addArticulation failed".into());
            }
            check("addArticulation")?;
            w.cache = px::PxArticulationReducedCoordinate_createCache(art);
            if w.cache.is_null() {
                return Err("createCache failed".into());
            }
            // Cache indexing: DoFs follow the low-level link order (root has none).
            let nl = w.links.len();
            let mut ll = Vec::with_capacity(nl);
            let mut dofs_by_ll = vec![0usize; nl];
            for &l in &w.links {
                let idx = px::PxArticulationLink_getLinkIndex(l) as usize;
                let nd = px::PxArticulationLink_getInboundJointDof(l) as usize;
                if idx >= nl {
                    return Err(format!("low-level link index {idx} out of range"));
                }
                dofs_by_ll[idx] = nd;
                ll.push(idx);
            }
            let mut offset = vec![0usize; nl];
            let mut acc = 0;
            for k in 0..nl {
                offset[k] = acc;
                acc += dofs_by_ll[k];
            }
            w.ndofs = px::PxArticulationReducedCoordinate_getDofs(art) as usize;
            if acc != w.ndofs || w.ndofs != nl.saturating_sub(1) {
                return Err(format!("articulation has {} DoFs for {nl} links", w.ndofs));
            }
            for (i, &k) in ll.iter().enumerate().skip(1) {
                if dofs_by_ll[k] != 1 {
                    return Err(format!("link {i}: inbound joint has {} DoFs, expected 1", dofs_by_ll[k]));
                }
                w.dof.push(offset[k]);
            }
            w.low_level = ll;
            if let Ok(mut s) = w.sink.lock() {
                s.ground = w.ground as usize;
                s.links = w.links.iter().map(|&l| l as usize).collect();
            }
            check("cache")?;
        }
        Ok(())
    }

    fn cache(&self) -> &px::PxArticulationCache {
        // SAFETY: created in `new`, non-null, released only in Drop.
        unsafe { &*self.cache }
    }

    fn dof_slice_mut(&mut self, ptr: *mut f32) -> &mut [f32] {
        // SAFETY: PhysX allocates every per-DoF array of the cache with getDofs() entries.
        unsafe { std::slice::from_raw_parts_mut(ptr, self.ndofs) }
    }

    /// Sets root pose/velocities and joint positions/velocities (link order, `links[1..]`), zeroes joint forces,
    /// updates link poses, and clears pending contact reports.
    pub fn set_state(&mut self, s: &RawState) -> Result<(), String> {
        if s.q.len() != self.ndofs || s.dq.len() != self.ndofs {
            return Err(format!("state has {} / {} joint entries, articulation {}", s.q.len(), s.dq.len(), self.ndofs));
        }
        let c = *self.cache();
        let dof = self.dof.clone();
        {
            let q = self.dof_slice_mut(c.jointPosition);
            for (i, &d) in dof.iter().enumerate() {
                q[d] = s.q[i] as f32;
            }
        }
        {
            let dq = self.dof_slice_mut(c.jointVelocity);
            for (i, &d) in dof.iter().enumerate() {
                dq[d] = s.dq[i] as f32;
            }
        }
        self.dof_slice_mut(c.jointForce).fill(0.0);
        // SAFETY: rootLinkData points to one PxArticulationRootLinkData of the cache; no simulation is running.
        unsafe {
            let root = &mut *c.rootLinkData;
            root.transform = to_transform(&s.root);
            root.worldLinVel = to_vec3(s.root_lin_vel);
            root.worldAngVel = to_vec3(s.root_ang_vel);
            let flags = px::PxArticulationCacheFlags::Position
                | px::PxArticulationCacheFlags::Velocity
                | px::PxArticulationCacheFlags::Force
                | px::PxArticulationCacheFlags::RootTransform
                | px::PxArticulationCacheFlags::RootVelocities;
            px::PxArticulationReducedCoordinate_applyCache_mut(self.articulation, self.cache, flags, true);
            let root_body = self.links[0] as *mut px::PxRigidBody;
            px::PxRigidBody_clearForce_mut(root_body, px::PxForceMode::Force);
            px::PxRigidBody_clearTorque_mut(root_body, px::PxForceMode::Force);
        }
        if let Ok(mut sink) = self.sink.lock() {
            sink.contacts.clear();
        }
        check("set_state")
    }

    /// Reads root and joint state.
    pub fn state(&mut self) -> Result<RawState, String> {
        let flags = px::PxArticulationCacheFlags::Position
            | px::PxArticulationCacheFlags::Velocity
            | px::PxArticulationCacheFlags::RootTransform
            | px::PxArticulationCacheFlags::RootVelocities;
        // SAFETY: no simulation is in flight outside `step`.
        unsafe { px::PxArticulationReducedCoordinate_copyInternalStateToCache(self.articulation, self.cache, flags) };
        let c = *self.cache();
        let q: Vec<f64> = {
            let s = self.dof_slice_mut(c.jointPosition);
            s.iter().copied().map(f64::from).collect()
        };
        let dq: Vec<f64> = {
            let s = self.dof_slice_mut(c.jointVelocity);
            s.iter().copied().map(f64::from).collect()
        };
        // SAFETY: see above.
        let root = unsafe { *c.rootLinkData };
        check("state")?;
        Ok(RawState {
            root: from_transform(root.transform),
            root_lin_vel: from_vec3(root.worldLinVel),
            root_ang_vel: from_vec3(root.worldAngVel),
            q: self.dof.iter().map(|&d| q[d]).collect(),
            dq: self.dof.iter().map(|&d| dq[d]).collect(),
        })
    }

    /// Joint positions and velocities only (`links[1..]` order), into caller buffers (no allocation).
    pub fn joints_into(&mut self, q: &mut [f64], dq: &mut [f64]) -> Result<(), String> {
        if q.len() != self.ndofs || dq.len() != self.ndofs {
            return Err(format!("buffers of {} / {} for {} DoFs", q.len(), dq.len(), self.ndofs));
        }
        let flags = px::PxArticulationCacheFlags::Position | px::PxArticulationCacheFlags::Velocity;
        // SAFETY: no simulation is in flight outside `step`; per-DoF arrays have ndofs entries.
        unsafe { px::PxArticulationReducedCoordinate_copyInternalStateToCache(self.articulation, self.cache, flags) };
        let c = *self.cache();
        let (pq, pv) = unsafe {
            (
                std::slice::from_raw_parts(c.jointPosition, self.ndofs),
                std::slice::from_raw_parts(c.jointVelocity, self.ndofs),
            )
        };
        for (i, &d) in self.dof.iter().enumerate() {
            q[i] = f64::from(pq[d]);
            dq[i] = f64::from(pv[d]);
        }
        Ok(())
    }

    /// Sets the joint forces (link order, `links[1..]`) applied from now on (PhysX keeps them until changed).
    pub fn set_joint_forces(&mut self, tau: &[f64]) -> Result<(), String> {
        if tau.len() != self.ndofs {
            return Err(format!("{} joint forces for {} DoFs", tau.len(), self.ndofs));
        }
        let c = *self.cache();
        let dof = self.dof.clone();
        {
            let f = self.dof_slice_mut(c.jointForce);
            for (i, &d) in dof.iter().enumerate() {
                f[d] = tau[i] as f32;
            }
        }
        // SAFETY: no simulation in flight.
        unsafe {
            px::PxArticulationReducedCoordinate_applyCache_mut(
                self.articulation,
                self.cache,
                px::PxArticulationCacheFlags::Force,
                true,
            )
        };
        check("set_joint_forces")
    }

    /// Adds a force (world, through the root COM) and a torque (world) on the root link for the next step.
    pub fn add_root_wrench(&mut self, force: [f64; 3], torque: [f64; 3]) -> Result<(), String> {
        let root = self.links[0] as *mut px::PxRigidBody;
        // SAFETY: the root link is in the scene; no simulation in flight.
        unsafe {
            px::PxRigidBody_addForce_mut(root, &to_vec3(force), px::PxForceMode::Force, true);
            px::PxRigidBody_addTorque_mut(root, &to_vec3(torque), px::PxForceMode::Force, true);
        }
        check("add_root_wrench")
    }

    /// Advances one step of `dt` seconds (blocking) and collects the contact reports of that step.
    pub fn step(&mut self, dt: f64) -> Result<(), String> {
        if let Ok(mut sink) = self.sink.lock() {
            sink.contacts.clear();
        }
        // SAFETY: the scene is valid; fetchResults(block = true) returns when the step is complete, after which
        // no PhysX task of this scene runs (zero worker threads anyway).
        unsafe {
            if !px::PxScene_simulate_mut(self.scene, dt as f32, null_mut(), null_mut(), 0, true) {
                check("simulate")?;
                return Err("PxScene::simulate refused to start".into());
            }
            let mut err: u32 = 0;
            if !px::PxScene_fetchResults_mut(self.scene, true, &mut err) {
                check("fetchResults")?;
                return Err(format!("PxScene::fetchResults failed (error state {err})"));
            }
        }
        check("step")
    }

    /// Contact points reported by the last step.
    pub fn contacts(&self) -> Vec<RawContact> {
        self.sink.lock().map(|s| s.contacts.clone()).unwrap_or_default()
    }

    /// World pose of every link frame (actor frame), link order.
    pub fn link_poses(&self) -> Vec<Pose> {
        self.links
            .iter()
            // SAFETY: links are valid while the World lives; no simulation in flight.
            .map(|&l| from_transform(unsafe { px::PxRigidActor_getGlobalPose(l as *const px::PxRigidActor) }))
            .collect()
    }

    /// Mass properties of every link as PhysX stores them.
    pub fn mass_props(&self) -> Vec<MassProps> {
        self.links
            .iter()
            .map(|&l| {
                let b = l as *const px::PxRigidBody;
                // SAFETY: see link_poses.
                unsafe {
                    MassProps {
                        mass: f64::from(px::PxRigidBody_getMass(b)),
                        mass_frame: from_transform(px::PxRigidBody_getCMassLocalPose(b)),
                        principal_inertia: from_vec3(px::PxRigidBody_getMassSpaceInertiaTensor(b)),
                    }
                }
            })
            .collect()
    }

    /// Joint limits as stored (`links[1..]` order); `None` for free joints.
    pub fn joint_limits(&self) -> Vec<Option<(f64, f64)>> {
        self.joints
            .iter()
            .map(|&j| {
                let tw = px::PxArticulationAxis::Twist;
                // SAFETY: joints are valid while the World lives.
                unsafe {
                    match px::PxArticulationJointReducedCoordinate_getMotion(j, tw) {
                        px::PxArticulationMotion::Limited => {
                            let l = px::PxArticulationJointReducedCoordinate_getLimitParams(j, tw);
                            Some((f64::from(l.low), f64::from(l.high)))
                        }
                        _ => None,
                    }
                }
            })
            .collect()
    }

    /// Child joint frame of every joint as stored (`links[1..]` order), in the child link frame.
    pub fn joint_child_frames(&self) -> Vec<Pose> {
        self.joints
            .iter()
            // SAFETY: joints are valid while the World lives.
            .map(|&j| from_transform(unsafe { px::PxArticulationJointReducedCoordinate_getChildPose(j) }))
            .collect()
    }

    /// Armature of every joint as stored (`links[1..]` order).
    pub fn joint_armature(&self) -> Vec<f64> {
        self.joints
            .iter()
            // SAFETY: joints are valid while the World lives.
            .map(|&j| {
                f64::from(unsafe {
                    px::PxArticulationJointReducedCoordinate_getArmature(j, px::PxArticulationAxis::Twist)
                })
            })
            .collect()
    }

    /// PhysX's dense Jacobian of the link COM velocities (world `[v; ω]` per link, rows in low-level link order,
    /// root first) with respect to `[root COM velocity (world), root angular velocity (world), DoFs]`, re-indexed
    /// here to rows in link order and DoF columns in `links[1..]` order. Returns `(6 * links) × (6 + dofs)`.
    pub fn dense_jacobian(&mut self) -> Result<Vec<f64>, String> {
        let (mut rows, mut cols) = (0u32, 0u32);
        // SAFETY: the cache's denseJacobian holds (6 · links) × (6 + dofs) floats (PxArticulationCache docs).
        unsafe {
            px::PxArticulationReducedCoordinate_computeDenseJacobian(
                self.articulation,
                self.cache,
                &mut rows,
                &mut cols,
            )
        };
        check("computeDenseJacobian")?;
        let nl = self.links.len();
        let (rows, cols) = (rows as usize, cols as usize);
        if rows != 6 * nl || cols != 6 + self.ndofs {
            return Err(format!("dense Jacobian is {rows} × {cols}, expected {} × {}", 6 * nl, 6 + self.ndofs));
        }
        let c = *self.cache();
        // SAFETY: size checked above against the documented allocation.
        let j = unsafe { std::slice::from_raw_parts(c.denseJacobian, rows * cols) };
        let mut out = vec![0.0; rows * cols];
        let col_of = |k: usize| -> usize {
            if k < 6 {
                k
            } else {
                6 + self.dof.iter().position(|&d| d == k - 6).unwrap_or(0)
            }
        };
        let col_map: Vec<usize> = (0..cols).map(col_of).collect();
        for (li, &ll) in self.low_level.iter().enumerate() {
            for r in 0..6 {
                let src = (6 * ll + r) * cols;
                let dst = (6 * li + r) * cols;
                for k in 0..cols {
                    out[dst + col_map[k]] = f64::from(j[src + k]);
                }
            }
        }
        Ok(out)
    }

    /// PhysX's inverse-dynamics quantities of the floating-base articulation at the current state, all in
    /// `links[1..]` DoF order: the joint-space mass matrix with the base free (`dofs × dofs`, row-major), the
    /// joint forces that cancel gravity and those that cancel Coriolis/centrifugal effects (both with the base
    /// free), and the joint accelerations under the given joint forces (forward dynamics with the base free).
    pub fn inverse_dynamics(&mut self, joint_forces: &[f64]) -> Result<InverseDynamics, String> {
        if joint_forces.len() != self.ndofs {
            return Err(format!("{} joint forces for {} DoFs", joint_forces.len(), self.ndofs));
        }
        let n = self.ndofs;
        let dof = self.dof.clone();
        let all = px::PxArticulationCacheFlags::Position
            | px::PxArticulationCacheFlags::Velocity
            | px::PxArticulationCacheFlags::RootTransform
            | px::PxArticulationCacheFlags::RootVelocities;
        // SAFETY: commonInit and the compute functions read the articulation's current (applied) state and write
        // the cache's per-DoF arrays (n entries) and massMatrix (n × n); no simulation in flight.
        unsafe {
            px::PxArticulationReducedCoordinate_copyInternalStateToCache(self.articulation, self.cache, all);
            px::PxArticulationReducedCoordinate_commonInit(self.articulation);
            px::PxArticulationReducedCoordinate_computeGeneralizedMassMatrix(self.articulation, self.cache);
        }
        check("computeGeneralizedMassMatrix")?;
        let c = *self.cache();
        // SAFETY: massMatrix has n × n entries.
        let mm = unsafe { std::slice::from_raw_parts(c.massMatrix, n * n) }.to_vec();
        let mut mass = vec![0.0; n * n];
        for (r, &dr) in dof.iter().enumerate() {
            for (k, &dk) in dof.iter().enumerate() {
                mass[r * n + k] = f64::from(mm[dr * n + dk]);
            }
        }
        unsafe { px::PxArticulationReducedCoordinate_computeGeneralizedGravityForce(self.articulation, self.cache) };
        check("computeGeneralizedGravityForce")?;
        let gravity: Vec<f64> = {
            let f = self.dof_slice_mut(c.jointForce).to_vec();
            dof.iter().map(|&d| f64::from(f[d])).collect()
        };
        unsafe {
            px::PxArticulationReducedCoordinate_copyInternalStateToCache(self.articulation, self.cache, all);
            px::PxArticulationReducedCoordinate_computeCoriolisAndCentrifugalForce(self.articulation, self.cache);
        }
        check("computeCoriolisAndCentrifugalForce")?;
        let coriolis: Vec<f64> = {
            let f = self.dof_slice_mut(c.jointForce).to_vec();
            dof.iter().map(|&d| f64::from(f[d])).collect()
        };
        unsafe {
            px::PxArticulationReducedCoordinate_copyInternalStateToCache(self.articulation, self.cache, all);
        }
        {
            let f = self.dof_slice_mut(c.jointForce);
            for (i, &d) in dof.iter().enumerate() {
                f[d] = joint_forces[i] as f32;
            }
        }
        unsafe { px::PxArticulationReducedCoordinate_computeJointAcceleration(self.articulation, self.cache) };
        check("computeJointAcceleration")?;
        let acceleration: Vec<f64> = {
            let a = self.dof_slice_mut(c.jointAcceleration).to_vec();
            dof.iter().map(|&d| f64::from(a[d])).collect()
        };
        // Restore the applied joint forces of the simulation (the cache's jointForce was used as scratch).
        unsafe {
            px::PxArticulationReducedCoordinate_copyInternalStateToCache(
                self.articulation,
                self.cache,
                px::PxArticulationCacheFlags::Force,
            )
        };
        check("inverse dynamics")?;
        Ok(InverseDynamics { mass, gravity, coriolis, acceleration })
    }

    /// The articulation's stabilisation threshold (PhysX default unless changed).
    pub fn stabilization_threshold(&self) -> f64 {
        // SAFETY: valid articulation.
        f64::from(unsafe { px::PxArticulationReducedCoordinate_getStabilizationThreshold(self.articulation) })
    }
}

/// See [`World::inverse_dynamics`].
#[derive(Debug, Clone, PartialEq)]
pub struct InverseDynamics {
    pub mass: Vec<f64>,
    pub gravity: Vec<f64>,
    pub coriolis: Vec<f64>,
    pub acceleration: Vec<f64>,
}
