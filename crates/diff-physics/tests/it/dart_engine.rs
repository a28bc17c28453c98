//! DART against the model crate's own rigid-body reference (the oracles of `ulab model check`), against DART's own
//! URDF loader (urdfdom + `dart::utils::DartLoader`: an independent route from the URDF text to a skeleton),
//! and against MuJoCo; plus the engine's own contract (true reset, state round trip, contacts, bad input) and
//! the DART behaviours the engine relies on (limits off unless enabled, Coulomb joint friction, implicit
//! damping, DART's potential energy).
//! Run: `cargo test -p diff-physics --features dart --test it -- dart_engine::`.
#![cfg(feature = "dart")]
#![allow(clippy::unwrap_used)]

use diff_physics::dart::{ffi, DartEngine, DartSettings};
use diff_physics::oracle::{random_state, run_checks, CheckOptions};
use diff_physics::{pd_torques, CommonSettings, Engine, EngineKind, PdTarget, State};
use nalgebra::{DMatrix, DVector, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use robot_model::RobotModel;

fn model() -> RobotModel {
    RobotModel::h1_2().expect("built-in model loads")
}

fn engine(common: &CommonSettings) -> DartEngine {
    DartEngine::new(&model(), common, &DartSettings::default()).expect("DART engine builds")
}

fn run(e: &mut DartEngine, model: &RobotModel, steps: usize) -> State {
    let pd = PdTarget::hold_standing(model);
    for _ in 0..steps {
        let s = e.state();
        e.step(&pd_torques(model, &pd, &s.q, &s.dq)).expect("step");
    }
    e.state()
}

#[test]
fn dart_passes_all_oracles() {
    let model = model();
    let report = run_checks(&model, &[EngineKind::Dart], &CheckOptions { samples: 3, ..CheckOptions::default() });
    println!("{}", report.table());
    assert!(!report.checks.is_empty());
    assert!(report.passed(), "{}", report.table());
}

#[cfg(feature = "mujoco")]
#[test]
fn one_step_with_contact_agrees_with_mujoco() {
    // MuJoCo (soft contacts, MJCF from the same model) against DART (hard LCP contacts): the oracle's
    // cross-engine one-step bounds, derived in oracle.rs.
    let model = model();
    let mut checks = Vec::new();
    diff_physics::oracle::one_step_cross(
        &model,
        &[EngineKind::Mujoco, EngineKind::Dart],
        &CheckOptions::default(),
        &mut checks,
    );
    assert_eq!(checks.len(), 6, "{checks:?}");
    for c in &checks {
        println!("{:<36} {:>10.3e} <= {:>10.3e} {}", c.name, c.error, c.tolerance, c.unit);
        assert!(c.passed, "{c:?}");
    }
}

#[test]
fn reset_is_a_true_reset() {
    // Same state + same inputs after a reset reproduce a run bit for bit, whatever ran before; and a second,
    // separately built engine reproduces it too (no hidden process state such as collision-object order).
    let model = model();
    let mut e = engine(&CommonSettings::default());
    let s0 = State::standing(&model);
    e.reset(&s0).unwrap();
    let a = run(&mut e, &model, 200);
    let ta = e.time();
    let mut kicked = s0.clone();
    kicked.base_lin_vel = [0.5, -0.3, 0.0];
    e.reset(&kicked).unwrap();
    run(&mut e, &model, 137);
    e.reset(&s0).unwrap();
    assert_eq!(e.time(), 0.0);
    assert!(e.contacts().is_empty(), "contacts survived the reset");
    let b = run(&mut e, &model, 200);
    assert_eq!(a, b, "a reset did not reproduce the run");
    assert_eq!(ta, e.time());
    let mut other = engine(&CommonSettings::default());
    other.reset(&s0).unwrap();
    assert_eq!(run(&mut other, &model, 200), a, "a second engine did not reproduce the run");
    assert!(a != s0, "the run did not move");
}

#[test]
fn state_round_trips_and_contacts_are_on_the_soles() {
    let model = model();
    let mut e = engine(&CommonSettings::default());
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for _ in 0..5 {
        let s = random_state(&model, &mut rng);
        e.reset(&s).unwrap();
        let r = e.state();
        // DART stores the base as a rotation vector and the base velocity in the pelvis frame: the round trip
        // is a few roundings (|v| <= 2).
        let (want, got): (Vec<f64>, Vec<f64>) =
            (s.qpos().into_iter().chain(s.v()).collect(), r.qpos().into_iter().chain(r.v()).collect());
        let worst = want.iter().zip(&got).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-14, "state round trip error {worst}");
    }
    e.reset(&State::standing(&model)).unwrap();
    run(&mut e, &model, 20);
    let cs = e.contacts();
    assert!(cs.len() >= 8, "expected the corners of both soles, got {cs:?}");
    let mut total = 0.0;
    for c in &cs {
        assert_eq!(c.body_a, "ground");
        assert!(c.body_b.ends_with("ankle_roll_link"), "{c:?}");
        assert!((c.normal[2] - 1.0).abs() < 1e-12, "{c:?}");
        assert!(c.normal_force >= 0.0 && c.point[2].abs() < 5e-3 && c.depth >= 0.0, "{c:?}");
        total += c.normal_force;
    }
    // Landing from 0 height and held by PD: the feet carry roughly the weight already (±50 %).
    let weight = model.total_mass() * robot_model::GRAVITY_EARTH;
    assert!((total - weight).abs() < 0.5 * weight, "total normal force {total} vs weight {weight}");
    // Wrong sizes and non-finite input are typed errors.
    assert!(e.step(&[0.0; 3]).is_err());
    let mut tau = vec![0.0; model.nj()];
    tau[0] = f64::NAN;
    assert!(e.step(&tau).is_err());
    let mut bad = State::standing(&model);
    bad.q.pop();
    assert!(e.reset(&bad).is_err());
    bad = State::standing(&model);
    bad.q[0] = f64::INFINITY;
    assert!(e.reset(&bad).is_err());
    assert!(e.generalized_acceleration(&[0.0; 5]).is_err());
    assert!(
        DartEngine::new(&model, &CommonSettings { timestep: 0.0, ..Default::default() }, &Default::default()).is_err()
    );
}

