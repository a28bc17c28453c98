//! The integration tests of `diff-physics`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p diff-physics --test it -- MODULE::`.

mod base_wrench;
mod bullet_engine;
mod dart_engine;
mod mujoco_oracles;
mod newton_engine;
mod physx_engine;
mod rapier_engines;
mod unitree_reference;
