//! Observation building against values derived by hand: projected gravity of known rotations, gait phase,
//! history layouts, joint order, and the torso-IMU → pelvis transform.

use policy_runtime::observation::{build_frame, gait_phase_sin_cos, projected_gravity, ObservationHistory};
use policy_runtime::{pelvis_imu_from_torso, HistoryLayout, PolicySpec, RobotObservation, WAIST_SLOT};
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}

/// Unit quaternion `[w, x, y, z]` for a rotation of `angle` about unit `axis`.
fn axis_angle(axis: [f64; 3], angle: f64) -> [f64; 4] {
    let (s, c) = (angle / 2.0).sin_cos();
    [c, axis[0] * s, axis[1] * s, axis[2] * s]
}

#[test]
fn projected_gravity_of_known_rotations() {
    let g = |q| projected_gravity(q).expect("valid quaternion").to_vec();
    // Upright: gravity points down the body z axis.
    assert!(close(&g([1.0, 0.0, 0.0, 0.0]), &[0.0, 0.0, -1.0], 1e-15));
    // Yaw does not change it.
    assert!(close(&g(axis_angle([0.0, 0.0, 1.0], 2.0)), &[0.0, 0.0, -1.0], 1e-15));
    // Roll θ about x: Rx(θ)ᵀ (0,0,-1) = (0, -sin θ, -cos θ).
    let t: f64 = 0.3;
    assert!(close(&g(axis_angle([1.0, 0.0, 0.0], t)), &[0.0, -t.sin(), -t.cos()], 1e-15));
    // Pitch θ about y: Ry(θ)ᵀ (0,0,-1) = (sin θ, 0, -cos θ) (nose down → gravity has +x in the body).
    assert!(close(&g(axis_angle([0.0, 1.0, 0.0], t)), &[t.sin(), 0.0, -t.cos()], 1e-15));
    // Upside down about x.
    assert!(close(&g(axis_angle([1.0, 0.0, 0.0], PI)), &[0.0, 0.0, 1.0], 1e-15));
    // Not normalized: same direction.
    let q = axis_angle([0.0, 1.0, 0.0], t).map(|v| 3.0 * v);
    assert!(close(&g(q), &[t.sin(), 0.0, -t.cos()], 1e-15));
    // Not a rotation.
    assert!(projected_gravity([0.0; 4]).is_err());
    assert!(projected_gravity([f64::NAN, 0.0, 0.0, 1.0]).is_err());
}

#[test]
fn gait_phase_sin_cos_values() {
    let p = 0.8;
    for (t, sin, cos) in [
        (0.0, 0.0, 1.0),
        (0.2, 1.0, 0.0),  // a quarter period
        (0.4, 0.0, -1.0), // half
        (0.6, -1.0, 0.0), // three quarters
        (1.0, 1.0, 0.0),  // wraps: 1.0 mod 0.8 = 0.2
    ] {
        let [s, c] = gait_phase_sin_cos(t, p);
        assert!((s - sin).abs() < 1e-12 && (c - cos).abs() < 1e-12, "t = {t}: got ({s}, {c})");
    }
}

fn frame(a: [f64; 3], b: [f64; 2]) -> Vec<Vec<f64>> {
    vec![a.to_vec(), b.to_vec()]
}

#[test]
fn history_term_major_fills_with_first_frame() {
    let mut h = ObservationHistory::new(3, HistoryLayout::TermMajor);
    h.push(frame([1.0, 2.0, 3.0], [10.0, 20.0]));
    assert_eq!(h.flatten(), vec![1., 2., 3., 1., 2., 3., 1., 2., 3., 10., 20., 10., 20., 10., 20.]);
    h.push(frame([4.0, 5.0, 6.0], [30.0, 40.0]));
    assert_eq!(h.flatten(), vec![1., 2., 3., 1., 2., 3., 4., 5., 6., 10., 20., 10., 20., 30., 40.]);
    h.push(frame([7.0, 8.0, 9.0], [50.0, 60.0]));
    h.push(frame([0.5, 0.5, 0.5], [70.0, 80.0]));
    // Oldest first; the first frame has left.
    assert_eq!(h.flatten(), vec![4., 5., 6., 7., 8., 9., 0.5, 0.5, 0.5, 30., 40., 50., 60., 70., 80.]);
    h.clear();
    h.push(frame([1.0, 1.0, 1.0], [2.0, 2.0]));
    assert_eq!(h.flatten(), vec![1., 1., 1., 1., 1., 1., 1., 1., 1., 2., 2., 2., 2., 2., 2.]);
}

