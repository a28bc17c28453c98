//! Oracle tolerances that follow from an engine's arithmetic (a leaf module: the oracles and the f32 engines use it).

/// Tolerance of an oracle check for an engine whose state is f32 (PhysX, Newton), derived from f32 arithmetic.
/// `None`: the check's f64 tolerance stands (physical tolerances that dwarf f32 rounding). `u = 2⁻²⁴ ≈ 6e-8` is
/// f32's unit roundoff.
pub fn f32_state_tolerance(check: &str) -> Option<f64> {
    match check {
        // Each mass is rounded once to f32 (|δm| <= u·m) and the heaviest H1-2 link is < 20 kg; the total sums
        // 28 such errors, <= u·M with M ≈ 70 kg (4.2e-6). 1e-5 kg covers both with margin (masses up to 160 kg).
        "per-link mass" | "total mass" => Some(1e-5),
        // Limits rounded once: |δ| <= u·|limit| <= u·π ≈ 1.9e-7 rad. 4e-7 rad.
        "joint limits" => Some(4e-7),
        // The engine composes <= 9 f32 transforms per chain from the f32 root pose and f32 joint angles: each level
        // adds ~4u of rotation error (quaternion product + renormalisation) plus u·π of angle rounding, so the
        // chain end is off by <= 9·(4 + π)u ≈ 65u ≈ 3.9e-6 rad; positions (<= 3 m from the origin, <= 1.5 m of
        // chain) by <= 65u·1.5 m + 9u·3 m ≈ 7.5e-6 m. Tolerances 2e-5 m and 1e-5 rad.
        "link-frame FK position" | "centre of mass" => Some(2e-5),
        "link-frame FK orientation" | "joint axes (world)" => Some(1e-5),
        // Assembled from the engine's f32 Jacobian or transforms (entries carry the FK error above, ~65u relative) and f32
        // inertias (u): δM/M <= 2·65u + u ≈ 8e-6. 5e-5 with margin for the Frobenius aggregation.
        "mass matrix (engine's own)" | "mass matrix (engine's own) (with armature)" => Some(5e-5),
        // ½vᵀMv with that M and the f32-rounded velocities: 8e-6 + 2u; 5e-5.
        "kinetic energy at reset" => Some(5e-5),
        // −m g·z_com with the COM off by <= 2e-5 m at heights >= 1 m: 2e-5 relative; 5e-5.
        "potential energy at reset" => Some(5e-5),
        _ => None,
    }
}
