//! The diagnosis on logs of a plant it did not generate (`tests/gap/suspended_plant.py`): Unitree's published MuJoCo
//! model of the H1-2 run by MuJoCo's official Python bindings with the pelvis welded in the air, the PD law computed
//! in Python, 1 ms physics steps with the PD law at 1 kHz (as a 1 kHz simulator runs; the diagnosing simulator takes
//! one 2 ms step), hidden effects through MuJoCo's own joint parameters (damping, frictionloss, armature) or the PD
//! law and the encoder, and the log written by the official Python `mcap` writer (zstd) with Unitree's hg messages.
//! The counterparts: the plant's program and model (Unitree's MJCF, not the project's model or generated MJCF), its
//! numerics, and the effect laws of MuJoCo. What is shared: MuJoCo itself, and the effects' sizes (given to both).
//!
//! Checked: a single effect on one joint (the classes the reviewer saw missed on such a plant: dry friction
//! on one elbow, a weak gain on one shoulder, armature on one leg; and an encoder offset on one hip) is named first,
//! on that joint, at its size; both effects of a pair are named; a no-effect log names nothing; and the numerics
//! stage says which stepping the log was made with (1 ms steps and PD at 1 kHz, or the diagnosing one); a friction
//! proportional to the load (outside the library) names nothing, where a viscous damping on the same joint is named;
//! a torque ceiling (a plain clip in the plant) is named from the log's own torque on its joint, at its size.
use crate::common;

use gap_diagnosis::diagnose::{HalvesRefit, Report, SplitBy};
use gap_diagnosis::{diagnose, DiagnoseOptions, EffectKind, RobotLog};
use std::path::Path;

/// Unitree's MJCF lives in the shared reference folder (`$ULAB_SHARED`, set by `scripts/env.sh`).
fn shared() -> Option<String> {
    let s = std::env::var("ULAB_SHARED").ok().filter(|s| !s.is_empty());
    if s.is_none() {
        eprintln!("SKIPPED: ULAB_SHARED is not set (Unitree's MJCF lives there)");
    }
    s
}

/// Runs the plant with `args` into `name.mcap` and diagnoses its log with the default options.
fn diagnose_plant(shared: &str, name: &str, args: &[&str]) -> Report {
    let model = common::model();
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gap-python-plant");
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(format!("{name}.mcap"));
    let out = std::process::Command::new(common::python())
        .arg(common::workspace().join("tests/gap/suspended_plant.py"))
        .arg(&path)
        .args(["--shared", shared])
        .args(args)
        .output()
        .expect("run the Python plant");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let bytes = std::fs::read(&path).expect("read the log");
    let log = RobotLog::from_mcap(&bytes, &model).expect("the official writer's zstd log reads");
    let r = diagnose(&model, &log, &DiagnoseOptions::default()).expect("diagnose");
    let summary: Vec<String> = r
        .effects
        .iter()
        .filter(|e| e.named)
        .map(|e| {
            let units: Vec<String> = e.params.iter().map(|p| format!("{}={:.4}", p.unit, p.value)).collect();
            format!("{} {:.3} [{}]", e.kind.name(), e.reduction.value, units.join(" "))
        })
        .collect();
    eprintln!("{name}: ranked {:?}; named {summary:?}", r.ranked);
    for e in &r.effects {
        for l in &e.splits {
            eprintln!(
                "{name}: {} split by {:?}: {:.2}x / {:.2}x, set aside {}",
                e.kind.name(),
                l.by,
                l.scale_low.value,
                l.scale_high.value,
                l.set_aside
            );
        }
    }
    r
}

/// The effect is ranked first, its best unit is `unit`, fitted within `tol` of `value`.
/// The refit of effect `kind` of `r` on the halves of the training windows by `by`.
fn split(r: &Report, kind: EffectKind, by: SplitBy) -> HalvesRefit {
    let e = r.effects.iter().find(|e| e.kind == kind).expect("the effect is assessed");
    e.splits.iter().find(|s| s.by == by).cloned().unwrap_or_else(|| panic!("no {by:?} split of {}", kind.name()))
}

fn assert_named_first(r: &Report, kind: EffectKind, unit: &str, value: f64, tol: f64) {
    assert_eq!(r.ranked.first(), Some(&kind), "ranked {:?}", r.ranked);
    assert_named_on(r, kind, unit, value, tol);
}

fn assert_named_on(r: &Report, kind: EffectKind, unit: &str, value: f64, tol: f64) {
    let e = r.effects.iter().find(|e| e.kind == kind && e.named).expect("named");
    let best =
        e.params.iter().max_by(|a, b| a.held_out_reduction.total_cmp(&b.held_out_reduction)).expect("a fitted unit");
    assert_eq!(best.unit, unit, "{} fitted on {:?}", kind.name(), e.params);
    assert!((best.value - value).abs() <= tol, "{} on {unit}: {} vs {value} ± {tol}", kind.name(), best.value);
}

