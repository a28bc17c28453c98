//! `ulab render`: a video of a recorded run. Joint angles come from the LowState messages of the recording. The
//! base pose, which LowState does not carry, comes from the recording's go SportModeState messages when it has
//! any (`rt/sportmodestate`: what `ulab sim` and Unitree's MuJoCo bridge publish, the simulator's own pelvis
//! position and orientation; each LowState takes the latest one at or before its log time), and is estimated
//! otherwise (`robot_render::odometry`): orientation from the IMU (on the H1-2's torso, taken through the waist
//! joint), height from the lowest collision point on the ground, horizontal position by kinematic leg odometry.
//! The printout and the picture's second caption line say which.

use super::video::{Panel, Video, VideoArgs};
use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use recording::{channel_type_name, kind_of};
use robot_model::{GenCoords, RobotModel};
use robot_render::odometry::{pelvis_quat_from_imu, LegOdometry};
use std::collections::BTreeSet;
use std::path::PathBuf;
use unitree_idl::MessageType;

/// MCAP metadata key naming the engine of a simulated run (written into the picture).
pub const ENGINE_METADATA_KEY: &str = "engine";

/// Arguments of `ulab render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// MCAP recording with hg LowState messages (what `ulab record` writes).
    pub file: PathBuf,
    /// The video to write (H.264 MP4).
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub video: VideoArgs,
    /// Robot model (built in): h1_2.
    #[arg(long, default_value = "h1_2")]
    pub robot: String,
    /// Label written after the time (default: the recording's `engine` metadata, else `log`).
    #[arg(long)]
    pub label: Option<String>,
    /// Where the base pose comes from: auto (the recorded SportModeState when the log has any, else the
    /// estimate), recorded (an error without SportModeState), estimated (ignore any recorded pose).
    #[arg(long, value_enum, default_value_t = BaseSource::Auto)]
    pub base_pose: BaseSource,
}

/// `--base-pose`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BaseSource {
    Auto,
    Recorded,
    Estimated,
}

/// One SportModeState: log time (ns), pelvis position (m) and orientation `[w, x, y, z]` (normalised).
struct BaseSample {
    t_ns: u64,
    pos: [f64; 3],
    quat: [f64; 4],
}

/// One LowState: log time (ns), joint angles (slot order), IMU quaternion `[w, x, y, z]`.
struct Sample {
    t_ns: u64,
    q: Vec<f64>,
    imu: [f64; 4],
}

/// What the first pass over a recording found.
#[derive(Default)]
struct Scan {
    /// LowState messages in log-time order (a message older than the one before it is left out).
    used: usize,
    /// Left out: older than the message before them.
    out_of_order: usize,
    undecodable: usize,
    first_ns: Option<u64>,
    last_ns: u64,
}

