//! Semantic checks, kept apart from decoding: a message can be well-formed CDR and still be
//! dangerous to apply. Each finding is typed and has a stable name for reports.

use unitree_idl::{go, h1_2, hg, IdlStruct, PrimKind, Primitive, Visitor};

/// Which command field a finding is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CmdField {
    /// Position target `q` (rad).
    Q,
    /// Velocity target `dq` (rad/s).
    Dq,
    /// Feed-forward torque `tau` (N·m).
    Tau,
    /// Stiffness `kp` (N·m/rad).
    Kp,
    /// Damping `kd` (N·m·s/rad).
    Kd,
}

impl CmdField {
    /// The IDL member name (`q`, `dq`, `tau`, `kp`, `kd`).
    pub const fn name(self) -> &'static str {
        match self {
            CmdField::Q => "q",
            CmdField::Dq => "dq",
            CmdField::Tau => "tau",
            CmdField::Kp => "kp",
            CmdField::Kd => "kd",
        }
    }
}

impl core::fmt::Display for CmdField {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// One problem found in a message.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Finding {
    /// A float member that is NaN or infinite.
    #[error("`{path}` is not finite ({value})")]
    NonFinite {
        /// Path of the member (`motor_cmd[3].kp`).
        path: String,
        /// The value found.
        value: f32,
    },
    /// A motor command whose `mode` is neither 0 (disabled) nor 1 (enabled).
    #[error("slot {slot}: mode {mode} is neither 0 (disabled) nor 1 (enabled)")]
    UnknownMode {
        /// Motor slot.
        slot: usize,
        /// The mode found.
        mode: u8,
    },
    /// A target or gain of an enabled motor outside the joint's limits.
    #[error("slot {slot} ({joint}): {field} = {value} outside [{min}, {max}]")]
    OutOfLimits {
        /// Motor slot.
        slot: usize,
        /// Name of the joint in that slot.
        joint: &'static str,
        /// Which command member.
        field: CmdField,
        /// The value found.
        value: f32,
        /// Smallest allowed value.
        min: f32,
        /// Largest allowed value.
        max: f32,
    },
    /// A member of a slot the robot does not use that is not zero.
    #[error("slot {slot} is not used by this robot but `{member}` is not zero")]
    UnusedSlotNotZero {
        /// Motor slot.
        slot: usize,
        /// IDL name of the non-zero member.
        member: &'static str,
    },
    /// An IMU orientation quaternion whose norm is not 1 (within rounding tolerance).
    #[error("IMU quaternion has norm {norm}, not 1")]
    QuaternionNotNormalized {
        /// The norm found.
        norm: f32,
    },
    /// An hg LowCmd whose `mode_pr` is neither 0 (ankle pitch/roll) nor 1 (ankle A/B motors).
    #[error("`mode_pr` is {mode_pr}, neither 0 (ankle pitch/roll) nor 1 (ankle A/B motors)")]
    UnknownAnkleMode {
        /// The value found.
        mode_pr: u8,
    },
    /// A go LowCmd whose `head` is not `FE EF`.
    #[error("`head` is {head:02X?}, not FE EF")]
    BadHead {
        /// The two bytes found.
        head: [u8; 2],
    },
    /// A go LowCmd whose `level_flag` is not 0xFF (low-level control).
    #[error("`level_flag` is {flag:#04x}, not 0xFF (low level)")]
    BadLevelFlag {
        /// The flag found.
        flag: u8,
    },
}

impl Finding {
    /// Stable snake_case name for reports and counters.
    pub const fn name(&self) -> &'static str {
        match self {
            Finding::NonFinite { .. } => "non_finite",
            Finding::UnknownMode { .. } => "unknown_mode",
            Finding::OutOfLimits { .. } => "out_of_limits",
            Finding::UnusedSlotNotZero { .. } => "unused_slot_not_zero",
            Finding::UnknownAnkleMode { .. } => "unknown_ankle_mode",
            Finding::QuaternionNotNormalized { .. } => "quaternion_not_normalized",
            Finding::BadHead { .. } => "bad_head",
            Finding::BadLevelFlag { .. } => "bad_level_flag",
        }
    }
}

