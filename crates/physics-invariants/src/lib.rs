//! The project's engine-independent oracles, in one place: the per-engine physical invariants and the
//! cross-engine divergence bounds that `engine-diff` applies to robot rollouts, and that the rediscovery
//! bench (`bench/rediscovery`) applies to small scenes run on old engine versions. Nothing here knows an
//! engine: every function judges numbers an engine reported (or geometry computed from its poses).
//!
//! Thresholds and their derivations:
//! - quaternion norm drift ≤ 1e-6: engines renormalise every step; more means an unnormalised integration;
//! - contact normal forces finite and ≥ 0;
//! - penetration ≤ 2 cm: a 70 kg robot on soft contacts sinks millimetres; a body resting on a support sinks
//!   less; more is a missed or mis-sized contact;
//! - joint-limit overrun ≤ 0.05 rad: soft limits give way by ~0.01 rad under full torque;
//! - passivity: with PD torques as the only actuation, mechanical energy may grow at most by the actuator
//!   work Σ τ·Δq (plus push energy), within 1 J + 5 % of the gross work (τ held over a step: O(dt) error);
//! - cross-engine: the largest plausible difference in contact acceleration between two engines (soft vs hard
//!   contact at touch-down) is 2.5 g; one step: base velocity Δv ≤ 2.5·g·dt, joint and base angular velocity
//!   10× that (≲ 0.1 m lever arms); k steps: link positions ½·2.5·g·(k·dt)²;
//! - free fall: with no contact, gravity is the only external force, so the centre of mass accelerates at
//!   exactly g (joint torques, joint constraints and friction are internal); integrators reproduce a constant
//!   force exactly, so |a_com − g| ≤ 0.25·|g| leaves room only for position corrections of joint constraints;
//! - dynamics with an analytic route: relative error ≤ 1e-8 (the H1-2 mass matrix has condition ~1e5, so
//!   solving loses ≤ 5 of 16 digits), as `diff_physics::oracle::dynamics` uses.
#![forbid(unsafe_code)]

use serde::{Deserialize, Serialize};

/// Standard gravity (m/s²), the scale of every acceleration bound.
pub const GRAVITY_EARTH: f64 = 9.81;
/// Allowed drift of a base quaternion's norm from 1.
pub const QUAT_NORM_TOL: f64 = 1e-6;
/// Largest allowed penetration of a body into another (m).
pub const PENETRATION_MAX: f64 = 0.02;
/// Largest allowed joint-limit overrun (rad).
pub const JOINT_LIMIT_OVERRUN_MAX: f64 = 0.05;
/// Allowed deviation of the free-fall centre-of-mass acceleration from gravity, as a fraction of |g|.
pub const FREE_FALL_ACCEL_TOL_FRACTION: f64 = 0.25;
/// Relative tolerance of analytic dynamics (mass matrix, bias forces, inverse dynamics) against a reference.
pub const DYNAMICS_REL_TOL: f64 = 1e-8;
/// The contact-acceleration difference two plausible engines may show (2.5 g).
pub const CONTACT_ACCEL_GAP: f64 = 2.5 * GRAVITY_EARTH;

/// Names of the invariants as they appear in findings and reports.
pub mod names {
    pub const QUAT_NORM: &str = "quaternion norm";
    pub const CONTACT_FORCE: &str = "contact normal force ≥ 0";
    pub const PENETRATION: &str = "penetration depth";
    pub const JOINT_LIMIT: &str = "joint limit overrun";
    pub const ENERGY: &str = "energy created beyond actuator work (J)";
    pub const NON_FINITE: &str = "non-finite state";
    pub const INVERSE_DYNAMICS: &str = "inverse dynamics vs reference (rel)";
    pub const FREE_FALL: &str = "free-fall COM acceleration error (m/s²)";
}

/// `value > bound`, with NaN counting as exceeding.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
pub fn exceeds(value: f64, bound: f64) -> bool {
    !(value <= bound)
}

/// Allowed energy gain beyond the actuator work, given the gross (absolute) actuator work over the window.
pub fn energy_tolerance(abs_work: f64) -> f64 {
    1.0 + 0.05 * abs_work
}

/// The cross-engine bounds for time step `dt` and windows of `k` steps.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    pub one_step_base_lin_vel: f64,
    pub one_step_joint_vel: f64,
    pub one_step_base_ang_vel: f64,
    pub k_step_link_pos: f64,
}

