//! Measured evidence for allow-list entries (issue 16, item 2): each experiment changes only the ingredient the
//! entry's rationale names and checks that the difference behaves as that rationale predicts. The counterpart
//! of every measurement is MuJoCo (an independent engine) on the same state and torques.
//!
//! - `soft-vs-speculative-contact`: the one-step difference is a CONTACT difference: from the same state with
//!   the feet on the ground it exceeds the bound, from the same state 0.2 m up (no contact can happen within the
//!   step) it is far below it.
//! - `impulse-joint-compliance`: the difference is the JOINT FORMULATION: in free flight, without any contact,
//!   with every joint driven hard (PD target 0.3 rad away), the impulse-joint engine drifts from MuJoCo ~20x
//!   further than the reduced-coordinate Rapier on the same solver. The entry's first rationale (slow
//!   convergence of the iterative joint solve) is REFUTED by the measurement: 8x the iterations and half the
//!   step leave the drift unchanged; turning the armature off removes the excess, so the cause is the armature
//!   approximation of maximal coordinates (the rationale now says so).
//! - every entry: `clean_runs_stay_under_every_cap` measures what each entry absorbs in clean runs; the caps in
//!   `allowlist.toml` are 1.5x those measurements.
use diff_physics::pd::pd_torques_into;
use diff_physics::{make_engine, CommonSettings, EngineKind, PdTarget, State};
use engine_diff::harness::Bounds;
use engine_diff::triage::AllowList;
use robot_model::RobotModel;

fn model() -> RobotModel {
    RobotModel::h1_2().expect("built-in model")
}

/// Steps `kind` and MuJoCo `steps` times from `start` with the PD law holding the standing pose (torques from
/// each engine's own state), and returns (base linear velocity difference after the first step, largest link
/// position difference after the last).
fn diverge(m: &RobotModel, kind: EngineKind, common: &CommonSettings, start: &State, steps: usize) -> (f64, f64) {
    diverge_to(m, kind, common, start, steps, &PdTarget::hold_standing(m))
}

