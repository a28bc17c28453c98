//! Check results and the report (`report.json`, `report.md`).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Version of the `report.json` layout; bump on any incompatible change.
/// 2: `discovery_type_information` replaced by the decisive `interop_cyclone_010` / `interop_cyclone_11` probes;
/// `target` gains the peer's measured LowState rate, RTPS vendor and protocol version; `settings.checks`.
/// 3: each result gains `probes` and `margin` (a version-2 report still reads: 1 probe, no margin); the `controller`
/// group and its `ctl_*` checks (`ulab conform controller`, mode `controller`).
pub const REPORT_SCHEMA_VERSION: u32 = 3;

/// Outcome of one check (the verdict).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Pass,
    Fail,
    /// No evidence could decide it; the summary says why (e.g. no joint could move or report torque).
    Inconclusive,
}

impl Status {
    pub const fn name(self) -> &'static str {
        match self {
            Status::Pass => "pass",
            Status::Fail => "fail",
            Status::Inconclusive => "inconclusive",
        }
    }
}

/// Which part of the protocol a check is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum Group {
    StateStream,
    Discovery,
    Interop,
    CommandHandling,
    Robustness,
    Fuzz,
    /// The peer is a controller: ulab plays the robot and judges its `rt/lowcmd`.
    Controller,
}

impl Group {
    pub const fn title(self) -> &'static str {
        match self {
            Group::StateStream => "State stream (rt/lowstate)",
            Group::Discovery => "Type, QoS and discovery",
            Group::Interop => "Interoperability with the robot's DDS stacks",
            Group::CommandHandling => "Command handling (rt/lowcmd)",
            Group::Robustness => "Robustness",
            Group::Fuzz => "Fuzzing",
            Group::Controller => "Controller (its rt/lowcmd, judged by a simulated robot)",
        }
    }

    /// The snake_case name (as in report.json and `--checks`).
    pub const fn name(self) -> &'static str {
        match self {
            Group::StateStream => "state_stream",
            Group::Discovery => "discovery",
            Group::Interop => "interop",
            Group::CommandHandling => "command_handling",
            Group::Robustness => "robustness",
            Group::Fuzz => "fuzz",
            Group::Controller => "controller",
        }
    }
}

/// Identity of a check. The snake_case names are stable: report.json, scripts and `--checks` key on them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(into = "String", try_from = "String")]
pub enum CheckId {
    StateCrc,
    StateRate,
    StateJitter,
    StateTick,
    StateFresh,
    StateFinite,
    StateQuaternion,
    StateJointLimits,
    DiscoveryTypesQos,
    InteropCyclone010,
    InteropCyclone11,
    CmdValidMovesJoint,
    CmdBadCrcIgnored,
    CmdMode0NoTorque,
    CmdAbsurdGainsSafe,
    CmdNonFiniteRejected,
    CmdTimeoutBehaviour,
    RobustTruncated,
    RobustBadHeader,
    RobustOversize,
    RobustXcdr2,
    RobustFlood,
    RobustDuplicatesReordering,
    /// Fuzz mode without a failure.
    Fuzz,
    /// The k-th failure found by fuzzing (`fuzz_failure_k`).
    FuzzFailure(u32),
    CtlCrc,
    CtlModeMachine,
    CtlMotorModes,
    CtlLimits,
    CtlFinite,
    CtlRate,
    CtlJitter,
    CtlStartJump,
    CtlStaleState,
    CtlFall,
}

impl CheckId {
    /// The checks of the default run, in report order.
    pub const DEFAULT_RUN: [CheckId; 23] = [
        CheckId::StateCrc,
        CheckId::StateRate,
        CheckId::StateJitter,
        CheckId::StateTick,
        CheckId::StateFresh,
        CheckId::StateFinite,
        CheckId::StateQuaternion,
        CheckId::StateJointLimits,
        CheckId::DiscoveryTypesQos,
        CheckId::InteropCyclone010,
        CheckId::InteropCyclone11,
        CheckId::CmdValidMovesJoint,
        CheckId::CmdBadCrcIgnored,
        CheckId::CmdMode0NoTorque,
        CheckId::CmdAbsurdGainsSafe,
        CheckId::CmdNonFiniteRejected,
        CheckId::CmdTimeoutBehaviour,
        CheckId::RobustTruncated,
        CheckId::RobustBadHeader,
        CheckId::RobustOversize,
        CheckId::RobustXcdr2,
        CheckId::RobustFlood,
        CheckId::RobustDuplicatesReordering,
    ];