impl Bounds {
    pub fn new(dt: f64, k: usize) -> Self {
        let a = CONTACT_ACCEL_GAP;
        let tw = dt * k as f64;
        Bounds {
            one_step_base_lin_vel: a * dt,
            one_step_joint_vel: 10.0 * a * dt,
            one_step_base_ang_vel: 10.0 * a * dt,
            k_step_link_pos: 0.5 * a * tw * tw,
        }
    }
}

/// |a − g| for the centre-of-mass positions `c` at three consecutive steps `dt` apart (second difference).
pub fn free_fall_error(c: [[f64; 3]; 3], dt: f64, gravity: [f64; 3]) -> f64 {
    (0..3).map(|k| ((c[2][k] - 2.0 * c[1][k] + c[0][k]) / (dt * dt) - gravity[k]).powi(2)).sum::<f64>().sqrt()
}

/// Lowest world z of a box with half-extents `half`, centred at `pos`, oriented by the unit quaternion
/// `quat` = `[w, x, y, z]` (body to world).
pub fn box_lowest_z(pos: [f64; 3], quat: [f64; 4], half: [f64; 3]) -> f64 {
    let [w, x, y, z] = quat;
    // Third row of the rotation matrix: the world z of each body axis.
    let row = [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)];
    pos[2] - row.iter().zip(half).map(|(r, h)| r.abs() * h).sum::<f64>()
}

/// Penetration of a body whose lowest point is at `lowest_z` into a horizontal support whose top is at
/// `support_top` (positive = below the top). Meaningful while the body is above the support's footprint;
/// a body that fell through the support shows a penetration of the whole drop.
pub fn penetration_below(support_top: f64, lowest_z: f64) -> f64 {
    support_top - lowest_z
}

/// `‖a − b‖ / ‖b‖` (Euclidean); `‖a − b‖` when `b` is zero. Different lengths give infinity.
pub fn relative_error(a: &[f64], b: &[f64]) -> f64 {
    if a.len() != b.len() {
        return f64::INFINITY;
    }
    let d = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt();
    let n = b.iter().map(|y| y * y).sum::<f64>().sqrt();
    if n > 0.0 {
        d / n
    } else {
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_exceeds_every_bound() {
        assert!(exceeds(f64::NAN, 1.0));
        assert!(exceeds(f64::INFINITY, 1.0));
        assert!(!exceeds(1.0, 1.0));
    }

    #[test]
    fn lowest_point_of_rotated_box() {
        // Unrotated: centre minus half height.
        assert!((box_lowest_z([0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0], [0.3, 0.2, 0.1]) - 0.9).abs() < 1e-12);
        // 45° about x: the y-z square's diagonal points down: h = (0.2 + 0.1) / √2.
        let c = (std::f64::consts::FRAC_PI_8).cos();
        let s = (std::f64::consts::FRAC_PI_8).sin();
        let z = box_lowest_z([0.0, 0.0, 1.0], [c, s, 0.0, 0.0], [0.3, 0.2, 0.1]);
        assert!((z - (1.0 - 0.3 / 2f64.sqrt())).abs() < 1e-12, "{z}");
    }

    #[test]
    fn bounds_scale_with_time() {
        let b = Bounds::new(0.002, 50);
        assert!((b.one_step_base_lin_vel - 2.5 * 9.81 * 0.002).abs() < 1e-15);
        assert!((b.k_step_link_pos - 0.5 * 2.5 * 9.81 * 0.01).abs() < 1e-12);
    }

    #[test]
    fn free_fall_of_a_point_is_exact() {
        let g = [0.0, 0.0, -9.81];
        let dt = 0.002;
        // Semi-implicit Euler from v0: every second difference is g·dt².
        let (mut x, mut v) = ([0.0, 0.0, 1.0], [0.3, 0.0, 0.5]);
        let mut c = Vec::new();
        for _ in 0..3 {
            for k in 0..3 {
                v[k] += g[k] * dt;
                x[k] += v[k] * dt;
            }
            c.push(x);
        }
        assert!(free_fall_error([c[0], c[1], c[2]], dt, g) < 1e-9);
        // Gravity pointing up is off by 2 g.
        assert!((free_fall_error([c[0], c[1], c[2]], dt, [0.0, 0.0, 9.81]) - 2.0 * 9.81).abs() < 1e-6);
    }

    #[test]
    fn relative_error_of_vectors() {
        assert_eq!(relative_error(&[1.0, 2.0], &[1.0, 2.0]), 0.0);
        assert!((relative_error(&[2.0, 0.0], &[1.0, 0.0]) - 1.0).abs() < 1e-15);
        assert!(relative_error(&[1.0], &[1.0, 2.0]).is_infinite());
    }
}
