//! Spec files: the shipped specs say what the published conventions say, and bad specs give typed errors.

use policy_runtime::{
    Controller, HistoryLayout, LstmInitialState, PolicyController, PolicyError, PolicyKind, PolicySpec, SpecError,
    TermKind,
};
use std::path::{Path, PathBuf};

fn spec_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../../robots/h1_2/policies/{name}.toml"))
}

fn shipped(name: &str) -> Option<PolicySpec> {
    match std::env::var("ULAB_SHARED") {
        Ok(s) if !s.is_empty() => Some(PolicySpec::load(&spec_path(name)).unwrap_or_else(|e| panic!("{name}: {e}"))),
        _ => {
            eprintln!("SKIP: ULAB_SHARED is not set (the shipped specs point into $ULAB_SHARED)");
            None
        }
    }
}

/// The figures of `../shared/reference/README.md` ("Policy conventions", "PD gains seen in Unitree code").
const LEG_DEFAULT: [f64; 6] = [0.0, -0.16, 0.0, 0.36, -0.2, 0.0];
const LEG_KP: [f64; 6] = [200.0, 200.0, 200.0, 300.0, 40.0, 40.0];
const LEG_KD: [f64; 6] = [2.5, 2.5, 2.5, 4.0, 2.0, 2.0];

fn check_common(spec: &PolicySpec) {
    let model = robot_model::RobotModel::h1_2().expect("built-in model");
    spec.check_robot(&model).expect("spec slots are the model's joints");
    assert_eq!(spec.policy_joints, (0..12).collect::<Vec<_>>(), "both policies command slots 0..11 in slot order");
    for (i, j) in spec.joints.iter().enumerate() {
        if i < 12 {
            assert_eq!((j.default_q, j.kp, j.kd), (LEG_DEFAULT[i % 6], LEG_KP[i % 6], LEG_KD[i % 6]), "{}", j.name);
        } else {
            assert_eq!(j.default_q, 0.0, "{}", j.name);
        }
    }
    assert_eq!((spec.joints[12].kp, spec.joints[12].kd), (300.0, 3.0), "waist");
    assert_eq!(spec.joints[13].kp, 120.0, "shoulder pitch");
    assert_eq!(spec.action_scale, 0.25);
    assert_eq!(spec.control_period, 0.02);
    assert_eq!(spec.decimation(0.002).expect("whole steps"), 10);
    assert_eq!(spec.decimation(0.005).expect("whole steps"), 4);
    assert!(spec.decimation(0.003).is_err());
    assert_eq!(spec.observation[0].kind, TermKind::AngVel);
    assert_eq!(spec.observation[0].scale, vec![0.25; 3]);
    assert_eq!(spec.observation[1].kind, TermKind::ProjectedGravity);
    assert_eq!(spec.observation[2].kind, TermKind::Command);
    assert_eq!(spec.observation[3].kind, TermKind::JointPosRel);
    assert_eq!(spec.observation[3].scale, vec![1.0; 12]);
    assert_eq!(spec.observation[4].kind, TermKind::JointVel);
    assert_eq!(spec.observation[4].scale, vec![0.05; 12]);
    assert_eq!(spec.observation[5].kind, TermKind::LastAction);
    assert_eq!(spec.clip_actions, None);
}

#[test]
fn shipped_gepetto_spec() {
    let Some(spec) = shipped("gepetto_demo_rsl") else {
        return;
    };
    check_common(&spec);
    assert_eq!(spec.kind, PolicyKind::OnnxMlp);
    assert_eq!((spec.history_length, spec.history_layout), (6, HistoryLayout::TermMajor));
    assert_eq!(spec.observation.len(), 6);
    assert_eq!(spec.observation[2].scale, vec![1.0; 3]);
    assert_eq!(spec.frame_dim(), 45);
    assert_eq!(spec.observation_dim(), 270);
}

#[test]
fn shipped_unitree_spec() {
    let Some(spec) = shipped("unitree_rl_gym_lstm") else {
        return;
    };
    check_common(&spec);
    assert_eq!(spec.kind, PolicyKind::LstmNpz);
    assert_eq!(spec.history_length, 1);
    assert_eq!(spec.lstm_initial_state, LstmInitialState::Stored);
    assert_eq!(spec.observation[2].scale, vec![2.0, 2.0, 0.25]);
    assert_eq!(spec.observation[6].kind, TermKind::GaitPhaseSinCos { period: 0.8 });
    assert_eq!(spec.observation_dim(), 47);
}

