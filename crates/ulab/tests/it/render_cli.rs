//! `ulab render`, `ulab sim --video`, `ulab diff --video` and `ulab validate --video` end to end: the videos decode
//! (ffmpeg's own H.264 decoder) into pictures of the robot, one panel per engine where engines are compared; a
//! recording of `ulab sim` carries the simulator's pelvis pose, which `ulab render` draws; bad input ends with exit
//! 2 and a message, never a panic. Needs ffmpeg (`bash scripts/setup.sh`).
use crate::common;

use common::{
    interrupt, lease_domain, robot_pixels, root, run_ulab, sim_summary, spawn_ulab, tail, wait_with_timeout,
    RealtimeSlot,
};
use gap_diagnosis::log::{Command, Measurement};
use gap_diagnosis::RobotLog;
use robot_render::video::decode;
use robot_render::Frame;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ulab-render-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn ffmpeg() -> PathBuf {
    robot_render::find_ffmpeg().unwrap_or_else(|e| panic!("this test needs ffmpeg: {e}"))
}

/// Decodes `path` and checks it is a browser-playable H.264 video of the robot; returns its frames.
fn check_video(path: &Path) -> Vec<Frame> {
    let (info, frames) = decode(&ffmpeg(), path).expect("ffmpeg decodes the video");
    assert_eq!((info.codec.as_str(), info.pix_fmt.as_str()), ("h264", "yuv420p"), "{}", info.line);
    assert_eq!((info.width, info.height), (640, 360));
    for (k, f) in frames.iter().enumerate() {
        assert!(robot_pixels(f.rgb()) > 1000, "frame {k}: the robot is not in the picture");
    }
    frames
}

/// A standing robot for one second at 100 Hz, arms swinging, facing 0.3 rad left of +x (the IMU says so).
fn standing_log(path: &Path) {
    let model = robot_model::builtin("h1_2").expect("model");
    let nj = model.nj();
    let q0 = model.default_q();
    let mut log = RobotLog::default();
    log.commands.push(Command {
        t: 0.0,
        q: q0.clone(),
        dq: vec![0.0; nj],
        kp: vec![0.0; nj],
        kd: vec![0.0; nj],
        tau: vec![0.0; nj],
    });
    for k in 0..=100 {
        let t = k as f64 * 0.01;
        let mut q = q0.clone();
        for (i, j) in model.joints.iter().enumerate() {
            if j.name.contains("shoulder_pitch") {
                q[i] += 0.6 * (6.0 * t).sin();
            }
        }
        let yaw: f64 = 0.3;
        log.states.push(Measurement {
            t,
            q,
            dq: vec![0.0; nj],
            tau: vec![0.0; nj],
            quat: [(yaw / 2.0).cos(), 0.0, 0.0, (yaw / 2.0).sin()],
            gyro: [0.0; 3],
            acc: [0.0, 0.0, 9.81],
        });
    }
    let f = std::fs::File::create(path).expect("create mcap");
    log.write_mcap(std::io::BufWriter::new(f), &model).expect("write mcap");
}

