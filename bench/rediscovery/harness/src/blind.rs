//! Blind mode of the cross-engine set (issue 63): random but valid scenes from a grammar, judged by the same
//! invariants as the hand-written scenes (`physics-invariants`), with no knowledge of which bug a version has.
//!
//! A [`World`] is data (JSON): rigid bodies in trees (a root is a floating base or is jointed to the world),
//! joints fixed / hinge / slide / free, primitives (box, sphere, capsule, cylinder) on the bodies, an optional
//! support (plane or box) whose top face is z = 0, contact parameters. The Python adapters
//! (`../adapters/python/scenes_*.py`, kind `world`) build it with each engine's own API and report, every
//! `record_every` steps, each body's pose and velocities; [`judge_world`] applies the invariants:
//!
//! * finite state (every engine, every scene);
//! * penetration into the support over the last `settle` seconds ≤ [`inv::PENETRATION_MAX`], from the
//!   reported poses and the known geometry (not from the engine's contact report);
//! * passivity: mechanical energy (computed here from poses, velocities, masses and inertias) must not grow by
//!   more than [`inv::energy_tolerance`]`(0)` (no actuator does work) — only when nothing overlaps at the start
//!   (or contacts are off), because resolving an initial overlap legitimately injects energy.
//!
//! [`generate`] is seeded and deterministic; [`reductions`] lists the one-step simplifications the minimiser
//! (delta debugging over bodies, geoms and attributes, in the `blind` binary) tries.
use crate::cross::{Observation, Support};
use crate::Verdict;
use physics_invariants as inv;
use serde::{Deserialize, Serialize};

/// A collision primitive; capsules and cylinders lie along the geom's local z axis.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Shape {
    Box { half: [f64; 3] },
    Sphere { radius: f64 },
    Capsule { radius: f64, half_length: f64 },
    Cylinder { radius: f64, half_length: f64 },
}

/// A primitive at a pose in its body's frame.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct BGeom {
    pub shape: Shape,
    pub pos: [f64; 3],
    /// `[w, x, y, z]`.
    pub quat: [f64; 4],
    pub friction: f64,
}

/// The joint between a body and its parent (or the world), located at the body's `anchor`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Joint {
    /// Floating base (roots only): initial world velocities of the centre of mass.
    Free { linvel: [f64; 3], angvel: [f64; 3] },
    /// Welded to the parent; with `World::fuse_static` an engine may merge it into its parent.
    Fixed,
    /// Rotation about `axis` (body frame). `limit` = `[lower, upper]`, possibly inverted (lower > upper).
    Hinge { axis: [f64; 3], limit: Option<[f64; 2]>, q0: f64, v0: f64 },
    /// Translation along `axis` (body frame).
    Slide { axis: [f64; 3], limit: Option<[f64; 2]>, q0: f64, v0: f64 },
}

/// A rigid body. Its frame is its centre-of-mass frame, in which the inertia is diagonal.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Body {
    /// Index of the parent body (always smaller than this body's); `None`: a root (free or jointed to the world).
    pub parent: Option<usize>,
    pub joint: Joint,
    /// Pose of the body frame in the parent's frame (the world for roots) at q = 0; for free roots the initial pose.
    pub pos: [f64; 3],
    pub quat: [f64; 4],
    /// The joint's location in the body frame.
    pub anchor: [f64; 3],
    pub mass: f64,
    pub inertia: [f64; 3],
    pub geoms: Vec<BGeom>,
    /// Generalized force of this body's joint for the inverse-dynamics probe (see [`id_residual`]): a free root
    /// `[fx, fy, fz, tx, ty, tz]` (world force at the centre of mass, world torque), a hinge or slide `[tau]`,
    /// empty otherwise. Absent in scenes saved before the probe existed (then zero forces).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub probe: Vec<f64>,
}

/// A generated scene.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct World {
    pub id: String,
    pub dt: f64,
    pub duration: f64,
    pub gravity: f64,
    /// The adapter reports the state every `record_every` steps (and at t = 0).
    pub record_every: usize,
    /// The penetration invariant covers the last `settle` seconds.
    pub settle: f64,
    /// Fixed support whose top face is z = 0 (a box support is centred at (0, 0, −half[2])).
    pub support: Option<Support>,
    /// Contacts on: between the support and every body, and between bodies of different trees (never within
    /// a tree). Off: no contact at all.
    pub collide: bool,
    /// Let the engine fuse jointless (fixed) bodies into their parents (MuJoCo `fusestatic`).
    pub fuse_static: bool,
    /// Soft-contact time constant for engines that have one (MuJoCo `solref`); `None`: engine default.
    pub contact_timeconst: Option<f64>,
    pub bodies: Vec<Body>,
}

// ---- deterministic random numbers ----------------------------------------------------------------

/// SplitMix64: small, seedable, the same sequence on every platform.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    /// Log-uniform in [lo, hi] (both > 0): sizes and masses across orders of magnitude.
    pub fn log_range(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.unit()).exp()
    }
    pub fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.unit() * n as f64) as usize % n.max(1)
    }
    fn vec3(&mut self, a: f64) -> [f64; 3] {
        [self.range(-a, a), self.range(-a, a), self.range(-a, a)]
    }
    fn unit_quat(&mut self) -> [f64; 4] {
        let v = [self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0)];
        let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if n < 1e-3 {
            IDENTITY
        } else {
            v.map(|x| x / n)
        }
    }
    fn axis(&mut self) -> [f64; 3] {
        if self.chance(0.6) {
            let mut a = [0.0; 3];
            a[self.below(3)] = 1.0;
            a
        } else {
            let v = self.vec3(1.0);
            let n = norm(v);
            if n < 1e-3 {
                [0.0, 0.0, 1.0]
            } else {
                v.map(|x| x / n)
            }
        }
    }
}