#[test]
fn zero_action_on_first_call_fills_default_pose_on_other_joints() {
    let Some(spec) = shipped("gepetto_demo_rsl") else {
        return;
    };
    let mut ctl = PolicyController::from_spec(spec.clone()).expect("controller");
    assert_eq!(ctl.name(), "gepetto_demo_rsl");
    assert_eq!(ctl.period(), 0.02);
    let obs = policy_runtime::RobotObservation {
        time: 0.02,
        base_quat: [1.0, 0.0, 0.0, 0.0],
        base_ang_vel: [0.0; 3],
        q: spec.joints.iter().map(|j| j.default_q).collect(),
        dq: vec![0.0; 27],
        command: [0.5, 0.0, 0.0],
    };
    let t = ctl.act(&obs).expect("act");
    assert_eq!(t.q_des.len(), 27);
    for j in &spec.joints[12..] {
        assert_eq!((t.q_des[j.slot], t.kp[j.slot], t.kd[j.slot]), (j.default_q, j.kp, j.kd), "{}", j.name);
    }
    // The first observation is six copies of one frame: term blocks of 6 equal frames.
    let o = ctl.last_observation();
    assert_eq!(o.len(), 270);
    assert!(o[..18].chunks(3).all(|c| c == [0.0, 0.0, 0.0]));
    assert!(o[18..36].chunks(3).all(|c| c == [0.0, 0.0, -1.0]));
    assert!(o[36..54].chunks(3).all(|c| c == [0.5, 0.0, 0.0]));
    assert!(o[198..].iter().all(|&v| v == 0.0), "last action starts at zero");
    // Second call: the newest last-action frame is the first call's action.
    let a1 = ctl.last_action().to_vec();
    ctl.act(&obs).expect("act");
    let newest: Vec<f64> = ctl.last_observation()[270 - 12..].iter().map(|&v| f64::from(v)).collect();
    assert!(newest.iter().zip(&a1).all(|(x, y)| (x - y).abs() < 1e-6));
    // Reset clears the history and the last action.
    ctl.reset();
    assert!(ctl.last_observation().is_empty() && ctl.last_action().iter().all(|&a| a == 0.0));
}

const BASE: &str = r#"
name = "t"
kind = "onnx_mlp"
model = "m.onnx"
control_period = 0.02

[[observation]]
term = "ang_vel"

[[observation]]
term = "joint_pos_rel"

[action]
scale = 0.25
joints = ["a", "b"]

[joints]
slots = [
  { slot = 0, name = "a", default = 0.0, kp = 1.0, kd = 0.1 },
  { slot = 1, name = "b", default = 0.0, kp = 1.0, kd = 0.1 },
]
"#;

fn parse(text: &str) -> Result<PolicySpec, SpecError> {
    PolicySpec::from_toml_str(text, Path::new("/specs"))
}

#[test]
fn base_spec_is_valid() {
    let s = parse(BASE).expect("valid");
    assert_eq!(s.model_path, Path::new("/specs/m.onnx"), "relative to the spec's directory");
    assert_eq!(s.frame_dim(), 5);
    let abs = parse(&BASE.replace("\"m.onnx\"", "\"/abs/m.onnx\"")).expect("valid");
    assert_eq!(abs.model_path, Path::new("/abs/m.onnx"));
    assert_eq!(abs.with_model_path("/other.onnx").model_path, Path::new("/other.onnx"));
}

#[test]
fn unknown_term() {
    let e = parse(&BASE.replace("term = \"ang_vel\"", "term = \"base_lin_vel\"")).unwrap_err();
    assert!(matches!(&e, SpecError::UnknownTerm { term, .. } if term == "base_lin_vel"), "{e}");
}

#[test]
fn unknown_kind_layout_joint_state() {
    assert!(matches!(parse(&BASE.replace("onnx_mlp", "tflite")), Err(SpecError::UnknownKind(k)) if k == "tflite"));
    let t =
        BASE.replace("control_period = 0.02", "control_period = 0.02\n[history]\nlength = 2\nlayout = \"interleaved\"");
    assert!(matches!(parse(&t), Err(SpecError::UnknownLayout(_))));
    assert!(
        matches!(parse(&BASE.replace("[\"a\", \"b\"]", "[\"a\", \"z\"]")), Err(SpecError::UnknownJoint(j)) if j == "z")
    );
    assert!(matches!(parse(&BASE.replace("[\"a\", \"b\"]", "[0, 7]")), Err(SpecError::UnknownJoint(_))));
    let t = BASE
        .replace("onnx_mlp", "lstm_npz")
        .replace("control_period = 0.02", "control_period = 0.02\n[lstm]\ninitial_state = \"random\"");
    assert!(matches!(parse(&t), Err(SpecError::UnknownInitialState(_))));
}

