//! Engine divergence: fuzz bytes (via `arbitrary`) become a short perturbation of the built-in excitation
//! rollout (command, noise, push, initial offsets, ground friction, timing jitter), run in MuJoCo (lead) and
//! Rapier multibody; coverage comes from Rapier's Rust code. The oracle is the per-engine invariants plus the
//! one-step cross-engine bound, with the allow-list of expected modelling differences applied
//! (`engine_diff::fuzz::oracle_findings`): anything left is a candidate engine bug and aborts.
#![no_main]

use diff_physics::{CommonSettings, Engine, EngineKind};
use engine_diff::harness::{self, excitation_factory, ControllerFactory, HarnessConfig};
use engine_diff::scenario::FuzzPerturbation;
use engine_diff::triage::AllowList;
use libfuzzer_sys::fuzz_target;
use robot_model::RobotModel;
use std::cell::RefCell;

/// Engines are built once per ground friction and reset per input (`Engine::reset` is a true reset).
struct World {
    model: RobotModel,
    allow: AllowList,
    ctrl: Box<ControllerFactory>,
    names: Vec<String>,
    friction_bits: Option<u64>,
    engines: Vec<Box<dyn Engine>>,
}

thread_local! {
    static WORLD: RefCell<Option<World>> = const { RefCell::new(None) };
}

const KINDS: [EngineKind; 2] = [EngineKind::Mujoco, EngineKind::RapierMultibody];

fn build(m: &RobotModel) -> Vec<Box<dyn Engine>> {
    KINDS.iter().map(|&k| diff_physics::make_engine(k, m, &CommonSettings::default()).expect("engine builds")).collect()
}

fuzz_target!(|p: FuzzPerturbation| {
    // 40 ms: two 50 Hz control ticks, two windows of 10 steps.
    let s = p.scenario(0.04);
    WORLD.with(|w| {
        let mut w = w.borrow_mut();
        let world = w.get_or_insert_with(|| {
            let model = RobotModel::h1_2().expect("built-in model");
            let engines = build(&model);
            World {
                allow: AllowList::builtin().expect("allow-list"),
                ctrl: excitation_factory(&model),
                names: KINDS.iter().map(|k| k.name().to_string()).collect(),
                friction_bits: None,
                engines,
                model,
            }
        });
        let m = harness::scenario_model(&world.model, &s);
        let key = s.ground_friction.map(f64::to_bits);
        if key != world.friction_bits {
            world.engines = build(&m);
            world.friction_bits = key;
        }
        let cfg = HarnessConfig { window_steps: 10, free_runs: false, ..HarnessConfig::default() };
        let r = harness::run_episode_on(&mut world.engines, &world.names, &m, world.ctrl.as_ref(), &s, &cfg)
            .unwrap_or_else(|e| panic!("engine failed on a valid input: {e}\n{s:?}"));
        let bad = engine_diff::fuzz::oracle_findings(&r, &world.allow);
        assert!(bad.is_empty(), "candidate engine bug: {bad:#?}\nscenario: {s:?}");
    });
});
