//! `ulab render` and `ulab sim --video` end to end: the videos decode (ffmpeg's own H.264 decoder) into pictures of
//! the robot; bad input ends with exit 2 and a message, never a panic. Needs ffmpeg (`bash scripts/setup.sh`).
mod common;

use common::{lease_domain, robot_pixels, run_ulab, sim_summary, tail};
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