// ---- small rigid-body algebra --------------------------------------------------------------------

pub const IDENTITY: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}
fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}
fn quat_axis_angle(axis: [f64; 3], angle: f64) -> [f64; 4] {
    let (s, c) = (0.5 * angle).sin_cos();
    [c, axis[0] * s, axis[1] * s, axis[2] * s]
}
/// Rotates `v` by the unit quaternion `q` = `[w, x, y, z]`.
pub fn rotate(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let u = [q[1], q[2], q[3]];
    let cross =
        |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let t = cross(u, v);
    let t2 = cross(u, t);
    [v[0] + 2.0 * (q[0] * t[0] + t2[0]), v[1] + 2.0 * (q[0] * t[1] + t2[1]), v[2] + 2.0 * (q[0] * t[2] + t2[2])]
}
fn conj(q: [f64; 4]) -> [f64; 4] {
    [q[0], -q[1], -q[2], -q[3]]
}

/// Radius of a sphere about the geom's centre that contains the shape.
pub fn bounding_radius(s: &Shape) -> f64 {
    match s {
        Shape::Box { half } => norm(*half),
        Shape::Sphere { radius } => *radius,
        Shape::Capsule { radius, half_length } => radius + half_length,
        Shape::Cylinder { radius, half_length } => (radius * radius + half_length * half_length).sqrt(),
    }
}

/// Lowest world z of a shape centred at `pos` with orientation `quat` (exact for every primitive).
pub fn shape_lowest_z(s: &Shape, pos: [f64; 3], quat: [f64; 4]) -> f64 {
    let az = rotate(quat, [0.0, 0.0, 1.0])[2];
    match s {
        Shape::Box { half } => inv::box_lowest_z(pos, quat, *half),
        Shape::Sphere { radius } => pos[2] - radius,
        Shape::Capsule { radius, half_length } => pos[2] - az.abs() * half_length - radius,
        Shape::Cylinder { radius, half_length } => {
            pos[2] - az.abs() * half_length - radius * (1.0 - az * az).max(0.0).sqrt()
        }
    }
}

/// World poses of every body frame at the initial joint positions (forward kinematics of the scene).
pub fn initial_poses(w: &World) -> Vec<([f64; 3], [f64; 4])> {
    let mut out: Vec<([f64; 3], [f64; 4])> = Vec::with_capacity(w.bodies.len());
    for b in &w.bodies {
        let (pp, pq) = b.parent.and_then(|p| out.get(p).copied()).unwrap_or(([0.0; 3], IDENTITY));
        // Body frame at q = 0, in the world.
        let mut q = quat_mul(pq, b.quat);
        let mut p = add(pp, rotate(pq, b.pos));
        match &b.joint {
            Joint::Free { .. } | Joint::Fixed => {}
            Joint::Hinge { axis, q0, .. } => {
                // Rotation about the anchor: the anchor's world point stays put.
                let anchor_w = add(p, rotate(q, b.anchor));
                q = quat_mul(q, quat_axis_angle(*axis, *q0));
                p = sub(anchor_w, rotate(q, b.anchor));
            }
            Joint::Slide { axis, q0, .. } => p = add(p, rotate(q, scale(*axis, *q0))),
        }
        out.push((p, q));
    }
    out
}

/// The tree (index of its root) of every body.
pub fn trees(w: &World) -> Vec<usize> {
    let mut t: Vec<usize> = Vec::with_capacity(w.bodies.len());
    for (i, b) in w.bodies.iter().enumerate() {
        let r = b.parent.and_then(|p| t.get(p).copied()).unwrap_or(i);
        t.push(r);
    }
    t
}

/// Whether anything that can touch overlaps at the start (conservative: bounding spheres of geoms of
/// different trees, and each geom's lowest point against the support's top face).
pub fn initial_overlap(w: &World) -> bool {
    if !w.collide {
        return false;
    }
    let poses = initial_poses(w);
    let tree = trees(w);
    let mut spheres: Vec<(usize, [f64; 3], f64)> = Vec::new();
    for (i, b) in w.bodies.iter().enumerate() {
        let (p, q) = poses[i];
        for g in &b.geoms {
            let c = add(p, rotate(q, g.pos));
            if w.support.is_some() && shape_lowest_z(&g.shape, c, quat_mul(q, g.quat)) < 0.0 {
                return true;
            }
            spheres.push((tree[i], c, bounding_radius(&g.shape)));
        }
    }
    for (k, a) in spheres.iter().enumerate() {
        for b in &spheres[k + 1..] {
            if a.0 != b.0 && norm(sub(a.1, b.1)) < a.2 + b.2 {
                return true;
            }
        }
    }
    false
}

// ---- the grammar ---------------------------------------------------------------------------------

