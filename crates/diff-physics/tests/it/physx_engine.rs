//! PhysX against the model crate's own rigid-body reference (an independent f64 implementation), against MuJoCo
//! (an independent engine) and against physical expectations. Run:
//! `cargo test -p diff-physics --features physx --test it -- physx_engine::`.
//!
//! PhysX computes in f32: tolerances here are derived from f32 arithmetic (u = 2⁻²⁴ ≈ 6e-8) next to each check.
#![cfg(all(feature = "physx", feature = "mujoco"))]
#![allow(clippy::unwrap_used)]

use diff_physics::mujoco::{MujocoEngine, MujocoSettings};
use diff_physics::oracle::{run_checks, CheckOptions};
use diff_physics::physx::{PhysxEngine, PhysxSettings};
use diff_physics::{pd_torques, CommonSettings, Engine, EngineError, EngineKind, PdTarget, State};
use nalgebra::{DMatrix, Unit, Vector3};
use rand::SeedableRng;
use robot_model::RobotModel;

fn model() -> RobotModel {
    RobotModel::h1_2().expect("built-in model loads")
}

fn physx(model: &RobotModel, common: &CommonSettings) -> PhysxEngine {
    PhysxEngine::new(model, common, &PhysxSettings::default()).expect("PhysX engine builds")
}

fn run(e: &mut dyn Engine, model: &RobotModel, steps: usize) -> State {
    let pd = PdTarget::hold_standing(model);
    for _ in 0..steps {
        let s = e.state();
        e.step(&pd_torques(model, &pd, &s.q, &s.dq)).expect("step");
    }
    e.state()
}

/// Every oracle of `ulab model check` (model equivalence, contact-free dynamics, standing, invariants, PhysX's
/// own inverse dynamics) against robot-model's RNEA/CRBA, and the one-step comparison with MuJoCo.
#[test]
fn physx_passes_all_oracles() {
    let model = model();
    let report = run_checks(
        &model,
        &[EngineKind::Mujoco, EngineKind::Physx],
        &CheckOptions { samples: 3, ..Default::default() },
    );
    println!("{}", report.table());
    assert!(report.checks.iter().filter(|c| c.engine == "physx").count() >= 29);
    assert!(report.checks.iter().any(|c| c.engine == "mujoco vs physx"), "no cross-engine check ran");
    assert!(report.passed(), "{}", report.table());
}

#[test]
fn reset_is_a_true_reset() {
    // Same state + same inputs after a reset reproduce a run bit for bit, whatever ran before (contact
    // manifolds, friction anchors, time: the scene is rebuilt).
    let model = model();
    let mut e = physx(&model, &CommonSettings::default());
    let s0 = State::standing(&model);
    e.reset(&s0).unwrap();
    let a = run(&mut e, &model, 200);
    let (ta, ca) = (e.time(), e.contacts());
    let mut kicked = s0.clone();
    kicked.base_lin_vel = [0.5, -0.3, 0.0];
    e.reset(&kicked).unwrap();
    run(&mut e, &model, 137);
    e.reset(&s0).unwrap();
    assert_eq!(e.time(), 0.0);
    let b = run(&mut e, &model, 200);
    assert_eq!(a, b, "a reset did not reproduce the run");
    assert_eq!(ta, e.time());
    assert_eq!(ca, e.contacts());
    assert!(a != s0, "the run did not move");
    assert!(!ca.is_empty(), "no contacts while standing");
}

