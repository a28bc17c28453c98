//! Check results and the report (`report.json`, `report.md`).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Version of the `report.json` layout; bump on any incompatible change.
pub const REPORT_SCHEMA_VERSION: u32 = 1;

/// Outcome of one check.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Pass,
    Fail,
    /// Not enough data to decide (e.g. no LowState during the phase, no discovery data).
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum Group {
    StateStream,
    Discovery,
    CommandHandling,
    Robustness,
    Fuzz,
}

impl Group {
    pub const fn title(self) -> &'static str {
        match self {
            Group::StateStream => "State stream (rt/lowstate)",
            Group::Discovery => "Type, QoS and discovery",
            Group::CommandHandling => "Command handling (rt/lowcmd)",
            Group::Robustness => "Robustness",
            Group::Fuzz => "Fuzzing",
        }
    }
}

/// One check's result with its evidence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckResult {
    /// Stable snake_case name (tests and scripts key on it).
    pub id: String,
    pub group: Group,
    pub status: Status,
    /// One sentence: what was seen.
    pub summary: String,
    /// Figures, sample counts, offending bytes (hex).
    pub evidence: BTreeMap<String, serde_json::Value>,
}

impl CheckResult {
    pub fn new(id: &str, group: Group, status: Status, summary: impl Into<String>) -> Self {
        CheckResult { id: id.to_owned(), group, status, summary: summary.into(), evidence: BTreeMap::new() }
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
        out.push_str(&format!(
            "Target: robot `{}` on DDS domain {} / `{}`{}  \nMode: {}; nominal LowState rate {} Hz; run took {:.1} s.  \n",
            self.target.robot,
            self.target.domain,
            self.target.interface,
            self.target.participant.as_ref().map(|p| format!(", participant `{p}`")).unwrap_or_default(),
            self.settings.mode,
            self.settings.expected_state_rate_hz,
            self.duration_s
        ));
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
            out.push_str(&format!("## {}\n\n| check | status | summary |\n|---|---|---|\n", g.title()));
            for r in self.results.iter().filter(|r| r.group == g) {
                let mark = match r.status {
                    Status::Pass => "pass",
                    Status::Fail => "**FAIL**",
                    Status::Inconclusive => "inconclusive",
                };
                out.push_str(&format!("| `{}` | {} | {} |\n", r.id, mark, r.summary.replace('|', "\\|")));
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
            target: TargetInfo { robot: "h1_2".into(), domain: 81, interface: "lo".into(), participant: None },
            settings: Settings { mode: "checks".into(), expected_state_rate_hz: 500.0, budget_s: None, seed: None },
            versions: BTreeMap::from([("ulab".to_owned(), "0.1.0".to_owned())]),
            duration_s: 1.0,
            results: vec![
                CheckResult::new("a", Group::StateStream, Status::Pass, "ok").with("n", 3),
                CheckResult::new("b", Group::Robustness, Status::Fail, "bad | pipe").with("bytes", "00ff"),
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
        let back: Report = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(back, r);
        assert!(r.any_fail());
    }

    #[test]
    fn markdown_escapes_pipes_and_lists_every_check() {
        let md = sample().to_markdown();
        assert!(md.contains("bad \\| pipe"));
        assert!(md.contains("`a`") && md.contains("`b`"));
        assert!(md.contains("1 pass, 1 fail, 0 inconclusive"));
    }
}