fn random_shape(r: &mut Rng, size: f64) -> Shape {
    let s = |r: &mut Rng| size * r.range(0.3, 1.0);
    match r.below(4) {
        0 => Shape::Box { half: [s(r), s(r), s(r)] },
        1 => Shape::Sphere { radius: s(r) },
        2 => Shape::Capsule { radius: s(r) * 0.5, half_length: s(r) },
        _ => Shape::Cylinder { radius: s(r) * 0.5, half_length: s(r) },
    }
}

fn random_limit(r: &mut Rng, span: f64) -> (Option<[f64; 2]>, f64) {
    if !r.chance(0.5) {
        return (None, r.range(-0.5, 0.5) * span);
    }
    let a = r.range(-1.0, 0.5) * span;
    let b = a + r.range(0.05, 1.5) * span;
    if r.chance(0.25) {
        // Inverted limits: a valid scene (engines must reject or ignore them), not a reachable range.
        (Some([b, a]), r.range(-0.5, 0.5) * span)
    } else {
        (Some([a, b]), r.range(a, b))
    }
}

/// Scene number `index` of the campaign seeded with `seed`: the same pair gives the same scene.
pub fn generate(seed: u64, index: u64) -> World {
    let mut r = Rng::new(seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let dt = [0.001, 0.002, 0.005][r.below(3)];
    let duration = (r.range(1.0, 3.0) / dt).round() * dt;
    let support = if r.chance(0.75) {
        Some(if r.chance(0.5) {
            Support::Plane
        } else {
            // Wide enough that nothing leaves it in 3 s at the generated speeds; thickness across orders of magnitude.
            Support::Box { half: [50.0, 50.0, r.log_range(0.002, 1.0)] }
        })
    } else {
        None
    };
    let collide = r.chance(0.8);
    let mut w = World {
        id: format!("s{seed}-{index}"),
        dt,
        duration,
        gravity: -inv::GRAVITY_EARTH,
        record_every: ((0.005 / dt).floor() as usize).max(1),
        settle: 0.2,
        support,
        collide,
        fuse_static: r.chance(0.5),
        // MuJoCo's default is 0.02 s; up to 0.15 s, where a small body's soft-contact equilibrium depth is still
        // ≈ 1 cm (the #2206 scene), within the penetration bound.
        contact_timeconst: r.chance(0.2).then(|| r.log_range(0.005, 0.15)),
        bodies: Vec::new(),
    };
    let n_trees = 1 + r.below(3);
    let mut top = 0.0_f64; // highest point placed so far (trees are stacked upwards)
    for _ in 0..n_trees {
        let size = r.log_range(0.005, 0.5);
        let n_bodies = 1 + r.below(4);
        let first = w.bodies.len();
        let free = r.chance(0.6);
        for k in 0..n_bodies {
            let parent = (k > 0).then(|| first + r.below(k));
            let link = size * r.range(0.5, 3.0);
            let joint = if k == 0 && free {
                let moving = r.chance(0.4);
                Joint::Free {
                    linvel: if moving { r.vec3(3.0) } else { [0.0; 3] },
                    angvel: if moving { r.vec3(5.0) } else { [0.0; 3] },
                }
            } else {
                let moving = r.chance(0.3);
                match r.below(if k == 0 { 3 } else { 4 }) {
                    0 => Joint::Fixed,
                    1 | 3 => {
                        let (limit, q0) = random_limit(&mut r, 1.5);
                        Joint::Hinge { axis: r.axis(), limit, q0, v0: if moving { r.range(-3.0, 3.0) } else { 0.0 } }
                    }
                    _ => {
                        let (limit, q0) = random_limit(&mut r, link);
                        let v0 = if moving { r.range(-1.0, 1.0) } else { 0.0 };
                        Joint::Slide { axis: r.axis(), limit, q0, v0 }
                    }
                }
            };
            let mass = if k > 0 && r.chance(0.07) {
                0.0
            } else if r.chance(0.07) {
                1e-6
            } else {
                r.log_range(1e-3, 10.0)
            };
            let h = [size * r.range(0.3, 1.0), size * r.range(0.3, 1.0), size * r.range(0.3, 1.0)];
            let inertia = [
                mass * (h[1] * h[1] + h[2] * h[2]) / 3.0,
                mass * (h[0] * h[0] + h[2] * h[2]) / 3.0,
                mass * (h[0] * h[0] + h[1] * h[1]) / 3.0,
            ];
            let n_geoms = [0, 1, 1, 1, 2][r.below(5)];
            let geoms = (0..n_geoms)
                .map(|_| BGeom {
                    shape: random_shape(&mut r, size),
                    pos: if r.chance(0.5) { [0.0; 3] } else { r.vec3(size) },
                    quat: if r.chance(0.5) { IDENTITY } else { r.unit_quat() },
                    friction: if r.chance(0.7) { 1.0 } else { r.log_range(0.01, 2.0) },
                })
                .collect();
            let (pos, anchor) = if k == 0 {
                ([0.0; 3], if free { [0.0; 3] } else { r.vec3(size) })
            } else {
                let mut d = r.vec3(1.0);
                let n = norm(d).max(1e-3);
                d = scale(d, link / n);
                (d, scale(d, -0.5))
            };
            let quat = if r.chance(0.5) { IDENTITY } else { r.unit_quat() };
            w.bodies.push(Body { parent, joint, pos, quat, anchor, mass, inertia, geoms, probe: Vec::new() });
        }
        // Place the tree: lowest point on the stack's top plus a gap, or embedded in the support.
        let poses = initial_poses(&w);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (b, &(p, q)) in w.bodies.iter().zip(&poses).skip(first) {
            for g in &b.geoms {
                let c = add(p, rotate(q, g.pos));
                let rad = bounding_radius(&g.shape);
                lo = lo.min(c[2] - rad);
                hi = hi.max(c[2] + rad);
            }
            lo = lo.min(p[2]);
            hi = hi.max(p[2]);
        }
        let embed = free && w.collide && w.support.is_some() && top == 0.0 && r.chance(0.3);
        let z = if embed {
            // Root's centre inside the support's upper half (a plane: within 0.3 m): the contact must push it out
            // upwards, and it must end on top.
            let depth = match &w.support {
                Some(Support::Box { half }) => half[2].min(0.3),
                _ => 0.3,
            };
            -r.range(0.0, depth)
        } else {
            top - lo + r.log_range(1e-3, 1.0)
        };
        let xy = [r.range(-1.0, 1.0) * size, r.range(-1.0, 1.0) * size];
        if let Some(root) = w.bodies.get_mut(first) {
            root.pos = add(root.pos, [xy[0], xy[1], z]);
        }
        top = top.max(z + hi);
    }
    add_probes(&mut w, seed, index);
    w
}

/// Random generalized forces for the inverse-dynamics probe, from a stream of their own (so that adding them
/// left every other draw of the scene unchanged): each entry uniform in ±2 times the body's weight (forces) or
/// its weight times its radius of gyration (torques; a hinge also the weight times the anchor's lever), i.e.
/// accelerations of the order of gravity whatever the body's size.
fn add_probes(w: &mut World, seed: u64, index: u64) {
    let mut r =
        Rng::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ 0x5EED_0F1D);
    let g = w.gravity.abs();
    for b in &mut w.bodies {
        let weight = b.mass * g;
        let gyration = if b.mass > 0.0 { (b.inertia.iter().copied().fold(0.0, f64::max) / b.mass).sqrt() } else { 0.0 };
        b.probe = match b.joint {
            Joint::Free { .. } => {
                let mut f: Vec<f64> = (0..3).map(|_| weight * r.range(-2.0, 2.0)).collect();
                f.extend((0..3).map(|_| weight * gyration * r.range(-2.0, 2.0)));
                f
            }
            Joint::Hinge { .. } => vec![weight * (gyration + norm(b.anchor)) * r.range(-2.0, 2.0)],
            Joint::Slide { .. } => vec![weight * r.range(-2.0, 2.0)],
            Joint::Fixed => Vec::new(),
        };
    }
}

