//! The validation verdict on engines whose difference is known (issue 15). The shipped LSTM policy
//! (unitree_rl_gym, trained in Isaac Gym) runs with MuJoCo as its reference engine against:
//! - DART (or, in a build without it, Rapier multibody), an independent engine that holds the same robot model:
//!   the policy must be judged to transfer (measured: it stays up with the same score, see BENCHMARKS.md);
//! - MuJoCo on a floor with friction 0.02 instead of the model's 1.0, a planted difference that no walking
//!   policy survives: it must be flagged (degrades or fails), with evidence of where.
//!
//! The planted floor is the known cause; the verdict does not know it and has to find the drop from the scores.
use diff_physics::{make_engine, CommonSettings, Engine, EngineError, EngineKind};
use engine_diff::harness::{builtin_factories, ControllerFactory, EngineFactory, HarnessConfig};
use engine_diff::scenario::Scenario;
use engine_diff::triage::AllowList;
use engine_diff::validate::{standard_commands, validate, ValidateSetup, ValidationReport, Verdict};
use robot_model::RobotModel;
use std::sync::Arc;

/// MuJoCo on a slippery floor.
#[derive(Debug)]
struct MujocoOnIce;

impl EngineFactory for MujocoOnIce {
    fn name(&self) -> String {
        "mujoco_on_ice".into()
    }
    fn build(&self, model: &RobotModel, common: &CommonSettings) -> Result<Box<dyn Engine>, EngineError> {
        let mut m = model.clone();
        m.contact.friction = ICE_FRICTION;
        make_engine(EngineKind::Mujoco, &m, common)
    }
}

const ICE_FRICTION: f64 = 0.02;

fn lstm_policy() -> (String, Box<ControllerFactory>) {
    let spec =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots/h1_2/policies/unitree_rl_gym_lstm.toml");
    let pc = policy_runtime::PolicyController::load(&spec).expect("shipped policy spec");
    let name = policy_runtime::Controller::name(&pc).to_string();
    (name, Box::new(move |_s: &Scenario| Ok(Box::new(pc.clone()) as Box<dyn policy_runtime::Controller>)))
}

/// The LSTM policy over stand + forward, seeds 1-4, 4 s, MuJoCo as the reference engine.
fn validate_lstm(factories: &[Arc<dyn EngineFactory>]) -> ValidationReport {
    let model = RobotModel::h1_2().expect("model");
    let (name, ctrl) = lstm_policy();
    let commands: Vec<_> =
        standard_commands().into_iter().filter(|c| c.name == "stand" || c.name == "forward").collect();
    let allow = AllowList::builtin().expect("allow-list");
    validate(&ValidateSetup {
        model: &model,
        factories,
        train_engine: "mujoco",
        controller: ctrl.as_ref(),
        controller_name: &name,
        commands: &commands,
        seeds: &[1, 2, 3, 4],
        seconds: 4.0,
        cfg: &HarnessConfig::default(),
        allow: &allow,
        evidence: true,
    })
    .expect("validation")
}

#[test]
fn flags_the_planted_floor_and_passes_an_independent_engine() {
    let other = if EngineKind::parse_available("dart").is_ok() { "dart" } else { "rapier_multibody" };
    let mut factories = builtin_factories(&["mujoco".to_string(), other.to_string()]).expect("engines");
    factories.push(Arc::new(MujocoOnIce));
    let r = validate_lstm(&factories);
    let md = r.markdown();
    let by = |n: &str| r.engines.iter().find(|e| e.engine == n).unwrap_or_else(|| panic!("{n} missing\n{md}"));
    assert_eq!(by("mujoco").verdict, Verdict::TrainingEngine, "{md}");
    assert_eq!(by("mujoco").fall_rate, 0.0, "the shipped policy stands and walks in MuJoCo\n{md}");
    assert_eq!(by(other).verdict, Verdict::Transfers, "{md}");
    let ice = by("mujoco_on_ice");
    assert!(matches!(ice.verdict, Verdict::Degrades | Verdict::Fails), "{md}");
    let ev = ice.evidence.as_ref().unwrap_or_else(|| panic!("flagged engines carry evidence\n{md}"));
    assert!(!ev.phase.is_empty() && !ev.joint.is_empty() && ev.phase_share > 0.0, "{md}");
    // 8 pairs: the exact sign-flip test cannot go below 2/256.
    assert!(
        ice.p_value.is_some_and(|p| (2.0 / 256.0 - 1e-12..0.05).contains(&p)) || ice.verdict == Verdict::Fails,
        "{md}"
    );
    assert!(md.contains("mujoco_on_ice") && md.contains("Where it degrades"), "{md}");
    println!("{md}");
}

/// MuJoCo without the model's joint armature.
#[derive(Debug)]
struct MujocoWithoutArmature;

impl EngineFactory for MujocoWithoutArmature {
    fn name(&self) -> String {
        "mujoco_no_armature".into()
    }
    fn build(&self, model: &RobotModel, common: &CommonSettings) -> Result<Box<dyn Engine>, EngineError> {
        make_engine(EngineKind::Mujoco, model, &CommonSettings { armature: false, ..common.clone() })
    }
}

/// Experiment (run with `--ignored --nocapture`; it prints, asserts nothing): does the missing joint armature
/// explain why the LSTM policy degrades in Bullet (no armature in btMultiBody) and Rapier impulse joints (armature
/// approximated)? MuJoCo with the armature switched off is the independent counterpart. Measured (2026-11-23,
/// stand + forward, seeds 1-4, 4 s): the degradation in Bullet and Rapier impulse is a pelvis yaw-rate wobble
/// (yaw-rate tracking error 0.75 and 1.03 rad/s RMS against MuJoCo's 0.085; forward and lateral unchanged);
/// MuJoCo without armature shows the same signature at a third of the size (0.29 rad/s; score drop 0.095 against
/// Bullet's 0.50): armature is one cause, not all of it. Figures in BENCHMARKS.md "Validation".
#[test]
#[ignore = "experiment: prints the validation with MuJoCo without armature beside Bullet and Rapier impulse"]
fn armature_share_of_the_degradation() {
    let mut factories = builtin_factories(&["mujoco".to_string(), "bullet".to_string(), "rapier_impulse".to_string()])
        .expect("engines");
    factories.push(Arc::new(MujocoWithoutArmature));
    let r = validate_lstm(&factories);
    for e in &r.engines {
        let mine: Vec<_> = r.episodes.iter().filter(|x| x.engine == e.engine).collect();
        let m: Vec<f64> = (0..3)
            .map(|k| mine.iter().map(|x| x.outcome.velocity_error_rms[k]).sum::<f64>() / mine.len().max(1) as f64)
            .collect();
        println!("{}: tracking error RMS forward / lateral / yaw rate {m:.3?}", e.engine);
    }
    println!("{}", r.markdown());
}
