//! Where two reference plants disagree with no effect injected: the benchmark's no-effect rig log (excitation plan,
//! 50 Hz commands with jitter, no sensor noise) generated in two engines, and the RMS difference of each joint's
//! angle and torque between them, largest first; then the same with the model's joint friction, armature or damping
//! removed from both, to see which joint parameter the engines treat differently. It says how much of a Rapier log's
//! unexplained residual is the engines' own difference (BENCHMARKS.md, "Where the engines disagree").
//!
//! Usage: `cargo run --release -p gap-bench --example engine_mismatch -- mujoco rapier_multibody 15`
//! (engine names as `ulab gap bench --reference-engine` takes them; the last argument is the log length in s).
use gap_bench::{generate_log_with, RealConfig, SensorNoise};
use gap_diagnosis::plant::{Effects, EngineChoice};
use robot_model::RobotModel;

type Variant = (&'static str, fn(&mut RobotModel));

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [a, b, duration] = args.as_slice() else {
        return Err("usage: engine_mismatch ENGINE_A ENGINE_B DURATION_S".into());
    };
    let (a, b) = (EngineChoice::parse(a)?, EngineChoice::parse(b)?);
    let duration: f64 = duration.parse()?;
    let base = robot_model::builtin("h1_2")?;
    let variants: [Variant; 4] = [
        ("as modelled", |_| {}),
        ("no joint friction", |m| m.joints.iter_mut().for_each(|j| j.frictionloss = 0.0)),
        ("no armature", |m| m.joints.iter_mut().for_each(|j| j.armature = 0.0)),
        ("no joint damping", |m| m.joints.iter_mut().for_each(|j| j.damping = 0.0)),
    ];
    for (name, edit) in variants {
        let mut model = base.clone();
        edit(&mut model);
        let log = |engine: &EngineChoice| {
            let cfg = RealConfig {
                effects: Effects::none(model.nj()),
                seed: 7,
                engine: engine.clone(),
                noise: SensorNoise { q: 0.0, dq: 0.0, tau: 0.0, gyro: 0.0, quat: 0.0, acc: 0.0 },
                ..RealConfig::new(&model, duration, 0)
            };
            generate_log_with(&model, &cfg, None)
        };
        let (la, lb) = (log(&a)?, log(&b)?);
        let n = la.states.len().min(lb.states.len()).max(1);
        let rms = |f: &dyn Fn(usize) -> f64| ((0..n).map(|i| f(i).powi(2)).sum::<f64>() / n as f64).sqrt();
        let mut rows: Vec<(String, f64, f64, f64)> = model
            .joints
            .iter()
            .enumerate()
            .map(|(j, joint)| {
                let dq = rms(&|i| la.states[i].q[j] - lb.states[i].q[j]);
                let dtau = rms(&|i| la.states[i].tau[j] - lb.states[i].tau[j]);
                let tau = rms(&|i| la.states[i].tau[j]);
                (joint.motor_name.clone(), dq, dtau, tau)
            })
            .collect();
        let total = |k: usize| rows.iter().map(|r| if k == 0 { r.1 * r.1 } else { r.2 * r.2 }).sum::<f64>().sqrt();
        println!("{name}: all joints, RMS angle difference {:.4} rad, torque {:.2} N·m", total(0), total(1));
        rows.sort_by(|x, y| y.2.total_cmp(&x.2));
        for (joint, dq, dtau, tau) in rows.iter().take(8) {
            println!("  {joint:22} angle {dq:.4} rad  torque {dtau:6.2} N·m  (the joint's RMS torque {tau:6.2})");
        }
    }
    Ok(())
}
