//! Throughput of the harness: rollouts per second per engine (one thread and all cores) and the fraction
//! of wall time spent outside the engines' `step` (observation, controller, PD law, bookkeeping).
use crate::harness::{self, ControllerFactory, EngineFactory, HarnessConfig};
use crate::scenario::Scenario;
use crate::DiffError;
use rayon::prelude::*;
use robot_model::RobotModel;
use serde::Serialize;
use std::sync::Arc;
use std::time::Instant;

/// One benchmark row.
#[derive(Debug, Clone, Serialize)]
pub struct BenchRow {
    /// Engine name, or `diff(a,b,..)` for the windowed harness over all engines.
    pub what: String,
    pub threads: usize,
    pub rollouts: usize,
    pub seconds_per_rollout: f64,
    pub rollouts_per_s: f64,
    /// Physics steps per wall second (all threads).
    pub steps_per_s: f64,
    /// Share of the time not spent in `Engine::step` (engine time summed over threads vs wall × threads).
    pub outside_engine: f64,
}

fn row(what: String, threads: usize, rollouts: usize, wall: f64, engine_s: f64, steps: u64, sim_s: f64) -> BenchRow {
    BenchRow {
        what,
        threads,
        rollouts,
        seconds_per_rollout: sim_s,
        rollouts_per_s: rollouts as f64 / wall,
        steps_per_s: steps as f64 / wall,
        outside_engine: (1.0 - engine_s / (wall * threads as f64)).clamp(0.0, 1.0),
    }
}

/// Free rollouts per engine (1 thread, then `threads` in parallel) and windowed diff episodes.
pub fn run(
    model: &RobotModel,
    factories: &[Arc<dyn EngineFactory>],
    ctrl: &ControllerFactory,
    cfg: &HarnessConfig,
    seconds: f64,
    rollouts: usize,
    threads: usize,
) -> Result<Vec<BenchRow>, DiffError> {
    let dt = cfg.common.timestep;
    let steps = ((seconds / dt).round() as usize).max(1);
    let mut rows = Vec::new();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .map_err(|e| DiffError::Input(e.to_string()))?;
    for f in factories {
        for t in [1, threads.max(1)] {
            let t0 = Instant::now();
            let one = |i: usize| -> Result<(f64, u64), DiffError> {
                let s = Scenario::excitation(i as u64 + 1, seconds);
                let mut e = f.build(model, &cfg.common)?;
                let ((_, es), n) = harness::free_run(e.as_mut(), &f.name(), model, ctrl, &s, dt, steps)?;
                Ok((es, n))
            };
            let res: Vec<Result<(f64, u64), DiffError>> = if t == 1 {
                (0..rollouts).map(one).collect()
            } else {
                pool.install(|| (0..rollouts).into_par_iter().map(one).collect())
            };
            let wall = t0.elapsed().as_secs_f64();
            let (mut es, mut n) = (0.0, 0);
            for r in res {
                let (a, b) = r?;
                es += a;
                n += b;
            }
            rows.push(row(f.name(), t, rollouts, wall, es, n, seconds));
            if threads <= 1 {
                break;
            }
        }
    }
    let names: Vec<String> = factories.iter().map(|f| f.name()).collect();
    let dcfg = HarnessConfig { free_runs: false, ..cfg.clone() };
    for t in [1, threads.max(1)] {
        let t0 = Instant::now();
        let one = |i: usize| {
            harness::run_episode(model, factories, ctrl, &Scenario::excitation(i as u64 + 1, seconds), &dcfg)
        };
        let res: Vec<Result<harness::EpisodeResult, DiffError>> = if t == 1 {
            (0..rollouts).map(one).collect()
        } else {
            pool.install(|| (0..rollouts).into_par_iter().map(one).collect())
        };
        let wall = t0.elapsed().as_secs_f64();
        let (mut es, mut n) = (0.0, 0);
        for r in res {
            let r = r?;
            es += r.timing.engine_s;
            n += r.timing.steps;
        }
        rows.push(row(format!("diff({})", names.join(",")), t, rollouts, wall, es, n, seconds));
        if threads <= 1 {
            break;
        }
    }
    Ok(rows)
}
