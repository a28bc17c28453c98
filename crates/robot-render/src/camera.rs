//! The pinhole camera and the camera that follows the pelvis.
use nalgebra::Vector3;

/// A perspective camera looking from `eye` at `target`, world z up, over an image of `width` x `height` pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Centre of projection, world frame (m).
    pub eye: Vector3<f64>,
    /// The point seen at the image centre, world frame (m).
    pub target: Vector3<f64>,
    /// Vertical field of view (rad).
    pub fov_y: f64,
    /// Image width (pixels).
    pub width: u32,
    /// Image height (pixels).
    pub height: u32,
}

/// Orthonormal camera axes in the world frame: forward (viewing direction), right, up.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Basis {
    pub forward: Vector3<f64>,
    pub right: Vector3<f64>,
    pub up: Vector3<f64>,
}

impl Camera {
    pub(crate) fn basis(&self) -> Basis {
        let forward = (self.target - self.eye).try_normalize(1e-9).unwrap_or_else(Vector3::x);
        let right = forward.cross(&Vector3::z()).try_normalize(1e-9).unwrap_or_else(Vector3::y);
        let up = right.cross(&forward);
        Basis { forward, right, up }
    }

    /// Focal length in pixels.
    pub fn focal_px(&self) -> f64 {
        0.5 * f64::from(self.height) / (0.5 * self.fov_y).tan()
    }

    /// Image position (pixels, x right, y down, pixel centres at `i + 0.5`) and depth along the viewing direction
    /// of a world point; `None` behind the camera.
    pub fn project(&self, p: Vector3<f64>) -> Option<(f64, f64, f64)> {
        self.project_with(&self.basis(), p)
    }

    pub(crate) fn project_with(&self, b: &Basis, p: Vector3<f64>) -> Option<(f64, f64, f64)> {
        let d = p - self.eye;
        let depth = d.dot(&b.forward);
        if depth <= 1e-6 {
            return None;
        }
        let f = self.focal_px() / depth;
        Some((
            0.5 * f64::from(self.width) + f * d.dot(&b.right),
            0.5 * f64::from(self.height) - f * d.dot(&b.up),
            depth,
        ))
    }
}

/// A camera at a fixed offset from a point that follows the pelvis in x and y (smoothed, so that the picture does
/// not shake with every step), at a fixed height.
#[derive(Debug, Clone)]
pub struct FollowCamera {
    /// Eye relative to the followed point (m).
    pub offset: Vector3<f64>,
    /// Height of the followed point (m).
    pub height: f64,
    /// Time constant of the smoothing (s); 0 follows exactly.
    pub time_constant: f64,
    /// Vertical field of view (rad).
    pub fov_y: f64,
    followed: Option<[f64; 2]>,
}

impl FollowCamera {
    /// A camera that has not seen the pelvis yet (it starts on it).
    pub fn new(offset: Vector3<f64>, height: f64, time_constant: f64, fov_y: f64) -> Self {
        FollowCamera { offset, height, time_constant, fov_y, followed: None }
    }

    /// Moves toward the pelvis at `pelvis` (world, m) after `dt` seconds, and returns the camera.
    pub fn update(&mut self, pelvis: [f64; 3], dt: f64, width: u32, height: u32) -> Camera {
        let p = [pelvis[0], pelvis[1]];
        let xy = match self.followed {
            Some(f) if self.time_constant > 0.0 && dt.is_finite() => {
                let a = 1.0 - (-dt.max(0.0) / self.time_constant).exp();
                [f[0] + a * (p[0] - f[0]), f[1] + a * (p[1] - f[1])]
            }
            _ => p,
        };
        self.followed = Some(xy);
        let target = Vector3::new(xy[0], xy[1], self.height);
        Camera { eye: target + self.offset, target, fov_y: self.fov_y, width, height }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_is_at_the_image_centre_and_up_is_up() {
        let cam = Camera {
            eye: Vector3::new(3.0, -2.0, 1.5),
            target: Vector3::new(0.0, 0.0, 1.0),
            fov_y: 0.8,
            width: 640,
            height: 360,
        };
        let (x, y, d) = cam.project(cam.target).expect("in front");
        assert!((x - 320.0).abs() < 1e-9 && (y - 180.0).abs() < 1e-9);
        assert!((d - (cam.target - cam.eye).norm()).abs() < 1e-9);
        let (_, y_up, _) = cam.project(cam.target + Vector3::z()).expect("in front");
        assert!(y_up < 180.0, "a higher point is drawn higher");
        assert!(cam.project(cam.eye - (cam.target - cam.eye)).is_none(), "behind the camera");
    }

    #[test]
    fn follow_camera_converges_on_the_pelvis() {
        let mut f = FollowCamera::new(Vector3::new(1.0, -3.0, 0.5), 0.9, 0.5, 0.8);
        let c0 = f.update([0.0, 0.0, 1.0], 0.0, 64, 36);
        assert_eq!(c0.target, Vector3::new(0.0, 0.0, 0.9));
        let c1 = f.update([1.0, 0.0, 1.0], 0.5, 64, 36);
        assert!((c1.target.x - (1.0 - (-1.0f64).exp())).abs() < 1e-12, "one time constant: 63 %");
        let mut c = c1;
        for _ in 0..20 {
            c = f.update([1.0, 0.0, 1.0], 0.5, 64, 36);
        }
        assert!((c.target.x - 1.0).abs() < 1e-6);
        assert_eq!(c.eye, c.target + Vector3::new(1.0, -3.0, 0.5));
    }
}