// ---- minimisation --------------------------------------------------------------------------------

/// Removes body `i` and its subtree, renumbering parents.
pub fn remove_subtree(w: &World, i: usize) -> World {
    let mut gone = vec![false; w.bodies.len()];
    for (k, b) in w.bodies.iter().enumerate() {
        gone[k] = k == i || b.parent.is_some_and(|p| gone.get(p).copied().unwrap_or(false));
    }
    let mut new_index = vec![usize::MAX; w.bodies.len()];
    let mut bodies = Vec::new();
    for (k, b) in w.bodies.iter().enumerate() {
        if !gone[k] {
            new_index[k] = bodies.len();
            let mut b = b.clone();
            b.parent = b.parent.map(|p| new_index[p]);
            bodies.push(b);
        }
    }
    World { bodies, ..w.clone() }
}

/// Scene size: bodies plus geoms (what the minimiser removes).
pub fn size(w: &World) -> usize {
    w.bodies.len() + w.bodies.iter().map(|b| b.geoms.len()).sum::<usize>()
}

/// Every one-step simplification of `w`: drop a subtree, drop a geom, then attributes set to their plain value
/// (zero initial velocities and positions, no limits, default contact, identity orientations). Candidates that
/// change nothing are omitted.
pub fn reductions(w: &World) -> Vec<World> {
    let mut out = Vec::new();
    for i in 0..w.bodies.len() {
        if w.bodies.len() > 1 {
            out.push(remove_subtree(w, i));
        }
    }
    for (i, b) in w.bodies.iter().enumerate() {
        for k in 0..b.geoms.len() {
            let mut c = w.clone();
            c.bodies[i].geoms.remove(k);
            out.push(c);
        }
    }
    let push_if = |c: World, out: &mut Vec<World>| {
        if &c != w {
            out.push(c);
        }
    };
    let mut c = w.clone();
    c.contact_timeconst = None;
    push_if(c, &mut out);
    let mut c = w.clone();
    c.fuse_static = false;
    push_if(c, &mut out);
    let mut c = w.clone();
    c.collide = false;
    push_if(c, &mut out);
    for i in 0..w.bodies.len() {
        let mut c = w.clone();
        match &mut c.bodies[i].joint {
            Joint::Free { linvel, angvel } => {
                *linvel = [0.0; 3];
                *angvel = [0.0; 3];
            }
            Joint::Hinge { v0, .. } | Joint::Slide { v0, .. } => *v0 = 0.0,
            Joint::Fixed => {}
        }
        push_if(c, &mut out);
        let mut c = w.clone();
        if let Joint::Hinge { limit, .. } | Joint::Slide { limit, .. } = &mut c.bodies[i].joint {
            *limit = None;
        }
        push_if(c, &mut out);
        let mut c = w.clone();
        if let Joint::Hinge { q0, limit: None, .. } | Joint::Slide { q0, limit: None, .. } = &mut c.bodies[i].joint {
            *q0 = 0.0;
        }
        push_if(c, &mut out);
        let mut c = w.clone();
        if !matches!(c.bodies[i].joint, Joint::Free { .. }) {
            c.bodies[i].joint = Joint::Fixed;
            c.bodies[i].probe.clear();
        }
        push_if(c, &mut out);
        let mut c = w.clone();
        c.bodies[i].probe.iter_mut().for_each(|f| *f = 0.0);
        push_if(c, &mut out);
        let mut c = w.clone();
        c.bodies[i].quat = IDENTITY;
        c.bodies[i].geoms.iter_mut().for_each(|g| g.quat = IDENTITY);
        push_if(c, &mut out);
        let mut c = w.clone();
        c.bodies[i].geoms.iter_mut().for_each(|g| g.friction = 1.0);
        push_if(c, &mut out);
    }
    out
}