/// `T` with `v_dart = T v_interface` for pelvis rotation `r` (the engine's documented convention; joints are
/// passed to the URDF probe in slot order, so only the base block is permuted and rotated).
fn dart_velocity_map(r: &nalgebra::Matrix3<f64>, nv: usize) -> DMatrix<f64> {
    let mut t = DMatrix::identity(nv, nv);
    t.view_mut((0, 0), (6, 6)).fill(0.0);
    for i in 0..3 {
        t[(i, 3 + i)] = 1.0;
        for k in 0..3 {
            t[(3 + i, k)] = r[(k, i)];
        }
    }
    t
}

#[test]
fn skeleton_matches_darts_own_urdf_loader() {
    // DART's URDF loader reads the same URDF text through urdfdom and builds its own skeleton: masses,
    // inertia placement, joint frames and axes all come from code we did not write. Collision elements are
    // dropped (the URDF's <capsule> is an extension urdfdom does not know; they carry no mass).
    let model = model();
    let (urdf, _) = RobotModel::h1_2_sources();
    let mut stripped = String::new();
    let mut rest = urdf;
    while let Some(start) = rest.find("<collision") {
        stripped.push_str(&rest[..start]);
        let Some(end) = rest[start..].find("</collision>") else { panic!("unterminated <collision>") };
        rest = &rest[start + end + "</collision>".len()..];
    }
    stripped.push_str(rest);
    let names: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
    let mut e = engine(&CommonSettings::rigid_body_only());
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let nv = model.nv();
    let mut worst = 0.0f64;
    for _ in 0..3 {
        let s = random_state(&model, &mut rng);
        let pose = [
            s.base_pos[0],
            s.base_pos[1],
            s.base_pos[2],
            s.base_quat[0],
            s.base_quat[1],
            s.base_quat[2],
            s.base_quat[3],
        ];
        let probe = ffi::urdf_probe(&stripped, &names, pose, &s.q).unwrap();
        assert!((probe.total_mass - model.total_mass()).abs() < 1e-12);
        // The claim, on the real library: after URDF loading no joint enforces its limits.
        assert!(probe.limits_enforced.iter().all(|e| !e), "DART's URDF loader enforced limits");
        assert!(probe.damping.iter().chain(&probe.friction).all(|x| *x == 0.0), "the URDF has no <dynamics>");
        let t = dart_velocity_map(&diff_physics::dart::rotation(s.base_quat), nv);
        let m_urdf = t.transpose() * DMatrix::from_row_slice(nv, nv, &probe.mass_matrix) * &t;
        e.reset(&s).unwrap();
        let m_ours = DMatrix::from_row_slice(nv, nv, &e.mass_matrix().unwrap());
        worst = worst.max((&m_ours - &m_urdf).norm() / m_urdf.norm());
    }
    println!("mass matrix, our skeleton vs DART's URDF loader: {worst:.2e} rel");
    // Same f64 numbers composed in different orders (rpy -> rotation, inertia placement): rounding only.
    assert!(worst < 1e-12, "{worst}");
    // And our own construction enforces limits exactly when asked.
    assert_eq!(engine(&CommonSettings::default()).limits_enforced(), model.nj());
    assert_eq!(engine(&CommonSettings { joint_limits: false, ..Default::default() }).limits_enforced(), 0);
}

