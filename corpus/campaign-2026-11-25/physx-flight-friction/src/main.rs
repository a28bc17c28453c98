//! PhysX 5.1.3 (physx-sys 0.11.5): a 27-DoF humanoid articulation in free flight gets a sideways push while
//! one foot is a few millimetres above the ground plane and PhysX applies no normal impulse anywhere.
//!
//! Reads `scene.txt` (scene settings, links, shapes, joints, initial state, per-step joint forces; format in
//! README.md), builds the scene, ground plane and articulation, and steps it twice: with the scene's
//! frictionOffsetThreshold as written (0.04 m, PhysX's default) and with 0.001 m. Each step it measures the
//! acceleration of the articulation's centre of mass from the link masses and link COM velocities before and
//! after the step, and collects the contact reports. With no normal impulse, the only external force is gravity:
//! the horizontal COM acceleration must be ~0 and the vertical one -g, whatever the joint forces do.
//!
//! Exit code 1 when a step has no normal impulse yet a COM acceleration off gravity by more than `TOLERANCE`.
use physx_sys as px;
use std::ffi::c_void;
use std::ptr::null_mut;

/// COM acceleration off gravity (m/s², per axis group) allowed in a step without normal impulse (measured f32
/// noise: < 3e-4).
const TOLERANCE: f32 = 0.1;

type Pose = [f32; 7]; // x y z, then quaternion x y z w

enum Geom {
    Box([f32; 3]),
    Sphere(f32),
    Capsule(f32, f32),
}

struct Joint {
    parent_pose: Pose,
    child_pose: Pose,
    limits: Option<(f32, f32)>,
    armature: f32,
    max_velocity: f32,
    friction_drive: Option<f32>,
}

struct Link {
    parent: Option<usize>,
    pose: Pose,
    mass: f32,
    cmass: Pose,
    inertia: [f32; 3],
    shapes: Vec<(Geom, Pose)>,
    joint: Option<Joint>,
}

#[derive(Default)]
struct Scene {
    dt: f32,
    gravity: [f32; 3],
    tgs: bool,
    iterations: [u32; 2],
    bounce_threshold: f32,
    friction_offset_threshold: f32,
    friction_correlation: f32,
    stabilization: bool,
    enhanced_determinism: bool,
    material: [f32; 3],
    ground: bool,
    contact_offset: f32,
    rest_offset: f32,
    self_collision: bool,
    max_velocities: [f32; 3], // linear, angular, depenetration
    links: Vec<Link>,
    root: Pose,
    root_velocity: [f32; 6], // COM linear, angular (world)
    q: Vec<f32>,
    qd: Vec<f32>,
    forces: Vec<Vec<f32>>,
}

/// Tokens of one record, with labelled reads.
struct Rec<'a>(std::str::SplitWhitespace<'a>);

impl Rec<'_> {
    fn word(&mut self) -> &str {
        self.0.next().expect("truncated record")
    }
    fn label(&mut self, l: &str) -> &mut Self {
        assert_eq!(self.word(), l, "scene.txt: expected label {l}");
        self
    }
    fn f(&mut self) -> f32 {
        self.word().parse().expect("number")
    }
    fn n<const N: usize>(&mut self) -> [f32; N] {
        std::array::from_fn(|_| self.f())
    }
    fn flag(&mut self) -> bool {
        self.word() == "1"
    }
    fn rest(&mut self) -> Vec<f32> {
        self.0.by_ref().map(|t| t.parse().expect("number")).collect()
    }
}

