//! Steps per second of the two Rapier engines at dt = 2 ms, single thread, through the `Engine` interface,
//! with the PD law computed outside the engine every step (as in every other engine's benchmark):
//! - `standing`: full robot on the ground holding the standing pose (contacts on). The default gains tip the
//!   passive robot over after ~1 s, so the engine is reset to the standing state every 250 steps (0.5 s);
//!   resets are excluded from the timing (`iter_custom`).
//! - `zero_gravity`: no gravity, no ground (no contacts), same PD hold.
//! - `raw_step`: Rapier's own `PhysicsWorld::step` on the standing scene without the `Engine` layer (no state
//!   conversion, no PD, no torque application), for the layer overhead.
//!
//! Run: `CARGO_TARGET_DIR=target-rapier cargo bench -p diff-physics --no-default-features --features rapier --bench rapier`
use criterion::{criterion_group, criterion_main, Criterion};
use diff_physics::rapier_impulse::{RapierImpulseEngine, RapierImpulseSettings};
use diff_physics::rapier_multibody::{RapierMultibodyEngine, RapierMultibodySettings};
use diff_physics::{pd_torques, CommonSettings, Engine, PdTarget, State};
use std::time::{Duration, Instant};

const RESET_EVERY: u64 = 250;

fn run(e: &mut dyn Engine, model: &robot_model::RobotModel, iters: u64) -> Duration {
    let target = PdTarget::hold_standing(model);
    let s0 = State::standing(model);
    let mut total = Duration::ZERO;
    let mut done = 0;
    while done < iters {
        if e.reset(&s0).is_err() {
            return total;
        }
        let n = RESET_EVERY.min(iters - done);
        let t0 = Instant::now();
        for _ in 0..n {
            let s = e.state();
            let tau = pd_torques(model, &target, &s.q, &s.dq);
            if e.step(&tau).is_err() {
                break;
            }
        }
        total += t0.elapsed();
        done += n;
    }
    total
}

fn engines(model: &robot_model::RobotModel, common: &CommonSettings) -> Vec<Box<dyn Engine>> {
    let mut out: Vec<Box<dyn Engine>> = Vec::new();
    if let Ok(e) = RapierMultibodyEngine::new(model, common, &RapierMultibodySettings::default()) {
        out.push(Box::new(e));
    }
    if let Ok(e) = RapierImpulseEngine::new(model, common, &RapierImpulseSettings::default()) {
        out.push(Box::new(e));
    }
    out
}

fn bench_rapier(c: &mut Criterion) {
    let Ok(model) = robot_model::builtin("h1_2") else {
        return;
    };
    let standing = CommonSettings::default();
    let zero_g = CommonSettings { gravity: [0.0; 3], ground: false, ..CommonSettings::default() };
    let mut group = c.benchmark_group("rapier_step");
    group.sample_size(20).measurement_time(Duration::from_secs(6));
    for (label, common) in [("standing", &standing), ("zero_gravity", &zero_g)] {
        for mut e in engines(&model, common) {
            let name = format!("{}/{label}", e.name());
            group.bench_function(name, |b| b.iter_custom(|iters| run(e.as_mut(), &model, iters)));
        }
    }
    // Solver-budget variants of the multibody engine (substeps per 2 ms step; the default is 4).
    for substeps in [1usize, 2] {
        let mut set = RapierMultibodySettings::default();
        set.solver.substeps = substeps;
        for (label, common) in [("standing", &standing), ("zero_gravity", &zero_g)] {
            if let Ok(mut e) = RapierMultibodyEngine::new(&model, common, &set) {
                group.bench_function(format!("rapier_multibody/{label}_substeps{substeps}"), |b| {
                    b.iter_custom(|iters| run(&mut e, &model, iters))
                });
            }
        }
    }
    // Layer overhead: the same standing scene, timed with bare world steps (torques of one PD step persist).
    let model_ref = &model;
    if let Ok(mut e) = RapierMultibodyEngine::new(&model, &standing, &RapierMultibodySettings::default()) {
        group.bench_function("rapier_multibody/standing_raw_step", |b| {
            b.iter_custom(|iters| raw(&mut e, model_ref, iters, |e| e.step_raw()))
        });
    }
    if let Ok(mut e) = RapierImpulseEngine::new(&model, &standing, &RapierImpulseSettings::default()) {
        group.bench_function("rapier_impulse/standing_raw_step", |b| {
            b.iter_custom(|iters| raw(&mut e, model_ref, iters, |e| e.step_raw()))
        });
    }
    group.finish();
}

/// Like [`run`] but each timed step is `step(e)` (the bare world step); one PD step after each reset sets the
/// (persisting) joint torques.
fn raw<E: Engine>(e: &mut E, model: &robot_model::RobotModel, iters: u64, step: impl Fn(&mut E)) -> Duration {
    let target = PdTarget::hold_standing(model);
    let s0 = State::standing(model);
    let mut total = Duration::ZERO;
    let mut done = 0;
    while done < iters {
        if e.reset(&s0).is_err() {
            return total;
        }
        let s = e.state();
        let tau = pd_torques(model, &target, &s.q, &s.dq);
        if e.step(&tau).is_err() {
            return total;
        }
        let n = RESET_EVERY.min(iters - done);
        let t0 = Instant::now();
        for _ in 0..n {
            step(e);
        }
        total += t0.elapsed();
        done += n;
    }
    total
}

criterion_group!(benches, bench_rapier);
criterion_main!(benches);
