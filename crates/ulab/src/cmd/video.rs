//! Video output shared by `ulab render` and `ulab sim --video`: a `robot_render::Renderer` feeding an ffmpeg
//! child (H.264 MP4), with the time each stage takes.
use anyhow::{Context, Result};
use robot_model::{GenCoords, RobotModel};
use robot_render::{Caption, RenderOptions, Renderer, VideoWriter};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Picture size and rate of a video.
#[derive(Debug, Clone, clap::Args)]
pub struct VideoArgs {
    /// Frames per second of the video (of simulated or recorded time).
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// Frame width (pixels, even).
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    /// Frame height (pixels, even).
    #[arg(long, default_value_t = 360)]
    pub height: u32,
}

impl Default for VideoArgs {
    fn default() -> Self {
        VideoArgs { fps: 30.0, width: 640, height: 360 }
    }
}

/// A video being written.
#[derive(Debug)]
pub struct Video {
    renderer: Renderer,
    writer: VideoWriter,
    out: PathBuf,
    fps: f64,
    last_t: Option<f64>,
    render_s: f64,
    write_s: f64,
}

impl Video {
    /// Finds ffmpeg and starts writing `out`.
    pub fn create(model: &RobotModel, out: &Path, args: &VideoArgs) -> Result<Self> {
        anyhow::ensure!(args.fps.is_finite() && args.fps > 0.0 && args.fps <= 240.0, "--fps must be in (0, 240]");
        let opts = RenderOptions { width: args.width, height: args.height, ..RenderOptions::default() };
        let renderer = Renderer::new(model, &opts).context("setting up the renderer")?;
        let ffmpeg = robot_render::find_ffmpeg().context("a video needs ffmpeg")?;
        let writer = VideoWriter::create(&ffmpeg, out, args.width, args.height, args.fps)
            .with_context(|| format!("starting the video {}", out.display()))?;
        Ok(Video { renderer, writer, out: out.to_owned(), fps: args.fps, last_t: None, render_s: 0.0, write_s: 0.0 })
    }

    /// Appends the frame of `pose` at time `t` (s).
    pub fn frame(&mut self, pose: &GenCoords, t: f64, label: &str, progress: Option<f64>) -> Result<()> {
        let dt = self.last_t.map_or(0.0, |last| t - last);
        self.last_t = Some(t);
        let started = Instant::now();
        let frame = self
            .renderer
            .render(pose, dt, &Caption { time_s: t, label, progress })
            .with_context(|| format!("rendering the frame at t = {t:.3} s"))?;
        let rendered = Instant::now();
        self.writer.write(frame).with_context(|| format!("writing {}", self.out.display()))?;
        self.render_s += (rendered - started).as_secs_f64();
        self.write_s += rendered.elapsed().as_secs_f64();
        Ok(())
    }

    /// Finishes the file and prints what was written.
    pub fn finish(self) -> Result<()> {
        let started = Instant::now();
        let frames = self.writer.finish().with_context(|| format!("finishing {}", self.out.display()))?;
        let write_s = self.write_s + started.elapsed().as_secs_f64();
        let bytes = std::fs::metadata(&self.out).map(|m| m.len()).unwrap_or(0);
        let per = |s: f64| 1e3 * s / frames.max(1) as f64;
        eprintln!(
            "video: {} ({frames} frames, {:.2} s at {} fps, {:.0} KiB); render {:.1} ms/frame, encode {:.1} ms/frame",
            self.out.display(),
            frames as f64 / self.fps,
            self.fps,
            bytes as f64 / 1024.0,
            per(self.render_s),
            per(write_s),
        );
        Ok(())
    }
}

/// A frame for the video thread: time (s), pose, progress.
type FrameMsg = (f64, GenCoords, Option<f64>);

/// A [`Video`] fed from another thread at a fixed rate of simulated time, so that rendering and encoding do not
/// hold up the loop that produces the poses (`ulab sim` paces physics to the wall clock). Dropped, it finishes
/// the file with the frames it was given.
#[derive(Debug)]
pub struct VideoThread {
    tx: Option<std::sync::mpsc::Sender<FrameMsg>>,
    handle: Option<std::thread::JoinHandle<Result<()>>>,
    next_t: f64,
    period: f64,
}

impl VideoThread {
    /// Starts the thread; every frame is captioned with `label`.
    pub fn start(mut video: Video, label: String) -> Self {
        let period = 1.0 / video.fps;
        let (tx, rx) = std::sync::mpsc::channel::<FrameMsg>();
        let handle = std::thread::spawn(move || {
            for (t, pose, progress) in rx {
                video.frame(&pose, t, &label, progress)?;
            }
            video.finish()
        });
        VideoThread { tx: Some(tx), handle: Some(handle), next_t: 0.0, period }
    }

    /// Hands over the pose at `t` when a frame is due (`pose` is called only then).
    pub fn offer(&mut self, t: f64, pose: impl FnOnce() -> GenCoords, progress: Option<f64>) {
        if t + 1e-9 < self.next_t {
            return;
        }
        while self.next_t <= t + 1e-9 {
            self.next_t += self.period;
        }
        if let Some(tx) = &self.tx {
            // A send fails only when the thread has stopped on an error, which `finish` reports.
            let _ = tx.send((t, pose(), progress));
        }
    }

    /// Waits for the last frames to be encoded and the file to be finished.
    pub fn finish(mut self) -> Result<()> {
        self.join()
    }

    fn join(&mut self) -> Result<()> {
        drop(self.tx.take());
        match self.handle.take().map(|h| h.join()) {
            None => Ok(()),
            Some(Ok(r)) => r,
            Some(Err(_)) => anyhow::bail!("the video thread panicked"),
        }
    }
}

impl Drop for VideoThread {
    fn drop(&mut self) {
        if let Err(e) = self.join() {
            eprintln!("video: {e:#}");
        }
    }
}