fn parse(text: &str) -> Scene {
    let mut s = Scene::default();
    for line in text.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty()) {
        let mut r = Rec(line.split_whitespace());
        match r.word() {
            "dt" => s.dt = r.f(),
            "scene" => {
                s.gravity = r.label("gravity").n();
                s.tgs = r.label("solver").word() == "tgs";
                s.iterations = [r.label("iterations").f() as u32, r.f() as u32];
                s.bounce_threshold = r.label("bounce_threshold_velocity").f();
                s.friction_offset_threshold = r.label("friction_offset_threshold").f();
                s.friction_correlation = r.label("friction_correlation_distance").f();
                s.stabilization = r.label("stabilization").flag();
                s.enhanced_determinism = r.label("enhanced_determinism").flag();
            }
            "material" => s.material = [r.label("static").f(), r.label("dynamic").f(), r.label("restitution").f()],
            "ground" => s.ground = r.flag(),
            "shapes" => [s.contact_offset, s.rest_offset] = [r.label("contact_offset").f(), r.label("rest_offset").f()],
            "articulation" => {
                s.self_collision = r.label("self_collision").flag();
                s.max_velocities = [
                    r.label("max_linear_velocity").f(),
                    r.label("max_angular_velocity").f(),
                    r.label("max_depenetration_velocity").f(),
                ];
            }
            "link" => {
                assert_eq!(r.word().parse::<usize>().ok(), Some(s.links.len()), "links in order");
                let parent = r.label("parent").word().parse().ok();
                s.links.push(Link {
                    parent,
                    pose: r.label("pose").n(),
                    mass: r.label("mass").f(),
                    cmass: r.label("cmass").n(),
                    inertia: r.label("inertia").n(),
                    shapes: Vec::new(),
                    joint: None,
                });
            }
            "shape" => {
                r.word();
                let g = match r.word() {
                    "box" => Geom::Box(r.n()),
                    "sphere" => Geom::Sphere(r.f()),
                    "capsule" => Geom::Capsule(r.f(), r.f()),
                    other => panic!("unknown shape {other}"),
                };
                let local = r.label("local").n();
                s.links.last_mut().expect("shape before link").shapes.push((g, local));
            }
            "joint" => {
                r.word();
                let parent_pose = r.label("parent_pose").n();
                let child_pose = r.label("child_pose").n();
                let lo = r.label("limits").word().to_string();
                let limits = (lo != "free").then(|| (lo.parse().expect("limit"), r.f()));
                let armature = r.label("armature").f();
                let max_velocity = r.label("max_joint_velocity").f();
                let friction_drive = r.label("friction_drive").word().parse().ok();
                let j = Joint { parent_pose, child_pose, limits, armature, max_velocity, friction_drive };
                s.links.last_mut().expect("joint before link").joint = Some(j);
            }
            "state" => {
                s.root = r.label("root").n();
                let [a, b, c] = r.label("lin_vel").n();
                let [d, e, f] = r.label("ang_vel").n();
                s.root_velocity = [a, b, c, d, e, f];
            }
            "q" => s.q = r.rest(),
            "qd" => s.qd = r.rest(),
            "force" => {
                assert_eq!(r.word().parse::<usize>().ok(), Some(s.forces.len()), "force steps in order");
                s.forces.push(r.rest());
            }
            other => panic!("scene.txt: unknown record {other}"),
        }
    }
    s
}

fn vec3(v: [f32; 3]) -> px::PxVec3 {
    px::PxVec3 { x: v[0], y: v[1], z: v[2] }
}

fn transform(p: &Pose) -> px::PxTransform {
    px::PxTransform { q: px::PxQuat { x: p[3], y: p[4], z: p[5], w: p[6] }, p: vec3([p[0], p[1], p[2]]) }
}

/// A contact point as reported for one step (actors as addresses, to be matched against the links).
struct Point {
    actors: [usize; 2],
    position: [f32; 3],
    separation: f32,
    impulse: [f32; 3],
}

/// Contact points reported in one step.
#[derive(Default)]
struct Reports {
    points: Vec<Point>,
}

