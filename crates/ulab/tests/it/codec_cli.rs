//! The `ulab codec` command-line contract, checked on the golden corpus (bytes from Cyclone
//! DDS's Python serializer and CRCs from Unitree's Python SDK).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn golden(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../corpus/golden").join(name)
}

fn ulab(args: &[&str], stdin: &[u8]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn ulab");
    child.stdin.take().expect("stdin").write_all(stdin).expect("write stdin");
    child.wait_with_output().expect("wait")
}

fn json(bytes: &[u8]) -> serde_json::Value {
    serde_json::from_slice(bytes).expect("valid JSON")
}

/// Floats in the golden JSON are f64 texts of f32 values; ours are shortest f32 texts. Compare
/// numbers as f32 bit patterns, everything else exactly.
fn same(a: &serde_json::Value, b: &serde_json::Value) -> bool {
    use serde_json::Value::*;
    match (a, b) {
        (Number(x), Number(y)) => match (x.as_i64(), y.as_i64()) {
            (Some(i), Some(j)) => i == j,
            _ => {
                let f = |n: &serde_json::Number| n.to_string().parse::<f32>().map(f32::to_bits);
                f(x).is_ok() && f(x) == f(y)
            }
        },
        (Array(x), Array(y)) => x.len() == y.len() && x.iter().zip(y).all(|(a, b)| same(a, b)),
        (Object(x), Object(y)) => x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| same(v, w))),
        _ => a == b,
    }
}

const CASES: &[(&str, &str)] = &[
    ("hg_lowcmd_realistic_x1le", "hg/LowCmd"),
    ("hg_lowcmd_badcrc_x1le", "hg/LowCmd"),
    ("hg_lowstate_typical_x2be", "hg/LowState"),
    ("go_lowcmd_realistic_x1le", "go/LowCmd"),
    ("go_lowstate_edge_x1be", "go/LowState"),
    ("hg_handstate_typical_x2le", "hg/HandState"),
    ("hg_imustate_nonfinite_x1le", "hg/IMUState"),
    ("go_bmsstate_edge_x2be", "go/BmsState"),
];

#[test]
fn decode_prints_the_recorded_document() {
    for (case, ty) in CASES {
        let bytes = std::fs::read(golden(&format!("{case}.cdr"))).expect("cdr");
        let out = ulab(&["codec", "decode", "--type", ty], &bytes);
        assert!(out.status.success(), "{case}: {}", String::from_utf8_lossy(&out.stderr));
        let expected = json(&std::fs::read(golden(&format!("{case}.json"))).expect("json"));
        assert!(same(&json(&out.stdout), &expected), "{case}: decoded document differs");
    }
}

#[test]
fn encode_reproduces_the_golden_bytes() {
    for (case, ty) in CASES {
        let doc = std::fs::read(golden(&format!("{case}.json"))).expect("json");
        let out = ulab(&["codec", "encode", "--type", ty], &doc);
        assert!(out.status.success(), "{case}: {}", String::from_utf8_lossy(&out.stderr));
        assert_eq!(out.stdout, std::fs::read(golden(&format!("{case}.cdr"))).expect("cdr"), "{case}");
    }
}

#[test]
fn encode_flags_override_the_document() {
    let doc = std::fs::read(golden("hg_lowcmd_realistic_x1le.json")).expect("json");
    let out = ulab(&["codec", "encode", "--type", "hg/LowCmd", "--representation", "xcdr2", "--big-endian"], &doc);
    assert!(out.status.success());
    assert_eq!(out.stdout, std::fs::read(golden("hg_lowcmd_realistic_x2be.cdr")).expect("cdr"));
    // Only `value` is required; the defaults are xcdr1 little-endian.
    let mut full = json(&doc);
    let bare = serde_json::json!({ "value": full["value"].take() });
    let out = ulab(&["codec", "encode", "--type", "hg/LowCmd"], bare.to_string().as_bytes());
    assert!(out.status.success());
    assert_eq!(out.stdout, std::fs::read(golden("hg_lowcmd_realistic_x1le.cdr")).expect("cdr"));
}

