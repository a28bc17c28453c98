//! The whole pipeline on small generated logs: the reference plant (MuJoCo RK4 on the rig, sensor noise, 50 Hz
//! command jitter) with one hidden effect writes an MCAP like `ulab record`; the diagnosis (MuJoCo implicitfast)
//! reads it back and must name that effect first, on the right joint or group, with a parameter near the truth.
//! A log without any effect must give no confident attribution.
//!
//! Each case takes one to four minutes of both cores: CI runs the no-effect control and one trial of the Rapier
//! benchmark (a torque ceiling named from the log); the others (every effect of the library on MuJoCo's plant, the
//! Rapier plant's control and single-joint cases, the other benchmark trials) are ignored here and run by
//! `scripts/nightly.sh` (issue 21: the CI time budget; the Python plant's tests keep an independent plant's control,
//! pair and ceiling in CI).
use crate::common;

use gap_bench::{generate_log, RealConfig};
use gap_diagnosis::diagnose::SplitBy;
use gap_diagnosis::effects::Scope;
use gap_diagnosis::plant::{joint_groups, Effects, EngineChoice, GROUPS};
use gap_diagnosis::{diagnose, DiagnoseOptions, EffectKind, Report, RobotLog};
use robot_model::RobotModel;

const DURATION: f64 = 5.0;
/// Log length with the reference plant in another engine (the benchmark's).
const INDEPENDENT_DURATION: f64 = 15.0;

fn model() -> RobotModel {
    robot_model::builtin("h1_2").expect("built-in model")
}

/// Injects `value` on `unit` (group name, motor name (also for a group-scope kind: a single joint), imu axis index as "0".."2", or "robot").
fn inject(model: &RobotModel, kind: EffectKind, unit: &str, value: f64) -> Effects {
    let mut fx = Effects::none(model.nj());
    let groups = joint_groups(model);
    match kind.scope() {
        Scope::Global => kind.set(&mut fx, 0, value),
        Scope::Imu => kind.set(&mut fx, unit.parse().expect("axis"), value),
        Scope::Joint => {
            let j = model.joints.iter().position(|j| j.motor_name == unit).expect("motor");
            kind.set(&mut fx, j, value);
        }
        Scope::Group => match GROUPS.iter().position(|g| *g == unit) {
            Some(g) => (0..model.nj()).filter(|&j| groups[j] == g).for_each(|j| kind.set(&mut fx, j, value)),
            // A group-scope effect on a single joint.
            None => kind.set(&mut fx, model.joints.iter().position(|j| j.motor_name == unit).expect("motor"), value),
        },
    }
    fx
}

/// Generates, writes as MCAP, reads back, diagnoses.
fn run(fx: Effects, seed: u64) -> Report {
    run_in(EngineChoice::mujoco("RK4"), DURATION, fx, seed)
}

/// As [`run`] with the reference plant in `engine` (another engine than MuJoCo: damping and Coulomb friction through
/// its own joint parameters, as `ulab gap bench --reference-engine` does) and a log of `duration` s.
fn run_in(engine: EngineChoice, duration: f64, fx: Effects, seed: u64) -> Report {
    let m = model();
    let cfg = RealConfig { effects: fx, engine, ..RealConfig::new(&m, duration, seed) };
    let log = generate_log(&m, &cfg).expect("generate");
    let mut buf = std::io::Cursor::new(Vec::new());
    log.write_mcap(&mut buf, &m).expect("write mcap");
    let back = RobotLog::from_mcap(buf.get_ref(), &m).expect("read mcap");
    assert_eq!(back.states.len(), log.states.len());
    assert_eq!(back.commands.len(), log.commands.len());
    diagnose(&m, &back, &DiagnoseOptions { block_s: 0.5, ..Default::default() }).expect("diagnose")
}

fn check(kind: EffectKind, unit: &str, value: f64, report_unit: &str, report_value: f64) {
    check_in(EngineChoice::mujoco("RK4"), DURATION, kind, unit, value, report_unit, report_value)
}