unsafe extern "C" fn on_contact(
    user: *mut c_void,
    header: *const px::PxContactPairHeader,
    pairs: *const px::PxContactPair,
    nb_pairs: u32,
) {
    // Called on the thread that calls fetchResults (the dispatcher has no worker threads).
    // SAFETY: `user` is run()'s `Reports`, alive while its scene simulates; `header` is valid during the call.
    let (reports, header) = unsafe { (&mut *(user as *mut Reports), &*header) };
    let actors = header.actors.map(|a| a as usize);
    for i in 0..nb_pairs as usize {
        // SAFETY: `pairs` holds `nb_pairs` entries.
        let pair = unsafe { &*pairs.add(i) };
        let mut buf = vec![
            px::PxContactPairPoint {
                position: vec3([0.0; 3]),
                separation: 0.0,
                normal: vec3([0.0; 3]),
                internalFaceIndex0: 0,
                impulse: vec3([0.0; 3]),
                internalFaceIndex1: 0,
            };
            usize::from(pair.contactCount)
        ];
        // SAFETY: `buf` has room for contactCount points.
        let n = unsafe { px::PxContactPair_extractContacts(pair, buf.as_mut_ptr(), buf.len() as u32) };
        for p in &buf[..n as usize] {
            reports.points.push(Point {
                actors,
                position: [p.position.x, p.position.y, p.position.z],
                separation: p.separation,
                impulse: [p.impulse.x, p.impulse.y, p.impulse.z],
            });
        }
    }
}

unsafe extern "C" fn filter_shader(info: *mut px::FilterShaderCallbackInfo) -> px::PxFilterFlags {
    // PhysX's default shader ran first; this adds contact reports with points.
    // SAFETY: PhysX passes a valid info block whose pairFlags pointer is writable during the call.
    unsafe {
        *(*info).pairFlags |= px::PxPairFlags::SolveContact
            | px::PxPairFlags::DetectDiscreteContact
            | px::PxPairFlags::NotifyTouchFound
            | px::PxPairFlags::NotifyTouchPersists
            | px::PxPairFlags::NotifyContactPoints;
    }
    px::PxFilterFlags::empty()
}

unsafe extern "C" fn on_error(
    code: px::PxErrorCode,
    message: *const std::ffi::c_char,
    _file: *const std::ffi::c_char,
    _line: u32,
    _user: *const c_void,
) {
    // SAFETY: PhysX passes a NUL-terminated message valid for the call.
    eprintln!("PhysX {code:?}: {}", unsafe { std::ffi::CStr::from_ptr(message) }.to_string_lossy());
}

struct World {
    scene: *mut px::PxScene,
    ground: usize,
    links: Vec<*mut px::PxArticulationLink>,
    cache: *mut px::PxArticulationCache,
    art: *mut px::PxArticulationReducedCoordinate,
    /// Cache index of the inbound DoF of link k + 1.
    dof: Vec<usize>,
}

