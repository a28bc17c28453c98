//! Malformed input gets a typed error, never a panic and never a large allocation.

use lowlevel_codec::{cdr, DecodeError, Encoding, Endianness, Representation};
use unitree_idl::hg;

fn sample() -> Vec<u8> {
    cdr::encode(&hg::LowCmd_::default(), Encoding::UNITREE)
}

#[test]
fn empty_and_short_inputs() {
    assert_eq!(cdr::decode::<hg::LowCmd_>(&[]), Err(DecodeError::MissingHeader { len: 0 }));
    assert_eq!(cdr::decode::<hg::LowCmd_>(&[0, 1]), Err(DecodeError::MissingHeader { len: 2 }));
    assert!(matches!(
        cdr::decode::<hg::LowCmd_>(&[0, 1, 0, 0]),
        Err(DecodeError::Truncated { member: "mode_pr", offset: 0, .. })
    ));
}

#[test]
fn truncated_anywhere() {
    let bytes = sample();
    for len in 4..bytes.len() {
        match cdr::decode::<hg::LowCmd_>(&bytes[..len]) {
            Err(DecodeError::Truncated { .. }) => {}
            other => panic!("length {len}: {other:?}"),
        }
    }
}

#[test]
fn trailing_bytes() {
    let mut bytes = sample();
    bytes.extend_from_slice(&[0, 0, 0, 0]);
    assert_eq!(cdr::decode::<hg::LowCmd_>(&bytes), Err(DecodeError::TrailingBytes { offset: 1000, count: 4 }));
}

#[test]
fn header_padding_option_is_honoured() {
    // Same sample with 3 padding bytes declared in the options (XTypes 7.6.3.1.2).
    let mut bytes = sample();
    bytes[3] = 3;
    bytes.extend_from_slice(&[0, 0, 0]);
    assert!(cdr::decode::<hg::LowCmd_>(&bytes).is_ok());
    // Declared padding larger than the payload.
    assert_eq!(cdr::decode::<hg::LowCmd_>(&[0, 1, 0, 3, 0]), Err(DecodeError::BadPadding { padding: 3, payload: 1 }));
}

#[test]
fn unknown_and_unsupported_representations() {
    let mut bytes = sample();
    bytes[1] = 0x42;
    assert_eq!(cdr::decode::<hg::LowCmd_>(&bytes), Err(DecodeError::UnknownRepresentation { id: 0x0042 }));
    for id in [0x02u8, 0x03, 0x08, 0x09, 0x0a, 0x0b] {
        bytes[1] = id;
        assert!(
            matches!(cdr::decode::<hg::LowCmd_>(&bytes), Err(DecodeError::UnsupportedRepresentation { .. })),
            "{id:#x}"
        );
    }
}

#[test]
fn xcdr2_sample_read_as_wrong_type_or_version() {
    let x2 = cdr::encode(
        &hg::LowCmd_::default(),
        Encoding { representation: Representation::Xcdr2, endianness: Endianness::Little },
    );
    // Relabel as XCDR1: the DHEADER is read as data, leaving 8 trailing bytes.
    let mut relabelled = x2.clone();
    relabelled[1] = 0x01;
    assert!(matches!(cdr::decode::<hg::LowCmd_>(&relabelled), Err(DecodeError::TrailingBytes { .. })));
    // Wrong DHEADER.
    let mut bad = x2;
    bad[4 + 4] = 0xff;
    assert!(matches!(cdr::decode::<hg::LowCmd_>(&bad), Err(DecodeError::BadDheader { member: "motor_cmd", .. })));
}

#[test]
fn huge_sequence_length_is_rejected_before_allocating() {
    // HandCmd_: sequence<MotorCmd_> count 0xFFFFFFFF followed by nothing.
    let bytes = [0u8, 1, 0, 0, 0xff, 0xff, 0xff, 0xff];
    match cdr::decode::<hg::HandCmd_>(&bytes) {
        Err(DecodeError::BadSequenceLength { member: "motor_cmd", count: u32::MAX, available: 0, .. }) => {}
        other => panic!("{other:?}"),
    }
    // XCDR2: DHEADER then count.
    let bytes = [0u8, 7, 0, 0, 8, 0, 0, 0, 0xff, 0xff, 0xff, 0x7f];
    assert!(matches!(cdr::decode::<hg::HandCmd_>(&bytes), Err(DecodeError::BadSequenceLength { .. })));
}

/// Payload sizes published for Unitree's messages (XCDR1 / XCDR2).
#[test]
fn payload_sizes_match_published_figures() {
    use unitree_idl::go;
    let len = |bytes: Vec<u8>| bytes.len() - cdr::HEADER_LEN;
    let x1 = Encoding::UNITREE;
    let x2 = Encoding { representation: Representation::Xcdr2, endianness: Endianness::Little };
    assert_eq!(len(cdr::encode(&hg::LowCmd_::default(), x1)), 1000);
    assert_eq!(len(cdr::encode(&hg::LowState_::default(), x1)), 2088);
    assert_eq!(len(cdr::encode(&go::LowCmd_::default(), x1)), 808);
    assert_eq!(len(cdr::encode(&go::LowState_::default(), x1)), 1176);
    assert_eq!(len(cdr::encode(&hg::LowCmd_::default(), x2)), 1008);
    assert_eq!(len(cdr::encode(&hg::LowState_::default(), x2)), 2096);
    assert_eq!(len(cdr::encode(&go::LowCmd_::default(), x2)), 816);
    assert_eq!(len(cdr::encode(&go::LowState_::default(), x2)), 1184);
    // First hg MotorCmd.mode at payload offset 2, first MotorState.mode at 70.
    let mut cmd = hg::LowCmd_::default();
    cmd.motor_cmd[0].mode = 0xAB;
    assert_eq!(cdr::encode(&cmd, x1)[4 + 2], 0xAB);
    let mut state = hg::LowState_::default();
    state.motor_state[0].mode = 0xCD;
    assert_eq!(cdr::encode(&state, x1)[4 + 70], 0xCD);
}
