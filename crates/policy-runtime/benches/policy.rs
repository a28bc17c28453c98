//! Time per policy call: the network alone (ONNX MLP 270→12 via tract; LSTM 47→12 from arrays) and the whole
//! controller step (observation + history + network + PD targets for 27 slots). A policy runs at 50 Hz, so
//! anything under a millisecond leaves the 20 ms budget to the physics and the transport.
//!
//! Run: `source scripts/env.sh && CARGO_TARGET_DIR=target-model cargo bench -p policy-runtime --bench policy`
//! (needs `ULAB_SHARED` for the reference policies).
use criterion::{criterion_group, criterion_main, Criterion};
use policy_runtime::{
    Controller, LstmInitialState, LstmPolicy, OnnxPolicy, PolicyController, PolicySpec, RobotObservation,
};
use std::hint::black_box;
use std::path::PathBuf;

fn spec(name: &str) -> PolicySpec {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../../robots/h1_2/policies/{name}.toml"));
    PolicySpec::load(&p).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn observation(spec: &PolicySpec, k: usize) -> RobotObservation {
    let s = (k as f64 * 0.37).sin();
    RobotObservation {
        time: k as f64 * 0.02,
        base_quat: [1.0, 0.01 * s, -0.02 * s, 0.0],
        base_ang_vel: [0.1 * s, -0.2 * s, 0.05],
        q: spec.joints.iter().map(|j| j.default_q + 0.05 * s).collect(),
        dq: vec![0.3 * s; spec.nj()],
        command: [0.5, 0.0, 0.0],
    }
}

fn bench(c: &mut Criterion) {
    if std::env::var("ULAB_SHARED").map_or(true, |s| s.is_empty()) {
        eprintln!("SKIP: ULAB_SHARED is not set");
        return;
    }
    let g = spec("gepetto_demo_rsl");
    let onnx = OnnxPolicy::load(&g.model_path).expect("onnx");
    let x: Vec<f32> = (0..270).map(|i| ((i as f32) * 0.1).sin() * 0.5).collect();
    c.bench_function("onnx_mlp_270_forward", |b| b.iter(|| onnx.forward(black_box(&x)).expect("forward")));

    let u = spec("unitree_rl_gym_lstm");
    let mut lstm = LstmPolicy::load(&u.model_path, LstmInitialState::Stored).expect("lstm");
    let x: Vec<f32> = (0..47).map(|i| ((i as f32) * 0.1).sin() * 0.5).collect();
    c.bench_function("lstm_47_step", |b| b.iter(|| lstm.step(black_box(&x)).expect("step")));

    for s in [g, u] {
        let name = format!("controller_act_{}", s.name);
        let obs: Vec<RobotObservation> = (0..64).map(|k| observation(&s, k)).collect();
        let mut ctl = PolicyController::from_spec(s).expect("controller");
        let mut k = 0;
        c.bench_function(&name, |b| {
            b.iter(|| {
                k = (k + 1) % obs.len();
                ctl.act(black_box(&obs[k])).expect("act")
            })
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
