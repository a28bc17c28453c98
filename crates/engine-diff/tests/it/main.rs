//! The integration tests of `engine-diff`, one module per topic, built as one test binary: each test binary
//! links every dependency again (the physics engines among them), and one binary links them once.
//! One topic: `cargo test -p engine-diff --test it -- MODULE::`.

/// The `Engine` methods a test's wrapper engine passes through unchanged to its inner engine `self.$inner`: the
/// wrappers (`harness::Offset`, `planted_bug::Planted`, `engine_failure::Diverging`) write only what they change.
macro_rules! delegate_engine {
    ($inner:tt) => {
        fn common(&self) -> &diff_physics::CommonSettings {
            self.$inner.common()
        }
        fn reset(&mut self, s: &diff_physics::State) -> Result<(), diff_physics::EngineError> {
            self.$inner.reset(s)
        }
        fn time(&self) -> f64 {
            self.$inner.time()
        }
        fn contacts(&self) -> Vec<diff_physics::Contact> {
            self.$inner.contacts()
        }
        fn energy(&mut self) -> diff_physics::Energy {
            self.$inner.energy()
        }
        fn link_masses(&self) -> Vec<f64> {
            self.$inner.link_masses()
        }
        fn link_poses(&mut self) -> Vec<diff_physics::LinkPose> {
            self.$inner.link_poses()
        }
        fn com(&mut self) -> [f64; 3] {
            self.$inner.com()
        }
        fn joint_axes(&mut self) -> Vec<[f64; 3]> {
            self.$inner.joint_axes()
        }
        fn joint_limits(&self) -> Vec<(f64, f64)> {
            self.$inner.joint_limits()
        }
        fn generalized_acceleration(&mut self, f: &[f64]) -> Result<Vec<f64>, diff_physics::EngineError> {
            self.$inner.generalized_acceleration(f)
        }
    };
}

mod allowlist_evidence;
mod campaign_triage;
mod determinism;
mod engine_failure;
mod fuzz_regressions;
mod harness;
mod planted_bug;
mod planted_cheat;
mod report_snapshot;
mod validate_verdict;
