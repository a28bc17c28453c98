//! The counterfactual plants of `ulab gap bench --counterfactuals`: a trial's plant without one of its hidden
//! effects, and what that effect shows to a perfect replay in the diagnosis's windows.

use super::common::model;
use gap_bench::{trial_config, trial_config_without, BenchOptions};
use gap_diagnosis::plant::Effects;

/// A pair trial without its first effect keeps the second one exactly, and without its second keeps the first;
/// a control has nothing to remove.
#[test]
fn removing_a_hidden_effect_keeps_the_other_and_nothing_else() {
    let m = model();
    let opts = BenchOptions::new(12, 9202, 4.0);
    let none = Effects::none(m.nj());
    let (trial, labels) = trial_config(&m, 2, &opts);
    assert_eq!(labels.injected.len(), 2, "trial 2 of the pattern is a pair");
    for (k, kept) in [(0, 1), (1, 0)] {
        let without = trial_config_without(&m, 2, &opts, k).expect("a pair has two effects");
        let (gone, stays) = (labels.injected[k].kind, labels.injected[kept].kind);
        for j in 0..m.nj() {
            assert_eq!(gone.get(&without.effects, j), gone.get(&none, j), "{} left on joint {j}", gone.name());
            assert_eq!(stays.get(&without.effects, j), stays.get(&trial.effects, j), "{} changed", stays.name());
        }
        assert_eq!(without.seed, trial.seed, "the same sensor noise and timing jitter");
    }
    assert!(trial_config_without(&m, 3, &opts, 0).is_none(), "trial 3 is a control");
}

/// A perfect replay sees a hidden latency: the plant with it and without it, started from the same logged state,
/// move apart in every window that has commands; with the effect not removed (the same plant twice) they would not.
#[test]
fn a_perfect_replay_sees_a_hidden_latency() {
    let m = model();
    let opts = BenchOptions::new(12, 9202, 4.0);
    let i = (0..12)
        .find(|&i| {
            let (_, labels) = trial_config(&m, i, &opts);
            labels.injected.len() == 1 && labels.injected[0].kind == gap_diagnosis::EffectKind::Latency
        })
        .expect("the first kinds cycle through the library, latency among them");
    let (cfg, _) = trial_config(&m, i, &opts);
    let log = gap_bench::generate_log_with(&m, &cfg, None).expect("trial log");
    let rows = gap_bench::oracle_differences(&m, i, &opts, &log, 0).expect("replays").expect("one effect");
    assert!(rows.len() >= 35, "about ten windows a second over 4 s: {}", rows.len());
    let moved = rows.iter().filter(|r| r.iter().sum::<f64>() > 1.0).count();
    assert!(moved * 10 >= rows.len() * 9, "{moved} of {} windows show the latency", rows.len());
}
