//! The table-driven CRC equals the bit-serial reference on any image.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lowlevel_codec::fuzzing::crc_fast_equals_reference(data));
