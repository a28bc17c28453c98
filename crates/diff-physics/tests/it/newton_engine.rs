//! Newton's solvers (Featherstone, Steel) against the model crate's RNEA/CRBA reference and MuJoCo, and the Python
//! server's failure modes as typed errors. Needs `bash scripts/setup.sh --newton`. Run:
//! `cargo test -p diff-physics --features newton --test it -- newton_engine::`.
//!
//! Newton's state is f32: the oracle tolerances come from `newton::f32_tolerance` (derived from u = 2⁻²⁴ as
//! PhysX's); the independent counterparts are robot-model's f64 reference and MuJoCo.
#![cfg(all(feature = "newton", feature = "mujoco"))]
#![allow(clippy::unwrap_used)]

use diff_physics::newton::protocol::NewtonError;
use diff_physics::newton::{NewtonEngine, NewtonSettings, NewtonSolver};
use diff_physics::oracle::{run_checks, CheckOptions};
use diff_physics::{pd_torques, CommonSettings, Engine, EngineError, EngineKind, PdTarget, State};
use robot_model::RobotModel;
use std::path::PathBuf;

fn model() -> RobotModel {
    RobotModel::h1_2().expect("built-in model loads")
}

fn run(e: &mut dyn Engine, model: &RobotModel, steps: usize) -> State {
    let pd = PdTarget::hold_standing(model);
    for _ in 0..steps {
        let s = e.state();
        e.step(&pd_torques(model, &pd, &s.q, &s.dq)).expect("step");
    }
    e.state()
}

fn oracles(kind: EngineKind) {
    let model = model();
    let report = run_checks(&model, &[EngineKind::Mujoco, kind], &CheckOptions { samples: 2, ..Default::default() });
    println!("{}", report.table());
    assert!(report.checks.iter().filter(|c| c.engine == kind.name()).count() >= 20, "{}", report.table());
    assert!(report.checks.iter().any(|c| c.engine == format!("mujoco vs {}", kind.name())), "no cross-engine check");
    assert!(report.passed(), "{}", report.table());
}

/// Every oracle of `ulab model check` (mass, COM, FK, axes, limits, mass matrix, bias forces, contact-free
/// accelerations, standing, energy and momentum invariants) and one step with contact against MuJoCo.
#[test]
fn featherstone_passes_the_oracles() {
    oracles(EngineKind::NewtonFeatherstone);
}

#[test]
fn steel_passes_the_oracles() {
    oracles(EngineKind::NewtonSteel);
}

#[test]
fn reset_is_a_true_reset_and_contacts_are_on_the_soles() {
    let model = model();
    let mut e =
        NewtonEngine::new(&model, &CommonSettings::default(), &NewtonSettings::for_solver(NewtonSolver::Featherstone))
            .expect("Newton engine builds");
    let s0 = State::standing(&model);
    e.reset(&s0).unwrap();
    let a = run(&mut e, &model, 40);
    let (ta, ca) = (e.time(), e.contacts());
    let mut kicked = s0.clone();
    kicked.base_lin_vel = [0.5, -0.3, 0.0];
    e.reset(&kicked).unwrap();
    run(&mut e, &model, 17);
    e.reset(&s0).unwrap();
    assert_eq!(e.time(), 0.0);
    let b = run(&mut e, &model, 40);
    assert_eq!(a, b, "a reset did not reproduce the run");
    assert_eq!(ta, e.time());
    assert_eq!(ca, e.contacts());
    assert!(a != s0, "the run did not move");
    assert!(ca.len() >= 2, "expected foot contacts, got {ca:?}");
    for c in &ca {
        assert_eq!(c.body_a, "ground");
        assert!(c.body_b.ends_with("ankle_roll_link"), "{c:?}");
        assert!((c.normal[2] - 1.0).abs() < 1e-6, "{c:?}");
        assert!(c.normal_force >= 0.0 && c.depth >= 0.0, "{c:?}");
    }
    // A window of steps in one request is the same as step-by-step.
    e.reset(&s0).unwrap();
    let pd = PdTarget::hold_standing(&model);
    let tau = pd_torques(&model, &pd, &s0.q, &s0.dq);
    e.step_window(&[tau.clone(), tau.clone(), tau.clone()]).unwrap();
    let w = e.state();
    e.reset(&s0).unwrap();
    for _ in 0..3 {
        e.step(&tau).unwrap();
    }
    assert_eq!(w, e.state());
    // Wrong sizes and non-finite values are typed errors, not panics.
    assert!(matches!(e.step(&[0.0; 3]), Err(EngineError::Input(_))));
    let mut bad = s0.clone();
    bad.q[0] = f64::NAN;
    assert!(matches!(e.reset(&bad), Err(EngineError::Input(_))));
    assert!(e.generalized_acceleration(&[0.0; 4]).is_err());
}

fn settings_with(python: PathBuf, server: PathBuf, timeout: f64) -> NewtonSettings {
    NewtonSettings {
        python,
        server,
        startup_timeout_s: timeout,
        request_timeout_s: timeout,
        ..NewtonSettings::for_solver(NewtonSolver::Featherstone)
    }
}

fn script(name: &str, body: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ulab-newton-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, body).unwrap();
    p
}

/// A missing interpreter, a server that exits and a server that hangs are typed errors within the deadline.
#[test]
fn server_failures_are_typed_errors_not_hangs() {
    let model = model();
    let common = CommonSettings::default();
    let py = PathBuf::from("python3");
    let build = |s: &NewtonSettings| NewtonEngine::new(&model, &common, s).map(|_| ()).unwrap_err();

    let missing = build(&settings_with(PathBuf::from("/nonexistent/python"), script("ok.py", ""), 5.0));
    assert!(missing.to_string().contains("cannot start"), "{missing}");

    let died = build(&settings_with(
        py.clone(),
        script("dies.py", "import sys\nprint('bye', file=sys.stderr)\nsys.exit(3)\n"),
        30.0,
    ));
    assert!(died.to_string().contains("died") && died.to_string().contains("bye"), "{died}");

    let t0 = std::time::Instant::now();
    let hang = build(&settings_with(py.clone(), script("hangs.py", "import time\ntime.sleep(120)\n"), 1.0));
    assert!(hang.to_string().contains("no answer"), "{hang}");
    assert!(t0.elapsed().as_secs_f64() < 20.0, "the deadline was not kept: {:?}", t0.elapsed());

    // Garbage on stdout is a protocol error (frame length out of range), not a panic.
    let garbage = build(&settings_with(
        py,
        script(
            "garbage.py",
            "import sys\nsys.stdout.buffer.write(b'\\xff' * 16)\nsys.stdout.flush()\nimport time\ntime.sleep(5)\n",
        ),
        10.0,
    ));
    assert!(garbage.to_string().contains("died") || garbage.to_string().contains("protocol"), "{garbage}");
    let _ = NewtonError::Protocol(String::new());
}