/// Zero gravity, no ground: a free-floating robot, so internal joint torques only move the joints.
fn floating() -> CommonSettings {
    CommonSettings { gravity: [0.0; 3], ..CommonSettings::rigid_body_only() }
}

#[test]
fn joint_limits_hold_only_when_enabled() {
    // Elbow pushed towards its upper limit with 5 N·m for 0.2 s from 0.1 rad below it.
    let model = model();
    let ji = model.joint_index("left_elbow_joint").unwrap();
    let upper = model.joints[ji].upper;
    let mut s = State::at_rest(robot_model::GenCoords::zero(&model));
    s.base_pos[2] = 1.0;
    s.q[ji] = upper - 0.1;
    let mut tau = vec![0.0; model.nj()];
    tau[ji] = 5.0;
    let peak = |limits: bool| {
        let mut e = engine(&CommonSettings { joint_limits: limits, ..floating() });
        e.reset(&s).unwrap();
        let mut peak = f64::NEG_INFINITY;
        for _ in 0..100 {
            e.step(&tau).unwrap();
            peak = peak.max(e.state().q[ji]);
        }
        peak
    };
    let (on, off) = (peak(true), peak(false));
    println!("elbow peak: limits on {:.4}, off {:.4}, upper {upper}", on, off);
    // On: a velocity-level limit lets the joint overshoot by at most one step's motion (|dq| dt) plus slow
    // error reduction; 5 N·m on the forearm (+0.1 armature) reaches ~3 rad/s, i.e. ~6 mm rad per step.
    assert!(on <= upper + 0.01, "limit not enforced: {on} > {upper}");
    assert!(off > upper + 0.3, "limit acted although disabled: {off}");
}

#[test]
fn coulomb_joint_friction_holds_below_its_level() {
    // A torque below the model's frictionloss (0.2 N·m) does not move the joint when joint friction is on;
    // above it, it does. Off, any torque moves it.
    let model = model();
    let ji = model.joint_index("left_elbow_joint").unwrap();
    let f = model.joints[ji].frictionloss;
    let mut s = State::at_rest(robot_model::GenCoords::zero(&model));
    s.base_pos[2] = 1.0;
    let travel = |friction: bool, torque: f64| {
        let mut e = engine(&CommonSettings { joint_friction: friction, joint_limits: false, ..floating() });
        e.reset(&s).unwrap();
        let mut tau = vec![0.0; model.nj()];
        tau[ji] = torque;
        for _ in 0..100 {
            e.step(&tau).unwrap();
        }
        e.state().q[ji].abs()
    };
    let (held, slips, free) = (travel(true, 0.5 * f), travel(true, 2.0 * f), travel(false, 0.5 * f));
    println!("elbow travel in 0.2 s: {held:.2e} (0.5 f, friction), {slips:.2e} (2 f), {free:.2e} (0.5 f, no friction)");
    assert!(held < 1e-9, "{held}");
    assert!(slips > 1e-3 && free > 1e-3, "{slips} {free}");
}

