//! The integration tests of `gap-diagnosis`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p gap-diagnosis --test it -- MODULE::`.

mod common;
mod compressed_logs;
mod python_plant;
