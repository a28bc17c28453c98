// Adapter body shared by the rapier versions with the glam API and `PhysicsWorld` (0.33 and later).
// Included (`include!`) by each adapter's main.rs, where `rapier3d` is that adapter's pinned version.
use rapier3d::prelude::*;
use rediscovery_harness::{
    BallJointLimit, OffCentreLanding, RestitutionDrop, SceneError, Series, WeldedDrop, WeldedDropRun, GRAVITY,
};

/// The pinned rapier version, driven through the harness trait.
#[derive(Debug)]
struct Rapier {
    version: &'static str,
}

fn v3(x: f64, y: f64, z: f64) -> Vector {
    Vector::new(x as Real, y as Real, z as Real)
}

fn world() -> PhysicsWorld {
    let mut w = PhysicsWorld::new();
    w.gravity = v3(0.0, 0.0, -GRAVITY);
    w
}

/// Steps `w` for `duration` seconds, sampling `observe` after every step.
fn run(w: &mut PhysicsWorld, duration: f64, mut observe: impl FnMut(&PhysicsWorld, f64)) -> Result<(), SceneError> {
    let dt = f64::from(w.integration_parameters.dt);
    if dt.is_nan() || dt <= 0.0 {
        return Err(SceneError::Engine(format!("time step {dt}")));
    }
    let steps = (duration / dt).ceil() as usize;
    observe(w, 0.0);
    for i in 1..=steps {
        w.step();
        observe(w, i as f64 * dt);
    }
    Ok(())
}

fn quat(b: &RigidBody) -> (f64, f64, f64, f64) {
    let q = b.rotation();
    (f64::from(q.w), f64::from(q.x), f64::from(q.y), f64::from(q.z))
}

fn body(w: &PhysicsWorld, h: RigidBodyHandle) -> Result<&RigidBody, SceneError> {
    w.bodies.get(h).ok_or_else(|| SceneError::Engine("body vanished".into()))
}

impl rediscovery_harness::Engine for Rapier {
    fn label(&self) -> String {
        format!("rapier3d {}", self.version)
    }

    fn restitution_drop(&mut self, s: &RestitutionDrop, e: f64) -> Result<Series, SceneError> {
        let mut w = world();
        let ground = w.insert_body(RigidBodyBuilder::fixed().translation(v3(0.0, 0.0, -1.0)));
        w.insert_collider(ColliderBuilder::cuboid(10.0, 10.0, 1.0).restitution(e as Real), Some(ground));
        let ball = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(0.0, 0.0, s.radius + s.drop_height)));
        w.insert_collider(ColliderBuilder::ball(s.radius as Real).restitution(e as Real), Some(ball));
        let mut out = Series::new();
        let mut err = None;
        run(&mut w, s.duration, |w, t| match body(w, ball) {
            Ok(b) => out.push((t, f64::from(b.translation().z) - s.radius)),
            Err(e) => err = Some(e),
        })?;
        err.map_or(Ok(out), Err)
    }

    fn offcentre_landing(&mut self, s: &OffCentreLanding) -> Result<Series, SceneError> {
        let mut w = world();
        let [px, py, pz] = s.pedestal_half;
        let ped = w.insert_body(RigidBodyBuilder::fixed().translation(v3(0.0, 0.0, -pz)));
        w.insert_collider(ColliderBuilder::cuboid(px as Real, py as Real, pz as Real).friction(s.friction as Real), Some(ped));
        let [bx, by, bz] = s.bar_half;
        let bar = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(s.bar_x, 0.0, s.gap + bz)));
        w.insert_collider(ColliderBuilder::cuboid(bx as Real, by as Real, bz as Real).friction(s.friction as Real), Some(bar));
        let tip = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(s.bar_x + s.tip_offset, 0.0, s.gap + bz)));
        w.insert_collider(ColliderBuilder::ball(s.tip_radius as Real).friction(s.friction as Real), Some(tip));
        let weld = FixedJointBuilder::new().local_anchor1(v3(s.tip_offset, 0.0, 0.0)).local_anchor2(v3(0.0, 0.0, 0.0));
        w.insert_multibody_joint(bar, tip, weld).ok_or_else(|| SceneError::Engine("multibody joint refused".into()))?;
        let mut out = Series::new();
        let mut err = None;
        run(&mut w, s.duration, |w, t| match body(w, bar) {
            Ok(b) => {
                let (qw, qx, qy, qz) = quat(b);
                out.push((t, rediscovery_harness::x_axis_tilt(qw, qx, qy, qz)))
            }
            Err(e) => err = Some(e),
        })?;
        err.map_or(Ok(out), Err)
    }

    fn ball_joint_limit(&mut self, s: &BallJointLimit) -> Result<Series, SceneError> {
        let mut w = world();
        let base = w.insert_body(RigidBodyBuilder::fixed().translation(v3(0.0, 0.0, s.pivot_z)));
        let [rx, ry, rz] = s.rod_half;
        let rod = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(rx, 0.0, s.pivot_z)));
        w.insert_collider(ColliderBuilder::cuboid(rx as Real, ry as Real, rz as Real), Some(rod));
        let l = [-s.limit as Real, s.limit as Real];
        let joint = SphericalJointBuilder::new()
            .local_anchor1(v3(0.0, 0.0, 0.0))
            .local_anchor2(v3(-rx, 0.0, 0.0))
            .limits(JointAxis::AngX, l)
            .limits(JointAxis::AngY, l)
            .limits(JointAxis::AngZ, l);
        w.insert_multibody_joint(base, rod, joint).ok_or_else(|| SceneError::Engine("multibody joint refused".into()))?;
        let mut out = Series::new();
        let mut err = None;
        run(&mut w, s.duration, |w, t| match body(w, rod) {
            Ok(b) => {
                let (qw, qx, qy, qz) = quat(b);
                out.push((t, rediscovery_harness::quat_angle(qw, qx, qy, qz)))
            }
            Err(e) => err = Some(e),
        })?;
        err.map_or(Ok(out), Err)
    }

    fn welded_drop(&mut self, s: &WeldedDrop) -> Result<WeldedDropRun, SceneError> {
        let mut w = world();
        let ground = w.insert_body(RigidBodyBuilder::fixed().translation(v3(0.0, 0.0, -1.0)));
        w.insert_collider(ColliderBuilder::cuboid(10.0, 10.0, 1.0).friction(s.friction as Real), Some(ground));
        let z0 = s.radius + s.drop_height;
        let root = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(0.0, 0.0, z0)));
        w.insert_collider(ColliderBuilder::ball(s.radius as Real).friction(s.friction as Real), Some(root));
        let top = w.insert_body(RigidBodyBuilder::dynamic().translation(v3(0.0, 0.0, z0 + s.offset)));
        w.insert_collider(ColliderBuilder::ball(s.top_radius as Real).friction(s.friction as Real), Some(top));
        let weld = FixedJointBuilder::new().local_anchor1(v3(0.0, 0.0, s.offset)).local_anchor2(v3(0.0, 0.0, 0.0));
        w.insert_multibody_joint(root, top, weld).ok_or_else(|| SceneError::Engine("multibody joint refused".into()))?;
        let mut out = WeldedDropRun::default();
        let mut err = None;
        run(&mut w, s.duration, |w, t| match body(w, root) {
            Ok(b) => {
                out.speed.push((t, f64::from(b.linvel().length())));
                out.height.push((t, f64::from(b.translation().z)));
            }
            Err(e) => err = Some(e),
        })?;
        err.map_or(Ok(out), Err)
    }
}
