//! The search comparison of `ulab diff search` with the built-in excitation input, without the CLI (so that it
//! runs in a build without ONNX): CEM vs the mutation fuzzer vs uniform random perturbations at equal compute.
//!
//!   cargo run -p engine-diff --no-default-features --example search_compare -- \
//!       [BUDGET] [SECONDS] [SEED] [ENGINES]      # defaults: 64 0.4 1 mujoco,rapier_impulse
use engine_diff::harness::{builtin_factories, excitation_factory, HarnessConfig};
use engine_diff::scenario::Scenario;
use engine_diff::search::{search, Method, SearchConfig, SearchSetup};
use engine_diff::triage::AllowList;
use robot_model::RobotModel;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let budget: usize = args.first().and_then(|x| x.parse().ok()).unwrap_or(64);
    let seconds: f64 = args.get(1).and_then(|x| x.parse().ok()).unwrap_or(0.4);
    let seed: u64 = args.get(2).and_then(|x| x.parse().ok()).unwrap_or(1);
    let engines: Vec<String> =
        args.get(3).map_or("mujoco,rapier_impulse", |s| s.as_str()).split(',').map(str::to_string).collect();
    let run = || -> Result<(), Box<dyn std::error::Error>> {
        let model = RobotModel::h1_2()?;
        let factories = builtin_factories(&engines)?;
        let ctrl = excitation_factory(&model);
        let cfg = HarnessConfig::default();
        let allow = AllowList::builtin()?;
        let base = Scenario {
            commands: vec![],
            pushes: vec![],
            action_noise: 0.0,
            init_q_offset: 0.0,
            ..Scenario::excitation(seed, seconds)
        };
        let setup = SearchSetup {
            model: &model,
            factories: &factories,
            controller: ctrl.as_ref(),
            cfg: &cfg,
            allow: &allow,
            base,
        };
        let c = SearchConfig { budget, seed, ..SearchConfig::default() };
        println!("engines {engines:?}, {budget} rollouts of {seconds} s per method, seed {seed}");
        println!(
            "| method | rollouts | failed | best divergence per unit | largest normalised divergence | finding groups | not allow-listed | wall s |"
        );
        println!("|---|---|---|---|---|---|---|---|");
        for m in [Method::Cem, Method::Mutation, Method::Random] {
            let o = search(&setup, m, &c)?;
            println!(
                "| {} | {} | {} | {:.4} | {:.3} | {} | {} | {:.1} |",
                m.name(),
                o.evaluated,
                o.failed,
                o.best_score,
                o.max_divergence,
                o.finding_groups,
                o.unexplained_groups,
                o.wall_s
            );
            for (k, e, q, p, r) in &o.unexplained {
                eprintln!("{}: not allow-listed: {k} / {e} / {q} / {p}, largest ratio {r:.2}", m.name());
            }
            let curve: Vec<String> = o
                .best_so_far
                .iter()
                .skip((budget / 8).max(1) - 1)
                .step_by((budget / 8).max(1))
                .map(|x| format!("{x:.3}"))
                .collect();
            eprintln!("{}: best so far every {} rollouts: {}", m.name(), (budget / 8).max(1), curve.join(" "));
        }
        Ok(())
    };
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
