//! Unitree SDK2 message types, exactly as Unitree's C++ SDK headers declare them.
//!
//! * [`hg`]: `unitree_hg` (H1-2, G1) and [`go`]: `unitree_go` (Go2, H1, B2): low-level control.
//! * [`api`]: `unitree_api`, the request/response of the SDK's RPC (high-level clients such as `LocoClient`),
//!   with the service names, API versions, API ids and status codes of Unitree's headers.
//! * Every struct implements [`IdlStruct`], a small reflection interface that walks its members
//!   in declaration order. The wire codec, the CRC image, JSON and validation are all written once
//!   against it (in `lowlevel-codec`), so member order and types live in exactly one place: here.
//! * [`MessageType`] names every type as the CLI and reports spell it (`hg/LowCmd`) and as DDS
//!   spells it (`unitree_hg::msg::dds_::LowCmd_`).
//! * [`h1_2`] is the H1-2 motor-slot map with per-joint limits.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod macros;
pub mod reflect;

pub mod api;
pub mod go;
pub mod h1_2;
pub mod hg;
mod registry;
pub mod topics;

pub use reflect::{align_up, Element, Field, IdlStruct, PrimKind, Primitive, Visitor, VisitorMut};
pub use registry::{MessageType, UnknownMessageType};

// The README's example is compiled (and, where it needs no network, run) as a doctest.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