#[test]
fn render_draws_a_recording() {
    let dir = temp_dir("log");
    let (log, out) = (dir.join("standing.mcap"), dir.join("standing.mp4"));
    standing_log(&log);
    let (code, _, err) = run_ulab(
        &["render", log.to_str().expect("utf-8"), "--out", out.to_str().expect("utf-8"), "--fps", "15"],
        Duration::from_secs(120),
    );
    assert_eq!(code, Some(0), "{}", tail(&err));
    assert!(err.contains("101 LowState messages over 1.00 s -> 16 frames"), "{}", tail(&err));
    // Standing still: the leg odometry keeps the pelvis where it started.
    assert!(err.contains("estimated pelvis travel (0.00, 0.00) m"), "{}", tail(&err));
    let frames = check_video(&out);
    assert_eq!(frames.len(), 16);
    // The arms swing: the picture changes.
    let diff = frames[0].rgb().iter().zip(frames[5].rgb()).filter(|(a, b)| a.abs_diff(**b) > 40).count();
    assert!(diff > 200, "the first frames are alike ({diff} pixels differ)");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The engine named in a recording's metadata (`engine`) is the label; without it the label is `log`.
#[test]
fn render_labels_the_video_with_the_recorded_engine() {
    let dir = temp_dir("meta");
    let (plain, tagged, out) = (dir.join("plain.mcap"), dir.join("tagged.mcap"), dir.join("x.mp4"));
    standing_log(&plain);
    // The same messages again, with a metadata record naming the engine.
    {
        let bytes = std::fs::read(&plain).expect("read");
        let mut w = recording::write_options("test", recording::Compression::Zstd)
            .create(std::io::BufWriter::new(std::fs::File::create(&tagged).expect("create")))
            .expect("writer");
        let mut channels = std::collections::BTreeMap::new();
        for m in recording::messages(&bytes).expect("mcap") {
            let m = m.expect("message");
            let ty = recording::channel_type_name(&m.channel).expect("type");
            let ch = *channels
                .entry(m.channel.topic.clone())
                .or_insert_with(|| recording::add_topic(&mut w, &m.channel.topic, &ty).expect("channel"));
            let hdr = mcap::records::MessageHeader {
                channel_id: ch,
                sequence: m.sequence,
                log_time: m.log_time,
                publish_time: m.publish_time,
            };
            w.write_to_known_channel(&hdr, &m.data).expect("message");
        }
        let meta = [("engine".to_owned(), "rapier-impulse".to_owned())].into_iter().collect();
        w.write_metadata(&mcap::records::Metadata { name: "ulab.sim".to_owned(), metadata: meta }).expect("metadata");
        w.finish().expect("finish");
    }
    let out = out.to_str().expect("utf-8");
    for (log, label) in [(&plain, "(log;"), (&tagged, "(rapier-impulse;")] {
        let (code, _, err) =
            run_ulab(&["render", log.to_str().expect("utf-8"), "--out", out, "--fps", "5"], Duration::from_secs(120));
        assert_eq!(code, Some(0), "{}", tail(&err));
        assert!(err.contains(label), "expected {label}: {}", tail(&err));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn render_refuses_bad_input_with_exit_2() {
    let dir = temp_dir("bad");
    let out = dir.join("x.mp4");
    let out = out.to_str().expect("utf-8");
    // No such file.
    let missing = dir.join("missing.mcap");
    let (code, _, err) = run_ulab(&["render", missing.to_str().expect("utf-8"), "--out", out], Duration::from_secs(60));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("reading") && err.contains("missing.mcap") && !err.contains("panicked"), "{err}");
    // Not an MCAP.
    let junk = dir.join("junk.mcap");
    std::fs::write(&junk, b"not an mcap file at all").expect("write");
    let (code, _, err) = run_ulab(&["render", junk.to_str().expect("utf-8"), "--out", out], Duration::from_secs(60));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("not an MCAP file") && !err.contains("panicked"), "{err}");
    // An MCAP without LowState: commands only.
    let cmds = dir.join("commands.mcap");
    {
        let mut w = recording::write_options("test", recording::Compression::None)
            .create(std::io::BufWriter::new(std::fs::File::create(&cmds).expect("create")))
            .expect("writer");
        let ch = recording::add_topic(&mut w, "rt/lowcmd", unitree_idl::MessageType::HgLowCmd.dds_type_name())
            .expect("channel");
        let hdr = mcap::records::MessageHeader { channel_id: ch, sequence: 0, log_time: 1, publish_time: 1 };
        w.write_to_known_channel(&hdr, &[0, 1, 0, 0]).expect("message");
        w.finish().expect("finish");
    }
    let (code, _, err) = run_ulab(&["render", cmds.to_str().expect("utf-8"), "--out", out], Duration::from_secs(60));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("no hg LowState messages") && err.contains("rt/lowcmd"), "{err}");
    // Odd frame size.
    standing_log(&cmds);
    let (code, _, err) =
        run_ulab(&["render", cmds.to_str().expect("utf-8"), "--out", out, "--width", "641"], Duration::from_secs(60));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("must be even"), "{err}");
    assert!(!Path::new(out).exists(), "no video from bad input");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sim_video_shows_the_simulated_robot_at_30_fps_of_simulated_time() {
    let domain = lease_domain();
    let dir = temp_dir("sim");
    let out = dir.join("sim.mp4");
    let (code, _, err) = run_ulab(
        &[
            "sim",
            "--domain",
            &domain.arg(),
            "--fast",
            "--duration",
            "0.5",
            "--loco-api",
            "none",
            "--quiet",
            "--video",
            out.to_str().expect("utf-8"),
        ],
        Duration::from_secs(180),
    );
    assert_eq!(code, Some(0), "{}", tail(&err));
    let s = sim_summary(&err).unwrap_or_else(|| panic!("no sim summary:\n{}", tail(&err)));
    let simulated = s["simulated_seconds"].as_f64().expect("simulated seconds");
    let frames = check_video(&out);
    // A frame every 1/30 s of simulated time, the first at 0.
    let expected = (simulated * 30.0).floor() as usize + 1;
    assert!(frames.len().abs_diff(expected) <= 1, "{} frames for {simulated} s", frames.len());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The pixels of panel `k` of `n` side by side (RGB, row by row).
fn panel(f: &Frame, k: u32, n: u32) -> Vec<u8> {
    let w = f.width() / n;
    (0..f.height()).flat_map(|y| (k * w..(k + 1) * w).flat_map(move |x| f.pixel(x, y).unwrap_or([0; 3]))).collect()
}

/// Caption text pixels (near white; sky and ground never are) in the caption corner of the panel starting at `x0`.
fn caption_pixels(f: &Frame, x0: u32) -> usize {
    (0..26u32)
        .flat_map(|y| (x0..x0 + 90).map(move |x| (x, y)))
        .filter(|&(x, y)| f.pixel(x, y).is_some_and(|p| p.iter().all(|&c| c > 225)))
        .count()
}

/// Pixels below the captions that differ clearly between the two halves of a frame.
fn halves_differ(f: &Frame) -> usize {
    let w = f.width() / 2;
    (30..f.height() - 10)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| match (f.pixel(x, y), f.pixel(x + w, y)) {
            (Some(a), Some(b)) => a.iter().zip(b).any(|(p, q)| p.abs_diff(q) > 40),
            _ => false,
        })
        .count()
}