fn check_in(
    engine: EngineChoice,
    duration: f64,
    kind: EffectKind,
    unit: &str,
    value: f64,
    report_unit: &str,
    report_value: f64,
) {
    let m = model();
    let r = run_in(engine, duration, inject(&m, kind, unit, value), 11);
    let summary: Vec<String> =
        r.effects.iter().map(|e| format!("{}:{}:{:.3}", e.kind.name(), e.named, e.reduction.value)).collect();
    assert_eq!(r.ranked.first(), Some(&kind), "ranking {:?}; effects {summary:?}", r.ranked);
    let e = r.effects.iter().find(|e| e.kind == kind).expect("effect result");
    let top =
        e.params.iter().max_by(|a, b| a.held_out_reduction.total_cmp(&b.held_out_reduction)).expect("a fitted unit");
    if kind.scope() == Scope::Imu {
        let p = e.params.iter().find(|p| p.unit == report_unit).expect("axis");
        assert!(
            (p.value - report_value).abs() < 0.2 * report_value.abs(),
            "{} fitted {} vs {report_value}",
            kind.name(),
            p.value
        );
    } else {
        assert_eq!(top.unit, report_unit, "{} attributed to {} ({:?})", kind.name(), top.unit, e.params);
        assert!(
            (top.value - report_value).abs() <= 0.25 * (report_value - kind.range().2).abs() + 1e-9,
            "{} fitted {} vs true {report_value}",
            kind.name(),
            top.value
        );
    }
    assert!(e.named, "{} not named: {:?}", kind.name(), e.note);
}

#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn armature() {
    check(EffectKind::Armature, "right_arm", 2.5, "right_arm", 2.5);
}
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn damping() {
    check(EffectKind::Damping, "left_leg", 2.5, "left_leg", 2.5);
}
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn friction() {
    check(EffectKind::Friction, "left_arm", 2.0, "left_arm", 2.0);
}
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn torque_saturation() {
    check(EffectKind::TorqueSaturation, "right_leg", 0.35, "right_leg", 0.35);
}
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn latency() {
    // 10 steps = 20 ms; reported in ms.
    check(EffectKind::Latency, "robot", 10.0, "robot", 20.0);
}
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn gain_scale() {
    check(EffectKind::GainScale, "left_arm", 0.65, "left_arm", 0.65);
}
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn backlash() {
    check(EffectKind::Backlash, "right_arm", 0.03, "right_arm", 0.03);
}
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn encoder_offset() {
    // A hip pitch carries the leg's weight: its offset changes a gravity torque the rig can see (a knee offset of this
    // size is below what a 5 s log resolves).
    check(EffectKind::EncoderOffset, "left_hip_pitch", 0.06, "left_hip_pitch", 0.06);
}
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn imu_bias() {
    check(EffectKind::ImuBias, "2", 0.1, "imu_z", 0.1);
}
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn imu_misalignment() {
    check(EffectKind::ImuMisalignment, "0", 0.06, "imu_x", 0.06);
}
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn link_mass() {
    check(EffectKind::LinkMass, "left_arm", 1.5, "left_arm", 1.5);
}
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn link_com() {
    check(EffectKind::LinkCom, "right_leg", 0.05, "right_leg", 0.05);
}

#[test]
fn no_effect_no_confident_attribution() {
    let m = model();
    let r = run(Effects::none(m.nj()), 12);
    assert!(r.ranked.is_empty(), "named on a no-effect log: {:?}", r.ranked);
    assert!(r.unexplained);
    assert!(r.best_combination.is_none());
    // Contact effects cannot be fitted on the rig: reported as abstentions with a reason.
    for k in [EffectKind::ContactFriction, EffectKind::ContactStiffness] {
        assert!(r.abstentions.iter().any(|(a, why)| *a == k && why.contains("contact")), "{k:?}");
    }
}

/// Issue 14: a friction on one elbow, in a plant that is not MuJoCo (Rapier's multibody, its own joint friction), is
/// named on that elbow, not diluted over the arm.
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn single_joint_friction_in_an_independent_engine() {
    let rapier = EngineChoice::Other(diff_physics::EngineKind::RapierMultibody);
    // 15 s: against the engines' own difference (the no-effect residual of a Rapier log), 5 s do not resolve it.
    check_in(rapier, INDEPENDENT_DURATION, EffectKind::Friction, "left_elbow", 2.0, "left_elbow", 2.0);
}

/// Issue 14: a link's COM shifted on the right elbow, in Rapier, is named a COM shift on the elbow. It shows most
/// in the shoulder joints that carry the forearm (the single-joint fit tries more than the joint with the largest
/// residual), and a few windows in which the legs reach their range limits in Rapier dominate the mean gap (named
/// on the trimmed windows).
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn single_link_com_in_an_independent_engine() {
    let rapier = EngineChoice::Other(diff_physics::EngineKind::RapierMultibody);
    check_in(rapier, INDEPENDENT_DURATION, EffectKind::LinkCom, "right_elbow", 0.046, "right_elbow", 0.046);
}

