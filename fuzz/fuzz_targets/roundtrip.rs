//! Structured values (type and contents chosen by `arbitrary`) round-trip in every
//! representation and endianness; see `lowlevel_codec::fuzzing::roundtrip_bytes`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lowlevel_codec::fuzzing::roundtrip_bytes(data));
