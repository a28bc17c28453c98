//! Tessellation of the collision shapes into triangles, once per model, in each link's frame.
//!
//! Every shape is convex and contains its frame's origin, so each triangle is wound outwards (its normal
//! `(b - a) × (c - a)` points away from the shape's centre): the rasteriser culls back faces by winding alone.
use nalgebra::{Isometry3, Point3, Vector3};
use robot_model::{RobotModel, Shape};

/// Segments around the axis of spheres, capsules and cylinders.
const AROUND: usize = 16;
/// Latitude steps of a hemisphere (sphere: twice as many).
const HEMI_STEPS: usize = 4;

/// The triangles of one link, in the link frame, and its colour.
#[derive(Debug, Clone)]
pub(crate) struct LinkMesh {
    /// Index into `model.links`.
    pub link: usize,
    /// Base colour (sRGB), lit by the rasteriser.
    pub color: [f32; 3],
    pub tris: Vec<[Point3<f32>; 3]>,
}

/// Colours: the left side orange, the right side coral, the trunk sand: all warm, so that no robot pixel looks
/// like the neutral-grey ground or the blue sky.
pub(crate) const LEFT: [f32; 3] = [235.0, 130.0, 40.0];
pub(crate) const RIGHT: [f32; 3] = [205.0, 70.0, 70.0];
pub(crate) const TRUNK: [f32; 3] = [220.0, 175.0, 110.0];

fn color_of(link_name: &str) -> [f32; 3] {
    if link_name.starts_with("left") || link_name.starts_with("L_") {
        LEFT
    } else if link_name.starts_with("right") || link_name.starts_with("R_") {
        RIGHT
    } else {
        TRUNK
    }
}

/// The meshes of every link that has collision shapes.
pub(crate) fn robot_meshes(model: &RobotModel) -> Vec<LinkMesh> {
    model
        .links
        .iter()
        .enumerate()
        .filter(|(_, l)| !l.collisions.is_empty())
        .map(|(i, l)| {
            let mut tris = Vec::new();
            for c in &l.collisions {
                shape_tris(&c.shape, &c.origin, &mut tris);
            }
            LinkMesh { link: i, color: color_of(&l.name), tris }
        })
        .collect()
}

/// Appends the triangles of `shape` placed at `origin` (in the link frame).
pub(crate) fn shape_tris(shape: &Shape, origin: &Isometry3<f64>, out: &mut Vec<[Point3<f32>; 3]>) {
    let local = match *shape {
        Shape::Box { half_extents: h } => box_tris(h),
        Shape::Sphere { radius } => revolve(&capsule_profile(radius, 0.0)),
        Shape::Capsule { radius, half_length } => revolve(&capsule_profile(radius, half_length)),
        Shape::Cylinder { radius, half_length } => {
            revolve(&[(0.0, -half_length), (radius, -half_length), (radius, half_length), (0.0, half_length)])
        }
    };
    for t in local {
        if let Some(t) = outward(t) {
            out.push(t.map(|p| (origin * p).cast::<f32>()));
        }
    }
}

/// The triangle wound outwards (normal away from the origin), or `None` when degenerate.
fn outward([a, b, c]: [Point3<f64>; 3]) -> Option<[Point3<f64>; 3]> {
    let n = (b - a).cross(&(c - a));
    if n.norm() < 1e-12 {
        return None;
    }
    let centroid = (a.coords + b.coords + c.coords) / 3.0;
    Some(if n.dot(&centroid) >= 0.0 { [a, b, c] } else { [a, c, b] })
}

fn box_tris(h: [f64; 3]) -> Vec<[Point3<f64>; 3]> {
    let corner = |i: usize| Point3::new(sign(i & 1) * h[0], sign(i & 2) * h[1], sign(i & 4) * h[2]);
    // Faces as corner indices (bit 0: +x, bit 1: +y, bit 2: +z), each a quad in cyclic order.
    const FACES: [[usize; 4]; 6] = [[0, 2, 6, 4], [1, 3, 7, 5], [0, 1, 5, 4], [2, 3, 7, 6], [0, 1, 3, 2], [4, 5, 7, 6]];
    FACES
        .iter()
        .flat_map(|f| [[corner(f[0]), corner(f[1]), corner(f[2])], [corner(f[0]), corner(f[2]), corner(f[3])]])
        .collect()
}