/// Issue 14: trial 13 of the Rapier benchmark's seed 3 (`ulab gap bench --reference-engine rapier_multibody --seed 3
/// --duration 15`, the same log, labels and diagnosis options): an encoder offset of -0.079 rad on the left shoulder
/// pitch is named, on that joint. Its signal is small (the PD loop closes on the offset reading, so mostly the gravity
/// torque at the shifted pose shows), and the joint-scope fit also puts an offset on the waist against the engines'
/// own difference there, which alone makes the whole held-out gap larger: such a unit is dropped, or it hides the
/// shoulder's (before it was, this trial abstained). On the default 64 windows the shoulder's offset is named
/// without the drop; the drop is checked on the 300 windows it was written for.
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn arm_encoder_offset_of_a_rapier_benchmark_trial() {
    let (score, report) = benchmark_trial(diff_physics::EngineKind::RapierMultibody, 24, 0, 3, 13);
    assert!(score.top1, "ranking {:?}; abstentions {:?}", report.ranked, report.abstentions);
    assert_eq!(score.attributed_units, vec![Some("left_shoulder_pitch".to_string())]);
    let (score, report) = benchmark_trial_on(diff_physics::EngineKind::RapierMultibody, 24, 0, 3, 13, Some(300));
    assert_eq!(score.injected.len(), 1, "{:?}", score.injected);
    assert_eq!(score.injected[0].kind, EffectKind::EncoderOffset);
    assert!(score.top1, "ranking {:?}; abstentions {:?}", report.ranked, report.abstentions);
    assert_eq!(score.attributed_units, vec![Some("left_shoulder_pitch".to_string())]);
    let e = report.effects.iter().find(|e| e.kind == EffectKind::EncoderOffset).expect("encoder offset result");
    assert!(e.worsening_units.iter().any(|u| u == "torso"), "no unit dropped: {:?}", e.worsening_units);
    assert!(score.param_errors.iter().all(|&x| x < 0.25), "{:?}", score.param_errors);
}

/// Issue 14, item 6: trial 13 of the Rapier benchmark's seed 22 (`--trials 40 --out-of-library 6 --seed 22`), an
/// encoder offset of -0.057 rad on the left elbow. It shifts the elbow's gravity torque as a COM shift of the forearm
/// does, and only the windows away from the range limits show either: a COM shift of -0.027 m was named there, the
/// offset not at all (its fit over every joint kept no unit), a confident misattribution. Fitted on the elbow the
/// COM shift was named on, the offset cuts those windows as much, so the report names the two as one ambiguous set,
/// with the offset near its true size.
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn an_elbow_encoder_offset_named_a_com_shift_on_part_of_the_windows_is_reported_with_it() {
    let (score, report) = benchmark_trial_on(diff_physics::EngineKind::RapierMultibody, 40, 6, 22, 13, None);
    assert_eq!(score.injected.len(), 1, "{:?}", score.injected);
    assert_eq!(score.injected[0].kind, EffectKind::EncoderOffset);
    assert_eq!(score.misattributed, 0, "ranking {:?}; ambiguous {:?}", report.ranked, report.ambiguous);
    let first = *report.ranked.first().expect("an effect named");
    if first != EffectKind::EncoderOffset {
        assert!(
            report.ambiguous.iter().any(|s| s.links(first, EffectKind::EncoderOffset)),
            "{first:?} named first without the offset beside it: {:?}",
            report.ambiguous
        );
    }
    let e = report.effects.iter().find(|e| e.kind == EffectKind::EncoderOffset).expect("encoder offset result");
    let p = e.params.iter().find(|p| p.unit == "left_elbow").expect("the offset fitted on the left elbow");
    assert!((p.value - -0.057).abs() < 0.015, "offset {} vs -0.057", p.value);
}

/// Runs trial `i` of the benchmark `--reference-engine engine --trials trials --out-of-library out_of_library --seed
/// seed --duration 15` as `ulab gap bench` does (its log written as MCAP and read back).
fn benchmark_trial(
    engine: diff_physics::EngineKind,
    trials: usize,
    out_of_library: usize,
    seed: u64,
    i: usize,
) -> (gap_bench::TrialScore, Report) {
    benchmark_trial_on(engine, trials, out_of_library, seed, i, None)
}