/// Pixels of panel `k` that differ clearly between two frames.
fn moved(a: &Frame, b: &Frame, k: u32, n: u32) -> usize {
    panel(a, k, n).iter().zip(panel(b, k, n)).filter(|(p, q)| p.abs_diff(*q) > 40).count()
}

/// Checks a two-panel video of `w` x `h` panels: H.264 in yuv420p, `frames` frames, the robot and a caption in
/// both panels of every frame; returns the frames.
fn check_two_panels(path: &Path, w: u32, h: u32, frames: usize) -> Vec<Frame> {
    let (info, decoded) = decode(&ffmpeg(), path).expect("ffmpeg decodes the video");
    assert_eq!((info.codec.as_str(), info.pix_fmt.as_str()), ("h264", "yuv420p"), "{}", info.line);
    assert_eq!((info.width, info.height), (2 * w, h), "two panels side by side");
    assert_eq!(decoded.len(), frames);
    for (k, f) in decoded.iter().enumerate() {
        for p in 0..2 {
            assert!(robot_pixels(&panel(f, p, 2)) > 150, "frame {k}: no robot in panel {p}");
            assert!(caption_pixels(f, p * w) > 40, "frame {k}: no caption in panel {p}");
        }
    }
    decoded
}

#[test]
fn diff_video_shows_the_engines_side_by_side_from_the_same_start() {
    let dir = temp_dir("diff");
    let (report, out) = (dir.join("report"), dir.join("diff.mp4"));
    let (code, stdout, err) = run_ulab(
        &[
            "diff",
            "--engines",
            "mujoco,rapier-impulse",
            "--episodes",
            "1",
            "--seconds",
            "2",
            "--minimize",
            "0",
            "--out",
            report.to_str().expect("utf-8"),
            "--video",
            out.to_str().expect("utf-8"),
            "--width",
            "192",
            "--height",
            "144",
        ],
        Duration::from_secs(300),
    );
    assert_eq!(code, Some(0), "{stdout}\n{}", tail(&err));
    // One frame per 1/30 s of the 2 s episode, the first at 0.
    let frames = check_two_panels(&out, 192, 144, 61);
    // The same start: the panels agree but for the captions; by the end the engines have drifted apart (the robot
    // falls backwards, Rapier's impulse solver ends 8 cm from MuJoCo).
    let (first, last) = (halves_differ(&frames[0]), halves_differ(&frames[60]));
    eprintln!("pixels that differ between the panels: {first} at t = 0, {last} at the end");
    assert!(first < 30, "the panels differ at t = 0 ({first} pixels)");
    assert!(last > 300, "the panels still agree at the end ({last} pixels)");
    // The robot moves in both panels.
    for p in 0..2 {
        let m = moved(&frames[0], &frames[60], p, 2);
        assert!(m > 300, "panel {p} does not change ({m} pixels)");
    }
    let line =
        stdout.lines().find(|l| l.starts_with("video: rapier_impulse ends")).unwrap_or_else(|| panic!("{stdout}"));
    assert!(line.ends_with("m from mujoco (pelvis)"), "{line}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn validate_video_renders_the_first_rollout_in_every_engine() {
    let dir = temp_dir("validate");
    let out = dir.join("validate.mp4");
    let spec = root().join("robots/h1_2/policies/unitree_rl_gym_lstm.toml");
    let (code, stdout, err) = run_ulab(
        &[
            "validate",
            "--policy",
            spec.to_str().expect("utf-8"),
            "--train-engine",
            "mujoco",
            "--engines",
            "mujoco,rapier-impulse",
            "--commands",
            "forward,stand",
            "--episodes",
            "1",
            "--seconds",
            "2",
            "--no-evidence",
            "--out",
            dir.join("report").to_str().expect("utf-8"),
            "--video",
            out.to_str().expect("utf-8"),
            "--width",
            "160",
            "--height",
            "120",
            "--fps",
            "15",
        ],
        Duration::from_secs(300),
    );
    assert_eq!(code, Some(0), "{stdout}\n{}", tail(&err));
    // The first command (forward) with the first seed, 2 s at 15 fps; the training engine leftmost.
    assert!(stdout.contains("video (forward seed 1): rapier_impulse ends"), "{stdout}");
    let frames = check_two_panels(&out, 160, 120, 31);
    assert!(halves_differ(&frames[0]) < 30, "the panels differ at t = 0");
    // Walking: the legs move in the training engine's panel.
    let m = moved(&frames[0], &frames[30], 0, 2);
    assert!(m > 200, "the lead panel does not change ({m} pixels)");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `(x, y, z)` after `label` in `text`.
fn triple_after(text: &str, label: &str) -> Option<[f64; 3]> {
    let rest = &text[text.find(label)? + label.len()..];
    let inner = rest.strip_prefix('(')?.split(')').next()?;
    let v: Vec<f64> = inner.split(',').filter_map(|x| x.trim().parse().ok()).collect();
    v.try_into().ok()
}

/// `ulab sim` publishes its own pelvis pose (rt/sportmodestate), `ulab record` records it by default and `ulab render`
/// draws it: where the rendered pelvis ends is where the simulator says it ended (its own summary, straight from the
/// engine, not through DDS and the recording); `--base-pose estimated` falls back to the estimate.
#[test]
fn render_of_a_sim_recording_uses_the_simulators_pelvis_pose() {
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let dir = temp_dir("truth");
    let (log, out) = (dir.join("sim.mcap"), dir.join("sim.mp4"));
    let recorder = spawn_ulab(&["record", "--domain", &domain.arg(), "--quiet", "--out", log.to_str().expect("utf-8")]);
    // Without the standing hold the robot collapses in damping mode: its pelvis drops and moves.
    let (code, _, sim_err) = run_ulab(
        &["sim", "--domain", &domain.arg(), "--duration", "3", "--no-hold", "--loco-api", "none", "--quiet"],
        Duration::from_secs(120),
    );
    assert_eq!(code, Some(0), "{}", tail(&sim_err));
    std::thread::sleep(Duration::from_millis(300));
    interrupt(&recorder);
    let (status, rec_out, rec_err) = wait_with_timeout(recorder, Duration::from_secs(60));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "{rec_out}\n{rec_err}");
    assert!(rec_out.contains("rt/sportmodestate: "), "{rec_out}");
    let s = sim_summary(&sim_err).unwrap_or_else(|| panic!("no sim summary:\n{}", tail(&sim_err)));
    let end: Vec<f64> = s["base"]["end"].as_array().expect("end").iter().filter_map(|v| v.as_f64()).collect();
    let start: Vec<f64> = s["base"]["start"].as_array().expect("start").iter().filter_map(|v| v.as_f64()).collect();
    assert!(start[2] - end[2] > 0.3, "the robot did not collapse: {}", s["base"]);

    let render = |pose: &str| {
        let (code, _, err) = run_ulab(
            &[
                "render",
                log.to_str().expect("utf-8"),
                "--out",
                out.to_str().expect("utf-8"),
                "--base-pose",
                pose,
                "--fps",
                "10",
                "--width",
                "160",
                "--height",
                "120",
            ],
            Duration::from_secs(120),
        );
        assert_eq!(code, Some(0), "{}", tail(&err));
        err
    };
    let err = render("auto");
    assert!(err.contains("SportModeState messages)") && err.contains("base pose recorded, "), "{}", tail(&err));
    let path = err.lines().find(|l| l.contains("recorded pelvis travel")).unwrap_or_else(|| panic!("{}", tail(&err)));
    let drawn = triple_after(path, " to ").unwrap_or_else(|| panic!("no pelvis end in {path:?}"));
    eprintln!("{path}\nsimulator: from {start:?} to {end:?}");
    for i in 0..3 {
        assert!((drawn[i] - end[i]).abs() < 0.01, "rendered pelvis end {drawn:?}, simulator's {end:?}");
    }
    let (_, frames) = decode(&ffmpeg(), &out).expect("ffmpeg decodes the video");
    assert!(frames.iter().all(|f| robot_pixels(f.rgb()) > 100), "a frame without the robot");

    let err = render("estimated");
    assert!(err.contains("base pose estimated") && err.contains("estimated pelvis travel"), "{}", tail(&err));
    eprintln!("{}", err.lines().find(|l| l.contains("estimated pelvis travel")).unwrap_or_default());
    let _ = std::fs::remove_dir_all(&dir);
}
