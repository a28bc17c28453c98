//! Experiments on the candidate bugs of the 2026-11-25 campaign (issue 16, item 4), replayed from their
//! committed reproducers (`corpus/campaign-2026-11-25/`): each changes only the ingredient a triage names and
//! checks that the finding moves as that explanation predicts. The counterparts are the other engines on the same
//! state and torques: an engine is an outlier only against engines that agree with each other.
//!
//! - one-step joint-velocity divergences at touch-down (nine entries): with collisions off every pair of engines
//!   agrees within the bound, so they are contact differences; the largest (Rapier 23-25x, PhysX 21x on one
//!   landing) vanish when Rapier's speculative prediction distance or PhysX's contact offset goes to 0.1-0.2 mm
//!   (the engine then agrees with MuJoCo, Bullet and DART within the bound); on the hard landing where the engines
//!   split into two groups, stiffening MuJoCo's soft contact moves it towards the rigid engines.
//! - MuJoCo penetration 2.02 cm: the soft contact's compliance; it falls with the contact time constant.
//! - PhysX free-fall COM error (`physx` feature, `scripts/nightly.sh`): NOT the link angular-velocity clamp first
//!   suspected (lifting it changes nothing). In the step that breaks free fall PhysX reports no contact and no
//!   vertical force acts (COM z acceleration -9.79 m/s²), yet the COM accelerates 2.7 m/s² sideways; the error
//!   vanishes with the scene's friction offset threshold (4 cm, Isaac Lab's value) at 1 mm: friction from contact
//!   points that carry no normal impulse. Still a candidate bug (Coulomb: no friction without normal force);
//!   reproduced standalone with physx-sys alone (`corpus/campaign-2026-11-25/physx-flight-friction/`, from the
//!   scene dump below); a separated box sliding in PhysX 5.3 through SAPIEN gets no friction.
use diff_physics::mujoco::{MujocoEngine, MujocoSettings};
use diff_physics::{make_engine, CommonSettings, Engine, EngineError, EngineKind};
use engine_diff::harness::{self, EngineFactory, WindowRun};
use engine_diff::repro::Reproducer;
use robot_model::RobotModel;
use std::sync::Arc;

type Build = dyn Fn(&RobotModel, &CommonSettings) -> Result<Box<dyn Engine>, EngineError> + Send + Sync;

/// An engine with non-default settings, for one experiment.
struct Variant {
    name: String,
    build: Box<Build>,
}

impl std::fmt::Debug for Variant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Variant({})", self.name)
    }
}

impl EngineFactory for Variant {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn build(&self, model: &RobotModel, common: &CommonSettings) -> Result<Box<dyn Engine>, EngineError> {
        (self.build)(model, common)
    }
}

fn builtin(kind: EngineKind) -> Arc<dyn EngineFactory> {
    Arc::new(Variant { name: kind.name().into(), build: Box::new(move |m, c| make_engine(kind, m, c)) })
}

fn mujoco_with(settings: MujocoSettings) -> Arc<dyn EngineFactory> {
    Arc::new(Variant {
        name: "mujoco".into(),
        build: Box::new(move |m, c| Ok(Box::new(MujocoEngine::new(m, c, &settings)?) as Box<dyn Engine>)),
    })
}

fn load(file: &str) -> Reproducer {
    load_from("campaign-2026-11-25", file)
}

