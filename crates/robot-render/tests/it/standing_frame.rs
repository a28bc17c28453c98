//! A frame of the standing robot, checked against a pinhole projection written here from the camera's
//! parameters: the silhouette is in the middle, and its height in pixels is that of a 1.7 to 1.8 m robot at the
//! camera's distance.
use robot_model::GenCoords;
use robot_render::{Caption, RenderOptions, Renderer};

/// Robot pixels: every robot colour is warm (red well above blue); ground is grey, sky blue, text white.
fn warm(p: [u8; 3]) -> bool {
    i32::from(p[0]) - i32::from(p[2]) > 20
}

/// Image row of world point `p` for a camera at `eye` looking at `target`, vertical field of view `fov` (rad).
fn row_of(p: [f64; 3], eye: [f64; 3], target: [f64; 3], fov: f64, height: f64) -> f64 {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross =
        |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let unit = |a: [f64; 3]| {
        let n = dot(a, a).sqrt();
        [a[0] / n, a[1] / n, a[2] / n]
    };
    let fwd = unit(sub(target, eye));
    let right = unit(cross(fwd, [0.0, 0.0, 1.0]));
    let up = cross(right, fwd);
    let d = sub(p, eye);
    let focal = height / 2.0 / (fov / 2.0).tan();
    height / 2.0 - focal * dot(d, up) / dot(d, fwd)
}

#[test]
fn standing_robot_is_centred_and_as_tall_as_a_robot_of_1_7_to_1_8_m() {
    let model = robot_model::builtin("h1_2").expect("model");
    let opts = RenderOptions::default();
    let mut r = Renderer::new(&model, &opts).expect("renderer");
    let mut pose = GenCoords::standing(&model);
    pose.base_pos[0] = 0.0;
    pose.base_pos[1] = 0.0;
    let caption = Caption { time_s: 0.0, label: "test", progress: Some(0.0), detail: "" };
    let frame = r.render(&pose, 0.0, &caption).expect("frame").clone();
    let (w, h) = (frame.width(), frame.height());

    let mut rows = (u32::MAX, 0);
    let mut cols = (u32::MAX, 0);
    let mut count = 0;
    for y in 0..h {
        for x in 0..w {
            if warm(frame.pixel(x, y).expect("inside")) {
                rows = (rows.0.min(y), rows.1.max(y));
                cols = (cols.0.min(x), cols.1.max(x));
                count += 1;
            }
        }
    }
    assert!(count > 2000, "only {count} robot pixels");
    let centre_x = f64::from(cols.0 + cols.1) / 2.0;
    assert!((centre_x - f64::from(w) / 2.0).abs() < 0.1 * f64::from(w), "silhouette columns {cols:?}");

    // The first frame's camera looks at the pelvis's x, y at the configured height.
    let target = [0.0, 0.0, opts.camera_height];
    let o = opts.camera_offset;
    let eye = [o[0], o[1], opts.camera_height + o[2]];
    let fov = opts.fov_y_deg.to_radians();
    let hf = f64::from(h);
    let ground = row_of([0.0, 0.0, 0.0], eye, target, fov, hf);
    let pixels = |height_m: f64| ground - row_of([0.0, 0.0, height_m], eye, target, fov, hf);
    let seen = f64::from(rows.1 - rows.0 + 1);
    let (lo, hi) = (pixels(1.7), pixels(1.8));
    assert!(
        seen > 0.95 * lo && seen < 1.05 * hi,
        "silhouette {seen} px tall; a 1.7 to 1.8 m robot: {lo:.0} to {hi:.0}"
    );
    // And it stands on the ground: its lowest row is where the ground under the pelvis is drawn (the feet reach a
    // little in front of and behind the pelvis).
    assert!((f64::from(rows.1) - ground).abs() < 0.05 * hf, "feet at row {}, ground at {ground:.0}", rows.1);
}
