//! Steps per second of the Newton engines beside the other engines of this build, in one process, and the inputs
//! of Newton's own loop (`bench/newton/own_loop.py`) for the subprocess layer's overhead (BENCHMARKS.md).
//!
//! Loop per engine, as `benches/engines.rs` times it: `Engine::state()` + Unitree's standing PD outside the
//! engine + `Engine::step()`, H1-2 standing on the ground, dt 2 ms, one thread, reset to standing every 250 steps
//! (not timed). Each engine runs `--steps` steps after one untimed warm-up window.
//!
//!   source scripts/env.sh
//!   cargo run -p diff-physics --features newton,bullet,dart --example newton_throughput -- \
//!       [--steps 500] [--engines mujoco,newton_featherstone,newton_steel] [--dump DIR]
//!
//! `--dump DIR` writes `DIR/<engine>.json` per Newton engine: the server's start-up request
//! ([`NewtonEngine::init_config`]), the standing state and the PD gains, which `own_loop.py` reads.
use diff_physics::newton::{NewtonEngine, NewtonSettings, NewtonSolver};
use diff_physics::{make_engine, pd_torques, CommonSettings, EngineKind, PdTarget, State};
use robot_model::RobotModel;
use std::time::{Duration, Instant};

const RESET_EVERY: usize = 250;

fn solver(kind: EngineKind) -> Option<NewtonSolver> {
    match kind {
        EngineKind::NewtonFeatherstone => Some(NewtonSolver::Featherstone),
        EngineKind::NewtonSteel => Some(NewtonSolver::Steel),
        EngineKind::NewtonXpbd => Some(NewtonSolver::Xpbd),
        EngineKind::NewtonSemiImplicit => Some(NewtonSolver::SemiImplicit),
        EngineKind::NewtonMujoco => Some(NewtonSolver::Mujoco),
        _ => None,
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |name: &str| args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).cloned();
    let steps: usize = flag("--steps").map(|s| s.parse()).transpose()?.unwrap_or(500);
    let kinds: Vec<EngineKind> = match flag("--engines") {
        Some(list) => list.split(',').map(EngineKind::parse_available).collect::<Result<_, _>>()?,
        None => EngineKind::available(),
    };
    let dump = flag("--dump").map(std::path::PathBuf::from);
    let model = RobotModel::h1_2()?;
    let common = CommonSettings::default();
    let s0 = State::standing(&model);
    let pd = PdTarget::hold_standing(&model);
    if let Some(dir) = &dump {
        std::fs::create_dir_all(dir)?;
    }
    println!("| engine | version | steps/s | ms/step | steps |");
    println!("|---|---|---:|---:|---:|");
    for kind in kinds {
        let t_build = Instant::now();
        let mut e = make_engine(kind, &model, &common)?;
        let build = t_build.elapsed();
        if let (Some(dir), Some(sv)) = (&dump, solver(kind)) {
            let out = serde_json::json!({
                "init": NewtonEngine::init_config(&model, &common, &NewtonSettings::for_solver(sv)),
                "qpos": s0.qpos(),
                "qvel": s0.v(),
                "pd": { "q_des": pd.q_des, "kp": pd.kp, "kd": pd.kd,
                        "limit": model.joints.iter().map(|j| j.torque_limit).collect::<Vec<_>>() },
                "reset_every": RESET_EVERY,
            });
            std::fs::write(dir.join(format!("{}.json", kind.name())), serde_json::to_string(&out)?)?;
        }
        let mut timed = Duration::ZERO;
        let mut done = 0;
        let mut warm = true;
        while done < steps {
            e.reset(&s0)?;
            let n = if warm { RESET_EVERY.min(50) } else { RESET_EVERY.min(steps - done) };
            let t0 = Instant::now();
            for _ in 0..n {
                let s = e.state();
                e.step(&pd_torques(&model, &pd, &s.q, &s.dq))?;
            }
            if warm {
                warm = false;
            } else {
                timed += t0.elapsed();
                done += n;
            }
        }
        let rate = steps as f64 / timed.as_secs_f64();
        println!("| {} | {} | {rate:.1} | {:.3} | {steps} |", kind.name(), e.version(), 1e3 / rate);
        eprintln!("{}: built in {:.1} s", kind.name(), build.as_secs_f64());
    }
    Ok(())
}