/// Builds the scene as ulab's adapter does (crates/diff-physics/src/physx/ffi.rs, `World::build`).
fn build(physics: *mut px::PxPhysics, s: &Scene, friction_offset: f32, reports: *mut Reports) -> World {
    // SAFETY: `physics` is valid; every created object lives until the process ends (a reproducer leaks them).
    unsafe {
        let mut sd = px::PxSceneDesc_new(px::PxPhysics_getTolerancesScale(physics));
        sd.gravity = vec3(s.gravity);
        let dispatcher = px::phys_PxDefaultCpuDispatcherCreate(
            0,
            null_mut(),
            px::PxDefaultCpuDispatcherWaitForWorkMode::WaitForWork,
            0,
        );
        sd.cpuDispatcher = dispatcher as *mut px::PxCpuDispatcher;
        px::enable_custom_filter_shader(&mut sd, filter_shader, 1);
        let info = px::SimulationEventCallbackInfo {
            collision_callback: Some(on_contact),
            collision_user_data: reports as *mut c_void,
            ..Default::default()
        };
        sd.simulationEventCallback = px::create_simulation_event_callbacks(&info);
        sd.solverType = if s.tgs { px::PxSolverType::Tgs } else { px::PxSolverType::Pgs };
        sd.bounceThresholdVelocity = s.bounce_threshold;
        sd.frictionOffsetThreshold = friction_offset;
        sd.frictionCorrelationDistance = s.friction_correlation;
        sd.flags.set(px::PxSceneFlags::EnableStabilization, s.stabilization);
        sd.flags.set(px::PxSceneFlags::EnableEnhancedDeterminism, s.enhanced_determinism);
        let scene = px::PxPhysics_createScene_mut(physics, &sd);
        let [st, dy, re] = s.material;
        let material = px::PxPhysics_createMaterial_mut(physics, st, dy, re);
        px::PxMaterial_setFrictionCombineMode_mut(material, px::PxCombineMode::Average);
        px::PxMaterial_setRestitutionCombineMode_mut(material, px::PxCombineMode::Average);
        let mut ground = null_mut();
        if s.ground {
            ground = px::phys_PxCreatePlane(physics, &px::PxPlane_new_1(0.0, 0.0, 1.0, 0.0), material);
            let mut shape: *mut px::PxShape = null_mut();
            px::PxRigidActor_getShapes(ground as *const px::PxRigidActor, &mut shape, 1, 0);
            px::PxShape_setContactOffset_mut(shape, s.contact_offset);
            px::PxShape_setRestOffset_mut(shape, s.rest_offset);
            px::PxScene_addActor_mut(scene, ground as *mut px::PxActor, std::ptr::null());
        }

        let art = px::PxPhysics_createArticulationReducedCoordinate_mut(physics);
        px::PxArticulationReducedCoordinate_setArticulationFlag_mut(
            art,
            px::PxArticulationFlag::DisableSelfCollision,
            !s.self_collision,
        );
        px::PxArticulationReducedCoordinate_setArticulationFlag_mut(
            art,
            px::PxArticulationFlag::DriveLimitsAreForces,
            true,
        );
        px::PxArticulationReducedCoordinate_setSolverIterationCounts_mut(art, s.iterations[0], s.iterations[1]);
        px::PxArticulationReducedCoordinate_setSleepThreshold_mut(art, 0.0);
        let mut links = Vec::new();
        for l in &s.links {
            let parent = l.parent.map_or(null_mut(), |p| links[p]);
            let link = px::PxArticulationReducedCoordinate_createLink_mut(art, parent, &transform(&l.pose));
            links.push(link);
            let body = link as *mut px::PxRigidBody;
            px::PxRigidBody_setMass_mut(body, l.mass);
            px::PxRigidBody_setCMassLocalPose_mut(body, &transform(&l.cmass));
            px::PxRigidBody_setMassSpaceInertiaTensor_mut(body, &vec3(l.inertia));
            px::PxRigidBody_setLinearDamping_mut(body, 0.0);
            px::PxRigidBody_setAngularDamping_mut(body, 0.0);
            px::PxRigidBody_setMaxLinearVelocity_mut(body, s.max_velocities[0]);
            px::PxRigidBody_setMaxAngularVelocity_mut(body, s.max_velocities[1]);
            px::PxRigidBody_setMaxDepenetrationVelocity_mut(body, s.max_velocities[2]);
            for (g, local) in &l.shapes {
                let (actor, flags) = (link as *mut px::PxRigidActor, px::PxShapeFlags::SimulationShape);
                let shape = match *g {
                    Geom::Box([x, y, z]) => {
                        let g = px::PxBoxGeometry_new(x, y, z);
                        px::PxRigidActorExt_createExclusiveShape_1(actor, &g as *const _ as _, material, flags)
                    }
                    Geom::Sphere(r) => {
                        let g = px::PxSphereGeometry_new(r);
                        px::PxRigidActorExt_createExclusiveShape_1(actor, &g as *const _ as _, material, flags)
                    }
                    Geom::Capsule(r, h) => {
                        let g = px::PxCapsuleGeometry_new(r, h);
                        px::PxRigidActorExt_createExclusiveShape_1(actor, &g as *const _ as _, material, flags)
                    }
                };
                px::PxShape_setLocalPose_mut(shape, &transform(local));
                px::PxShape_setContactOffset_mut(shape, s.contact_offset);
                px::PxShape_setRestOffset_mut(shape, s.rest_offset);
            }
            if let Some(j) = &l.joint {
                let jt = px::PxArticulationLink_getInboundJoint(link);
                let tw = px::PxArticulationAxis::Twist;
                px::PxArticulationJointReducedCoordinate_setJointType_mut(jt, px::PxArticulationJointType::Revolute);
                px::PxArticulationJointReducedCoordinate_setParentPose_mut(jt, &transform(&j.parent_pose));
                px::PxArticulationJointReducedCoordinate_setChildPose_mut(jt, &transform(&j.child_pose));
                if let Some((low, high)) = j.limits {
                    px::PxArticulationJointReducedCoordinate_setMotion_mut(jt, tw, px::PxArticulationMotion::Limited);
                    px::PxArticulationJointReducedCoordinate_setLimitParams_mut(
                        jt,
                        tw,
                        &px::PxArticulationLimit { low, high },
                    );
                } else {
                    px::PxArticulationJointReducedCoordinate_setMotion_mut(jt, tw, px::PxArticulationMotion::Free);
                }
                px::PxArticulationJointReducedCoordinate_setArmature_mut(jt, tw, j.armature);
                px::PxArticulationJointReducedCoordinate_setFrictionCoefficient_mut(jt, 0.0);
                px::PxArticulationJointReducedCoordinate_setMaxJointVelocity_mut(jt, j.max_velocity);
                if let Some(max_force) = j.friction_drive {
                    // Joint dry friction: velocity drive to 0, bounded by max_force (N·m).
                    let drive = px::PxArticulationDrive {
                        stiffness: 0.0,
                        damping: 1.0,
                        maxForce: max_force,
                        driveType: px::PxArticulationDriveType::Velocity,
                    };
                    px::PxArticulationJointReducedCoordinate_setDriveParams_mut(jt, tw, &drive);
                    px::PxArticulationJointReducedCoordinate_setDriveVelocity_mut(jt, tw, 0.0, false);
                }
            }
        }
        assert!(px::PxScene_addArticulation_mut(scene, art), "addArticulation failed");
        let cache = px::PxArticulationReducedCoordinate_createCache(art);
        // Cache DoF order follows PhysX's internal link order (one DoF per non-root link).
        let index: Vec<usize> = links.iter().map(|&l| px::PxArticulationLink_getLinkIndex(l) as usize).collect();
        let dof = index[1..].iter().map(|&k| k - 1).collect();
        World { scene, ground: ground as usize, links, cache, art, dof }
    }
}

