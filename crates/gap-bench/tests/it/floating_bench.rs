//! The floating-base benchmark's plumbing (`ulab gap bench --floating`): the hidden effects it draws, the fall
//! check that makes it redraw them, and one short walking trial end to end — labels sealed before the diagnosis,
//! the diagnosis choosing the floating plant by itself, and a large leg damping scored top-1 against the label that
//! was injected. The walking trial needs `$ULAB_SHARED` for the policy weights (skips without it).
use gap_bench::{
    draw_floating_trial, fell_at, injectable_floating, open, run_floating_trial_drawn, seal, trial_plan, trial_salt,
    BenchOptions, FloatingLog, Injected, InputKind, Labels, Seal,
};
use gap_diagnosis::diagnose::PlantKind;
use gap_diagnosis::effects::Scope;
use gap_diagnosis::floating::BaseState;
use gap_diagnosis::plant::{joint_groups, Effects, GROUPS};
use gap_diagnosis::{DiagnoseOptions, EffectKind, RobotLog};
use policy_runtime::PolicySpec;
use std::path::Path;

fn model() -> robot_model::RobotModel {
    robot_model::builtin("h1_2").expect("built-in model")
}

/// Singles cycle through every ground kind, pairs are two distinct kinds, every fourth trial is a control; group
/// effects sit on a leg, on every joint of it and nowhere else; magnitudes lie inside the library's fitting range
/// on the far side of the no-effect value; a redraw changes the magnitudes, never the kinds.
#[test]
fn draws_cover_the_ground_kinds_on_the_legs() {
    let m = model();
    let groups = joint_groups(&m);
    let kinds = injectable_floating();
    let mut singles = Vec::new();
    for i in 0..24 {
        let (fx, labels) = draw_floating_trial(&m, i, 1, 0);
        assert_eq!(labels.trial, i);
        assert_eq!(labels.injected.len(), trial_plan(i), "trial {i}");
        if labels.injected.len() == 1 {
            singles.push(labels.injected[0].kind);
        }
        if labels.injected.len() == 2 {
            assert_ne!(labels.injected[0].kind, labels.injected[1].kind);
        }
        for inj in &labels.injected {
            assert!(kinds.contains(&inj.kind), "{:?} is not a ground kind", inj.kind);
            let (lo, hi, none) = inj.kind.range();
            let v = if inj.kind == EffectKind::Latency { inj.value / 2.0 } else { inj.value }; // ms -> 2 ms steps
            assert!(v >= lo && v <= hi && v != none, "{inj:?} outside ({lo}, {hi}) or at the no-effect value");
            match inj.kind.scope() {
                Scope::Group => {
                    let g = GROUPS.iter().position(|n| *n == inj.unit).expect("a group name");
                    assert!(g <= 1, "{inj:?}: not on a leg");
                    for (j, &group) in groups.iter().enumerate() {
                        let want = if group == g { inj.value } else { none };
                        assert_eq!(inj.kind.get(&fx, j), want, "{inj:?}, joint {j}");
                    }
                }
                _ => assert_eq!(inj.unit, "robot"),
            }
        }
        let (_, again) = draw_floating_trial(&m, i, 1, 0);
        assert_eq!(again, labels, "the draw is deterministic");
        let (_, redrawn) = draw_floating_trial(&m, i, 1, 1);
        assert_eq!(
            redrawn.injected.iter().map(|x| x.kind).collect::<Vec<_>>(),
            labels.injected.iter().map(|x| x.kind).collect::<Vec<_>>()
        );
        if !labels.injected.is_empty() {
            assert_ne!(redrawn, labels, "a redraw must change the magnitudes");
        }
    }
    singles.sort();
    singles.dedup();
    assert_eq!(singles.len(), kinds.len(), "24 trials give every ground kind a single-effect trial");
}

fn base(z: f64, tilt: f64) -> BaseState {
    // Rotation by `tilt` about the pelvis x axis.
    let (s, c) = (tilt / 2.0).sin_cos();
    BaseState { pos: [0.0, 0.0, z], quat: [c, s, 0.0, 0.0], lin_vel: [0.0; 3], ang_vel: [0.0; 3] }
}

