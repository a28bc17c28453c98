//! Replays every saved `engine_divergence` fuzz input (`fuzz/corpus/engine_divergence/regressions/`: inputs
//! that once aborted the target, named for what they exercise; `fuzz/corpus/engine_divergence/seeds/`: the seeds;
//! not the inputs a local `cargo fuzz run` wrote beside them)
//! through the oracle the fuzz target runs, decoding the bytes the way libFuzzer's typed entry point does. Each
//! input runs on every pair the target can choose in this build (every pair of its engines; an input
//! chooses one pair when fuzzing; inputs saved before that choice existed were found on MuJoCo against Rapier
//! multibody), so the corpus exercises every engine.

use arbitrary::{Arbitrary, Unstructured};
use engine_diff::fuzz::{oracle_pair, oracle_pairs, DivergenceOracle};
use engine_diff::scenario::FuzzPerturbation;
use std::path::Path;

#[test]
fn engine_divergence_inputs_raise_no_candidate_bug() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus/engine_divergence");
    let mut oracle = DivergenceOracle::h1_2().expect("built-in oracle");
    let allow = engine_diff::triage::AllowList::builtin().expect("allow-list");
    // Largest ratio to its bound per (lead, engine, kind, quantity, phase) over every input: the figures the
    // allow-list's caps for touch-down inputs are set from (printed with --nocapture).
    let mut largest: std::collections::BTreeMap<
        (String, String, String, String, engine_diff::phase::ContactPhase),
        (f64, String),
    > = Default::default();
    let (mut regressions, mut seeds) = (0, 0);
    let mut failures = Vec::new();
    for (dir, count) in [(root.join("regressions"), &mut regressions), (root.join("seeds"), &mut seeds)] {
        let mut paths: Vec<_> =
            std::fs::read_dir(&dir).expect("corpus folder").map(|e| e.expect("entry").path()).collect();
        paths.sort();
        for path in paths.iter().filter(|p| p.is_file() && p.extension().is_none_or(|e| e != "md")) {
            let bytes = std::fs::read(path).expect("read");
            let p = FuzzPerturbation::arbitrary_take_rest(Unstructured::new(&bytes)).expect("any bytes decode");
            let own = oracle_pair(p.engines).expect("two engines");
            for pair in oracle_pairs() {
                let all = oracle
                    .findings_on_pair(&p, pair)
                    .unwrap_or_else(|e| panic!("{} on {pair:?}: engine failed: {e}", path.display()));
                for f in &all {
                    let key = (f.lead.clone(), f.engine.clone(), f.kind.clone(), f.quantity.clone(), f.phase);
                    let worst = largest.entry(key).or_insert((0.0, String::new()));
                    if f.ratio() > worst.0 {
                        *worst =
                            (f.ratio(), path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default());
                    }
                }
                let bad: Vec<_> = all.into_iter().filter(|f| allow.covering(f).is_none()).collect();
                if !bad.is_empty() {
                    failures.push(format!(
                        "{} on {pair:?} (the input chooses {own:?}): candidate engine bug {bad:#?}\n{:?}",
                        path.display(),
                        p.scenario(engine_diff::fuzz::ORACLE_SECONDS)
                    ));
                }
            }
            *count += 1;
        }
    }
    for ((lead, engine, kind, quantity, phase), (ratio, input)) in &largest {
        println!("{lead:>16} {engine:>16} {kind:>14} {quantity:>24} {phase:>7}: largest ratio {ratio:.2} ({input})");
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(regressions > 0 && seeds > 0, "expected saved inputs, found {regressions} regressions and {seeds} seeds");
}
