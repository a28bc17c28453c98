//! Helpers shared by the gap-bench integration tests.
#![allow(dead_code)]

use gap_bench::PolicyInput;
use robot_model::RobotModel;
use std::path::PathBuf;

/// The built-in H1-2.
pub fn model() -> RobotModel {
    robot_model::builtin("h1_2").expect("built-in model")
}

/// Whether `$ULAB_SHARED` (where the walking policies' weights live) is set; prints why a test skips otherwise.
pub fn shared_set() -> bool {
    match std::env::var("ULAB_SHARED") {
        Ok(s) if !s.is_empty() => true,
        _ => {
            eprintln!("SKIP: ULAB_SHARED is not set (the walking policy lives in $ULAB_SHARED/reference/policies/)");
            false
        }
    }
}

/// Unitree's LSTM walking policy (unitree_rl_gym) under velocity command `command` = (vx, vy, wz).
pub fn lstm_policy(command: [f64; 3]) -> PolicyInput {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../robots/h1_2/policies/unitree_rl_gym_lstm.toml");
    PolicyInput { spec: policy_runtime::PolicySpec::load(&path).expect("policy spec"), command }
}

/// Runs trial `i` of the benchmark `opts` as `ulab gap bench` does: its log written as MCAP and read back before the
/// diagnosis.
pub fn run_trial_through_mcap(
    model: &RobotModel,
    i: usize,
    opts: &gap_bench::BenchOptions,
) -> (gap_bench::TrialScore, gap_diagnosis::Report) {
    let mut through_mcap = |_: usize, log: &gap_diagnosis::RobotLog| {
        let mut buf = std::io::Cursor::new(Vec::new());
        log.write_mcap(&mut buf, model)?;
        gap_diagnosis::RobotLog::from_mcap(buf.get_ref(), model)
    };
    let (_, score, report) = gap_bench::run_trial(model, i, opts, &mut through_mcap).expect("trial");
    (score, report)
}
