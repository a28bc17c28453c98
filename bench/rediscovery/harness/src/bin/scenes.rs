//! `scenes`: prints the cross-engine scene list (JSON) that the Python adapters read.
#![forbid(unsafe_code)]

use std::process::ExitCode;

fn main() -> ExitCode {
    match serde_json::to_string_pretty(&rediscovery_harness::cross::scenes()) {
        Ok(s) => {
            println!("{s}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("cannot serialise the scenes: {e}");
            ExitCode::from(2)
        }
    }
}