/// [`benchmark_trial`] diagnosed on at most `max_windows` windows (`None`: the default cap).
fn benchmark_trial_on(
    engine: diff_physics::EngineKind,
    trials: usize,
    out_of_library: usize,
    seed: u64,
    i: usize,
    max_windows: Option<usize>,
) -> (gap_bench::TrialScore, Report) {
    let mut opts = gap_bench::BenchOptions::new(trials, seed, INDEPENDENT_DURATION);
    opts.reference = EngineChoice::Other(engine);
    opts.out_of_library = out_of_library;
    opts.diagnose.max_windows = max_windows;
    common::run_trial_through_mcap(&model(), i, &opts)
}

/// Runs trial `i` of the Rapier benchmark `--trials trials --out-of-library 6 --seed seed --duration 15` as the
/// benchmark does, checks it hides the out-of-library effect `label` (kind, unit) and that nothing is named.
fn out_of_library_trial_names_nothing(trials: usize, seed: u64, i: usize, label: (&str, &str)) -> Report {
    out_of_library_trial_on(trials, seed, i, label, None)
}

/// [`out_of_library_trial_names_nothing`] diagnosed on at most `max_windows` windows.
fn out_of_library_trial_on(
    trials: usize,
    seed: u64,
    i: usize,
    label: (&str, &str),
    max_windows: Option<usize>,
) -> Report {
    let (score, report) =
        benchmark_trial_on(diff_physics::EngineKind::RapierMultibody, trials, 6, seed, i, max_windows);
    let ool = score.out_of_library.as_ref().expect("an out-of-library trial");
    assert_eq!((ool.kind.as_str(), ool.unit.as_str()), label, "{ool:?}");
    assert!(report.ranked.is_empty(), "named {:?} on a {}", report.ranked, label.0);
    report
}

/// The speed split of effect `kind` in `report`.
fn speed_split(report: &Report, kind: EffectKind) -> gap_diagnosis::diagnose::HalvesRefit {
    let e = report.effects.iter().find(|e| e.kind == kind).expect("effect assessed");
    e.splits.iter().find(|s| s.by == SplitBy::Speed).cloned().expect("a speed split")
}

/// Issue 14 item 5: out-of-library trial 5 of the Rapier benchmark's seed 1 (`ulab gap bench --reference-engine
/// rapier_multibody --trials 0 --out-of-library 6 --seed 1 --duration 15`): a friction of about 0.1 times the motor
/// torque against the motion of the right arm, outside the library. The library's damping fitted it better than
/// its friction and was named; refitted on the slowest and the fastest halves of the training windows, it wants far
/// more where the arm moves slowly, which a viscous torque cannot: the speed split sets it aside and nothing of the
/// library is named (the load split alone did not: this damping wants less, not more, under load).
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn a_load_friction_of_a_rapier_benchmark_trial_is_not_named_as_damping() {
    // On the default 64 windows the damping does not clear the floor: nothing is named, no split is needed.
    out_of_library_trial_names_nothing(0, 1, 5, ("load_friction", "right_arm"));
    // On the 300 windows the split was written for, it clears, and the speed split sets it aside.
    let report = out_of_library_trial_on(0, 1, 5, ("load_friction", "right_arm"), Some(300));
    let by_speed = speed_split(&report, EffectKind::Damping);
    assert!(by_speed.set_aside && by_speed.scale_low.lo > by_speed.scale_high.hi, "{by_speed:?}");
}

/// Issue 14 item 5, found blind: out-of-library trial 5 of the Rapier benchmark's seed 5 (`ulab gap bench
/// --reference-engine rapier_multibody --trials 2 --out-of-library 6 --seed 5 --duration 15`; the out-of-library
/// trials do not depend on the policies given): a friction of about 0.12 times the motor torque on the left leg.
/// The library's damping cleared the floor only on the held-out windows without those of largest gap, and was named;
/// its slow half of the training windows wants 3.6 times the fast half's scale, with intervals that touch (the
/// slowest windows barely move the leg). An effect cleared on part of the windows only is set aside by halves that
/// far apart in scale, and nothing of the library is named.
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn a_load_friction_cleared_on_part_of_the_windows_is_not_named_as_damping() {
    // As above: nothing named on the default 64 windows, and on the 300 the split was written for it sets the
    // damping aside.
    out_of_library_trial_names_nothing(2, 5, 5, ("load_friction", "left_leg"));
    let report = out_of_library_trial_on(2, 5, 5, ("load_friction", "left_leg"), Some(300));
    let by_speed = speed_split(&report, EffectKind::Damping);
    assert!(by_speed.set_aside && by_speed.cleared_on_part, "{by_speed:?}");
    assert!(by_speed.scale_low.value >= 2.0 * by_speed.scale_high.value, "{by_speed:?}");
}

