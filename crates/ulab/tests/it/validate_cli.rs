//! `ulab validate` end to end: a short run of the shipped LSTM policy with MuJoCo as the training engine and
//! DART beside it writes `report.md`, `report.json` and `scores.svg` with a verdict per engine; bad arguments
//! exit 2 with a message. The verdict itself is tested on engines whose difference is known in
//! `engine-diff/tests/it/validate_verdict.rs`.

use crate::common;

use common::{root, run_ulab, tail};
use std::time::Duration;

const SPEC: &str = "robots/h1_2/policies/unitree_rl_gym_lstm.toml";

fn ulab(args: &[&str]) -> (Option<i32>, String, String) {
    // Relative policy paths resolve from the repository root.
    let spec = root().join(SPEC);
    let args: Vec<String> =
        args.iter().map(|a| if *a == "SPEC" { spec.display().to_string() } else { a.to_string() }).collect();
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    run_ulab(&refs, Duration::from_secs(300))
}

#[test]
fn short_run_writes_a_report_with_a_verdict_per_engine() {
    let out = std::env::temp_dir().join(format!("ulab_validate_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let o = out.to_str().expect("utf-8 path");
    let (code, stdout, stderr) = ulab(&[
        "validate",
        "--policy",
        "SPEC",
        "--train-engine",
        "mujoco",
        "--engines",
        "mujoco,dart",
        "--commands",
        "stand",
        "--episodes",
        "2",
        "--seconds",
        "2",
        "--out",
        o,
        "--fail-on-degrade",
    ]);
    assert_eq!(code, Some(0), "{stdout}\n{}", tail(&stderr));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).expect("report.json")).expect("JSON");
    assert_eq!(report["schema_version"], 1);
    assert_eq!(report["train_engine"], "mujoco");
    let engines = report["engines"].as_array().expect("engines");
    let verdicts: Vec<(&str, &str)> =
        engines.iter().map(|e| (e["engine"].as_str().unwrap_or(""), e["verdict"].as_str().unwrap_or(""))).collect();
    assert_eq!(verdicts, [("mujoco", "training_engine"), ("dart", "transfers")], "{stdout}");
    // 2 engines x 1 command x 2 seeds, each with its outcome.
    assert_eq!(report["episodes"].as_array().map(Vec::len), Some(4));
    let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    assert!(md.contains("| dart | transfers |"), "{md}");
    assert!(std::fs::read_to_string(out.join("scores.svg")).expect("plot").contains("<svg"));
    let _ = std::fs::remove_dir_all(&out);
}

/// `--gait-search`: one short search in MuJoCo, then the validation of what it found; the search's result
/// is saved and the report names the gait. (The verdict on a gait searched in one engine is tested in
/// `engine-diff/tests/it/planted_cheat.rs`.)
#[test]
fn gait_search_saves_the_gait_and_validates_it() {
    let out = std::env::temp_dir().join(format!("ulab_validate_gait_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let o = out.to_str().expect("utf-8 path");
    let (code, stdout, stderr) = ulab(&[
        "validate",
        "--gait-search",
        "--gait-iterations",
        "1",
        "--train-engine",
        "mujoco",
        "--engines",
        "mujoco,dart",
        "--commands",
        "forward",
        "--episodes",
        "1",
        "--seconds",
        "4",
        "--out",
        o,
    ]);
    assert_eq!(code, Some(0), "{stdout}\n{}", tail(&stderr));
    let gait: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("gait.json")).expect("gait.json")).expect("JSON");
    assert_eq!(gait["engine"], "mujoco");
    assert_eq!(gait["params"]["theta"].as_array().map(Vec::len), Some(16));
    // 16 candidates and the incumbent, 2 search seeds each.
    assert_eq!(gait["episodes"], 34);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).expect("report.json")).expect("JSON");
    assert_eq!(report["controller"], "gait optimised in mujoco");
    assert_eq!(report["episodes"].as_array().map(Vec::len), Some(2));
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn bad_arguments_exit_2_with_a_message() {
    let out = std::env::temp_dir().join(format!("ulab_validate_bad_{}", std::process::id()));
    let o = out.to_str().expect("utf-8 path");
    for (args, expect) in [
        (vec!["validate", "--policy", "SPEC", "--out", o, "--commands", "moonwalk"], "unknown command moonwalk"),
        (vec!["validate", "--policy", "SPEC", "--out", o, "--seconds", "1"], "--seconds"),
        (vec!["validate", "--policy", "SPEC", "--out", o, "--episodes", "0"], "--episodes"),
        (vec!["validate", "--policy", "SPEC", "--gait-search", "--out", o], "cannot be used with"),
        (vec!["validate", "--out", o], "--policy"),
        (vec!["validate", "--gait-search", "--gait-iterations", "0", "--out", o], "--gait-iterations"),
        (vec!["validate", "--policy", "SPEC", "--out", o, "--train-engine", "ode"], "--train-engine"),
        (
            vec![
                "validate",
                "--policy",
                "/nonexistent.toml",
                "--out",
                o,
                "--engines",
                "mujoco,dart",
                "--train-engine",
                "mujoco",
            ],
            "policy spec",
        ),
        (
            vec!["validate", "--policy", "SPEC", "--out", o, "--engines", "mujoco", "--train-engine", "mujoco"],
            "besides the training engine",
        ),
    ] {
        let (code, stdout, stderr) = ulab(&args);
        assert_eq!(code, Some(2), "{args:?}\n{stdout}\n{stderr}");
        assert!(stderr.contains(expect), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}
