//! `ulab diff` end to end: a short run with the built-in input across the three engines writes the report
//! files and reproducers that `ulab diff replay` reproduces bit for bit (a tampered one exits 1); fuzzing
//! writes a corpus and a report; the shipped policy specs run (they read models through $ULAB_SHARED);
//! bad arguments exit 2.

use crate::common;

use common::{root, tail};
use std::path::Path;

fn ulab(args: &[&str]) -> (Option<i32>, String, String) {
    // From the repository root: relative policy paths resolve there (in every shard and the merge, too).
    common::run_ulab_from_root(args)
}

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("ulab_diff_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn reproducers(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .expect("out dir")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with("repro_")))
        .collect();
    v.sort();
    v
}

#[test]
fn builtin_input_report_and_bit_exact_replay() {
    let out = tmp("run");
    let o = out.to_string_lossy().to_string();
    let (code, stdout, err) = ulab(&[
        "diff",
        "--robot",
        "h1_2",
        "--engines",
        "mujoco,rapier-multibody,rapier-impulse",
        "--episodes",
        "2",
        "--seconds",
        "0.2",
        "--seed",
        "3",
        "--window",
        "25",
        "--minimize",
        "2",
        "--out",
        &o,
    ]);
    assert_eq!(code, Some(0), "{}\n{}", stdout, tail(&err));
    let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    assert!(
        md.contains("rapier_multibody") && md.contains("rapier_impulse") && md.contains("Triaged divergences"),
        "{md}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).expect("report.json")).expect("json");
    assert_eq!(json["schema_version"], 1);
    assert_eq!(json["seeds"], serde_json::json!([3, 4]));
    assert_eq!(json["engines"].as_array().map(|a| a.len()), Some(3));
    for e in json["entries"].as_array().expect("entries") {
        assert!(e["triage"]["class"].is_string(), "untriaged entry {e}");
    }
    for svg in ["one_step.svg", "k_step.svg", "per_joint.svg"] {
        let t = std::fs::read_to_string(out.join(svg)).expect(svg);
        assert!(t.contains("<svg") && t.contains("<polyline"), "{svg}");
    }
    let repros = reproducers(&out);
    assert_eq!(
        repros.len(),
        json["entries"].as_array().map(|a| a.iter().filter(|e| !e["minimized"].is_null()).count()).unwrap_or(0)
    );
    for r in &repros {
        let (code, stdout, err) = ulab(&["diff", "replay", &r.to_string_lossy()]);
        assert_eq!(code, Some(0), "{}: {stdout}\n{}", r.display(), tail(&err));
        assert!(stdout.contains("identical"), "{stdout}");
    }
    if let Some(r) = repros.first() {
        // Flip the lowest bit of one expected state entry: the replay must notice.
        let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(r).expect("read")).expect("json");
        let x = v["expected"]["states"][0]["qpos"][9].as_str().expect("bits").to_string();
        let flipped = format!("{:016x}", u64::from_str_radix(&x, 16).expect("hex") ^ 1);
        v["expected"]["states"][0]["qpos"][9] = serde_json::Value::String(flipped);
        let bad = out.join("tampered.json");
        std::fs::write(&bad, v.to_string()).expect("write");
        let (code, stdout, _) = ulab(&["diff", "replay", &bad.to_string_lossy()]);
        assert_eq!(code, Some(1), "{stdout}");
        assert!(stdout.contains("DIFFERS"), "{stdout}");
    }
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn dart_runs_in_diff_and_replays_bit_for_bit() {
    // DART against MuJoCo; every reproducer is replayed in a fresh process: DART's results must not depend on
    // anything but the inputs (no collision-order or allocation-dependent state).
    let out = tmp("dart");
    let o = out.to_string_lossy().to_string();
    let (code, stdout, err) = ulab(&[
        "diff",
        "--robot",
        "h1_2",
        "--engines",
        "mujoco,dart",
        "--episodes",
        "1",
        "--seconds",
        "0.3",
        "--seed",
        "5",
        "--window",
        "25",
        "--minimize",
        "2",
        "--out",
        &o,
    ]);
    assert_eq!(code, Some(0), "{}\n{}", stdout, tail(&err));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).expect("report.json")).expect("json");
    let names: Vec<&str> =
        json["engines"].as_array().expect("engines").iter().filter_map(|e| e["name"].as_str()).collect();
    assert_eq!(names, ["mujoco", "dart"], "{}", json["engines"]);
    let repros = reproducers(&out);
    for r in &repros {
        let (code, stdout, err) = ulab(&["diff", "replay", &r.to_string_lossy()]);
        assert_eq!(code, Some(0), "{}: {stdout}\n{}", r.display(), tail(&err));
        assert!(stdout.contains("identical"), "{stdout}");
    }
    eprintln!("mujoco vs dart: {} reproducers replayed identically", repros.len());
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn fuzz_writes_corpus_and_triaged_report() {
    let out = tmp("fuzz");
    let o = out.to_string_lossy().to_string();
    let (code, stdout, err) = ulab(&[
        "diff",
        "fuzz",
        "--engines",
        "mujoco,rapier-impulse",
        "--iterations",
        "6",
        "--seconds",
        "0.1",
        "--window",
        "10",
        "--minimize",
        "1",
        "--seed",
        "1",
        "--jobs",
        "2",
        "--out",
        &o,
    ]);
    assert_eq!(code, Some(0), "{stdout}\n{}", tail(&err));
    assert!(stdout.contains("6 inputs evaluated"), "{stdout}");
    let corpus = std::fs::read_dir(out.join("corpus")).expect("corpus").count();
    assert!(corpus >= 1);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).expect("report.json")).expect("json");
    for e in json["entries"].as_array().expect("entries") {
        assert!(e["triage"]["class"].is_string(), "untriaged entry {e}");
    }
    // With this seed the search finds at least one divergence; its reproducer replays bit for bit.
    let repros = reproducers(&out);
    assert!(!repros.is_empty(), "no reproducer written");
    for r in &repros {
        let (code, stdout, err) = ulab(&["diff", "replay", &r.to_string_lossy()]);
        assert_eq!(code, Some(0), "{}: {stdout}\n{}", r.display(), tail(&err));
        assert!(stdout.contains("identical"), "{stdout}");
    }
    // Flip the lowest bit of the recorded value: the replay must notice and exit 1.
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&repros[0]).expect("read")).expect("json");
    let x = v["expected"]["value_bits"].as_str().expect("bits").to_string();
    v["expected"]["value_bits"] =
        serde_json::Value::String(format!("{:016x}", u64::from_str_radix(&x, 16).expect("hex") ^ 1));
    let bad = out.join("tampered.json");
    std::fs::write(&bad, v.to_string()).expect("write");
    let (code, stdout, _) = ulab(&["diff", "replay", &bad.to_string_lossy()]);
    assert_eq!(code, Some(1), "{stdout}");
    assert!(stdout.contains("DIFFERS"), "{stdout}");
    // The written corpus is a valid seed corpus.
    let out2 = tmp("fuzz2");
    let (code, stdout, err) = ulab(&[
        "diff",
        "fuzz",
        "--engines",
        "mujoco,rapier-impulse",
        "--iterations",
        "1",
        "--seconds",
        "0.05",
        "--window",
        "10",
        "--minimize",
        "0",
        "--corpus",
        &out.join("corpus").to_string_lossy(),
        "--out",
        &out2.to_string_lossy(),
    ]);
    assert_eq!(code, Some(0), "{stdout}\n{}", tail(&err));
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_dir_all(&out2);
}

