//! Oracles: model equivalence, contact-free dynamics, one step with contacts and per-engine invariants.
//!
//! Every check reports its measured error and its tolerance; tolerances are derived in the comments next to
//! them from the arithmetic involved, never from what an engine happened to produce. The in-house reference is
//! `robot-model`'s forward kinematics and RNEA/CRBA (f64, nalgebra), an implementation independent of every
//! engine.
use crate::engine::*;
use crate::pd::{pd_torques, PdTarget};
use nalgebra::{DMatrix, DVector, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robot_model::{GenCoords, RobotModel};
use serde::Serialize;

#[cfg(feature = "physx")]
mod physx_native;

/// One measured check.
#[derive(Debug, Clone, Serialize)]
pub struct CheckResult {
    /// Group: `model`, `dynamics`, `contact`, `invariant`.
    pub group: String,
    pub name: String,
    /// Engine under test (or `a vs b` for cross-engine checks).
    pub engine: String,
    pub error: f64,
    pub tolerance: f64,
    pub unit: String,
    pub passed: bool,
    /// Set when a failure is a documented engine limitation (reported, not counted as a failure).
    pub known_difference: Option<String>,
    pub note: String,
}

/// Engines' identities and settings, written into every report.
#[derive(Debug, Clone, Serialize)]
pub struct EngineInfo {
    pub name: String,
    pub version: String,
    pub settings: serde_json::Value,
}

/// A full check report.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub robot: String,
    pub reference: String,
    pub seed: u64,
    pub engines: Vec<EngineInfo>,
    pub unavailable: Vec<String>,
    pub checks: Vec<CheckResult>,
}

impl Report {
    /// True when every check passed or is a documented known difference.
    pub fn passed(&self) -> bool {
        self.checks.iter().all(|c| c.passed || c.known_difference.is_some())
    }
    /// Plain-text table.
    pub fn table(&self) -> String {
        let mut s = format!("robot {}  reference: {}  seed {}\n", self.robot, self.reference, self.seed);
        for e in &self.engines {
            s += &format!("engine {}: {}\n  settings: {}\n", e.name, e.version, e.settings);
            // Engines that list what they do differently (Newton's solvers) get it on lines of its own.
            for d in e.settings.get("known_differences").and_then(|v| v.as_array()).into_iter().flatten() {
                if let Some(d) = d.as_str() {
                    s += &format!("  known difference: {d}\n");
                }
            }
        }
        for u in &self.unavailable {
            s += &format!("engine {u}: not available in this build\n");
        }
        s += &format!(
            "{:<10} {:<44} {:<18} {:>12} {:>12} {:<8} {}\n",
            "group", "check", "engine", "error", "tolerance", "unit", "result"
        );
        for c in &self.checks {
            let res = if c.passed {
                "ok".to_string()
            } else if let Some(k) = &c.known_difference {
                format!("KNOWN: {k}")
            } else {
                "FAIL".to_string()
            };
            s += &format!(
                "{:<10} {:<44} {:<18} {:>12.3e} {:>12.3e} {:<8} {}\n",
                c.group, c.name, c.engine, c.error, c.tolerance, c.unit, res
            );
        }
        let failed = self.checks.iter().filter(|c| !c.passed && c.known_difference.is_none()).count();
        s += &format!(
            "{} checks, {} failed, {} known differences\n",
            self.checks.len(),
            failed,
            self.checks.iter().filter(|c| !c.passed && c.known_difference.is_some()).count()
        );
        s
    }
}

/// What to run.
#[derive(Debug, Clone)]
pub struct CheckOptions {
    pub seed: u64,
    /// Random configurations for FK and dynamics checks.
    pub samples: usize,
    pub timestep: f64,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions { seed: 1, samples: 5, timestep: 0.002 }
    }
}

