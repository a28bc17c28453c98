//! Bit-for-bit reproducibility (issue 62, item 3): every engine of this build hashes the fixed episode of
//! `engine_diff::determinism` identically on one worker thread and on two (engines running beside each other), and
//! as the committed table of this machine class in `corpus/determinism/` says — the tables were written by another
//! process of an earlier build (`ulab diff hash --write`), and `diff_cli::hash_table_*` checks them again from the
//! CLI's process. A table's entries for engines this build lacks (PhysX and Newton are feature builds) are not
//! compared; a feature build checks them.
//!
//! What this proves is repetition (across thread counts, processes, commits and machines of one class), not
//! correctness: the tables are this project's own measurement. Whether the engines agree with each other is the
//! differential harness's question. When an engine's numerics change on purpose (a new library version, a fixed
//! model), the table is rewritten with `ulab diff hash --write corpus/determinism/FILE.json` and the reason goes
//! in the CHANGELOG.
use diff_physics::EngineKind;
use engine_diff::determinism::{compare, hash_table, read_tables, table_for, Comparison, HashTable, Probe};
use engine_diff::harness::{builtin_factories, excitation_factory};
use std::path::PathBuf;

/// The committed tables, one per machine class the hashes were measured on.
fn committed_tables() -> Vec<HashTable> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../corpus/determinism");
    read_tables(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
}

#[test]
fn every_engine_repeats_its_hash_on_any_thread_count_and_as_the_committed_table() {
    let tables = committed_tables();
    // The engines CI builds must be in every table: an entry dropped would silently stop being checked.
    for t in &tables {
        for name in ["mujoco", "rapier_multibody", "rapier_impulse", "bullet", "dart"] {
            assert!(t.engines.iter().any(|e| e.engine == name), "{name} is missing from the table for {}", t.machine);
        }
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
    // Another machine class may round differently: without a table for this one the run says so instead of
    // passing or failing.
    let Some(table) = table_for(&tables, "h1_2", &one.machine) else {
        let measured: Vec<String> = tables.iter().map(|t| t.machine.to_string()).collect();
        eprintln!("no committed table for {}: not compared (tables for {measured:?})", one.machine);
        return;
    };
    for (engine, c) in compare(table, &one).expect("same probe") {
        let hashed = one.engines.iter().any(|e| e.engine == engine);
        let in_table = table.engines.iter().any(|t| t.engine == engine);
        match c {
            Comparison::Reproduced => {}
            // Engines outside the table (an engine never measured on this class), and entries for engines not in
            // this build (PhysX, Newton in CI), are not part of this build's check.
            Comparison::NotCompared { why } if !hashed || !in_table => eprintln!("{engine}: not compared: {why}"),
            other => panic!(
                "{engine}: {other:?}; if the change is intended, rewrite the table with `ulab diff hash --write \
                 corpus/determinism/FILE.json` and give the reason in CHANGELOG.md"
            ),
        }
    }
}