#[test]
fn history_step_major() {
    let mut h = ObservationHistory::new(2, HistoryLayout::StepMajor);
    h.push(frame([1.0, 2.0, 3.0], [10.0, 20.0]));
    h.push(frame([4.0, 5.0, 6.0], [30.0, 40.0]));
    assert_eq!(h.flatten(), vec![1., 2., 3., 10., 20., 4., 5., 6., 30., 40.]);
}

/// A 4-slot robot whose policy commands slots 3 and 1, in that order.
const SMALL_SPEC: &str = r#"
name = "small"
kind = "onnx_mlp"
model = "nowhere.onnx"
control_period = 0.02

[[observation]]
term = "ang_vel"
scale = [1.0, 2.0, 3.0]

[[observation]]
term = "projected_gravity"

[[observation]]
term = "command"
scale = 0.5

[[observation]]
term = "joint_pos_rel"
scale = 10.0

[[observation]]
term = "joint_vel"
scale = [0.1, 0.01]

[[observation]]
term = "last_action"

[[observation]]
term = "gait_phase_sin_cos"
period = 1.0

[action]
scale = 0.5
joints = ["d", 1]

[joints]
slots = [
  { slot = 0, name = "a", default = 0.0, kp = 1.0, kd = 0.1 },
  { slot = 1, name = "b", default = 0.1, kp = 2.0, kd = 0.2 },
  { slot = 2, name = "c", default = 0.2, kp = 3.0, kd = 0.3 },
  { slot = 3, name = "d", default = 0.3, kp = 4.0, kd = 0.4 },
]
"#;

#[test]
fn frame_follows_spec_order_scales_and_joint_order() {
    let spec = PolicySpec::from_toml_str(SMALL_SPEC, Path::new("/base")).expect("valid spec");
    assert_eq!(spec.policy_joints, vec![3, 1]);
    assert_eq!(spec.frame_dim(), 3 + 3 + 3 + 2 + 2 + 2 + 2);
    assert_eq!(spec.model_path, Path::new("/base/nowhere.onnx"));
    let obs = RobotObservation {
        time: 0.25,
        base_quat: axis_angle([1.0, 0.0, 0.0], FRAC_PI_2),
        base_ang_vel: [1.0, 1.0, 1.0],
        q: vec![9.0, 0.5, 9.0, 1.0],
        dq: vec![9.0, 3.0, 9.0, 4.0],
        command: [0.5, -1.0, 2.0],
    };
    let f = build_frame(&spec, &obs, &[0.7, -0.2]).expect("frame");
    let expect: Vec<Vec<f64>> = vec![
        vec![1.0, 2.0, 3.0],
        vec![0.0, -1.0, 0.0], // rolled 90° about x: gravity along −y of the body
        vec![0.25, -0.5, 1.0],
        vec![(1.0 - 0.3) * 10.0, (0.5 - 0.1) * 10.0], // slot 3 then slot 1
        vec![4.0 * 0.1, 3.0 * 0.01],
        vec![0.7, -0.2],
        vec![1.0, 0.0], // a quarter period
    ];
    for (k, (a, b)) in f.iter().zip(&expect).enumerate() {
        assert!(close(a, b, 1e-12), "term {k}: {a:?} vs {b:?}");
    }
    // Wrong joint count or non-finite input: errors, not panics.
    let mut bad = obs.clone();
    bad.q.pop();
    assert!(build_frame(&spec, &bad, &[0.0, 0.0]).is_err());
    let mut bad = obs.clone();
    bad.dq[1] = f64::NAN;
    assert!(build_frame(&spec, &bad, &[0.0, 0.0]).is_err());
    assert!(build_frame(&spec, &obs, &[0.0]).is_err());
}

