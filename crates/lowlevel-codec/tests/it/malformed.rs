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

/// The RPC request of the golden corpus whose parameter is `{"data":204}`-like JSON, built here:
/// header (32 bytes in XCDR1), then the string length at payload offset 32.
fn rpc_request(parameter: &str) -> Vec<u8> {
    let mut r = unitree_idl::api::Request_::default();
    r.header.identity.api_id = 8101;
    r.header.policy.noreply = true;
    r.parameter = parameter.to_owned();
    r.binary = vec![1, 2, 3];
    lowlevel_codec::encode(&r, Encoding::UNITREE)
}

#[test]
fn rpc_booleans_other_than_0_and_1_are_rejected() {
    let mut bytes = rpc_request("{}");
    // policy.noreply: the byte after priority (payload offset 28).
    assert_eq!(bytes[4 + 28], 1);
    bytes[4 + 28] = 2;
    assert_eq!(
        cdr::decode::<unitree_idl::api::Request_>(&bytes),
        Err(DecodeError::InvalidBool { member: "noreply", offset: 28, value: 2 })
    );
}

#[test]
fn rpc_strings_must_be_terminated_utf8_with_a_length() {
    use lowlevel_codec::StringFault;
    let good = rpc_request("{\"data\":1}");
    assert!(cdr::decode::<unitree_idl::api::Request_>(&good).is_ok());
    let at = 4 + 32;
    assert_eq!(u32::from_le_bytes(good[at..at + 4].try_into().expect("4 bytes")), 11, "length counts the NUL");
    let fault = |bytes: &[u8]| match cdr::decode::<unitree_idl::api::Request_>(bytes) {
        Err(DecodeError::BadString { member: "parameter", offset: 32, reason }) => Some(reason),
        other => panic!("unexpected {other:?}"),
    };
    // The terminating NUL replaced.
    let mut bad = good.clone();
    bad[at + 4 + 10] = b'x';
    assert_eq!(fault(&bad), Some(StringFault::Unterminated));
    // Not UTF-8: a lone continuation byte at character 3.
    let mut bad = good.clone();
    bad[at + 4 + 3] = 0x80;
    assert_eq!(fault(&bad), Some(StringFault::NotUtf8 { at: 3 }));
    // Length 0 (no room even for the NUL).
    let mut r = unitree_idl::api::Request_::default();
    r.binary.clear();
    let mut bad = lowlevel_codec::encode(&r, Encoding::UNITREE);
    assert_eq!(&bad[at..at + 5], &[1, 0, 0, 0, 0], "an empty string is a NUL");
    bad[at] = 0;
    bad.remove(at + 4);
    assert_eq!(fault(&bad), Some(StringFault::ZeroLength));
    // A length beyond the input is a bad length, found before anything is allocated.
    let mut bad = good.clone();
    bad[at + 3] = 0x7f;
    assert!(matches!(
        cdr::decode::<unitree_idl::api::Request_>(&bad),
        Err(DecodeError::BadSequenceLength { member: "parameter", offset: 32, .. })
    ));
}

#[test]
fn rpc_binary_sequence_length_is_checked() {
    let good = rpc_request("");
    // binary: count at payload 32 + 5 (string "") -> aligned to 40.
    let at = 4 + 40;
    assert_eq!(&good[at..], &[3, 0, 0, 0, 1, 2, 3]);
    let mut bad = good.clone();
    bad[at] = 4;
    assert!(matches!(
        cdr::decode::<unitree_idl::api::Request_>(&bad),
        Err(DecodeError::BadSequenceLength { member: "binary", offset: 40, count: 4, available: 3 })
    ));
    let mut bad = good;
    bad[at] = 2;
    assert!(matches!(cdr::decode::<unitree_idl::api::Request_>(&bad), Err(DecodeError::TrailingBytes { .. })));
}