/// Every non-finite float in any message, with its path (`motor_cmd[3].kp`).
pub fn non_finite<T: IdlStruct>(value: &T) -> Vec<Finding> {
    let mut finder = NonFiniteFinder { path: Vec::new(), found: Vec::new() };
    value.walk(&mut finder);
    finder.found
}

struct NonFiniteFinder {
    path: Vec<String>,
    found: Vec<Finding>,
}

impl NonFiniteFinder {
    fn check(&mut self, name: &str, index: Option<usize>, bits: u64) {
        let x = f32::from_bits(bits as u32);
        if !x.is_finite() {
            let mut path = self.path.join(".");
            if !path.is_empty() {
                path.push('.');
            }
            path.push_str(name);
            if let Some(i) = index {
                path.push_str(&format!("[{i}]"));
            }
            self.found.push(Finding::NonFinite { path, value: x });
        }
    }
}

impl Visitor for NonFiniteFinder {
    fn primitive<P: Primitive>(&mut self, name: &'static str, value: &P) {
        if P::KIND == PrimKind::F32 {
            self.check(name, None, value.to_bits());
        }
    }
    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &[P]) {
        if P::KIND == PrimKind::F32 {
            for (i, item) in items.iter().enumerate() {
                self.check(name, Some(i), item.to_bits());
            }
        }
    }
    fn structure<S: IdlStruct>(&mut self, name: &'static str, value: &S) {
        self.path.push(name.to_owned());
        value.walk(self);
        self.path.pop();
    }
    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &[S]) {
        for (i, item) in items.iter().enumerate() {
            self.path.push(format!("{name}[{i}]"));
            item.walk(self);
            self.path.pop();
        }
    }
    fn struct_sequence<S: IdlStruct>(&mut self, name: &'static str, items: &[S]) {
        self.struct_array(name, items);
    }
    fn primitive_sequence<P: Primitive>(&mut self, name: &'static str, items: &[P]) {
        self.primitive_array(name, items);
    }
    fn string(&mut self, _name: &'static str, _value: &str) {}
}

/// What the H1-2's ankle slots (4, 5, 10, 11) command: `LowCmd.mode_pr`. Each ankle is a parallel linkage of two
/// motors (A and B) that turns the pitch and roll joints of Unitree's robot models.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AnkleMode {
    /// `mode_pr` = 0: the slots command the pitch and roll joints; the robot solves the linkage.
    PitchRoll,
    /// `mode_pr` = 1: the slots command the A and B motors directly; their position targets are motor angles.
    MotorsAb,
}

impl AnkleMode {
    /// The mode a command asks for (`None` for a `mode_pr` other than 0 and 1).
    pub const fn of(cmd: &hg::LowCmd_) -> Option<AnkleMode> {
        match cmd.mode_pr {
            0 => Some(AnkleMode::PitchRoll),
            1 => Some(AnkleMode::MotorsAb),
            _ => None,
        }
    }
}

/// Slack on a joint's position range (rad). Unitree publishes the H1-2's ranges to six decimals, cut rather than
/// rounded (30° = 0.5235988 rad appears as 0.523598), so a target at the true limit exceeds the published number
/// by up to 1e-6 rad; its float32 encoding adds up to 6e-8 rad.
pub const RANGE_SLACK_RAD: f32 = 2e-6;

/// Checks an H1-2 hg LowCmd: non-finite values; for every enabled used slot, targets within
/// the joint's position, speed and torque limits and gains within [0, KP_MAX] / [0, KD_MAX];
/// modes other than 0/1; unused slots (27..35) entirely zero; `mode_pr` other than 0/1. In the ankles'
/// A/B mode the ankle slots' position targets are motor angles, whose range the published models do not give:
/// they are not checked (their speeds, torques and gains are).
pub fn h1_2_lowcmd(cmd: &hg::LowCmd_) -> Vec<Finding> {
    match AnkleMode::of(cmd) {
        Some(mode) => h1_2_lowcmd_in(cmd, mode),
        None => {
            let mut findings = h1_2_lowcmd_in(cmd, AnkleMode::PitchRoll);
            findings.push(Finding::UnknownAnkleMode { mode_pr: cmd.mode_pr });
            findings
        }
    }
}