impl World {
    /// Sets the articulation state as the adapter does (`World::set_state`).
    fn set_state(&mut self, s: &Scene) {
        // SAFETY: the cache's per-DoF arrays have one entry per DoF (links − 1); no simulation is running.
        unsafe {
            let c = &mut *self.cache;
            for (k, &d) in self.dof.iter().enumerate() {
                *c.jointPosition.add(d) = s.q[k];
                *c.jointVelocity.add(d) = s.qd[k];
                *c.jointForce.add(d) = 0.0;
            }
            let root = &mut *c.rootLinkData;
            root.transform = transform(&s.root);
            let v = s.root_velocity;
            root.worldLinVel = vec3([v[0], v[1], v[2]]);
            root.worldAngVel = vec3([v[3], v[4], v[5]]);
            let flags = px::PxArticulationCacheFlags::Position
                | px::PxArticulationCacheFlags::Velocity
                | px::PxArticulationCacheFlags::Force
                | px::PxArticulationCacheFlags::RootTransform
                | px::PxArticulationCacheFlags::RootVelocities;
            px::PxArticulationReducedCoordinate_applyCache_mut(self.art, self.cache, flags, true);
            let root_body = self.links[0] as *mut px::PxRigidBody;
            px::PxRigidBody_clearForce_mut(root_body, px::PxForceMode::Force);
            px::PxRigidBody_clearTorque_mut(root_body, px::PxForceMode::Force);
        }
    }

    fn set_joint_forces(&mut self, f: &[f32]) {
        // SAFETY: as in set_state.
        unsafe {
            for (k, &d) in self.dof.iter().enumerate() {
                *(*self.cache).jointForce.add(d) = f[k];
            }
            let flags = px::PxArticulationCacheFlags::Force;
            px::PxArticulationReducedCoordinate_applyCache_mut(self.art, self.cache, flags, true);
        }
    }