#[test]
fn state_round_trips_and_contacts_are_on_the_soles() {
    let model = model();
    let mut e = physx(&model, &CommonSettings::default());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let s = diff_physics::oracle::random_state(&model, &mut rng);
    e.reset(&s).unwrap();
    let r = e.state();
    // Joint values are rounded to f32 once: |δ| <= u·|x| <= 6e-8 · 3 rad. Base linear velocity goes to the COM
    // and back (v ± ω × Rc, |Rc| ≈ 0.05 m) in f32: <= a few u·(|v| + |ω||Rc|) ≈ 1e-6. Tolerance 1e-6.
    let worst =
        r.qpos().iter().zip(s.qpos()).chain(r.v().iter().zip(s.v())).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(worst < 1e-6, "state round trip off by {worst}");

    e.reset(&State::standing(&model)).unwrap();
    run(&mut e, &model, 20);
    let cs = e.contacts();
    assert!(cs.len() >= 2, "expected foot contacts, got {cs:?}");
    for c in &cs {
        assert_eq!(c.body_a, "ground");
        assert!(c.body_b.ends_with("ankle_roll_link"), "{c:?}");
        // The plane normal is exactly +z in f32.
        assert!((c.normal[2] - 1.0).abs() < 1e-6, "{c:?}");
        // Engaged points only: on the sole, within the contact offset (0.01 m) of the floor.
        assert!(c.normal_force >= 0.0 && c.point[2].abs() < 0.011, "{c:?}");
    }
    let total: f64 = cs.iter().map(|c| c.normal_force).sum();
    assert!(total > 100.0, "feet carry almost nothing: {total} N");

    // Wrong sizes and non-finite values are typed errors, not panics.
    assert!(matches!(e.step(&[0.0; 3]), Err(EngineError::Input(_))));
    let mut bad = State::standing(&model);
    bad.q.pop();
    assert!(e.reset(&bad).is_err());
    bad = State::standing(&model);
    bad.q[0] = f64::NAN;
    assert!(e.reset(&bad).is_err());
    let mut tau = vec![0.0; model.nj()];
    tau[1] = f64::INFINITY;
    assert!(e.step(&tau).is_err());
    assert!(e.generalized_acceleration(&[0.0; 4]).is_err());
}

#[test]
fn bad_settings_are_typed_errors() {
    let model = model();
    let common = CommonSettings::default();
    let bad = [
        PhysxSettings { contact_offset: 0.0, ..PhysxSettings::default() },
        PhysxSettings { rest_offset: 0.02, ..PhysxSettings::default() },
        PhysxSettings { position_iterations: 0, ..PhysxSettings::default() },
        PhysxSettings { acceleration_probe_dt: f64::NAN, ..PhysxSettings::default() },
    ];
    for s in bad {
        assert!(matches!(PhysxEngine::new(&model, &common, &s), Err(EngineError::Input(_))), "{s:?}");
    }
    assert!(PhysxEngine::new(&model, &CommonSettings { timestep: -1.0, ..common.clone() }, &PhysxSettings::default())
        .is_err());
    // Explicit damping would be unstable: d·dt must stay below the joint inertia (>= armature 0.1 kg·m²).
    let coarse = CommonSettings { timestep: 0.5, ..common };
    assert!(matches!(PhysxEngine::new(&model, &coarse, &PhysxSettings::default()), Err(EngineError::Unsupported(_))));
}

