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

/// Checks an H1-2 hg LowCmd: non-finite values; for every enabled used slot, targets within
/// the joint's position, speed and torque limits and gains within [0, KP_MAX] / [0, KD_MAX];
/// modes other than 0/1; unused slots (27..35) entirely zero.
pub fn h1_2_lowcmd(cmd: &hg::LowCmd_) -> Vec<Finding> {
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
            // NaN fails both comparisons and is already reported as non-finite.
            if value.is_finite() && !(min..=max).contains(&value) {
                findings.push(Finding::OutOfLimits { slot, joint: joint.name, field, value, min, max });
            }
        };
        // A position target only matters when it is stiffly tracked.
        if m.kp != 0.0 {
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