// ---- the judge -----------------------------------------------------------------------------------

/// Which invariant a flagged verdict violated (the minimiser keeps a reduction only when the same one fails).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Violation {
    EngineFailure,
    NonFinite,
    Penetration,
    Energy,
    InverseDynamics,
}

#[derive(Debug, Deserialize)]
struct WorldData {
    t: Vec<f64>,
    /// Per sample, per body: `[px, py, pz, qw, qx, qy, qz, vx, vy, vz, wx, wy, wz]` (body-frame origin = centre
    /// of mass; velocities in world coordinates).
    state: Vec<Vec<Vec<Option<f64>>>>,
    /// The inverse-dynamics probe, one entry per tree with a degree of freedom; absent when the adapter's engine
    /// has no inverse-dynamics API (the invariant is then "unsupported", never a verdict).
    #[serde(default)]
    id_probe: Option<Vec<IdProbe>>,
}

/// What an adapter reports for one tree of the inverse-dynamics probe, all in the engine's generalized
/// coordinates: the applied generalized force `applied`; `qd` and `qdd` (q̈ from the velocity change over one
/// step with no contact or limit); `inverse` = ID(q, q̇, q̈); `bias` = ID(q, q̇, 0); `mass_cols` = the mass
/// matrix's columns ID(q, 0, e_i) − ID(q, 0, 0). `error`: the engine refused to compute it.
#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
pub struct IdProbe {
    #[serde(default)]
    pub applied: Vec<Option<f64>>,
    #[serde(default)]
    pub inverse: Option<Vec<Option<f64>>>,
    #[serde(default)]
    pub bias: Vec<Option<f64>>,
    #[serde(default)]
    pub mass_cols: Vec<Vec<Option<f64>>>,
    #[serde(default)]
    pub qd: Vec<Option<f64>>,
    #[serde(default)]
    pub qdd: Vec<Option<f64>>,
    #[serde(default)]
    pub dt: f64,
    #[serde(default)]
    pub error: Option<String>,
}

