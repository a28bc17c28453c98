//! Which feet of a biped are on the ground: the one contact-phase type of the engine comparison
//! (`engine_diff::phase::ContactPhase`, named `flight`, `left`, `right`, `double`) and of the gap diagnosis's
//! breakdown by phase (which names one foot `swing` and both `stance`).

/// Which feet are on the ground.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FootContact {
    /// Neither foot.
    Flight,
    /// The left foot only.
    Left,
    /// The right foot only.
    Right,
    /// Both feet.
    Double,
}

impl FootContact {
    /// Every value, in declaration order.
    pub const ALL: [FootContact; 4] = [FootContact::Flight, FootContact::Left, FootContact::Right, FootContact::Double];

    /// The phase of a left and a right foot that do (`true`) or do not touch the ground.
    pub const fn from_feet(left: bool, right: bool) -> FootContact {
        match (left, right) {
            (true, true) => FootContact::Double,
            (true, false) => FootContact::Left,
            (false, true) => FootContact::Right,
            (false, false) => FootContact::Flight,
        }
    }

    /// Its name: `flight`, `left`, `right` or `double`.
    pub const fn name(self) -> &'static str {
        match self {
            FootContact::Flight => "flight",
            FootContact::Left => "left",
            FootContact::Right => "right",
            FootContact::Double => "double",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn feet_and_names() {
        assert_eq!(FootContact::from_feet(true, true), FootContact::Double);
        assert_eq!(FootContact::from_feet(true, false), FootContact::Left);
        assert_eq!(FootContact::from_feet(false, true), FootContact::Right);
        assert_eq!(FootContact::from_feet(false, false), FootContact::Flight);
        let names: Vec<&str> = FootContact::ALL.iter().map(|f| f.name()).collect();
        assert_eq!(names, ["flight", "left", "right", "double"]);
    }
}