pub fn run(args: Args) -> Result<Exit> {
    let model = robot_model::builtin(&args.robot).with_context(|| format!("loading robot `{}`", args.robot))?;
    let name = args.file.display();
    let bytes = std::fs::read(&args.file).with_context(|| format!("reading {name}"))?;
    // Two passes over the file, so that an hour at 500 Hz is rendered in constant memory: the first finds the time
    // span (for the frame count and the progress bar), the second estimates the base pose and renders as it goes.
    let mut scan = Scan::default();
    for_each_lowstate(&bytes, &model, &mut scan.undecodable, |s| {
        match scan.first_ns {
            Some(_) if s.t_ns < scan.last_ns => scan.out_of_order += 1,
            _ => {
                scan.first_ns.get_or_insert(s.t_ns);
                scan.last_ns = s.t_ns;
                scan.used += 1;
            }
        }
        Ok(())
    })
    .with_context(|| format!("reading {name}"))?;
    let Some(t0) = scan.first_ns else {
        let topics = topics(&bytes);
        bail!(
            "{name} holds no hg LowState messages (type {}){}",
            MessageType::HgLowState.dds_type_name(),
            if topics.is_empty() { String::new() } else { format!("; its topics: {}", topics.join(", ")) }
        );
    };
    if scan.undecodable > 0 {
        eprintln!("render: {} LowState messages do not decode; skipped", scan.undecodable);
    }
    if scan.out_of_order > 0 {
        eprintln!("render: {} LowState messages older than the one before them; skipped", scan.out_of_order);
    }
    let label = args.label.clone().or_else(|| engine_metadata(&bytes)).unwrap_or_else(|| "log".to_owned());
    let duration = (scan.last_ns - t0) as f64 * 1e-9;
    let fps = args.video.fps;
    let frames = (duration * fps + 1e-9).floor() as usize + 1;
    let recorded = if args.base_pose == BaseSource::Estimated {
        Vec::new()
    } else {
        base_samples(&bytes).with_context(|| format!("reading the SportModeState messages of {name}"))?
    };
    if args.base_pose == BaseSource::Recorded && recorded.is_empty() {
        bail!(
            "{name} holds no usable SportModeState messages (type {}): no recorded base pose",
            MessageType::GoSportModeState.dds_type_name()
        );
    }
    let source = if recorded.is_empty() {
        "base pose estimated".to_owned()
    } else {
        format!("base pose recorded, {} SportModeState messages", recorded.len())
    };
    eprintln!(
        "render: {} LowState messages over {duration:.2} s -> {frames} frames at {fps} fps ({label}; {source})",
        scan.used
    );
    let detail = if recorded.is_empty() { "pose: estimated" } else { "pose: recorded" };

    let mut video = Video::create(&model, &args.out, &args.video)?;
    let mut odo = Odometry::new(&model, recorded)?;
    let mut k = 0usize;
    let mut prev: Option<GenCoords> = None;
    let mut last_ns = 0u64;
    let progress = |t: f64| if duration > 0.0 { t / duration } else { 1.0 };
    let mut ignored = 0usize;
    let rendered = for_each_lowstate(&bytes, &model, &mut ignored, |s| {
        if prev.is_some() && s.t_ns < last_ns {
            return Ok(());
        }
        last_ns = s.t_ns;
        let t = (s.t_ns - t0) as f64 * 1e-9;
        // Frames before this message show the latest pose at or before their time.
        if let Some(p) = &prev {
            while k < frames && (k as f64) / fps < t {
                let panel = Panel { pose: p, followed: p.base_pos, label: &label, detail };
                video.frame_panels(&[panel], k as f64 / fps, Some(progress(k as f64 / fps)))?;
                k += 1;
            }
        }
        prev = Some(odo.update(&model, &s));
        Ok(())
    })
    .and_then(|_| {
        if let Some(p) = &prev {
            while k < frames {
                let panel = Panel { pose: p, followed: p.base_pos, label: &label, detail };
                video.frame_panels(&[panel], k as f64 / fps, Some(progress(k as f64 / fps)))?;
                k += 1;
            }
        }
        video.finish()
    });
    if let Err(e) = rendered {
        // ffmpeg was stopped (or failed): what it left is no playable file.
        let _ = std::fs::remove_file(&args.out);
        return Err(e);
    }
    odo.report();
    Ok(Exit::Success)
}

/// Calls `f` with every hg LowState message of a recording (any topic whose type is hg LowState), in file order;
/// counts those that do not decode.
fn for_each_lowstate(
    bytes: &[u8],
    model: &RobotModel,
    undecodable: &mut usize,
    mut f: impl FnMut(Sample) -> Result<()>,
) -> Result<()> {
    for m in recording::messages(bytes)? {
        let m = m?;
        if channel_type_name(&m.channel).and_then(|t| kind_of(&t)) != Some(MessageType::HgLowState) {
            continue;
        }
        let Ok(d) = lowlevel_codec::decode::<unitree_idl::hg::LowState_>(&m.data) else {
            *undecodable += 1;
            continue;
        };
        let s = &d.value;
        let mut q = Vec::with_capacity(model.nj());
        for j in &model.joints {
            let Some(ms) = s.motor_state.get(j.slot) else {
                bail!("LowState has {} motor slots, the {} joint is slot {}", s.motor_state.len(), j.name, j.slot);
            };
            q.push(f64::from(ms.q));
        }
        f(Sample { t_ns: m.log_time, q, imu: s.imu_state.quaternion.map(f64::from) })?;
    }
    Ok(())
}

/// The base pose over the recording (recorded or estimated, see the module docs), with what it had to make up.
struct Odometry {
    legs: LegOdometry,
    /// Recorded base poses in log-time order; empty: estimate.
    recorded: Vec<BaseSample>,
    start: Option<GenCoords>,
    last: Option<GenCoords>,
    path_m: f64,
    no_imu: usize,
    bad: usize,
}

impl Odometry {
    fn new(model: &RobotModel, recorded: Vec<BaseSample>) -> Result<Self> {
        let legs = LegOdometry::new(model).context("finding the feet of the model")?;
        Ok(Odometry { legs, recorded, start: None, last: None, path_m: 0.0, no_imu: 0, bad: 0 })
    }

