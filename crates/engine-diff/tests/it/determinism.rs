//! Bit-for-bit reproducibility (issue 62, item 3): every engine of this build hashes the fixed episode of
//! `engine_diff::determinism` identically on one worker thread and on two (engines running beside each other), and
//! as the committed table `corpus/determinism/h1_2.json` says — the table was written by another process of an
//! earlier build (`ulab diff hash --write`), and `diff_cli::hash_table_*` checks it again from the CLI's process.
//!
//! What this proves is repetition (across thread counts, processes, commits and machines of one class), not
//! correctness: the table is this project's own measurement. Whether the engines agree with each other is the
//! differential harness's question. When an engine's numerics change on purpose (a new library version, a fixed
//! model), the table is rewritten with `ulab diff hash --write corpus/determinism/h1_2.json` and the reason goes
//! in the CHANGELOG.
use diff_physics::EngineKind;
use engine_diff::determinism::{compare, hash_table, Comparison, HashTable, Probe};
use engine_diff::harness::{builtin_factories, excitation_factory};
use std::path::PathBuf;

fn committed_table() -> HashTable {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../corpus/determinism/h1_2.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).expect("the committed table parses")
}

#[test]
fn every_engine_repeats_its_hash_on_any_thread_count_and_as_the_committed_table() {
    let table = committed_table();
    // The engines CI builds must all be in the table: an entry dropped would silently stop being checked.
    for name in ["mujoco", "rapier_multibody", "rapier_impulse", "bullet", "dart"] {
        assert!(table.engines.iter().any(|e| e.engine == name), "{name} is missing from the committed table");
    }
    let model = robot_model::builtin("h1_2").expect("built-in model");
    let names: Vec<String> = EngineKind::available().iter().map(|k| k.name().to_string()).collect();
    let factories = builtin_factories(&names).expect("engines of this build");
    let ctrl = excitation_factory(&model);
    let one = hash_table(&factories, "h1_2", &model, ctrl.as_ref(), Probe::default(), 1).expect("one thread");
    let two = hash_table(&factories, "h1_2", &model, ctrl.as_ref(), Probe::default(), 2).expect("two threads");
    assert_eq!(one, two, "hashes depend on the thread count");
    for e in &one.engines {
        assert!(e.steps > 0, "{}: no step ran", e.engine);
    }
    for (engine, c) in compare(&table, &one).expect("same probe") {
        match c {
            Comparison::Reproduced => {}
            // Another machine class may round differently; the run says so instead of passing or failing.
            Comparison::NotCompared { why } if table.machine != one.machine => {
                eprintln!("{engine}: not compared: {why}")
            }
            // Engines outside the table (PhysX, Newton in feature builds) are not part of the committed check.
            Comparison::NotCompared { why } if !table.engines.iter().any(|t| t.engine == engine) => {
                eprintln!("{engine}: not compared: {why}")
            }
            other => panic!(
                "{engine}: {other:?}; if the change is intended, rewrite the table with `ulab diff hash --write \
                 corpus/determinism/h1_2.json` and give the reason in CHANGELOG.md"
            ),
        }
    }
}
