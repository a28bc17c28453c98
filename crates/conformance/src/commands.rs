//! LowCmd building blocks shared by the checks and the fuzzer: the hold command that keeps the
//! robot where it stands, the test joint, gains and encodings.

use lowlevel_codec::{cdr, crc, Encoding};
use unitree_idl::{h1_2, hg};

/// Joint whose response the command checks observe: the left elbow (slot 16), light, so an
/// applied command moves it quickly, and far from the balance-critical legs.
pub const TEST_JOINT: usize = 16;

/// Step of the elbow target in the command checks (rad): large against sensor noise and gravity
/// sag, small enough to stay inside the joint range from any standing pose.
pub const STEP: f32 = 0.5;

/// Margin kept from the joint range when a measured pose becomes a target (rad).
const RANGE_MARGIN: f32 = 0.02;

/// PD gains (kp N·m/rad, kd N·m·s/rad) of the hold command per slot: legs as stiff as
/// `ulab sim`'s standing hold (a robot without a balance controller stays up with them), the rest
/// moderate. All within the project's sanity bounds (`KP_MAX`, `KD_MAX`).
pub fn hold_gains(slot: usize) -> (f32, f32) {
    let name = h1_2::JOINTS.get(slot).map_or("", |j| j.name);
    if name.contains("ankle") {
        (600.0, 10.0)
    } else if name.contains("hip") || name.contains("knee") {
        (500.0, 5.0)
    } else if name.contains("torso") {
        (300.0, 5.0)
    } else if name.contains("shoulder") {
        (100.0, 2.0)
    } else {
        (40.0, 2.0)
    }
}

/// The joint range of a slot (rad), if the slot is used.
pub fn range(slot: usize) -> Option<(f32, f32)> {
    h1_2::JOINTS.get(slot).map(|j| (j.lower, j.upper))
}

/// Clamps a position target into a joint's range with a small margin.
pub fn clamp_target(slot: usize, q: f32) -> f32 {
    match range(slot) {
        Some((lo, hi)) if q.is_finite() => q.clamp(lo + RANGE_MARGIN, hi - RANGE_MARGIN),
        Some((lo, hi)) => 0.5 * (lo + hi),
        None => 0.0,
    }
}

/// A command holding every used joint at `pose` (slot order, one entry per used joint), mode 1,
/// hold gains, CRC sealed. `mode_machine` echoes what the robot reports, as Unitree's examples do.
pub fn hold_command(pose: &[f32; h1_2::NUM_JOINTS], mode_machine: u8) -> hg::LowCmd_ {
    let mut cmd = hg::LowCmd_ { mode_machine, ..Default::default() };
    for (slot, q) in pose.iter().enumerate() {
        let (kp, kd) = hold_gains(slot);
        let m = &mut cmd.motor_cmd[slot];
        m.mode = 1;
        m.q = clamp_target(slot, *q);
        m.kp = kp;
        m.kd = kd;
    }
    crc::seal(&mut cmd);
    cmd
}

/// `base` with one joint's target and gains replaced, resealed.
pub fn with_joint(base: &hg::LowCmd_, slot: usize, q: f32, kp: f32, kd: f32) -> hg::LowCmd_ {
    let mut cmd = base.clone();
    if let Some(m) = cmd.motor_cmd.get_mut(slot) {
        m.q = q;
        m.kp = kp;
        m.kd = kd;
    }
    crc::seal(&mut cmd);
    cmd
}

/// CDR bytes as Unitree's SDK puts them on the wire (XCDR1 little-endian).
pub fn wire(cmd: &hg::LowCmd_) -> Vec<u8> {
    cdr::encode(cmd, Encoding::UNITREE)
}

/// `cmd` with its CRC deliberately wrong (every bit flipped).
pub fn bad_crc(cmd: &hg::LowCmd_) -> hg::LowCmd_ {
    let mut c = cmd.clone();
    c.crc = crc::compute(&c) ^ 0xFFFF_FFFF;
    c
}

/// Lower-case hex of a byte string, optionally truncated (evidence in reports).
pub fn hex(bytes: &[u8], max: usize) -> String {
    let mut s: String = bytes.iter().take(max).map(|b| format!("{b:02x}")).collect();
    if bytes.len() > max {
        s.push_str(&format!("… ({} bytes)", bytes.len()));
    }
    s
}

/// Parses [`hex`] output without truncation.
pub fn unhex(text: &str) -> Option<Vec<u8>> {
    let t = text.trim();
    if !t.len().is_multiple_of(2) {
        return None;
    }
    (0..t.len()).step_by(2).map(|i| t.get(i..i + 2).and_then(|b| u8::from_str_radix(b, 16).ok())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use lowlevel_codec::validate;

    #[test]
    fn hold_command_is_valid_and_sealed() {
        let pose = [0.0f32; h1_2::NUM_JOINTS];
        let cmd = hold_command(&pose, 6);
        assert!(crc::verify(&cmd));
        let findings = validate::h1_2_lowcmd(&cmd);
        assert!(findings.is_empty(), "{findings:?}");
        assert!(!crc::verify(&bad_crc(&cmd)));
    }

    #[test]
    fn targets_are_clamped_into_range() {
        let (lo, hi) = range(TEST_JOINT).unwrap_or((0.0, 0.0));
        assert!(clamp_target(TEST_JOINT, 100.0) < hi);
        assert!(clamp_target(TEST_JOINT, -100.0) > lo);
        assert!(clamp_target(TEST_JOINT, f32::NAN).is_finite());
    }

    #[test]
    fn hex_round_trips() {
        let b = vec![0u8, 1, 0xab, 0xff];
        assert_eq!(unhex(&hex(&b, 100)), Some(b));
        assert_eq!(unhex("abc"), None);
        assert_eq!(unhex("zz"), None);
    }
}
