//! Wire codec for Unitree SDK2 messages (low-level and RPC), written once against the reflection in
//! [`unitree_idl`]:
//!
//! * [`cdr`]: CDR encode/decode, XCDR1 and XCDR2 (plain, for `@final` types), little- and
//!   big-endian, with the 4-byte encapsulation header. Decoding never panics and never
//!   allocates in proportion to a length read from the input.
//! * [`crc`]: Unitree's CRC over the C struct image (padding zeroed), a fast table-driven
//!   implementation and the bit-serial reference; [`crc::seal`] and [`crc::verify`].
//! * `json` (feature `json`): the JSON document form used by `ulab codec` (exact float round trip); it turns on
//!   `serde_json`'s `arbitrary_precision` so that decimals parse straight to `f32`, hence opt-in. [`text`]: the
//!   float text it prints, always available.
//! * [`view`](mod@view): zero-copy views of fixed-layout samples (hg/go `LowCmd`, `LowState`, ...):
//!   the same validation as [`decode`] at the cost of a length check, then typed accessors
//!   named after the IDL members that read on demand.
//! * [`validate`]: semantic checks kept apart from decoding (non-finite values, limits, unused
//!   slots), each finding typed and named.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod cdr;
pub mod crc;
pub mod fuzzing;
#[cfg(feature = "json")]
pub mod json;
pub mod text;
pub mod validate;
pub mod view;

pub use cdr::{decode, encode, DecodeError, Decoded, Encoding, Endianness, Representation, StringFault};
pub use crc::{seal, verify, Checksummed};
pub use view::{view, MessageView, Viewable};

// The README's example is compiled (and, where it needs no network, run) as a doctest.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
