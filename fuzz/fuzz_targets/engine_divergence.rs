//! Engine divergence: fuzz bytes (via `arbitrary`) become a short perturbation of the built-in excitation
//! rollout (command, noise, push, initial offsets, ground friction, timing jitter) and a choice of one pair of the
//! engines compiled into this target (MuJoCo, both Rapier formulations, Bullet and DART: any two, the earlier of
//! `EngineKind::ALL` leading; `engine_diff::fuzz::oracle_pair`); coverage comes from the Rust code on the path
//! (Rapier's, the harness's). The oracle is the per-engine invariants plus the one-step cross-engine bound, with
//! the allow-list of expected modelling differences applied (directly for pairs with MuJoCo, through MuJoCo for
//! the others: `engine_diff::triage::AllowList::covering`; `engine_diff::fuzz::DivergenceOracle`, which `cargo
//! test -p engine-diff` also replays the saved inputs through): anything left is a candidate engine bug and
//! aborts. PhysX stays out of this build (its vendored SDK would double the fuzz build time); it runs in `ulab
//! diff fuzz`.
#![no_main]

use engine_diff::fuzz::DivergenceOracle;
use engine_diff::scenario::FuzzPerturbation;
use libfuzzer_sys::fuzz_target;
use std::cell::RefCell;

thread_local! {
    static ORACLE: RefCell<Option<DivergenceOracle>> = const { RefCell::new(None) };
}

fuzz_target!(|p: FuzzPerturbation| {
    ORACLE.with(|o| {
        let mut o = o.borrow_mut();
        let oracle = o.get_or_insert_with(|| DivergenceOracle::h1_2().expect("built-in model, engines and allow-list"));
        let bad = oracle.check(&p).unwrap_or_else(|e| {
            panic!("engine failed on a valid input: {e}\n{:?}", p.scenario(engine_diff::fuzz::ORACLE_SECONDS))
        });
        assert!(
            bad.is_empty(),
            "candidate engine bug: {bad:#?}\nscenario: {:?}",
            p.scenario(engine_diff::fuzz::ORACLE_SECONDS)
        );
    });
});