/// Down = pelvis below 0.6 m or tilted past 45 degrees, at the first such sample.
#[test]
fn a_fall_is_a_low_or_tilted_pelvis() {
    let log = |truth: Vec<BaseState>| FloatingLog { log: RobotLog::default(), truth };
    let deg = std::f64::consts::PI / 180.0;
    assert_eq!(fell_at(&log(vec![base(1.0, 0.0), base(0.7, 40.0 * deg), base(0.95, -40.0 * deg)])), None);
    assert_eq!(fell_at(&log(vec![base(1.0, 0.0), base(0.59, 0.0), base(0.3, 0.0)])), Some(1));
    assert_eq!(fell_at(&log(vec![base(1.0, 0.0), base(1.0, 10.0 * deg), base(1.0, 50.0 * deg)])), Some(2));
    assert_eq!(fell_at(&log(vec![base(1.0, -50.0 * deg)])), Some(0));
}

/// One 4 s walking trial with 3 N·m·s/rad of extra damping on the left leg (after a first draw that makes the robot
/// fall), through the benchmark's trial runner with the default diagnosis options.
#[test]
fn leg_damping_trial_is_sealed_diagnosed_on_the_floating_plant_and_scored_top1() {
    if std::env::var("ULAB_SHARED").map_or(true, |v| v.is_empty()) {
        eprintln!("SKIPPED: ULAB_SHARED is not set (the policy arrays live there)");
        return;
    }
    let m = model();
    let spec = PolicySpec::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots/h1_2/policies/unitree_rl_gym_lstm.toml"),
    )
    .expect("LSTM policy spec");
    let opts =
        BenchOptions { policies: vec![spec], diagnose: DiagnoseOptions::default(), ..BenchOptions::new(1, 1, 4.0) };
    let groups = joint_groups(&m);
    let injected = vec![Injected { kind: EffectKind::Damping, unit: "left_leg".into(), value: 3.0 }];
    // The first draw takes the PD gains off both legs, so the robot collapses and the runner must redraw; the
    // second is the leg damping.
    let mut attempts = Vec::new();
    let mut draw = |attempt: usize| {
        attempts.push(attempt);
        let mut fx = Effects::none(m.nj());
        if attempt == 0 {
            (0..m.nj()).filter(|&j| groups[j] <= 1).for_each(|j| fx.gain_scale[j] = 0.0);
            let limp =
                (0..2).map(|g| Injected { kind: EffectKind::GainScale, unit: GROUPS[g].into(), value: 0.0 }).collect();
            return (fx, Labels { trial: 0, injected: limp, out_of_library: vec![] });
        }
        (0..m.nj()).filter(|&j| groups[j] == 0).for_each(|j| fx.damping[j] = 3.0);
        (fx, Labels { trial: 0, injected: injected.clone(), out_of_library: vec![] })
    };
    // The seal handed over with the log, i.e. before the diagnosis runs.
    let mut sealed_before: Vec<Seal> = Vec::new();
    let mut on_log = |_i: usize, log: &RobotLog, s: &Seal| {
        sealed_before.push(s.clone());
        Ok::<_, gap_diagnosis::GapError>(log.clone())
    };
    let (sealed, score, report) = run_floating_trial_drawn(&m, 0, &opts, &mut draw, &mut on_log).expect("trial");
    eprintln!(
        "{} -> ranked {:?}, units {:?}, param errors {:?}",
        score.policy.clone().unwrap_or_default(),
        score.ranked,
        score.attributed_units,
        score.param_errors
    );

    assert_eq!(attempts, vec![0, 1], "one redraw after the fall");
    assert_eq!(sealed_before.len(), 1, "on_log runs once, before the diagnosis");
    assert_eq!(sealed_before[0].sha256, sealed.sha256);
    let (expected, text) =
        seal(&Labels { trial: 0, injected: injected.clone(), out_of_library: vec![] }, &trial_salt(1, 0))
            .expect("seal");
    assert_eq!(expected.sha256, sealed.sha256, "the seal is of the injected labels with the trial's salt");
    assert_eq!(open(&sealed, &text).expect("opens").injected, injected);

    assert_eq!(report.plant, PlantKind::Floating, "{}", report.rig_check.message);
    assert_eq!(score.plant, Some(PlantKind::Floating));
    assert_eq!(score.redraws, Some(1), "the limp legs fall, the damped leg walks");
    assert_eq!(score.input, InputKind::Policy);
    assert_eq!(score.injected, injected);
    assert_eq!(report.ranked.first(), Some(&EffectKind::Damping), "ranked {:?}", report.ranked);
    assert!(score.top1 && score.top3 && score.all_found);
    assert_eq!(score.attributed_units, vec![Some("left_leg".to_string())]);
    assert_eq!((score.joints_correct, score.joints_total), (1, 1));
    assert_eq!(score.false_confident, 0);
}
