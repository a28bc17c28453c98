//! `engine-diff`: Differential testing of physics engines: rollouts, divergence metrics, fuzzing, triage and reports (issue 5).
#![forbid(unsafe_code)]
