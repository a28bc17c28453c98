//! `ulab gap` end to end: a log of the reference plant written as MCAP is read by the official Python `mcap`
//! package and decoded with Unitree's own Python message types (so it is what `ulab record` would have written);
//! `ulab gap diagnose` finds the hidden effect in it, also from the CSV pair `ulab log export` writes; the
//! excitation plan stays within the joint limits; bad input fails cleanly.
use crate::common;
use common::{python, root, run_ulab, tail, wait_with_timeout};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

fn ulab(args: &[&str]) -> (Option<i32>, String, String) {
    run_ulab(args, Duration::from_secs(300))
}

fn dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ulab-gap-tests").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn read_with_python(path: &Path) -> serde_json::Value {
    let child = Command::new(python())
        .arg(root().join("crates/ulab/tests/py/read_mcap.py"))
        .arg(path)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn python");
    let (status, out, err) = wait_with_timeout(child, Duration::from_secs(120));
    assert!(status.is_some_and(|s| s.success()), "Python mcap reader failed:\n{}\n{}", tail(&out), tail(&err));
    serde_json::from_str(&out).expect("reader prints JSON")
}

#[test]
fn simulated_log_is_a_recording_and_diagnose_finds_the_effect() {
    let d = dir("simulate");
    let log = d.join("real.mcap");
    let (code, out, err) = ulab(&[
        "gap",
        "simulate",
        "--duration",
        "5",
        "--effect",
        "damping:left_arm:2.5",
        "--out",
        log.to_str().unwrap_or(""),
    ]);
    assert_eq!(code, Some(0), "simulate failed:\n{out}\n{err}");

    // Independent reader: Python mcap + Unitree's Cyclone DDS types.
    let v = read_with_python(&log);
    assert_eq!(v["errors"].as_array().map(|a| a.len()), Some(0), "{}", v["errors"]);
    assert_eq!(v["channels"]["rt/lowcmd"]["encoding"], "cdr");
    assert_eq!(v["channels"]["rt/lowstate"]["metadata"]["dds_type_name"], "unitree_hg::msg::dds_::LowState_");
    assert_eq!(v["schemas"]["unitree_hg::msg::dds_::LowCmd_"]["encoding"], "omgidl");
    assert_eq!(v["topics"]["rt/lowcmd"]["count"], 250, "50 Hz for 5 s");
    assert_eq!(v["topics"]["rt/lowstate"]["count"], 2500, "500 Hz for 5 s");

    let out_dir = d.join("report");
    let (code, out, err) = ulab(&[
        "gap",
        "diagnose",
        "--log",
        log.to_str().unwrap_or(""),
        "--robot",
        "h1_2",
        "--out",
        out_dir.to_str().unwrap_or(""),
        "--format",
        "json",
        "--block",
        "0.5",
    ]);
    assert_eq!(code, Some(0), "diagnose failed:\n{}\n{err}", tail(&out));
    let r: serde_json::Value = serde_json::from_str(&out).expect("JSON report on stdout");
    assert_eq!(r["schema_version"], gap_diagnosis::diagnose::SCHEMA_VERSION);
    assert_eq!(r["ranked"][0], "damping", "ranked {}", r["ranked"]);
    // Each stage's wall time, in pipeline order; together they are the diagnosis's time (the report's own clock).
    let stages: Vec<(&str, f64)> = r["stages"]
        .as_array()
        .map(|a| a.iter().filter_map(|t| Some((t["stage"].as_str()?, t["s"].as_f64()?))).collect())
        .unwrap_or_default();
    let names: Vec<&str> = stages.iter().map(|(n, _)| *n).collect();
    let pipeline =
        ["rig check and windows", "timing", "numerics", "breakdown", "judge", "identifiability", "remainder"];
    assert_eq!(names, pipeline.to_vec(), "{}", r["stages"]);
    let (sum, elapsed) = (stages.iter().map(|(_, s)| s).sum::<f64>(), r["elapsed_s"].as_f64().unwrap_or(0.0));
    assert!(stages.iter().all(|(_, s)| *s >= 0.0) && sum <= elapsed && sum >= 0.9 * elapsed, "{sum} vs {elapsed}");
    // Every window is listed once; the held-out ones give the report's held-out metrics both before (the baseline,
    // computed by the breakdown stage) and after (the named effects, computed by the judge).
    let windows = r["window_residuals"].as_array().cloned().unwrap_or_default();
    let n = |k: &str| r[k].as_u64().unwrap_or(0) as usize;
    assert_eq!(windows.len(), n("windows_train") + n("windows_held_out"));
    let held: Vec<&serde_json::Value> = windows.iter().filter(|w| w["held_out"] == true).collect();
    assert_eq!(held.len(), n("windows_held_out"));
    let mean = |k: &str| held.iter().filter_map(|w| w[k].as_f64()).sum::<f64>() / held.len().max(1) as f64;
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(1.0);
    let base = r["baseline_metric"]["value"].as_f64().unwrap_or(f64::NAN);
    let after = r["best_combination"]["metric_after"]["value"].as_f64().unwrap_or(f64::NAN);
    assert!(close(mean("baseline"), base), "held-out windows' baseline mean {} vs {base}", mean("baseline"));
    assert!(close(mean("after"), after), "held-out windows' mean after {} vs {after}", mean("after"));
    // Damping on one arm explains most of this gap; what is left is small against what was there.
    assert!(
        r["unexplained_residual"]["fraction_of_baseline"].as_f64().unwrap_or(1.0) < 0.5,
        "{}",
        r["unexplained_residual"]
    );
    for f in ["report.md", "report.json", "by_joint.svg", "effects.svg"] {
        assert!(out_dir.join(f).is_file(), "{f} missing");
    }
    let md = std::fs::read_to_string(out_dir.join("report.md")).unwrap_or_default();
    assert!(md.contains("damping") && md.contains("left_arm"), "{}", tail(&md));
    assert!(md.contains("## What this log can reveal"), "{}", tail(&md));
    // Only damping is in the log: the friction that fits part of it is not named, and the judge says why it stopped.
    assert_eq!(r["ranked"], serde_json::json!(["damping"]), "ranked {}", r["ranked"]);
    let steps = r["steps"].as_array().cloned().unwrap_or_default();
    assert_eq!(steps.len(), 2, "one step named damping, the next stopped: {}", r["steps"]);
    assert!(steps[0]["abstention"].is_null() && !steps[1]["abstention"].is_null(), "{}", r["steps"]);
    assert!(md.contains("## How the judge decided") && md.contains("### Step 2"), "{}", tail(&md));
    // The effect the fit found must be one the log could reveal where it was found (two computations: the fit
    // on the log's residual, the simulator's sensitivity at the magnitude of interest).
    let damping_left_arm = r["identifiability"]
        .as_array()
        .and_then(|a| a.iter().find(|i| i["kind"] == "damping"))
        .and_then(|i| i["units"].as_array()?.iter().find(|u| u["unit"] == "left_arm").cloned())
        .unwrap_or_default();
    assert!(
        damping_left_arm["signal"].as_f64().unwrap_or(0.0) >= damping_left_arm["floor"].as_f64().unwrap_or(f64::MAX),
        "damping on left_arm found but reported not identifiable: {damping_left_arm}"
    );

    // The corrected model: the named damping is in the arm's joints of the corrected MJCF and not in the nominal
    // twin written beside it, which is otherwise the same file.
    let xml = d.join("corrected.xml");
    let (code, out, err) = ulab(&[
        "gap",
        "diagnose",
        "--log",
        log.to_str().unwrap_or(""),
        "--out",
        d.join("report_export").to_str().unwrap_or(""),
        "--block",
        "0.5",
        "--effects",
        "damping",
        "--export-mjcf",
        xml.to_str().unwrap_or(""),
    ]);
    assert_eq!(code, Some(0), "diagnose --export-mjcf failed:\n{}\n{err}", tail(&out));
    let corrected = std::fs::read_to_string(&xml).unwrap_or_default();
    let nominal = std::fs::read_to_string(d.join("corrected.nominal.xml")).unwrap_or_default();
    let damping_of = |xml: &str, joint: &str| -> f64 {
        let at = xml.find(&format!(r#"name="{joint}""#)).unwrap_or(0);
        let v = xml[at..].split("damping=\"").nth(1).and_then(|t| t.split('"').next()).unwrap_or("nan");
        v.parse().unwrap_or(f64::NAN)
    };
    let (c, n) = (damping_of(&corrected, "left_elbow_joint"), damping_of(&nominal, "left_elbow_joint"));
    assert!((c - n - 2.5).abs() < 0.5, "left elbow damping {c} corrected vs {n} nominal");
    assert_eq!(damping_of(&corrected, "right_elbow_joint"), damping_of(&nominal, "right_elbow_joint"));

    // The same log through `ulab log export` (CSV pair) gives the same verdict and the same damping: asked about
    // damping alone (`--effects`, which also keeps this second diagnosis short).
    let csv = d.join("csv");
    let (code, out, err) =
        ulab(&["log", "export", log.to_str().unwrap_or(""), "--format", "csv", "--out", csv.to_str().unwrap_or("")]);
    assert_eq!(code, Some(0), "export failed:\n{out}\n{err}");
    let (code, out, err) = ulab(&[
        "gap",
        "diagnose",
        "--log",
        csv.to_str().unwrap_or(""),
        "--out",
        d.join("report_csv").to_str().unwrap_or(""),
        "--format",
        "json",
        "--block",
        "0.5",
        "--effects",
        "damping",
    ]);
    assert_eq!(code, Some(0), "diagnose (csv) failed:\n{}\n{err}", tail(&out));
    let c: serde_json::Value = serde_json::from_str(&out).expect("JSON report on stdout");
    assert_eq!(c["ranked"], serde_json::json!(["damping"]), "ranked {}", c["ranked"]);
    let kinds: Vec<&str> =
        c["effects"].as_array().map(|a| a.iter().filter_map(|e| e["kind"].as_str()).collect()).unwrap_or_default();
    assert_eq!(kinds, vec!["damping"], "only the effect asked about is assessed");
    let damping = |r: &serde_json::Value| -> Vec<(String, f64)> {
        let e = r["effects"].as_array().and_then(|a| a.iter().find(|e| e["kind"] == "damping").cloned());
        let ps = e.and_then(|e| e["params"].as_array().cloned()).unwrap_or_default();
        ps.iter()
            .map(|p| (p["unit"].as_str().unwrap_or("").to_string(), p["value"].as_f64().unwrap_or(f64::NAN)))
            .collect()
    };
    let (from_csv, from_mcap) = (damping(&c), damping(&r));
    assert_eq!(from_csv.len(), from_mcap.len(), "{from_csv:?} vs {from_mcap:?}");
    for ((u, v), (w, x)) in from_csv.iter().zip(&from_mcap) {
        assert!(u == w && (v - x).abs() <= 0.05 * x.abs(), "{from_csv:?} vs {from_mcap:?}");
    }
}

#[test]
fn excitation_plan_is_within_limits_and_readable() {
    let d = dir("excite");
    let plan = d.join("plan.mcap");
    let (code, out, err) = ulab(&[
        "gap",
        "excite",
        "--robot",
        "h1_2",
        "--duration",
        "6",
        "--rate",
        "100",
        "--out",
        plan.to_str().unwrap_or(""),
    ]);
    assert_eq!(code, Some(0), "excite failed:\n{out}\n{err}");
    let v = read_with_python(&plan);
    assert_eq!(v["errors"].as_array().map(|a| a.len()), Some(0), "{}", v["errors"]);
    assert_eq!(v["topics"]["rt/lowcmd"]["count"], 600);
    assert!(v["topics"].get("rt/lowstate").is_none(), "a plan holds commands only");
    // Limits from the URDF the model reads, checked on the decoded commands.
    let model = robot_model::builtin("h1_2").expect("model");
    let bytes = std::fs::read(&plan).expect("plan");
    let mut moved = vec![false; model.nj()];
    for m in mcap::MessageStream::new(&bytes).expect("mcap") {
        let m = m.expect("message");
        let c = lowlevel_codec::decode::<unitree_idl::hg::LowCmd_>(&m.data).expect("LowCmd").value;
        assert!(lowlevel_codec::verify(&c), "CRC");
        for (j, joint) in model.joints.iter().enumerate() {
            let q = f64::from(c.motor_cmd[joint.slot].q);
            assert!(
                q > joint.lower && q < joint.upper,
                "{} target {q} outside [{}, {}]",
                joint.name,
                joint.lower,
                joint.upper
            );
            assert!(f64::from(c.motor_cmd[joint.slot].kp) <= joint.kp + 1e-3);
            moved[j] |= (q - joint.default_q).abs() > 0.02;
        }
    }
    assert!(moved.iter().filter(|m| **m).count() >= model.nj() - 2, "most joints are excited: {moved:?}");
}

#[test]
fn bad_input_fails_cleanly() {
    let d = dir("bad");
    let junk = d.join("junk.mcap");
    std::fs::write(&junk, b"not an mcap file at all").expect("write");
    let (code, _, err) =
        ulab(&["gap", "diagnose", "--log", junk.to_str().unwrap_or(""), "--out", d.join("o").to_str().unwrap_or("")]);
    assert_eq!(code, Some(2));
    assert!(err.contains("MCAP"), "{err}");
    let (code, _, err) = ulab(&[
        "gap",
        "diagnose",
        "--log",
        junk.to_str().unwrap_or(""),
        "--engine",
        "bullet",
        "--out",
        d.join("o").to_str().unwrap_or(""),
    ]);
    assert_eq!(code, Some(2));
    assert!(err.contains("engine"), "{err}");
    // An unknown effect kind is named with the kinds there are, before any log is read.
    let (code, _, err) = ulab(&[
        "gap",
        "diagnose",
        "--log",
        junk.to_str().unwrap_or(""),
        "--effects",
        "damping,stiction",
        "--out",
        d.join("o").to_str().unwrap_or(""),
    ]);
    assert_eq!(code, Some(2));
    assert!(err.contains("`stiction`") && err.contains("link_com"), "{err}");
    let (code, _, err) = ulab(&[
        "gap",
        "simulate",
        "--effect",
        "damping:left_tail:1",
        "--duration",
        "2",
        "--out",
        d.join("x.mcap").to_str().unwrap_or(""),
    ]);
    assert_eq!(code, Some(2));
    assert!(err.contains("left_tail"), "{err}");
    // A trial outside the bench is refused before any log is generated.
    let (code, _, err) = ulab(&[
        "gap",
        "bench",
        "--trials",
        "3",
        "--out-of-library",
        "1",
        "--only",
        "4",
        "--out",
        d.join("b").to_str().unwrap_or(""),
    ]);
    assert_eq!(code, Some(2));
    assert!(err.contains("--only 4") && err.contains("0 to 3"), "{err}");
}

/// A walking robot through the CLI: `ulab gap bench --floating` writes one sealed trial log of Unitree's LSTM
/// walking on the ground with a hidden effect; `ulab gap diagnose` on that MCAP picks the floating-base plant by
/// itself and names what the opened seal says was injected; `--plant rig` on the same log abstains with exit 3.
#[test]
fn walking_log_is_diagnosed_on_the_floating_base() {
    if std::env::var_os("ULAB_SHARED").is_none() {
        eprintln!("skipped: ULAB_SHARED is not set (the walking policy's weights live in the shared reference folder)");
        return;
    }
    let d = dir("floating");
    let bench = d.join("bench");
    let policy = root().join("robots/h1_2/policies/unitree_rl_gym_lstm.toml");
    let (code, out, err) = ulab(&[
        "gap",
        "bench",
        "--floating",
        "--policy",
        policy.to_str().unwrap_or(""),
        "--trials",
        "1",
        "--seed",
        "1",
        "--duration",
        "4",
        "--out",
        bench.to_str().unwrap_or(""),
    ]);
    assert_eq!(code, Some(0), "bench failed:\n{}\n{}", tail(&out), tail(&err));
    let scores: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(bench.join("scores.json")).unwrap_or_default())
            .expect("scores.json");
    let injected = &scores[0]["injected"];
    assert_eq!(injected.as_array().map(Vec::len), Some(1), "trial 0 is a single effect: {injected}");
    let log = bench.join("trial_000.mcap");

    let (code, out, err) = ulab(&[
        "gap",
        "diagnose",
        "--log",
        log.to_str().unwrap_or(""),
        "--out",
        d.join("report").to_str().unwrap_or(""),
        "--format",
        "json",
        "--block",
        "0.5",
    ]);
    assert_eq!(code, Some(0), "diagnose failed:\n{}\n{err}", tail(&out));
    let r: serde_json::Value = serde_json::from_str(&out).expect("JSON report on stdout");
    assert_eq!(r["plant"], "floating", "rig check: {}", r["rig_check"]["message"]);
    assert_eq!(r["rig_check"]["suspended"], false);
    assert!(
        r["rig_check"]["foot_load_fraction"].as_f64().is_some_and(|f| f > 0.5),
        "a walking robot's feet carry it: {}",
        r["rig_check"]
    );
    assert_eq!(r["windows_down"], 0);
    assert_eq!(r["ranked"][0], injected[0]["kind"], "ranked {} for {injected}", r["ranked"]);

    let (code, _, err) = ulab(&[
        "gap",
        "diagnose",
        "--log",
        log.to_str().unwrap_or(""),
        "--out",
        d.join("report_rig").to_str().unwrap_or(""),
        "--plant",
        "rig",
    ]);
    assert_eq!(code, Some(3), "--plant rig on a walking log must abstain with exit 3:\n{err}");
    assert!(err.contains("ABSTAINED"), "{err}");
}
