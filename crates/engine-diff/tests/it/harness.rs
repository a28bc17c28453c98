//! Harness properties that do not depend on what the engines happen to produce: determinism (an engine
//! compared with itself diverges by exactly zero), metric plumbing (a known injected offset is measured on
//! the right joint), bit-exact reproducers (and a tampered one is caught), allow-list hygiene.
use diff_physics::{CommonSettings, Engine, EngineError, EngineKind, State};
use engine_diff::harness::{self, excitation_factory, BuiltinEngine, EngineFactory, HarnessConfig};
use engine_diff::repro::Reproducer;
use engine_diff::scenario::Scenario;
use engine_diff::triage::{AllowList, Minimized};
use robot_model::RobotModel;
use std::sync::Arc;

fn model() -> RobotModel {
    RobotModel::h1_2().expect("built-in model")
}

fn cfg(window: usize) -> HarnessConfig {
    HarnessConfig { window_steps: window, free_runs: false, ..HarnessConfig::default() }
}

#[test]
fn an_engine_compared_with_itself_diverges_by_exactly_zero() {
    let m = model();
    for kind in [EngineKind::Mujoco, EngineKind::RapierImpulse] {
        let f: Vec<Arc<dyn EngineFactory>> = vec![Arc::new(BuiltinEngine(kind)), Arc::new(BuiltinEngine(kind))];
        let ctrl = excitation_factory(&m);
        let r = harness::run_episode(&m, &f, ctrl.as_ref(), &Scenario::excitation(7, 0.1), &cfg(10)).expect("episode");
        assert_eq!(r.windows.len(), 5);
        for w in &r.windows {
            for d in &w.divs {
                for div in [&d.one_step, &d.k_step] {
                    let all = div.q.iter().chain(&div.dq).chain(&div.link_pos).chain([
                        &div.base_pos,
                        &div.base_rot,
                        &div.base_lin_vel,
                        &div.base_ang_vel,
                    ]);
                    assert!(all.into_iter().all(|x| *x == 0.0), "{} window {}: {div:?}", kind.name(), w.index);
                }
            }
        }
        assert!(r.findings.iter().all(|f| f.kind == "invariant"), "{:?}", r.findings);
    }
}

/// MuJoCo, except that it reports joint `J` off by `OFF` rad.
#[derive(Debug)]
struct Offset(Box<dyn Engine>);
const J: usize = 3;
const OFF: f64 = 0.01;

impl Engine for Offset {
    fn name(&self) -> &'static str {
        "offset"
    }
    fn version(&self) -> String {
        "test".into()
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::Value::Null
    }
    fn step(&mut self, tau: &[f64]) -> Result<(), EngineError> {
        self.0.step(tau)
    }
    fn state(&self) -> State {
        let mut s = self.0.state();
        s.q[J] += OFF;
        s
    }
    delegate_engine!(0);
}

#[derive(Debug)]
struct OffsetFactory;
impl EngineFactory for OffsetFactory {
    fn name(&self) -> String {
        "offset".into()
    }
    fn build(&self, model: &RobotModel, common: &CommonSettings) -> Result<Box<dyn Engine>, EngineError> {
        Ok(Box::new(Offset(diff_physics::make_engine(EngineKind::Mujoco, model, common)?)))
    }
}

#[test]
fn a_known_joint_offset_is_measured_on_that_joint() {
    let m = model();
    let f: Vec<Arc<dyn EngineFactory>> = vec![Arc::new(BuiltinEngine(EngineKind::Mujoco)), Arc::new(OffsetFactory)];
    let ctrl = excitation_factory(&m);
    let s = Scenario {
        obs_noise: 0.0,
        action_noise: 0.0,
        timing_jitter: 0,
        pushes: vec![],
        ..Scenario::excitation(3, 0.02)
    };
    let r = harness::run_episode(&m, &f, ctrl.as_ref(), &s, &cfg(10)).expect("episode");
    let d = &r.windows[0].divs[0].one_step;
    // The reported offset, plus the one-step effect of the PD reacting to it: Δτ = kp·OFF over one step moves
    // the joint by ≲ kp·OFF·dt²/I ≈ 200·0.01·4e-6/0.05 ≈ 2e-4 rad, i.e. ≤ 2% of OFF.
    assert!((d.q[J] - OFF).abs() < 0.02 * OFF, "joint {J}: {}", d.q[J]);
    for (i, x) in d.q.iter().enumerate() {
        if i != J {
            assert!(*x < 0.05 * OFF, "joint {i}: {x}");
        }
    }
}

#[test]
fn reproducers_replay_bit_for_bit_and_catch_tampering() {
    let m = model();
    let f: Vec<Arc<dyn EngineFactory>> =
        vec![Arc::new(BuiltinEngine(EngineKind::Mujoco)), Arc::new(BuiltinEngine(EngineKind::RapierImpulse))];
    let ctrl = excitation_factory(&m);
    let s = Scenario::excitation(11, 0.06);
    let c = cfg(10);
    let r = harness::run_episode(&m, &f, ctrl.as_ref(), &s, &c).expect("episode");
    let w = &r.windows[2];
    let finding = harness::Finding {
        kind: "k_step_bound".into(),
        engine: "rapier_impulse".into(),
        lead: "mujoco".into(),
        quantity: "link position".into(),
        value: 0.0,
        bound: 1.0,
        window: 2,
        t0: w.t0,
        phase: w.phase,
        contact_bodies: w.contact_bodies.len(),
    };
    let min = Minimized { scale: 1.0, scenario: s.clone(), finding, window: w.input.clone(), steps: 10 };
    let repro = Reproducer::new(&m, &f, &c.common, "excitation", &min).expect("reproducer");
    // The value is the k-step link divergence the episode measured for that window.
    assert_eq!(repro.expected.value, w.divs[0].k_step.max_link());
    let text = serde_json::to_string(&repro).expect("json");
    let back: Reproducer = serde_json::from_str(&text).expect("parse");
    assert_eq!(back.window.start.state().expect("state"), w.input.start);
    let o = back.replay(&m).expect("replay");
    assert!(o.identical, "{:?}", o.mismatches);
    let mut bad = back.clone();
    let x = &mut bad.expected.states[1].qvel[8];
    *x = format!("{:016x}", u64::from_str_radix(x, 16).expect("hex") ^ 1);
    let o = bad.replay(&m).expect("replay");
    assert!(!o.identical && o.mismatches.iter().any(|m| m.contains("rapier_impulse")), "{:?}", o.mismatches);
}

#[test]
fn allow_list_entries_have_rationale_and_citations() {
    let a = AllowList::builtin().expect("allow-list parses");
    assert!(!a.entries.is_empty());
    let no_cite = r#"[[entry]]
id = "x"
engines = ["rapier_impulse"]
kinds = ["invariant"]
max_ratio = 2.0
rationale = "a rationale that is long enough to pass the length check"
citation = []
"#;
    assert!(AllowList::parse(no_cite).is_err());
    assert!(AllowList::parse(&no_cite.replace("[]", "[\"http://insecure\"]")).is_err());
    assert!(AllowList::parse(&no_cite.replace("[]", "[\"https://example.org\"]")).is_ok());
    assert!(
        AllowList::parse(&no_cite.replace("invariant", "anything").replace("[]", "[\"https://example.org\"]")).is_err()
    );
}
