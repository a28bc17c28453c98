//! Benchmark logs driven by a policy rollout: the unitree_rl_gym LSTM (arrays from `$ULAB_SHARED`) closed around
//! the suspended reference plant's noisy measurements at 50 Hz with timing jitter drives the legs; torso and arms
//! follow the excitation plan. The diagnosis must still find an effect injected on a leg; and on a trial of the
//! Rapier benchmark driven by the LSTM, must not name a torque saturation that the logged torque contradicts.
use crate::common;

use gap_bench::{generate_log, generate_log_with, trial_input, InputKind, PolicyInput, RealConfig};
use gap_diagnosis::plant::{joint_groups, Effects, GROUPS};
use gap_diagnosis::{diagnose, DiagnoseOptions, EffectKind, Outcome};
use policy_runtime::PolicySpec;
use std::path::Path;

/// Trial `i` of the Rapier benchmark `--trials 24 --out-of-library out_of_library --seed seed --duration 15` with
/// both public policies (Gepetto's, then the LSTM), run as `ulab gap bench` runs it (`None` without the arrays).
fn rapier_policy_trial(
    seed: u64,
    out_of_library: usize,
    i: usize,
) -> Option<(gap_bench::TrialScore, gap_diagnosis::diagnose::Report)> {
    let lstm = lstm_spec()?;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots/h1_2/policies/gepetto_demo_rsl.toml");
    let gepetto = PolicySpec::load(&path).expect("Gepetto policy spec");
    let m = robot_model::builtin("h1_2").expect("model");
    let mut opts = gap_bench::BenchOptions::new(24, seed, 15.0);
    opts.reference = gap_diagnosis::plant::EngineChoice::Other(diff_physics::EngineKind::RapierMultibody);
    opts.out_of_library = out_of_library;
    opts.policies = vec![gepetto, lstm];
    Some(common::run_trial_through_mcap(&m, i, &opts))
}

