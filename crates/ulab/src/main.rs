//! `ulab`: one binary in front of every tool of the project.
//!
//! Each subcommand lives in its own module under `cmd/`; this file only dispatches.
#![forbid(unsafe_code)]

mod cmd;
mod exit;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Debug, Parser)]
#[command(name = "ulab", version, about = "Toolkit for Unitree robots over SDK2 low-level DDS channels")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Encode, decode and checksum SDK2 messages, low-level and RPC (CDR with encapsulation header).
    Codec(cmd::codec::Args),
    /// Record DDS topics (rt/lowcmd, rt/lowstate, ...) into an MCAP file.
    Record(cmd::record::Args),
    /// Republish an MCAP recording over DDS with its original timing.
    Replay(cmd::replay::Args),
    /// Inspect and export MCAP recordings (CSV).
    Log(cmd::log::Args),
    /// A video (H.264 MP4) of a recorded run: the robot drawn from its LowState, base pose estimated.
    Render(cmd::render::Args),
    /// The robot model in several physics engines: oracles (check), mass matrix dumps (inspect), MJCF export.
    Model(cmd::model::Args),
    /// Simulated robot behind rt/lowcmd and rt/lowstate and the SDK's locomotion RPC (LocoClient).
    Sim(cmd::sim::Args),
    /// Check how a DDS peer that plays the robot side handles good and bad traffic (report, fuzz, replay).
    Conform(cmd::conform::Args),
    /// Differential testing of physics engines driven by policy rollouts (run, fuzz, replay).
    Diff(cmd::diff::Args),
    /// A policy as the robot's low-level controller over DDS (start sequence, limits, safety stops).
    Deploy(cmd::deploy::Args),
    /// Cross-engine policy validation: does a policy keep its score outside the engine it was trained in?
    Validate(cmd::validate::Args),
    /// Sim-to-real gap diagnosis from robot logs (diagnose, excite, bench).
    Gap(cmd::gap::Args),
    /// The report of a sharded campaign (`--shard K/N` runs of diff, diff fuzz, validate or gap bench): what the
    /// unsharded run writes.
    Merge(cmd::merge::Args),
    /// Why an SDK client sees nothing: interfaces, DDS participants (vendor, version), topics, QoS, diagnosis.
    Doctor(cmd::doctor::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Codec(args) => cmd::codec::run(args),
        Command::Record(args) => cmd::record::run(args),
        Command::Replay(args) => cmd::replay::run(args),
        Command::Log(args) => cmd::log::run(args),
        Command::Render(args) => cmd::render::run(args),
        Command::Model(args) => cmd::model::run(args),
        Command::Sim(args) => cmd::sim::run(args),
        Command::Conform(args) => cmd::conform::run(args),
        Command::Diff(args) => cmd::diff::run(args),
        Command::Deploy(args) => cmd::deploy::run(args),
        Command::Validate(args) => cmd::validate::run(args),
        Command::Gap(args) => cmd::gap::run(args),
        Command::Merge(args) => cmd::merge::run(args),
        Command::Doctor(args) => cmd::doctor::run(args),
    };
    match result {
        Ok(exit) => exit.into(),
        Err(err) => {
            eprintln!("error: {err:#}");
            exit::Exit::Error.into()
        }
    }
}
