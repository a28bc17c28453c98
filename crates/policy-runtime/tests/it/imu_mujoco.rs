//! The torso-IMU → pelvis transform against MuJoCo's kinematics of the project's H1-2: the torso link's world
//! orientation at a random state, and its angular velocity by finite differences of that orientation over a
//! tiny time step of the state's own velocities, must map back to the pelvis orientation and angular velocity
//! the state was built with.

use diff_physics::{make_engine, CommonSettings, EngineKind, State};
use policy_runtime::{pelvis_imu_from_torso, WAIST_SLOT};

fn qmul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

fn qconj(a: [f64; 4]) -> [f64; 4] {
    [a[0], -a[1], -a[2], -a[3]]
}

/// Rotation by the vector `v` (axis × angle) as a quaternion.
fn qexp(v: [f64; 3]) -> [f64; 4] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if n < 1e-300 {
        return [1.0, 0.0, 0.0, 0.0];
    }
    let (s, c) = (n / 2.0).sin_cos();
    [c, v[0] / n * s, v[1] / n * s, v[2] / n * s]
}

fn normalize(q: [f64; 4]) -> [f64; 4] {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    q.map(|v| v / n)
}

#[test]
fn pelvis_from_torso_matches_mujoco_kinematics() {
    let model = robot_model::RobotModel::h1_2().expect("model");
    let torso = model.link_index("torso_link").expect("torso_link");
    let mut engine = make_engine(EngineKind::Mujoco, &model, &CommonSettings::default()).expect("MuJoCo");
    // A fixed pseudo-random sequence (no RNG dependency needed): varied, non-trivial values.
    let cases = [
        ([0.1, -0.2, 0.7], [0.4, -1.1, 0.8], 0.6, -1.5),
        ([-0.3, 0.25, -2.0], [-0.7, 0.2, -0.3], -1.1, 2.0),
        ([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.3, 0.0),
    ];
    let eps = 1e-6;
    for (rot, w_pelvis, waist, waist_dq) in cases {
        let mut s = State::standing(&model);
        s.base_quat = qexp(rot);
        s.base_ang_vel = w_pelvis;
        for (i, (q, dq)) in s.q.iter_mut().zip(s.dq.iter_mut()).enumerate() {
            *q += 0.05 * ((i as f64) * 1.7).sin();
            *dq = ((i as f64) * 0.9).cos();
        }
        s.q[WAIST_SLOT] = waist;
        s.dq[WAIST_SLOT] = waist_dq;
        engine.reset(&s).expect("reset");
        let t0 = engine.link_poses()[torso].quat;
        // Advance the configuration by eps along the state's velocities (pelvis angular velocity is body-frame).
        let mut s1 = s.clone();
        s1.base_quat = normalize(qmul(s.base_quat, qexp(w_pelvis.map(|v| v * eps))));
        for (q, dq) in s1.q.iter_mut().zip(&s.dq) {
            *q += dq * eps;
        }
        engine.reset(&s1).expect("reset");
        let t1 = engine.link_poses()[torso].quat;
        // Torso angular velocity in the torso frame: conj(t0) ⊗ t1 ≈ (1, ω ε / 2).
        let d = qmul(qconj(t0), t1);
        let sign = d[0].signum();
        let gyro = [2.0 * sign * d[1] / eps, 2.0 * sign * d[2] / eps, 2.0 * sign * d[3] / eps];

        let p = pelvis_imu_from_torso(t0, gyro, waist, waist_dq);
        let dot: f64 = p.quat.iter().zip(&s.base_quat).map(|(a, b)| a * b).sum();
        assert!((dot.abs() - 1.0).abs() < 1e-12, "pelvis orientation: {:?} vs {:?}", p.quat, s.base_quat);
        for k in 0..3 {
            assert!(
                (p.ang_vel[k] - w_pelvis[k]).abs() < 1e-4,
                "pelvis angular velocity {:?} vs {w_pelvis:?} (torso gyro {gyro:?})",
                p.ang_vel
            );
        }
    }
}
