//! Any bytes into every message type: no panic; whatever decodes re-encodes to a canonical form
//! that decodes to the same value (see `lowlevel_codec::fuzzing::decode_any`).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lowlevel_codec::fuzzing::decode_any(data));