/// Known engine limitations: (engine, check name) -> reason. A failing check listed here is reported as a
/// known difference with its measured figure instead of failing the run.
pub fn known_difference(engine: &str, check: &str) -> Option<&'static str> {
    // Rapier impulse-joint engine: reasons and measured figures live next to the engine (rapier_impulse.rs).
    #[cfg(feature = "rapier")]
    if engine == "rapier_impulse" {
        return crate::rapier_impulse::known_difference(check);
    }
    #[cfg(feature = "bullet")]
    if engine == "bullet" {
        return crate::bullet::known_difference(check);
    }
    #[cfg(feature = "dart")]
    if engine == "dart" {
        return crate::dart::known_difference(check);
    }
    // PhysX (f32): reasons and measured figures live next to the engine (physx/mod.rs).
    #[cfg(feature = "physx")]
    if engine == "physx" {
        return crate::physx::known_difference(check);
    }
    #[cfg(feature = "newton")]
    if engine.starts_with("newton_") {
        return crate::newton::known_difference(engine, check);
    }
    let _ = (engine, check);
    None
}

/// The tolerance of a check for an engine: the stated one (derived for f64 arithmetic) unless the engine computes
/// in lower precision, whose own derivation then applies (PhysX: f32, see `physx::f32_tolerance`).
pub fn precision_tolerance(engine: &str, check: &str, tolerance: f64) -> f64 {
    #[cfg(feature = "physx")]
    if engine == "physx" {
        return crate::physx::f32_tolerance(check, tolerance).unwrap_or(tolerance);
    }
    // Newton (f32 Warp state): derivations next to the engine (newton/mod.rs).
    #[cfg(feature = "newton")]
    if engine.starts_with("newton_") {
        return crate::newton::f32_tolerance(check, tolerance).unwrap_or(tolerance);
    }
    let _ = (engine, check);
    tolerance
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn push(
    out: &mut Vec<CheckResult>,
    group: &str,
    name: &str,
    engine: &str,
    error: f64,
    tolerance: f64,
    unit: &str,
    note: &str,
) {
    let tolerance = precision_tolerance(engine, name, tolerance);
    let passed = error.is_finite() && error <= tolerance;
    let known = if passed { None } else { known_difference(engine, name).map(str::to_string) };
    out.push(CheckResult {
        group: group.into(),
        name: name.into(),
        engine: engine.into(),
        error,
        tolerance,
        unit: unit.into(),
        passed,
        known_difference: known,
        note: note.into(),
    });
}

/// A random configuration: joints uniform inside their ranges, base anywhere in a 2 m box at 1..2 m height
/// with a uniformly random orientation.
pub fn random_coords(model: &RobotModel, rng: &mut impl Rng) -> GenCoords {
    let q = model.joints.iter().map(|j| rng.gen_range(j.lower..j.upper)).collect();
    let base_pos = [rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(1.0..2.0)];
    // Uniform random rotation (Shoemake).
    let (u1, u2, u3): (f64, f64, f64) = (rng.gen(), rng.gen(), rng.gen());
    let tau = std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let quat = [b * (tau * u3).cos(), a * (tau * u2).sin(), a * (tau * u2).cos(), b * (tau * u3).sin()];
    GenCoords { base_pos, base_quat: quat, q }
}

/// A random state: random configuration, base velocity in ±1 m/s and ±1 rad/s, joint velocities in ±2 rad/s.
pub fn random_state(model: &RobotModel, rng: &mut impl Rng) -> State {
    let c = random_coords(model, rng);
    let mut s = State::at_rest(c);
    for k in 0..3 {
        s.base_lin_vel[k] = rng.gen_range(-1.0..1.0);
        s.base_ang_vel[k] = rng.gen_range(-1.0..1.0);
    }
    s.dq = (0..model.nj()).map(|_| rng.gen_range(-2.0..2.0)).collect();
    s
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    if a.len() != b.len() {
        return f64::INFINITY;
    }
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

fn rel_err(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    if a.shape() != b.shape() {
        return f64::INFINITY;
    }
    (a - b).norm() / b.norm().max(f64::MIN_POSITIVE)
}

/// Mass matrix obtained from an engine's accelerations: columns of M⁻¹ are a(e_i) − a(0) for unit generalized
/// forces e_i (nv + 1 acceleration evaluations), then inverted. Used for every engine so that engines exposing
/// no mass matrix are checked the same way; engines that do expose one are additionally compared directly.
pub fn mass_matrix_from_accelerations(e: &mut dyn Engine, nv: usize) -> Result<DMatrix<f64>, EngineError> {
    let zero = vec![0.0; nv];
    let a0 = e.generalized_acceleration(&zero)?;
    let mut minv = DMatrix::zeros(nv, nv);
    let mut f = zero.clone();
    for i in 0..nv {
        f.iter_mut().for_each(|x| *x = 0.0);
        f[i] = 1.0;
        let ai = e.generalized_acceleration(&f)?;
        for r in 0..nv {
            minv[(r, i)] = ai[r] - a0[r];
        }
    }
    let minv = (&minv + minv.transpose()) * 0.5;
    minv.try_inverse().ok_or_else(|| EngineError::Diverged("M⁻¹ from accelerations is singular".into()))
}

fn row_major(v: &[f64], n: usize) -> DMatrix<f64> {
    DMatrix::from_row_slice(n, n, v)
}

/// Runs every check for the given engines.
pub fn run_checks(model: &RobotModel, kinds: &[EngineKind], opts: &CheckOptions) -> Report {
    let mut checks = Vec::new();
    let mut infos = Vec::new();
    let mut unavailable = Vec::new();
    let mut available = Vec::new();
    for &k in kinds {
        let common = CommonSettings { timestep: opts.timestep, ..CommonSettings::default() };
        match crate::make_engine(k, model, &common) {
            Ok(e) => {
                infos.push(EngineInfo { name: e.name().into(), version: e.version(), settings: e.settings() });
                available.push(k);
            }
            Err(EngineError::Unavailable(n)) => unavailable.push(n),
            Err(err) => {
                push(&mut checks, "build", "engine builds", k.name(), f64::INFINITY, 0.0, "-", &err.to_string())
            }
        }
    }
    for &k in &available {
        model_equivalence(model, k, opts, &mut checks);
        dynamics(model, k, opts, &mut checks);
        standing(model, k, opts, &mut checks);
        invariants(model, k, opts, &mut checks);
        // PhysX's own inverse-dynamics API (floating base), against the same reference.
        #[cfg(feature = "physx")]
        if k == EngineKind::Physx {
            physx_native::native_checks(model, opts, &mut checks);
        }
    }
    one_step_cross(model, &available, opts, &mut checks);
    Report {
        robot: model.name.clone(),
        reference: robot_model::RigidBodyDynamics::NAME.into(),
        seed: opts.seed,
        engines: infos,
        unavailable,
        checks,
    }
}

fn build(
    model: &RobotModel,
    k: EngineKind,
    common: &CommonSettings,
    name: &str,
    out: &mut Vec<CheckResult>,
) -> Option<Box<dyn Engine>> {
    match crate::make_engine(k, model, common) {
        Ok(e) => Some(e),
        Err(err) => {
            push(out, "build", name, k.name(), f64::INFINITY, 0.0, "-", &format!("engine build failed: {err}"));
            None
        }
    }
}

/// Model equivalence: masses, COM, FK of every link frame, joint axes and limits.
pub fn model_equivalence(model: &RobotModel, k: EngineKind, opts: &CheckOptions, out: &mut Vec<CheckResult>) {
    let common = CommonSettings { timestep: opts.timestep, ground: false, ..CommonSettings::default() };
    let Some(mut e) = build(model, k, &common, "model equivalence", out) else { return };
    let en = k.name();
    // Masses are copied numbers (shortest round-trip decimal or direct f64): they must be equal up to the
    // rounding of a 28-term sum, ~28 ulp of 70 kg ≈ 4e-13 kg. Tolerance 1e-9 kg.
    let masses = e.link_masses();
    let ref_m: Vec<f64> = model.links.iter().map(|l| l.inertial.mass).collect();
    push(out, "model", "per-link mass", en, max_abs_diff(&masses, &ref_m), 1e-9, "kg", "max over links");
    push(out, "model", "total mass", en, (masses.iter().sum::<f64>() - model.total_mass()).abs(), 1e-9, "kg", "");
    // Limits are copied numbers: exact up to decimal round trip. Tolerance 1e-12 rad.
    let lim = e.joint_limits();
    let ref_l: Vec<f64> = model.joints.iter().flat_map(|j| [j.lower, j.upper]).collect();
    let got_l: Vec<f64> = lim.iter().flat_map(|&(a, b)| [a, b]).collect();
    push(out, "model", "joint limits", en, max_abs_diff(&got_l, &ref_l), 1e-12, "rad", "slot order");

    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let (mut pos_err, mut rot_err, mut com_err, mut axis_err) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for _ in 0..opts.samples {
        let c = random_coords(model, &mut rng);
        if let Err(err) = e.reset(&State::at_rest(c.clone())) {
            push(out, "model", "reset", en, f64::INFINITY, 0.0, "-", &err.to_string());
            return;
        }
        let Ok(fk) = model.fk(&c) else { continue };
        let poses = e.link_poses();
        for (p, r) in poses.iter().zip(&fk.link_poses) {
            let t = r.translation.vector;
            pos_err = pos_err.max((Vector3::from(p.pos) - t).norm());
            rot_err = rot_err.max(quat_angle(p.quat, robot_model::quat_wxyz(&r.rotation)));
        }
        if poses.len() != fk.link_poses.len() {
            pos_err = f64::INFINITY;
        }
        if let Ok(com) = model.com(&c) {
            com_err = com_err.max((Vector3::from(e.com()) - com).norm());
        }
        for (a, r) in e.joint_axes().iter().zip(&fk.joint_axes) {
            // Difference of unit vectors (≈ angle for small angles; acos would only resolve ~1e-8 rad).
            axis_err = axis_err.max((Vector3::from(*a) - r.into_inner()).norm());
        }
    }
    // FK composes ≤ 9 transforms per chain in f64 (unit roundoff 1.1e-16); positions ~1 m, so accumulated
    // rounding is ~1e-14 m. Engines that keep poses in f32 would need ~1e-6. Tolerance 1e-9 m / 1e-9 rad
    // (angle_to of nearly equal quaternions resolves ~1e-8 rad, so orientations use 1e-7 rad).
    push(
        out,
        "model",
        "link-frame FK position",
        en,
        pos_err,
        1e-9,
        "m",
        &format!("{} random configs, all links", opts.samples),
    );
    push(out, "model", "link-frame FK orientation", en, rot_err, 1e-7, "rad", "angle between quaternions");
    push(out, "model", "centre of mass", en, com_err, 1e-9, "m", "");
    push(out, "model", "joint axes (world)", en, axis_err, 1e-9, "-", "|a − a_ref| of unit axes");
}

/// Contact-free dynamics against the RNEA/CRBA reference.
pub fn dynamics(model: &RobotModel, k: EngineKind, opts: &CheckOptions, out: &mut Vec<CheckResult>) {
    let en = k.name();
    let nv = model.nv();
    let g = [0.0, 0.0, -robot_model::GRAVITY_EARTH];
    for armature in [false, true] {
        let common = CommonSettings { timestep: opts.timestep, armature, ..CommonSettings::rigid_body_only() };
        let Some(mut e) = build(model, k, &common, "dynamics", out) else { return };
        let analytic = e
            .settings()
            .get("acceleration_method")
            .and_then(|m| m.as_str())
            .map(|m| m.starts_with("analytic"))
            .unwrap_or(false);
        let mut rng = ChaCha8Rng::seed_from_u64(opts.seed ^ 0xD1);
        let (mut m_direct, mut m_acc, mut b_err, mut a_err) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut have_direct = false;
        let mut have_bias = false;
        for _ in 0..opts.samples {
            let s = random_state(model, &mut rng);
            if e.reset(&s).is_err() {
                m_acc = f64::INFINITY;
                break;
            }
            let c = s.coords();
            let v = s.v();
            let (Ok(m_ref), Ok(b_ref)) = (model.mass_matrix(&c, armature), model.bias_forces(&c, &v, g)) else {
                continue;
            };
            if let Some(m) = e.mass_matrix() {
                have_direct = true;
                m_direct = m_direct.max(rel_err(&row_major(&m, nv), &m_ref));
            }
            if let Some(b) = e.bias_forces() {
                have_bias = true;
                b_err = b_err.max((DVector::from_vec(b) - &b_ref).norm() / b_ref.norm());
            }
            match mass_matrix_from_accelerations(e.as_mut(), nv) {
                Ok(m) => m_acc = m_acc.max(rel_err(&m, &m_ref)),
                Err(_) => m_acc = f64::INFINITY,
            }
            // Random joint torques within half the limits plus a random base wrench.
            let mut f: Vec<f64> = (0..6).map(|_| rng.gen_range(-50.0..50.0)).collect();
            f.extend(model.joints.iter().map(|j| rng.gen_range(-0.5..0.5) * j.torque_limit));
            match (e.generalized_acceleration(&f), model.forward_dynamics(&c, &v, &f, g, armature)) {
                (Ok(a), Ok(a_ref)) => a_err = a_err.max((DVector::from_vec(a) - &a_ref).norm() / a_ref.norm()),
                _ => a_err = f64::INFINITY,
            }
        }
        let tag = if armature { " (with armature)" } else { "" };
        // Analytic routes: M is assembled from the same f64 inertias; its condition number for the H1-2 is
        // ~1e5 (wrist inertias 1e-4 vs base 70 kg), so solving/inverting loses ≤ 5 digits of 16: 1e-9 relative
        // for M and b, 1e-8 for accelerations and for M rebuilt from accelerations (one extra inversion).
        // Finite-difference routes (one semi-implicit step): first-order error ~ dt·|Ṁ|/|M| ≈ 2e-3·(|v|≈2) → 1e-2.
        let (tol_m, tol_a) = if analytic { (1e-8, 1e-8) } else { (1e-2, 1e-2) };
        if have_direct {
            push(
                out,
                "dynamics",
                &format!("mass matrix (engine's own){tag}"),
                en,
                m_direct,
                1e-9,
                "rel",
                "Frobenius, vs RNEA columns",
            );
        }
        push(
            out,
            "dynamics",
            &format!("mass matrix from accelerations{tag}"),
            en,
            m_acc,
            tol_m,
            "rel",
            "M⁻¹ columns = a(e_i) − a(0)",
        );
        if have_bias && !armature {
            push(out, "dynamics", "bias forces C(q,v)v + g", en, b_err, 1e-9, "rel", "");
        }
        push(
            out,
            "dynamics",
            &format!("accelerations under random (q,v,tau){tag}"),
            en,
            a_err,
            tol_a,
            "rel",
            "gravity on, no contact",
        );
    }
}

/// Standing with PD: contacts on the feet only, and quasi-static support equals the weight.
pub fn standing(model: &RobotModel, k: EngineKind, opts: &CheckOptions, out: &mut Vec<CheckResult>) {
    let en = k.name();
    let common = CommonSettings { timestep: opts.timestep, ..CommonSettings::default() };
    let Some(mut e) = build(model, k, &common, "standing", out) else { return };
    let mut pd = PdTarget::hold_standing(model);
    // The robot's RL gains (ankle kp 40) cannot hold a static pose without a policy: the body pivoting on the
    // ankles has a toppling stiffness m g h ≈ 70·9.81·1 ≈ 690 N·m/rad against 2·40 = 80 N·m/rad. This check is
    // about contact forces, not balance control, so it stiffens the ankles to kp 600 / kd 10 (2·600 > 690).
    for (i, j) in model.joints.iter().enumerate() {
        if j.motor_name.contains("ankle") {
            pd.kp[i] = 600.0;
            pd.kd[i] = 10.0;
        }
    }
    if e.reset(&State::standing(model)).is_err() {
        return;
    }
    // Settle 1 s, then average the total normal force over the next 0.5 s.
    let steps = (1.0 / opts.timestep).round() as usize;
    let avg_steps = steps / 2;
    let (mut fsum, mut n, mut non_foot) = (0.0, 0usize, 0usize);
    let mut failed = None;
    for i in 0..steps + avg_steps {
        let s = e.state();
        let tau = pd_torques(model, &pd, &s.q, &s.dq);
        if let Err(err) = e.step(&tau) {
            failed = Some(err.to_string());
            break;
        }
        if i >= steps {
            let cs = e.contacts();
            fsum += cs.iter().map(|c| c.normal_force).sum::<f64>();
            non_foot += cs.iter().filter(|c| !(c.body_a == "ground" && c.body_b.contains("ankle_roll"))).count();
            n += 1;
        }
    }
    let weight = model.total_mass() * robot_model::GRAVITY_EARTH;
    let err = if let Some(f) = failed {
        push(out, "contact", "standing 1.5 s", en, f64::INFINITY, 0.0, "-", &f);
        return;
    } else {
        (fsum / n.max(1) as f64 - weight).abs() / weight
    };
    // Quasi-static: the feet carry the weight. Residual sway under PD moves the COM by millimetres with
    // accelerations ≲ 0.2 m/s², i.e. ≲ 2% of g. Tolerance 2%.
    push(
        out,
        "contact",
        "standing: mean normal force vs weight",
        en,
        err,
        0.02,
        "rel",
        "PD hold of the standing pose, t = 1..1.5 s",
    );
    push(
        out,
        "contact",
        "standing: contacts off the soles",
        en,
        non_foot as f64,
        0.0,
        "count",
        "robot-ground contacts only on *_ankle_roll_link",
    );
    let s = e.state();
    let drop = (s.base_pos[2] - model.standing.base_pos[2]).abs();
    // PD compliance under load: knee/hip torques of ~20-30 N·m against kp 200-300 deflect the joints by ~0.1 rad,
    // lowering the pelvis by 1-2 cm; contact penetration adds ~1 mm. Tolerance 5 cm (a fall is ~0.5 m).
    push(out, "contact", "standing: pelvis height change", en, drop, 0.05, "m", "after 1.5 s");
}

/// One step with contacts from identical reset states, per-quantity divergence across engines.
pub fn one_step_cross(model: &RobotModel, kinds: &[EngineKind], opts: &CheckOptions, out: &mut Vec<CheckResult>) {
    if kinds.len() < 2 {
        return;
    }
    let common = CommonSettings { timestep: opts.timestep, ..CommonSettings::default() };
    let pd = PdTarget::hold_standing(model);
    let start = State::standing(model);
    let tau = pd_torques(model, &pd, &start.q, &start.dq);
    let mut results = Vec::new();
    for &k in kinds {
        let Some(mut e) = build(model, k, &common, "one step", out) else { continue };
        if e.reset(&start).is_ok() && e.step(&tau).is_ok() {
            results.push((k, e.state()));
        }
    }
    let Some((k0, s0)) = results.first().cloned() else { return };
    // Engines may differ in contact acceleration during the step by up to ~2.5 g (soft vs hard contact at
    // touch-down), i.e. Δv ≤ 2.5·9.81·dt and Δx ≤ 2.5·9.81·dt².
    let dt = opts.timestep;
    let (tv, tx) = (2.5 * 9.81 * dt, 2.5 * 9.81 * dt * dt);
    for (k, s) in results.iter().skip(1) {
        let en = format!("{} vs {}", k0.name(), k.name());
        let d = |a: &[f64], b: &[f64]| max_abs_diff(a, b);
        push(
            out,
            "contact",
            "one step: base position",
            &en,
            d(&s.base_pos, &s0.base_pos),
            tx,
            "m",
            "standing reset, PD torques",
        );
        push(out, "contact", "one step: base orientation", &en, quat_angle(s.base_quat, s0.base_quat), tx, "rad", "");
        push(
            out,
            "contact",
            "one step: joint angles",
            &en,
            d(&s.q, &s0.q),
            tx * 10.0,
            "rad",
            "joint accel. ≲ 25 g/m lever",
        );
        push(
            out,
            "contact",
            "one step: base linear velocity",
            &en,
            d(&s.base_lin_vel, &s0.base_lin_vel),
            tv,
            "m/s",
            "",
        );
        push(
            out,
            "contact",
            "one step: base angular velocity",
            &en,
            d(&s.base_ang_vel, &s0.base_ang_vel),
            tv * 10.0,
            "rad/s",
            "",
        );
        push(out, "contact", "one step: joint velocities", &en, d(&s.dq, &s0.dq), tv * 10.0, "rad/s", "");
    }
}

/// Per-engine invariants: energy at reset vs reference, energy drift in free flight, momentum in zero gravity,
/// timestep refinement.
pub fn invariants(model: &RobotModel, k: EngineKind, opts: &CheckOptions, out: &mut Vec<CheckResult>) {
    let en = k.name();
    let g = [0.0, 0.0, -robot_model::GRAVITY_EARTH];
    let zero_tau = vec![0.0; model.nj()];
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed ^ 0xE7);
    // A free-flight state: standing configuration lifted 1 m, moderate velocities.
    let mut s0 = State::standing(model);
    s0.base_pos[2] += 1.0;
    for i in 0..3 {
        s0.base_lin_vel[i] = rng.gen_range(-0.5..0.5);
        s0.base_ang_vel[i] = rng.gen_range(-0.5..0.5);
    }
    s0.dq = (0..model.nj()).map(|_| rng.gen_range(-1.0..1.0)).collect();

    // Energy at reset vs the reference (½vᵀMv with armature, −m g·com).
    let common = CommonSettings { timestep: opts.timestep, armature: true, ..CommonSettings::rigid_body_only() };
    if let Some(mut e) = build(model, k, &common, "energy", out) {
        if e.reset(&s0).is_ok() {
            let en0 = e.energy();
            let c = s0.coords();
            let v = s0.v();
            if let (Ok(ke), Ok(pe)) = (model.kinetic_energy(&c, &v, true), model.potential_energy(&c, g)) {
                // Same quadratic form evaluated in f64: relative 1e-9.
                push(
                    out,
                    "invariant",
                    "kinetic energy at reset",
                    en,
                    (en0.kinetic - ke).abs() / ke,
                    1e-9,
                    "rel",
                    "½ vᵀ(M + armature)v",
                );
                push(
                    out,
                    "invariant",
                    "potential energy at reset",
                    en,
                    (en0.potential - pe).abs() / pe.abs(),
                    1e-9,
                    "rel",
                    "−m g·com",
                );
            }
        }
    }
    // Energy drift over 1 s of free flight with zero torque and no damping, (a) in zero gravity, where the
    // kinetic energy alone is conserved, relative to KE0; (b) under gravity, relative to the largest kinetic
    // energy reached (the fall dominates). A first-order integrator's energy error grows ~ dt·t·|power| :
    // (a) internal power exchange ~ KE0·|ω| with |ω| ≲ 2 rad/s → ~ 2e-3·2 ≈ 4e-3 of KE0 per second;
    // (b) free fall alone gives m g² dt t / 2 ≈ 6.7 J of ~3.2 kJ ≈ 2e-3. Tolerance 1% for both.
    for (label, gravity) in [("zero g", [0.0; 3]), ("gravity", g)] {
        let common =
            CommonSettings { timestep: opts.timestep, gravity, armature: true, ..CommonSettings::rigid_body_only() };
        let Some(mut e) = build(model, k, &common, "energy drift", out) else { continue };
        if e.reset(&s0).is_err() {
            continue;
        }
        let en0 = e.energy();
        let e_start = en0.total();
        let (mut worst, mut ke_max) = (0.0f64, en0.kinetic);
        let steps = (1.0 / opts.timestep).round() as usize;
        for _ in 0..steps {
            if e.step(&zero_tau).is_err() {
                worst = f64::INFINITY;
                break;
            }
            let en = e.energy();
            ke_max = ke_max.max(en.kinetic);
            worst = worst.max((en.total() - e_start).abs());
        }
        let scale = if label == "zero g" { en0.kinetic } else { ke_max };
        push(
            out,
            "invariant",
            &format!("energy drift, free flight 1 s, {label}"),
            en,
            worst / scale,
            0.01,
            if label == "zero g" { "rel KE0" } else { "rel KEmax" },
            "τ = 0, no damping",
        );
    }

    // Momentum in zero gravity: linear momentum exactly conserved by the continuous dynamics; the discrete
    // error comes from evaluating M at q_n vs q_{n+1}: O(dt²) per step, O(dt) over 1 s → ~|Ṁ|dt ~ 1e-3 relative.
    let common = CommonSettings { timestep: opts.timestep, gravity: [0.0; 3], ..CommonSettings::rigid_body_only() };
    if let Some(mut e) = build(model, k, &common, "momentum", out) {
        if e.reset(&s0).is_ok() {
            let mom = |s: &State| model.momentum(&s.coords(), &s.v()).ok();
            if let Some((l0, p0)) = mom(&s0) {
                let (mut dl, mut dp) = (0.0f64, 0.0f64);
                let steps = (1.0 / opts.timestep).round() as usize;
                for _ in 0..steps {
                    if e.step(&zero_tau).is_err() {
                        dl = f64::INFINITY;
                        break;
                    }
                    if let Some((l, p)) = mom(&e.state()) {
                        dl = dl.max((Vector3::from(l) - Vector3::from(l0)).norm());
                        dp = dp.max((Vector3::from(p) - Vector3::from(p0)).norm());
                    }
                }
                let (nl, np) = (Vector3::from(l0).norm(), Vector3::from(p0).norm());
                push(
                    out,
                    "invariant",
                    "linear momentum drift, zero g 1 s",
                    en,
                    dp / np,
                    5e-3,
                    "rel",
                    "momentum from engine state via reference",
                );
                push(
                    out,
                    "invariant",
                    "angular momentum drift, zero g 1 s",
                    en,
                    dl / nl,
                    5e-3,
                    "rel",
                    "about the world origin",
                );
            }
        }
    }

    // Timestep refinement: 0.2 s of free flight under gravity at dt, dt/2, dt/4. For a first-order method the
    // error against dt/4 shrinks by (dt − dt/4)/(dt/2 − dt/4) = 3 when halving; we require ≥ 1.8 (first order
    // with a margin for the higher-order terms) and an absolute difference below 1e-2 (joint rad) at dt.
    let horizon = 0.2;
    let mut finals = Vec::new();
    for div in [1.0, 2.0, 4.0] {
        let dt = opts.timestep / div;
        let common = CommonSettings { timestep: dt, ..CommonSettings::rigid_body_only() };
        let Some(mut e) = build(model, k, &common, "timestep refinement", out) else { return };
        if e.reset(&s0).is_err() {
            return;
        }
        let steps = (horizon / dt).round() as usize;
        let mut ok = true;
        for _ in 0..steps {
            if e.step(&zero_tau).is_err() {
                ok = false;
                break;
            }
        }
        if !ok {
            push(out, "invariant", "timestep refinement", en, f64::INFINITY, 0.0, "-", "diverged");
            return;
        }
        finals.push(e.state().q);
    }
    let e1 = max_abs_diff(&finals[0], &finals[2]);
    let e2 = max_abs_diff(&finals[1], &finals[2]);
    push(out, "invariant", "timestep refinement: |q(dt) − q(dt/4)|", en, e1, 1e-2, "rad", "0.2 s free flight");
    let ratio = if e2 > 0.0 { e1 / e2 } else { f64::INFINITY };
    // Reported as "1/ratio" so that smaller is better like every other row: pass when ratio ≥ 1.8.
    push(
        out,
        "invariant",
        "timestep refinement: convergence 1/ratio",
        en,
        1.0 / ratio,
        1.0 / 1.8,
        "-",
        &format!("ratio {ratio:.2}, first order → 3"),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An engine's listed known differences get a table line each; an engine without the list gets none.
    #[test]
    fn table_lists_each_known_difference_of_an_engine() {
        let engine =
            |name: &str, settings: serde_json::Value| EngineInfo { name: name.into(), version: "v".into(), settings };
        let report = Report {
            robot: "r".into(),
            reference: "ref".into(),
            seed: 1,
            engines: vec![
                engine("a", serde_json::json!({ "known_differences": ["first one", "second one"] })),
                engine("b", serde_json::json!({ "solver": "x" })),
            ],
            unavailable: Vec::new(),
            checks: Vec::new(),
        };
        let t = report.table();
        let lines: Vec<&str> = t.lines().filter(|l| l.starts_with("  known difference: ")).collect();
        assert_eq!(lines, ["  known difference: first one", "  known difference: second one"], "{t}");
        let b = t.find("engine b:").expect("engine b listed");
        assert!(!t[b..].contains("known difference:"), "{t}");
    }
}
