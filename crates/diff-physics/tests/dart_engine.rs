//! DART against the model crate's own rigid-body reference, against DART's own URDF loader, and against MuJoCo.
//! Run: `cargo test -p diff-physics --features dart --test dart_engine`.
#![cfg(feature = "dart")]
#![allow(clippy::unwrap_used)]

use diff_physics::dart::{DartEngine, DartSettings};
use diff_physics::oracle::{run_checks, CheckOptions};
use diff_physics::{CommonSettings, Engine, EngineKind};

fn model() -> robot_model::RobotModel {
    robot_model::RobotModel::h1_2().expect("built-in model loads")
}

#[test]
fn dart_passes_all_oracles() {
    let model = model();
    let report = run_checks(&model, &[EngineKind::Dart], &CheckOptions { samples: 3, ..CheckOptions::default() });
    println!("{}", report.table());
    assert!(!report.checks.is_empty());
    assert!(report.passed(), "{}", report.table());
}

#[test]
fn builds() {
    let e = DartEngine::new(&model(), &CommonSettings::default(), &DartSettings::default()).unwrap();
    println!("{}", e.version());
    println!("{}", e.settings());
}

#[test]
#[ignore]
fn debug_standing() {
    use diff_physics::{pd_torques, PdTarget, State};
    let model = model();
    for (label, common) in [
        ("full", CommonSettings::default()),
        ("no armature", CommonSettings { armature: false, ..CommonSettings::default() }),
        ("no friction", CommonSettings { joint_friction: false, ..CommonSettings::default() }),
        ("no limits", CommonSettings { joint_limits: false, ..CommonSettings::default() }),
        (
            "no arm/fric/lim/damp",
            CommonSettings {
                joint_limits: false,
                armature: false,
                joint_friction: false,
                joint_damping: false,
                ..CommonSettings::default()
            },
        ),
    ] {
        let mut e = DartEngine::new(&model, &common, &DartSettings::default()).unwrap();
        let mut pd = PdTarget::hold_standing(&model);
        for (i, j) in model.joints.iter().enumerate() {
            if j.motor_name.contains("ankle") {
                pd.kp[i] = 600.0;
                pd.kd[i] = 10.0;
            }
        }
        e.reset(&State::standing(&model)).unwrap();
        print!("{label}: ");
        for i in 0..750 {
            let s = e.state();
            let tau = pd_torques(&model, &pd, &s.q, &s.dq);
            e.step(&tau).unwrap();
            if i % 50 == 0 || i < 3 {
                let cs = e.contacts();
                let f: f64 = cs.iter().map(|c| c.normal_force).sum();
                print!("[{i} z={:.4} n={} F={:.0}] ", e.state().base_pos[2], cs.len(), f);
            }
        }
        println!();
    }
}
