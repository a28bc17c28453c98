//! Writes the logs of chosen trials of the rig benchmark (`ulab gap bench --reference-engine ENGINE --seed SEED
//! --trials TRIALS --out-of-library OOL --duration D`, excitation plan) as MCAP, with their labels in the clear
//! beside them, without diagnosing: to study a trial's log with `ulab gap diagnose`, or to diagnose many trials in
//! parallel. The benchmark itself seals the labels before it diagnoses; these are for study, not for scoring.
//!
//! Usage: `cargo run --release -p gap-bench --example trial_logs -- rapier_multibody 17 40 0 15 OUT_DIR 22 30`
//! (writes `OUT_DIR/trial_022.mcap` and `OUT_DIR/trial_022.labels.json`, and the same for trial 30).
use gap_bench::{generate_log_with, trial_config, BenchOptions};
use gap_diagnosis::plant::EngineChoice;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [engine, seed, trials, out_of_library, duration, dir, picks @ ..] = args.as_slice() else {
        return Err("usage: trial_logs ENGINE SEED TRIALS OUT_OF_LIBRARY DURATION_S OUT_DIR TRIAL...".into());
    };
    let model = robot_model::builtin("h1_2")?;
    let opts = BenchOptions {
        reference: EngineChoice::parse(engine)?,
        out_of_library: out_of_library.parse()?,
        ..BenchOptions::new(trials.parse()?, seed.parse()?, duration.parse()?)
    };
    let dir = PathBuf::from(dir);
    std::fs::create_dir_all(&dir)?;
    for pick in picks {
        let i: usize = pick.parse()?;
        if i >= opts.trials + opts.out_of_library {
            return Err(
                format!("trial {i} is not among the benchmark's {} trials", opts.trials + opts.out_of_library).into()
            );
        }
        let (cfg, labels) = trial_config(&model, i, &opts);
        let log = generate_log_with(&model, &cfg, None)?;
        let path = dir.join(format!("trial_{i:03}.mcap"));
        log.write_mcap(std::io::BufWriter::new(std::fs::File::create(&path)?), &model)?;
        std::fs::write(dir.join(format!("trial_{i:03}.labels.json")), serde_json::to_string_pretty(&labels)?)?;
        eprintln!("{}: {}", path.display(), serde_json::to_string(&labels.injected)?);
    }
    Ok(())
}
