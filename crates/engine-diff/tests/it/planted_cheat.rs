//! Issue 15, item 3: the validation verdict on a controller whose cheat is known by construction. A small
//! parameterised gait ([`engine_diff::gait`], 16 parameters) is optimised for forward speed in ONE engine (the
//! cross-entropy method, scored by the validation's own task score for the forward command, on seeds 101-102
//! that the validation does not use); nothing in its search rewards working anywhere else. With that engine as
//! the training engine, the verdict must flag the engines where the gait does not work, with evidence.
//!
//! The training engine of the cheat is Rapier with impulse joints: maximal coordinates, joints held by
//! constraints that give a little (the formulation whose defects issue 5 documents), so a gait tuned to it can
//! lean on that give. The independent counterparts are MuJoCo, DART and Bullet (Featherstone): other code, other
//! joint formulations, other contact models. The control (nightly): the same search in MuJoCo gives a gait that
//! transfers to DART and Bullet, so the verdict does not simply flag every open-loop gait.
use diff_physics::EngineKind;
use engine_diff::gait::{fitness, optimise, GaitController, GaitOptimum, GaitParams, GaitSearchConfig};
use engine_diff::harness::{builtin_factories, HarnessConfig};
use engine_diff::triage::AllowList;
use engine_diff::validate::{standard_commands, validate, ValidateSetup, ValidationReport, Verdict};
use robot_model::RobotModel;

/// Validation seeds (the search used 101 and 102).
const SEEDS: [u64; 6] = [1, 2, 3, 4, 5, 6];

/// Optimises the gait in `train` and validates it there and in every available engine of `others`.
fn optimise_and_validate(train: &str, others: &[&str], rng_seed: u64) -> (GaitOptimum, ValidationReport) {
    let model = RobotModel::h1_2().expect("model");
    let cfg = HarnessConfig::default();
    let forward = standard_commands().into_iter().find(|c| c.name == "forward").expect("forward command");
    let train_f = builtin_factories(&[train.to_string()]).expect("training engine");
    let search = GaitSearchConfig { rng_seed, ..GaitSearchConfig::default() };
    let opt = optimise(&model, train_f[0].as_ref(), &forward, &search, &cfg).expect("search");
    let mut names = vec![train.to_string()];
    names.extend(others.iter().filter(|e| EngineKind::parse_available(e).is_ok()).map(|e| e.to_string()));
    let factories = builtin_factories(&names).expect("engines");
    let ctrl = GaitController::factory(&model, opt.params.clone()).expect("gait");
    let allow = AllowList::builtin().expect("allow-list");
    let r = validate(&ValidateSetup {
        model: &model,
        factories: &factories,
        train_engine: train,
        controller: ctrl.as_ref(),
        controller_name: &format!("gait optimised in {train}"),
        commands: std::slice::from_ref(&forward),
        seeds: &SEEDS,
        seconds: search.seconds,
        cfg: &cfg,
        allow: &allow,
        evidence: true,
    })
    .expect("validation");
    println!(
        "search in {train} (rng seed {rng_seed}): {} episodes, best fitness per iteration {:.3?}\nθ = {:.3?}\n{}",
        opt.episodes,
        opt.history,
        opt.params.theta,
        r.markdown()
    );
    (opt, r)
}

