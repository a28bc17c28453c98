//! `judge OBSERVATIONS.jsonl...`: turns the adapters' observation lines into verdict lines (JSON, one per
//! scene and engine) with the project's invariants. Lines that only name the engine (`{"engine": ...}`) are
//! skipped; the reference engine's observations are found among all files.
#![forbid(unsafe_code)]

use rediscovery_harness::cross::{judge, Observation, REFERENCE_ENGINE};
use std::process::ExitCode;

fn main() -> ExitCode {
    let mut all: Vec<Observation> = Vec::new();
    for f in std::env::args().skip(1) {
        let text = match std::fs::read_to_string(&f) {
            Ok(t) => t,
            Err(e) => {
                eprintln!("cannot read {f}: {e}");
                return ExitCode::from(2);
            }
        };
        for line in text.lines().filter(|l| l.contains("\"scene\"")) {
            match serde_json::from_str::<Observation>(line) {
                Ok(o) => all.push(o),
                Err(e) => {
                    eprintln!("{f}: not an observation line ({e}): {line:.80}");
                    return ExitCode::from(2);
                }
            }
        }
    }
    for o in &all {
        let reference = all.iter().find(|r| r.engine == REFERENCE_ENGINE && r.scene == o.scene);
        if let Some(v) = judge(o, reference) {
            match serde_json::to_string(&v) {
                Ok(l) => println!("{l}"),
                Err(e) => {
                    eprintln!("cannot serialise a verdict: {e}");
                    return ExitCode::from(2);
                }
            }
        }
    }
    ExitCode::SUCCESS
}