#[test]
fn observation_clipping() {
    let text = SMALL_SPEC.replace("control_period = 0.02", "control_period = 0.02\nclip_observations = 0.5");
    let spec = PolicySpec::from_toml_str(&text, Path::new("/")).expect("valid spec");
    let obs = RobotObservation {
        time: 0.0,
        base_quat: [1.0, 0.0, 0.0, 0.0],
        base_ang_vel: [1.0, -1.0, 0.1],
        q: vec![0.0; 4],
        dq: vec![0.0; 4],
        command: [0.0; 3],
    };
    let f = build_frame(&spec, &obs, &[0.0, 0.0]).expect("frame");
    assert!(close(&f[0], &[0.5, -0.5, 0.3], 1e-12), "{:?}", f[0]);
    assert!(close(&f[1], &[0.0, 0.0, -0.5], 1e-12), "{:?}", f[1]);
}

#[test]
fn torso_imu_to_pelvis_hand_cases() {
    // Pelvis upright and still, waist turned by a: the torso quaternion is Rz(a); the pelvis is the identity.
    let a = 0.7;
    let p = pelvis_imu_from_torso(axis_angle([0.0, 0.0, 1.0], a), [0.0, 0.0, 0.3], a, 0.3);
    assert!(close(&p.quat, &[1.0, 0.0, 0.0, 0.0], 1e-15), "{:?}", p.quat);
    // The torso spins at 0.3 rad/s only because the waist does: the pelvis does not rotate.
    assert!(close(&p.ang_vel, &[0.0, 0.0, 0.0], 1e-15), "{:?}", p.ang_vel);

    // Pelvis rolling about its x axis at r with the waist at +90°: the torso's x axis is the pelvis's y axis,
    // so the torso gyro reads (0, −r, 0); the pelvis gets (r, 0, 0).
    let r = 1.3;
    let p = pelvis_imu_from_torso(axis_angle([0.0, 0.0, 1.0], FRAC_PI_2), [0.0, -r, 0.0], FRAC_PI_2, 0.0);
    assert!(close(&p.ang_vel, &[r, 0.0, 0.0], 1e-12), "{:?}", p.ang_vel);

    // Pelvis pitched by b about y, waist at a: torso = Ry(b) Rz(a), pelvis = Ry(b).
    let b = -0.2;
    let ry = axis_angle([0.0, 1.0, 0.0], b);
    let rz = axis_angle([0.0, 0.0, 1.0], a);
    // Ry(b) ⊗ Rz(a) by hand.
    let torso = [ry[0] * rz[0], ry[2] * rz[3], ry[2] * rz[0], ry[0] * rz[3]];
    let p = pelvis_imu_from_torso(torso, [0.0; 3], a, 0.0);
    assert!(close(&p.quat, &ry, 1e-15), "{:?} vs {ry:?}", p.quat);
}

#[test]
fn observation_from_torso_imu_uses_the_waist_slot() {
    let a = -0.4;
    let mut q = vec![0.0; 27];
    q[WAIST_SLOT] = a;
    let mut dq = vec![0.0; 27];
    dq[WAIST_SLOT] = 0.5;
    let obs =
        RobotObservation::from_torso_imu(1.0, axis_angle([0.0, 0.0, 1.0], a), [0.0, 0.0, 0.5], q, dq, [0.5, 0.0, 0.0])
            .expect("observation");
    assert!(close(&obs.base_quat, &[1.0, 0.0, 0.0, 0.0], 1e-15));
    assert!(close(&obs.base_ang_vel, &[0.0; 3], 1e-15));
    assert!(RobotObservation::from_torso_imu(
        0.0,
        [1.0, 0.0, 0.0, 0.0],
        [0.0; 3],
        vec![0.0; 5],
        vec![0.0; 5],
        [0.0; 3]
    )
    .is_err());
}
