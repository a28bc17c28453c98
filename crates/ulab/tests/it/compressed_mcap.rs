//! Every MCAP reader of `ulab` (`log info`, `log export`, `replay`, `gap diagnose`) on files written by the official
//! Python `mcap` writer (`tests/mcap/write_mcap.py`: Unitree hg messages serialized by Cyclone DDS's Python
//! serializer) with zstd (the writer's default), lz4, uncompressed chunks and no chunks; a truncated zstd file is a
//! clear error (exit 2), not a panic.
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;
use test_support::process::wait_with_timeout;

fn root() -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    p.canonicalize().unwrap_or(p)
}

fn python() -> PathBuf {
    std::env::var_os("ULAB_PYTHON").map_or_else(|| root().join(".venv/bin/python"), PathBuf::from)
}

/// Runs `ulab ARGS` with a timeout; returns (exit code, stdout, stderr).
fn ulab(args: &[&str]) -> (Option<i32>, String, String) {
    let child = Command::new(env!("CARGO_BIN_EXE_ulab"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start ulab");
    let (status, out, err) = wait_with_timeout(child, Duration::from_secs(120));
    (status.and_then(|s| s.code()), out, err)
}

#[test]
fn every_reader_reads_every_form_of_the_official_writer() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ulab-official-writer");
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(python())
        .arg(root().join("tests/mcap/write_mcap.py"))
        .arg(&dir)
        .args(["--states", "200"])
        .output()
        .expect("run the Python mcap writer");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let files: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let path = |form: &str| files[form]["path"].as_str().expect("path").to_string();
    let domain = test_support::lease_domain();
    for form in ["zstd", "lz4", "none", "unchunked"] {
        let file = path(form);
        // log info: the channels, their types (from the schema: no ulab metadata) and counts.
        let (code, out, err) = ulab(&["log", "info", &file]);
        assert_eq!(code, Some(0), "{form}: {err}");
        assert!(out.contains("rt/lowcmd\tunitree_hg::msg::dds_::LowCmd_\tcdr\t100 messages"), "{form}: {out}");
        assert!(out.contains("rt/lowstate\tunitree_hg::msg::dds_::LowState_\tcdr\t200 messages"), "{form}: {out}");
        // log export: one row per message, decoded by our codec, values as the writer printed them.
        let csv = dir.join(format!("{form}_lowstate.csv"));
        let (code, _, err) =
            ulab(&["log", "export", &file, "--topic", "rt/lowstate", "--out", csv.to_str().expect("utf-8")]);
        assert_eq!(code, Some(0), "{form}: {err}");
        let text = std::fs::read_to_string(&csv).expect("csv");
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().expect("header").split(',').collect();
        let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
        assert_eq!(rows.len(), 200, "{form}");
        let col = |name: &str| header.iter().position(|c| *c == name).expect(name);
        let (tick, q3) = (col("tick"), col("motor_state[3].q"));
        for (k, r) in rows.iter().enumerate() {
            assert_eq!(r[tick], (1000 + 2 * k).to_string(), "{form} row {k}");
            let q: f64 = r[q3].parse().expect("q");
            let want = 0.1 * (0.01 * k as f64 + 0.9).sin();
            assert!((q - want).abs() < 1e-6, "{form} row {k}: {q} vs {want}");
        }
        // replay: every message published (no subscriber needed to count what was written).
        let (code, out, err) =
            ulab(&["replay", &file, "--domain", &domain.arg(), "--speed", "20", "--wait-readers", "0"]);
        assert_eq!(code, Some(0), "{form}: {out}\n{err}");
        assert!(
            out.contains("rt/lowstate: 200 messages sent") && out.contains("rt/lowcmd: 100 messages sent"),
            "{out}"
        );
    }
    // Truncated zstd: every reader fails with exit 2 and says so (gap diagnose through the same reader).
    let bytes = std::fs::read(path("zstd")).expect("read");
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).expect("write");
    let cut = cut.to_str().expect("utf-8").to_string();
    let report = dir.join("report");
    for args in [
        vec!["log", "info", &cut],
        vec!["log", "export", &cut, "--out", "-"],
        vec!["gap", "diagnose", "--log", &cut, "--out", report.to_str().expect("utf-8")],
    ] {
        let (code, _, err) = ulab(&args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(err.contains("truncated") && !err.contains("panicked"), "{args:?}: {err}");
    }
}
