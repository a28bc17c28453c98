//! The integration tests of `robot-render`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p robot-render --test it -- MODULE::`.

mod standing_frame;
mod video_clip;
