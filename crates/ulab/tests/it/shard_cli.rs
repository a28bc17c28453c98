//! Sharded campaigns end to end (issue 62): a small campaign of each kind runs unsharded, then as 3 shards
//! (`--shard K/3`, one process each) merged by `ulab merge`; the merged output directory must hold the same files
//! as the unsharded one, byte for byte, but for the wall-clock fields of `report.json` (`timing.engine_s`,
//! `timing.total_s` of `ulab diff`). Bad shard specs and bad sets of shards exit 2 with their reason.

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

/// Every file of `dir` by name.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .expect("output dir")
        .filter_map(|e| e.ok())
        .map(|e| (e.file_name().to_string_lossy().into_owned(), std::fs::read(e.path()).expect("read")))
        .collect()
}

/// `report.json` texts equal line for line, but for lines whose key is one of `wall_clock` (each present once in
/// both, so a renamed field cannot make the comparison vacuous).
fn assert_same_json(a: &str, b: &str, wall_clock: &[&str]) {
    let (la, lb): (Vec<&str>, Vec<&str>) = (a.lines().collect(), b.lines().collect());
    assert_eq!(la.len(), lb.len(), "report.json line counts differ");
    let key = |l: &str| wall_clock.iter().find(|k| l.trim_start().starts_with(&format!("\"{k}\":"))).copied();
    let mut skipped = Vec::new();
    for (i, (x, y)) in la.iter().zip(&lb).enumerate() {
        match (key(x), key(y)) {
            (Some(k), Some(k2)) if k == k2 => skipped.push(k),
            _ => assert_eq!(x, y, "report.json line {}", i + 1),
        }
    }
    skipped.sort_unstable();
    let mut want = wall_clock.to_vec();
    want.sort_unstable();
    assert_eq!(skipped, want, "each wall-clock field once");
}

/// Runs `campaign` unsharded into `whole/`, as shards 1/3..3/3 into `shards/`, merges into `merged/`, and compares.
fn unsharded_equals_merged(name: &str, campaign: &[&str], wall_clock: &[&str]) -> PathBuf {
    let base = tmp(name);
    let (whole, shards, merged) = (base.join("whole"), base.join("shards"), base.join("merged"));
    ok(&[campaign, &["--out", &s(&whole)]].concat());
    for k in 1..=3 {
        let spec = format!("{k}/3");
        let out = ok(&[campaign, &["--out", &s(&shards), "--shard", &spec]].concat());
        assert!(out.contains(&format!("shard {spec}")), "{out}");
    }
    assert!(!shards.join("report.json").exists(), "a shard writes no report");
    ok(&["merge", &s(&shards), "--out", &s(&merged)]);
    let (a, b) = (files(&whole), files(&merged));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>(), "the same files");
    for (f, bytes) in &a {
        if f == "report.json" {
            let text = |v: &[u8]| String::from_utf8(v.to_vec()).expect("utf-8");
            assert_same_json(&text(bytes), &text(&b[f]), wall_clock);
        } else {
            assert!(bytes == &b[f], "{f} differs");
        }
    }
    base
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
