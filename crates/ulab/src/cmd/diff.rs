//! `ulab diff` (placeholder until its issue lands).
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`ulab diff` is not implemented yet")
}
