//! Closed loop in MuJoCo: each shipped policy walks the project's H1-2 forward at a 0.5 m/s command for 5 s
//! without falling. Physics at 2 ms, PD torques at every physics step, the policy every `decimation` steps
//! (Unitree's `deploy_mujoco.py` scheme: the policy sees the state after the step, time = steps × dt, and its
//! targets drive the following steps).
#![cfg(test)]

use diff_physics::{make_engine, pd_torques, CommonSettings, EngineKind, State};
use policy_runtime::observation::projected_gravity;
use policy_runtime::{Controller, PolicyController, PolicySpec, RobotObservation};
use std::path::PathBuf;

struct Outcome {
    min_height: f64,
    min_uprightness: f64,
    final_pos: [f64; 3],
}

fn walk(policy: &str, command: [f64; 3], seconds: f64) -> Option<Outcome> {
    match std::env::var("ULAB_SHARED") {
        Ok(s) if !s.is_empty() => {}
        _ => {
            eprintln!("SKIP: ULAB_SHARED is not set (the policies live in $ULAB_SHARED/reference/policies/)");
            return None;
        }
    }
    let spec_path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../../robots/h1_2/policies/{policy}.toml"));
    let spec = PolicySpec::load(&spec_path).unwrap_or_else(|e| panic!("{policy}: {e}"));
    let model =
        robot_model::RobotModel::load(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../robots/h1_2/h1_2.toml"))
            .expect("robots/h1_2 loads");
    spec.check_robot(&model).expect("spec fits the model");
    let common = CommonSettings::default();
    let decimation = spec.decimation(common.timestep).expect("whole steps");
    let mut ctl = PolicyController::from_spec(spec).expect("controller");
    let mut engine = make_engine(EngineKind::Mujoco, &model, &common).expect("MuJoCo engine");
    engine.reset(&State::standing(&model)).expect("reset");
    ctl.reset();

    let mut target = ctl.default_target();
    let steps = (seconds / common.timestep).round() as usize;
    let mut out = Outcome { min_height: f64::INFINITY, min_uprightness: f64::INFINITY, final_pos: [0.0; 3] };
    for k in 1..=steps {
        let s = engine.state();
        let tau = pd_torques(&model, &target, &s.q, &s.dq);
        engine.step(&tau).expect("physics step");
        let s = engine.state();
        out.min_height = out.min_height.min(s.base_pos[2]);
        let g = projected_gravity(s.base_quat).expect("valid quaternion");
        out.min_uprightness = out.min_uprightness.min(-g[2]);
        out.final_pos = s.base_pos;
        if k % decimation == 0 {
            let obs = RobotObservation {
                time: engine.time(),
                base_quat: s.base_quat,
                base_ang_vel: s.base_ang_vel,
                q: s.q.clone(),
                dq: s.dq.clone(),
                command,
            };
            target = ctl.act(&obs).unwrap_or_else(|e| panic!("{policy} at t = {:.2} s: {e}", engine.time()));
        }
    }
    eprintln!(
        "{policy}: {seconds} s at command {command:?}: pelvis min height {:.3} m, min cos(tilt) {:.3}, final position ({:.3}, {:.3}, {:.3})",
        out.min_height, out.min_uprightness, out.final_pos[0], out.final_pos[1], out.final_pos[2]
    );
    Some(out)
}

fn check_walks_forward(policy: &str) {
    let Some(o) = walk(policy, [0.5, 0.0, 0.0], 5.0) else {
        return;
    };
    assert!(o.min_height > 0.8, "{policy}: the pelvis fell to {:.3} m", o.min_height);
    assert!(o.min_uprightness > 0.8, "{policy}: tilted to cos = {:.3}", o.min_uprightness);
    // 0.5 m/s for 5 s is 2.5 m; allow for the start-up and tracking error, but it must clearly walk forward.
    assert!(o.final_pos[0] > 1.25, "{policy}: moved only {:.3} m forward", o.final_pos[0]);
    assert!(o.final_pos[1].abs() < 1.0, "{policy}: drifted {:.3} m sideways", o.final_pos[1]);
}

#[test]
fn gepetto_policy_walks_forward_in_mujoco() {
    check_walks_forward("gepetto_demo_rsl");
}

#[test]
fn unitree_lstm_policy_walks_forward_in_mujoco() {
    check_walks_forward("unitree_rl_gym_lstm");
}
