// Adapter body shared by the rapier versions with the nalgebra API and the explicit
// `PhysicsPipeline::step` (0.12 to 0.31). Included (`include!`) by each adapter's main.rs, which pins
// `rapier3d` and names that version's broad-phase type as `Broad`.
use rapier3d::prelude::*;
use rediscovery_harness::{
    BallJointLimit, OffCentreLanding, RestitutionDrop, SceneError, Series, WeldedDrop, WeldedDropRun, GRAVITY,
};

/// The pinned rapier version, driven through the harness trait.
#[derive(Debug)]
struct Rapier {
    version: &'static str,
}

fn v3(x: f64, y: f64, z: f64) -> Vector<Real> {
    Vector::new(x as Real, y as Real, z as Real)
}

fn p3(x: f64, y: f64, z: f64) -> Point<Real> {
    Point::new(x as Real, y as Real, z as Real)
}

/// Everything one scene needs, as the pre-`PhysicsWorld` API wants it.
struct World {
    pipeline: PhysicsPipeline,
    params: IntegrationParameters,
    islands: IslandManager,
    broad: Broad,
    narrow: NarrowPhase,
    bodies: RigidBodySet,
    colliders: ColliderSet,
    impulse_joints: ImpulseJointSet,
    multibody_joints: MultibodyJointSet,
    ccd: CCDSolver,
}

impl World {
    fn new() -> Self {
        World {
            pipeline: PhysicsPipeline::new(),
            params: IntegrationParameters::default(),
            islands: IslandManager::new(),
            broad: Broad::new(),
            narrow: NarrowPhase::new(),
            bodies: RigidBodySet::new(),
            colliders: ColliderSet::new(),
            impulse_joints: ImpulseJointSet::new(),
            multibody_joints: MultibodyJointSet::new(),
            ccd: CCDSolver::new(),
        }
    }

    fn insert_body(&mut self, b: RigidBodyBuilder) -> RigidBodyHandle {
        self.bodies.insert(b.build())
    }

    fn insert_collider(&mut self, c: ColliderBuilder, parent: RigidBodyHandle) {
        self.colliders.insert_with_parent(c.build(), parent, &mut self.bodies);
    }

    fn step(&mut self) {
        let gravity = v3(0.0, 0.0, -GRAVITY);
        self.pipeline.step(
            &gravity,
            &self.params,
            &mut self.islands,
            &mut self.broad,
            &mut self.narrow,
            &mut self.bodies,
            &mut self.colliders,
            &mut self.impulse_joints,
            &mut self.multibody_joints,
            &mut self.ccd,
            None,
            &(),
            &(),
        );
    }

    fn body(&self, h: RigidBodyHandle) -> Result<&RigidBody, SceneError> {
        self.bodies.get(h).ok_or_else(|| SceneError::Engine("body vanished".into()))
    }

    /// Steps for `duration` seconds, sampling `observe` after every step.
    fn run(&mut self, duration: f64, mut observe: impl FnMut(&World, f64)) -> Result<(), SceneError> {
        let dt = f64::from(self.params.dt);
        if dt.is_nan() || dt <= 0.0 {
            return Err(SceneError::Engine(format!("time step {dt}")));
        }
        let steps = (duration / dt).ceil() as usize;
        observe(self, 0.0);
        for i in 1..=steps {
            self.step();
            observe(self, i as f64 * dt);
        }
        Ok(())
    }
}

fn quat(b: &RigidBody) -> (f64, f64, f64, f64) {
    let q = b.rotation();
    (f64::from(q.w), f64::from(q.i), f64::from(q.j), f64::from(q.k))
}

impl rediscovery_harness::Engine for Rapier {
    fn label(&self) -> String {
        format!("rapier3d {}", self.version)
    }