/// A fuzzing campaign is the same on any machine: its rounds have a fixed size (`--batch`), so the inputs drawn,
/// the corpus and the report do not depend on how many threads run them. They did: the round was twice the thread
/// count, so `--jobs 1` and `--jobs 3` (or a 2-core and a 64-core machine) fuzzed different inputs from one seed.
#[test]
fn fuzz_campaign_is_the_same_on_any_thread_count() {
    let run = |jobs: &str| {
        let out = tmp(&format!("fuzz-jobs{jobs}"));
        let (code, stdout, err) = ulab(&[
            "diff",
            "fuzz",
            "--engines",
            "mujoco,rapier-impulse",
            "--iterations",
            "10",
            "--seconds",
            "0.1",
            "--window",
            "10",
            "--minimize",
            "0",
            "--seed",
            "3",
            "--jobs",
            jobs,
            "--out",
            &out.to_string_lossy(),
        ]);
        assert_eq!(code, Some(0), "--jobs {jobs}: {stdout}\n{}", tail(&err));
        out
    };
    let (a, b) = (run("1"), run("3"));
    // Wall-clock fields aside (`timing.engine_s`, `timing.total_s`), the reports are equal.
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(m) => {
                m.remove("engine_s");
                m.remove("total_s");
                m.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let report = |d: &Path| {
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("report.json")).expect("report.json")).expect("json");
        strip(&mut v);
        v
    };
    assert_eq!(report(&a), report(&b), "report.json differs between --jobs 1 and --jobs 3");
    let corpus = |d: &Path| {
        let mut files: Vec<_> = std::fs::read_dir(d.join("corpus"))
            .expect("corpus")
            .map(|e| {
                let p = e.expect("entry").path();
                (p.file_name().map(|n| n.to_owned()), std::fs::read(&p).expect("read"))
            })
            .collect();
        files.sort();
        files
    };
    let (ca, cb) = (corpus(&a), corpus(&b));
    assert!(!ca.is_empty());
    assert!(ca == cb, "the corpus differs between --jobs 1 and --jobs 3 ({} vs {} entries)", ca.len(), cb.len());
    let _ = std::fs::remove_dir_all(&a);
    let _ = std::fs::remove_dir_all(&b);
}