/// [`h1_2_lowcmd`] with the ankle slots read in `mode` whatever `mode_pr` says: a simulator of the serial pitch/roll
/// model applies every ankle target to those joints, so it checks them in [`AnkleMode::PitchRoll`].
pub fn h1_2_lowcmd_in(cmd: &hg::LowCmd_, mode: AnkleMode) -> Vec<Finding> {
    let mut findings = non_finite(cmd);
    for (slot, m) in cmd.motor_cmd.iter().enumerate() {
        let Some(joint) = h1_2::JOINTS.get(slot) else {
            let zero = hg::MotorCmd_::default();
            let fields: [(&'static str, bool); 7] = [
                ("mode", m.mode != zero.mode),
                ("q", m.q.to_bits() != 0),
                ("dq", m.dq.to_bits() != 0),
                ("tau", m.tau.to_bits() != 0),
                ("kp", m.kp.to_bits() != 0),
                ("kd", m.kd.to_bits() != 0),
                ("reserve", m.reserve != 0),
            ];
            findings.extend(
                fields.iter().filter(|(_, nz)| *nz).map(|(member, _)| Finding::UnusedSlotNotZero { slot, member }),
            );
            continue;
        };
        match m.mode {
            0 => continue,
            1 => {}
            mode => {
                findings.push(Finding::UnknownMode { slot, mode });
                continue;
            }
        }
        let mut limit = |field: CmdField, value: f32, min: f32, max: f32| {
            let slack = if field == CmdField::Q { RANGE_SLACK_RAD } else { 0.0 };
            // NaN fails both comparisons and is already reported as non-finite.
            if value.is_finite() && !(min - slack..=max + slack).contains(&value) {
                findings.push(Finding::OutOfLimits { slot, joint: joint.name, field, value, min, max });
            }
        };
        // A position target only matters when it is stiffly tracked, and is a joint angle unless it is an ankle
        // motor's.
        let motor_angle = mode == AnkleMode::MotorsAb && h1_2::ANKLE_SLOTS.contains(&slot);
        if m.kp != 0.0 && !motor_angle {
            limit(CmdField::Q, m.q, joint.lower, joint.upper);
        }
        limit(CmdField::Dq, m.dq, -joint.speed_limit, joint.speed_limit);
        limit(CmdField::Tau, m.tau, -joint.torque_limit, joint.torque_limit);
        limit(CmdField::Kp, m.kp, 0.0, h1_2::KP_MAX);
        limit(CmdField::Kd, m.kd, 0.0, h1_2::KD_MAX);
    }
    findings
}

/// Checks an hg LowState: non-finite values and a unit IMU quaternion.
pub fn hg_lowstate(state: &hg::LowState_) -> Vec<Finding> {
    let mut findings = non_finite(state);
    findings.extend(quaternion(state.imu_state.quaternion));
    findings
}

/// Checks a go LowCmd: non-finite values, `head` = FE EF and `level_flag` = 0xFF.
pub fn go_lowcmd(cmd: &go::LowCmd_) -> Vec<Finding> {
    let mut findings = non_finite(cmd);
    if cmd.head != go::LOWCMD_HEAD {
        findings.push(Finding::BadHead { head: cmd.head });
    }
    if cmd.level_flag != go::LOWLEVEL_FLAG {
        findings.push(Finding::BadLevelFlag { flag: cmd.level_flag });
    }
    findings
}

/// Checks a go LowState: non-finite values and a unit IMU quaternion.
pub fn go_lowstate(state: &go::LowState_) -> Vec<Finding> {
    let mut findings = non_finite(state);
    findings.extend(quaternion(state.imu_state.quaternion));
    findings
}

/// The checks that apply to a message of any type: the type's own validator for the four
/// low-level messages (H1-2 limits for hg LowCmd), non-finite values for every other type.
pub fn any<T: IdlStruct>(value: &T) -> Vec<Finding> {
    let any = value as &dyn core::any::Any;
    if let Some(v) = any.downcast_ref::<hg::LowCmd_>() {
        h1_2_lowcmd(v)
    } else if let Some(v) = any.downcast_ref::<hg::LowState_>() {
        hg_lowstate(v)
    } else if let Some(v) = any.downcast_ref::<go::LowCmd_>() {
        go_lowcmd(v)
    } else if let Some(v) = any.downcast_ref::<go::LowState_>() {
        go_lowstate(v)
    } else {
        non_finite(value)
    }
}

/// Tolerance on |q| - 1: float32 rounding of a normalised quaternion is ~1e-7; 1e-3 allows
/// for a sensor's own normalisation while flagging anything unnormalised.
const QUATERNION_TOLERANCE: f32 = 1e-3;

fn quaternion(q: [f32; 4]) -> Option<Finding> {
    let norm = q.iter().map(|x| x * x).sum::<f32>().sqrt();
    (norm.is_finite() && (norm - 1.0).abs() > QUATERNION_TOLERANCE).then_some(Finding::QuaternionNotNormalized { norm })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every used slot enabled and holding `q` with moderate gains.
    fn holding(q: [f32; h1_2::NUM_JOINTS], mode_pr: u8) -> hg::LowCmd_ {
        let mut cmd = hg::LowCmd_ { mode_pr, ..Default::default() };
        for (m, q) in cmd.motor_cmd.iter_mut().zip(q) {
            *m = hg::MotorCmd_ { mode: 1, q, kp: 50.0, kd: 2.0, ..Default::default() };
        }
        cmd
    }

    fn out_of_limits(findings: &[Finding]) -> Vec<(usize, CmdField)> {
        findings
            .iter()
            .filter_map(|f| match f {
                Finding::OutOfLimits { slot, field, .. } => Some((*slot, *field)),
                _ => None,
            })
            .collect()
    }

    /// Unitree's H1-2 example drives the ankle pitch to 30° (0.5235988 rad as float32) where the published range
    /// ends at 0.523598: a target at a limit passes, one a tenth of a milliradian beyond it does not.
    #[test]
    fn a_target_at_a_published_limit_passes_and_beyond_it_fails() {
        for j in h1_2::JOINTS.iter() {
            for (q, ok) in [(j.lower, true), (j.upper, true), (j.upper + 1e-4, false), (j.lower - 1e-4, false)] {
                let mut pose = [0.0_f32; h1_2::NUM_JOINTS];
                pose[j.slot] = q;
                let found = out_of_limits(&h1_2_lowcmd(&holding(pose, 0)));
                assert_eq!(found.is_empty(), ok, "{} at {q}: {found:?}", j.name);
            }
        }
        let mut pose = [0.0_f32; h1_2::NUM_JOINTS];
        pose[4] = 30.0_f32.to_radians();
        assert!(h1_2_lowcmd(&holding(pose, 0)).is_empty(), "30° ankle pitch");
    }

    /// In the A/B mode the ankle slots carry the linkage motors' angles: a roll-slot target beyond the roll joint's
    /// ±15° is no finding there, while the same target in pitch/roll mode is, and the other joints, the ankle slots'
    /// gains, and a simulator that reads every target as pitch/roll keep their checks.
    #[test]
    fn ankle_targets_in_the_ab_mode_are_motor_angles() {
        let mut pose = [0.0_f32; h1_2::NUM_JOINTS];
        pose[5] = 0.5;
        pose[11] = -0.5;
        assert_eq!(out_of_limits(&h1_2_lowcmd(&holding(pose, 0))), vec![(5, CmdField::Q), (11, CmdField::Q)]);
        assert!(h1_2_lowcmd(&holding(pose, 1)).is_empty());
        assert_eq!(
            out_of_limits(&h1_2_lowcmd_in(&holding(pose, 1), AnkleMode::PitchRoll)),
            vec![(5, CmdField::Q), (11, CmdField::Q)]
        );
        pose[3] = 3.0; // beyond the knee's range
        let mut cmd = holding(pose, 1);
        cmd.motor_cmd[10].kp = h1_2::KP_MAX * 2.0;
        assert_eq!(out_of_limits(&h1_2_lowcmd(&cmd)), vec![(3, CmdField::Q), (10, CmdField::Kp)]);
    }

    #[test]
    fn an_unknown_ankle_mode_is_a_finding() {
        let pose = [0.0_f32; h1_2::NUM_JOINTS];
        assert!(h1_2_lowcmd(&holding(pose, 0)).is_empty());
        let found = h1_2_lowcmd(&holding(pose, 2));
        assert_eq!(found, vec![Finding::UnknownAnkleMode { mode_pr: 2 }]);
        assert_eq!(found[0].name(), "unknown_ankle_mode");
    }
}
