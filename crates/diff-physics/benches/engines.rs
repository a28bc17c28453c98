//! MuJoCo steps per second at dt = 2 ms, single thread, and the overhead of the `Engine` layer over raw
//! mujoco-rs calls; then one summary run that times every compiled-in engine in the same process and prints
//! the ratios (for BENCHMARKS.md).
//!
//! Scenarios (PD law computed outside the engine every step, from the state the loop reads):
//! - `standing`: full robot on the ground holding the standing pose with the default gains (contacts on). The
//!   passive robot tips over after ~1 s, so it is reset every 250 steps (0.5 s); resets are not timed.
//! - `zero_gravity`: no gravity, no ground (no contacts), same PD hold.
//!
//! Loops: `engine` = `Engine::state()` + `pd_torques` + `Engine::step()`; `raw` = read `qpos`/`qvel` from
//! `MjData` + the same PD + write `ctrl` + `mj_step` (no layer). Bullet (feature `bullet`) also has a raw loop:
//! joint state straight from the btMultiBody + the same PD and the viscous damping the layer adds + one world step.
//! PhysX (feature `physx`) too: joint positions/velocities from the articulation cache + the same PD (gains permuted
//! to PhysX's DoF order once) + `jointForce` + `simulate`/`fetchResults` (no state conversion, no root read-back).
//! DART (feature `dart`) too: joint values and velocities of each joint's dof from the world + the same PD + forces
//! on those dofs + one `World::step` (no pelvis frame conversion, no safe-range check).
//!
//! Run: `source scripts/env.sh && CARGO_TARGET_DIR=target-model cargo bench -p diff-physics --features bullet,dart --bench engines`
use criterion::{criterion_group, Criterion};
use diff_physics::mujoco::{MujocoEngine, MujocoSettings};
use diff_physics::pd::pd_torques_into;
use diff_physics::{make_engine, CommonSettings, Engine, EngineKind, PdTarget, State};
use robot_model::RobotModel;
use std::time::{Duration, Instant};

const RESET_EVERY: u64 = 250;

fn scenario(zero_g: bool) -> CommonSettings {
    if zero_g {
        CommonSettings { gravity: [0.0; 3], ground: false, ..CommonSettings::default() }
    } else {
        CommonSettings::default()
    }
}

fn start(model: &RobotModel, zero_g: bool) -> State {
    let mut s = State::standing(model);
    if zero_g {
        s.base_pos[2] += 1.0;
    }
    s
}

/// Times `iters` calls of `step` (each one control step: read state, PD, step), resetting the engine to `s0`
/// untimed every `RESET_EVERY` steps. `Duration::MAX` when a reset or a step fails.
fn timed<E: Engine + ?Sized>(e: &mut E, s0: &State, iters: u64, mut step: impl FnMut(&mut E) -> bool) -> Duration {
    let mut total = Duration::ZERO;
    let mut done = 0;
    while done < iters {
        if e.reset(s0).is_err() {
            return Duration::MAX;
        }
        let n = RESET_EVERY.min(iters - done);
        let t0 = Instant::now();
        for _ in 0..n {
            if !step(e) {
                return Duration::MAX;
            }
        }
        total += t0.elapsed();
        done += n;
    }
    total
}

fn run_engine(e: &mut dyn Engine, model: &RobotModel, s0: &State, iters: u64) -> Duration {
    let target = PdTarget::hold_standing(model);
    let limits: Vec<f64> = model.joints.iter().map(|j| j.torque_limit).collect();
    let mut tau = vec![0.0; model.nj()];
    timed(e, s0, iters, |e| {
        let s = e.state();
        pd_torques_into(&target, &s.q, &s.dq, &limits, &mut tau);
        e.step(&tau).is_ok()
    })
}

/// The same loop on raw mujoco-rs calls (the engine is only used to reset, outside the timing).
fn run_raw(e: &mut MujocoEngine, model: &RobotModel, s0: &State, iters: u64) -> Duration {
    let target = PdTarget::hold_standing(model);
    let limits: Vec<f64> = model.joints.iter().map(|j| j.torque_limit).collect();
    let nj = model.nj();
    let (mut q, mut dq, mut tau) = (vec![0.0; nj], vec![0.0; nj], vec![0.0; nj]);
    timed(e, s0, iters, |e| {
        let d = e.raw_data();
        // Our MJCF puts the joints in slot order right after the free joint (checked by the oracles).
        q.copy_from_slice(&d.qpos()[7..7 + nj]);
        dq.copy_from_slice(&d.qvel()[6..6 + nj]);
        pd_torques_into(&target, &q, &dq, &limits, &mut tau);
        d.ctrl_mut().copy_from_slice(&tau);
        d.step();
        true
    })
}

