//! Helpers shared by the gap-diagnosis integration tests.
#![allow(dead_code)]

use robot_model::RobotModel;
use std::path::PathBuf;

/// The built-in H1-2.
pub fn model() -> RobotModel {
    robot_model::builtin("h1_2").expect("built-in model")
}

/// The workspace root.
pub fn workspace() -> PathBuf {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    p.canonicalize().unwrap_or(p)
}

/// The project's Python (the venv with MuJoCo's and `mcap`'s official bindings), from `$ULAB_PYTHON` or `.venv`.
pub fn python() -> PathBuf {
    std::env::var_os("ULAB_PYTHON").map_or_else(|| workspace().join(".venv/bin/python"), PathBuf::from)
}
