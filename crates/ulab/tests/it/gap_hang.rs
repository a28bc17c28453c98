//! The gap diagnosis end to end on a real recording, as on the robot's gantry: `ulab sim --hang` (the simulated
//! H1-2 on the suspension stand) on loopback DDS, `ulab record` of rt/lowcmd + rt/lowstate while `ulab replay`
//! plays a short `ulab gap excite` plan to it, then `ulab gap diagnose` on the recorded MCAP. The hung simulator
//! and the diagnosing plant are the same model on the same stand, so the log must pass the rig-assumption check
//! and no effect may be named: the only gap is DDS and scheduling timing.
//!
//! Nothing depends on the machine's speed (issue 21): the replay starts once both the simulator and the recorder
//! subscribe to rt/lowcmd, and the recorder and simulator are stopped as Ctrl-C would once the replay is done.
use crate::common;
use common::{interrupt, lease_domain, run_ulab, spawn_ulab, tail, wait_with_timeout, KillOnDrop, RealtimeSlot};
use std::path::Path;
use std::time::Duration;

fn spawn(args: &[&str]) -> KillOnDrop {
    KillOnDrop(Some(spawn_ulab(args)))
}

/// Stops a child as Ctrl-C would and collects its exit code and output.
fn finish(mut p: KillOnDrop, timeout: Duration) -> (Option<i32>, String, String) {
    let child = p.0.take().expect("child");
    interrupt(&child);
    let (status, out, err) = wait_with_timeout(child, timeout);
    (status.and_then(|s| s.code()), out, err)
}

#[test]
fn hung_sim_recording_is_diagnosed_without_a_confident_effect() {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ulab-gap-hang");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    let (plan, rec, out) = (d.join("plan.mcap"), d.join("rec.mcap"), d.join("report"));
    let s = |p: &Path| p.to_str().unwrap_or("").to_string();

    let (code, o, e) =
        run_ulab(&["gap", "excite", "--duration", "6", "--rate", "100", "--out", &s(&plan)], Duration::from_secs(30));
    assert_eq!(code, Some(0), "excite failed:\n{o}\n{e}");

    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let d = domain.arg();
    let sim = spawn(&["sim", "--hang", "--on-time-state", "--domain", &d, "--quiet"]);
    let recorder = spawn(&["record", "--domain", &d, "--quiet", "--out", &s(&rec)]);
    // The replay starts once both the simulator and the recorder subscribe to rt/lowcmd.
    let (code, o, e) = run_ulab(
        &["replay", &s(&plan), "--domain", &d, "--topics", "rt/lowcmd", "--min-readers", "2", "--wait-readers", "60"],
        Duration::from_secs(180),
    );
    assert_eq!(code, Some(0), "replay failed:\n{o}\n{e}");
    assert!(!e.contains("publishing anyway"), "the replay started before both subscribers were there:\n{e}");
    let (code, o, e) = finish(recorder, Duration::from_secs(60));
    assert_eq!(code, Some(0), "record failed:\n{o}\n{e}");
    drop(finish(sim, Duration::from_secs(60)));

    let (code, o, e) = run_ulab(
        &["gap", "diagnose", "--log", &s(&rec), "--out", &s(&out), "--format", "json", "--block", "0.5"],
        Duration::from_secs(180),
    );
    assert_eq!(code, Some(0), "diagnose failed or abstained on the rig check:\n{}\n{e}", tail(&o));
    let r: serde_json::Value = serde_json::from_str(&o).expect("JSON report");
    eprintln!("rig check: {}", r["rig_check"]["message"]);
    eprintln!(
        "baseline {} ; effects: {}",
        r["baseline_metric"],
        r["effects"]
            .as_array()
            .map(|a| a
                .iter()
                .map(|e| format!("{}:{}:{}", e["kind"], e["named"], e["reduction"]["value"]))
                .collect::<Vec<_>>()
                .join(" "))
            .unwrap_or_default()
    );
    assert_eq!(r["outcome"], "diagnosed");
    assert_eq!(r["rig_check"]["suspended"], true, "{}", r["rig_check"]);
    assert!(r["log_duration_s"].as_f64().unwrap_or(0.0) > 6.0, "{}", r["log_duration_s"]);
    assert_eq!(
        r["ranked"].as_array().map(Vec::len),
        Some(0),
        "named effects on a log of the same model: {}",
        r["ranked"]
    );
    assert_eq!(r["unexplained"], true);
}

#[test]
fn diagnose_with_plant_rig_abstains_with_exit_3_on_a_swinging_pelvis() {
    // A rig log whose torso IMU also swings ±6° at 1 Hz about x (the pelvis is not held): the rig check fails and,
    // with `--plant rig`, the CLI writes the abstaining report, says so on stderr and exits 3.
    let m = robot_model::builtin("h1_2").expect("model");
    let cfg = gap_bench::RealConfig::new(&m, 4.0, 2);
    let mut log = gap_bench::generate_log(&m, &cfg).expect("log");
    for s in &mut log.states {
        // swing ⊗ quat, swing = rotation of 0.1 sin(2π t) rad about the world x axis.
        let half = 0.05 * (2.0 * std::f64::consts::PI * s.t).sin();
        let (c, x) = (half.cos(), half.sin());
        let [w, i, j, k] = s.quat;
        s.quat = [c * w - x * i, c * i + x * w, c * j - x * k, c * k + x * j];
    }
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ulab-gap-swing");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    let file = d.join("swing.mcap");
    log.write_mcap(std::io::BufWriter::new(std::fs::File::create(&file).expect("create")), &m).expect("write");
    let out = d.join("report");
    let f = |p: &Path| p.to_str().unwrap_or("").to_string();
    let (code, o, e) = run_ulab(
        &["gap", "diagnose", "--log", &f(&file), "--plant", "rig", "--out", &f(&out), "--format", "json"],
        Duration::from_secs(120),
    );
    assert_eq!(code, Some(3), "expected the rig-check abstention:\n{}\n{e}", tail(&o));
    assert!(e.contains("ABSTAINED") && e.contains("not from a suspended robot"), "{e}");
    let r: serde_json::Value = serde_json::from_str(&o).expect("JSON report");
    assert_eq!(r["outcome"], "rig_assumption_violated");
    assert_eq!(r["ranked"].as_array().map(Vec::len), Some(0));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap_or_default();
    assert!(md.contains("Rig assumption violated"), "{}", tail(&md));
}