fn diverge_to(
    m: &RobotModel,
    kind: EngineKind,
    common: &CommonSettings,
    start: &State,
    steps: usize,
    target: &PdTarget,
) -> (f64, f64) {
    let limits: Vec<f64> = m.joints.iter().map(|j| j.torque_limit).collect();
    let mut engines =
        [make_engine(EngineKind::Mujoco, m, common).expect("mujoco"), make_engine(kind, m, common).expect("engine")];
    let mut tau = vec![0.0; m.nj()];
    let mut first = [[0.0; 3]; 2];
    for (i, e) in engines.iter_mut().enumerate() {
        e.reset(start).expect("reset");
        for s in 0..steps {
            let st = e.state();
            pd_torques_into(target, &st.q, &st.dq, &limits, &mut tau);
            e.step(&tau).expect("step");
            if s == 0 {
                first[i] = e.state().base_lin_vel;
            }
        }
    }
    let dv = first[0].iter().zip(&first[1]).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
    let (a, b) = (engines[0].link_poses(), engines[1].link_poses());
    let dl = a
        .iter()
        .zip(&b)
        .map(|(x, y)| x.pos.iter().zip(&y.pos).map(|(p, q)| (p - q).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    (dv, dl)
}

fn entry_cap(id: &str) -> f64 {
    AllowList::builtin().expect("allow-list").entries.iter().find(|e| e.id == id).expect("entry").max_ratio
}

#[test]
fn soft_vs_speculative_contact_is_a_contact_difference() {
    let m = model();
    let common = CommonSettings::default();
    let bound = Bounds::new(common.timestep, 1).one_step_base_lin_vel;
    let standing = State::standing(&m);
    let mut lifted = standing.clone();
    lifted.base_pos[2] += 0.2;
    for kind in [EngineKind::RapierMultibody, EngineKind::RapierImpulse] {
        let (on_ground, _) = diverge(&m, kind, &common, &standing, 1);
        let (in_flight, _) = diverge(&m, kind, &common, &lifted, 1);
        eprintln!(
            "{}: one-step base velocity difference / bound: standing {:.3}, 0.2 m up {:.2e} (cap {})",
            kind.name(),
            on_ground / bound,
            in_flight / bound,
            entry_cap("soft-vs-speculative-contact")
        );
        // Without contact the engines agree to a small fraction of the bound; with contact they do not.
        assert!(in_flight < 0.05 * bound, "{}: {in_flight} without contact", kind.name());
        assert!(
            on_ground > 10.0 * in_flight,
            "{}: contact adds no difference ({on_ground} vs {in_flight})",
            kind.name()
        );
        assert!(on_ground / bound <= entry_cap("soft-vs-speculative-contact"), "{}: beyond the cap", kind.name());
    }
}

#[test]
fn impulse_joint_compliance_is_the_armature_approximation_not_solver_convergence() {
    use diff_physics::rapier_impulse::{RapierImpulseEngine, RapierImpulseSettings};
    let m = model();
    let horizon = 0.05;
    let mut start = State::standing(&m);
    start.base_pos[2] += 0.5;
    let mut target = PdTarget::hold_standing(&m);
    for (q, j) in target.q_des.iter_mut().zip(&m.joints) {
        *q = (*q + 0.3).clamp(j.lower, j.upper);
    }
    let common = CommonSettings { ground: false, ..CommonSettings::default() };
    let steps = (horizon / common.timestep).round() as usize;
    let bound = Bounds::new(common.timestep, steps).k_step_link_pos;
    let (_, d_impulse) = diverge_to(&m, EngineKind::RapierImpulse, &common, &start, steps, &target);
    let (_, d_multibody) = diverge_to(&m, EngineKind::RapierMultibody, &common, &start, steps, &target);
    // The same at dt 1 ms: a discretisation error would halve.
    let fine = CommonSettings { timestep: 0.001, ..common.clone() };
    let (_, d_impulse_fine) = diverge_to(&m, EngineKind::RapierImpulse, &fine, &start, 2 * steps, &target);
    // Without armature (the reflected rotor inertia, which maximal coordinates cannot put on a joint axis).
    let no_arm = CommonSettings { armature: false, joint_damping: false, joint_friction: false, ..common.clone() };
    let (_, d_impulse_no_arm) = diverge_to(&m, EngineKind::RapierImpulse, &no_arm, &start, steps, &target);
    let (_, d_multibody_no_arm) = diverge_to(&m, EngineKind::RapierMultibody, &no_arm, &start, steps, &target);
    eprintln!("without armature, damping, friction: rapier_impulse {d_impulse_no_arm:.3e} m, rapier_multibody {d_multibody_no_arm:.3e} m");
    // The same engine with 8 instead of 1 Gauss-Seidel iteration per substep (everything else unchanged).
    let mut more = RapierImpulseSettings::default();
    more.solver.pgs_iterations_per_substep = 8;
    more.solver.stabilization_iterations_per_substep = 8;
    let converged = {
        let mut e = RapierImpulseEngine::new(&m, &common, &more).expect("engine");
        let mut lead = make_engine(EngineKind::Mujoco, &m, &common).expect("mujoco");
        let limits: Vec<f64> = m.joints.iter().map(|j| j.torque_limit).collect();
        let mut tau = vec![0.0; m.nj()];
        for eng in [&mut e as &mut dyn diff_physics::Engine, lead.as_mut()] {
            eng.reset(&start).expect("reset");
            for _ in 0..steps {
                let st = eng.state();
                pd_torques_into(&target, &st.q, &st.dq, &limits, &mut tau);
                eng.step(&tau).expect("step");
            }
        }
        let (a, b) = (lead.link_poses(), diff_physics::Engine::link_poses(&mut e));
        a.iter()
            .zip(&b)
            .map(|(x, y)| x.pos.iter().zip(&y.pos).map(|(p, q)| (p - q).powi(2)).sum::<f64>().sqrt())
            .fold(0.0, f64::max)
    };
    eprintln!(
        "{horizon} s of free flight, joints driven 0.3 rad: largest link divergence from MuJoCo: rapier_impulse \
         {d_impulse:.3e} m ({:.3} of the bound; dt 1 ms: {d_impulse_fine:.3e}; 8 iterations/substep: {converged:.3e}), \
         rapier_multibody {d_multibody:.3e} m (cap of the entry {})",
        d_impulse / bound,
        entry_cap("impulse-joint-compliance")
    );
    // The reduced-coordinate Rapier (same solver, same contacts: none) stays close: the difference is the
    // maximal-coordinate joints.
    assert!(
        d_multibody < 0.1 * d_impulse,
        "the reduced-coordinate Rapier drifts as much ({d_multibody} vs {d_impulse})"
    );
    // Not an unconverged iterative solve, not a discretisation error: 8x the iterations and half the step leave it.
    assert!(
        (converged - d_impulse).abs() < 0.1 * d_impulse,
        "solver iterations change the drift ({converged} vs {d_impulse})"
    );
    assert!(
        (d_impulse_fine - d_impulse).abs() < 0.2 * d_impulse,
        "the step changes the drift ({d_impulse_fine} vs {d_impulse})"
    );
    // The armature approximation: without armature the impulse engine is no further from MuJoCo than multibody.
    assert!(
        d_impulse_no_arm / d_multibody_no_arm < 0.25 * (d_impulse / d_multibody),
        "armature off does not remove the impulse engine's excess ({d_impulse_no_arm} / {d_multibody_no_arm})"
    );
    assert!(d_impulse / bound <= entry_cap("impulse-joint-compliance"));
}

/// What every entry absorbs in clean runs (three engines, the built-in excitation with its push at the standard
/// and at a strong amplitude, two seeds of 1 s each): the measured basis of the caps. Each entry's largest absorbed ratio must stay under its cap with a
/// margin, or the cap is too tight for the engines as they are; the printed table is the measurement.
#[test]
fn clean_runs_stay_under_every_cap() {
    use engine_diff::harness::{self, builtin_factories, excitation_factory, HarnessConfig};
    use engine_diff::report::allow_usage;
    use engine_diff::scenario::Scenario;
    let m = model();
    // Every engine of this build (the CLI's build has all six), MuJoCo leading.
    let names: Vec<String> = EngineKind::available().iter().map(|k| k.name().to_string()).collect();
    let f = builtin_factories(&names).expect("engines");
    let ctrl = excitation_factory(&m);
    let cfg = HarnessConfig { free_runs: false, ..HarnessConfig::default() };
    // The standard excitation (0.15 rad) and the strong one the planted-bug test uses (0.5 rad).
    let episodes: Vec<_> = [(1u64, 0.15), (2, 0.15), (5, 0.5), (6, 0.5)]
        .into_iter()
        .map(|(seed, a)| {
            let s = Scenario { excitation: a, ..Scenario::excitation(seed, 1.0) };
            harness::run_episode(&m, &f, ctrl.as_ref(), &s, &cfg).expect("episode")
        })
        .collect();
    let allow = AllowList::builtin().expect("allow-list");
    for u in allow_usage(&allow, &episodes) {
        eprintln!(
            "{}: {} findings in {} groups absorbed, largest ratio {:.2} (cap {}), {} in scope over the cap",
            u.id, u.findings, u.groups, u.max_ratio, u.cap, u.over_cap
        );
        assert_eq!(u.over_cap, 0, "{}: clean runs exceed the cap", u.id);
    }
}
