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
