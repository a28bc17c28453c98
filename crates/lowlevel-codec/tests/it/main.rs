//! The integration tests of `lowlevel-codec`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p lowlevel-codec --test it -- MODULE::`.

mod fuzz_regressions;
mod golden;
mod malformed;
mod malformed_json;
mod properties;
mod view;
