//! The renderer: a robot pose in, a frame out (background, shadow, shaded shapes, caption).
use crate::camera::{Camera, FollowCamera};
use crate::error::RenderError;
use crate::mesh::{robot_meshes, LinkMesh};
use crate::overlay;
use crate::raster::{Canvas, Frame, ScreenVertex};
use nalgebra::{Point3, Vector3};
use robot_model::{GenCoords, RobotModel};

/// Picture size and camera placement.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOptions {
    /// Frame width (pixels, even: H.264 in yuv420p needs even sizes).
    pub width: u32,
    /// Frame height (pixels, even).
    pub height: u32,
    /// Vertical field of view (degrees).
    pub fov_y_deg: f64,
    /// Camera eye relative to the followed point (m, world axes): in front of the robot and to its right, a
    /// little above, so that a robot walking along +x is seen three-quarters from the front.
    pub camera_offset: [f64; 3],
    /// Height of the point the camera looks at (m).
    pub camera_height: f64,
    /// Time constant with which the camera follows the pelvis (s).
    pub follow_time_constant: f64,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 640,
            height: 360,
            fov_y_deg: 40.0,
            camera_offset: [1.6, -3.4, 0.5],
            camera_height: 0.85,
            follow_time_constant: 0.5,
        }
    }
}

/// What is written over a frame.
#[derive(Debug, Clone, Copy)]
pub struct Caption<'a> {
    /// Time of the frame (s), written as `t = 1.23 s`.
    pub time_s: f64,
    /// Written after the time: the engine, or where the poses come from.
    pub label: &'a str,
    /// Fraction of the run done (0 to 1), drawn as a bar; `None`: no bar.
    pub progress: Option<f64>,
    /// A second line under the first (empty: none): what a panel of a side-by-side video adds, such as its
    /// divergence from the lead engine.
    pub detail: &'a str,
}

/// Direction toward the light (world), unnormalised: high, from the camera's side.
const LIGHT: [f64; 3] = [0.35, -0.45, 1.0];

/// Renders a robot, frame after frame, with the camera following its pelvis.
#[derive(Debug)]
pub struct Renderer {
    model: RobotModel,
    meshes: Vec<LinkMesh>,
    follow: FollowCamera,
    canvas: Canvas,
    camera: Option<Camera>,
    /// Scratch: world-frame triangles of the current pose, with their mesh index.
    world: Vec<([Vector3<f64>; 3], usize)>,
}

impl Renderer {
    /// A renderer of `model` (its collision shapes are tessellated here, once).
    pub fn new(model: &RobotModel, opts: &RenderOptions) -> Result<Self, RenderError> {
        let (w, h) = (opts.width, opts.height);
        if !(16..=4096).contains(&w) || !(16..=4096).contains(&h) || w % 2 != 0 || h % 2 != 0 {
            return Err(RenderError::Options(format!("frame size {w}x{h}: each side must be even, 16 to 4096")));
        }
        if !(opts.fov_y_deg > 1.0 && opts.fov_y_deg < 170.0) {
            return Err(RenderError::Options(format!("field of view {} degrees", opts.fov_y_deg)));
        }
        let offset = Vector3::from(opts.camera_offset);
        if !(offset.iter().all(|v| v.is_finite()) && offset.norm() > 0.1 && opts.camera_height.is_finite()) {
            return Err(RenderError::Options(format!("camera offset {:?}", opts.camera_offset)));
        }
        if !(opts.follow_time_constant >= 0.0) {
            return Err(RenderError::Options("negative follow time constant".into()));
        }
        Ok(Renderer {
            model: model.clone(),
            meshes: robot_meshes(model),
            follow: FollowCamera::new(
                offset,
                opts.camera_height,
                opts.follow_time_constant,
                opts.fov_y_deg.to_radians(),
            ),
            canvas: Canvas::new(w, h),
            camera: None,
            world: Vec::new(),
        })
    }

    /// The camera of the last frame.
    pub fn camera(&self) -> Option<&Camera> {
        self.camera.as_ref()
    }

    /// Number of triangles drawn per frame (the tessellated collision shapes).
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.tris.len()).sum()
    }

    /// Renders the robot at `pose`, `dt` seconds after the previous frame (the camera follows with its lag).
    pub fn render(&mut self, pose: &GenCoords, dt: f64, caption: &Caption<'_>) -> Result<&Frame, RenderError> {
        self.render_following(pose, pose.base_pos, dt, caption)
    }

    /// [`Renderer::render`] with the camera following `followed` (world, m) instead of this robot's pelvis:
    /// panels of one video that follow the same point show how far their robots are apart.
    pub fn render_following(
        &mut self,
        pose: &GenCoords,
        followed: [f64; 3],
        dt: f64,
        caption: &Caption<'_>,
    ) -> Result<&Frame, RenderError> {
        let fk = self.model.fk(pose)?;
        let (w, h) = (self.canvas.frame.width(), self.canvas.frame.height());
        let cam = self.follow.update(followed, dt, w, h);
        let basis = cam.basis();
        self.canvas.background(&cam);

        self.world.clear();
        for (k, m) in self.meshes.iter().enumerate() {
            let pose = fk.link_poses[m.link];
            for t in &m.tris {
                self.world.push((t.map(|p: Point3<f32>| (pose * p.cast::<f64>()).coords), k));
            }
        }
        let project = |p: Vector3<f64>| -> Option<ScreenVertex> {
            cam.project_with(&basis, p).map(|(x, y, d)| (x as f32, y as f32, (1.0 / d) as f32))
        };

        // Shadow: every triangle projected along the light onto the ground.
        let light = Vector3::from(LIGHT);
        for (t, _) in &self.world {
            let on_ground = t.map(|p| p - light * (p.z.max(0.0) / light.z));
            if let [Some(a), Some(b), Some(c)] = on_ground.map(project) {
                self.canvas.shadow_tri([a, b, c]);
            }
        }
        self.canvas.apply_shadow();

        let light = light.normalize();
        for (t, k) in &self.world {
            let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
            // Back faces (the shapes are closed and wound outwards) are hidden anyway.
            if n.dot(&(t[0] - cam.eye)) >= 0.0 {
                continue;
            }
            let n = n.normalize();
            let shade = (0.3 + 0.55 * n.dot(&light).max(0.0) + 0.25 * (-n.dot(&basis.forward)).max(0.0)).min(1.0);
            let color = self.meshes[*k].color.map(|c| (f64::from(c) * shade).round().clamp(0.0, 255.0) as u8);
            if let [Some(a), Some(b), Some(c)] = t.map(project) {
                self.canvas.tri([a, b, c], color);
            }
        }

        let text = format!("t = {:.2} s  {}", caption.time_s, caption.label);
        overlay::draw(&mut self.canvas.frame, &[&text, caption.detail], caption.progress);
        self.camera = Some(cam);
        Ok(&self.canvas.frame)
    }
}
