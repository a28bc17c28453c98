//! The suspension stand holds the pelvis still while the limbs swing hard (what both `ulab sim --hang` and the gap
//! diagnosis's rig assume), and a free robot built the same way without the stand falls (the stand is what holds it).
use diff_physics::mujoco::{MujocoEngine, MujocoSettings};
use diff_physics::Engine;
use sim_bridge::suspension::{self, SuspendedMujoco, BASE_POS};

fn swing(engine: &mut dyn Engine, model: &robot_model::RobotModel, seconds: f64) -> (f64, f64) {
    let q0 = model.default_q();
    engine.reset(&suspension::state_on_stand(&q0, &vec![0.0; q0.len()])).expect("reset");
    let (mut max_pos, mut max_rot) = (0.0_f64, 0.0_f64);
    let steps = (seconds / engine.common().timestep) as usize;
    for i in 0..steps {
        let t = i as f64 * engine.common().timestep;
        let s = engine.state();
        // Every joint driven at 2 Hz, ±0.4 rad around the standing pose, at the model's gains (clamped).
        let tau: Vec<f64> = model
            .joints
            .iter()
            .enumerate()
            .map(|(j, jt)| {
                let target = q0[j] + 0.4 * (2.0 * std::f64::consts::PI * 2.0 * t).sin();
                (jt.kp * (target - s.q[j]) - jt.kd * s.dq[j]).clamp(-jt.torque_limit, jt.torque_limit)
            })
            .collect();
        engine.step(&tau).expect("step");
        let s = engine.state();
        let d = (0..3).map(|k| (s.base_pos[k] - BASE_POS[k]).powi(2)).sum::<f64>().sqrt();
        let w = s.base_quat[0].abs().min(1.0);
        max_pos = max_pos.max(d);
        max_rot = max_rot.max(2.0 * w.acos());
    }
    (max_pos, max_rot)
}

#[test]
fn the_stand_holds_the_pelvis_still_and_without_it_the_robot_falls() {
    let model = robot_model::builtin("h1_2").expect("model");
    let mut hung = SuspendedMujoco::new(&model, 0.002, &MujocoSettings::default()).expect("engine");
    let (pos, rot) = swing(&mut hung, &model, 1.0);
    // Under a millimetre and a few milliradians (0.3°), far below what the gap diagnosis's rig check tolerates
    // (2.9°), with every joint swinging at 2 Hz.
    assert!(pos < 1e-3 && rot < 5e-3, "pelvis moved {pos} m / {rot} rad on the stand");
    // Same model, same settings, no stand: gravity takes it down by far more.
    let mut free = MujocoEngine::new(
        &suspension::suspended_model(&model),
        &suspension::settings(0.002),
        &MujocoSettings::default(),
    )
    .expect("engine");
    let (pos, _) = swing(&mut free, &model, 1.0);
    assert!(pos > 1.0, "without the stand the pelvis should fall (moved {pos} m)");
}
