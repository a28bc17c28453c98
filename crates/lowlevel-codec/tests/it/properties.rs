//! Property tests: structured random values (from the `arbitrary` derive, fed by proptest's
//! shrinking byte strings) round-trip in every representation and endianness; the fast CRC
//! equals the bit-serial reference on random images.

use arbitrary::{Arbitrary, Unstructured};
use lowlevel_codec::{crc, fuzzing};
use proptest::prelude::*;
use unitree_idl::{api, go, hg, IdlStruct};

fn roundtrip_from_bytes<T: IdlStruct + for<'a> Arbitrary<'a>>(bytes: &[u8]) {
    let mut u = Unstructured::new(bytes);
    if let Ok(value) = T::arbitrary(&mut u) {
        fuzzing::roundtrip(&value);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn hg_roundtrip(bytes in proptest::collection::vec(any::<u8>(), 0..4096)) {
        roundtrip_from_bytes::<hg::LowCmd_>(&bytes);
        roundtrip_from_bytes::<hg::LowState_>(&bytes);
        roundtrip_from_bytes::<hg::HandCmd_>(&bytes);
        roundtrip_from_bytes::<hg::HandState_>(&bytes);
        roundtrip_from_bytes::<hg::BmsState_>(&bytes);
        roundtrip_from_bytes::<hg::BmsCmd_>(&bytes);
        roundtrip_from_bytes::<hg::MainBoardState_>(&bytes);
        roundtrip_from_bytes::<hg::PressSensorState_>(&bytes);
    }

    #[test]
    fn go_roundtrip(bytes in proptest::collection::vec(any::<u8>(), 0..4096)) {
        roundtrip_from_bytes::<go::LowCmd_>(&bytes);
        roundtrip_from_bytes::<go::LowState_>(&bytes);
        roundtrip_from_bytes::<go::BmsState_>(&bytes);
        roundtrip_from_bytes::<go::MotorState_>(&bytes);
    }

    #[test]
    fn api_roundtrip(bytes in proptest::collection::vec(any::<u8>(), 0..4096)) {
        roundtrip_from_bytes::<api::Request_>(&bytes);
        roundtrip_from_bytes::<api::Response_>(&bytes);
        roundtrip_from_bytes::<api::RequestPolicy_>(&bytes);
    }

    /// A valid RPC sample (strings, sequences, booleans, int64) with one byte changed: decodes to
    /// something or fails cleanly, and whatever decodes re-encodes canonically.
    #[test]
    fn rpc_decoder_never_panics_on_mutations(seed in proptest::collection::vec(any::<u8>(), 16..2048), at in any::<usize>(), byte in any::<u8>()) {
        let mut u = Unstructured::new(&seed);
        if let Ok(value) = api::Request_::arbitrary(&mut u) {
            for encoding in fuzzing::ENCODINGS {
                let mut bytes = lowlevel_codec::encode(&value, encoding);
                let i = at % bytes.len();
                bytes[i] = byte;
                fuzzing::decode_any(&bytes);
            }
        }
    }

    #[test]
    fn fast_crc_equals_reference(image in proptest::collection::vec(any::<u8>(), 0..3000)) {
        prop_assert_eq!(crc::crc32_words(&image), crc::crc32_reference(&image));
    }

    #[test]
    fn decoder_never_panics_on_noise(bytes in proptest::collection::vec(any::<u8>(), 0..2200)) {
        fuzzing::decode_any(&bytes);
    }

    /// A valid sample with one byte changed: decodes to something or fails cleanly.
    #[test]
    fn decoder_never_panics_on_mutations(seed in proptest::collection::vec(any::<u8>(), 64..4096), at in any::<usize>(), byte in any::<u8>()) {
        let mut u = Unstructured::new(&seed);
        if let Ok(value) = hg::HandState_::arbitrary(&mut u) {
            for encoding in fuzzing::ENCODINGS {
                let mut bytes = lowlevel_codec::encode(&value, encoding);
                let i = at % bytes.len();
                bytes[i] = byte;
                fuzzing::decode_any(&bytes);
            }
        }
    }
}

/// Sealing makes every CRC type verify, and flipping any single bit of any member breaks it.
#[test]
fn seal_then_verify_and_detect_corruption() {
    let mut cmd = hg::LowCmd_::default();
    cmd.motor_cmd[3].q = 0.5;
    cmd.motor_cmd[3].kp = 100.0;
    crc::seal(&mut cmd);
    assert!(crc::verify(&cmd));
    cmd.motor_cmd[3].q = 0.500_000_06;
    assert!(!crc::verify(&cmd));
    let mut state = go::LowState_::default();
    crc::seal(&mut state);
    assert!(crc::verify(&state));
    state.tick = 1;
    assert!(!crc::verify(&state));
}