    fn restitution_drop(&mut self, s: &RestitutionDrop, e: f64) -> Result<Series, SceneError> {
        let mut w = World::new();
        let ground = w.insert_body(RigidBodyBuilder::fixed().translation(v3(0.0, 0.0, -1.0)));
        w.insert_collider(ColliderBuilder::cuboid(10.0, 10.0, 1.0).restitution(e as Real), ground);
        let ball = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(0.0, 0.0, s.radius + s.drop_height)));
        w.insert_collider(ColliderBuilder::ball(s.radius as Real).restitution(e as Real), ball);
        let mut out = Series::new();
        let mut err = None;
        w.run(s.duration, |w, t| match w.body(ball) {
            Ok(b) => out.push((t, f64::from(b.translation().z) - s.radius)),
            Err(e) => err = Some(e),
        })?;
        err.map_or(Ok(out), Err)
    }

    fn offcentre_landing(&mut self, s: &OffCentreLanding) -> Result<Series, SceneError> {
        let mut w = World::new();
        let [px, py, pz] = s.pedestal_half;
        let ped = w.insert_body(RigidBodyBuilder::fixed().translation(v3(0.0, 0.0, -pz)));
        w.insert_collider(ColliderBuilder::cuboid(px as Real, py as Real, pz as Real).friction(s.friction as Real), ped);
        let [bx, by, bz] = s.bar_half;
        let bar = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(s.bar_x, 0.0, s.gap + bz)));
        w.insert_collider(ColliderBuilder::cuboid(bx as Real, by as Real, bz as Real).friction(s.friction as Real), bar);
        let tip = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(s.bar_x + s.tip_offset, 0.0, s.gap + bz)));
        w.insert_collider(ColliderBuilder::ball(s.tip_radius as Real).friction(s.friction as Real), tip);
        let weld = FixedJointBuilder::new().local_anchor1(p3(s.tip_offset, 0.0, 0.0)).local_anchor2(p3(0.0, 0.0, 0.0));
        w.multibody_joints
            .insert(bar, tip, weld, true)
            .ok_or_else(|| SceneError::Engine("multibody joint refused".into()))?;
        let mut out = Series::new();
        let mut err = None;
        w.run(s.duration, |w, t| match w.body(bar) {
            Ok(b) => {
                let (qw, qx, qy, qz) = quat(b);
                out.push((t, rediscovery_harness::x_axis_tilt(qw, qx, qy, qz)))
            }
            Err(e) => err = Some(e),
        })?;
        err.map_or(Ok(out), Err)
    }

    fn ball_joint_limit(&mut self, s: &BallJointLimit) -> Result<Series, SceneError> {
        let mut w = World::new();
        let base = w.insert_body(RigidBodyBuilder::fixed().translation(v3(0.0, 0.0, s.pivot_z)));
        let [rx, ry, rz] = s.rod_half;
        let rod = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(rx, 0.0, s.pivot_z)));
        w.insert_collider(ColliderBuilder::cuboid(rx as Real, ry as Real, rz as Real), rod);
        let l = [-s.limit as Real, s.limit as Real];
        let joint = SphericalJointBuilder::new()
            .local_anchor1(p3(0.0, 0.0, 0.0))
            .local_anchor2(p3(-rx, 0.0, 0.0))
            .limits(JointAxis::AngX, l)
            .limits(JointAxis::AngY, l)
            .limits(JointAxis::AngZ, l);
        w.multibody_joints
            .insert(base, rod, joint, true)
            .ok_or_else(|| SceneError::Engine("multibody joint refused".into()))?;
        let mut out = Series::new();
        let mut err = None;
        w.run(s.duration, |w, t| match w.body(rod) {
            Ok(b) => {
                let (qw, qx, qy, qz) = quat(b);
                out.push((t, rediscovery_harness::quat_angle(qw, qx, qy, qz)))
            }
            Err(e) => err = Some(e),
        })?;
        err.map_or(Ok(out), Err)
    }

    fn welded_drop(&mut self, s: &WeldedDrop) -> Result<WeldedDropRun, SceneError> {
        let mut w = World::new();
        let ground = w.insert_body(RigidBodyBuilder::fixed().translation(v3(0.0, 0.0, -1.0)));
        w.insert_collider(ColliderBuilder::cuboid(10.0, 10.0, 1.0).friction(s.friction as Real), ground);
        let z0 = s.radius + s.drop_height;
        let root = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(0.0, 0.0, z0)));
        w.insert_collider(ColliderBuilder::ball(s.radius as Real).friction(s.friction as Real), root);
        let top = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(0.0, 0.0, z0 + s.offset)));
        w.insert_collider(ColliderBuilder::ball(s.top_radius as Real).friction(s.friction as Real), top);
        let weld = FixedJointBuilder::new().local_anchor1(p3(0.0, 0.0, s.offset)).local_anchor2(p3(0.0, 0.0, 0.0));
        w.multibody_joints
            .insert(root, top, weld, true)
            .ok_or_else(|| SceneError::Engine("multibody joint refused".into()))?;
        let mut out = WeldedDropRun::default();
        let mut err = None;
        w.run(s.duration, |w, t| match w.body(root) {
            Ok(b) => {
                out.speed.push((t, f64::from(b.linvel().norm())));
                out.height.push((t, f64::from(b.translation().z)));
            }
            Err(e) => err = Some(e),
        })?;
        err.map_or(Ok(out), Err)
    }
}
