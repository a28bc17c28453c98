//! Pixels: the frame, the sky and checkerboard ground, the shadow mask and z-buffered triangles.
use crate::camera::Camera;
use nalgebra::Vector3;

/// An RGB image (8 bits a channel), rows top to bottom: what [`crate::VideoWriter`] encodes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
}

impl Frame {
    /// A black frame.
    pub fn new(width: u32, height: u32) -> Self {
        Frame { width, height, rgb: vec![0; width as usize * height as usize * 3] }
    }

    /// A frame over `rgb` (`width * height * 3` bytes, rows top to bottom), or `None` when the size is wrong.
    pub fn from_rgb(width: u32, height: u32, rgb: Vec<u8>) -> Option<Self> {
        (rgb.len() == width as usize * height as usize * 3).then_some(Frame { width, height, rgb })
    }

    /// Width (pixels).
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height (pixels).
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixels, `[r, g, b]` row by row.
    pub fn rgb(&self) -> &[u8] {
        &self.rgb
    }

    /// The pixel at column `x`, row `y`, if inside.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 3;
        Some([self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]])
    }

    /// The frames side by side, left to right (the panels of one video), or `None` when their heights differ or
    /// there are none.
    pub fn side_by_side(panels: &[&Frame]) -> Option<Frame> {
        let height = panels.first()?.height;
        if panels.iter().any(|p| p.height != height) {
            return None;
        }
        let width = panels.iter().map(|p| p.width).sum();
        let mut rgb = Vec::with_capacity(width as usize * height as usize * 3);
        for y in 0..height as usize {
            for p in panels {
                let row = p.width as usize * 3;
                rgb.extend_from_slice(&p.rgb[y * row..(y + 1) * row]);
            }
        }
        Some(Frame { width, height, rgb })
    }

    pub(crate) fn set(&mut self, i: usize, c: [u8; 3]) {
        self.rgb[3 * i..3 * i + 3].copy_from_slice(&c);
    }

    pub(crate) fn get(&self, i: usize) -> [u8; 3] {
        [self.rgb[3 * i], self.rgb[3 * i + 1], self.rgb[3 * i + 2]]
    }
}

/// Side of a ground square (m).
const CHECKER_M: f64 = 0.5;
/// Ground squares fade into one grey between these distances (m), before they alias.
const FADE_FROM_M: f64 = 6.0;
const FADE_TO_M: f64 = 18.0;
/// Light factor of the ground in the robot's shadow.
const SHADOW: f32 = 0.6;

/// A screen vertex: pixel x, pixel y, inverse depth (1/m).
pub(crate) type ScreenVertex = (f32, f32, f32);

/// A frame with its z-buffer (inverse depth, 0 = infinitely far) and the shadow mask.
#[derive(Debug)]
pub(crate) struct Canvas {
    pub frame: Frame,
    inv_depth: Vec<f32>,
    shadow: Vec<bool>,
}

impl Canvas {
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Canvas { frame: Frame::new(width, height), inv_depth: vec![0.0; n], shadow: vec![false; n] }
    }

    /// Sky and checkerboard ground (plane z = 0) seen by `cam`, with the ground's depth in the z-buffer.
    pub fn background(&mut self, cam: &Camera) {
        let b = cam.basis();
        let f = cam.focal_px();
        let (w, h) = (self.frame.width as usize, self.frame.height as usize);
        let (cx, cy) = (0.5 * w as f64, 0.5 * h as f64);
        for y in 0..h {
            let dy = (y as f64 + 0.5 - cy) / f;
            let row = b.forward - b.up * dy;
            for x in 0..w {
                let i = y * w + x;
                // Ray with unit component along the viewing direction: its parameter at the ground is the depth.
                let d: Vector3<f64> = row + b.right * ((x as f64 + 0.5 - cx) / f);
                self.shadow[i] = false;
                if d.z < -1e-9 && cam.eye.z > 0.0 {
                    let t = -cam.eye.z / d.z;
                    let p = cam.eye + d * t;
                    let dark = ((p.x / CHECKER_M).floor() + (p.y / CHECKER_M).floor()).rem_euclid(2.0) < 0.5;
                    let fade = ((t * d.norm() - FADE_FROM_M) / (FADE_TO_M - FADE_FROM_M)).clamp(0.0, 1.0) as f32;
                    let g = if dark { 132.0 } else { 188.0 } * (1.0 - fade) + 160.0 * fade;
                    self.frame.set(i, [g as u8; 3]);
                    self.inv_depth[i] = (1.0 / t) as f32;
                } else {
                    // Sky: deeper blue upwards.
                    let up = (-d.z / d.norm()).clamp(-1.0, 1.0) as f32;
                    let s = (1.0 - up).clamp(0.0, 1.0);
                    let c = [110.0 + 90.0 * s, 150.0 + 75.0 * s, 225.0 + 25.0 * s];
                    self.frame.set(i, c.map(|v| v as u8));
                    self.inv_depth[i] = 0.0;
                }
            }
        }
    }

    /// Marks the pixels under a shadow triangle (vertices on the ground).
    pub fn shadow_tri(&mut self, v: [ScreenVertex; 3]) {
        let shadow = &mut self.shadow;
        raster(self.frame.width, self.frame.height, v, |i, _| shadow[i] = true);
    }

    /// Darkens the marked ground pixels (call before drawing the robot).
    pub fn apply_shadow(&mut self) {
        for i in 0..self.shadow.len() {
            if self.shadow[i] && self.inv_depth[i] > 0.0 {
                let c = self.frame.get(i);
                self.frame.set(i, c.map(|v| (f32::from(v) * SHADOW) as u8));
            }
        }
    }

    /// A z-tested triangle of one colour.
    pub fn tri(&mut self, v: [ScreenVertex; 3], color: [u8; 3]) {
        let (depth, frame) = (&mut self.inv_depth, &mut self.frame);
        raster(frame.width, frame.height, v, |i, z| {
            if z > depth[i] {
                depth[i] = z;
                frame.set(i, color);
            }
        });
    }
}