    /// The checks of a controller run (`ulab conform controller`), in report order.
    pub const CONTROLLER_RUN: [CheckId; 10] = [
        CheckId::CtlCrc,
        CheckId::CtlModeMachine,
        CheckId::CtlMotorModes,
        CheckId::CtlLimits,
        CheckId::CtlFinite,
        CheckId::CtlRate,
        CheckId::CtlJitter,
        CheckId::CtlStartJump,
        CheckId::CtlStaleState,
        CheckId::CtlFall,
    ];

    /// The stable snake_case name.
    pub fn name(self) -> String {
        let fixed = match self {
            CheckId::StateCrc => "state_crc",
            CheckId::StateRate => "state_rate",
            CheckId::StateJitter => "state_jitter",
            CheckId::StateTick => "state_tick",
            CheckId::StateFresh => "state_fresh",
            CheckId::StateFinite => "state_finite",
            CheckId::StateQuaternion => "state_quaternion",
            CheckId::StateJointLimits => "state_joint_limits",
            CheckId::DiscoveryTypesQos => "discovery_types_qos",
            CheckId::InteropCyclone010 => "interop_cyclone_010",
            CheckId::InteropCyclone11 => "interop_cyclone_11",
            CheckId::CmdValidMovesJoint => "cmd_valid_moves_joint",
            CheckId::CmdBadCrcIgnored => "cmd_bad_crc_ignored",
            CheckId::CmdMode0NoTorque => "cmd_mode0_no_torque",
            CheckId::CmdAbsurdGainsSafe => "cmd_absurd_gains_safe",
            CheckId::CmdNonFiniteRejected => "cmd_non_finite_rejected",
            CheckId::CmdTimeoutBehaviour => "cmd_timeout_behaviour",
            CheckId::RobustTruncated => "robust_truncated",
            CheckId::RobustBadHeader => "robust_bad_header",
            CheckId::RobustOversize => "robust_oversize",
            CheckId::RobustXcdr2 => "robust_xcdr2",
            CheckId::RobustFlood => "robust_flood",
            CheckId::RobustDuplicatesReordering => "robust_duplicates_reordering",
            CheckId::Fuzz => "fuzz",
            CheckId::CtlCrc => "ctl_crc",
            CheckId::CtlModeMachine => "ctl_mode_machine",
            CheckId::CtlMotorModes => "ctl_motor_modes",
            CheckId::CtlLimits => "ctl_limits",
            CheckId::CtlFinite => "ctl_finite",
            CheckId::CtlRate => "ctl_rate",
            CheckId::CtlJitter => "ctl_jitter",
            CheckId::CtlStartJump => "ctl_start_jump",
            CheckId::CtlStaleState => "ctl_stale_state",
            CheckId::CtlFall => "ctl_fall",
            CheckId::FuzzFailure(k) => return format!("fuzz_failure_{k}"),
        };
        fixed.to_owned()
    }

    /// Parses a [`CheckId::name`].
    pub fn parse(name: &str) -> Option<CheckId> {
        if let Some(k) = name.strip_prefix("fuzz_failure_") {
            return k.parse().ok().map(CheckId::FuzzFailure);
        }
        Self::DEFAULT_RUN.into_iter().chain(Self::CONTROLLER_RUN).chain([CheckId::Fuzz]).find(|c| c.name() == name)
    }

    /// The group it belongs to.
    pub const fn group(self) -> Group {
        match self {
            CheckId::StateCrc
            | CheckId::StateRate
            | CheckId::StateJitter
            | CheckId::StateTick
            | CheckId::StateFresh
            | CheckId::StateFinite
            | CheckId::StateQuaternion
            | CheckId::StateJointLimits => Group::StateStream,
            CheckId::DiscoveryTypesQos => Group::Discovery,
            CheckId::InteropCyclone010 | CheckId::InteropCyclone11 => Group::Interop,
            CheckId::CmdValidMovesJoint
            | CheckId::CmdBadCrcIgnored
            | CheckId::CmdMode0NoTorque
            | CheckId::CmdAbsurdGainsSafe
            | CheckId::CmdNonFiniteRejected
            | CheckId::CmdTimeoutBehaviour => Group::CommandHandling,
            CheckId::RobustTruncated
            | CheckId::RobustBadHeader
            | CheckId::RobustOversize
            | CheckId::RobustXcdr2
            | CheckId::RobustFlood
            | CheckId::RobustDuplicatesReordering => Group::Robustness,
            CheckId::Fuzz | CheckId::FuzzFailure(_) => Group::Fuzz,
            CheckId::CtlCrc
            | CheckId::CtlModeMachine
            | CheckId::CtlMotorModes
            | CheckId::CtlLimits
            | CheckId::CtlFinite
            | CheckId::CtlRate
            | CheckId::CtlJitter
            | CheckId::CtlStartJump
            | CheckId::CtlStaleState
            | CheckId::CtlFall => Group::Controller,
        }
    }
}