#[test]
fn crc_equals_unitree_sdk() {
    let manifest = json(&std::fs::read(golden("manifest.json")).expect("manifest"));
    for case in manifest["cases"].as_array().expect("cases").iter().filter(|c| c["crc"].is_u64()).take(12) {
        let name = case["case"].as_str().expect("name");
        let doc = std::fs::read(golden(&format!("{name}.json"))).expect("json");
        let out = ulab(&["codec", "crc", "--type", case["type"].as_str().expect("type")], &doc);
        assert!(out.status.success(), "{name}");
        assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), case["crc"].to_string(), "{name}");
    }
}

#[test]
fn errors_exit_2_with_a_message() {
    let cases: &[(&[&str], &[u8])] = &[
        (&["codec", "decode", "--type", "hg/LowCmd"], b"\x00\x01\x00\x00\x01"),
        (&["codec", "decode", "--type", "hg/LowCmd"], b""),
        (&["codec", "encode", "--type", "hg/LowCmd"], b"{\"value\": {}}"),
        (&["codec", "encode", "--type", "hg/LowCmd"], b"not json"),
        (&["codec", "crc", "--type", "hg/HandCmd"], b"{\"value\": {\"motor_cmd\": [], \"reserve\": [0,0,0,0]}}"),
        (&["codec", "decode", "--type", "hg/Nope"], b""),
    ];
    for (args, stdin) in cases {
        let out = ulab(args, stdin);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(out.stdout.is_empty(), "{args:?}");
        assert!(!out.stderr.is_empty(), "{args:?}");
    }
}

/// Human-readable forms, pinned: the decode of small golden messages (edge values: -0.0,
/// subnormals, non-finite floats, sequences) and the error messages users see.
#[test]
fn snapshots() {
    for case in
        ["hg_imustate_edge_x1le", "hg_imustate_nonfinite_x2be", "hg_handcmd_typical_x2le", "go_bmscmd_edge_x1le"]
    {
        let ty = match &case[..6] {
            "hg_imu" => "hg/IMUState",
            "hg_han" => "hg/HandCmd",
            _ => "go/BmsCmd",
        };
        let bytes = std::fs::read(golden(&format!("{case}.cdr"))).expect("cdr");
        let out = ulab(&["codec", "decode", "--type", ty], &bytes);
        insta::assert_snapshot!(case, String::from_utf8_lossy(&out.stdout));
    }
    let mut errors = String::new();
    let inputs: &[(&str, &[u8])] = &[
        ("hg/LowCmd", b"\x00\x01\x00\x00\x01\x02\x03"),
        ("hg/LowCmd", b"\x00\x03\x00\x00"),
        ("hg/HandCmd", b"\x00\x01\x00\x00\xff\xff\xff\xff"),
        ("go/BmsCmd", b"\x00\x01\x00\x00\x01\x02\x03\x04\x05"),
    ];
    for (ty, bytes) in inputs {
        let out = ulab(&["codec", "decode", "--type", ty], bytes);
        errors.push_str(&format!(
            "{ty} {bytes:02x?}\n  exit {:?}: {}",
            out.status.code(),
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    insta::assert_snapshot!("decode_errors", errors);
}

/// `validate` on golden messages: the non-finite and random-valued LowCmds are flagged (exit 1),
/// an all-zero LowCmd is clean (exit 0). The listing is pinned for review.
#[test]
fn validate_lists_findings() {
    let mut report = String::new();
    for (case, ty) in [
        ("hg_lowcmd_zero_x1le", "hg/LowCmd"),
        ("hg_lowcmd_nonfinite_x1le", "hg/LowCmd"),
        ("hg_lowcmd_badcrc_x1le", "hg/LowCmd"),
        ("hg_lowstate_zero_x1le", "hg/LowState"),
    ] {
        let bytes = std::fs::read(golden(&format!("{case}.cdr"))).expect("cdr");
        let out = ulab(&["codec", "validate", "--type", ty], &bytes);
        let stdout = String::from_utf8_lossy(&out.stdout);
        let lines: Vec<&str> = stdout.lines().collect();
        report.push_str(&format!("{case}: exit {:?}, {} line(s)\n", out.status.code(), lines.len()));
        for l in lines.iter().take(6) {
            report.push_str(&format!("  {l}\n"));
        }
    }
    insta::assert_snapshot!("validate", report);
}
