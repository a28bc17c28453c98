//! The reference plant in engines other than the diagnosing MuJoCo (`ulab gap bench --reference-engine`): each
//! engine holds the pelvis on the stand through its own base force (`Engine::set_base_wrench`), and without any
//! hidden effect its rig is the same robot as MuJoCo RK4's, to within what the engines' different integrators
//! explain; a damping or Coulomb friction effect applied through the engine's own joint parameters moves the
//! joints as the same effect applied as torques by the effect layer does. The counterparts are the engines
//! themselves (Rapier, DART, Bullet: independent implementations of articulated dynamics and joint friction).
use diff_physics::EngineKind;
use gap_bench::in_engine;
use gap_diagnosis::excite;
use gap_diagnosis::plant::{joint_groups, Effects, EngineChoice, Rig, Stepping};
use robot_model::RobotModel;

fn model() -> RobotModel {
    robot_model::builtin("h1_2").expect("built-in model")
}

const ENGINES: [EngineKind; 3] = [EngineKind::RapierMultibody, EngineKind::Dart, EngineKind::Bullet];

/// Runs the excitation plan for `duration` s on `choice`'s rig with `fx`; returns the largest pelvis displacement
/// (m) and tilt (rad) seen, and the true joint angles at every step.
fn run_rig(
    model: &RobotModel,
    choice: &EngineChoice,
    fx: &Effects,
    native: bool,
    duration: f64,
) -> (f64, f64, Vec<Vec<f64>>) {
    let (m, fx) = in_engine(&fx.apply_to_model(model), fx, native);
    let mut rig = Rig::reference(&m, choice, Stepping::DIAGNOSING).expect("rig");
    let q0 = model.default_q();
    rig.reset(&q0, &vec![0.0; model.nj()]).expect("reset");
    let amp = excite::amplitudes(model);
    let groups = joint_groups(model);
    let (mut dmax, mut tilt) = (0.0f64, 0.0f64);
    let mut qs = Vec::new();
    let dt = gap_diagnosis::plant::DT;
    for i in 0..(duration / dt).round() as usize {
        let cmd = excite::command_at(model, &amp, &groups, duration, i as f64 * dt);
        rig.step(&cmd, &fx).expect("step");
        let (p, quat) = rig.pelvis();
        let d = (0..3).map(|k| (p[k] - gap_diagnosis::plant::RIG_BASE_POS[k]).powi(2)).sum::<f64>().sqrt();
        dmax = dmax.max(d);
        tilt = tilt.max(2.0 * quat[0].abs().min(1.0).acos());
        qs.push(rig.joints().0);
    }
    (dmax, tilt, qs)
}

fn rms(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for (x, y) in a.iter().zip(b) {
        for (p, q) in x.iter().zip(y) {
            s += (p - q).powi(2);
            n += 1;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

#[test]
fn every_reference_engine_holds_the_pelvis_and_moves_like_mujoco() {
    let m = model();
    let none = Effects::none(m.nj());
    let (_, _, reference) = run_rig(&m, &EngineChoice::mujoco("RK4"), &none, false, 4.0);
    for kind in ENGINES {
        let (d, tilt, qs) = run_rig(&m, &EngineChoice::Other(kind), &none, true, 4.0);
        let e = rms(&qs, &reference);
        eprintln!(
            "{}: pelvis moved {:.2e} m, tilted {:.2e} rad; joint RMS vs MuJoCo RK4 {e:.4} rad",
            kind.name(),
            d,
            tilt
        );
        assert!(d < 1e-3, "{}: the stand let the pelvis move {d} m", kind.name());
        assert!(tilt < 1e-3, "{}: the stand let the pelvis tilt {tilt} rad", kind.name());
        // Bullet has no armature: it adds the rotor inertia to the child link about the joint axis, which is
        // exact for the joint's own mass-matrix entry only (diff_physics::bullet); measured 0.08 rad RMS here,
        // a model difference the benchmark's Bullet table carries as a baseline mismatch.
        let tolerance = if kind == EngineKind::Bullet { 0.15 } else { 0.03 };
        assert!(e < tolerance, "{}: joint RMS {e} rad from MuJoCo RK4 on the same rig and commands", kind.name());
    }
}

#[test]
fn damping_and_friction_through_the_engines_own_joints_act_like_the_effect_layer() {
    let m = model();
    let groups = joint_groups(&m);
    let arm: Vec<usize> = (0..m.nj()).filter(|&j| groups[j] == 3).collect();
    let mut damping = Effects::none(m.nj());
    let mut friction = Effects::none(m.nj());
    for &j in &arm {
        damping.damping[j] = 3.0;
        friction.coulomb[j] = 3.0;
    }
    for kind in [EngineKind::RapierMultibody, EngineKind::Dart] {
        let choice = EngineChoice::Other(kind);
        let (_, _, none) = run_rig(&m, &choice, &Effects::none(m.nj()), true, 4.0);
        for (what, fx) in [("damping", &damping), ("Coulomb friction", &friction)] {
            let (_, _, native) = run_rig(&m, &choice, fx, true, 4.0);
            let (_, _, layer) = run_rig(&m, &choice, fx, false, 4.0);
            let effect = rms(&native, &none);
            let routes = rms(&native, &layer);
            eprintln!("{} {what}: effect {effect:.4} rad RMS, engine's own vs effect layer {routes:.4}", kind.name());
            assert!(effect > 0.01, "{} {what}: the engine's own parameter did nothing ({effect})", kind.name());
            assert!(routes < 0.3 * effect, "{} {what}: engine {routes} vs effect {effect}", kind.name());
        }
    }
}