#[test]
fn a_gait_optimised_in_rapier_impulse_is_flagged_in_the_independent_engines() {
    // The standing pattern (θ = 0) in the training engine: what the search must beat.
    let model = RobotModel::h1_2().expect("model");
    let forward = standard_commands().into_iter().find(|c| c.name == "forward").expect("forward command");
    let train_f = builtin_factories(&["rapier_impulse".to_string()]).expect("engine");
    let standing = fitness(
        &model,
        train_f[0].as_ref(),
        &GaitParams::standing(),
        &forward,
        &GaitSearchConfig::default(),
        &HarnessConfig::default(),
    )
    .expect("standing fitness");
    println!("standing pattern: fitness {standing:.3}");
    // A search whose gait also falls in half of its own validation episodes gets "inconclusive" (measured for search
    // seed 8, see BENCHMARKS.md): the verdict rightly refuses to blame other engines then, and the next search seed
    // is tried. Seeds 7 and 9 gave a gait that mostly stays up in its engine.
    for rng_seed in [7, 9, 8] {
        let (opt, r) = optimise_and_validate("rapier_impulse", &["mujoco", "dart", "bullet"], rng_seed);
        let md = r.markdown();
        assert!(
            opt.history.windows(2).all(|w| w[1] >= w[0]) && opt.fitness > standing + 0.1,
            "{:?}\n{md}",
            opt.history
        );
        let train = r.engines.iter().find(|e| e.verdict == Verdict::TrainingEngine).expect("training engine row");
        let others: Vec<_> = r.engines.iter().filter(|e| e.verdict != Verdict::TrainingEngine).collect();
        assert!(!others.is_empty(), "MuJoCo is always built");
        if train.fall_rate >= 0.5 {
            assert!(others.iter().all(|e| e.verdict == Verdict::Inconclusive), "{md}");
            println!("search seed {rng_seed}: the gait falls in its own engine too; verdict inconclusive, next seed");
            continue;
        }
        for e in &others {
            assert!(matches!(e.verdict, Verdict::Fails | Verdict::Degrades), "{} not flagged\n{md}", e.engine);
            let ev = e.evidence.as_ref().unwrap_or_else(|| panic!("{} flagged without evidence\n{md}", e.engine));
            assert!(!ev.phase.is_empty() && !ev.joint.is_empty(), "{md}");
        }
        assert_eq!(r.flagged().len(), others.len(), "{md}");
        assert!(!md.contains("**Transfers**") && md.contains("Where it degrades"), "{md}");
        // With every other engine flagging it, the report points at the training engine's own modelling.
        if others.len() >= 2 {
            assert!(r.train_known_differences.iter().any(|d| d == "impulse-joint-compliance"), "{md}");
            assert!(md.contains("every other engine") && md.contains("impulse-joint-compliance"), "{md}");
        }
        return;
    }
    panic!("no search produced a gait that stays up in its own engine");
}

/// The control: the same search in MuJoCo. Measured (2026-11-23, rng seed 7): score 0.845 in MuJoCo, 0.831 in
/// DART, 0.834 in Bullet, no falls: it transfers, so the flag above is about the training engine, not about
/// open-loop gaits. Nightly (it adds half a minute of CPU and proves the negative direction, which
/// `validate_verdict.rs` already covers with the shipped LSTM policy in DART).
#[test]
#[ignore = "nightly: control of the planted cheat (gait optimised in MuJoCo transfers)"]
fn a_gait_optimised_in_mujoco_transfers() {
    let (_, r) = optimise_and_validate("mujoco", &["dart", "bullet"], 7);
    let md = r.markdown();
    assert!(r.flagged().is_empty(), "{md}");
    assert!(r.engines.iter().all(|e| e.fall_rate == 0.0), "{md}");
}

/// Experiment (prints, asserts nothing): how often the search in each engine yields a gait flagged elsewhere,
/// over search seeds. Summary in BENCHMARKS.md "Validation".
#[test]
#[ignore = "experiment: planted cheat over search seeds and training engines"]
fn planted_cheat_over_search_seeds() {
    let all = ["mujoco", "rapier_impulse", "rapier_multibody", "dart", "bullet"];
    let train: Vec<String> = std::env::var("ULAB_CHEAT_TRAIN")
        .map(|v| v.split(',').map(str::to_string).collect())
        .unwrap_or_else(|_| vec!["mujoco".into(), "rapier_impulse".into()]);
    for t in &train {
        for seed in [7, 8, 9] {
            let others: Vec<&str> = all.iter().copied().filter(|e| e != t).collect();
            let (opt, r) = optimise_and_validate(t, &others, seed);
            let row: Vec<String> = r
                .engines
                .iter()
                .map(|e| {
                    format!(
                        "{} {:?} score {:.3} falls {:.0}%",
                        e.engine,
                        e.verdict,
                        e.score.map_or(f64::NAN, |s| s.mean),
                        100.0 * e.fall_rate
                    )
                })
                .collect();
            println!("SUMMARY train {t} seed {seed} fitness {:.3}: {}", opt.fitness, row.join("; "));
        }
    }
}
