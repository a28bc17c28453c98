//! PhysX's own floating-base dynamics API checked against `robot-model`'s reference (issue 15): an oracle of the
//! PhysX engine, kept with the oracles so that the engine module does not depend on them.
use super::{push, random_state, CheckOptions, CheckResult};
use crate::engine::{CommonSettings, Engine, State};
use crate::physx::{PhysxEngine, PhysxSettings, F32_UNIT_ROUNDOFF};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use robot_model::RobotModel;

/// Splits a reference `nv × nv` matrix into its base (first 6) and joint blocks.
fn blocks(m: &DMatrix<f64>) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let n = m.nrows();
    (
        m.view((0, 0), (6, 6)).into_owned(),
        m.view((6, 0), (n - 6, 6)).into_owned(),
        m.view((6, 6), (n - 6, n - 6)).into_owned(),
    )
}

/// 2-norm condition number of a symmetric positive definite matrix.
fn condition(m: &DMatrix<f64>) -> f64 {
    let e = m.clone().symmetric_eigen().eigenvalues;
    let (lo, hi) = e.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &x| (lo.min(x.abs()), hi.max(x.abs())));
    if lo > 0.0 {
        hi / lo
    } else {
        f64::INFINITY
    }
}

/// Checks of PhysX's own floating-base inverse-dynamics API (`computeGeneralizedMassMatrix`,
/// `computeGeneralizedGravityForce`, `computeCoriolisAndCentrifugalForce`, `computeJointAcceleration`) against
/// `robot-model`'s RNEA/CRBA. With a floating base PhysX leaves the base free, so the reference is reduced the
/// same way: `M_red = M_jj − M_jb M_bb⁻¹ M_bj` (the joint-space inertia with the base free) and, for a bias
/// vector `b`, `b_red = b_j − M_jb M_bb⁻¹ b_b`. For uniform gravity `g_red = 0` exactly (a free body falls
/// without internal accelerations).
///
/// Tolerances from f32 arithmetic (u = 2⁻²⁴): PhysX's joint-space sums carry the FK error of the link frames
/// (≤ 65u relative, see [`crate::physx::f32_tolerance`]) twice, ≤ 130u of the largest term `‖M_jj‖` (or `‖b_j‖`), and inverting
/// the 6×6 composite base inertia in f32 costs ≤ 10·κ(M_bb)·u of the subtracted term (κ: its condition number,
/// the factor 10 covering the change from our base coordinates to PhysX's root COM frame). Accelerations solve
/// with `M_red`: first-order error ≤ κ(M_red) × the entries' relative error (130u).
pub fn native_checks(model: &RobotModel, opts: &CheckOptions, out: &mut Vec<CheckResult>) {
    let en = "physx";
    let u = F32_UNIT_ROUNDOFF;
    let g = [0.0, 0.0, -robot_model::GRAVITY_EARTH];
    for armature in [false, true] {
        let common = CommonSettings { timestep: opts.timestep, armature, ..CommonSettings::rigid_body_only() };
        let mut e = match PhysxEngine::new(model, &common, &PhysxSettings::default()) {
            Ok(e) => e,
            Err(err) => {
                push(out, "build", "PhysX native dynamics", en, f64::INFINITY, 0.0, "-", &err.to_string());
                return;
            }
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed ^ 0x9A);
        // (error, tolerance) pairs: the worst ratio over the samples is reported.
        let mut worst = [(0.0f64, 1.0f64); 4];
        let mut note = String::new();
        let keep = |k: usize, err: f64, tol: f64, worst: &mut [(f64, f64); 4]| {
            if !(err / tol <= worst[k].0 / worst[k].1) {
                worst[k] = (err, tol);
            }
        };
        for _ in 0..opts.samples {
            let s = random_state(model, &mut rng);
            let c = s.coords();
            let v = s.v();
            let tau: Vec<f64> = model.joints.iter().map(|j| rng.gen_range(-0.5..0.5) * j.torque_limit).collect();
            let (Ok(m0), Ok(m_arm), Ok(gb), Ok(cb)) = (
                model.mass_matrix(&c, false),
                model.mass_matrix(&c, armature),
                model.bias_forces(&c, &vec![0.0; model.nv()], g),
                model.bias_forces(&c, &v, [0.0; 3]),
            ) else {
                continue;
            };
            let mut f = vec![0.0; 6];
            f.extend_from_slice(&tau);
            let Ok(a_ref) = model.forward_dynamics(&c, &v, &f, g, armature) else { continue };
            let native = match e.reset(&s).and_then(|_| e.native_dynamics(&tau)) {
                Ok(n) => n,
                Err(err) => {
                    push(out, "dynamics", "PhysX native dynamics", en, f64::INFINITY, 0.0, "-", &err.to_string());
                    return;
                }
            };
            let nj = model.nj();
            let (bb, jb, jj) = blocks(&m0);
            let Some(bb_inv) = bb.clone().try_inverse() else { continue };
            let kappa_b = condition(&bb);
            let sub = &jb * &bb_inv * jb.transpose();
            let m_red = &jj - &sub;
            let reduce = |b: &nalgebra::DVector<f64>| -> nalgebra::DVector<f64> {
                let bj = b.rows(6, nj).into_owned();
                let bbv = b.rows(0, 6).into_owned();
                bj - &jb * (&bb_inv * bbv)
            };
            let scale =
                |big: f64, subtracted: f64, result: f64| (130.0 * big + 10.0 * kappa_b * subtracted) * u / result;
            if !armature {
                let m_px = DMatrix::from_row_slice(nj, nj, &native.mass);
                keep(0, (&m_px - &m_red).norm() / m_red.norm(), scale(jj.norm(), sub.norm(), m_red.norm()), &mut worst);
                // At rest: PhysX 5.1 builds the gravity term with the root's current angular velocity in its
                // gyroscopic term (computeZ uses the link velocities; only joint velocities are dropped), so
                // with a spinning root it is not "purely gravity" as documented (measured 1.6e-3 of ‖g_j‖ at
                // |ω| <= 1.7 rad/s). The documented inputs are the pose only: check it there.
                let at_rest = match e.reset(&State::at_rest(c.clone())).and_then(|_| e.native_dynamics(&tau)) {
                    Ok(n) => n,
                    Err(err) => {
                        push(out, "dynamics", "PhysX native dynamics", en, f64::INFINITY, 0.0, "-", &err.to_string());
                        return;
                    }
                };
                let g_px = nalgebra::DVector::from_vec(at_rest.gravity.clone());
                let gj = gb.rows(6, nj).norm();
                keep(1, g_px.norm() / gj, scale(gj, gj, gj), &mut worst);
                let c_red = reduce(&cb);
                let c_px = nalgebra::DVector::from_vec(native.coriolis.clone());
                let cj = cb.rows(6, nj).norm();
                keep(
                    2,
                    (&c_px - &c_red).norm() / c_red.norm(),
                    scale(cj, (cj - c_red.norm()).abs().max(c_red.norm()), c_red.norm()),
                    &mut worst,
                );
                note = format!("κ(M_bb) = {kappa_b:.0}");
            }
            // Accelerations: M_red (with armature as configured) solves; its error and the right-hand side's.
            let (_, _, jj_arm) = blocks(&m_arm);
            let m_red_arm = &jj_arm - &sub;
            let kappa_r = condition(&m_red_arm);
            let a_j = a_ref.rows(6, nj).into_owned();
            let a_px = nalgebra::DVector::from_vec(native.acceleration.clone());
            // First-order perturbation bound: the entries' f32 error (130u, as above) amplified by κ(M_red).
            keep(3, (&a_px - &a_j).norm() / a_j.norm(), kappa_r * 130.0 * u, &mut worst);
            if armature {
                note = format!("{note}; κ(M_red with armature) up to {kappa_r:.1e}");
            } else if !note.contains("M_red)") {
                note = format!("{note}; κ(M_red) = {kappa_r:.1e}");
            }
        }
        let tag = if armature { " (with armature)" } else { "" };
        if !armature {
            push(
                out,
                "dynamics",
                "PhysX mass matrix, base free",
                en,
                worst[0].0,
                worst[0].1,
                "rel",
                &format!("computeGeneralizedMassMatrix vs M_jj − M_jb M_bb⁻¹ M_bj; {note}"),
            );
            push(
                out,
                "dynamics",
                "PhysX gravity forces, base free (= 0)",
                en,
                worst[1].0,
                worst[1].1,
                "rel ‖g_j‖",
                "computeGeneralizedGravityForce at rest; exactly 0 for a free body",
            );
            push(
                out,
                "dynamics",
                "PhysX Coriolis forces, base free",
                en,
                worst[2].0,
                worst[2].1,
                "rel",
                "computeCoriolisAndCentrifugalForce vs c_j − M_jb M_bb⁻¹ c_b",
            );
        }
        push(
            out,
            "dynamics",
            &format!("PhysX joint accelerations, base free{tag}"),
            en,
            worst[3].0,
            worst[3].1,
            "rel",
            &format!("computeJointAcceleration (ABA) vs reference forward dynamics; {note}"),
        );
    }
}
