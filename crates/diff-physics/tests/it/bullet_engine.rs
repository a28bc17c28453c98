//! Bullet's btMultiBody against the model crate's own rigid-body reference and against MuJoCo (independent
//! implementations), and the Bullet semantics the engine normalises, each measured on the real library.
//! Run: `cargo test -p diff-physics --features bullet --test it -- bullet_engine::`.
#![cfg(feature = "bullet")]
#![allow(clippy::unwrap_used)]
use diff_physics::bullet::{BulletEngine, BulletSettings};
use diff_physics::oracle::{random_state, run_checks, CheckOptions};
use diff_physics::{pd_torques, CommonSettings, Engine, EngineKind, PdTarget, State};
use nalgebra::DVector;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use robot_model::RobotModel;

fn model() -> RobotModel {
    RobotModel::h1_2().expect("built-in model loads")
}

fn bullet(m: &RobotModel, common: &CommonSettings, s: &BulletSettings) -> BulletEngine {
    BulletEngine::new(m, common, s).expect("Bullet engine builds")
}

/// The oracles of `ulab model check`: model equivalence, contact-free dynamics, standing and invariants against
/// robot-model's RNEA/CRBA. Armature is approximated (known differences, reasons in `bullet::known_difference`).
#[test]
fn bullet_passes_the_oracles() {
    let m = model();
    let report = run_checks(&m, &[EngineKind::Bullet], &CheckOptions { samples: 3, ..CheckOptions::default() });
    println!("{}", report.table());
    assert!(report.checks.len() >= 20, "{}", report.table());
    assert!(report.passed(), "{}", report.table());
    // The known differences are the armature ones only; everything else passes outright.
    for c in report.checks.iter().filter(|c| !c.passed) {
        assert!(
            c.name.contains("armature") || c.name == "kinetic energy at reset",
            "unexpected known difference {c:?}"
        );
    }
}

/// One step with contacts from the standing state: Bullet against MuJoCo (the oracle's cross-engine check).
#[cfg(feature = "mujoco")]
#[test]
fn one_step_agrees_with_mujoco() {
    let m = model();
    let mut checks = Vec::new();
    diff_physics::oracle::one_step_cross(
        &m,
        &[EngineKind::Mujoco, EngineKind::Bullet],
        &CheckOptions::default(),
        &mut checks,
    );
    for c in &checks {
        println!("{:<36} {:>12.3e} {:>12.3e} {}", c.name, c.error, c.tolerance, c.unit);
    }
    assert_eq!(checks.len(), 6);
    assert!(checks.iter().all(|c| c.passed), "{checks:#?}");
}

fn run_pd(e: &mut dyn Engine, m: &RobotModel, steps: usize) -> State {
    let pd = PdTarget::hold_standing(m);
    for _ in 0..steps {
        let s = e.state();
        e.step(&pd_torques(m, &pd, &s.q, &s.dq)).unwrap();
    }
    e.state()
}

/// Same state + same inputs after a reset reproduce a run bit for bit, whatever ran before (the whole Bullet
/// world, manifolds and warm starts included, is rebuilt).
#[test]
fn reset_is_a_true_reset() {
    let m = model();
    let mut e = bullet(&m, &CommonSettings::default(), &BulletSettings::default());
    let s0 = State::standing(&m);
    e.reset(&s0).unwrap();
    let a = run_pd(&mut e, &m, 200);
    let ca = e.contacts();
    let mut kicked = s0.clone();
    kicked.base_lin_vel = [0.5, -0.3, 0.0];
    e.reset(&kicked).unwrap();
    run_pd(&mut e, &m, 137);
    e.reset(&s0).unwrap();
    assert_eq!(e.time(), 0.0);
    let b = run_pd(&mut e, &m, 200);
    assert_eq!(a, b, "a reset did not reproduce the run");
    assert_eq!(ca, e.contacts());
    assert!(a != s0, "the run did not move: the comparison would be vacuous");
}

