//! `Engine::set_base_wrench` against Newton's and Euler's laws, for every compiled-in engine that has it: the robot
//! floats at rest without gravity, joints free; a force at the pelvis origin accelerates the whole robot's centre
//! of mass by F / M, whatever the engine's own base frame (MuJoCo's body origin, Rapier's and Bullet's COM, DART's
//! pelvis frame); a pure torque leaves the centre of mass still and turns the pelvis about the torque's direction.
//! Engines without it must refuse with `Unsupported`, not ignore the wrench.
use diff_physics::{make_engine, CommonSettings, EngineError, EngineKind, State};

const STEPS: usize = 50;

fn zero_g() -> CommonSettings {
    CommonSettings { gravity: [0.0; 3], ..CommonSettings::rigid_body_only() }
}

#[test]
fn a_base_wrench_obeys_newton_and_euler_in_every_engine() {
    let model = robot_model::builtin("h1_2").expect("model");
    let mass = model.total_mass();
    let mut tried = 0;
    for kind in EngineKind::ALL {
        let mut e = match make_engine(kind, &model, &zero_g()) {
            Ok(e) => e,
            Err(EngineError::Unavailable(_)) => continue,
            Err(err) => panic!("{}: {err}", kind.name()),
        };
        let dt = e.common().timestep;
        let t = STEPS as f64 * dt;
        // Force only.
        e.reset(&State::standing(&model)).expect("reset");
        let f = [30.0, -20.0, 10.0];
        match e.set_base_wrench([f[0], f[1], f[2], 0.0, 0.0, 0.0]) {
            Ok(()) => {}
            Err(EngineError::Unsupported(_)) => {
                eprintln!("{}: no base wrench (Unsupported)", kind.name());
                continue;
            }
            Err(err) => panic!("{}: {err}", kind.name()),
        }
        tried += 1;
        let c0 = e.com();
        let tau0 = vec![0.0; model.nj()];
        for _ in 0..STEPS {
            e.step(&tau0).expect("step");
        }
        let c1 = e.com();
        for k in 0..3 {
            let expect = 0.5 * f[k] / mass * t * t;
            let got = c1[k] - c0[k];
            // Semi-implicit integrators move by (n+1)/n of the continuous value: 2 % at 50 steps.
            assert!(
                (got - expect).abs() < 0.03 * expect.abs() + 1e-6,
                "{}: COM moved {got} m along {k}, Newton says {expect}",
                kind.name()
            );
        }
        // Torque only: the COM stays, the pelvis turns about the torque's direction.
        e.reset(&State::standing(&model)).expect("reset");
        let torque = [0.0, 0.0, 40.0];
        e.set_base_wrench([0.0, 0.0, 0.0, torque[0], torque[1], torque[2]]).expect("wrench");
        let c0 = e.com();
        for _ in 0..STEPS {
            e.step(&tau0).expect("step");
        }
        let c1 = e.com();
        let drift = (0..3).map(|k| (c1[k] - c0[k]).powi(2)).sum::<f64>().sqrt();
        assert!(drift < 1e-4, "{}: a pure torque moved the COM by {drift} m", kind.name());
        let q = e.state().base_quat;
        let yaw = 2.0 * q[3].atan2(q[0]);
        assert!(yaw > 1e-3, "{}: the pelvis turned {yaw} rad about +z under a +z torque", kind.name());
    }
    assert!(tried >= 2, "no engine with a base wrench was compiled in");
}
