//! Video output shared by `ulab render`, `ulab sim --video`, `ulab diff --video` and `ulab validate --video`:
//! `robot_render::Renderer`s (one per panel) feeding an ffmpeg child (H.264 MP4), with the time each stage takes.
use anyhow::{Context, Result};
use engine_diff::harness::{Div, Trajectory};
use robot_model::{GenCoords, RobotModel};
use robot_render::{Caption, Frame, RenderOptions, Renderer, VideoWriter};
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

/// A video being written: one panel, or several side by side (each `--width` wide).
#[derive(Debug)]
pub struct Video {
    renderers: Vec<Renderer>,
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
        Self::create_panels(model, out, args, 1)
    }

    /// [`Video::create`] with `panels` pictures side by side, each `args.width` wide.
    pub fn create_panels(model: &RobotModel, out: &Path, args: &VideoArgs, panels: usize) -> Result<Self> {
        anyhow::ensure!(args.fps.is_finite() && args.fps > 0.0 && args.fps <= 240.0, "--fps must be in (0, 240]");
        anyhow::ensure!((1..=8).contains(&panels), "a video has 1 to 8 panels, not {panels}");
        let opts = RenderOptions { width: args.width, height: args.height, ..RenderOptions::default() };
        let renderers = (0..panels)
            .map(|_| Renderer::new(model, &opts))
            .collect::<Result<Vec<_>, _>>()
            .context("setting up the renderer")?;
        let ffmpeg = robot_render::find_ffmpeg().context("a video needs ffmpeg")?;
        let writer = VideoWriter::create(&ffmpeg, out, args.width * panels as u32, args.height, args.fps)
            .with_context(|| format!("starting the video {}", out.display()))?;
        Ok(Video { renderers, writer, out: out.to_owned(), fps: args.fps, last_t: None, render_s: 0.0, write_s: 0.0 })
    }

    /// Appends the frame of `pose` at time `t` (s).
    pub fn frame(&mut self, pose: &GenCoords, t: f64, label: &str, progress: Option<f64>) -> Result<()> {
        self.frame_panels(&[Panel { pose, followed: pose.base_pos, label, detail: "" }], t, progress)
    }

    /// Appends a frame of one panel per renderer, left to right, at time `t` (s).
    pub fn frame_panels(&mut self, panels: &[Panel<'_>], t: f64, progress: Option<f64>) -> Result<()> {
        anyhow::ensure!(
            panels.len() == self.renderers.len(),
            "{} panels for a video of {}",
            panels.len(),
            self.renderers.len()
        );
        let dt = self.last_t.map_or(0.0, |last| t - last);
        self.last_t = Some(t);
        let started = Instant::now();
        let frames = self
            .renderers
            .iter_mut()
            .zip(panels)
            .map(|(r, p)| {
                let caption = Caption { time_s: t, label: p.label, progress, detail: p.detail };
                r.render_following(p.pose, p.followed, dt, &caption)
            })
            .collect::<Result<Vec<&Frame>, _>>()
            .with_context(|| format!("rendering the frame at t = {t:.3} s"))?;
        let tiled;
        let frame = match frames.as_slice() {
            [one] => *one,
            many => {
                tiled = Frame::side_by_side(many).context("panels of different heights")?;
                &tiled
            }
        };
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

/// One panel of a frame: the robot's pose, the point the camera follows, the caption.
#[derive(Debug, Clone, Copy)]
pub struct Panel<'a> {
    pub pose: &'a GenCoords,
    /// World point (m) the panel's camera follows.
    pub followed: [f64; 3],
    /// Written after the time (the engine).
    pub label: &'a str,
    /// The caption's second line (empty: none).
    pub detail: &'a str,
}

/// Renders free runs of several engines side by side, the lead (`trajs[0]`) leftmost, one frame per trajectory
/// sample, and returns how far each engine's pelvis ended from the lead's (m).
///
/// Every panel's camera follows the lead's pelvis, not its own robot: the engines start from the same state, so
/// the panels start identical, and a robot that drifts, turns or falls differently from the lead is seen moving
/// away from the centre of its panel. A camera per robot would keep every robot centred and hide exactly that
/// drift. Each non-lead panel's second caption line is its divergence from the lead at that instant (pelvis
/// distance, largest joint-angle difference: `engine_diff::harness::Div`, the quantities of the diff report).
/// A run that ended early (a fall, an engine error) keeps its last state, captioned `stopped`.
pub fn render_trajectories(model: &RobotModel, out: &Path, args: &VideoArgs, trajs: &[Trajectory]) -> Result<Vec<f64>> {
    let Some(lead) = trajs.first() else { anyhow::bail!("no trajectory to render") };
    anyhow::ensure!(trajs.iter().all(|t| !t.samples.is_empty()), "a trajectory without samples");
    anyhow::ensure!(trajs.iter().all(|t| (t.fps - args.fps).abs() < 1e-9), "trajectories not sampled at --fps");
    let frames = trajs.iter().map(|t| t.samples.len()).max().unwrap_or(0);
    let mut video = Video::create_panels(model, out, args, trajs.len())?;
    /// Sample `k`, or the last one of a run that ended before it (none is empty, checked above).
    fn at(t: &Trajectory, k: usize) -> &(diff_physics::State, Vec<diff_physics::LinkPose>) {
        &t.samples[k.min(t.samples.len().saturating_sub(1))]
    }
    let mut last_div = vec![0.0; trajs.len()];
    let result = (0..frames).try_for_each(|k| {
        let (lead_st, lead_links) = at(lead, k);
        let poses: Vec<GenCoords> = trajs.iter().map(|t| at(t, k).0.coords()).collect();
        let details: Vec<String> = trajs
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let stopped = if k >= t.samples.len() { "stopped  " } else { "" };
                if i == 0 {
                    return format!("{stopped}lead");
                }
                let (st, links) = at(t, k);
                let d = Div::between(lead_st, lead_links, st, links);
                last_div[i] = d.base_pos;
                format!("{stopped}vs {}: pelvis {:.3} m, joint {:.2} rad", lead.engine, d.base_pos, d.max_q())
            })
            .collect();
        let panels: Vec<Panel<'_>> = trajs
            .iter()
            .zip(&poses)
            .zip(&details)
            .map(|((t, pose), detail)| Panel { pose, followed: lead_st.base_pos, label: &t.engine, detail })
            .collect();
        let progress = if frames > 1 { k as f64 / (frames - 1) as f64 } else { 1.0 };
        video.frame_panels(&panels, k as f64 / args.fps, Some(progress))
    });
    if let Err(e) = result.and_then(|()| video.finish()) {
        // What ffmpeg left of a stopped encode is no playable file.
        let _ = std::fs::remove_file(out);
        return Err(e);
    }
    Ok(last_div)
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
