//! The integration tests of `dds-transport`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p dds-transport --test it -- MODULE::`.

mod c010_controls;
mod c010_interop;
mod common;
mod loopback;
mod py11_interop;