fn l2(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Relative residual of forward/inverse dynamics consistency, ‖ID(q, q̇, q̈) − τ‖ / S, with τ the applied
/// generalized force and q̈ the engine's forward acceleration under τ. The scale is the backward-error scale of
/// the two computations, S = ‖τ‖ + ‖b‖ + ‖M‖_F (‖q̈‖ + ‖q̇‖/dt) (b the bias forces, M the mass matrix): a
/// backward-stable articulated-body solve and Newton–Euler recursion leave a residual of a small multiple of
/// ε‖M‖‖q̈‖ + ε(‖τ‖ + ‖b‖) whatever M's condition, and q̈ from the velocity change over one step carries
/// ≤ 2ε‖q̇‖/dt of rounding. So a consistent engine in double precision stays orders of magnitude below
/// [`inv::DYNAMICS_REL_TOL`], and anything above it is a modelling disagreement between the two
/// computations, not rounding. `None`: the engine refused (error), or nothing to compare. Non-finite or
/// mismatched lengths: infinity.
pub fn id_residual(p: &IdProbe) -> Option<f64> {
    if p.error.is_some() {
        return None;
    }
    let inverse = p.inverse.as_ref()?;
    let fin = |v: &[Option<f64>]| -> Option<Vec<f64>> { v.iter().map(|x| x.filter(|x| x.is_finite())).collect() };
    let (Some(tau), Some(id), Some(b), Some(qd), Some(qdd)) =
        (fin(&p.applied), fin(inverse), fin(&p.bias), fin(&p.qd), fin(&p.qdd))
    else {
        return Some(f64::INFINITY);
    };
    let n = tau.len();
    if id.len() != n || b.len() != n || qd.len() != n || qdd.len() != n || p.mass_cols.len() != n {
        return Some(f64::INFINITY);
    }
    let mut m_frob = 0.0;
    for c in &p.mass_cols {
        let Some(c) = fin(c) else { return Some(f64::INFINITY) };
        if c.len() != n {
            return Some(f64::INFINITY);
        }
        m_frob += c.iter().map(|x| x * x).sum::<f64>();
    }
    let m_norm = m_frob.sqrt();
    let resid = l2(&id.iter().zip(&tau).map(|(a, b)| a - b).collect::<Vec<_>>());
    let scale = l2(&tau) + l2(&b) + m_norm * (l2(&qdd) + if p.dt > 0.0 { l2(&qd) / p.dt } else { 0.0 });
    if scale > 0.0 {
        Some(resid / scale)
    } else {
        Some(resid)
    }
}

/// Mechanical energy of the scene in one sample (kinetic + gravitational potential), from the scene's masses
/// and inertias.
fn energy(w: &World, s: &[[f64; 13]]) -> f64 {
    w.bodies
        .iter()
        .zip(s)
        .map(|(b, x)| {
            let q = [x[3], x[4], x[5], x[6]];
            let v = [x[7], x[8], x[9]];
            let om = rotate(conj(q), [x[10], x[11], x[12]]);
            let rot = om[0] * om[0] * b.inertia[0] + om[1] * om[1] * b.inertia[1] + om[2] * om[2] * b.inertia[2];
            0.5 * b.mass * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + 0.5 * rot - b.mass * w.gravity * x[2]
        })
        .sum()
}

/// Judges one observation of a generated scene. Returns the verdict and, when flagged, the violation.
pub fn judge_world(w: &World, obs: &Observation) -> (Verdict, Option<Violation>) {
    let passive = !initial_overlap(w);
    let mut v = Verdict {
        engine: obs.engine.clone(),
        bug: "-".into(),
        scene: w.id.clone(),
        metric: "finite state; penetration over the last settle s (m); energy gain (J)".into(),
        value: None,
        threshold: format!(
            "finite; <= {} ({}){}",
            inv::PENETRATION_MAX,
            inv::names::PENETRATION,
            if passive {
                format!("; <= {} ({})", inv::energy_tolerance(0.0), inv::names::ENERGY)
            } else {
                String::new()
            }
        ),
        flagged: false,
        detail: String::new(),
        runtime_ms: 0.0,
    };
    match obs.status.as_str() {
        "unsupported" => {
            v.detail = format!("not run: {}", obs.detail);
            return (v, None);
        }
        "ok" => {}
        _ => {
            v.flagged = true;
            v.detail = format!("engine failure ({}): {}", obs.status, obs.detail);
            return (v, Some(Violation::EngineFailure));
        }
    }
    let Some(d) = obs.data.clone().and_then(|d| serde_json::from_value::<WorldData>(d).ok()) else {
        v.flagged = true;
        v.detail = "malformed observables".into();
        return (v, Some(Violation::EngineFailure));
    };
    let steps = (w.duration / w.dt).round() as usize;
    let expected = steps / w.record_every.max(1) + 1;
    let mut states: Vec<Vec<[f64; 13]>> = Vec::with_capacity(d.state.len());
    let mut bad_at = None;
    for (t, s) in d.t.iter().zip(&d.state) {
        let row: Option<Vec<[f64; 13]>> = s
            .iter()
            .map(|b| {
                let mut a = [0.0; 13];
                if b.len() != 13 {
                    return None;
                }
                for (x, y) in a.iter_mut().zip(b) {
                    *x = y.filter(|y| y.is_finite())?;
                }
                Some(a)
            })
            .collect();
        match row {
            Some(r) if r.len() == w.bodies.len() => states.push(r),
            _ => {
                bad_at = Some(*t);
                break;
            }
        }
    }
    if bad_at.is_some() || states.len() != expected || d.t.len() != expected {
        v.flagged = true;
        v.detail = format!(
            "{}: {} of {expected} samples finite (first bad t = {})",
            inv::names::NON_FINITE,
            states.len(),
            bad_at.map_or("-".into(), |t| format!("{t:.4} s"))
        );
        return (v, Some(Violation::NonFinite));
    }
    let mut pen = f64::NEG_INFINITY;
    if w.collide && w.support.is_some() {
        for (t, s) in d.t.iter().zip(&states) {
            if *t < w.duration - w.settle - 1e-9 {
                continue;
            }
            for (b, x) in w.bodies.iter().zip(s) {
                let (p, q) = ([x[0], x[1], x[2]], [x[3], x[4], x[5], x[6]]);
                for g in &b.geoms {
                    let z = shape_lowest_z(&g.shape, add(p, rotate(q, g.pos)), quat_mul(q, g.quat));
                    pen = pen.max(inv::penetration_below(0.0, z));
                }
            }
        }
    }
    let e: Vec<f64> = states.iter().map(|s| energy(w, s)).collect();
    let e0 = e.first().copied().unwrap_or(0.0);
    let gain = e.iter().map(|x| x - e0).fold(f64::NEG_INFINITY, f64::max);
    v.value = Some(pen.max(0.0));
    let pen_text = if pen.is_finite() { format!("{pen:.4} m") } else { "n/a (no geom over a support)".into() };
    v.detail = format!("penetration {pen_text}, energy gain {gain:.4} J (initial {e0:.4} J, passive: {passive})");
    if inv::exceeds(pen.max(0.0), inv::PENETRATION_MAX) {
        v.flagged = true;
        return (v, Some(Violation::Penetration));
    }
    if passive && inv::exceeds(gain, inv::energy_tolerance(0.0)) {
        v.flagged = true;
        v.value = Some(gain);
        return (v, Some(Violation::Energy));
    }
    match &d.id_probe {
        None => v.detail.push_str("; inverse dynamics: unsupported by this adapter"),
        Some(probes) => {
            let r: Vec<f64> = probes.iter().filter_map(id_residual).collect();
            let refused = probes.len() - r.len();
            let worst = r.iter().copied().fold(0.0, f64::max);
            v.threshold.push_str(&format!("; forward/inverse dynamics residual <= {} (rel)", inv::DYNAMICS_REL_TOL));
            v.detail.push_str(&format!(
                "; inverse-dynamics residual {worst:.3e} (rel) over {} tree(s){}",
                r.len(),
                if refused > 0 { format!(", {refused} refused by the engine") } else { String::new() }
            ));
            if inv::exceeds(worst, inv::DYNAMICS_REL_TOL) {
                v.flagged = true;
                v.value = Some(worst);
                return (v, Some(Violation::InverseDynamics));
            }
        }
    }
    (v, None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_gives_the_same_scenes_and_they_round_trip() {
        for i in 0..50 {
            let a = generate(7, i);
            assert_eq!(a, generate(7, i));
            let text = serde_json::to_string(&a).unwrap_or_default();
            let back: Option<World> = serde_json::from_str(&text).ok();
            assert_eq!(back.as_ref(), Some(&a));
        }
        assert_ne!(generate(7, 0), generate(8, 0));
    }

    #[test]
    fn generated_scenes_are_valid() {
        let mut seen_inverted = false;
        for i in 0..300 {
            let w = generate(3, i);
            assert!(!w.bodies.is_empty());
            for (k, b) in w.bodies.iter().enumerate() {
                assert!(b.parent.is_none_or(|p| p < k), "parent after child in {}", w.id);
                assert!(b.mass >= 0.0 && b.inertia.iter().all(|x| *x >= 0.0));
                if matches!(b.joint, Joint::Free { .. }) {
                    assert!(b.parent.is_none());
                }
                if let Joint::Hinge { limit: Some([lo, hi]), .. } = b.joint {
                    seen_inverted |= lo > hi;
                }
                let [i0, i1, i2] = b.inertia;
                assert!(i0 + i1 >= i2 * (1.0 - 1e-9) && i1 + i2 >= i0 * (1.0 - 1e-9) && i0 + i2 >= i1 * (1.0 - 1e-9));
            }
        }
        assert!(seen_inverted);
    }

    #[test]
    fn removing_a_subtree_renumbers_parents() {
        let w = (0..200).map(|i| generate(5, i)).find(|w| w.bodies.len() >= 3).unwrap_or_else(|| generate(5, 0));
        let r = remove_subtree(&w, 0);
        assert!(r.bodies.len() < w.bodies.len());
        for (k, b) in r.bodies.iter().enumerate() {
            assert!(b.parent.is_none_or(|p| p < k));
        }
        assert!(reductions(&w).iter().all(|c| size(c) <= size(&w)));
    }

    fn one_sphere(z: f64) -> World {
        World {
            id: "t".into(),
            dt: 0.01,
            duration: 0.5,
            gravity: -inv::GRAVITY_EARTH,
            record_every: 1,
            settle: 0.2,
            support: Some(Support::Plane),
            collide: true,
            fuse_static: false,
            contact_timeconst: None,
            bodies: vec![Body {
                parent: None,
                joint: Joint::Free { linvel: [0.0; 3], angvel: [0.0; 3] },
                pos: [0.0, 0.0, z],
                quat: IDENTITY,
                anchor: [0.0; 3],
                mass: 1.0,
                inertia: [0.1; 3],
                probe: Vec::new(),
                geoms: vec![BGeom {
                    shape: Shape::Sphere { radius: 0.1 },
                    pos: [0.0; 3],
                    quat: IDENTITY,
                    friction: 1.0,
                }],
            }],
        }
    }

    fn run(w: &World, z: impl Fn(usize) -> f64, vz: impl Fn(usize) -> f64) -> Observation {
        let n = (w.duration / w.dt).round() as usize + 1;
        let state: Vec<Vec<Vec<f64>>> =
            (0..n).map(|i| vec![vec![0.0, 0.0, z(i), 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, vz(i), 0.0, 0.0, 0.0]]).collect();
        let t: Vec<f64> = (0..n).map(|i| i as f64 * w.dt).collect();
        Observation {
            engine: "X 1".into(),
            scene: w.id.clone(),
            status: "ok".into(),
            detail: String::new(),
            data: Some(serde_json::json!({"t": t, "state": state})),
        }
    }

    #[test]
    fn the_judge_flags_falling_through_and_energy_from_nothing_and_nothing_else() {
        let w = one_sphere(0.1);
        assert!(!initial_overlap(&w));
        // Resting: quiet.
        assert_eq!(judge_world(&w, &run(&w, |_| 0.1, |_| 0.0)).1, None);
        // Fell through the plane: penetration.
        assert_eq!(judge_world(&w, &run(&w, |i| 0.1 - 0.1 * i as f64, |_| -1.0)).1, Some(Violation::Penetration));
        // Rising at 5 m/s forever from rest: energy created.
        assert_eq!(
            judge_world(&w, &run(&w, |i| 0.1 + 0.05 * i as f64, |i| if i > 0 { 5.0 } else { 0.0 })).1,
            Some(Violation::Energy)
        );
        // A run that stopped early: non-finite.
        let mut o = run(&w, |_| 0.1, |_| 0.0);
        o.data = Some(
            serde_json::json!({"t": [0.0], "state": [[[0.0, 0.0, 0.1, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]]]}),
        );
        assert_eq!(judge_world(&w, &o).1, Some(Violation::NonFinite));
        // Embedded at the start: no energy oracle, but it must end on top.
        let e = one_sphere(-0.05);
        assert!(initial_overlap(&e));
        assert_eq!(
            judge_world(&e, &run(&e, |i| if i > 5 { 0.1 } else { -0.05 }, |i| if i == 5 { 9.0 } else { 0.0 })).1,
            None
        );
        assert_eq!(judge_world(&e, &run(&e, |_| -0.05, |_| 0.0)).1, Some(Violation::Penetration));
    }

    #[test]
    fn forward_kinematics_turns_about_the_anchor() {
        let mut w = one_sphere(1.0);
        w.bodies[0].joint =
            Joint::Hinge { axis: [0.0, 1.0, 0.0], limit: None, q0: std::f64::consts::FRAC_PI_2, v0: 0.0 };
        w.bodies[0].anchor = [-0.5, 0.0, 0.0];
        let (p, _) = initial_poses(&w)[0];
        // Anchor at world (−0.5, 0, 1); a quarter turn about +y takes the centre from +x of it to −z of it.
        assert!((p[0] + 0.5).abs() < 1e-12 && (p[2] - 0.5).abs() < 1e-12, "{p:?}");
    }

    /// A pendulum (point mass m at length l, angle q from the downward vertical): M = m l², b = m g l sin q + 0
    /// (no velocity terms for one dof). `shift` evaluates the inverse dynamics at the wrong angle, as an engine that
    /// reads the wrong coordinate slot would.
    fn pendulum_probe(q: f64, qd: f64, tau: f64, shift: f64) -> IdProbe {
        let (m, l, g, dt) = (2.0, 0.5, inv::GRAVITY_EARTH, 0.002);
        let mm = m * l * l;
        let bias = |q: f64| m * g * l * q.sin();
        let qdd = (tau - bias(q)) / mm;
        IdProbe {
            applied: vec![Some(tau)],
            inverse: Some(vec![Some(mm * qdd + bias(q + shift))]),
            bias: vec![Some(bias(q + shift))],
            mass_cols: vec![vec![Some(mm)]],
            qd: vec![Some(qd)],
            qdd: vec![Some(qdd)],
            dt,
            error: None,
        }
    }

    #[test]
    fn the_inverse_dynamics_probe_flags_an_inconsistent_answer_and_passes_a_consistent_one() {
        let ok = id_residual(&pendulum_probe(0.7, 2.0, 3.0, 0.0)).unwrap_or(f64::INFINITY);
        assert!(ok <= 1e-15, "{ok}");
        // Inverse dynamics at a joint angle off by 0.7 rad (the slot of another coordinate).
        let bad = id_residual(&pendulum_probe(0.7, 2.0, 3.0, -0.7)).unwrap_or(0.0);
        assert!(inv::exceeds(bad, inv::DYNAMICS_REL_TOL), "{bad}");
        // An error by one part in 1e10 of the applied force is rounding-sized: quiet.
        let mut p = pendulum_probe(0.7, 2.0, 3.0, 0.0);
        p.inverse = p.inverse.map(|v| v.into_iter().map(|x| x.map(|x| x * (1.0 + 1e-10))).collect());
        assert!(!inv::exceeds(id_residual(&p).unwrap_or(f64::INFINITY), inv::DYNAMICS_REL_TOL));
        // Refused by the engine: no verdict; non-finite or wrong length: flagged.
        p.error = Some("refused".into());
        assert_eq!(id_residual(&p), None);
        let mut p = pendulum_probe(0.7, 2.0, 3.0, 0.0);
        p.inverse = Some(vec![None]);
        assert_eq!(id_residual(&p), Some(f64::INFINITY));
        p.inverse = Some(vec![Some(0.0), Some(0.0)]);
        assert_eq!(id_residual(&p), Some(f64::INFINITY));
        // Through the judge: the same resting sphere, with the probe attached.
        let w = one_sphere(0.1);
        let mut o = run(&w, |_| 0.1, |_| 0.0);
        assert!(judge_world(&w, &o).0.detail.contains("unsupported"));
        for (probe, want) in [
            (pendulum_probe(0.7, 2.0, 3.0, 0.0), None),
            (pendulum_probe(0.7, 2.0, 3.0, -0.7), Some(Violation::InverseDynamics)),
        ] {
            if let Some(serde_json::Value::Object(d)) = o.data.as_mut() {
                d.insert("id_probe".into(), serde_json::json!([probe]));
            }
            assert_eq!(judge_world(&w, &o).1, want);
        }
    }

    #[test]
    fn probes_match_the_joints_and_leave_the_rest_of_the_scene_unchanged() {
        for i in 0..200 {
            let w = generate(1, i);
            for b in &w.bodies {
                let want = match b.joint {
                    Joint::Free { .. } => 6,
                    Joint::Hinge { .. } | Joint::Slide { .. } => 1,
                    Joint::Fixed => 0,
                };
                assert_eq!(b.probe.len(), want);
                assert!(b.probe.iter().all(|f| f.is_finite()));
            }
        }
        // Scenes saved before the probe existed still load (zero probe forces) and write back unchanged.
        let saved = include_str!("../../../../corpus/rediscovery/dart-gz-physics-849-massless-link.json");
        let w: Option<World> = serde_json::from_str(saved).ok();
        assert!(w.as_ref().is_some_and(|w| w.bodies.iter().all(|b| b.probe.is_empty())));
        assert!(!serde_json::to_string(&w).unwrap_or_default().contains("probe"));
    }
}