/// State round trip through reset, contacts on the soles with upward normals, and bad input rejected.
#[test]
fn state_round_trip_contacts_and_bad_input() {
    let m = model();
    let mut e = bullet(&m, &CommonSettings::default(), &BulletSettings::default());
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for _ in 0..5 {
        let s = random_state(&m, &mut rng);
        e.reset(&s).unwrap();
        let r = e.state();
        // Pelvis origin <-> COM frame conversions and back: a few ulp of ~1 m.
        let all = r.qpos().into_iter().chain(r.v()).zip(s.qpos().into_iter().chain(s.v()));
        let worst = all.map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-12, "state round trip error {worst:e}");
        assert_eq!(r.q, s.q);
        assert_eq!(r.dq, s.dq);
    }
    e.reset(&State::standing(&m)).unwrap();
    assert!(e.contacts().is_empty(), "no step yet: no contacts");
    run_pd(&mut e, &m, 50);
    let cs = e.contacts();
    assert!(cs.len() >= 6, "expected most sole corners in contact, got {cs:?}");
    for c in &cs {
        assert_eq!(c.body_a, "ground");
        assert!(c.body_b.ends_with("ankle_roll_link"), "{c:?}");
        assert!((c.normal[2] - 1.0).abs() < 1e-12, "{c:?}");
        assert!(c.normal_force >= 0.0 && c.point[2].abs() < 2e-3 && c.depth < 2e-3, "{c:?}");
    }
    assert!(e.step(&[0.0; 3]).is_err());
    assert!(e.step(&vec![f64::NAN; m.nj()]).is_err());
    let mut bad = State::standing(&m);
    bad.q.pop();
    assert!(e.reset(&bad).is_err());
    let mut bad = State::standing(&m);
    bad.base_quat = [0.0; 4];
    assert!(e.reset(&bad).is_err());
    assert!(e.generalized_acceleration(&[0.0; 5]).is_err());
}

/// Bullet's `m_maxCoordinateVelocity` (default 100) clamps generalized velocities inside a step. Measured on the
/// library: a 150 rad/s wrist comes out of one contact-free step at 100 with Bullet's default, and near 150 with
/// the engine's setting (no clamp).
#[test]
fn max_coordinate_velocity_is_normalised() {
    let m = model();
    let common = CommonSettings { gravity: [0.0; 3], ..CommonSettings::rigid_body_only() };
    let j = m.joint_index("left_wrist_yaw_joint").or_else(|| m.joints.len().checked_sub(1)).unwrap();
    let mut s = State::standing(&m);
    s.dq[j] = 150.0;
    let tau = vec![0.0; m.nj()];
    let mut clamped =
        bullet(&m, &common, &BulletSettings { max_coordinate_velocity: 100.0, ..BulletSettings::default() });
    clamped.reset(&s).unwrap();
    clamped.step(&tau).unwrap();
    let mut free = bullet(&m, &common, &BulletSettings::default());
    free.reset(&s).unwrap();
    free.step(&tau).unwrap();
    let (c, f) = (clamped.state().dq[j], free.state().dq[j]);
    println!("150 rad/s wrist after one step: Bullet default clamp {c:.3}, engine setting {f:.3}");
    assert!(c <= 100.0 + 1e-9, "Bullet's default clamp not observed: {c}");
    // One step changes the free joint's speed by dt·q̈ only (gyroscopic coupling of a light wrist): well
    // under 1 rad/s.
    assert!((f - 150.0).abs() < 1.0, "unclamped wrist changed to {f}");
}

/// Viscous damping is not applied by Bullet (m_jointDamping is stored, unused): the engine adds -d·q̇. The
/// contact-free accelerations with damping on equal robot-model's forward dynamics under τ - d·q̇.
#[test]
fn joint_damping_is_applied_as_torque() {
    let m = model();
    let common = CommonSettings { joint_damping: true, ..CommonSettings::rigid_body_only() };
    let mut e = bullet(&m, &common, &BulletSettings::default());
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let s = random_state(&m, &mut rng);
    e.reset(&s).unwrap();
    let f = vec![0.0; m.nv()];
    let a = DVector::from_vec(e.generalized_acceleration(&f).unwrap());
    let mut fd = f.clone();
    for (k, j) in m.joints.iter().enumerate() {
        fd[6 + k] -= j.damping * s.dq[k];
    }
    let want = m.forward_dynamics(&s.coords(), &s.v(), &fd, common.gravity, false).unwrap();
    let without = m.forward_dynamics(&s.coords(), &s.v(), &f, common.gravity, false).unwrap();
    let err = (&a - &want).norm() / want.norm();
    let gap = (&want - &without).norm() / want.norm();
    println!(
        "damping: error vs reference with -d·q̇ {err:.3e}; the damping term itself moves accelerations by {gap:.3e}"
    );
    // Analytic ABA vs RNEA/CRBA: rounding level (see the oracle's 1e-8), and the check must be able to fail.
    assert!(err < 1e-8 && gap > 1e-3, "err {err:e}, gap {gap:e}");
}