#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the control, the pair and the waist's ceiling (issue 21: the CI time budget)"]
fn single_joint_effects_of_another_program_s_plant_are_named_on_their_joint() {
    let Some(shared) = shared() else { return };
    // Dry friction (MuJoCo's frictionloss, a hard Coulomb law; the library's is smooth with stiction) on one elbow.
    let r = diagnose_plant(&shared, "friction", &["--extra-frictionloss", "left_elbow_joint=1.0"]);
    assert_named_first(&r, EffectKind::Friction, "left_elbow", 1.0, 0.15);
    // MuJoCo's frictionloss does not depend on the load: the refit on either half of the windows wants its size.
    let l = split(&r, EffectKind::Friction, SplitBy::Load);
    assert!(!l.set_aside && (l.scale_high.value - l.scale_low.value).abs() < 0.2, "{l:?}");
    // A Coulomb torque keeps its size at speed: the fitted friction cuts the fast half's gap as well as the slow
    // half's (within a factor of two either way).
    let l = split(&r, EffectKind::Friction, SplitBy::Speed);
    assert!(!l.set_aside && l.by_cut, "{l:?}");
    assert!(l.cut_high.value > 0.5 * l.cut_low.value && l.cut_low.value > 0.5 * l.cut_high.value, "{l:?}");
    // A weak gain on one shoulder (kp and kd at 60 %).
    let r = diagnose_plant(&shared, "gain", &["--gain-scale", "left_shoulder_pitch_joint=0.6"]);
    assert_named_first(&r, EffectKind::GainScale, "left_shoulder_pitch", 0.6, 0.06);
    // A gain scales the torque that drives the joint and the torque that brakes it alike: refitted on the windows
    // where the shoulder's motor mostly drives it and on those where it mostly brakes, it wants its size on both.
    let l = split(&r, EffectKind::GainScale, SplitBy::Power);
    assert!(!l.set_aside && (l.scale_high.value - l.scale_low.value).abs() < 0.3, "{l:?}");
    // Armature 0.1 -> 0.25 kg m^2 on one knee: the library's armature is a multiple of the model's.
    let r = diagnose_plant(&shared, "armature", &["--extra-armature", "left_knee_joint=0.15"]);
    assert_named_first(&r, EffectKind::Armature, "left_knee", 2.5, 0.4);
    // An encoder reading 0.05 rad high on one hip.
    let r = diagnose_plant(&shared, "encoder", &["--encoder-offset", "right_hip_pitch_joint=0.05"]);
    assert_named_first(&r, EffectKind::EncoderOffset, "right_hip_pitch", 0.05, 0.01);
}

#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the control, the pair and the waist's ceiling (issue 21: the CI time budget)"]
fn a_friction_that_grows_with_the_load_is_not_named_as_one_of_the_library() {
    let Some(shared) = shared() else { return };
    // 0.15 times the motor torque's magnitude against the motion of one elbow: outside the library. Damping,
    // friction and a dead band each fit it as an average (before the load split, damping and friction were named
    // on this log); refitted on the lightly and on the heavily loaded training windows they want sizes far apart.
    let r = diagnose_plant(&shared, "load_friction", &["--load-friction", "left_elbow_joint=0.15"]);
    assert!(r.ranked.is_empty() && r.unexplained, "ranked {:?}", r.ranked);
    for kind in [EffectKind::Damping, EffectKind::Friction] {
        let l = split(&r, kind, SplitBy::Load);
        assert!(l.set_aside && l.scale_high.lo > l.scale_low.hi, "{}: {l:?}", kind.name());
    }
    // A dead band fitted to it wants a wider band under load, as a true band on a leg may (DART's seed 8, trial 6);
    // what sets this one aside is that it cuts nothing of the light half's gap, where a band, lost at every
    // reversal, cuts some at any load.
    let l = split(&r, EffectKind::Backlash, SplitBy::Load);
    assert!(l.set_aside && l.load_paced && l.cut_low.lo <= 0.0 && l.cut_high.lo > 0.0, "{l:?}");
    // A viscous damping (MuJoCo's dof_damping) on the same elbow has one size at every load: named, on the elbow.
    let r = diagnose_plant(&shared, "damping", &["--extra-damping", "left_elbow_joint=1.0"]);
    assert_named_first(&r, EffectKind::Damping, "left_elbow", 1.0, 0.1);
    // ... and, being viscous, one size at every speed: the speed split keeps it.
    for by in [SplitBy::Load, SplitBy::Speed] {
        let l = split(&r, EffectKind::Damping, by);
        assert!(!l.set_aside && (l.scale_high.value - l.scale_low.value).abs() < 0.2, "{l:?}");
    }
}

