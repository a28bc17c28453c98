//! `ulab model` end to end (needs the MuJoCo library: `source scripts/env.sh`).
use std::process::Command;

fn ulab(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_ulab")).args(args).output().expect("run ulab");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

fn json(s: &str) -> serde_json::Value {
    serde_json::from_str(s).expect("valid JSON")
}

/// `ulab model inspect` of `engine` at the seeded random pose used by every mass-matrix test, plus `extra` flags.
fn inspect(engine: &str, extra: &[&str]) -> serde_json::Value {
    let args =
        [&["model", "inspect", "--robot", "h1_2", "--engine", engine, "--q", "random:5", "--format", "json"], extra]
            .concat();
    let (code, out, err) = ulab(&args);
    assert_eq!(code, 0, "{engine}: {err}");
    json(&out)
}

/// The mass matrix of an inspect report, row-major.
fn mass_matrix(v: &serde_json::Value) -> Vec<f64> {
    v["mass_matrix"]
        .as_array()
        .expect("rows")
        .iter()
        .flat_map(|r| r.as_array().expect("row").iter().map(|x| x.as_f64().expect("f64")))
        .collect()
}

/// ‖a − b‖ / ‖b‖ (Frobenius): how far an engine's mass matrix is from the reference's.
fn relative_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let norm = b.iter().map(|x| x * x).sum::<f64>().sqrt();
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt() / norm
}

#[test]
fn check_mujoco_passes_and_reports_errors_and_tolerances() {
    let (code, out, err) =
        ulab(&["model", "check", "--robot", "h1_2", "--engine", "mujoco", "--format", "json", "--samples", "2"]);
    assert_eq!(code, 0, "{out}\n{err}");
    let r = json(&out);
    assert_eq!(r["engines"][0]["name"], "mujoco");
    assert_eq!(r["engines"][0]["settings"]["mujoco"]["integrator"], "implicitfast");
    let checks = r["checks"].as_array().expect("checks");
    assert!(checks.len() > 20);
    for c in checks {
        assert!(c["error"].is_number() && c["tolerance"].is_number(), "{c}");
        assert_eq!(c["passed"], true, "{c}");
    }
}

#[test]
fn check_dart_passes_and_reports_its_settings() {
    let (code, out, err) =
        ulab(&["model", "check", "--robot", "h1_2", "--engine", "dart", "--format", "json", "--samples", "2"]);
    assert_eq!(code, 0, "{out}\n{err}");
    let r = json(&out);
    assert_eq!(r["engines"][0]["name"], "dart");
    assert_eq!(r["engines"][0]["settings"]["dart"]["collision_detector"], "ode");
    assert_eq!(r["engines"][0]["settings"]["dart"]["lcp_solver"], "dantzig");
    let checks = r["checks"].as_array().expect("checks");
    assert!(checks.len() > 20);
    for c in checks {
        assert_eq!(c["passed"], true, "{c}");
    }
}

#[test]
fn inspect_dart_equals_the_reference_mass_matrix() {
    let (ma, mb) = (mass_matrix(&inspect("dart", &[])), mass_matrix(&inspect("reference", &[])));
    assert_eq!(ma.len(), 33 * 33);
    let d = relative_difference(&ma, &mb);
    assert!(d < 1e-9, "DART vs reference mass matrix: {d}");
}

#[test]
fn inspect_mujoco_equals_the_reference_mass_matrix() {
    let (a, b) = (inspect("mujoco", &[]), inspect("reference", &[]));
    for v in [&a, &b] {
        assert_eq!(v["nq"], 34);
        assert_eq!(v["nv"], 33);
        // Sum of the 28 body masses in Unitree's published MJCF.
        assert!((v["total_mass"].as_f64().expect("mass") - 66.984).abs() < 1e-9);
        assert_eq!(v["mass_matrix"].as_array().expect("rows").len(), 33);
    }
    let (ma, mb) = (mass_matrix(&a), mass_matrix(&b));
    let d = relative_difference(&ma, &mb);
    assert!(d < 1e-9, "MuJoCo vs reference mass matrix: {d}");
    for i in 0..33 {
        for j in 0..33 {
            assert!((ma[i * 33 + j] - ma[j * 33 + i]).abs() < 1e-12);
        }
    }
    let com_a: Vec<f64> = a["com"].as_array().expect("com").iter().map(|x| x.as_f64().expect("f")).collect();
    let com_b: Vec<f64> = b["com"].as_array().expect("com").iter().map(|x| x.as_f64().expect("f")).collect();
    assert!(com_a.iter().zip(&com_b).all(|(x, y)| (x - y).abs() < 1e-9));
}

