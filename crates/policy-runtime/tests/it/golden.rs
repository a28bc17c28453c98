//! Our policies against an independent reference: `tests/oracle/policy_oracle.py` (onnxruntime for the ONNX
//! policy, numpy from the `.npz` arrays for the LSTM, observation assembly written from the published
//! conventions) recorded robot-state sequences, the network inputs built from them, the actions and the PD
//! targets into `corpus/golden/policies/`. We check
//!
//! * the forward pass alone (golden observation → action) to 1e-5;
//! * the whole controller (robot state → observation → action → `q_des`) against the same data.
//!
//! With `ULAB_PYTHON` set, the oracle is also re-run into a temporary directory and both checks repeat on its
//! fresh output, which must also equal the committed files (so a changed oracle cannot pass on stale data).
//! The models are read from `$ULAB_SHARED/reference/policies/`; without `ULAB_SHARED` the tests skip.

use policy_runtime::{
    Controller, LstmInitialState, LstmPolicy, OnnxPolicy, PolicyController, PolicySpec, RobotObservation,
};
use serde::Deserialize;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

const FORWARD_TOL: f64 = 1e-5;
/// Observation values are `f32` of the same `f64` expressions computed in another order: 1–2 ulp of values ≲ 5.
const OBS_TOL: f64 = 2e-6;

#[derive(Debug, Deserialize)]
struct Golden {
    policy: String,
    model: String,
    model_sha256: String,
    control_period: f64,
    steps: Vec<Step>,
}