fn lstm_spec() -> Option<PolicySpec> {
    if std::env::var("ULAB_SHARED").map_or(true, |v| v.is_empty()) {
        eprintln!("SKIPPED: ULAB_SHARED is not set (the policy arrays live there)");
        return None;
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots/h1_2/policies/unitree_rl_gym_lstm.toml");
    Some(PolicySpec::load(&path).expect("LSTM policy spec"))
}

#[test]
fn inputs_alternate_balanced_over_the_trial_pattern() {
    let kinds: Vec<InputKind> = (0..8).map(|i| trial_input(i, true)).collect();
    use InputKind::{Excitation as E, Policy as P};
    assert_eq!(kinds, vec![E, P, E, P, P, E, P, E]);
    assert!((0..8).all(|i| trial_input(i, false) == E));
}

#[test]
fn policy_driven_log_moves_the_legs_and_the_diagnosis_finds_leg_damping() {
    let Some(spec) = lstm_spec() else { return };
    let m = robot_model::builtin("h1_2").expect("model");
    let groups = joint_groups(&m);
    let left_leg = GROUPS.iter().position(|g| *g == "left_leg").expect("group");
    let mut fx = Effects::none(m.nj());
    (0..m.nj()).filter(|&j| groups[j] == left_leg).for_each(|j| EffectKind::Damping.set(&mut fx, j, 3.0));
    let cfg = RealConfig { effects: fx, ..RealConfig::new(&m, 5.0, 3) };
    let input = PolicyInput { spec, command: [0.5, 0.0, 0.2] };
    let log = generate_log_with(&m, &cfg, Some(&input)).expect("policy rollout");
    let plan = generate_log(&m, &cfg).expect("excitation plan");

    // 50 Hz commands; the legs are commanded by the policy (not the plan), the arms by the plan.
    assert_eq!(log.commands.len(), 250);
    let legs: Vec<usize> = (0..m.nj()).filter(|&j| groups[j] <= 1).collect();
    let arms: Vec<usize> = (0..m.nj()).filter(|&j| groups[j] >= 3).collect();
    let differs = |j: usize| log.commands.iter().zip(&plan.commands).any(|(a, b)| (a.q[j] - b.q[j]).abs() > 1e-3);
    assert!(
        legs.iter().all(|&j| differs(j) || m.joints[j].motor_name.contains("ankle_roll")),
        "legs not driven by the policy"
    );
    assert!(arms.iter().all(|&j| log
        .commands
        .iter()
        .zip(&plan.commands)
        .all(|(a, b)| (a.q[j] - b.q[j]).abs() < 1e-12)));
    for c in &log.commands {
        for &j in &legs {
            assert!(c.q[j] >= m.joints[j].lower && c.q[j] <= m.joints[j].upper);
        }
    }
    // The legs swing: speeds well above the sensor noise.
    let peak = log.states.iter().flat_map(|s| legs.iter().map(move |&j| s.dq[j].abs())).fold(0.0, f64::max);
    assert!(peak > 1.0, "legs barely move (peak {peak} rad/s)");

    let opts = DiagnoseOptions {
        block_s: 0.5,
        kinds: Some(vec![EffectKind::Damping, EffectKind::Armature, EffectKind::Friction, EffectKind::GainScale]),
        ..Default::default()
    };
    let r = diagnose(&m, &log, &opts).expect("diagnose");
    assert_eq!(r.outcome, Outcome::Diagnosed, "{}", r.rig_check.message);
    assert_eq!(r.ranked.first(), Some(&EffectKind::Damping), "ranked {:?}", r.ranked);
    let e = r.effects.iter().find(|e| e.kind == EffectKind::Damping).expect("damping");
    let top = e.params.first().expect("a unit");
    assert_eq!(top.unit, "left_leg", "{:?}", e.params);
}

/// 12 ms of latency and an added armature (2.52x) on the left shoulder yaw, driven by the LSTM (trial 6 of `ulab gap
/// bench --reference-engine rapier_multibody --trials 24 --out-of-library 6 --seed 4 --duration 15 --policy
/// …/gepetto_demo_rsl.toml --policy …/unitree_rl_gym_lstm.toml`). A torque saturation fitted on that shoulder, at
/// 0.68 of its limit, once stood in for the armature; the logged torque exceeds that ceiling in over a quarter of the
/// samples, which a saturation cannot let happen. No saturation is named, and both injected effects are.
#[test]
#[ignore = "nightly (scripts/nightly.sh): ~4 min of one core; CI keeps the policy-driven leg damping"]
fn a_torque_saturation_the_logged_torque_exceeds_is_not_named() {
    let Some((score, report)) = rapier_policy_trial(4, 6, 6) else { return };
    let kinds: Vec<EffectKind> = score.injected.iter().map(|i| i.kind).collect();
    assert_eq!(kinds, vec![EffectKind::Latency, EffectKind::Armature], "{:?}", score.injected);
    assert!(!report.ranked.contains(&EffectKind::TorqueSaturation), "ranked {:?}", report.ranked);
    assert!(score.all_found && score.misattributed == 0, "ranked {:?}", report.ranked);
}

/// An added armature (2.96x) on the right shoulder yaw and a torque ceiling (0.41) on the right hip roll, driven by
/// the LSTM (trial 22 of `--trials 24 --seed 18` with both policies). The leg's armature fit once wanted the bound of
/// its range on the hip roll, standing in for the ceiling there, and the armature was named on both joints. Both
/// effects are named, the armature on the shoulder (or its arm), not on the leg.
#[test]
#[ignore = "nightly (scripts/nightly.sh): ~4 min of one core; CI keeps the policy-driven leg damping"]
fn an_armature_beside_a_hip_ceiling_is_named_on_the_shoulder() {
    let Some((score, report)) = rapier_policy_trial(18, 0, 22) else { return };
    let kinds: Vec<EffectKind> = score.injected.iter().map(|i| i.kind).collect();
    assert_eq!(kinds, vec![EffectKind::Armature, EffectKind::TorqueSaturation], "{:?}", score.injected);
    assert!(score.all_found && score.misattributed == 0, "ranked {:?}", report.ranked);
    let e = report.effects.iter().find(|e| e.kind == EffectKind::Armature && e.named).expect("armature named");
    let units: Vec<&str> = e.params.iter().map(|p| p.unit.as_str()).collect();
    assert!(matches!(units.as_slice(), ["right_shoulder_yaw"] | ["right_arm"]), "{e:?}");
}

/// 14 ms of latency and a dead band of 0.029 rad on the left hip yaw, driven by the LSTM (trial 6 of the same run).
/// Fitted alone, beside the latency it does not model, the leg's band once wanted the bound of its range; fitted
/// given latency it lies inside. Latency is named, then the band.
#[test]
#[ignore = "nightly (scripts/nightly.sh): ~4 min of one core; CI keeps the policy-driven leg damping"]
fn a_dead_band_beside_latency_is_named_second() {
    let Some((score, report)) = rapier_policy_trial(18, 0, 6) else { return };
    let kinds: Vec<EffectKind> = score.injected.iter().map(|i| i.kind).collect();
    assert_eq!(kinds, vec![EffectKind::Latency, EffectKind::Backlash], "{:?}", score.injected);
    assert_eq!(report.ranked, vec![EffectKind::Latency, EffectKind::Backlash]);
    assert!(score.all_found && score.misattributed == 0, "ranked {:?}", report.ranked);
}
