//! The exit status of every `ulab` command, as one type, so that a number means the same thing in every subcommand
//! (scripts and CI branch on it: `ulab conform ... || handle_failed_checks`).
use std::process::ExitCode;

/// How a run ended, as its caller sees it in `$?`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// 0: the run did what was asked, and its answer is "yes" (or there was no question).
    Success,
    /// 1: the run worked and its answer is "no": failed checks or oracles, a candidate engine bug with
    /// `--fail-on-bug`, a degrading policy with `--fail-on-degrade`, validation findings, a safety stop, a
    /// reproducer that reproduces, a replay that is not bit-identical.
    Failed,
    /// 2: the run could not be done: bad arguments or input, a missing file or peer, an engine error. `main` gives
    /// it to every error a command returns.
    Error,
    /// 3: `ulab gap diagnose` abstained: the log breaks the assumption of the chosen plant (a walking log under
    /// `--plant rig`); the report is written and every effect abstained.
    Abstained,
}

impl Exit {
    /// The number the process exits with.
    pub const fn code(self) -> u8 {
        match self {
            Exit::Success => 0,
            Exit::Failed => 1,
            Exit::Error => 2,
            Exit::Abstained => 3,
        }
    }

    /// `Failed` when `failed`, else `Success`: the common ending of a command that answers a yes/no question.
    pub const fn failed_if(failed: bool) -> Self {
        if failed {
            Exit::Failed
        } else {
            Exit::Success
        }
    }
}

impl From<Exit> for ExitCode {
    fn from(e: Exit) -> Self {
        ExitCode::from(e.code())
    }
}

#[cfg(test)]
mod tests {
    use super::Exit;

    /// The numbers are a public contract (README, docs, scripts): pinned here against the documented values.
    #[test]
    fn codes_are_the_documented_numbers() {
        assert_eq!([Exit::Success, Exit::Failed, Exit::Error, Exit::Abstained].map(Exit::code), [0, 1, 2, 3]);
        assert_eq!(Exit::failed_if(true), Exit::Failed);
        assert_eq!(Exit::failed_if(false), Exit::Success);
    }
}
