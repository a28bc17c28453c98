//! `report REFERENCE.jsonl RAPIER.jsonl...`: prints the markdown tables of the verdict lines; the
//! engine of the first file is the reference column.
#![forbid(unsafe_code)]

use std::process::ExitCode;

fn main() -> ExitCode {
    let files: Vec<String> = std::env::args().skip(1).collect();
    if files.is_empty() {
        eprintln!("usage: report REFERENCE.jsonl VERDICTS.jsonl...");
        return ExitCode::from(2);
    }
    let mut all = Vec::new();
    for f in &files {
        let text = match std::fs::read_to_string(f) {
            Ok(t) => t,
            Err(e) => {
                eprintln!("cannot read {f}: {e}");
                return ExitCode::from(2);
            }
        };
        match rediscovery_harness::report::parse_lines(&text) {
            Ok(v) => all.extend(v),
            Err(e) => {
                eprintln!("{f}: not verdict lines: {e}");
                return ExitCode::from(2);
            }
        }
    }
    let Some(reference) = all.first().map(|v| v.engine.clone()) else {
        eprintln!("{}: no verdicts", files[0]);
        return ExitCode::from(2);
    };
    print!("{}", rediscovery_harness::report::markdown(&all, &reference));
    ExitCode::SUCCESS
}
