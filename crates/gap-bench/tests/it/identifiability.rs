//! Identifiability against physics: on a suspended robot that only holds its standing pose, viscous damping,
//! rotor inertia (armature) and command latency act on nothing (no joint moves, no command changes), while a
//! heavier link changes the gravity torques the joints hold. The diagnosis must say exactly that ("not
//! identifiable from this log" for the first three, with the motion that would reveal them), and must find them
//! and joint friction identifiable once the excitation plan moves the joints. The counterpart is the physical
//! argument, not the code: the sensitivities come from the diagnosing simulator, the expectation from mechanics.
//! On the holding log with 1 N·m of friction hidden in one arm, friction may not be named.
//!
//! Friction is left out of the holding assertion on purpose: each replay starts from the measured (noisy) joint
//! velocities, and the friction model's stiction acts on that micro-motion, so its signal on a holding log is
//! 0.43 / 0.54 / 0.89 of the floor on seeds 7 / 8 / 9 (damping, armature and latency stay under 0.01): not
//! identifiable there, but too close to the floor for a test that must not depend on the seed.
use gap_bench::{generate_log, RealConfig};
use gap_diagnosis::plant::{joint_groups, Effects, GROUPS};
use gap_diagnosis::{diagnose, DiagnoseOptions, EffectKind, Report};
use robot_model::RobotModel;

const KINDS: [EffectKind; 6] = [
    EffectKind::Friction,
    EffectKind::Damping,
    EffectKind::Armature,
    EffectKind::Latency,
    EffectKind::LinkMass,
    EffectKind::GainScale,
];

fn model() -> RobotModel {
    robot_model::builtin("h1_2").expect("built-in model")
}

fn report(excitation_scale: f64, fx: Effects) -> Report {
    let m = model();
    let cfg = RealConfig { effects: fx, excitation_scale, ..RealConfig::new(&m, 5.0, 7) };
    let log = generate_log(&m, &cfg).expect("generate");
    let opts = DiagnoseOptions { block_s: 0.5, kinds: Some(KINDS.to_vec()), ..Default::default() };
    diagnose(&m, &log, &opts).expect("diagnose")
}

fn identifiable_units(r: &Report, kind: EffectKind) -> Vec<String> {
    let i = r.identifiability.iter().find(|i| i.kind == kind).unwrap_or_else(|| panic!("{} not listed", kind.name()));
    for u in &i.units {
        eprintln!("  {} {}: signal {:.3e}, floor {:.3e}", kind.name(), u.unit, u.signal, u.floor);
    }
    i.identifiable_units().into_iter().map(str::to_string).collect()
}

/// A robot holding still (no excitation) with a dry friction of 1 N·m on every joint of its left arm: the model,
/// the left arm's joints (motor names) and the diagnosis.
fn still_robot_with_arm_friction() -> (RobotModel, Vec<String>, Report) {
    let m = model();
    let mut fx = Effects::none(m.nj());
    let groups = joint_groups(&m);
    let arm = GROUPS.iter().position(|g| *g == "left_arm").expect("left_arm group");
    let arm_joints: Vec<usize> = (0..m.nj()).filter(|&j| groups[j] == arm).collect();
    arm_joints.iter().for_each(|&j| EffectKind::Friction.set(&mut fx, j, 1.0));
    let names = arm_joints.iter().map(|&j| m.joints[j].motor_name.clone()).collect();
    let hold = report(0.0, fx);
    (m, names, hold)
}

#[test]
fn a_robot_holding_still_cannot_reveal_dynamic_effects_but_can_reveal_a_heavier_link() {
    let (m, _, hold) = still_robot_with_arm_friction();
    for kind in [EffectKind::Damping, EffectKind::Armature, EffectKind::Latency] {
        let units = identifiable_units(&hold, kind);
        assert!(units.is_empty(), "{} identifiable on {units:?} while nothing moves", kind.name());
        let (_, why) = hold.abstentions.iter().find(|(k, _)| *k == kind).expect("abstained");
        assert!(why.contains("not identifiable from this log") && why.contains(kind.revealed_by()), "{why}");
    }
    assert!(!identifiable_units(&hold, EffectKind::LinkMass).is_empty(), "a 20 % heavier link changes held torques");

    let moving = report(1.0, Effects::none(m.nj()));
    for kind in [EffectKind::Friction, EffectKind::Damping, EffectKind::Armature, EffectKind::Latency] {
        assert!(
            !identifiable_units(&moving, kind).is_empty(),
            "{} not identifiable under the excitation plan",
            kind.name()
        );
    }
}

/// A gentle chirp (a third of the plan's amplitude, sweeps to 1 Hz, no steps) asks a joint for about a thirtieth
/// of the plan's accelerations and far less torque: rotor inertia must lose most of its signal, and a torque limit
/// at 80 % of nominal, which such motion never reaches, must be reported not identifiable, with the motion that
/// would reveal it. The counterpart is mechanics (inertial torque scales with amplitude times frequency squared),
/// not the code.
#[test]
fn a_gentle_chirp_hides_inertia_and_torque_limits_that_the_plan_reveals() {
    let m = model();
    let run = |motion: gap_bench::Motion| {
        let cfg = RealConfig { motion, ..RealConfig::new(&m, 5.0, 7) };
        let log = generate_log(&m, &cfg).expect("generate");
        let kinds = vec![EffectKind::Armature, EffectKind::TorqueSaturation];
        let opts = DiagnoseOptions { block_s: 0.5, kinds: Some(kinds), ..Default::default() };
        diagnose(&m, &log, &opts).expect("diagnose")
    };
    let plan = run(gap_bench::Motion::Plan);
    let gentle = run(gap_bench::Motion::GentleChirp);
    let ratio = |r: &Report, kind: EffectKind| {
        r.identifiability.iter().find(|i| i.kind == kind).map(|i| i.best_ratio()).expect("listed")
    };
    let (a_plan, a_gentle) = (ratio(&plan, EffectKind::Armature), ratio(&gentle, EffectKind::Armature));
    eprintln!("armature signal/floor: plan {a_plan:.3}, gentle chirp {a_gentle:.3}");
    assert!(a_plan >= 1.0, "armature not identifiable under the plan ({a_plan:.3})");
    assert!(a_gentle < 0.25 * a_plan, "a gentle chirp keeps {a_gentle:.3} of armature's signal (plan {a_plan:.3})");
    assert!(
        identifiable_units(&gentle, EffectKind::TorqueSaturation).is_empty(),
        "a torque limit at 80 % is identifiable under a gentle chirp"
    );
    let (_, why) = gentle.abstentions.iter().find(|(k, _)| *k == EffectKind::TorqueSaturation).expect("abstained");
    assert!(why.contains("not identifiable from this log"), "{why}");
}

/// A friction on the left arm of a robot holding still: the friction holds the arm off its PD target, which the log
/// shows, so naming it is right, but only on the arm. The judge names it on the left leg: a wrong name on a log
/// without motion, where a friction's fit has no velocity to tell joints apart.
#[test]
#[ignore = "known wrong name: the still arm's friction is named on the left leg; the test of its fix"]
fn a_friction_named_on_a_robot_holding_still_is_on_the_joints_that_carry_it() {
    let (_, arm_joints, hold) = still_robot_with_arm_friction();
    for e in hold.effects.iter().filter(|e| e.kind == EffectKind::Friction && e.named) {
        for p in &e.params {
            assert!(p.unit == "left_arm" || arm_joints.contains(&p.unit), "friction named on {}", p.unit);
        }
    }
}