    /// The pose of the next message. Recorded: the latest base pose at or before the message (the first one
    /// before it). Estimated: a message with non-finite joint angles keeps the previous pose; an IMU quaternion
    /// that is no rotation (all zeros) counts as upright.
    fn update(&mut self, model: &RobotModel, s: &Sample) -> GenCoords {
        let pose = if self.recorded.is_empty() {
            self.estimate(model, s)
        } else {
            let i = self.recorded.partition_point(|b| b.t_ns <= s.t_ns).saturating_sub(1);
            let b = &self.recorded[i];
            if s.q.iter().all(|q| q.is_finite()) {
                GenCoords { base_pos: b.pos, base_quat: b.quat, q: s.q.clone() }
            } else {
                self.bad += 1;
                let q = self.last.as_ref().map_or_else(|| model.default_q(), |l| l.q.clone());
                GenCoords { base_pos: b.pos, base_quat: b.quat, q }
            }
        };
        if let Some(last) = &self.last {
            self.path_m += dist_xy(last, &pose);
        }
        self.start.get_or_insert_with(|| pose.clone());
        self.last = Some(pose.clone());
        pose
    }

    fn estimate(&mut self, model: &RobotModel, s: &Sample) -> GenCoords {
        let pelvis = pelvis_quat_from_imu(model, s.imu, &s.q).unwrap_or_else(|_| {
            self.no_imu += 1;
            [1.0, 0.0, 0.0, 0.0]
        });
        match self.legs.update(model, pelvis, &s.q) {
            Ok(c) => c,
            Err(_) => {
                self.bad += 1;
                self.last.clone().unwrap_or_else(|| GenCoords::standing(model))
            }
        }
    }

    fn report(&self) {
        if self.no_imu > 0 {
            eprintln!("render: {} LowState messages have no valid IMU quaternion; drawn upright", self.no_imu);
        }
        if self.bad > 0 {
            eprintln!("render: {} LowState messages have non-finite joint angles; the previous pose is kept", self.bad);
        }
        if let (Some(a), Some(b)) = (&self.start, &self.last) {
            let p = |c: &GenCoords| format!("({:.3}, {:.3}, {:.3})", c.base_pos[0], c.base_pos[1], c.base_pos[2]);
            eprintln!(
                "render: {} pelvis travel ({:.2}, {:.2}) m, {:.2} m in all; from {} to {} m",
                if self.recorded.is_empty() { "estimated" } else { "recorded" },
                b.base_pos[0] - a.base_pos[0],
                b.base_pos[1] - a.base_pos[1],
                self.path_m,
                p(a),
                p(b)
            );
        }
    }
}

/// The recording's go SportModeState messages with a finite position and a non-zero orientation, in log-time
/// order (any topic of that type).
fn base_samples(bytes: &[u8]) -> Result<Vec<BaseSample>> {
    let mut out = Vec::new();
    let mut unusable = 0usize;
    for m in recording::messages(bytes)? {
        let m = m?;
        if channel_type_name(&m.channel).and_then(|t| kind_of(&t)) != Some(MessageType::GoSportModeState) {
            continue;
        }
        let Ok(d) = lowlevel_codec::decode::<unitree_idl::go::SportModeState_>(&m.data) else {
            unusable += 1;
            continue;
        };
        let pos = d.value.position.map(f64::from);
        let q = d.value.imu_state.quaternion.map(f64::from);
        let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        if !(pos.iter().all(|x| x.is_finite()) && n.is_finite() && n > 0.5) {
            unusable += 1;
            continue;
        }
        out.push(BaseSample { t_ns: m.log_time, pos, quat: q.map(|x| x / n) });
    }
    if unusable > 0 {
        eprintln!("render: {unusable} SportModeState messages do not decode or hold no pose; skipped");
    }
    out.sort_by_key(|b| b.t_ns);
    Ok(out)
}

fn dist_xy(a: &GenCoords, b: &GenCoords) -> f64 {
    (a.base_pos[0] - b.base_pos[0]).hypot(a.base_pos[1] - b.base_pos[1])
}

/// The `engine` entry of the recording's metadata records, if any.
fn engine_metadata(bytes: &[u8]) -> Option<String> {
    let reader = mcap::read::LinearReader::new(bytes).ok()?;
    reader.map_while(Result::ok).find_map(|r| match r {
        mcap::records::Record::Metadata(m) => m.metadata.get(ENGINE_METADATA_KEY).cloned(),
        _ => None,
    })
}

/// The topics of a recording, for an error message.
fn topics(bytes: &[u8]) -> Vec<String> {
    let Ok(messages) = recording::messages(bytes) else {
        return Vec::new();
    };
    let set: BTreeSet<String> = messages.map_while(Result::ok).map(|m| m.channel.topic.clone()).collect();
    set.into_iter().collect()
}