/// The same loop on Bullet's raw joint state and step (link order; the damping torque the layer adds is added
/// here too so that both loops simulate the same thing). The engine is only used to reset, outside the timing.
#[cfg(feature = "bullet")]
fn run_raw_bullet(e: &mut diff_physics::bullet::BulletEngine, model: &RobotModel, s0: &State, iters: u64) -> Duration {
    let joint = e.joint_of_link();
    let target = PdTarget::hold_standing(model).permuted(&joint);
    let limits: Vec<f64> = joint.iter().map(|&j| model.joints[j].torque_limit).collect();
    let damping: Vec<f64> = joint.iter().map(|&j| model.joints[j].damping).collect();
    let mut tau = vec![0.0; joint.len()];
    timed(e, s0, iters, |e| {
        let (q, dq) = e.raw_joint_state();
        pd_torques_into(&target, &q, &dq, &limits, &mut tau);
        for (t, (d, v)) in tau.iter_mut().zip(damping.iter().zip(&dq)) {
            *t -= d * v;
        }
        e.step_raw(&tau).is_ok()
    })
}

/// The same loop on PhysX's raw cache access (the engine is only used to reset, outside the timing).
#[cfg(feature = "physx")]
fn run_raw_physx(e: &mut diff_physics::physx::PhysxEngine, model: &RobotModel, s0: &State, iters: u64) -> Duration {
    let slot = e.dof_joints().to_vec();
    let target = PdTarget::hold_standing(model).permuted(&slot);
    let limits: Vec<f64> = slot.iter().map(|&j| model.joints[j].torque_limit).collect();
    let nj = model.nj();
    let (mut q, mut dq, mut tau) = (vec![0.0; nj], vec![0.0; nj], vec![0.0; nj]);
    timed(e, s0, iters, |e| {
        e.raw_joints(&mut q, &mut dq).is_ok() && {
            pd_torques_into(&target, &q, &dq, &limits, &mut tau);
            e.raw_step(&tau).is_ok()
        }
    })
}

/// The same loop on DART's own world (its coordinates: the joint values of the dof each joint drives, forces
/// written to the same dofs, no quaternion or frame conversion, no safe-range check). Damping and friction are
/// DART's own joint properties in both loops. The engine is only used to reset, outside the timing.
#[cfg(feature = "dart")]
fn run_raw_dart(e: &mut diff_physics::dart::DartEngine, model: &RobotModel, s0: &State, iters: u64) -> Duration {
    let dofs = e.dof_of_joint().to_vec();
    let target = PdTarget::hold_standing(model);
    let limits: Vec<f64> = model.joints.iter().map(|j| j.torque_limit).collect();
    let nj = model.nj();
    let (mut q, mut dq, mut tau) = (vec![0.0; nj], vec![0.0; nj], vec![0.0; nj]);
    let mut forces = Vec::new();
    timed(e, s0, iters, |e| {
        let world = e.raw_world();
        let Ok(raw) = world.state() else { return false };
        for (j, &d) in dofs.iter().enumerate() {
            q[j] = raw.q[d - 6];
            dq[j] = raw.vel[d];
        }
        pd_torques_into(&target, &q, &dq, &limits, &mut tau);
        forces.clear();
        forces.resize(raw.vel.len(), 0.0);
        for (&d, t) in dofs.iter().zip(&tau) {
            forces[d] = *t;
        }
        world.step(&forces).is_ok()
    })
}

fn mujoco(model: &RobotModel, zero_g: bool) -> MujocoEngine {
    MujocoEngine::new(model, &scenario(zero_g), &MujocoSettings::default()).expect("MuJoCo engine builds")
}

