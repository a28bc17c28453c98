//! `conformance`: checks and fuzzing of a DDS peer that plays the robot side of Unitree's
//! low-level protocol (publishes `rt/lowstate`, consumes `rt/lowcmd`): a simulator bridge, a
//! controller proxy, or the robot itself.
//!
//! * [`target::Target`]: one participant with a LowCmd writer, a LowState reader and a
//!   discovery monitor; drives command phases at a fixed rate and records every LowState.
//! * [`checks`]: the default check run (state stream, discovery, command handling,
//!   robustness), each check a [`report::CheckResult`] with its evidence.
//! * [`interop`]: participants of the robot's own DDS stacks (Cyclone 0.10.2 in C, Cyclone 11 in Python) that try
//!   to read the peer's state.
//! * [`wire`]: the peer's RTPS vendor and protocol version, from the header of its answer to an SPDP announcement.
//! * [`fuzz`]: structure-aware mutation of LowCmd sequences with state feedback, minimisation
//!   and reproducer files ([`fuzz::Reproducer`]).
//! * [`controller`]: the other direction: verdicts on a controller's LowCmd stream, recorded while ulab plays
//!   the robot (`ulab conform controller`), with the decision table in one place.
//! * [`safety`]: the extra rule for fuzzing a non-loopback target (the network rule itself is
//!   `dds_transport::DomainConfig::validate`).
//!
//! The H1-2 (`unitree_hg` family) is the only robot so far.
#![forbid(unsafe_code)]

pub mod checks;
pub mod commands;
pub mod controller;
pub mod fuzz;
pub mod interop;
pub mod report;
pub mod safety;
pub mod target;
pub mod timing;
pub mod wire;

/// Why a conformance run could not be carried out (as opposed to a check that failed).
#[derive(Debug, thiserror::Error)]
pub enum ConformError {
    #[error("DDS: {0}")]
    Dds(#[from] dds_transport::Error),
    #[error(
        "no LowState from the target on rt/lowstate within {seconds} s (is it running on this domain and interface?)"
    )]
    NoState { seconds: f64 },
    #[error("the target's LowState cannot be used as a starting pose: {0}")]
    BadStartState(String),
    #[error("unsupported robot `{0}` (supported: h1_2)")]
    UnsupportedRobot(String),
    /// A reproducer file is not valid JSON of the expected shape (the parser's error is the source).
    #[error("reproducer")]
    ReproducerJson(#[source] serde_json::Error),
    /// A reproducer's content is out of range (what).
    #[error("reproducer: {0}")]
    Reproducer(String),
    #[error("{0}")]
    Refused(String),
    #[error("--checks: {0}")]
    Selection(String),
}