#[test]
fn bad_scale_length() {
    let t = BASE.replace("term = \"joint_pos_rel\"", "term = \"joint_pos_rel\"\nscale = [1.0, 2.0, 3.0]");
    let e = parse(&t).unwrap_err();
    assert!(matches!(e, SpecError::BadScale { expected: 2, found: 3, .. }), "{e}");
}

#[test]
fn invalid_values() {
    for (from, to) in [
        ("control_period = 0.02", "control_period = -1.0"),
        ("[\"a\", \"b\"]", "[\"a\", \"a\"]"),
        ("slot = 1, name = \"b\"", "slot = 2, name = \"b\""),
        ("slot = 1, name = \"b\"", "slot = 1, name = \"a\""),
        ("slot = 1, name = \"b\", default = 0.0, kp = 1.0", "slot = 1, name = \"b\", default = 0.0, kp = -1.0"),
        ("term = \"ang_vel\"", "term = \"gait_phase_sin_cos\""),
        ("term = \"ang_vel\"", "term = \"ang_vel\"\nperiod = 0.8"),
    ] {
        let t = BASE.replace(from, to);
        assert_ne!(t, BASE, "replacement {from} did not apply");
        assert!(matches!(parse(&t), Err(SpecError::Invalid(_))), "{to}: {:?}", parse(&t));
    }
}

#[test]
fn parse_errors_are_typed() {
    assert!(matches!(parse("name = "), Err(SpecError::Parse { .. })));
    assert!(matches!(parse(&BASE.replace("kind = ", "kinds = ")), Err(SpecError::Parse { .. })), "unknown key");
    let e = PolicySpec::load(Path::new("/nonexistent/spec.toml")).unwrap_err();
    assert!(matches!(e, SpecError::Io { .. }), "{e}");
}

#[test]
fn missing_model_file() {
    let spec = parse(BASE).expect("valid").with_model_path("/nonexistent/policy.onnx");
    let e = PolicyController::from_spec(spec).unwrap_err();
    assert!(matches!(e, PolicyError::InvalidSpec(SpecError::MissingFile { .. })), "{e}");
    let spec = parse(&BASE.replace("onnx_mlp", "lstm_npz")).expect("valid").with_model_path("/nonexistent/p.npz");
    let e = PolicyController::from_spec(spec).unwrap_err();
    assert!(matches!(e, PolicyError::InvalidSpec(SpecError::MissingFile { .. })), "{e}");
}

#[test]
fn model_that_is_not_a_model() {
    let bogus = std::env::temp_dir().join(format!("policy-runtime-bogus-{}.onnx", std::process::id()));
    std::fs::write(&bogus, b"not an onnx file").expect("write temp file");
    let e = PolicyController::from_spec(parse(BASE).expect("valid").with_model_path(&bogus)).unwrap_err();
    assert!(matches!(e, PolicyError::Model { .. }), "{e}");
    let e = PolicyController::from_spec(
        parse(&BASE.replace("onnx_mlp", "lstm_npz")).expect("valid").with_model_path(&bogus),
    )
    .unwrap_err();
    assert!(matches!(e, PolicyError::Model { .. }), "{e}");
    let _ = std::fs::remove_file(&bogus);
}

#[test]
fn dimension_mismatch_with_the_model() {
    let Some(spec) = shipped("gepetto_demo_rsl") else {
        return;
    };
    // Five frames of history instead of six: 225 inputs for a 270-input network.
    let text =
        std::fs::read_to_string(spec_path("gepetto_demo_rsl")).expect("spec").replace("length = 6", "length = 5");
    let short = PolicySpec::from_toml_str(&text, Path::new("/")).expect("valid on its own");
    let e = PolicyController::from_spec(short).unwrap_err();
    assert!(matches!(e, PolicyError::InvalidSpec(SpecError::DimensionMismatch { spec: 225, model: 270, .. })), "{e}");
    // The LSTM spec's observation against the ONNX model.
    let Some(lstm) = shipped("unitree_rl_gym_lstm") else {
        return;
    };
    let mut mixed = lstm.clone();
    mixed.kind = PolicyKind::OnnxMlp;
    mixed.model_path = spec.model_path.clone();
    let e = PolicyController::from_spec(mixed).unwrap_err();
    assert!(matches!(e, PolicyError::InvalidSpec(SpecError::DimensionMismatch { spec: 47, model: 270, .. })), "{e}");
}

#[test]
fn robot_mismatch() {
    let model = robot_model::RobotModel::h1_2().expect("built-in model");
    let e = parse(BASE).expect("valid").check_robot(&model).unwrap_err();
    assert!(matches!(e, SpecError::RobotMismatch(_)), "{e}");
}