#[test]
fn shipped_policies_run_across_engines() {
    if std::env::var_os("ULAB_SHARED").is_none() {
        eprintln!("skipped: ULAB_SHARED is not set (the policy models live in the shared reference folder)");
        return;
    }
    for spec in ["gepetto_demo_rsl.toml", "unitree_rl_gym_lstm.toml"] {
        let out = tmp(spec);
        let p = root().join("robots/h1_2/policies").join(spec);
        let (code, stdout, err) = ulab(&[
            "diff",
            "--policy",
            &p.to_string_lossy(),
            "--episodes",
            "2",
            "--seconds",
            "0.2",
            "--window",
            "25",
            "--minimize",
            "1",
            "--out",
            &out.to_string_lossy(),
        ]);
        assert_eq!(code, Some(0), "{spec}: {stdout}\n{}", tail(&err));
        let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
        assert!(md.contains("Episode outcomes"), "{md}");
        let _ = std::fs::remove_dir_all(&out);
    }
}

#[test]
fn bad_arguments_exit_2() {
    for args in [
        vec!["diff", "--engines", "mujoco", "--out", "/tmp/x"],
        vec!["diff", "--engines", "mujoco,bogus", "--out", "/tmp/x"],
        vec!["diff", "--seconds", "-1", "--out", "/tmp/x"],
        vec!["diff", "--seconds", "0.1"],
        vec!["diff", "replay", "/nonexistent/repro.json"],
        vec!["diff", "--policy", "/nonexistent/spec.toml", "--out", "/tmp/x"],
    ] {
        let (code, _, err) = ulab(&args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(err.starts_with("error:"), "{err}");
    }
}

/// `ulab diff hash --check corpus/determinism` reproduces the committed table of this machine class from its own
/// process (the library test `engine-diff`'s `determinism::` checks it in the test's process on one and two
/// threads), and a copy of that table with MuJoCo's hash changed makes it exit 1. On a machine of a class no table
/// was measured on, the engines are reported as not compared and the tampered check cannot fail: the test then
/// says so and checks only that.
#[test]
fn hash_table_reproduces_from_the_cli_and_a_tampered_table_differs() {
    let (code, out, err) = ulab(&["diff", "hash", "--check", "corpus/determinism"]);
    assert_eq!(code, Some(0), "stdout:\n{out}\nstderr:\n{}", tail(&err));
    // The committed table of this machine class, if there is one (the first line names the class).
    let class = out.lines().next().and_then(|l| l.strip_prefix("machine class ")).and_then(|l| l.split(';').next());
    let class = class.expect("the first line names the machine class").to_string();
    let mut table = None;
    for entry in std::fs::read_dir(root().join("corpus/determinism")).expect("tables") {
        let path = entry.expect("entry").path();
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).expect("table")).expect("table parses");
        let m = &json["machine"];
        let mut name = m["arch"].as_str().expect("arch").to_string();
        for f in m["features"].as_array().expect("features") {
            name = format!("{name}+{}", f.as_str().expect("feature"));
        }
        if name == class && json["robot"] == "h1_2" {
            table = Some(json);
        }
    }
    let other_class = table.is_none();
    if other_class {
        assert!(out.contains("not compared: corpus/determinism has no table for h1_2 on"), "{out}");
    } else {
        for engine in ["mujoco", "rapier_multibody", "rapier_impulse", "bullet", "dart"] {
            assert!(out.contains(&format!("{engine}: reproduced")), "{engine} not reproduced:\n{out}");
        }
    }
    let mut json = match table {
        Some(t) => t,
        None => {
            serde_json::from_str(&std::fs::read_to_string(root().join("corpus/determinism/h1_2.json")).expect("table"))
                .expect("table parses")
        }
    };
    let entries = json["engines"].as_array_mut().expect("engines");
    let mujoco = entries.iter_mut().find(|e| e["engine"] == "mujoco").expect("mujoco entry");
    let hash = mujoco["sha256"].as_str().expect("hash").to_string();
    let flipped = match hash.strip_prefix('0') {
        Some(rest) => format!("1{rest}"),
        None => format!("0{}", hash.get(1..).expect("a hex hash")),
    };
    mujoco["sha256"] = serde_json::Value::String(flipped);
    let dir = tmp("hash");
    std::fs::create_dir_all(&dir).expect("tmp dir");
    let tampered = dir.join("tampered.json");
    std::fs::write(&tampered, serde_json::to_string(&json).expect("json")).expect("write");
    let (code, out, err) = ulab(&["diff", "hash", "--engines", "mujoco", "--check", &tampered.to_string_lossy()]);
    if other_class {
        eprintln!("machine class differs from the table's: the tampered table cannot be detected here\n{out}");
        assert_eq!(code, Some(0), "stdout:\n{out}\nstderr:\n{}", tail(&err));
    } else {
        assert_eq!(code, Some(1), "a changed hash must exit 1; stdout:\n{out}\nstderr:\n{}", tail(&err));
        assert!(out.contains("mujoco: DIFFERS"), "{out}");
    }
    let (code, _, err) = ulab(&["diff", "hash", "--seconds", "0", "--engines", "mujoco"]);
    assert_eq!(code, Some(2), "--seconds 0 is an input error: {err}");
}
