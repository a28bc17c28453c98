//! A short clip of a synthetic motion (the pelvis moves 1 m forward, the legs swing) written to MP4, then decoded
//! by ffmpeg's own H.264 decoder and checked: H.264 in yuv420p, the index at the front, every frame a picture (not
//! blank, robot pixels present), and the robot moves in the picture. Needs ffmpeg (`bash scripts/setup.sh`): the
//! test fails, saying so, without it.
use robot_model::GenCoords;
use robot_render::video::decode;
use robot_render::{find_ffmpeg, Caption, Frame, RenderOptions, Renderer, VideoWriter};

const FPS: f64 = 15.0;
const FRAMES: usize = 24;

fn warm(p: &[u8]) -> bool {
    i32::from(p[0]) - i32::from(p[2]) > 40
}

fn warm_mask(f: &Frame) -> Vec<bool> {
    f.rgb().chunks(3).map(warm).collect()
}

/// The synthetic motion at time `t`: walking-like leg swing while the pelvis moves forward 1 m over the clip.
fn pose_at(model: &robot_model::RobotModel, t: f64) -> GenCoords {
    let mut c = GenCoords::standing(model);
    let duration = (FRAMES - 1) as f64 / FPS;
    c.base_pos[0] = t / duration;
    let phase = (2.0 * std::f64::consts::PI * 1.2 * t).sin();
    for (i, j) in model.joints.iter().enumerate() {
        let side = if j.name.starts_with("left") { 1.0 } else { -1.0 };
        if j.name.contains("hip_pitch") {
            c.q[i] += 0.5 * side * phase;
        } else if j.name.contains("knee") {
            c.q[i] += 0.4 * (1.0 + side * phase);
        } else if j.name.contains("shoulder_pitch") {
            c.q[i] -= 0.5 * side * phase;
        }
    }
    c
}