/// The oracles' tolerances for PhysX (f32-derived, far looser than the f64 ones) still reject the classic
/// translation mistakes: each mistake below is compared against the reference of the CORRECT model.
#[test]
fn f32_tolerances_still_detect_translation_bugs() {
    use diff_physics::oracle::random_coords;
    let model = model();
    let common = CommonSettings::rigid_body_only();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let c = random_coords(&model, &mut rng);
    let m_ref = model.mass_matrix(&c, false).unwrap();
    let nv = model.nv();
    // The tolerances the oracle applies to PhysX for these checks.
    let tol_m = diff_physics::oracle::precision_tolerance("physx", "mass matrix (engine's own)", 1e-9);
    let tol_fk = diff_physics::oracle::precision_tolerance("physx", "link-frame FK position", 1e-9);
    assert!(tol_m <= 1e-4 && tol_fk <= 1e-4);

    // 1. Inertia orientation dropped on one thigh.
    let mut bad = model.clone();
    let li = bad.link_index("left_hip_roll_link").unwrap();
    let eig = bad.links[li].inertial.inertia.symmetric_eigenvalues();
    bad.links[li].inertial.inertia = nalgebra::Matrix3::from_diagonal(&eig);
    let mut e = physx(&bad, &common);
    e.reset(&State::at_rest(c.clone())).unwrap();
    let m = DMatrix::from_row_slice(nv, nv, &e.mass_matrix().unwrap());
    let err = (&m - &m_ref).norm() / m_ref.norm();
    assert!(err > 10.0 * tol_m, "dropped inertia orientation went unnoticed: {err}");

    // 2. One joint axis sign flipped.
    let mut bad = model.clone();
    bad.joints[3].axis = Unit::new_unchecked(-bad.joints[3].axis.into_inner());
    let mut e = physx(&bad, &common);
    e.reset(&State::at_rest(c.clone())).unwrap();
    let fk = model.fk(&c).unwrap();
    let worst = e
        .link_poses()
        .iter()
        .zip(&fk.link_poses)
        .map(|(p, r)| (Vector3::from(p.pos) - r.translation.vector).norm())
        .fold(0.0, f64::max);
    assert!(worst > 10.0 * tol_fk, "flipped axis went unnoticed: {worst}");

    // 3. Armature forgotten: 0.1 kg·m² on the joint diagonal.
    let mut e = physx(&model, &common);
    e.reset(&State::at_rest(c.clone())).unwrap();
    let m = DMatrix::from_row_slice(nv, nv, &e.mass_matrix().unwrap());
    let m_arm = model.mass_matrix(&c, true).unwrap();
    assert!((&m - &m_arm).norm() / m_arm.norm() > 10.0 * tol_m);

    // 4. Centre of mass 1 cm off on the pelvis: PhysX's mass matrix sees it.
    let mut bad = model.clone();
    bad.links[0].inertial.com.x += 0.01;
    let mut e = physx(&bad, &common);
    e.reset(&State::at_rest(c.clone())).unwrap();
    let m = DMatrix::from_row_slice(nv, nv, &e.mass_matrix().unwrap());
    assert!((&m - &m_ref).norm() / m_ref.norm() > 10.0 * tol_m);
}

/// Dry friction (the model's frictionloss, 0.2 N·m) as PhysX's bounded velocity drive against MuJoCo's
/// frictionloss constraint, in zero gravity without ground: a torque below the bound holds the joint, a torque
/// above it accelerates the joint by the excess, and both engines agree on the resulting joint velocity.
#[test]
fn dry_friction_holds_below_and_slips_above_the_bound_like_mujoco() {
    let model = model();
    let common = CommonSettings {
        gravity: [0.0; 3],
        ground: false,
        collisions: false,
        joint_damping: false,
        joint_limits: false,
        ..CommonSettings::default()
    };
    let j = model.joints.iter().position(|j| j.motor_name == "left_elbow").expect("elbow");
    let f = model.joints[j].frictionloss;
    assert!(f > 0.0);
    let mut s0 = State::standing(&model);
    s0.base_pos[2] += 1.0;
    let mut results = Vec::new();
    for torque in [0.5 * f, 3.0 * f] {
        let mut tau = vec![0.0; model.nj()];
        tau[j] = torque;
        let mut px = physx(&model, &common);
        let mut mj = MujocoEngine::new(&model, &common, &MujocoSettings::default()).unwrap();
        let mut dq = Vec::new();
        for e in [&mut px as &mut dyn Engine, &mut mj] {
            e.reset(&s0).unwrap();
            for _ in 0..50 {
                e.step(&tau).unwrap();
            }
            dq.push(e.state().dq[j]);
        }
        results.push((torque, dq));
    }
    println!("torque, [physx, mujoco] elbow velocity after 0.1 s: {results:?}");
    let (_, below) = &results[0];
    let (_, above) = &results[1];
    // Below the bound the joint sticks: MuJoCo's soft constraint creeps (its impedance), PhysX's drive holds to
    // solver precision. Both well under the 0.1 s·(τ/I ≈ 1 rad/s²)·… of a free joint: 1e-2 rad/s.
    assert!(below[0].abs() < 1e-3, "PhysX slipped below the friction bound: {}", below[0]);
    assert!(below[1].abs() < 1e-2, "MuJoCo slipped below the friction bound: {}", below[1]);
    // Above it both accelerate by the excess torque: agree within 10% (MuJoCo's soft constraint leaks ~5%).
    assert!(above[0] > 0.0 && above[1] > 0.0);
    assert!((above[0] - above[1]).abs() < 0.1 * above[1], "PhysX {} vs MuJoCo {}", above[0], above[1]);
}
