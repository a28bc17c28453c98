//! Sharded campaigns end to end (issue 62): a small campaign of each kind runs unsharded, then as 3 shards
//! (`--shard K/3`, one process each) merged by `ulab merge`; the merged output directory must hold the same files
//! as the unsharded one, byte for byte, but for the wall-clock fields of `report.json` (`timing.engine_s`,
//! `timing.total_s` of `ulab diff` and `ulab diff fuzz`) and the diagnosis times of `ulab gap bench` (its scores, table and per-trial
//! reports). Bad shard specs and bad sets of shards exit 2 with their reason.

use crate::common;

use common::tail;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn ulab(args: &[&str]) -> (Option<i32>, String, String) {
    // From the repository root: relative policy paths resolve there (in every shard and the merge, too).
    common::run_ulab_from_root(args)
}

fn ok(args: &[&str]) -> String {
    let (code, out, err) = ulab(args);
    assert_eq!(code, Some(0), "{args:?}\n{out}\n{}", tail(&err));
    out
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ulab_shard_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn s(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

/// Every file under `dir`, by its path relative to `dir` (`/`-separated).
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(dir: &Path, prefix: &str, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(dir).expect("output dir").filter_map(|e| e.ok()) {
            let name = format!("{prefix}{}", e.file_name().to_string_lossy());
            if e.path().is_dir() {
                walk(&e.path(), &format!("{name}/"), out);
            } else {
                out.insert(name, std::fs::read(e.path()).expect("read"));
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, "", &mut out);
    out
}

/// Texts equal line for line, but for lines that start (after indentation) with one of `wall_clock`; each of those
/// prefixes must be skipped as often as it is listed, at the same lines in both, so that a renamed field cannot make
/// the comparison vacuous.
fn assert_same_lines(what: &str, a: &str, b: &str, wall_clock: &[&str]) {
    let (la, lb): (Vec<&str>, Vec<&str>) = (a.lines().collect(), b.lines().collect());
    assert_eq!(la.len(), lb.len(), "{what}: line counts differ");
    let key = |l: &str| wall_clock.iter().find(|k| l.trim_start().starts_with(*k)).copied();
    let mut skipped = Vec::new();
    for (i, (x, y)) in la.iter().zip(&lb).enumerate() {
        match (key(x), key(y)) {
            (Some(k), Some(k2)) if k == k2 => skipped.push(k),
            _ => assert_eq!(x, y, "{what} line {}", i + 1),
        }
    }
    skipped.sort_unstable();
    let mut want = wall_clock.to_vec();
    want.sort_unstable();
    assert_eq!(skipped, want, "{what}: each wall-clock line as often as listed");
}

/// JSON texts equal line for line, but for the lines of the keys `wall_clock` (each as often as listed).
fn assert_same_json(what: &str, a: &str, b: &str, wall_clock: &[&str]) {
    let keys: Vec<String> = wall_clock.iter().map(|k| format!("\"{k}\":")).collect();
    assert_same_lines(what, a, b, &keys.iter().map(String::as_str).collect::<Vec<_>>());
}

fn text(v: &[u8]) -> String {
    String::from_utf8(v.to_vec()).expect("utf-8")
}

/// Runs `campaign` unsharded into `whole/`, as shards 1/3..3/3 into `shards/`, merges into `merged/`, and checks
/// that both hold the same files; `compare(path, unsharded, merged)` compares each pair.
fn unsharded_equals_merged_by(name: &str, campaign: &[&str], compare: impl Fn(&str, &[u8], &[u8])) -> PathBuf {
    let base = tmp(name);
    let (whole, shards, merged) = (base.join("whole"), base.join("shards"), base.join("merged"));
    ok(&[campaign, &["--out", &s(&whole)]].concat());
    for k in 1..=3 {
        let spec = format!("{k}/3");
        let out = ok(&[campaign, &["--out", &s(&shards), "--shard", &spec]].concat());
        assert!(out.contains(&format!("shard {spec}")), "{out}");
    }
    for report in ["report.json", "table.md"] {
        assert!(!shards.join(report).exists(), "a shard writes no report");
    }
    ok(&["merge", &s(&shards), "--out", &s(&merged)]);
    let (a, b) = (files(&whole), files(&merged));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>(), "the same files");
    for (f, bytes) in &a {
        compare(f, bytes, &b[f]);
    }
    base
}

/// [`unsharded_equals_merged_by`] with every file byte-identical, but for the `wall_clock` keys of `report.json`.
fn unsharded_equals_merged(name: &str, campaign: &[&str], wall_clock: &[&str]) -> PathBuf {
    unsharded_equals_merged_by(name, campaign, |f, a, b| {
        if f == "report.json" {
            assert_same_json(f, &text(a), &text(b), wall_clock);
        } else {
            assert!(a == b, "{f} differs");
        }
    })
}

/// `ulab diff fuzz` of 4 lanes (12 inputs): lanes 0 and 3 in shard 1, so the merge puts lanes back in order; the
/// corpus files and the report are the unsharded campaign's.
#[test]
fn fuzz_campaign_merged_from_three_shards_equals_the_unsharded_run() {
    let campaign = [
        "diff",
        "fuzz",
        "--engines",
        "mujoco,rapier-impulse",
        "--iterations",
        "12",
        "--lanes",
        "4",
        "--seconds",
        "0.1",
        "--seed",
        "2",
        "--window",
        "10",
        "--minimize",
        "1",
    ];
    let base = unsharded_equals_merged("fuzz", &campaign, &["engine_s", "total_s"]);
    let corpus = std::fs::read_dir(base.join("merged/corpus")).expect("corpus").count();
    assert!(corpus >= 4, "every lane adds its seeds' entries: {corpus}");
}

#[test]
fn diff_campaign_merged_from_three_shards_equals_the_unsharded_run() {
    let campaign = [
        "diff",
        "--engines",
        "mujoco,rapier-impulse",
        "--episodes",
        "4",
        "--seconds",
        "0.2",
        "--seed",
        "5",
        "--window",
        "25",
        "--minimize",
        "1",
    ];
    let base = unsharded_equals_merged("diff", &campaign, &["engine_s", "total_s"]);
    let shards = base.join("shards");

    // A shard names the commit its `ulab` was built from, as git reports this checkout's.
    let header = campaign::read_header(&shards.join("shard-1-of-3.cbor")).expect("shard header");
    let head = std::process::Command::new("git").args(["rev-parse", "--short=12", "HEAD"]).output().expect("git");
    let head = String::from_utf8_lossy(&head.stdout).trim().to_owned();
    assert!(head.len() == 12 && header.producer.ends_with(&format!("(commit {head})")), "{} / {head}", header.producer);

    // A missing shard, and a shard of another campaign (another seed), are refused.
    let (code, _, err) = ulab(&[
        "merge",
        &s(&shards.join("shard-1-of-3.cbor")),
        &s(&shards.join("shard-3-of-3.cbor")),
        "--out",
        &s(&base.join("m2")),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("shard(s) [2] of 3 missing"), "{err}");
    let other = base.join("other");
    let mut seed9 = campaign.to_vec();
    seed9[8] = "9";
    ok(&[&seed9[..], &["--out", &s(&other), "--shard", "2/3"]].concat());
    let (code, _, err) = ulab(&[
        "merge",
        &s(&shards.join("shard-1-of-3.cbor")),
        &s(&other.join("shard-2-of-3.cbor")),
        &s(&shards.join("shard-3-of-3.cbor")),
        "--out",
        &s(&base.join("m3")),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("different campaign configuration"), "{err}");
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn validate_campaign_merged_from_three_shards_equals_the_unsharded_run() {
    let campaign = [
        "validate",
        "--policy",
        "robots/h1_2/policies/unitree_rl_gym_lstm.toml",
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
    ];
    // The validation report holds no wall-clock time: the whole report.json is compared.
    let base = unsharded_equals_merged("validate", &campaign, &[]);
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn gap_bench_merged_from_three_shards_equals_the_unsharded_run() {
    // A small rig bench that still deals two trials to one shard (trials 0 and 3 to shard 1/3): the shortest log
    // the bench takes, diagnosed with one effect kind on 8 windows (about 2 s a trial instead of 90).
    let trials = 4;
    let n = trials.to_string();
    let campaign = [
        "gap",
        "bench",
        "--trials",
        &n,
        "--seed",
        "3",
        "--duration",
        "4",
        "--effects",
        "damping",
        "--max-windows",
        "8",
    ];
    let base = unsharded_equals_merged_by("gap", &campaign, |f, a, b| {
        let (ta, tb) = (text_or_empty(f, a), text_or_empty(f, b));
        if f == "scores.json" {
            assert_same_json(f, &ta, &tb, &vec!["diagnose_s"; trials]);
        } else if f == "table.md" {
            assert_same_lines(f, &ta, &tb, &["| mean diagnosis time per log |"]);
        } else if f.ends_with("/report.json") {
            // The diagnosis's wall time and each of its stages' (as many stages as the unsharded report lists).
            let r: serde_json::Value = serde_json::from_str(&ta).expect("trial report.json");
            let stages = r["stages"].as_array().map_or(0, Vec::len);
            assert!(stages > 0, "{f}: no stage times");
            let mut wall_clock = vec!["s"; stages];
            wall_clock.push("elapsed_s");
            assert_same_json(f, &ta, &tb, &wall_clock);
        } else if f.ends_with("/report.md") {
            assert_same_lines(f, &ta, &tb, &["Diagnosis time:"]);
        } else {
            assert!(a == b, "{f} differs");
        }
    });
    // Every trial's log and report reached the merged directory, beside the bench's own files.
    let merged = files(&base.join("merged"));
    for i in 0..trials {
        for f in [format!("trial_{i:03}.mcap"), format!("trial_{i:03}/report.json")] {
            assert!(merged.contains_key(&f), "{f} missing: {:?}", merged.keys().collect::<Vec<_>>());
        }
    }
    for f in ["seals.json", "scores.json", "table.md"] {
        assert!(merged.contains_key(f), "{f} missing");
    }
    let header = campaign::read_header(&base.join("shards").join("shard-1-of-3.cbor")).expect("shard header");
    assert_eq!((header.kind.as_str(), header.total), ("gap-bench", trials));
    let _ = std::fs::remove_dir_all(&base);
}

/// A text file's content (the SVG plots and MCAP logs are compared as bytes, so they need not be text).
fn text_or_empty(f: &str, v: &[u8]) -> String {
    if f.ends_with(".json") || f.ends_with(".md") {
        text(v)
    } else {
        String::new()
    }
}

#[test]
fn bad_shard_specs_and_shard_sets_exit_2_with_the_reason() {
    let out = tmp("bad");
    let o = s(&out);
    for (spec, expect) in [("0/3", "numbered from 1"), ("4/3", "only 3 shards"), ("2", "not K/N")] {
        let (code, _, err) = ulab(&["diff", "--engines", "mujoco,rapier-impulse", "--out", &o, "--shard", spec]);
        assert_eq!(code, Some(2), "{spec}: {err}");
        assert!(err.contains(expect), "{spec}: {err}");
    }
    let (code, _, err) = ulab(&["diff", "--out", &o, "--shard", "1/2", "--video", &s(&out.join("v.mp4"))]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("cannot be used with"), "{err}");
    std::fs::create_dir_all(&out).expect("dir");
    let (code, _, err) = ulab(&["merge", &o, "--out", &s(&out.join("m"))]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("no shard file"), "{err}");
    let junk = out.join("shard-1-of-1.cbor");
    std::fs::write(&junk, b"not cbor").expect("write");
    let (code, _, err) = ulab(&["merge", &s(&junk), "--out", &s(&out.join("m"))]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("not a readable shard file"), "{err}");
    let _ = std::fs::remove_dir_all(&out);
}