#[test]
fn a_rendered_clip_decodes_as_h264_and_shows_the_robot_moving() {
    let ffmpeg = find_ffmpeg().unwrap_or_else(|e| panic!("this test needs ffmpeg: {e}"));
    let model = robot_model::builtin("h1_2").expect("model");
    let opts = RenderOptions { width: 320, height: 180, ..RenderOptions::default() };
    let mut r = Renderer::new(&model, &opts).expect("renderer");
    let dir = std::env::temp_dir().join(format!("robot-render-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let out = dir.join("clip.mp4");
    let mut v = VideoWriter::create(&ffmpeg, &out, opts.width, opts.height, FPS).expect("ffmpeg starts");
    for k in 0..FRAMES {
        let t = k as f64 / FPS;
        let caption =
            Caption { time_s: t, label: "synthetic", progress: Some(k as f64 / (FRAMES - 1) as f64), detail: "" };
        let frame = r.render(&pose_at(&model, t), 1.0 / FPS, &caption).expect("frame");
        v.write(frame).expect("frame written");
    }
    assert_eq!(v.finish().expect("ffmpeg finishes"), FRAMES as u64);

    let bytes = std::fs::read(&out).expect("mp4");
    let at = |tag: &[u8]| bytes.windows(4).position(|w| w == tag);
    assert_eq!(at(b"ftyp"), Some(4), "an ISO media file");
    let (moov, mdat) = (at(b"moov").expect("moov box"), at(b"mdat").expect("mdat box"));
    assert!(moov < mdat, "+faststart: the index comes before the media data");

    let (info, frames) = decode(&ffmpeg, &out).expect("ffmpeg decodes the clip");
    assert_eq!(info.codec, "h264", "{}", info.line);
    assert_eq!(info.pix_fmt, "yuv420p", "{}", info.line);
    assert_eq!((info.width, info.height), (opts.width, opts.height));
    assert_eq!(frames.len(), FRAMES, "every frame is in the file");

    for (k, f) in frames.iter().enumerate() {
        let luma: Vec<f64> = f
            .rgb()
            .chunks(3)
            .map(|p| 0.3 * f64::from(p[0]) + 0.59 * f64::from(p[1]) + 0.11 * f64::from(p[2]))
            .collect();
        let mean = luma.iter().sum::<f64>() / luma.len() as f64;
        let var = luma.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / luma.len() as f64;
        assert!(var.sqrt() > 15.0, "frame {k} is nearly blank (luma std {:.1})", var.sqrt());
        let robot = warm_mask(f).iter().filter(|&&m| m).count();
        assert!(robot > 500, "frame {k}: only {robot} robot-coloured pixels");
    }
    // The legs swing: the silhouette changes between the first and the last frame.
    let (a, b) = (warm_mask(&frames[0]), warm_mask(&frames[FRAMES - 1]));
    let changed = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    let union = a.iter().zip(&b).filter(|(x, y)| **x || **y).count();
    assert!(changed as f64 > 0.15 * union as f64, "silhouette barely changes: {changed} of {union} pixels");
    // The pelvis moves forward and the camera follows it: the ground under the robot scrolls. Compare the ground
    // (bottom quarter, robot pixels left out) of consecutive frames.
    let (w, h) = (opts.width as usize, opts.height as usize);
    let ground_diff = |f: &Frame, g: &Frame| {
        let (mut sum, mut n) = (0.0, 0usize);
        for y in 3 * h / 4..h - 12 {
            for x in 0..w {
                let i = 3 * (y * w + x);
                let (p, q) = (&f.rgb()[i..i + 3], &g.rgb()[i..i + 3]);
                if !warm(p) && !warm(q) {
                    sum += (f64::from(p[1]) - f64::from(q[1])).abs();
                    n += 1;
                }
            }
        }
        sum / n.max(1) as f64
    };
    let scroll = ground_diff(&frames[FRAMES / 2], &frames[FRAMES / 2 + 2]);
    assert!(scroll > 4.0, "the ground does not move under the walking robot (mean difference {scroll:.1})");
    // A still robot: the same two frames of a standing pose leave the ground still (the check above can fail).
    let mut still = Renderer::new(&model, &opts).expect("renderer");
    let cap = Caption { time_s: 0.0, label: "still", progress: None, detail: "" };
    let s0 = still.render(&GenCoords::standing(&model), 1.0 / FPS, &cap).expect("frame").clone();
    let s1 = still.render(&GenCoords::standing(&model), 2.0 / FPS, &cap).expect("frame").clone();
    assert!(ground_diff(&s0, &s1) < 0.5);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_failing_ffmpeg_reports_its_messages() {
    let ffmpeg = find_ffmpeg().unwrap_or_else(|e| panic!("this test needs ffmpeg: {e}"));
    // A directory that does not exist: ffmpeg cannot open its output and exits with an error.
    let out = std::env::temp_dir().join("robot-render-no-such-dir").join("x").join("clip.mp4");
    let mut v = VideoWriter::create(&ffmpeg, &out, 32, 32, 10.0).expect("ffmpeg starts");
    let frame = Frame::new(32, 32);
    let mut err = None;
    for _ in 0..200 {
        if let Err(e) = v.write(&frame) {
            err = Some(e);
            break;
        }
    }
    let err = match err {
        Some(e) => e,
        None => v.finish().expect_err("ffmpeg cannot write there"),
    };
    let text = err.to_string();
    assert!(text.contains("No such file") || text.contains("robot-render-no-such-dir"), "{text}");
}

/// A writer dropped in the middle of a video (an error elsewhere, a panic) stops and reaps its ffmpeg: no child is
/// left running or as a zombie.
#[test]
fn a_dropped_writer_leaves_no_child() {
    let ffmpeg = find_ffmpeg().unwrap_or_else(|e| panic!("this test needs ffmpeg: {e}"));
    let dir = std::env::temp_dir().join(format!("robot-render-drop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let mut v = VideoWriter::create(&ffmpeg, &dir.join("dropped.mp4"), 64, 48, 10.0).expect("ffmpeg starts");
    v.write(&Frame::new(64, 48)).expect("frame");
    let pid = v.pid();
    let proc_dir = std::path::PathBuf::from(format!("/proc/{pid}"));
    assert!(proc_dir.exists(), "ffmpeg runs while the video is open");
    drop(v);
    assert!(!proc_dir.exists(), "ffmpeg (pid {pid}) is still there after the writer was dropped");
    let _ = std::fs::remove_dir_all(&dir);
}
