//! Any bytes into every message type: no panic; whatever decodes re-encodes to a canonical form
//! that decodes to the same value; and every type with a zero-copy view is also viewed: `view`
//! fails iff `decode` fails, with the same error, and its `to_owned` equals the decoded value
//! (see `lowlevel_codec::fuzzing::decode_any` and `view_agrees_with_decode`).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lowlevel_codec::fuzzing::decode_any(data));