/// Issue 14 item 5, found blind: out-of-library trial 0 of the Rapier benchmark's seed 6 (`ulab gap bench
/// --reference-engine rapier_multibody --trials 0 --out-of-library 6 --seed 6 --duration 15`): a torque ripple
/// periodic in the right knee's angle, fitted as a friction of 4.0 N·m and named. The inertia filters a ripple out
/// at speed, so the fitted friction cuts the gap of the slowest half of the training windows and not that of the
/// fastest half, which no Coulomb torque does: the speed split sets it aside and nothing is named (on the 300
/// windows it was written for). On the default 64 windows the split does not (the friction cuts the slow half's gap
/// 1.96 times the fast half's, just under its 2x; BENCHMARKS.md "How many windows"), and it was named until units
/// fitted at the bound of their search range were dropped: the friction stops at its 4.0 bound, its knee is
/// dropped, and nothing is named.
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn a_torque_ripple_fitted_as_a_friction_that_fades_with_speed_is_not_named() {
    let report = out_of_library_trial_names_nothing(0, 6, 0, ("torque_ripple", "right_knee"));
    let friction = report.effects.iter().find(|e| e.kind == EffectKind::Friction).expect("friction assessed");
    assert_eq!(friction.pinned_units, vec!["right_knee".to_string()], "{friction:?}");
    let report = out_of_library_trial_on(0, 6, 0, ("torque_ripple", "right_knee"), Some(300));
    let by_speed = speed_split(&report, EffectKind::Friction);
    assert!(by_speed.set_aside && by_speed.by_cut && by_speed.cut_low.lo > by_speed.cut_high.hi, "{by_speed:?}");
}

/// Issue 14 item 5, found blind: out-of-library trial 4 of the same seed-6 run: a torque ripple periodic in the right
/// ankle pitch's angle, fitted as a dead band (backlash) and named. A dead band loses its width at every load
/// reversal however fast the joint turns, yet the fitted one cuts the slowest half's gap about twice the fastest
/// half's (the benchmark's own backlashes cut the slow half's 0.01 to 0.97 times the fast half's): the speed split
/// sets it aside and nothing is named (on the 300 windows this was written for). On the default 64 windows no
/// dead band clears the floor; a friction of that joint does, on the windows away from the range limits only, and
/// cuts the slow half's gap 3.6 times the fast half's with intervals that touch: for an effect cleared on part of
/// the windows that suffices, and nothing is named either.
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn a_torque_ripple_fitted_as_a_dead_band_that_fades_with_speed_is_not_named() {
    let report = out_of_library_trial_names_nothing(0, 6, 4, ("torque_ripple", "right_ankle_pitch"));
    let by_speed = speed_split(&report, EffectKind::Friction);
    assert!(by_speed.set_aside && by_speed.by_cut && by_speed.cleared_on_part, "{by_speed:?}");
    assert!(by_speed.cut_low.lo <= by_speed.cut_high.hi, "intervals apart: not the case this checks {by_speed:?}");
    let report = out_of_library_trial_on(0, 6, 4, ("torque_ripple", "right_ankle_pitch"), Some(300));
    let by_speed = speed_split(&report, EffectKind::Backlash);
    assert!(by_speed.set_aside && by_speed.by_cut && by_speed.cut_low.lo > by_speed.cut_high.hi, "{by_speed:?}");
}

