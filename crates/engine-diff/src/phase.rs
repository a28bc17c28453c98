//! Contact phases of a humanoid window: which feet touch the ground, and whether any other body does. Findings,
//! reports and the allow-list name them (`flight`, `left`, `right`, `double`, with `+other` when a body other than
//! the feet touches the ground); one type instead of strings means a misspelt phase in `allowlist.toml` is an error
//! when the list is read, not an entry that silently never matches.

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;
use std::str::FromStr;

/// Which feet are on the ground: the type shared with the gap diagnosis's breakdown by phase.
pub use robot_model::FootContact;

/// The contact phase of a window.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ContactPhase {
    /// Which feet touch the ground.
    pub feet: FootContact,
    /// Whether a body other than the feet (a knee, a hand, the pelvis) touches it too.
    pub other: bool,
}

impl ContactPhase {
    /// Neither foot nor anything else on the ground.
    pub const FLIGHT: ContactPhase = ContactPhase { feet: FootContact::Flight, other: false };
    /// Both feet on the ground, nothing else.
    pub const DOUBLE: ContactPhase = ContactPhase { feet: FootContact::Double, other: false };

    /// Whether anything touches the ground (every phase but plain flight).
    pub fn has_contact(self) -> bool {
        self != ContactPhase::FLIGHT
    }
}

impl fmt::Display for ContactPhase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // `pad` so that width and alignment in format strings apply to the whole name.
        if self.other {
            f.pad(&format!("{}+other", self.feet.name()))
        } else {
            f.pad(self.feet.name())
        }
    }
}

/// A phase name that is not one of `flight`, `left`, `right`, `double` (optionally with `+other`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown contact phase `{0}` (expected flight, left, right or double, optionally with +other)")]
pub struct UnknownPhase(pub String);

impl FromStr for ContactPhase {
    type Err = UnknownPhase;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (base, other) = s.strip_suffix("+other").map_or((s, false), |b| (b, true));
        let feet = FootContact::ALL.into_iter().find(|f| f.name() == base).ok_or_else(|| UnknownPhase(s.to_owned()))?;
        Ok(ContactPhase { feet, other })
    }
}

/// Ordered by name, the order reports have always listed phases in.
impl Ord for ContactPhase {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.to_string().cmp(&other.to_string())
    }
}

impl PartialOrd for ContactPhase {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Serialize for ContactPhase {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for ContactPhase {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        String::deserialize(d)?.parse().map_err(serde::de::Error::custom)
    }
}

/// The phases an allow-list entry covers: one phase, or `contact` (any phase with something on the ground).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PhaseSelector {
    /// Every phase with a ground contact.
    Contact,
    /// Exactly this phase.
    Exactly(ContactPhase),
}

impl PhaseSelector {
    /// Whether `phase` is covered.
    pub fn covers(self, phase: ContactPhase) -> bool {
        match self {
            PhaseSelector::Contact => phase.has_contact(),
            PhaseSelector::Exactly(p) => p == phase,
        }
    }
}

impl fmt::Display for PhaseSelector {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PhaseSelector::Contact => f.pad("contact"),
            PhaseSelector::Exactly(p) => p.fmt(f),
        }
    }
}

impl Serialize for PhaseSelector {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for PhaseSelector {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        if s == "contact" {
            return Ok(PhaseSelector::Contact);
        }
        s.parse().map(PhaseSelector::Exactly).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_misspellings_are_refused() {
        for name in ["flight", "left", "right", "double", "flight+other", "left+other", "right+other", "double+other"] {
            let p: ContactPhase = name.parse().expect(name);
            assert_eq!(p.to_string(), name);
            assert_eq!(serde_json::to_string(&p).expect("json"), format!("\"{name}\""));
        }
        assert!("dual".parse::<ContactPhase>().is_err());
        assert!("double+others".parse::<ContactPhase>().is_err());
        assert!(serde_json::from_str::<PhaseSelector>("\"conact\"").is_err());
        assert_eq!(format!("{:>8}|", ContactPhase::DOUBLE), "  double|");
    }

    #[test]
    fn contact_covers_every_phase_but_plain_flight() {
        let contact: PhaseSelector = serde_json::from_str("\"contact\"").expect("selector");
        assert!(!contact.covers(ContactPhase::FLIGHT));
        assert!(contact.covers("flight+other".parse().expect("phase")));
        assert!(contact.covers(ContactPhase::DOUBLE));
        assert!(PhaseSelector::Exactly(ContactPhase::DOUBLE).covers(ContactPhase::DOUBLE));
        assert!(!PhaseSelector::Exactly(ContactPhase::DOUBLE).covers("double+other".parse().expect("phase")));
    }

    #[test]
    fn order_is_the_order_of_the_names() {
        let mut v: Vec<ContactPhase> =
            ["right", "double+other", "flight", "left", "double"].iter().map(|n| n.parse().expect("phase")).collect();
        v.sort();
        let names: Vec<String> = v.iter().map(ToString::to_string).collect();
        assert_eq!(names, ["double", "double+other", "flight", "left", "right"]);
    }
}
