//! `robot-render`: headless video of a robot, on a machine with no display and no GPU.
//!
//! A small software rasteriser draws the model's collision shapes (boxes, spheres, capsules, cylinders,
//! tessellated once) as z-buffered, Lambert-shaded triangles over a checkerboard ground with the robot's shadow,
//! seen by a perspective camera that follows the pelvis; a 5x7 bitmap font writes the time and a label (the engine)
//! and a bar shows the progress. [`VideoWriter`] pipes the frames into an `ffmpeg` child that encodes H.264 in an
//! MP4 a browser plays (yuv420p, `+faststart`).
//!
//! Stages, one module each: `mesh` (tessellation), `camera` (projection and the follow camera), `raster`
//! (triangles, ground, shadow), `overlay` (font, caption, progress bar), [`video`] (ffmpeg), [`odometry`] (base
//! pose of a robot log that has none: IMU orientation and kinematic leg odometry); [`Renderer`] puts the first four
//! together.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod camera;
mod error;
mod mesh;
pub mod odometry;
mod overlay;
mod raster;
mod scene;
pub mod video;

pub use camera::{Camera, FollowCamera};
pub use error::RenderError;
pub use raster::Frame;
pub use scene::{Caption, RenderOptions, Renderer};
pub use video::{find_ffmpeg, VideoError, VideoWriter};