fn sign(bit: usize) -> f64 {
    if bit != 0 {
        1.0
    } else {
        -1.0
    }
}

/// Profile `(radius, z)` of a capsule from its bottom pole to its top pole (a sphere when `half_length` is 0).
fn capsule_profile(radius: f64, half_length: f64) -> Vec<(f64, f64)> {
    let mut p = Vec::with_capacity(2 * HEMI_STEPS + 2);
    for i in 0..=HEMI_STEPS {
        let a = -std::f64::consts::FRAC_PI_2 * (1.0 - i as f64 / HEMI_STEPS as f64);
        p.push((radius * a.cos(), -half_length + radius * a.sin()));
    }
    for i in 0..=HEMI_STEPS {
        let a = std::f64::consts::FRAC_PI_2 * i as f64 / HEMI_STEPS as f64;
        p.push((radius * a.cos(), half_length + radius * a.sin()));
    }
    p
}

/// Surface of revolution about z of a profile `(radius, z)`.
fn revolve(profile: &[(f64, f64)]) -> Vec<[Point3<f64>; 3]> {
    let ring = |k: usize, (r, z): (f64, f64)| {
        let a = std::f64::consts::TAU * (k % AROUND) as f64 / AROUND as f64;
        Point3::from(Vector3::new(r * a.cos(), r * a.sin(), z))
    };
    let mut tris = Vec::new();
    for w in profile.windows(2) {
        for k in 0..AROUND {
            let (a, b) = (ring(k, w[0]), ring(k + 1, w[0]));
            let (c, d) = (ring(k, w[1]), ring(k + 1, w[1]));
            tris.push([a, b, d]);
            tris.push([a, d, c]);
        }
    }
    tris
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every triangle of every shape faces outwards, and the tessellation encloses the shape's extent.
    #[test]
    fn shapes_are_closed_outward_and_of_the_right_size() {
        let shapes = [
            (Shape::Box { half_extents: [0.1, 0.2, 0.3] }, [0.1, 0.2, 0.3]),
            (Shape::Sphere { radius: 0.05 }, [0.05, 0.05, 0.05]),
            (Shape::Capsule { radius: 0.05, half_length: 0.2 }, [0.05, 0.05, 0.25]),
            (Shape::Cylinder { radius: 0.04, half_length: 0.1 }, [0.04, 0.04, 0.1]),
        ];
        for (shape, ext) in shapes {
            let mut tris = Vec::new();
            shape_tris(&shape, &Isometry3::identity(), &mut tris);
            assert!(tris.len() >= 12, "{shape:?}");
            let mut max = [0.0f32; 3];
            // Closed: the signed volume (divergence theorem) is positive and close to the shape's.
            let mut volume = 0.0f64;
            for [a, b, c] in &tris {
                let n = (b - a).cross(&(c - a));
                let centroid = (a.coords + b.coords + c.coords) / 3.0;
                assert!(n.dot(&centroid) > 0.0, "{shape:?}: a triangle faces inwards");
                volume += f64::from(a.coords.dot(&b.coords.cross(&c.coords))) / 6.0;
                for p in [a, b, c] {
                    for k in 0..3 {
                        max[k] = max[k].max(p[k].abs());
                    }
                }
            }
            for k in 0..3 {
                assert!((f64::from(max[k]) - ext[k]).abs() < 1e-6, "{shape:?}: extent {max:?} vs {ext:?}");
            }
            let exact = match shape {
                Shape::Box { half_extents: h } => 8.0 * h[0] * h[1] * h[2],
                Shape::Sphere { radius: r } => 4.0 / 3.0 * std::f64::consts::PI * r.powi(3),
                Shape::Capsule { radius: r, half_length: h } => {
                    std::f64::consts::PI * r * r * (2.0 * h) + 4.0 / 3.0 * std::f64::consts::PI * r.powi(3)
                }
                Shape::Cylinder { radius: r, half_length: h } => std::f64::consts::PI * r * r * 2.0 * h,
            };
            assert!(volume > 0.85 * exact && volume <= exact * 1.0001, "{shape:?}: volume {volume} vs {exact}");
        }
    }
}