impl std::fmt::Display for CheckId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

impl From<CheckId> for String {
    fn from(id: CheckId) -> String {
        id.name()
    }
}

/// A check name that is not one of [`CheckId`]'s.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown check `{0}`")]
pub struct UnknownCheck(pub String);

impl TryFrom<String> for CheckId {
    type Error = UnknownCheck;
    fn try_from(name: String) -> Result<CheckId, UnknownCheck> {
        CheckId::parse(&name).ok_or(UnknownCheck(name))
    }
}

impl std::str::FromStr for CheckId {
    type Err = UnknownCheck;
    fn from_str(name: &str) -> Result<CheckId, UnknownCheck> {
        CheckId::parse(name).ok_or_else(|| UnknownCheck(name.to_owned()))
    }
}

/// One check's result with its evidence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckResult {
    /// Stable snake_case name (tests and scripts key on it).
    pub id: CheckId,
    pub group: Group,
    pub status: Status,
    /// One sentence: what was seen, and for a fail or an inconclusive result, why.
    pub summary: String,
    /// Figures, sample counts, offending bytes (hex).
    pub evidence: BTreeMap<String, serde_json::Value>,
    /// Probes the verdict rests on (a probing check repeats a spoilt or failing probe: `checks::decision`); 1 for a
    /// check decided once.
    #[serde(default = "one_probe")]
    pub probes: u32,
    /// The statistic that decided the verdict and how far from its threshold it fell; `None` for a categorical
    /// check (discovery, interop) or one that could not measure.
    #[serde(default)]
    pub margin: Option<Margin>,
}

fn one_probe() -> u32 {
    1
}

/// How close a decision came to its threshold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Margin {
    /// What was compared (`rate_hz`, `fraction_of_unsafe_effect`, …).
    pub statistic: String,
    /// The measured value (a non-finite one is written `null` and read back as NaN).
    #[serde(deserialize_with = "null_as_nan")]
    pub value: f64,
    /// `<=` or `>=`: the side of the threshold on which the check's condition holds.
    pub holds_if: String,
    pub threshold: f64,
    /// Signed distance past the threshold, in units of the threshold (or of the value when the threshold is 0):
    /// positive when the condition holds, negative when it does not; near 0, a close call. A non-finite value gives
    /// minus infinity (it holds no condition), written `null` in JSON and read back as NaN.
    #[serde(deserialize_with = "null_as_nan")]
    pub relative: f64,
}

/// JSON has no non-finite numbers: serde_json writes them as `null`.
fn null_as_nan<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

impl Margin {
    /// The condition `value <= threshold`.
    pub fn at_most(statistic: &str, value: f64, threshold: f64) -> Margin {
        Margin::new(statistic, value, "<=", threshold, threshold - value)
    }

    /// The condition `value >= threshold`.
    pub fn at_least(statistic: &str, value: f64, threshold: f64) -> Margin {
        Margin::new(statistic, value, ">=", threshold, value - threshold)
    }

    fn new(statistic: &str, value: f64, holds_if: &str, threshold: f64, distance: f64) -> Margin {
        let scale = if threshold != 0.0 { threshold.abs() } else { value.abs().max(1.0) };
        // A non-finite value never satisfies its condition.
        let relative = if distance.is_finite() { distance / scale } else { f64::NEG_INFINITY };
        Margin { statistic: statistic.to_owned(), value, holds_if: holds_if.to_owned(), threshold, relative }
    }