/// Issue 14 item 5, found blind: trial 6 of the DART benchmark's seed 8 (`ulab gap bench --reference-engine dart
/// --trials 8 --seed 8 --duration 15`): 12 ms latency and a dead band of 0.034 rad on the left leg. The band was
/// fitted (0.047) and set aside by its load split (the heavy half of the training windows wants 1.75x, the light
/// half 0.75x, intervals apart), and a friction and a gain scale were named in its place. A band is lost at every
/// reversal at any load, so it cuts the light half's gap too (39 per window at 0.5 % of the limit, 118 at 14 %),
/// where a friction growing with the load cuts nothing there: kept, the two injected effects are named and nothing
/// else. On the default 64 windows the two are named and nothing else, without the split contradicting the band;
/// on the 300 windows it was written for, the split keeps the band and its fitted value cuts the light half's gap.
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn a_leg_dead_band_that_wants_a_wider_band_under_load_is_still_named() {
    let (score, report) = benchmark_trial(diff_physics::EngineKind::Dart, 8, 0, 8, 6);
    assert!(score.all_found && score.misattributed == 0, "ranked {:?}", report.ranked);
    assert_eq!(report.ranked.len(), 2, "ranked {:?}", report.ranked);
    let (score, report) = benchmark_trial_on(diff_physics::EngineKind::Dart, 8, 0, 8, 6, Some(300));
    let mut injected: Vec<EffectKind> = score.injected.iter().map(|i| i.kind).collect();
    injected.sort_by_key(|k| k.name());
    assert_eq!(injected, vec![EffectKind::Backlash, EffectKind::Latency], "{:?}", score.injected);
    assert!(score.all_found && score.misattributed == 0, "ranked {:?}", report.ranked);
    assert_eq!(report.ranked.len(), 2, "ranked {:?}", report.ranked);
    let e = report.effects.iter().find(|e| e.kind == EffectKind::Backlash).expect("backlash assessed");
    let by_load = e.splits.iter().find(|s| s.by == SplitBy::Load).expect("a load split");
    // Since the split's bound fix (`81b9c95`) the heavy half wants 1.28x (the band's range bound), not 1.75x, so
    // the scales no longer contradict the band even here; the load-paced rule keeps its unit test
    // (`a_dead_band_whose_cut_grows_more_slowly_than_the_load_is_kept`, on this trial's numbers).
    assert!(by_load.load_paced && !by_load.set_aside, "{by_load:?}");
    assert!(by_load.cut_low.lo > 0.0, "{by_load:?}");
}

/// Issue 14, a sparse effect: trial 2 of the Rapier benchmark's seed 10 (`ulab gap bench --reference-engine
/// rapier_multibody --trials 8 --out-of-library 4 --seed 10 --duration 15`, blind before this rule): a friction on the
/// right leg and a torque saturation of the right knee at 0.49 of its limit, which the excitation reaches for a few
/// tens of milliseconds. The saturation's fit cut too little of the whole held-out gap to clear a floor and only the
/// friction was named; the log's own torque shows the knee held at 0.49 of its limit while the PD law asked for up
/// to 1.45 times that, and the saturation is named from it, on that joint, beside the friction.
#[test]
fn a_torque_ceiling_the_motion_reaches_in_a_few_windows_is_named_from_the_log() {
    let (score, report) = benchmark_trial(diff_physics::EngineKind::RapierMultibody, 8, 4, 10, 2);
    let mut injected: Vec<EffectKind> = score.injected.iter().map(|i| i.kind).collect();
    injected.sort_by_key(|k| k.name());
    assert_eq!(injected, vec![EffectKind::Friction, EffectKind::TorqueSaturation], "{:?}", score.injected);
    assert!(score.all_found && score.misattributed == 0, "ranked {:?}", report.ranked);
    assert_eq!(report.ranked.len(), 2, "ranked {:?}", report.ranked);
    let e = report.effects.iter().find(|e| e.kind == EffectKind::TorqueSaturation).expect("saturation assessed");
    assert_eq!(e.ceilings_in_log.len(), 1, "{:?}", e.ceilings_in_log);
    assert_eq!(e.ceilings_in_log[0].joint, "right_knee");
    assert!((e.ceilings_in_log[0].scale - 0.491).abs() < 0.02, "{:?}", e.ceilings_in_log);
    assert_eq!(e.params.len(), 1);
    assert_eq!(e.params[0].unit, "right_knee");
}

#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn single_joint_gain_scale() {
    check(EffectKind::GainScale, "left_shoulder_pitch", 0.65, "left_shoulder_pitch", 0.65);
}

/// No effect in a plant that is not MuJoCo: the engines' differences (integrator, joint-limit and friction models)
/// must not be named as an effect.
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn no_effect_in_an_independent_engine_no_confident_attribution() {
    let m = model();
    let rapier = EngineChoice::Other(diff_physics::EngineKind::RapierMultibody);
    let r = run_in(rapier, INDEPENDENT_DURATION, Effects::none(m.nj()), 12);
    assert!(r.ranked.is_empty(), "named on a no-effect Rapier log: {:?}", r.ranked);
}

