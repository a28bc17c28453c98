//! `report.md` for a fixed seed, pinned (figures printed to three significant digits). Same versions give
//! bit-identical runs; a changed snapshot means the engines, the harness or the report changed.
use engine_diff::harness::{self, builtin_factories, excitation_factory, HarnessConfig};
use engine_diff::report::{analyse, Analysis};
use engine_diff::scenario::Scenario;
use engine_diff::triage::AllowList;
use robot_model::RobotModel;

#[test]
fn report_for_a_fixed_seed() {
    let m = RobotModel::h1_2().expect("model");
    let f = builtin_factories(&["mujoco".into(), "rapier-multibody".into(), "rapier-impulse".into()]).expect("engines");
    let ctrl = excitation_factory(&m);
    let cfg = HarnessConfig { window_steps: 25, ..HarnessConfig::default() };
    let episodes: Vec<_> = (1..=2u64)
        .map(|seed| {
            // A hard shove and noisy actions, so that the report has triaged and minimized entries.
            let mut s = Scenario::excitation(seed, 0.2);
            s.pushes = vec![engine_diff::scenario::Push { t: 0.1, dv: [1.0, -0.6, 0.0] }];
            s.action_noise = 0.05;
            harness::run_episode(&m, &f, ctrl.as_ref(), &s, &cfg).expect("episode")
        })
        .collect();
    let allow = AllowList::builtin().expect("allow-list");
    let a = Analysis {
        model: &m,
        factories: &f,
        controller: ctrl.as_ref(),
        controller_name: "excitation",
        cfg: &cfg,
        allow: &allow,
        minimize_limit: 2,
    };
    let (report, repros) = analyse(&a, &episodes).expect("analysis");
    // Every entry is triaged, and every minimized entry has a reproducer that replays identically.
    for (name, r) in &repros {
        let o = r.replay(&m).expect("replay");
        assert!(o.identical, "{name}: {:?}", o.mismatches);
    }
    assert_eq!(repros.len(), report.entries.iter().filter(|e| e.minimized.is_some()).count());
    // Engine versions are part of the snapshot: results are only bit-identical on the same versions.
    insta::assert_snapshot!("report_excitation_seed_1_2", report.markdown());
}
