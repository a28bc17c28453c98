//! The checks behind the fuzz targets, kept here so that `cargo test` replays the saved
//! regressions through exactly the same code as the fuzzers.

use crate::view::{self, Viewable};
use crate::{cdr, crc, Encoding, Endianness, Representation};
use unitree_idl::{with_message_type, IdlStruct, MessageType};

/// Every encoding a decoded value is re-encoded in.
pub const ENCODINGS: [Encoding; 4] = [
    Encoding { representation: Representation::Xcdr1, endianness: Endianness::Little },
    Encoding { representation: Representation::Xcdr1, endianness: Endianness::Big },
    Encoding { representation: Representation::Xcdr2, endianness: Endianness::Little },
    Encoding { representation: Representation::Xcdr2, endianness: Endianness::Big },
];

/// `decode_any`: feeds `bytes` to the decoder of every type. Decoding must return a value or an
/// error (never panic); whatever decodes must re-encode, in every encoding, to a canonical form
/// that decodes to the same value, and re-encoding in its own encoding must be stable. Every
/// type with a view is also viewed: see [`view_agrees_with_decode`].
pub fn decode_any(bytes: &[u8]) {
    for &ty in MessageType::ALL {
        with_message_type!(ty, T => decode_one::<T>(bytes));
        crate::with_viewable_type!(ty, T => view_agrees_with_decode::<T>(bytes));
    }
}

/// [`view::view`] accepts exactly what [`cdr::decode`] accepts, fails with the same error
/// otherwise, and its `to_owned` is the decoded value bit for bit, with the same header.
pub fn view_agrees_with_decode<T: Viewable>(bytes: &[u8]) {
    match (cdr::decode::<T>(bytes), view::view::<T>(bytes)) {
        (Ok(decoded), Ok(v)) => {
            assert_eq!(
                (v.encoding(), v.options()),
                (decoded.encoding, decoded.options),
                "{}: header",
                T::DDS_TYPE_NAME
            );
            let owned = v.to_owned();
            assert_eq!(
                cdr::encode(&owned, Encoding::UNITREE),
                cdr::encode(&decoded.value, Encoding::UNITREE),
                "{}: view value",
                T::DDS_TYPE_NAME
            );
        }
        (Err(a), Err(b)) => assert_eq!(a, b, "{}: view error differs from decode", T::DDS_TYPE_NAME),
        (Ok(_), Err(e)) => panic!("{}: decode accepts, view rejects: {e}", T::DDS_TYPE_NAME),
        (Err(e), Ok(_)) => panic!("{}: view accepts, decode rejects: {e}", T::DDS_TYPE_NAME),
    }
}

fn decode_one<T: IdlStruct>(bytes: &[u8]) {
    let Ok(decoded) = cdr::decode::<T>(bytes) else { return };
    // Bit-exact comparison through the canonical encoding (NaN != NaN under PartialEq).
    let reference = cdr::encode(&decoded.value, Encoding::UNITREE);
    for encoding in ENCODINGS {
        let canonical = cdr::encode(&decoded.value, encoding);
        let again = match cdr::decode::<T>(&canonical) {
            Ok(d) => d,
            Err(e) => panic!("{}: canonical {encoding:?} form does not decode: {e}", T::DDS_TYPE_NAME),
        };
        assert_eq!(again.encoding, encoding);
        assert_eq!(
            cdr::encode(&again.value, Encoding::UNITREE),
            reference,
            "{}: value changed through {encoding:?}",
            T::DDS_TYPE_NAME
        );
        assert_eq!(cdr::encode(&again.value, encoding), canonical, "{}: {encoding:?} not stable", T::DDS_TYPE_NAME);
    }
}

/// `crc`: the table-driven CRC equals the bit-serial reference.
pub fn crc_fast_equals_reference(bytes: &[u8]) {
    assert_eq!(crc::crc32_words(bytes), crc::crc32_reference(bytes), "CRC mismatch on {} bytes", bytes.len());
}

/// `roundtrip`: a structured value survives encode then decode in every encoding, bit for bit,
/// and sealing makes it verify.
pub fn roundtrip<T: IdlStruct>(value: &T) {
    let reference = cdr::encode(value, Encoding::UNITREE);
    for encoding in ENCODINGS {
        let bytes = cdr::encode(value, encoding);
        match cdr::decode::<T>(&bytes) {
            Ok(d) => {
                assert_eq!(cdr::encode(&d.value, Encoding::UNITREE), reference, "{}: {encoding:?}", T::DDS_TYPE_NAME)
            }
            Err(e) => panic!("{}: own {encoding:?} encoding does not decode: {e}", T::DDS_TYPE_NAME),
        }
    }
}

/// `roundtrip` on raw fuzz bytes: the bytes choose a message type and its value through
/// `arbitrary`, so saved inputs replay identically from `cargo test`.
#[cfg(feature = "arbitrary")]
pub fn roundtrip_bytes(data: &[u8]) {
    use arbitrary::{Arbitrary, Unstructured};
    use unitree_idl::{api, go, hg};

    // Built once per fuzz input and matched immediately: boxing the big variants buys nothing.
    #[allow(clippy::large_enum_variant)]
    #[derive(Debug, Arbitrary)]
    enum Message {
        HgLowCmd(hg::LowCmd_),
        HgLowState(hg::LowState_),
        HgHandCmd(hg::HandCmd_),
        HgHandState(hg::HandState_),
        HgBmsState(hg::BmsState_),
        GoLowCmd(go::LowCmd_),
        GoLowState(go::LowState_),
        ApiRequest(api::Request_),
        ApiResponse(api::Response_),
    }

    let Ok(message) = Message::arbitrary_take_rest(Unstructured::new(data)) else { return };
    match &message {
        Message::HgLowCmd(v) => roundtrip(v),
        Message::HgLowState(v) => roundtrip(v),
        Message::HgHandCmd(v) => roundtrip(v),
        Message::HgHandState(v) => roundtrip(v),
        Message::HgBmsState(v) => roundtrip(v),
        Message::GoLowCmd(v) => roundtrip(v),
        Message::GoLowState(v) => roundtrip(v),
        Message::ApiRequest(v) => roundtrip(v),
        Message::ApiResponse(v) => roundtrip(v),
    }
}