#[derive(Debug, Deserialize, PartialEq)]
struct Step {
    time: f64,
    base_quat: [f64; 4],
    base_ang_vel: [f64; 3],
    q: Vec<f64>,
    dq: Vec<f64>,
    command: [f64; 3],
    obs: Vec<f32>,
    action: Vec<f32>,
    q_des: Vec<f64>,
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn shared() -> Option<PathBuf> {
    match std::env::var("ULAB_SHARED") {
        Ok(s) if !s.is_empty() => Some(PathBuf::from(s)),
        _ => {
            eprintln!("SKIP: ULAB_SHARED is not set; the reference policies live in $ULAB_SHARED/reference/policies/");
            None
        }
    }
}

fn read_golden(dir: &Path, policy: &str) -> Golden {
    let path = dir.join(format!("{policy}.json"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn spec(policy: &str) -> PolicySpec {
    let path = root().join(format!("robots/h1_2/policies/{policy}.toml"));
    PolicySpec::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn max_abs_diff<A: Copy + Into<f64>, B: Copy + Into<f64>>(a: &[A], b: &[B]) -> f64 {
    assert_eq!(a.len(), b.len(), "length mismatch");
    a.iter().zip(b).map(|(&x, &y)| (x.into() - y.into()).abs()).fold(0.0, f64::max)
}

fn check_model_file(g: &Golden, model_path: &Path) {
    let bytes = std::fs::read(model_path).unwrap_or_else(|e| panic!("{}: {e}", model_path.display()));
    let sha: String = Sha256::digest(&bytes).iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(
        sha,
        g.model_sha256,
        "{} is not the model the golden data was made with ({})",
        model_path.display(),
        g.model
    );
}

/// Golden observation → action, through the network alone.
fn check_forward(g: &Golden, spec: &PolicySpec) {
    check_model_file(g, &spec.model_path);
    let mut worst = 0.0f64;
    match g.policy.as_str() {
        "gepetto_demo_rsl" => {
            let net = OnnxPolicy::load(&spec.model_path).expect("ONNX policy loads");
            assert_eq!((net.input_dim(), net.output_dim()), (270, 12));
            for (k, s) in g.steps.iter().enumerate() {
                let a = net.forward(&s.obs).expect("forward");
                let d = max_abs_diff(&a, &s.action);
                assert!(d <= FORWARD_TOL, "step {k}: |ours - onnxruntime| = {d:e}");
                worst = worst.max(d);
            }
        }
        "unitree_rl_gym_lstm" => {
            let mut net = LstmPolicy::load(&spec.model_path, LstmInitialState::Stored).expect("LSTM loads");
            assert_eq!((net.input_dim(), net.output_dim()), (47, 12));
            for (k, s) in g.steps.iter().enumerate() {
                let a = net.step(&s.obs).expect("step");
                let d = max_abs_diff(&a, &s.action);
                assert!(d <= FORWARD_TOL, "step {k}: |ours - numpy| = {d:e}");
                worst = worst.max(d);
            }
            // The sequence exercises the recurrent state: a fresh LSTM on the last input answers differently.
            let last = g.steps.last().expect("steps");
            let mut fresh = LstmPolicy::load(&spec.model_path, LstmInitialState::Stored).expect("LSTM loads");
            let a = fresh.step(&last.obs).expect("step");
            assert!(max_abs_diff(&a, &last.action) > 1e-2, "recurrent state has no effect on this sequence");
        }
        other => panic!("unknown policy {other}"),
    }
    eprintln!("{}: forward pass, {} steps, max |diff| {worst:e}", g.policy, g.steps.len());
}

/// Robot state → observation → action → PD targets, through the controller built from the shipped spec.
fn check_controller(g: &Golden, spec: PolicySpec) {
    assert!((spec.control_period - g.control_period).abs() < 1e-12);
    let mut ctl = PolicyController::from_spec(spec).expect("controller builds");
    ctl.reset();
    let (mut worst_obs, mut worst_q) = (0.0f64, 0.0f64);
    for (k, s) in g.steps.iter().enumerate() {
        let obs = RobotObservation {
            time: s.time,
            base_quat: s.base_quat,
            base_ang_vel: s.base_ang_vel,
            q: s.q.clone(),
            dq: s.dq.clone(),
            command: s.command,
        };
        let t = ctl.act(&obs).unwrap_or_else(|e| panic!("step {k}: {e}"));
        let d_obs = max_abs_diff(ctl.last_observation(), &s.obs);
        assert!(d_obs <= OBS_TOL, "step {k}: observation differs from the oracle's by {d_obs:e}");
        let d_act = max_abs_diff(ctl.last_action(), &s.action);
        assert!(d_act <= FORWARD_TOL, "step {k}: action differs by {d_act:e}");
        let d_q = max_abs_diff(&t.q_des, &s.q_des);
        assert!(d_q <= FORWARD_TOL, "step {k}: q_des differs by {d_q:e}");
        assert!(t.dq_des.iter().chain(&t.tau_ff).all(|&v| v == 0.0));
        worst_obs = worst_obs.max(d_obs);
        worst_q = worst_q.max(d_q);
    }
    eprintln!("{}: controller, max |obs diff| {worst_obs:e}, max |q_des diff| {worst_q:e}", g.policy);
}

fn committed_dir() -> PathBuf {
    root().join("corpus/golden/policies")
}

#[test]
fn onnx_forward_matches_onnxruntime() {
    if shared().is_none() {
        return;
    }
    check_forward(&read_golden(&committed_dir(), "gepetto_demo_rsl"), &spec("gepetto_demo_rsl"));
}

#[test]
fn lstm_forward_matches_numpy() {
    if shared().is_none() {
        return;
    }
    check_forward(&read_golden(&committed_dir(), "unitree_rl_gym_lstm"), &spec("unitree_rl_gym_lstm"));
}

#[test]
fn gepetto_controller_matches_oracle() {
    if shared().is_none() {
        return;
    }
    check_controller(&read_golden(&committed_dir(), "gepetto_demo_rsl"), spec("gepetto_demo_rsl"));
}

#[test]
fn unitree_lstm_controller_matches_oracle() {
    if shared().is_none() {
        return;
    }
    check_controller(&read_golden(&committed_dir(), "unitree_rl_gym_lstm"), spec("unitree_rl_gym_lstm"));
}

#[test]
fn golden_files_are_small_sequences() {
    for policy in ["gepetto_demo_rsl", "unitree_rl_gym_lstm"] {
        let path = committed_dir().join(format!("{policy}.json"));
        let len = std::fs::metadata(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).len();
        assert!(len < 300_000, "{} is {len} bytes", path.display());
        let g = read_golden(&committed_dir(), policy);
        assert!(g.steps.len() >= 10, "{policy}: a sequence, not a single step");
    }
}

/// Re-runs the oracle live: its fresh output must equal the committed files and our code must match it.
#[test]
fn live_oracle_agrees() {
    let Some(python) = std::env::var("ULAB_PYTHON").ok().filter(|s| !s.is_empty()) else {
        eprintln!("SKIP: ULAB_PYTHON is not set (the live oracle needs numpy and onnxruntime)");
        return;
    };
    if shared().is_none() {
        return;
    }
    let out = std::env::temp_dir().join(format!("policy-oracle-{}", std::process::id()));
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/oracle/policy_oracle.py");
    let status = std::process::Command::new(&python)
        .arg(&script)
        .arg("--out")
        .arg(&out)
        .status()
        .unwrap_or_else(|e| panic!("cannot run {python}: {e}"));
    assert!(status.success(), "oracle failed: {status}");
    for policy in ["gepetto_demo_rsl", "unitree_rl_gym_lstm"] {
        let fresh = read_golden(&out, policy);
        let committed = read_golden(&committed_dir(), policy);
        assert_eq!(fresh.model_sha256, committed.model_sha256, "{policy}: model changed since the golden data");
        assert_eq!(fresh.steps.len(), committed.steps.len(), "{policy}: regenerate corpus/golden/policies");
        for (k, (f, c)) in fresh.steps.iter().zip(&committed.steps).enumerate() {
            let same_inputs = f.time == c.time
                && f.base_quat == c.base_quat
                && f.base_ang_vel == c.base_ang_vel
                && f.q == c.q
                && f.dq == c.dq
                && f.command == c.command;
            assert!(same_inputs, "{policy} step {k}: oracle inputs changed; regenerate corpus/golden/policies");
            let d = max_abs_diff(&f.obs, &c.obs).max(max_abs_diff(&f.action, &c.action));
            assert!(d <= 1e-6, "{policy} step {k}: oracle output changed by {d:e}; regenerate corpus/golden/policies");
        }
        check_forward(&fresh, &spec(policy));
        check_controller(&fresh, spec(policy));
    }
    let _ = std::fs::remove_dir_all(&out);
}
