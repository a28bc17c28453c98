//! MuJoCo against the model crate's own rigid-body reference (independent implementations).
#![cfg(feature = "mujoco")]
use diff_physics::oracle::{run_checks, CheckOptions};
use diff_physics::EngineKind;

#[test]
fn mujoco_passes_all_oracles() {
    let model = robot_model::RobotModel::h1_2().expect("built-in model loads");
    let report = run_checks(&model, &[EngineKind::Mujoco], &CheckOptions { samples: 3, ..CheckOptions::default() });
    println!("{}", report.table());
    assert!(!report.checks.is_empty());
    assert!(report.passed(), "{}", report.table());
}

use diff_physics::mujoco::{MujocoEngine, MujocoSettings};
use diff_physics::{pd_torques, CommonSettings, Engine, PdTarget, State};

fn run(e: &mut MujocoEngine, model: &robot_model::RobotModel, steps: usize) -> State {
    let pd = PdTarget::hold_standing(model);
    for _ in 0..steps {
        let s = e.state();
        e.step(&pd_torques(model, &pd, &s.q, &s.dq)).expect("step");
    }
    e.state()
}

#[test]
fn reset_is_a_true_reset() {
    // Same state + same inputs after a reset must reproduce a run bit for bit, whatever ran before
    // (warm starts, contacts and time are cleared).
    let model = robot_model::RobotModel::h1_2().expect("model");
    let mut e = MujocoEngine::new(&model, &CommonSettings::default(), &MujocoSettings::default()).expect("engine");
    let s0 = State::standing(&model);
    e.reset(&s0).expect("reset");
    let a = run(&mut e, &model, 200);
    let ta = e.time();
    // Disturb: a different history (kicked state, other torques).
    let mut kicked = s0.clone();
    kicked.base_lin_vel = [0.5, -0.3, 0.0];
    e.reset(&kicked).expect("reset");
    run(&mut e, &model, 137);
    e.reset(&s0).expect("reset");
    assert_eq!(e.time(), 0.0);
    let b = run(&mut e, &model, 200);
    assert_eq!(a, b, "a reset did not reproduce the run");
    assert_eq!(ta, e.time());
    // And the run actually moved (the comparison is not vacuous).
    assert!(a != s0);
}

#[test]
fn state_round_trips_through_reset_and_contacts_are_on_the_soles() {
    let model = robot_model::RobotModel::h1_2().expect("model");
    let mut e = MujocoEngine::new(&model, &CommonSettings::default(), &MujocoSettings::default()).expect("engine");
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(9);
    let s = diff_physics::oracle::random_state(&model, &mut rng);
    e.reset(&s).expect("reset");
    let r = e.state();
    assert_eq!(r.q, s.q);
    assert_eq!(r.dq, s.dq);
    assert_eq!(r.base_lin_vel, s.base_lin_vel);
    assert_eq!(r.base_ang_vel, s.base_ang_vel);
    for k in 0..4 {
        assert!((r.base_quat[k] - s.base_quat[k]).abs() < 1e-15);
    }
    // Standing: a few steps later, contacts exist only between the ground and the feet, normals point up.
    e.reset(&State::standing(&model)).expect("reset");
    run(&mut e, &model, 20);
    let cs = e.contacts();
    assert!(cs.len() >= 2, "expected foot contacts, got {cs:?}");
    for c in &cs {
        assert_eq!(c.body_a, "ground");
        assert!(c.body_b.ends_with("ankle_roll_link"), "{c:?}");
        assert!((c.normal[2] - 1.0).abs() < 1e-9, "{c:?}");
        assert!(c.normal_force >= 0.0 && c.point[2].abs() < 5e-3, "{c:?}");
    }
    // Wrong sizes are rejected, not panicking.
    assert!(e.step(&[0.0; 3]).is_err());
    let mut bad = State::standing(&model);
    bad.q.pop();
    assert!(e.reset(&bad).is_err());
    bad = State::standing(&model);
    bad.q[0] = f64::NAN;
    assert!(e.reset(&bad).is_err());
}

#[test]
fn oracles_detect_typical_translation_bugs() {
    // The oracles' tolerances must reject the classic engine-translation mistakes. We build MuJoCo from a
    // deliberately mistranslated model and compare with the reference of the correct one.
    use diff_physics::oracle::{mass_matrix_from_accelerations, random_coords};
    use nalgebra::{DMatrix, Unit};
    let model = robot_model::RobotModel::h1_2().expect("model");
    let common = CommonSettings::rigid_body_only();
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(11);
    let c = random_coords(&model, &mut rng);
    let m_ref = model.mass_matrix(&c, false).expect("M");

    // 1. Inertia orientation dropped (principal moments used as if aligned with the link frame) on one thigh.
    let mut bad = model.clone();
    let li = bad.link_index("left_hip_roll_link").expect("link");
    let eig = bad.links[li].inertial.inertia.symmetric_eigenvalues();
    bad.links[li].inertial.inertia = nalgebra::Matrix3::from_diagonal(&eig);
    let mut e = MujocoEngine::new(&bad, &common, &MujocoSettings::default()).expect("engine");
    e.reset(&State::at_rest(c.clone())).expect("reset");
    let m = mass_matrix_from_accelerations(&mut e, model.nv()).expect("M");
    let err = (&m - &m_ref).norm() / m_ref.norm();
    assert!(err > 1e-6, "dropped inertia orientation went unnoticed: {err}");

    // 2. One joint axis sign flipped: link FK differs.
    let mut bad = model.clone();
    bad.joints[3].axis = Unit::new_unchecked(-bad.joints[3].axis.into_inner());
    let mut e = MujocoEngine::new(&bad, &common, &MujocoSettings::default()).expect("engine");
    e.reset(&State::at_rest(c.clone())).expect("reset");
    let fk = model.fk(&c).expect("fk");
    let worst = e
        .link_poses()
        .iter()
        .zip(&fk.link_poses)
        .map(|(p, r)| (nalgebra::Vector3::from(p.pos) - r.translation.vector).norm())
        .fold(0.0, f64::max);
    assert!(worst > 1e-3, "flipped axis went unnoticed: {worst}");

    // 3. Quaternion convention [x, y, z, w] fed where [w, x, y, z] is expected.
    let mut e = MujocoEngine::new(&model, &common, &MujocoSettings::default()).expect("engine");
    let mut s = State::at_rest(c.clone());
    let [w, x, y, z] = s.base_quat;
    s.base_quat = [x, y, z, w];
    e.reset(&s).expect("reset");
    let base = e.link_poses()[0];
    let q = fk.link_poses[0].rotation;
    let angle = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        base.quat[0],
        base.quat[1],
        base.quat[2],
        base.quat[3],
    ))
    .angle_to(&q);
    assert!(angle > 1e-3, "quaternion convention swap went unnoticed");

    // 4. Armature forgotten: the with-armature mass matrix differs by 0.1 on the joint diagonal.
    let mut e = MujocoEngine::new(&model, &common, &MujocoSettings::default()).expect("engine");
    e.reset(&State::at_rest(c.clone())).expect("reset");
    let m = DMatrix::from_row_slice(model.nv(), model.nv(), &e.mass_matrix().expect("M"));
    let m_arm = model.mass_matrix(&c, true).expect("M");
    assert!((&m - &m_arm).norm() / m_arm.norm() > 1e-3);
}
