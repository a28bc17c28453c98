//! `ulab render`: a video of a recorded run. Joint angles come from the LowState messages of the recording; the
//! base pose, which LowState does not carry, is estimated (`robot_render::odometry`): orientation from the IMU
//! (on the H1-2's torso, taken through the waist joint), height from the lowest collision point on the ground,
//! horizontal position by kinematic leg odometry.

use super::video::{Video, VideoArgs};
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
}

/// One LowState: time since the first (s), joint angles (slot order), IMU quaternion `[w, x, y, z]`.
struct Sample {
    t_ns: u64,
    q: Vec<f64>,
    imu: [f64; 4],
}

pub fn run(args: Args) -> Result<Exit> {
    let model = robot_model::builtin(&args.robot).with_context(|| format!("loading robot `{}`", args.robot))?;
    let name = args.file.display();
    let bytes = std::fs::read(&args.file).with_context(|| format!("reading {name}"))?;
    let (mut samples, undecodable) = lowstates(&bytes, &model).with_context(|| format!("reading {name}"))?;
    if samples.is_empty() {
        let topics = topics(&bytes);
        bail!(
            "{name} holds no hg LowState messages (type {}){}",
            MessageType::HgLowState.dds_type_name(),
            if topics.is_empty() { String::new() } else { format!("; its topics: {}", topics.join(", ")) }
        );
    }
    if undecodable > 0 {
        eprintln!("render: {undecodable} LowState messages do not decode; skipped");
    }
    samples.sort_by_key(|s| s.t_ns);
    let label = args.label.clone().or_else(|| engine_metadata(&bytes)).unwrap_or_else(|| "log".to_owned());

    let poses = estimate_poses(&model, &samples)?;
    if let (Some(first), Some(last)) = (poses.first(), poses.last()) {
        let [x0, y0, _] = first.base_pos;
        let [x1, y1, _] = last.base_pos;
        eprintln!(
            "render: estimated pelvis travel ({:.2}, {:.2}) m, {:.2} m in all",
            x1 - x0,
            y1 - y0,
            poses.windows(2).map(|w| dist_xy(&w[0], &w[1])).sum::<f64>()
        );
    }
    let t0 = samples[0].t_ns;
    let times: Vec<f64> = samples.iter().map(|s| (s.t_ns - t0) as f64 * 1e-9).collect();
    let duration = times.last().copied().unwrap_or(0.0);
    let frames = (duration * args.video.fps).floor() as usize + 1;
    eprintln!(
        "render: {} LowState messages over {duration:.2} s -> {frames} frames at {} fps ({label}; base pose estimated)",
        samples.len(),
        args.video.fps
    );
    let mut video = Video::create(&model, &args.out, &args.video)?;
    for k in 0..frames {
        let t = k as f64 / args.video.fps;
        // The latest state at or before the frame's time.
        let i = times.partition_point(|&s| s <= t).saturating_sub(1);
        let progress = if duration > 0.0 { t / duration } else { 1.0 };
        video.frame(&poses[i], t, &label, Some(progress))?;
    }
    video.finish()?;
    Ok(Exit::Success)
}

/// The hg LowState messages of a recording (any topic whose type is hg LowState), and how many did not decode.
fn lowstates(bytes: &[u8], model: &RobotModel) -> Result<(Vec<Sample>, usize)> {
    let mut out = Vec::new();
    let mut bad = 0;
    for m in recording::messages(bytes)? {
        let m = m?;
        if channel_type_name(&m.channel).and_then(|t| kind_of(&t)) != Some(MessageType::HgLowState) {
            continue;
        }
        let Ok(d) = lowlevel_codec::decode::<unitree_idl::hg::LowState_>(&m.data) else {
            bad += 1;
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
        out.push(Sample { t_ns: m.log_time, q, imu: s.imu_state.quaternion.map(f64::from) });
    }
    Ok((out, bad))
}

/// Base pose of every sample (see the module docs). A sample with non-finite joint angles keeps the previous pose;
/// an IMU quaternion that is no rotation (all zeros) counts as upright.
fn estimate_poses(model: &RobotModel, samples: &[Sample]) -> Result<Vec<GenCoords>> {
    let mut odo = LegOdometry::new(model).context("finding the feet of the model")?;
    let mut poses: Vec<GenCoords> = Vec::with_capacity(samples.len());
    let (mut no_imu, mut bad) = (0usize, 0usize);
    for s in samples {
        let pelvis = pelvis_quat_from_imu(model, s.imu, &s.q).unwrap_or_else(|_| {
            no_imu += 1;
            [1.0, 0.0, 0.0, 0.0]
        });
        match odo.update(model, pelvis, &s.q) {
            Ok(c) => poses.push(c),
            Err(_) => {
                bad += 1;
                let prev = poses.last().cloned().unwrap_or_else(|| GenCoords::standing(model));
                poses.push(prev);
            }
        }
    }
    if no_imu > 0 {
        eprintln!("render: {no_imu} LowState messages have no valid IMU quaternion; drawn upright");
    }
    if bad > 0 {
        eprintln!("render: {bad} LowState messages have non-finite joint angles; the previous pose is kept");
    }
    Ok(poses)
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