    /// Mass-weighted sum of link COM velocities (momentum, world frame) and the total mass.
    fn momentum(&self) -> ([f64; 3], f64) {
        let (mut p, mut m) = ([0.0; 3], 0.0);
        for &l in &self.links {
            // SAFETY: links are valid; no simulation is running.
            let (v, mass) = unsafe {
                let b = l as *const px::PxRigidBody;
                (px::PxRigidBody_getLinearVelocity(b), f64::from(px::PxRigidBody_getMass(b)))
            };
            for (pk, vk) in p.iter_mut().zip([v.x, v.y, v.z]) {
                *pk += mass * f64::from(vk);
            }
            m += mass;
        }
        (p, m)
    }

    /// Per link: link pose, then COM position, COM linear velocity and angular velocity (world frame).
    fn kinematics(&self) -> Vec<(px::PxTransform, [[f32; 3]; 3])> {
        let v = |v: px::PxVec3| [v.x, v.y, v.z];
        self.links
            .iter()
            .map(|&l| {
                // SAFETY: links are valid; no simulation is running.
                let (pose, cmass, lin, ang) = unsafe {
                    let b = l as *const px::PxRigidBody;
                    let pose = px::PxRigidActor_getGlobalPose(l as *const px::PxRigidActor);
                    let cm = px::PxRigidBody_getCMassLocalPose(b);
                    (pose, cm, px::PxRigidBody_getLinearVelocity(b), px::PxRigidBody_getAngularVelocity(b))
                };
                let c = rotate(pose.q, v(cmass.p));
                (pose, [[pose.p.x + c[0], pose.p.y + c[1], pose.p.z + c[2]], v(lin), v(ang)])
            })
            .collect()
    }

