//! The integration tests of `robot-model`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p robot-model --test it -- MODULE::`.

mod h1_2;
mod malformed;