/// Dry joint friction (frictionloss) as a zero-velocity motor bounded by frictionloss·dt: a torque below the
/// friction holds a joint at rest (stiction), a torque above it moves the joint. Coulomb's law is the
/// counterpart; zero gravity, no contacts, so nothing else acts.
#[test]
fn joint_friction_holds_below_and_slips_above() {
    let m = model();
    let common =
        CommonSettings { gravity: [0.0; 3], joint_friction: true, armature: true, ..CommonSettings::rigid_body_only() };
    let j = m.joint_index("left_elbow_joint").unwrap_or(m.nj() - 3);
    let fl = m.joints[j].frictionloss;
    assert!(fl > 0.0);
    let mut speeds = Vec::new();
    for scale in [0.5, 2.0] {
        let mut e = bullet(&m, &common, &BulletSettings::default());
        e.reset(&State::standing(&m)).unwrap();
        let mut tau = vec![0.0; m.nj()];
        tau[j] = scale * fl;
        for _ in 0..100 {
            e.step(&tau).unwrap();
        }
        speeds.push(e.state().dq[j].abs());
    }
    println!(
        "elbow speed after 0.2 s: torque 0.5×friction {:.3e} rad/s, 2×friction {:.3e} rad/s",
        speeds[0], speeds[1]
    );
    // Held: the motor cancels the torque up to the convergence of 50 Gauss-Seidel sweeps (measured 1.2e-7
    // rad/s; 0 with 500 sweeps): below 1e-6 rad/s.
    assert!(speeds[0] < 1e-6, "stiction failed: {}", speeds[0]);
    // Slipping: net torque (2 - 1)·friction = 0.2 N·m on at least the armature 0.1 kg·m² for 0.2 s gives at most
    // 0.4 rad/s; the forearm's own inertia lowers that. More than 1e-2 rad/s shows it slips.
    assert!(speeds[1] > 1e-2, "no slip above friction: {}", speeds[1]);
}

/// With Bullet's default single friction direction per contact point (along the momentary sliding velocity),
/// a PD-held standing robot's feet creep over the floor; with two directions (the engine's setting) they stay.
/// Measured on the library; the fixed feet are the physically right answer (μ = 1, no horizontal load).
#[test]
fn feet_do_not_creep_with_two_friction_directions() {
    let m = model();
    let foot = m.link_index("left_ankle_roll_link").unwrap();
    let mut drift = Vec::new();
    for two in [false, true] {
        let mut e = bullet(
            &m,
            &CommonSettings::default(),
            &BulletSettings { two_friction_directions: two, ..BulletSettings::default() },
        );
        e.reset(&State::standing(&m)).unwrap();
        let p0 = e.link_poses()[foot].pos;
        run_pd(&mut e, &m, 400);
        let p1 = e.link_poses()[foot].pos;
        drift.push(((p1[0] - p0[0]).powi(2) + (p1[1] - p0[1]).powi(2)).sqrt());
    }
    println!("left foot horizontal drift over 0.8 s: one friction direction {:.4} m, two {:.2e} m", drift[0], drift[1]);
    assert!(drift[0] > 0.02, "expected Bullet's single-direction creep, got {}", drift[0]);
    assert!(drift[1] < 1e-3, "feet slid with two friction directions: {}", drift[1]);
}

/// Joint limits hold (btMultiBodyJointLimitConstraint, solved because every link has a collider, also with
/// collisions off): a joint pushed hard towards its upper limit stops there, in zero gravity without contacts.
#[test]
fn joint_limits_stop_a_pushed_joint() {
    let m = model();
    let common =
        CommonSettings { gravity: [0.0; 3], joint_limits: true, armature: true, ..CommonSettings::rigid_body_only() };
    let j = m.joint_index("left_elbow_joint").unwrap_or(m.nj() - 3);
    let upper = m.joints[j].upper;
    let mut e = bullet(&m, &common, &BulletSettings::default());
    let mut s = State::standing(&m);
    s.q[j] = upper - 0.05;
    e.reset(&s).unwrap();
    let mut tau = vec![0.0; m.nj()];
    tau[j] = 10.0;
    let mut worst: f64 = 0.0;
    for _ in 0..250 {
        e.step(&tau).unwrap();
        worst = worst.max(e.state().q[j] - upper);
    }
    let fin = e.state().q[j];
    println!("elbow pushed with 10 N·m: worst overrun {worst:.2e} rad, final {:.2e} rad from the limit", fin - upper);
    // Reached the limit (10 N·m on ~0.1 kg·m² covers 0.05 rad in ~0.03 s) and stays within the Baumgarte
    // correction's overrun: one step of approach speed (≲ 1 rad/s × 2 ms) = 2e-3 rad; 5e-3 bound.
    assert!((fin - upper).abs() < 5e-3 && worst < 5e-3, "final {fin}, upper {upper}, worst overrun {worst}");
    let lim = e.joint_limits();
    assert_eq!(lim[j], (m.joints[j].lower, upper));
}