fn edge(a: ScreenVertex, b: ScreenVertex, px: f32, py: f32) -> f32 {
    (b.0 - a.0) * (py - a.1) - (b.1 - a.1) * (px - a.0)
}

/// Calls `pixel(index, inverse depth)` for every pixel whose centre is inside the triangle (either winding).
/// Inverse depth is affine in screen space, so interpolating it is perspective-correct.
fn raster(width: u32, height: u32, v: [ScreenVertex; 3], mut pixel: impl FnMut(usize, f32)) {
    let area = edge(v[0], v[1], v[2].0, v[2].1);
    if area.abs() < 1e-6 || v.iter().any(|p| !(p.0.is_finite() && p.1.is_finite())) {
        return;
    }
    let min = |a: f32, b: f32, c: f32| a.min(b).min(c);
    let max = |a: f32, b: f32, c: f32| a.max(b).max(c);
    let x0 = min(v[0].0, v[1].0, v[2].0).floor().max(0.0) as usize;
    let y0 = min(v[0].1, v[1].1, v[2].1).floor().max(0.0) as usize;
    let x1 = (max(v[0].0, v[1].0, v[2].0).ceil().min(width as f32)).max(0.0) as usize;
    let y1 = (max(v[0].1, v[1].1, v[2].1).ceil().min(height as f32)).max(0.0) as usize;
    let inv = 1.0 / area;
    for y in y0..y1 {
        let py = y as f32 + 0.5;
        for x in x0..x1 {
            let px = x as f32 + 0.5;
            let b0 = edge(v[1], v[2], px, py) * inv;
            let b1 = edge(v[2], v[0], px, py) * inv;
            let b2 = edge(v[0], v[1], px, py) * inv;
            if b0 >= 0.0 && b1 >= 0.0 && b2 >= 0.0 {
                pixel(y * width as usize + x, b0 * v[0].2 + b1 * v[1].2 + b2 * v[2].2);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangles_cover_their_area_in_either_winding_and_depth_test() {
        let mut c = Canvas::new(40, 30);
        let t = [(0.0, 0.0, 1.0), (40.0, 0.0, 1.0), (0.0, 30.0, 1.0)];
        c.tri(t, [255, 0, 0]);
        let red = |c: &Canvas| c.frame.rgb().chunks(3).filter(|p| p == &[255, 0, 0]).count();
        // Half of the 1200 pixels, give or take the diagonal.
        assert!((580..=620).contains(&red(&c)), "{}", red(&c));
        // The same triangle farther away (smaller inverse depth) is hidden; reversed winding, nearer, is drawn.
        c.tri(t, [0, 255, 0]);
        c.tri([(0.0, 0.0, 0.5), (40.0, 0.0, 0.5), (0.0, 30.0, 0.5)], [0, 0, 255]);
        assert!((580..=620).contains(&red(&c)));
        c.tri([t[0], t[2], t[1]].map(|p| (p.0, p.1, 2.0)), [0, 0, 255]);
        assert_eq!(red(&c), 0);
    }

    #[test]
    fn side_by_side_puts_each_panel_in_its_columns() {
        let a = Frame::from_rgb(2, 2, vec![1; 12]).expect("2x2");
        let b = Frame::from_rgb(3, 2, (0..18).collect()).expect("3x2");
        let s = Frame::side_by_side(&[&a, &b]).expect("same height");
        assert_eq!((s.width(), s.height()), (5, 2));
        assert_eq!(s.pixel(1, 1), Some([1, 1, 1]));
        assert_eq!(s.pixel(2, 0), Some([0, 1, 2]), "b starts in column 2");
        assert_eq!(s.pixel(4, 1), Some([15, 16, 17]), "b's last pixel is the last");
        assert!(Frame::side_by_side(&[&a, &Frame::new(2, 4)]).is_none(), "heights differ");
        assert!(Frame::side_by_side(&[]).is_none());
    }

    #[test]
    fn the_ground_is_below_the_horizon_and_the_sky_above() {
        let cam = Camera {
            eye: Vector3::new(0.0, -4.0, 1.0),
            target: Vector3::new(0.0, 0.0, 1.0),
            fov_y: 0.8,
            width: 64,
            height: 36,
        };
        let mut c = Canvas::new(64, 36);
        c.background(&cam);
        let top = c.frame.pixel(32, 0).expect("inside");
        let bottom = c.frame.pixel(32, 35).expect("inside");
        assert!(top[2] > top[0] + 20, "sky is blue: {top:?}");
        assert!(bottom[0] == bottom[1] && bottom[1] == bottom[2], "ground is grey: {bottom:?}");
        // The horizontal camera puts the horizon on the middle row.
        assert_eq!(c.inv_depth[17 * 64 + 32], 0.0);
        assert!(c.inv_depth[19 * 64 + 32] > 0.0);
    }
}
