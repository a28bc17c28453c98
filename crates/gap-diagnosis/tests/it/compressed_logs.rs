//! The diagnosis reads logs written by the official Python `mcap` writer (`tests/mcap/write_mcap.py`: Unitree hg
//! messages serialized by Cyclone DDS's Python serializer) with zstd (the writer's default), lz4, uncompressed and
//! unchunked, into the same commands and states; a truncated zstd log is a typed error.
use crate::common;

use gap_diagnosis::{GapError, RobotLog};
use std::path::Path;

#[test]
fn logs_of_the_official_python_writer_read_in_every_form() {
    let model = common::model();
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gap-official-writer");
    let _ = std::fs::remove_dir_all(&dir);
    let out = std::process::Command::new(common::python())
        .arg(common::workspace().join("tests/mcap/write_mcap.py"))
        .arg(&dir)
        .args(["--states", "300"])
        .output()
        .expect("run the Python mcap writer");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let files: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    // Joint 0 of the model and its motor slot: the writer's values are per slot.
    let slot0 = model.joints[0].slot;
    let mut logs = Vec::new();
    for form in ["zstd", "lz4", "none", "unchunked"] {
        let bytes = std::fs::read(files[form]["path"].as_str().expect("path")).expect("read");
        let log = RobotLog::from_mcap(&bytes, &model).unwrap_or_else(|e| panic!("{form}: {e:?}"));
        assert_eq!((log.commands.len(), log.states.len()), (150, 300), "{form}");
        // State k: log time 2 ms * k + 1 us after the first command; q of slot s = 0.1 sin(0.01 k + 0.3 s).
        for (k, s) in log.states.iter().enumerate() {
            let want = 0.1 * (0.01 * k as f64 + 0.3 * slot0 as f64).sin();
            assert!((s.q[0] - want).abs() < 1e-6, "{form} state {k}: {} vs {want}", s.q[0]);
            assert!((s.t - (0.002 * k as f64 + 1e-6)).abs() < 1e-9, "{form} state {k}: t {}", s.t);
        }
        let want = 0.2 * (0.02 * 7.0 + 0.1 * slot0 as f64).sin();
        assert!((log.commands[7].q[0] - want).abs() < 1e-6 && log.commands[7].kp[0] == 100.0, "{form}");
        logs.push(log);
    }
    assert!(logs.windows(2).all(|w| w[0] == w[1]), "every form gives the same log");
    // Truncated: a typed error that keeps the reader's cause.
    let bytes = std::fs::read(files["zstd"]["path"].as_str().expect("path")).expect("read");
    match RobotLog::from_mcap(&bytes[..bytes.len() / 2], &model) {
        Err(GapError::Recording(recording::ReadError::Truncated { messages, .. })) => assert!(messages > 0),
        other => panic!("truncated zstd log: {other:?}"),
    }
}