    /// The opposite condition (`<=` becomes `>`), the same distance with the other sign.
    #[must_use]
    pub fn negated(self) -> Margin {
        let holds_if = match self.holds_if.as_str() {
            "<=" => ">",
            ">=" => "<",
            "<" => ">=",
            _ => "<=",
        };
        Margin { holds_if: holds_if.to_owned(), relative: -self.relative, ..self }
    }

    /// `rate_hz 496.2 (>= 450, +10 %)`.
    pub fn describe(&self) -> String {
        let relative =
            if self.relative.is_finite() { format!("{:+.0} %", self.relative * 100.0) } else { "never".to_owned() };
        format!("{} {} ({} {}, {relative})", self.statistic, short(self.value), self.holds_if, short(self.threshold))
    }
}

fn short(x: f64) -> String {
    if x == 0.0 || (1e-3..1e5).contains(&x.abs()) {
        format!("{}", (x * 1e4).round() / 1e4)
    } else {
        format!("{x:.3e}")
    }
}

impl CheckResult {
    pub fn new(id: CheckId, status: Status, summary: impl Into<String>) -> Self {
        CheckResult {
            id,
            group: id.group(),
            status,
            summary: summary.into(),
            evidence: BTreeMap::new(),
            probes: 1,
            margin: None,
        }
    }

    /// Sets the number of probes (0: the check could not probe at all).
    #[must_use]
    pub fn with_probes(mut self, probes: u32) -> Self {
        self.probes = probes;
        self
    }

    /// Sets the deciding statistic's margin, given as the condition a pass needs or as the condition that decided
    /// the verdict. A fail whose pass condition does not hold is stated as the opposite condition, so that a margin
    /// always describes the verdict: positive for a pass or a fail, by how much; negative only when nothing was
    /// decided (how far the nearest condition was from holding).
    #[must_use]
    pub fn with_margin(mut self, margin: Option<Margin>) -> Self {
        self.margin = margin.map(|m| if self.status == Status::Fail && m.relative < 0.0 { m.negated() } else { m });
        self
    }

    /// Adds one evidence item.
    #[must_use]
    pub fn with(mut self, key: &str, value: impl Serialize) -> Self {
        self.evidence.insert(key.to_owned(), serde_json::to_value(value).unwrap_or(serde_json::Value::Null));
        self
    }
}

/// What was tested.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetInfo {
    pub robot: String,
    pub domain: u32,
    pub interface: String,
    /// GUID prefix (hex) of the participant that published rt/lowstate, if discovered.
    pub participant: Option<String>,
    /// LowState rate measured while nothing was sent (Hz): every duration of the run scales with it.
    #[serde(default)]
    pub measured_state_rate_hz: Option<f64>,
    /// RTPS vendor of that participant as seen on the wire (`1.16 Eclipse Cyclone DDS`), where it answered.
    #[serde(default)]
    pub rtps_vendor: Option<String>,
    /// RTPS protocol version of that participant as seen on the wire (`2.1`).
    #[serde(default)]
    pub rtps_protocol_version: Option<String>,
}

/// Settings of the run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    pub mode: String,
    /// Nominal LowState rate the stream is judged against (Hz).
    pub expected_state_rate_hz: f64,
    /// Fuzz budget (s), fuzz mode only.
    pub budget_s: Option<f64>,
    pub seed: Option<u64>,
    /// The checks that were asked for (`--checks`); every check of the default run if empty.
    #[serde(default)]
    pub checks: Vec<CheckId>,
}

/// The whole report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub schema_version: u32,
    pub target: TargetInfo,
    pub settings: Settings,
    /// Tool and library versions.
    pub versions: BTreeMap<String, String>,
    /// Wall time of the run (s).
    pub duration_s: f64,
    pub results: Vec<CheckResult>,
    /// Reproducer files written (fuzz mode), relative to the report.
    #[serde(default)]
    pub reproducers: Vec<String>,
}

