//! Speed of the renderer and of the encoder (BENCHMARKS.md "Video"): `cargo bench -p robot-render --bench render`.
//! Renders 150 frames (5 s at 30 fps) of a swinging-legs motion at 640x360, then encodes the same frames with
//! ffmpeg (libx264 veryfast), and prints milliseconds per frame of each stage and the file size.
use robot_model::GenCoords;
use robot_render::{find_ffmpeg, Caption, RenderOptions, Renderer, VideoWriter};
use std::time::Instant;

fn main() {
    let model = robot_model::builtin("h1_2").expect("model");
    let opts = RenderOptions::default();
    let mut r = Renderer::new(&model, &opts).expect("renderer");
    let n = 150;
    let fps = 30.0;
    let poses: Vec<GenCoords> = (0..n)
        .map(|k| {
            let t = k as f64 / fps;
            let mut c = GenCoords::standing(&model);
            c.base_pos[0] = 0.5 * t;
            for (i, j) in model.joints.iter().enumerate() {
                let side = if j.name.starts_with("left") { 1.0 } else { -1.0 };
                if j.name.contains("hip_pitch") {
                    c.q[i] += 0.4 * side * (5.0 * t).sin();
                }
            }
            c
        })
        .collect();
    // Warm-up, then timed rendering alone.
    let cap =
        |k: usize| Caption { time_s: k as f64 / fps, label: "bench", progress: Some(k as f64 / n as f64), detail: "" };
    r.render(&poses[0], 0.0, &cap(0)).expect("frame");
    let started = Instant::now();
    let mut frames = Vec::with_capacity(n);
    for (k, p) in poses.iter().enumerate() {
        frames.push(r.render(p, 1.0 / fps, &cap(k)).expect("frame").clone());
    }
    let render_ms = 1e3 * started.elapsed().as_secs_f64() / n as f64;
    let ffmpeg = find_ffmpeg().expect("ffmpeg");
    let out = std::env::temp_dir().join(format!("robot-render-bench-{}.mp4", std::process::id()));
    let started = Instant::now();
    let mut v = VideoWriter::create(&ffmpeg, &out, opts.width, opts.height, fps).expect("ffmpeg");
    for f in &frames {
        v.write(f).expect("write");
    }
    v.finish().expect("finish");
    let encode_ms = 1e3 * started.elapsed().as_secs_f64() / n as f64;
    let bytes = std::fs::metadata(&out).map(|m| m.len()).unwrap_or(0);
    let _ = std::fs::remove_file(&out);
    println!(
        "{}x{}, {} triangles: render {render_ms:.2} ms/frame, encode (ffmpeg libx264 veryfast) {encode_ms:.2} ms/frame, \
         {n} frames ({:.1} s) -> {:.0} KiB",
        opts.width,
        opts.height,
        r.triangle_count(),
        n as f64 / fps,
        bytes as f64 / 1024.0
    );
}