/// Issue 14: pairs whose second effect the first masks (blind misses of the Rapier benchmark's seeds 15 and 16,
/// `ulab gap bench --reference-engine rapier_multibody --trials 24 --seed S --duration 15`, trials 22 and 18):
/// fitted alone, a left-knee damping under the left leg's armature, and a right-shoulder-roll friction under the
/// right arm's link mass, cut no unit's residual by the unit floor, so they were never offered to the selection.
/// Refitted on one joint with the first effect applied (`diagnose/unmask.rs`), each is named second, on its joint,
/// near its value; nothing else is named. Checked on the 300 windows it was written for: **on the default 64 the
/// knee damping of seed 15's trial 22 is not named** (the armature alone; BENCHMARKS.md "How many windows").
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn a_second_effect_masked_by_the_first_is_named_on_its_joint() {
    for (seed, i, first, second, joint, value) in [
        (15, 22, EffectKind::Armature, EffectKind::Damping, "left_knee", 1.52),
        (16, 18, EffectKind::LinkMass, EffectKind::Friction, "right_shoulder_roll", 2.22),
    ] {
        let (score, report) = benchmark_trial_on(diff_physics::EngineKind::RapierMultibody, 24, 0, seed, i, Some(300));
        let mut injected: Vec<EffectKind> = score.injected.iter().map(|i| i.kind).collect();
        injected.sort_by_key(|k| k.name());
        let mut want = vec![first, second];
        want.sort_by_key(|k| k.name());
        assert_eq!(injected, want, "seed {seed} trial {i}: {:?}", score.injected);
        assert_eq!(report.ranked, vec![first, second], "seed {seed} trial {i}: {:?}", report.abstentions);
        let e = report.effects.iter().find(|e| e.kind == second).expect("second effect");
        assert_eq!(e.params.len(), 1, "seed {seed} trial {i}: {:?}", e.params);
        assert_eq!(e.params[0].unit, joint);
        assert!((e.params[0].value - value).abs() < 0.25 * value, "seed {seed} trial {i}: {:?}", e.params);
    }
}

/// Issue 14 item 6, found blind: trial 6 of the Rapier benchmark's seed 20 (`ulab gap bench --reference-engine
/// rapier_multibody --trials 40 --out-of-library 6 --seed 20 --duration 15 --only 6`): 14 ms of latency and a torso
/// link 1.575 times heavier. On the suspended rig a heavier torso shows as inertia about the vertical waist axis, as
/// an added waist armature does. The armature kept a unit alone and the link mass did not, so given latency the
/// armature was the only one tried and was named second: a confident misattribution. Each candidate added after the
/// first is now checked as a masked effect's offer is: the link mass, refitted given latency, cuts what latency leaves
/// on the torso as much as the armature does, and the two are reported as one set the log cannot order.
#[test]
#[ignore = "nightly (scripts/nightly.sh): CI keeps the no-effect control and one benchmark trial"]
fn a_candidate_added_given_the_first_is_reported_with_the_masked_effect_it_cannot_be_told_from() {
    let (score, report) = benchmark_trial(diff_physics::EngineKind::RapierMultibody, 40, 6, 20, 6);
    let injected: Vec<EffectKind> = score.injected.iter().map(|i| i.kind).collect();
    assert_eq!(injected, vec![EffectKind::Latency, EffectKind::LinkMass], "{:?}", score.injected);
    assert_eq!(report.ranked.first(), Some(&EffectKind::Latency), "{:?}", report.ranked);
    assert_eq!(score.misattributed, 0, "ranked {:?}, sets {:?}", report.ranked, report.ambiguous);
    // Whatever stands second is in a set with the link mass, fitted on the torso.
    for &k in report.ranked.iter().skip(1).filter(|&&k| k != EffectKind::LinkMass) {
        assert!(report.ambiguous.iter().any(|s| s.links(k, EffectKind::LinkMass)), "{k:?}: {:?}", report.ambiguous);
    }
    let mass = report.effects.iter().find(|e| e.kind == EffectKind::LinkMass).expect("link mass assessed");
    assert!(mass.params.iter().any(|p| p.unit == "torso"), "{:?}", mass.params);
}