    fn step(&mut self, dt: f32) {
        // SAFETY: the scene is valid; fetchResults(block) returns when the step is done.
        unsafe {
            assert!(px::PxScene_simulate_mut(self.scene, dt, null_mut(), null_mut(), 0, true));
            let mut err = 0u32;
            assert!(px::PxScene_fetchResults_mut(self.scene, true, &mut err));
        }
    }
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Rotates `v` by the unit quaternion `q`: v + 2w (u × v) + 2 u × (u × v).
fn rotate(q: px::PxQuat, v: [f32; 3]) -> [f32; 3] {
    let u = [q.x, q.y, q.z];
    let t = cross(u, v).map(|x| 2.0 * x);
    let ut = cross(u, t);
    std::array::from_fn(|i| v[i] + q.w * t[i] + ut[i])
}

/// Runs the scene with the given friction offset threshold; returns the number of steps showing the fault.
fn run(physics: *mut px::PxPhysics, s: &Scene, friction_offset: f32) -> usize {
    let mut reports = Box::new(Reports::default());
    let mut w = build(physics, s, friction_offset, &mut *reports);
    w.set_state(s);
    let g = f64::from(s.gravity[2]);
    println!("\nfrictionOffsetThreshold = {friction_offset} m (COM acceleration a in m/s², world frame)");
    println!("step       a_x       a_y       a_z    |a_xy|  points  normal impulse  links (index)");
    let (mut faults, mut quiet) = (0, Vec::new());
    for (k, f) in s.forces.iter().enumerate() {
        let ((p0, m), kin) = (w.momentum(), w.kinematics());
        w.set_joint_forces(f);
        reports.points.clear();
        w.step(s.dt);
        let ((p1, _), kin_after) = (w.momentum(), w.kinematics());
        let a: [f64; 3] = std::array::from_fn(|i| (p1[i] - p0[i]) / (m * f64::from(s.dt)));
        let horizontal = a[0].hypot(a[1]);
        let norm = |v: [f32; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let impulse: f32 = reports.points.iter().map(|p| norm(p.impulse)).sum();
        let link_of = |p: &Point| p.actors.iter().find_map(|&a| w.links.iter().position(|&l| l as usize == a));
        let fault = impulse == 0.0 && (horizontal > f64::from(TOLERANCE) || (a[2] - g).abs() > f64::from(TOLERANCE));
        faults += usize::from(fault);
        if reports.points.is_empty() && !fault {
            quiet.push((k, horizontal, a[2]));
            continue;
        }
        if let (Some(first), Some(last)) = (quiet.first(), quiet.last()) {
            let h = quiet.iter().map(|q| q.1).fold(0.0, f64::max);
            let z = quiet.iter().map(|q| (q.2 - g).abs()).fold(0.0, f64::max);
            println!("{:>4}-{}: no contact points, |a_xy| <= {h:.4}, |a_z - g_z| <= {z:.4}", first.0, last.0);
            quiet.clear();
        }
        let links: Vec<usize> = reports.points.iter().filter_map(link_of).collect();
        println!(
            "{k:>4} {:>9.4} {:>9.4} {:>9.4} {horizontal:>9.4}  {:>6} {impulse:>11.6} N·s  {links:?}{}",
            a[0],
            a[1],
            a[2],
            reports.points.len(),
            if fault { "  <- no normal impulse, yet not free fall" } else { "" }
        );
        // Each point against the ground (plane z = 0): its gap, how fast the link closes it (before the step),
        // and where the link's nearest point is after the step.
        for p in reports.points.iter().filter(|p| p.actors.contains(&w.ground)) {
            let Some(l) = link_of(p) else { continue };
            let (pose, [c, v, om]) = kin[l];
            let r = std::array::from_fn(|i| p.position[i] - c[i]);
            let closing = -(v[2] + cross(om, r)[2]);
            let near = [p.position[0], p.position[1], p.position[2] + p.separation];
            let inverse = px::PxQuat { x: -pose.q.x, y: -pose.q.y, z: -pose.q.z, w: pose.q.w };
            let local = rotate(inverse, std::array::from_fn(|i| near[i] - [pose.p.x, pose.p.y, pose.p.z][i]));
            let after = kin_after[l].0;
            let gap_after = after.p.z + rotate(after.q, local)[2];
            println!(
                "        link {l}: gap {:.3} mm closing at {closing:.4} m/s, gap after the step {:.3} mm, \
                 normal impulse {:.6} N·s",
                p.separation * 1e3,
                gap_after * 1e3,
                norm(p.impulse)
            );
        }
    }
    faults
}

fn main() {
    let path = std::env::args().nth(1).unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/scene.txt").into());
    let scene = parse(&std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}")));
    let name = std::path::Path::new(&path).file_name().map_or(path.clone(), |n| n.to_string_lossy().into_owned());
    println!(
        "PhysX 5.1.3 (physx-sys 0.11.5), {name}: {} links, {} steps of {} s, gravity {:?}",
        scene.links.len(),
        scene.forces.len(),
        scene.dt,
        scene.gravity
    );
    // SAFETY: one foundation and one physics object per process, created once and never released.
    let physics = unsafe {
        let version = px::version(5, 1, 3);
        let errors = px::create_error_callback(on_error, null_mut());
        let foundation = px::phys_PxCreateFoundation(version, px::get_default_allocator() as *mut _, errors);
        let scale = px::PxTolerancesScale_new(1.0, 10.0);
        px::phys_PxCreatePhysics(version, foundation, &scale, false, null_mut(), null_mut())
    };
    let mut verdicts = Vec::new();
    for threshold in [scene.friction_offset_threshold, 0.001] {
        verdicts.push((threshold, run(physics, &scene, threshold)));
    }
    println!("\nExpectation: in a step without normal impulse the only external force is gravity:");
    println!("|a_xy| and |a_z - g_z| below {TOLERANCE} m/s², whatever the joint forces.");
    for (threshold, faults) in &verdicts {
        let v = if *faults == 0 { "as expected".to_string() } else { format!("WRONG in {faults} step(s)") };
        println!("frictionOffsetThreshold {threshold} m: {v}");
    }
    std::process::exit(i32::from(verdicts.iter().any(|v| v.1 > 0)));
}
