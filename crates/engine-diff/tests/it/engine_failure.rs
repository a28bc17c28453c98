//! An engine that fails while the fuzzer runs it is the plainest engine bug there is, and the report must say so.
//!
//! Story (issue 63, item 3): `ulab diff fuzz --engines mujoco,newton-featherstone` on an H1-2 without armature
//! reached Newton issue #4269 on its first input — Featherstone went non-finite at t = 0.014 s — and then reported
//! "0 entries, no finding exceeded its bound": inputs on which an engine failed were counted on stdout and dropped.
//! The engine here is MuJoCo that reports a divergence from its 40th step on (what Newton's server does on a
//! non-finite state), under its own name; the lead is the unmodified MuJoCo.
use diff_physics::{CommonSettings, Engine, EngineError, EngineKind, State};
use engine_diff::fuzz::{fuzz, FuzzConfig};
use engine_diff::harness::{excitation_factory, BuiltinEngine, EngineFactory, HarnessConfig};
use engine_diff::report::{analyse, Analysis};
use engine_diff::scenario::Scenario;
use engine_diff::triage::AllowList;
use robot_model::RobotModel;
use std::sync::Arc;

/// Steps after which the engine fails (inside the first window of 50).
const FAILS_AFTER: usize = 40;

#[derive(Debug)]
struct Diverging(Box<dyn Engine>, usize);

impl Engine for Diverging {
    fn name(&self) -> &'static str {
        "diverging"
    }
    fn version(&self) -> String {
        format!("{} failing after {FAILS_AFTER} steps", self.0.version())
    }
    fn settings(&self) -> serde_json::Value {
        self.0.settings()
    }
    fn step(&mut self, tau: &[f64]) -> Result<(), EngineError> {
        if self.1 >= FAILS_AFTER {
            return Err(EngineError::Diverged(format!("non-finite state at t = {:.6} s", self.0.time())));
        }
        self.1 += 1;
        self.0.step(tau)
    }
    fn state(&self) -> State {
        self.0.state()
    }
    delegate_engine!(0);
}

#[derive(Debug)]
struct DivergingFactory;

impl EngineFactory for DivergingFactory {
    fn name(&self) -> String {
        "diverging".into()
    }
    fn build(&self, model: &RobotModel, common: &CommonSettings) -> Result<Box<dyn Engine>, EngineError> {
        Ok(Box::new(Diverging(diff_physics::make_engine(EngineKind::Mujoco, model, common)?, 0)))
    }
}

#[test]
fn an_engine_that_fails_on_an_input_is_reported_with_the_input() {
    let m = RobotModel::h1_2().expect("built-in model");
    let f: Vec<Arc<dyn EngineFactory>> = vec![Arc::new(BuiltinEngine(EngineKind::Mujoco)), Arc::new(DivergingFactory)];
    let ctrl = excitation_factory(&m);
    let cfg = HarnessConfig::default();
    let seeds = vec![Scenario::excitation(1, 0.3), Scenario::excitation(2, 0.3)];
    let fcfg = FuzzConfig { iterations: 2, batch: 2, seed: 1 };
    let o = fuzz(&m, &f, ctrl.as_ref(), &cfg, &fcfg, seeds.clone(), &|_| {}).expect("fuzzing");
    assert_eq!(o.failed, 2, "both inputs run past {FAILS_AFTER} steps");
    assert_eq!(o.failures.len(), 2);
    for (x, s) in o.failures.iter().zip(&seeds) {
        assert_eq!(x.engine, "diverging");
        assert_eq!(&x.scenario, s, "the failure keeps the input that caused it");
        assert!((x.t - FAILS_AFTER as f64 * cfg.common.timestep).abs() < 1e-9, "failed at {} s", x.t);
        assert!(x.error.contains("non-finite"), "{}", x.error);
    }
    let allow = AllowList::builtin().expect("allow-list");
    let a = Analysis {
        model: &m,
        factories: &f,
        controller: ctrl.as_ref(),
        controller_name: "excitation",
        cfg: &cfg,
        allow: &allow,
        minimize_limit: 0,
    };
    let (mut report, _) = analyse(&a, &o.episodes).expect("analysis");
    report.engine_failures = o.failures;
    let md = report.markdown();
    assert!(md.contains("## Engine failures") && md.contains("| diverging |"), "{md}");
    let json = serde_json::to_value(&report).expect("json");
    assert_eq!(json["engine_failures"].as_array().map(Vec::len), Some(2));
}
