//! The integration tests of `sim-bridge`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p sim-bridge --test it -- MODULE::`.

mod bridge;
mod loco;
mod suspension;