fn bench(c: &mut Criterion) {
    let model = RobotModel::h1_2().expect("model");
    for zero_g in [false, true] {
        let name = if zero_g { "zero_gravity" } else { "standing" };
        let s0 = start(&model, zero_g);
        let mut g = c.benchmark_group(format!("mujoco/{name}"));
        let mut e = mujoco(&model, zero_g);
        g.bench_function("engine", |b| b.iter_custom(|n| run_engine(&mut e, &model, &s0, n)));
        let mut e = mujoco(&model, zero_g);
        g.bench_function("raw", |b| b.iter_custom(|n| run_raw(&mut e, &model, &s0, n)));
        g.finish();
    }
}

/// Interleaved timing of every compiled-in engine, median of 5 rounds of 2000 steps, printed as a table.
fn summary() {
    let model = RobotModel::h1_2().expect("model");
    let steps = 2000;
    let median = |mut v: Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        v[v.len() / 2]
    };
    println!("\n## summary: steps/s at dt = 2 ms, single thread, median of 5 rounds of {steps} steps");
    println!("| scenario | loop | steps/s | ratio to MuJoCo raw |");
    println!("|---|---|---:|---:|");
    for zero_g in [false, true] {
        let name = if zero_g { "zero gravity (no contacts)" } else { "standing (contacts)" };
        let s0 = start(&model, zero_g);
        let mut raw_e = mujoco(&model, zero_g);
        let mut engines: Vec<(String, Box<dyn Engine>)> = Vec::new();
        for k in EngineKind::available() {
            if let Ok(e) = make_engine(k, &model, &scenario(zero_g)) {
                engines.push((format!("{} (Engine layer)", k.name()), e));
            }
        }
        #[cfg(feature = "bullet")]
        let mut bullet_raw = diff_physics::bullet::BulletEngine::new(&model, &scenario(zero_g), &Default::default())
            .expect("Bullet engine builds");
        #[cfg(feature = "bullet")]
        let mut bullet_raw_rates = Vec::new();
        #[cfg(feature = "physx")]
        let mut physx_raw_e = diff_physics::physx::PhysxEngine::new(&model, &scenario(zero_g), &Default::default())
            .expect("PhysX engine builds");
        #[cfg(feature = "physx")]
        let mut physx_raw_rates = Vec::new();
        #[cfg(feature = "dart")]
        let mut dart_raw = diff_physics::dart::DartEngine::new(&model, &scenario(zero_g), &Default::default())
            .expect("DART engine builds");
        #[cfg(feature = "dart")]
        let mut dart_raw_rates = Vec::new();
        let mut raw_rates = Vec::new();
        let mut rates: Vec<Vec<f64>> = vec![Vec::new(); engines.len()];
        for _ in 0..5 {
            let t = run_raw(&mut raw_e, &model, &s0, steps).as_secs_f64();
            raw_rates.push(steps as f64 / t);
            #[cfg(feature = "bullet")]
            bullet_raw_rates.push(steps as f64 / run_raw_bullet(&mut bullet_raw, &model, &s0, steps).as_secs_f64());
            #[cfg(feature = "dart")]
            dart_raw_rates.push(steps as f64 / run_raw_dart(&mut dart_raw, &model, &s0, steps).as_secs_f64());
            #[cfg(feature = "physx")]
            physx_raw_rates.push(steps as f64 / run_raw_physx(&mut physx_raw_e, &model, &s0, steps).as_secs_f64());
            for (i, (_, e)) in engines.iter_mut().enumerate() {
                let t = run_engine(e.as_mut(), &model, &s0, steps).as_secs_f64();
                rates[i].push(steps as f64 / t);
            }
        }
        let raw = median(raw_rates);
        println!("| {name} | mujoco raw mujoco-rs | {raw:.0} | 1.000 |");
        #[cfg(feature = "bullet")]
        {
            let r = median(bullet_raw_rates);
            println!("| {name} | bullet raw btMultiBody | {r:.0} | {:.3} |", r / raw);
        }
        #[cfg(feature = "dart")]
        {
            let r = median(dart_raw_rates);
            println!("| {name} | dart raw World | {r:.0} | {:.3} |", r / raw);
        }
        #[cfg(feature = "physx")]
        {
            let r = median(physx_raw_rates);
            println!("| {name} | physx raw (articulation cache) | {r:.0} | {:.3} |", r / raw);
        }
        for ((label, _), r) in engines.iter().zip(rates) {
            let r = median(r);
            println!("| {name} | {label} | {r:.0} | {:.3} |", r / raw);
        }
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
    targets = bench
}

fn main() {
    benches();
    summary();
    Criterion::default().configure_from_args().final_summary();
}
