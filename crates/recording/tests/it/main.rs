//! The integration tests of `recording`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p recording --test it -- MODULE::`.

mod official_writer;