#[test]
fn viscous_damping_is_implicit_in_the_articulated_body_algorithm() {
    // DART integrates joint damping implicitly: its accelerations are (M + A + dt·D)⁻¹ (f − b − D q̇), with M
    // and b from the model crate's RNEA (independent) and D the model's damping on the joints.
    let model = model();
    let dt = 0.002;
    let common =
        CommonSettings { timestep: dt, joint_damping: true, armature: true, ..CommonSettings::rigid_body_only() };
    let mut e = engine(&common);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let s = random_state(&model, &mut rng);
    e.reset(&s).unwrap();
    let (c, v) = (s.coords(), s.v());
    let g = [0.0, 0.0, -robot_model::GRAVITY_EARTH];
    let mut m = model.mass_matrix(&c, true).unwrap();
    let mut rhs = DVector::zeros(model.nv()) - model.bias_forces(&c, &v, g).unwrap();
    for (ji, j) in model.joints.iter().enumerate() {
        m[(6 + ji, 6 + ji)] += dt * j.damping;
        rhs[6 + ji] -= j.damping * v[6 + ji];
    }
    let want = m.cholesky().unwrap().solve(&rhs);
    let got = DVector::from_vec(e.generalized_acceleration(&vec![0.0; model.nv()]).unwrap());
    let err = (&got - &want).norm() / want.norm();
    println!("implicit damping accelerations: {err:.2e} rel");
    assert!(err < 1e-8, "{err}");
}

#[test]
fn darts_potential_energy_uses_body_origins() {
    // Why Engine::energy does not use Skeleton::computePotentialEnergy: DART 6.12 sums −m g·p over body frame
    // ORIGINS p. Reproduced here from the link poses and masses; the interface's −m g·com differs from it.
    let model = model();
    let mut e = engine(&CommonSettings::rigid_body_only());
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    e.reset(&random_state(&model, &mut rng)).unwrap();
    let g = Vector3::new(0.0, 0.0, -robot_model::GRAVITY_EARTH);
    let origins: f64 = e.link_poses().iter().zip(e.link_masses()).map(|(p, m)| -m * g.dot(&Vector3::from(p.pos))).sum();
    let dart = e.dart_potential_energy();
    let ours = e.energy().potential;
    println!("DART {dart:.9} J, at body origins {origins:.9} J, −m g·com {ours:.9} J");
    assert!((dart - origins).abs() < 1e-9 * origins.abs());
    assert!((dart - ours).abs() > 1e-2, "DART's potential energy now uses the COM: use it again");
}

#[test]
fn a_blow_up_is_a_typed_error_not_an_abort() {
    // The elbow of the limit test, driven on without limits: DART's explicit integration of the spinning arm
    // blows up (measured: > 1e3 rad/s at 0.53 s, 1e91 rad/s nine steps later). DART itself would abort the
    // process on the resulting NaN (assertions are on in Debian's build); the engine stops first with
    // Diverged, keeps refusing to step, and a reset brings it back.
    let model = model();
    let ji = model.joint_index("left_elbow_joint").unwrap();
    let mut s = State::at_rest(robot_model::GenCoords::zero(&model));
    s.base_pos[2] = 1.0;
    let mut tau = vec![0.0; model.nj()];
    tau[ji] = 5.0;
    let mut e = engine(&CommonSettings { joint_limits: false, ..floating() });
    e.reset(&s).unwrap();
    let failed_at = (0..2000).find(|_| e.step(&tau).is_err());
    println!("diverged at step {failed_at:?}");
    assert!(matches!(failed_at, Some(n) if n > 100), "{failed_at:?}");
    assert!(matches!(e.step(&tau), Err(diff_physics::EngineError::Diverged(_))));
    e.reset(&s).unwrap();
    e.step(&tau).unwrap();
    // Out-of-range input is refused up front.
    let mut fast = s.clone();
    fast.dq[ji] = 2.0 * diff_physics::dart::MAX_SPEED;
    assert!(matches!(e.reset(&fast), Err(diff_physics::EngineError::Input(_))));
    tau[ji] = 1e300;
    assert!(matches!(e.step(&tau), Err(diff_physics::EngineError::Input(_))));
}