impl Report {
    /// Counts per status.
    pub fn counts(&self) -> BTreeMap<&'static str, usize> {
        let mut m = BTreeMap::new();
        for s in [Status::Pass, Status::Fail, Status::Inconclusive] {
            m.insert(s.name(), self.results.iter().filter(|r| r.status == s).count());
        }
        m
    }

    /// Whether any check failed.
    pub fn any_fail(&self) -> bool {
        self.results.iter().any(|r| r.status == Status::Fail)
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }

    /// Human-readable Markdown: a summary table, then each check with its evidence.
    pub fn to_markdown(&self) -> String {
        let mut out = String::new();
        let c = self.counts();
        out.push_str("# Conformance report\n\n");
        if self.settings.mode == "controller" {
            // ulab played the robot: the peer judged is the controller that connected.
            out.push_str(&format!(
                "Target: a controller of robot `{}` on DDS domain {} / `{}`{}, judged by ulab playing the robot  \nMode: controller; LowState published at {} against {} Hz nominal; run took {:.1} s.  \n",
                self.target.robot,
                self.target.domain,
                self.target.interface,
                self.target.participant.as_ref().map(|p| format!(", participant `{p}`")).unwrap_or_default(),
                self.target.measured_state_rate_hz.map_or("?".to_owned(), |r| format!("{r:.1} Hz")),
                self.settings.expected_state_rate_hz,
                self.duration_s
            ));
        } else {
            out.push_str(&format!(
            "Target: robot `{}` on DDS domain {} / `{}`{}{}  \nMode: {}; LowState measured at {} against {} Hz nominal; run took {:.1} s.  \n",
            self.target.robot,
            self.target.domain,
            self.target.interface,
            self.target.participant.as_ref().map(|p| format!(", participant `{p}`")).unwrap_or_default(),
            match (&self.target.rtps_vendor, &self.target.rtps_protocol_version) {
                (Some(v), Some(p)) => format!(" (RTPS vendor {v}, protocol {p})"),
                _ => String::new(),
            },
            self.settings.mode,
            self.target.measured_state_rate_hz.map_or("?".to_owned(), |r| format!("{r:.1} Hz")),
            self.settings.expected_state_rate_hz,
            self.duration_s
        ));
        }
        let versions: Vec<String> = self.versions.iter().map(|(k, v)| format!("{k} {v}")).collect();
        out.push_str(&format!("Versions: {}.\n\n", versions.join(", ")));
        out.push_str(&format!(
            "**{} pass, {} fail, {} inconclusive.**\n\n",
            c.get("pass").copied().unwrap_or(0),
            c.get("fail").copied().unwrap_or(0),
            c.get("inconclusive").copied().unwrap_or(0)
        ));
        let mut groups: Vec<Group> = self.results.iter().map(|r| r.group).collect();
        groups.sort();
        groups.dedup();
        for g in groups {
            out.push_str(&format!(
                "## {}\n\n| check | status | probes | margin | summary |\n|---|---|---|---|---|\n",
                g.title()
            ));
            for r in self.results.iter().filter(|r| r.group == g) {
                let mark = match r.status {
                    Status::Pass => "pass",
                    Status::Fail => "**FAIL**",
                    Status::Inconclusive => "inconclusive",
                };
                out.push_str(&format!(
                    "| `{}` | {} | {} | {} | {} |\n",
                    r.id,
                    mark,
                    r.probes,
                    r.margin.as_ref().map_or_else(|| "-".to_owned(), Margin::describe).replace('|', "\\|"),
                    r.summary.replace('|', "\\|")
                ));
            }
            out.push('\n');
            for r in self.results.iter().filter(|r| r.group == g) {
                out.push_str(&format!("<details><summary><code>{}</code> evidence</summary>\n\n", r.id));
                for (k, v) in &r.evidence {
                    let text = match v {
                        serde_json::Value::String(s) => s.clone(),
                        other => other.to_string(),
                    };
                    out.push_str(&format!("- {k}: `{}`\n", text.replace('`', "'")));
                }
                out.push_str("\n</details>\n\n");
            }
        }
        if !self.reproducers.is_empty() {
            out.push_str("## Reproducers\n\n");
            for r in &self.reproducers {
                out.push_str(&format!("- `{r}` (re-run: `ulab conform replay {r}`)\n"));
            }
            out.push('\n');
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Report {
        Report {
            schema_version: REPORT_SCHEMA_VERSION,
            target: TargetInfo {
                robot: "h1_2".into(),
                domain: 81,
                interface: "lo".into(),
                participant: None,
                measured_state_rate_hz: Some(499.9),
                rtps_vendor: Some("1.16 Eclipse Cyclone DDS".into()),
                rtps_protocol_version: Some("2.5".into()),
            },
            settings: Settings {
                mode: "checks".into(),
                expected_state_rate_hz: 500.0,
                budget_s: None,
                seed: None,
                checks: vec![CheckId::StateCrc, CheckId::FuzzFailure(3)],
            },
            versions: BTreeMap::from([("ulab".to_owned(), "0.1.0".to_owned())]),
            duration_s: 1.0,
            results: vec![
                CheckResult::new(CheckId::StateCrc, Status::Pass, "ok").with("n", 3),
                CheckResult::new(CheckId::RobustFlood, Status::Fail, "bad | pipe").with("bytes", "00ff"),
            ],
            reproducers: vec![],
        }
    }

    #[test]
    fn json_round_trips_and_uses_snake_case() {
        let r = sample();
        let text = r.to_json();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap_or_default();
        assert_eq!(v["results"][1]["status"], "fail");
        assert_eq!(v["results"][0]["group"], "state_stream");
        assert_eq!(v["results"][0]["id"], "state_crc");
        assert_eq!(v["settings"]["checks"][1], "fuzz_failure_3");
        let back: Report = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(back, r);
        assert!(r.any_fail());
    }

    #[test]
    fn margins_are_signed_by_whether_the_condition_holds() {
        let m = Margin::at_least("rate_hz", 495.0, 450.0);
        assert!((m.relative - 0.1).abs() < 1e-12);
        assert_eq!(m.describe(), "rate_hz 495 (>= 450, +10 %)");
        assert!(Margin::at_most("p99_ms", 25.0, 20.0).relative < 0.0);
        // A zero threshold is measured in units of the value; a NaN never holds.
        assert!((Margin::at_most("bad_crc", 3.0, 0.0).relative + 1.0).abs() < 1e-12);
        assert_eq!(Margin::at_most("bad_crc", 0.0, 0.0).relative, 0.0);
        assert_eq!(Margin::at_most("x", f64::NAN, 1.0).relative, f64::NEG_INFINITY);
        let text = serde_json::to_string(&Margin::at_most("x", f64::NAN, 1.0)).unwrap_or_default();
        let back: Margin = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{text}: {e}"));
        assert!(back.value.is_nan() && back.relative.is_nan());
    }

    #[test]
    fn a_fail_states_the_condition_that_failed_it() {
        let m = Margin::at_least("rate_hz", 300.0, 450.0);
        let fail = CheckResult::new(CheckId::StateRate, Status::Fail, "slow").with_margin(Some(m.clone()));
        let fm = fail.margin.unwrap_or_else(|| panic!("margin"));
        assert_eq!((fm.holds_if.as_str(), fm.relative > 0.0), ("<", true));
        // Undecided: the distance stays negative.
        let open = CheckResult::new(CheckId::StateRate, Status::Inconclusive, "?").with_margin(Some(m));
        assert!(open.margin.is_some_and(|m| m.relative < 0.0 && m.holds_if == ">="));
    }

    #[test]
    fn a_version_2_result_reads_as_one_probe_without_margin() {
        let v2 = r#"{"id":"state_crc","group":"state_stream","status":"pass","summary":"ok","evidence":{}}"#;
        let r: CheckResult = serde_json::from_str(v2).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((r.probes, r.margin), (1, None));
    }

    #[test]
    fn markdown_escapes_pipes_and_lists_every_check() {
        let md = sample().to_markdown();
        assert!(md.contains("bad \\| pipe"));
        assert!(md.contains("`state_crc`") && md.contains("`robust_flood`"));
        assert!(md.contains("RTPS vendor 1.16 Eclipse Cyclone DDS, protocol 2.5"));
        assert!(md.contains("1 pass, 1 fail, 0 inconclusive"));
    }
}

#[cfg(test)]
mod id_tests {
    use super::*;

    #[test]
    fn check_names_round_trip_and_are_unique() {
        let mut seen = std::collections::BTreeSet::new();
        for id in CheckId::DEFAULT_RUN.into_iter().chain(CheckId::CONTROLLER_RUN).chain([
            CheckId::Fuzz,
            CheckId::FuzzFailure(0),
            CheckId::FuzzFailure(12),
        ]) {
            assert_eq!(CheckId::parse(&id.name()), Some(id));
            assert!(seen.insert(id.name()), "{id}");
            let json = serde_json::to_string(&id).unwrap_or_default();
            assert_eq!(json, format!("\"{}\"", id.name()));
        }
        assert_eq!(CheckId::parse("discovery_type_information"), None);
        assert!(serde_json::from_str::<CheckId>("\"no_such_check\"").is_err());
    }
}
