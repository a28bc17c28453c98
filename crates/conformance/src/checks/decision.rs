//! How every probing check turns probes into a verdict, in one place.
//!
//! A check that acts on the peer (the command-handling checks, the robustness cases, command loss) runs a *probe*:
//! a hold, the probe's messages, and the state the peer publishes meanwhile. One probe can be spoilt by the machine
//! it runs on: on two loaded cores the tester's commands and the peer's states arrive late and in bursts, which thins
//! the evidence (too few samples that tell the interpretations apart: undecided), shifts the share of the time the
//! probe message was in force (a stalled sender leaves its last message in force: each probe measures that share
//! from its own send times and is undecided below half the nominal share), or looks like a defect (a stream that
//! seems to stall). So the probes are settled by [`settle`]:
//!
//! | after a probe that | the check |
//! |---|---|
//! | passed | passes: the protection was seen in force |
//! | failed, and one probe had failed before | fails: the defect repeated |
//! | failed for the first time, or was inconclusive | probes again, up to [`MAX_PROBES`] in all |
//!
//! A pass settles at once: a conformant peer never follows a probe's unsafe law, and with the probe's share of the
//! time measured an applying peer follows it in that share whatever the load, so a thinned probe reads as undecided,
//! not as safe. A fail claims a defect and must show twice. After [`MAX_PROBES`] without settling, the check fails
//! if a probe failed and none passed, else it is inconclusive (with the last probe's reason). A check that cannot
//! probe at all (no free joint to test with, no reader of our commands) says so at once with 0 probes. A verdict
//! therefore rests on one clean pass or on a defect seen twice.
//!
//! `cmd_valid_moves_joint` is the exception that the others rest on: it also chooses the test joints, so it probes
//! again (from a new hold, up to [`MAX_PROBES`] times) while no joint has shown a valid step, and reports its last
//! probe.
//!
//! Checks judged on a fixed window of the stream (rate, jitter, CRC, …) and the interop probes are decided once.
//! Every check reports how many probes it used and its [`Margin`]: the statistic that decided it, its threshold and
//! how far from that threshold it fell.

use crate::report::{CheckResult, Margin, Status};
use crate::ConformError;

/// At most this many probes per check. Three: one spoilt probe and one confirmation fit, and the default run's
/// command phase stays under a minute on a conformant peer, which passes every probing check at its first probe.
pub const MAX_PROBES: u32 = 3;

/// Runs `probe` until its verdict settles (see the module's table) and returns the deciding probe's result with the
/// number of probes used and every probe's status in its evidence.
pub(super) fn settle<F>(mut probe: F) -> Result<CheckResult, ConformError>
where
    F: FnMut() -> Result<CheckResult, ConformError>,
{
    let mut statuses = Vec::new();
    let mut first_fail: Option<CheckResult> = None;
    let mut result = probe()?;
    loop {
        if result.probes == 0 {
            // Nothing could be probed (no free joint, no matched reader): probing again would not change that.
            return Ok(result);
        }
        statuses.push(result.status);
        match result.status {
            Status::Pass => return Ok(finish(result, &statuses)),
            Status::Fail if first_fail.is_some() => return Ok(finish(result, &statuses)),
            Status::Fail => first_fail = Some(result.clone()),
            Status::Inconclusive => {}
        }
        if statuses.len() >= MAX_PROBES as usize {
            break;
        }
        result = probe()?;
    }
    // Unsettled: a failure seen once and never contradicted by a pass stands; otherwise nothing was decided and the
    // last probe says why.
    Ok(finish(first_fail.unwrap_or(result), &statuses))
}

fn finish(mut result: CheckResult, statuses: &[Status]) -> CheckResult {
    result.probes = u32::try_from(statuses.len()).unwrap_or(u32::MAX);
    result.with("probe_statuses", statuses.iter().map(|s| s.name()).collect::<Vec<_>>())
}

/// The margin of a check decided on several conditions that must all hold (a pass of every case, every criterion):
/// the one closest to its threshold.
pub(super) fn weakest(margins: impl IntoIterator<Item = Margin>) -> Option<Margin> {
    margins.into_iter().min_by(|a, b| a.relative.total_cmp(&b.relative))
}

/// The margin of a check decided by any one of several alternatives (one unsafe case fails a check): the one
/// farthest past its threshold.
pub(super) fn strongest(margins: impl IntoIterator<Item = Margin>) -> Option<Margin> {
    margins.into_iter().max_by(|a, b| a.relative.total_cmp(&b.relative))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::CheckId;

    fn scripted(statuses: &[Status]) -> (Result<CheckResult, ConformError>, usize) {
        let mut calls = 0usize;
        let r = settle(|| {
            let s = statuses[calls.min(statuses.len() - 1)];
            calls += 1;
            Ok(CheckResult::new(CheckId::RobustFlood, s, format!("probe {calls}")))
        });
        (r, calls)
    }

    fn verdict(statuses: &[Status]) -> (Status, u32, String, usize) {
        let (r, calls) = scripted(statuses);
        let r = r.unwrap_or_else(|e| panic!("{e}"));
        (r.status, r.probes, r.summary, calls)
    }

    use Status::{Fail as F, Inconclusive as I, Pass as P};

    #[test]
    fn a_pass_settles_at_once_and_a_fail_needs_a_second_fail() {
        assert_eq!(verdict(&[P]), (P, 1, "probe 1".into(), 1));
        assert_eq!(verdict(&[F, F]), (F, 2, "probe 2".into(), 2));
        // A spoilt first probe does not decide: the next one does.
        assert_eq!(verdict(&[I, P]), (P, 2, "probe 2".into(), 2));
        assert_eq!(verdict(&[F, P]), (P, 2, "probe 2".into(), 2));
        assert_eq!(verdict(&[I, F, F]), (F, 3, "probe 3".into(), 3));
    }

    #[test]
    fn unsettled_after_three_probes_a_lone_fail_stands_and_otherwise_nothing_is_decided() {
        // The failing probe's own evidence is reported, not the inconclusive ones'.
        assert_eq!(verdict(&[F, I, I]), (F, 3, "probe 1".into(), 3));
        assert_eq!(verdict(&[I, I, F]), (F, 3, "probe 3".into(), 3));
        assert_eq!(verdict(&[I, I, I]), (I, 3, "probe 3".into(), 3));
    }

    #[test]
    fn a_check_that_cannot_probe_is_not_repeated() {
        let mut calls = 0;
        let r = settle(|| {
            calls += 1;
            let mut r = CheckResult::new(CheckId::CmdBadCrcIgnored, I, "no free joint");
            r.probes = 0;
            Ok(r)
        });
        assert_eq!(r.map(|r| (r.status, r.probes)).ok(), Some((I, 0)));
        assert_eq!(calls, 1);
    }

    #[test]
    fn every_probe_status_is_in_the_evidence() {
        let (r, _) = scripted(&[I, F, F]);
        let r = r.unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(r.evidence["probe_statuses"], serde_json::json!(["inconclusive", "fail", "fail"]));
    }

    #[test]
    fn weakest_and_strongest_pick_by_relative_margin() {
        let a = Margin::at_most("x", 0.1, 0.25);
        let b = Margin::at_most("y", 0.2, 0.25);
        assert_eq!(weakest([a.clone(), b.clone()]).map(|m| m.statistic), Some("y".to_owned()));
        assert_eq!(strongest([a, b]).map(|m| m.statistic), Some("x".to_owned()));
    }
}