#[cfg(feature = "mujoco")]
#[test]
fn standing_tracks_mujoco() {
    // 0.5 s of PD standing (ankles stiffened as in the oracle's standing check) in MuJoCo and DART from the same
    // reset. The two differ in their contact models only: MuJoCo's soft contacts sink under the weight
    // (solref 0.02 s: measured 0.55 mm lower pelvis), DART's hard LCP contacts do not. Measured at 0.5 s:
    // |Δz| 0.56 mm, |Δxy| 0.2 mm, Δ orientation 3e-4 rad, Δ joints 1e-3 rad, equal mean foot load. Tolerances:
    // 2 mm, 2 mm, 2e-3 rad, 5e-3 rad, 2 % — a model translation error (e.g. armature missing from the contact
    // impulses, which sank DART's pelvis 4 cm in 0.2 s) exceeds them by an order of magnitude.
    let model = model();
    let common = CommonSettings::default();
    let mut pd = PdTarget::hold_standing(&model);
    for (i, j) in model.joints.iter().enumerate() {
        if j.motor_name.contains("ankle") {
            pd.kp[i] = 600.0;
            pd.kd[i] = 10.0;
        }
    }
    let mut engines: Vec<Box<dyn Engine>> =
        vec![diff_physics::make_engine(EngineKind::Mujoco, &model, &common).unwrap(), Box::new(engine(&common))];
    let mut load = [0.0; 2];
    for e in engines.iter_mut() {
        e.reset(&State::standing(&model)).unwrap();
    }
    for i in 0..250 {
        for (k, e) in engines.iter_mut().enumerate() {
            let s = e.state();
            e.step(&pd_torques(&model, &pd, &s.q, &s.dq)).unwrap();
            if i >= 125 {
                load[k] += e.contacts().iter().map(|c| c.normal_force).sum::<f64>() / 125.0;
            }
        }
    }
    let (a, b) = (engines[0].state(), engines[1].state());
    let dz = (a.base_pos[2] - b.base_pos[2]).abs();
    let dxy = (a.base_pos[0] - b.base_pos[0]).hypot(a.base_pos[1] - b.base_pos[1]);
    let angle = diff_physics::engine::quat_angle(a.base_quat, b.base_quat);
    let dq = a.q.iter().zip(&b.q).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    let dload = (load[0] - load[1]).abs() / load[0];
    println!("MuJoCo vs DART at 0.5 s: dz {dz:.2e} m, dxy {dxy:.2e} m, angle {angle:.2e} rad, dq {dq:.2e} rad, load {dload:.2e}");
    assert!(dz < 2e-3 && dxy < 2e-3, "{dz} {dxy}");
    assert!(angle < 2e-3 && dq < 5e-3, "{angle} {dq}");
    assert!(dload < 0.02, "{load:?}");
}

#[test]
#[ignore]
fn time_reset_and_step() {
    let model = model();
    let mut e = engine(&CommonSettings::default());
    let s = State::standing(&model);
    let t0 = std::time::Instant::now();
    for _ in 0..200 {
        e.reset(&s).unwrap();
    }
    let reset = t0.elapsed().as_secs_f64() / 200.0;
    let t0 = std::time::Instant::now();
    run(&mut e, &model, 500);
    let step = t0.elapsed().as_secs_f64() / 500.0;
    println!("reset {:.1} us, step {:.1} us", reset * 1e6, step * 1e6);
}