#[test]
fn both_effects_of_a_pair_are_named() {
    let Some(shared) = shared() else { return };
    let r = diagnose_plant(
        &shared,
        "pair",
        &["--extra-frictionloss", "right_elbow_joint=0.8", "--gain-scale", "left_knee_joint=0.7"],
    );
    assert_eq!(r.ranked.len(), 2, "ranked {:?}", r.ranked);
    assert_named_on(&r, EffectKind::Friction, "right_elbow", 0.8, 0.12);
    assert_named_on(&r, EffectKind::GainScale, "left_knee", 0.7, 0.07);
}

#[test]
fn a_no_effect_log_names_nothing_and_its_stepping_is_recognised() {
    let Some(shared) = shared() else { return };
    // 1 ms steps, PD at 1 kHz: part of the baseline is numerics, and the 1 ms / 1 ms replay is what fits.
    let r = diagnose_plant(&shared, "control_1ms", &[]);
    assert!(r.ranked.is_empty() && r.unexplained, "ranked {:?}", r.ranked);
    let n = r.numerics.as_ref().expect("numerics on the rig");
    let best = n.better_variant().map(|v| (v.engine.as_str(), v.timestep_ms, v.pd_period_ms));
    assert_eq!(best, Some(("mujoco", 1.0, 1.0)), "{:?}", n.variants);
    // The diagnosing stepping (one 2 ms step, implicitfast): no variant fits better.
    let r = diagnose_plant(&shared, "control_2ms", &["--timestep", "0.002"]);
    assert!(r.ranked.is_empty(), "ranked {:?}", r.ranked);
    let n = r.numerics.as_ref().expect("numerics on the rig");
    assert!(n.better_variant().is_none(), "{:?}", n.variants);
}

/// 1 ms steps with the PD law held for 2 ms: the numerics stage tells the timestep alone from the timestep and the
/// PD rate (`a_no_effect_log_names_nothing...` has the two other steppings).
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the 1 ms and 2 ms steppings (issue 21: the CI time budget)"]
fn a_no_effect_log_with_the_pd_law_held_for_two_steps_is_recognised() {
    let Some(shared) = shared() else { return };
    let r = diagnose_plant(&shared, "control_1ms_pd2ms", &["--pd-every", "2"]);
    assert!(r.ranked.is_empty(), "ranked {:?}", r.ranked);
    let n = r.numerics.as_ref().expect("numerics on the rig");
    let best = n.better_variant().map(|v| (v.engine.as_str(), v.timestep_ms, v.pd_period_ms));
    assert_eq!(best, Some(("mujoco", 1.0, 2.0)), "{:?}", n.variants);
}

/// A torque ceiling (issue 14, a sparse effect): the plant's motor delivers at most 0.3 of the limit, a plain clip
/// written in the plant's program (the diagnosis's saturation has a torque-speed line), which the chirps reach on the
/// waist in a dozen samples and on a hip pitch in about sixty. Named from the log's own torque, on that joint, at its
/// size; a no-effect log of the same plant shows no ceiling (`a_no_effect_log_names_nothing...`).
#[test]
fn a_torque_ceiling_of_another_program_s_plant_is_named_from_the_log() {
    let Some(shared) = shared() else { return };
    ceiling_is_named(&shared, "torso_joint", "torso");
}

/// The same on a hip pitch, which the chirps hold at the ceiling for about sixty samples.
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the waist's ceiling (issue 21: the CI time budget)"]
fn a_torque_ceiling_on_a_hip_of_another_program_s_plant_is_named_from_the_log() {
    let Some(shared) = shared() else { return };
    ceiling_is_named(&shared, "left_hip_pitch_joint", "left_hip_pitch");
}

/// A plant whose `joint` delivers at most 0.3 of its torque limit: the saturation alone is named, on `motor`, at
/// that size, and the log shows that ceiling on that joint only.
fn ceiling_is_named(shared: &str, joint: &str, motor: &str) {
    let r = diagnose_plant(shared, &format!("ceiling_{motor}"), &["--torque-scale", &format!("{joint}=0.3")]);
    assert_eq!(r.ranked, vec![EffectKind::TorqueSaturation], "{motor}");
    assert_named_on(&r, EffectKind::TorqueSaturation, motor, 0.3, 0.02);
    let e = r.effects.iter().find(|e| e.kind == EffectKind::TorqueSaturation).expect("assessed");
    let seen: Vec<&str> = e.ceilings_in_log.iter().map(|c| c.joint.as_str()).collect();
    assert_eq!(seen, vec![motor], "{:?}", e.ceilings_in_log);
}