#[test]
fn bad_arguments_are_errors() {
    let (code, _, err) = ulab(&["model", "inspect", "--robot", "h1_2", "--engine", "mujoco", "--q", "bogus"]);
    assert_eq!(code, 2);
    assert!(err.contains("random:SEED"), "{err}");
    let (code, _, err) = ulab(&["model", "inspect", "--robot", "nope", "--engine", "mujoco"]);
    assert_eq!(code, 2, "{err}");
    let (code, _, err) = ulab(&["model", "check", "--engine", "bogus"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("unknown engine"), "{err}");
}

/// Bullet through the CLI: every oracle passes or is a known difference (armature, which Bullet lacks), and its
/// mass matrix without armature (from Bullet's own articulated-body accelerations) equals the reference's.
#[test]
fn bullet_checks_and_inspects_like_the_reference() {
    let (code, out, err) =
        ulab(&["model", "check", "--robot", "h1_2", "--engine", "bullet", "--format", "json", "--samples", "2"]);
    assert_eq!(code, 0, "{out}\n{err}");
    let r = json(&out);
    assert_eq!(r["engines"][0]["name"], "bullet");
    assert_eq!(r["engines"][0]["settings"]["bullet"]["two_friction_directions"], true);
    for c in r["checks"].as_array().expect("checks") {
        assert!(c["passed"] == true || c["known_difference"].is_string(), "{c}");
    }
    let no_armature = ["--armature", "false"];
    let (ma, mb) = (mass_matrix(&inspect("bullet", &no_armature)), mass_matrix(&inspect("reference", &no_armature)));
    assert_eq!(ma.len(), 33 * 33);
    let d = relative_difference(&ma, &mb);
    // Same tolerance as the oracle's analytic route (M rebuilt from accelerations: one extra inversion).
    assert!(d < 1e-8, "Bullet vs reference mass matrix: {d}");
}

/// Issue 15: `ulab model check` passes on PhysX (f32 tolerances), and `ulab model inspect` shows PhysX's own
/// mass matrix (built from its dense Jacobian) equal to the reference's within f32 rounding.
// PhysX is opt-in (`--features physx`, `scripts/nightly.sh`): its SDK build does not fit the CI budget.
#[cfg(feature = "physx")]
#[test]
fn check_and_inspect_physx() {
    let (code, out, err) =
        ulab(&["model", "check", "--robot", "h1_2", "--engine", "physx", "--format", "json", "--samples", "2"]);
    assert_eq!(code, 0, "{out}\n{err}");
    let r = json(&out);
    assert_eq!(r["engines"][0]["name"], "physx");
    assert_eq!(r["engines"][0]["settings"]["specific"]["solver"], "tgs");
    let checks = r["checks"].as_array().expect("checks");
    assert!(checks.iter().any(|c| c["name"] == "PhysX mass matrix, base free"), "PhysX's own checks missing");
    for c in checks {
        assert!(c["passed"] == true || c["known_difference"].is_string(), "{c}");
    }
    let d = relative_difference(&mass_matrix(&inspect("physx", &[])), &mass_matrix(&inspect("reference", &[])));
    // f32 Jacobian and inertias: <= ~8e-6 relative (derivation in diff_physics::physx::f32_tolerance).
    assert!(d < 5e-5, "PhysX vs reference mass matrix: {d}");
}

/// Issue 61: `ulab model check` on Newton's Featherstone and Steel (f32 tolerances): every check passes or is one of
/// the solver's documented known differences, and each engine lists those differences in its settings. The
/// independent counterparts are robot-model's f64 reference and MuJoCo (the cross-engine step).
// Newton is opt-in (`--features newton`, `scripts/setup.sh --newton`, `scripts/nightly.sh`): Warp's CPU kernels take
// 30–70 s per solver to compile on a cold cache.
#[cfg(feature = "newton")]
#[test]
fn check_newton_solvers() {
    let args = ["model", "check", "--robot", "h1_2", "--format", "json", "--samples", "2", "--engine", "mujoco"];
    let args = [&args[..], &["--engine", "newton-featherstone", "--engine", "newton-steel"]].concat();
    let (code, out, err) = ulab(&args);
    assert_eq!(code, 0, "{out}\n{err}");
    let r = json(&out);
    let engines = r["engines"].as_array().expect("engines");
    let names: Vec<&str> = engines.iter().filter_map(|e| e["name"].as_str()).collect();
    assert_eq!(names, ["mujoco", "newton_featherstone", "newton_steel"]);
    for e in &engines[1..] {
        let listed = e["settings"]["known_differences"].as_array().expect("known differences listed");
        assert!(listed.iter().any(|d| d.as_str().is_some_and(|d| d.contains("f32"))), "{e}");
        assert!(listed.iter().any(|d| d.as_str().is_some_and(|d| d.contains("dry friction"))), "{e}");
        assert!(e["settings"]["normalisations"].as_array().is_some_and(|n| !n.is_empty()), "{e}");
    }
    let checks = r["checks"].as_array().expect("checks");
    for name in ["newton_featherstone", "newton_steel"] {
        let own = checks.iter().filter(|c| c["engine"] == name).count();
        assert!(own >= 20, "{name}: {own} checks");
        assert!(checks.iter().any(|c| c["engine"] == format!("mujoco vs {name}")), "{name}: no step against MuJoCo");
    }
    for c in checks {
        assert!(c["passed"] == true || c["known_difference"].is_string(), "{c}");
        // Featherstone has no known difference an oracle trips over; Steel only its free-flight dissipation.
        if c["passed"] == false {
            assert_eq!(c["engine"], "newton_steel", "{c}");
            assert!(c["name"].as_str().is_some_and(|n| n.contains("zero g")), "{c}");
        }
    }
}