/// A reproducer of the campaign recorded in `corpus/{campaign}/`.
fn load_from(campaign: &str, file: &str) -> Reproducer {
    let path = format!("{}/../../corpus/{campaign}/{file}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// Replays the reproducer's window (its minimized length, or `steps`) on `factories` (lead first).
fn replay(r: &Reproducer, factories: &[Arc<dyn EngineFactory>], steps: Option<usize>) -> WindowRun {
    let model = RobotModel::h1_2().expect("built-in model");
    let m = harness::scenario_model(&model, &r.scenario);
    let w = r.window.input(m.nj()).expect("window");
    let mut engines = harness::build_engines(factories, &m, &r.common).expect("engines");
    harness::replay_window(&mut engines, &m, &w, steps.unwrap_or(r.steps), r.common.timestep, false).expect("replay")
}

/// The largest value of invariant `quantity` in engine `i` over the window, violated or not.
fn peak(run: &WindowRun, i: usize, quantity: &str) -> f64 {
    run.invariant_peaks[i].iter().find(|(q, _, _)| q == quantity).map_or(0.0, |x| x.1)
}

use engine_diff::harness::Div;

/// One-step joint-velocity difference between engines `i` and `j` of a run, over the finding's bound.
fn dq_ratio(r: &Reproducer, run: &WindowRun, i: usize, j: usize) -> f64 {
    let (a, b) = (&run.after_k[i], &run.after_k[j]);
    Div::between(&a.0, &a.1, &b.0, &b.1).max_dq() / r.finding.bound
}

const CPU_ENGINES: [EngineKind; 5] =
    [EngineKind::Mujoco, EngineKind::RapierMultibody, EngineKind::RapierImpulse, EngineKind::Bullet, EngineKind::Dart];

const TOUCHDOWN: [&str; 9] = [
    "gepetto-seed12-D01.json",
    "gepetto-seed12-D02.json",
    "gepetto-seed12-D03.json",
    "gepetto-seed12-D04.json",
    "gepetto-seed12-D05.json",
    "gepetto-seed13-D01.json",
    "gepetto-seed13-D02.json",
    "gepetto-seed13-D03.json",
    "lstm-seed12-D01.json",
];

#[test]
fn touchdown_divergences_are_contact_differences() {
    let f: Vec<_> = CPU_ENGINES.iter().map(|k| builtin(*k)).collect();
    for file in TOUCHDOWN {
        let r = load(file);
        assert_eq!((r.finding.kind.as_str(), r.finding.quantity.as_str()), ("one_step_bound", "joint velocity"));
        let with = replay(&r, &f, Some(1));
        let mut off = r.clone();
        off.common.collisions = false;
        let without = replay(&off, &f, Some(1));
        let mut worst = (0.0_f64, 0.0_f64);
        for i in 0..f.len() {
            for j in i + 1..f.len() {
                worst.0 = worst.0.max(dq_ratio(&r, &with, i, j));
                worst.1 = worst.1.max(dq_ratio(&r, &without, i, j));
            }
        }
        eprintln!(
            "{file}: largest pairwise one-step joint-velocity difference / bound: {:.2} with contacts, {:.2} without",
            worst.0, worst.1
        );
        // The finding is there (some pair exceeds the bound); without contacts every pair is back at the bound
        // or below it (measured 0.24-1.03): what exceeds it comes from the contact models, not from the joints,
        // the integrators or the torques. The two marginal findings (1.03x and 1.17x of the bound) sit where the
        // engines already are without contact; for every other the contact-free difference is under a quarter.
        assert!(worst.0 > 1.0, "{file}: no pair exceeds the bound with contacts ({})", worst.0);
        assert!(worst.1 < 1.05, "{file}: engines disagree without contacts ({})", worst.1);
        if worst.0 > 2.0 {
            assert!(worst.1 < 0.35 * worst.0, "{file}: contacts explain little ({worst:?})");
        }
    }
}

#[test]
fn rapier_touchdown_outlier_is_its_speculative_margin() {
    use diff_physics::rapier_multibody::{RapierMultibodyEngine, RapierMultibodySettings};
    let r = load("gepetto-seed13-D02.json");
    let rapier = |prediction: f64| -> Arc<dyn EngineFactory> {
        let mut s = RapierMultibodySettings::default();
        s.solver.prediction_distance_m = prediction;
        Arc::new(Variant {
            name: "rapier_multibody".into(),
            build: Box::new(move |m, c| Ok(Box::new(RapierMultibodyEngine::new(m, c, &s)?) as Box<dyn Engine>)),
        })
    };
    let others = [EngineKind::Mujoco, EngineKind::Bullet, EngineKind::Dart];
    let ratios = |prediction: f64| -> Vec<f64> {
        let mut f: Vec<_> = others.iter().map(|k| builtin(*k)).collect();
        f.push(rapier(prediction));
        let run = replay(&r, &f, Some(1));
        (0..others.len()).map(|j| dq_ratio(&r, &run, 3, j)).collect()
    };
    let default = ratios(RapierMultibodySettings::default().solver.prediction_distance_m);
    let thin = ratios(1e-4);
    eprintln!("Rapier multibody against MuJoCo, Bullet, DART: {default:.2?} (5 mm prediction), {thin:.2?} (0.1 mm)");
    // The three other engines agree with each other (checked by the first test's matrix: <= 0.9x); Rapier is
    // the outlier against every one of them, and only because it engages contacts before the foot touches.
    assert!(default.iter().all(|&x| x > 10.0), "{default:?}");
    assert!(thin.iter().all(|&x| x < 1.0), "{thin:?}");
}

#[test]
fn stiffer_soft_contact_moves_mujoco_towards_the_rigid_engines() {
    let r = load("gepetto-seed12-D05.json");
    let ratios = |timeconst: f64| -> (f64, f64) {
        let s = MujocoSettings { solref: [timeconst, 1.0], ..MujocoSettings::default() };
        let f = vec![mujoco_with(s), builtin(EngineKind::Dart), builtin(EngineKind::RapierMultibody)];
        let run = replay(&r, &f, Some(1));
        (dq_ratio(&r, &run, 0, 1), dq_ratio(&r, &run, 0, 2))
    };
    let soft = ratios(0.02);
    let stiff = ratios(0.004);
    eprintln!("MuJoCo against DART, Rapier multibody: {soft:.2?} (solref 0.02 s), {stiff:.2?} (0.004 s = 2 steps)");
    // DART's and Rapier's rigid contacts stop the landing foot within the step; MuJoCo's soft contact builds its
    // force over its time constant. Making it stiffer must bring MuJoCo towards both.
    assert!(stiff.0 < 0.5 * soft.0 && stiff.1 < 0.5 * soft.1, "{soft:?} -> {stiff:?}");
}

#[test]
fn mujoco_penetration_is_its_soft_contact() {
    let r = load("lstm-seed12-D02.json");
    assert_eq!(r.finding.quantity, "penetration depth");
    let depth = |timeconst: f64| -> (f64, f64) {
        let s = MujocoSettings { solref: [timeconst, 1.0], ..MujocoSettings::default() };
        let run = replay(&r, &[mujoco_with(s), builtin(EngineKind::Dart)], None);
        (peak(&run, 0, &r.finding.quantity), peak(&run, 1, &r.finding.quantity))
    };
    let series: Vec<(f64, (f64, f64))> = [0.02, 0.014, 0.01, 0.007].into_iter().map(|t| (t, depth(t))).collect();
    for (t, (m, d)) in &series {
        eprintln!("solref time constant {t} s: MuJoCo penetration {:.2} mm (DART, rigid: {:.2} mm)", m * 1e3, d * 1e3);
    }
    let (m0, dart) = series[0].1;
    assert!(m0 > r.finding.bound, "the finding is gone at the default contact ({m0})");
    // Softness, not a collision defect: the depth falls with every step of the time constant, and the rigid
    // DART keeps the foot at the start's penetration (the window starts a few mm in).
    assert!(series.windows(2).all(|w| w[1].1 .0 < w[0].1 .0), "{series:?}");
    assert!(series[2].1 .0 < 0.6 * m0, "{series:?}");
    assert!(dart < 0.5 * m0, "DART sinks as deep ({dart})");
}

#[cfg(feature = "physx")]
mod physx {
    use super::*;
    use diff_physics::physx::{PhysxEngine, PhysxSettings};

    fn physx(s: PhysxSettings) -> Arc<dyn EngineFactory> {
        Arc::new(Variant {
            name: "physx".into(),
            build: Box::new(move |m, c| Ok(Box::new(PhysxEngine::new(m, c, &s)?) as Box<dyn Engine>)),
        })
    }

    #[test]
    fn physx_flight_friction_is_its_friction_offset_threshold() {
        let r = load("gepetto-seed12-D06.json");
        let error = |s: PhysxSettings| -> f64 {
            let run = replay(&r, &[builtin(EngineKind::Mujoco), physx(s)], None);
            peak(&run, 1, &r.finding.quantity)
        };
        let d = PhysxSettings::default();
        let default = error(d.clone());
        let no_clamp = error(PhysxSettings { max_link_angular_velocity: 1e7, ..d.clone() });
        let thin = error(PhysxSettings { friction_offset_threshold: 0.001, ..d.clone() });
        eprintln!(
            "PhysX free-fall COM error (bound {:.2} m/s²): {default:.3} default, {no_clamp:.3} angular-velocity clamp \
             lifted, {thin:.3} friction offset threshold 1 mm",
            r.finding.bound
        );
        assert!(default > r.finding.bound);
        // The first suspicion, the link angular-velocity clamp, is refuted: lifting it changes nothing.
        assert!((no_clamp - default).abs() < 1e-9 * default.max(1.0), "{no_clamp} vs {default}");
        // Friction for points within the threshold that carry no normal impulse: gone with a 1-mm threshold.
        assert!(thin < 0.1 * r.finding.bound, "{thin}");
        // ...while PhysX reports no contact at all in the window.
        let model = RobotModel::h1_2().expect("model");
        let m = harness::scenario_model(&model, &r.scenario);
        let w = r.window.input(m.nj()).expect("window");
        let mut engines = harness::build_engines(&[physx(d)], &m, &r.common).expect("engine");
        harness::replay_window(&mut engines, &m, &w, r.steps, r.common.timestep, false).expect("replay");
        assert!(engines[0].contacts().is_empty(), "PhysX reports a contact at the end of the window");
    }

    /// The standalone reproducer's scene (`corpus/campaign-2026-11-25/physx-flight-friction/scene.txt`, read by
    /// the `physx-sys`-only program there): what the adapter hands PhysX for D06's window (world, state, the joint
    /// forces of every step), recorded from the same replay as the test above. Fails when the committed file is
    /// no longer what the adapter produces; `ULAB_WRITE_SCENE=1` rewrites it.
    #[test]
    fn physx_flight_friction_scene_dump_is_current() {
        let r = load("gepetto-seed12-D06.json");
        let text = Arc::new(std::sync::Mutex::new(String::new()));
        let rec = Arc::clone(&text);
        let factory = Arc::new(Variant {
            name: "physx".into(),
            build: Box::new(move |m, c| {
                let mut e = PhysxEngine::new(m, c, &PhysxSettings::default())?;
                e.record_scene(Arc::clone(&rec));
                Ok(Box::new(e) as Box<dyn Engine>)
            }),
        }) as Arc<dyn EngineFactory>;
        let run = replay(&r, &[factory], None);
        let error = peak(&run, 0, &r.finding.quantity);
        assert!(error > r.finding.bound, "the finding is gone ({error})");
        let body = text.lock().expect("recording").clone();
        assert_eq!(body.lines().filter(|l| l.starts_with("force ")).count(), r.steps);
        let model = RobotModel::h1_2().expect("built-in model");
        let names: Vec<String> = model.links.iter().enumerate().map(|(i, l)| format!("{i} {}", l.name)).collect();
        let dump = format!(
            "# PhysX scene dump (format: README.md here; ulab's crates/diff-physics/src/physx/dump.rs): the H1-2 of\n\
             # corpus/campaign-2026-11-25/gepetto-seed12-D06.json, its {} steps from the window start, as ulab's\n\
             # PhysX adapter hands them to PhysX 5.1.3 (physx-sys 0.11.5). Written by engine-diff's test\n\
             # campaign_triage::physx::physx_flight_friction_scene_dump_is_current (ULAB_WRITE_SCENE=1).\n\
             # links: {}\n{body}",
            r.steps,
            names.join(", ")
        );
        let path =
            format!("{}/../../corpus/campaign-2026-11-25/physx-flight-friction/scene.txt", env!("CARGO_MANIFEST_DIR"));
        if std::env::var("ULAB_WRITE_SCENE").is_ok_and(|v| v == "1") {
            std::fs::write(&path, &dump).unwrap_or_else(|e| panic!("{path}: {e}"));
        }
        let committed = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        assert!(committed == dump, "{path} is stale: rewrite it with ULAB_WRITE_SCENE=1");
    }

    #[test]
    fn physx_touchdown_outlier_is_its_contact_offset() {
        let r = load("gepetto-seed13-D03.json");
        let others = [EngineKind::Mujoco, EngineKind::Bullet, EngineKind::Dart];
        let ratios = |offset: f64| -> Vec<f64> {
            let mut f: Vec<_> = others.iter().map(|k| builtin(*k)).collect();
            f.push(physx(PhysxSettings { contact_offset: offset, ..PhysxSettings::default() }));
            let run = replay(&r, &f, Some(1));
            (0..others.len()).map(|j| dq_ratio(&r, &run, 3, j)).collect()
        };
        let default = ratios(PhysxSettings::default().contact_offset);
        let thin = ratios(2e-4);
        eprintln!("PhysX against MuJoCo, Bullet, DART: {default:.2?} (1 cm contact offset), {thin:.2?} (0.2 mm)");
        assert!(default.iter().all(|&x| x > 10.0), "{default:?}");
        assert!(thin.iter().all(|&x| x < 1.0), "{thin:?}");
    }
}

/// Newton (`newton` feature, `scripts/nightly.sh`; issue 61): the candidates of the Newton campaign
/// (`corpus/newton-2026-12-03/`), Steel's and Featherstone's one-step joint velocity with feet on the ground.
#[cfg(feature = "newton")]
mod newton {
    use super::*;

    const NAMES: [&str; 5] = ["mujoco", "bullet", "dart", "newton_featherstone", "newton_steel"];
    const FEATHERSTONE: usize = 3;
    const STEEL: usize = 4;

    type Matrix = Vec<Vec<f64>>;

    /// One-step joint-velocity difference / bound between every pair of `NAMES` on the reproducer's first step:
    /// with contacts (MuJoCo's solref time constant 0.02 s), with MuJoCo stiffened to 0.004 s (two steps), and
    /// with collisions off.
    fn matrices(file: &str) -> (Reproducer, Matrix, Matrix, Matrix) {
        let r = load_from("newton-2026-12-03", file);
        let rest = [EngineKind::Bullet, EngineKind::Dart, EngineKind::NewtonFeatherstone, EngineKind::NewtonSteel];
        let matrix = |r: &Reproducer, timeconst: f64| -> Matrix {
            let s = MujocoSettings { solref: [timeconst, 1.0], ..MujocoSettings::default() };
            let mut f = vec![mujoco_with(s)];
            f.extend(rest.iter().map(|k| builtin(*k)));
            let run = replay(r, &f, Some(1));
            (0..f.len()).map(|i| (0..f.len()).map(|j| dq_ratio(r, &run, i, j)).collect()).collect()
        };
        let soft = matrix(&r, 0.02);
        let stiff = matrix(&r, 0.004);
        let mut off = r.clone();
        off.common.collisions = false;
        let free = matrix(&off, 0.02);
        for (label, m) in [("with contacts", &soft), ("MuJoCo solref 0.004 s", &stiff), ("collisions off", &free)] {
            eprintln!("{file}: one-step joint-velocity difference / bound, {label} ({NAMES:?}):");
            for (n, row) in NAMES.iter().zip(m.iter()) {
                eprintln!("  {n:>20}: {row:.2?}");
            }
        }
        (r, soft, stiff, free)
    }

    /// Steel's contact rows are rigid, velocity-level constraints; MuJoCo's contacts are soft. If Steel's excess
    /// is that difference, it must vanish without collisions and shrink when only MuJoCo's contact is made stiff.
    #[test]
    fn steel_ground_contact_is_rigid_against_soft_contact() {
        for file in [
            "steel-double-support-D01.json",
            "fuzz-gepetto_demo_rsl-D01.json",
            "fuzz-unitree_rl_gym_lstm-D01.json",
            "fuzz-excitation-D01.json",
            "fuzz-unitree_rl_gym_lstm-min5-D04.json",
        ] {
            let (r, soft, stiff, free) = matrices(file);
            assert_eq!((r.finding.engine.as_str(), r.finding.quantity.as_str()), ("newton_steel", "joint velocity"));
            let (with, stiffened) = (soft[STEEL][0], stiff[STEEL][0]);
            eprintln!(
                "{file}: Steel against MuJoCo {with:.2} (solref 0.02 s) -> {stiffened:.2} (0.004 s), without \
                 collisions {:.2}; against Bullet {:.2}, DART {:.2}, Featherstone {:.2}",
                free[STEEL][0], soft[STEEL][1], soft[STEEL][2], soft[STEEL][FEATHERSTONE]
            );
            assert!(with > 1.0, "{file}: the finding is gone ({with})");
            // Without contacts Steel agrees with MuJoCo, DART and Featherstone to a few hundredths of the bound:
            // the excess comes from the contact models. (Bullet is up to about the bound from all four even
            // without contacts, as in the touch-down test above, so it is no counterpart for this check.)
            for j in [0, 2, FEATHERSTONE] {
                assert!(
                    free[STEEL][j] < 0.35 * with.min(1.0),
                    "{file}: Steel vs {} without contacts: {free:?}",
                    NAMES[j]
                );
            }
            // Stiffening only MuJoCo's soft contact must bring it towards Steel's rigid rows: the difference is the
            // softness, not Steel's joints or integrator.
            assert!(stiffened < 0.5 * with, "{file}: {with} -> {stiffened}");
            // And the allow-list entry written from this experiment covers the recorded finding.
            let allow = engine_diff::triage::AllowList::builtin().expect("allow-list");
            let id = allow.matching(&r.finding).map(|e| e.id.as_str());
            assert_eq!(id, Some("steel-rigid-contact-rows"), "{file}: {:?}", r.finding);
        }
    }

    /// The finding's quantity (joint or base linear velocity) between engines `i` and `j` after one step, over
    /// the finding's bound.
    fn ratio(r: &Reproducer, run: &WindowRun, i: usize, j: usize) -> f64 {
        let (a, b) = (&run.after_k[i], &run.after_k[j]);
        let d = Div::between(&a.0, &a.1, &b.0, &b.1);
        let x = match r.finding.quantity.as_str() {
            "base linear velocity" => d.base_lin_vel,
            "joint velocity" => d.max_dq(),
            q => panic!("no ratio for {q}"),
        };
        x / r.finding.bound
    }

    fn newton_with(s: NewtonSettings) -> Arc<dyn EngineFactory> {
        use diff_physics::newton::NewtonEngine;
        Arc::new(Variant {
            name: s.solver.kind().name().into(),
            build: Box::new(move |m, c| Ok(Box::new(NewtonEngine::new(m, c, &s)?) as Box<dyn Engine>)),
        })
    }

    use diff_physics::newton::{NewtonSettings, NewtonSolver};

    /// Every engine's one-step ratio from the lead (index 0).
    fn from_lead(r: &Reproducer, f: &[Arc<dyn EngineFactory>]) -> Vec<f64> {
        let run = replay(r, f, Some(1));
        (0..f.len()).map(|j| ratio(r, &run, j, 0)).collect()
    }

    /// Steel's base linear velocity in double support (lstm D05, 1.07 times the bound): the same rigid contact
    /// rows as its joint velocities above. It must vanish without collisions and when only MuJoCo's contact is
    /// made stiff.
    #[test]
    fn steel_base_velocity_in_double_support_is_the_same_rigid_contact() {
        let file = "fuzz-unitree_rl_gym_lstm-min5-D05.json";
        let r = load_from("newton-2026-12-03", file);
        assert_eq!((r.finding.engine.as_str(), r.finding.quantity.as_str()), ("newton_steel", "base linear velocity"));
        let rest = [EngineKind::Bullet, EngineKind::Dart, EngineKind::NewtonFeatherstone, EngineKind::NewtonSteel];
        let engines = |timeconst: f64| {
            let mut f = vec![mujoco_with(MujocoSettings { solref: [timeconst, 1.0], ..MujocoSettings::default() })];
            f.extend(rest.iter().map(|k| builtin(*k)));
            f
        };
        let mut off = r.clone();
        off.common.collisions = false;
        let (soft, stiff, free) =
            (from_lead(&r, &engines(0.02)), from_lead(&r, &engines(0.004)), from_lead(&off, &engines(0.02)));
        eprintln!(
            "{file}: base linear velocity difference / bound from MuJoCo ({NAMES:?}): solref 0.02 s {soft:.2?}, \
             0.004 s {stiff:.2?}, collisions off {free:.2?}"
        );
        let with = soft[STEEL];
        assert!(with > 1.0, "{file}: the finding is gone ({with})");
        assert!(free[STEEL] < 0.35 * with.min(1.0), "{file}: Steel without contacts {free:?}");
        assert!(stiff[STEEL] < 0.5 * with, "{file}: {with} -> {}", stiff[STEEL]);
        let allow = engine_diff::triage::AllowList::builtin().expect("allow-list");
        let id = allow.matching(&r.finding).map(|e| e.id.as_str());
        assert_eq!(id, Some("steel-rigid-contact-rows"), "{file}: {:?}", r.finding);
    }

    /// Featherstone applies its penalty contact forces (spring `contact_ke`, damper `contact_kd`, viscous friction
    /// `contact_kf` up to Coulomb's limit) explicitly, from the state the step starts from, in a semi-implicit
    /// Euler step, which Newton documents as needing a step small enough for the stiffness and damping. If the
    /// lstm D02/D03 excess is that step's discretisation of the contact, it must vanish without collisions and
    /// when the same contact law is integrated in sub-steps, and converge there; the engines that solve contact
    /// implicitly (DART, Rapier multibody) must agree with MuJoCo on these windows (MuJoCo is not the outlier).
    #[test]
    fn featherstone_excess_is_its_explicit_penalty_contact_in_one_step() {
        for file in ["fuzz-unitree_rl_gym_lstm-min5-D02.json", "fuzz-unitree_rl_gym_lstm-min5-D03.json"] {
            let r = load_from("newton-2026-12-03", file);
            assert_eq!(
                (r.finding.engine.as_str(), r.finding.quantity.as_str()),
                ("newton_featherstone", "joint velocity")
            );
            let sub = |n: u32| {
                newton_with(NewtonSettings { substeps: n, ..NewtonSettings::for_solver(NewtonSolver::Featherstone) })
            };
            let f = vec![
                builtin(EngineKind::Mujoco),
                builtin(EngineKind::Dart),
                builtin(EngineKind::RapierMultibody),
                sub(1),
                sub(4),
                sub(20),
            ];
            let names =
                ["mujoco", "dart", "rapier_multibody", "featherstone x1", "featherstone x4", "featherstone x20"];
            let with = from_lead(&r, &f);
            let mut off = r.clone();
            off.common.collisions = false;
            let free = from_lead(&off, &f);
            eprintln!(
                "{file}: joint velocity difference / bound from MuJoCo ({names:?}, xN: N sub-steps per 2 ms): with \
                 contacts {with:.2?}, collisions off {free:.2?}"
            );
            assert!(with[3] > 1.0, "{file}: the finding is gone ({with:?})");
            assert!(free[3] < 0.35, "{file}: Featherstone without contacts {free:?}");
            // The implicit-contact engines agree with MuJoCo here: the outlier is the one-step Featherstone.
            assert!(with[1] < 1.0 && with[2] < 1.0, "{file}: DART / Rapier multibody {with:?}");
            // The same contact law in 0.5 ms sub-steps is under the bound, and 0.1 ms sub-steps change little more.
            assert!(with[4] < 1.0, "{file}: four sub-steps {with:?}");
            assert!((with[5] - with[4]).abs() < 0.1, "{file}: not converged in time {with:?}");
            let allow = engine_diff::triage::AllowList::builtin().expect("allow-list");
            let id = allow.matching(&r.finding).map(|e| e.id.as_str());
            assert_eq!(id, Some("featherstone-explicit-penalty-contact"), "{file}: {:?}", r.finding);
        }
    }

    /// The one-step sweeps docs/newton.md quotes for D02/D03 (a measurement, printed; no assertion): Featherstone's
    /// penalty stiffness, damping and friction slope, ground friction off for every engine, MuJoCo stiffened.
    /// `cargo test -p engine-diff --features newton --test it -- --ignored featherstone_contact_parameter_sweep`.
    #[test]
    #[ignore = "a measurement for docs/newton.md (about 2 min), no assertion"]
    fn featherstone_contact_parameter_sweep() {
        let fs = |s: NewtonSettings| vec![builtin(EngineKind::Mujoco), newton_with(s)];
        let base = || NewtonSettings::for_solver(NewtonSolver::Featherstone);
        for file in ["fuzz-unitree_rl_gym_lstm-min5-D02.json", "fuzz-unitree_rl_gym_lstm-min5-D03.json"] {
            let r = load_from("newton-2026-12-03", file);
            let kinds = [
                EngineKind::Mujoco,
                EngineKind::Bullet,
                EngineKind::Dart,
                EngineKind::RapierMultibody,
                EngineKind::RapierImpulse,
                EngineKind::NewtonFeatherstone,
                EngineKind::NewtonSteel,
            ];
            let f: Vec<_> = kinds.iter().map(|k| builtin(*k)).collect();
            let names: Vec<&str> = kinds.iter().map(|k| k.name()).collect();
            eprintln!("{file}: {names:?} from MuJoCo: {:.2?}", from_lead(&r, &f));
            let mut nf = r.clone();
            nf.scenario.ground_friction = Some(0.0);
            eprintln!("{file}: ground friction 0: {:.2?}", from_lead(&nf, &f));
            let stiff = vec![
                mujoco_with(MujocoSettings { solref: [0.004, 1.0], ..MujocoSettings::default() }),
                builtin(EngineKind::NewtonFeatherstone),
            ];
            eprintln!("{file}: Featherstone from MuJoCo with solref 0.004 s: {:.2}", from_lead(&r, &stiff)[1]);
            for ke in [3e4, 1e5, 3e5, 1e6] {
                let x = from_lead(&r, &fs(NewtonSettings { contact_ke: ke, ..base() }))[1];
                eprintln!("{file}: Featherstone contact_ke {ke:.0e} N/m: {x:.2}");
            }
            for kd in [1.0, 1e2, 3e2, 1e3, 3e3] {
                let x = from_lead(&r, &fs(NewtonSettings { contact_kd: kd, ..base() }))[1];
                eprintln!("{file}: Featherstone contact_kd {kd:.0e} N s/m: {x:.2}");
            }
            for kf in [1e2, 3e2, 1e3, 1e4] {
                let x = from_lead(&r, &fs(NewtonSettings { contact_kf: kf, ..base() }))[1];
                eprintln!("{file}: Featherstone contact_kf {kf:.0e} N s/m: {x:.2}");
            }
        }
    }
}
