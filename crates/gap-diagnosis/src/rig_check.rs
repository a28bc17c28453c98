//! The rig-assumption check: is this log from a robot whose pelvis is held still (the suspension rig the
//! diagnosis simulates)?
//!
//! On the rig the torso turns only with the waist joint, so the torso IMU's orientation and gyroscope follow from
//! the logged joint angles and speeds alone ([`crate::plant::imu_reading`]), and the accelerometer reads gravity
//! in the IMU frame (plus small centripetal terms). A robot standing or walking on the ground (floating base) moves
//! its pelvis and breaks that relation; the diagnosis then replays its commands on a plant that cannot reproduce it
//! and fits effects to the floating-base motion. The check compares every logged sample with the rig's prediction
//! after removing what the effect library itself fits as constants — an IMU mounting misalignment (a constant
//! rotation in the IMU frame, also absorbing a constant encoder offset on the waist), a gyroscope bias (a
//! constant) and an accelerometer offset — and counts the samples whose remaining deviation is beyond a
//! threshold. Threshold per channel: the larger of a fixed floor and [`NOISE_MULTIPLE`] times that channel's
//! white-noise level estimated from the log itself (first differences of the residual, robust MAD), so a noisy
//! IMU does not trip it.
//!
//! A robot standing perfectly still on the ground is kinematically a rig (its constant tilt looks like a
//! misalignment), so the IMU cannot tell; its legs can. The foot-load test ([`foot_load`]) explains the logged leg
//! torques beyond what hanging legs need by a wrench on each foot and asks how much of the body weight the feet
//! carry: on the rig nothing, standing nearly all of it.
use crate::effects::EffectKind;
use crate::log::{Measurement, RobotLog};
use crate::plant::{imu_reading, Effects, RIG_BASE_POS};
use crate::GapError;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use robot_model::{GenCoords, RobotModel};
use serde::{Deserialize, Serialize};

/// Orientation deviation floor (rad, 2.9°): far above IMU attitude noise, below the pelvis sway of a standing
/// robot moving its limbs.
pub const ORIENTATION_FLOOR_RAD: f64 = 0.05;
/// Gyroscope deviation floor (rad/s).
pub const GYRO_FLOOR_RAD_S: f64 = 0.2;
/// Accelerometer deviation floor (m/s²): above the error of the differentiated torso acceleration on the rig.
pub const ACC_FLOOR_M_S2: f64 = 2.0;
/// Threshold = max(floor, NOISE_MULTIPLE × estimated per-axis noise standard deviation).
pub const NOISE_MULTIPLE: f64 = 8.0;
/// The log violates the rig assumption when more than this fraction of samples deviate beyond a threshold.
pub const MAX_VIOLATING_FRACTION: f64 = 0.05;

/// The log violates the rig assumption when the feet carry more than this fraction of the body weight (median over
/// the log). Hanging legs carry none: rig logs read 0 to -1 %, also with the library's largest link mass (x1.8) and
/// Coulomb friction on a whole leg; a robot standing still reads 100 % (`tests/rig_check.rs`).
pub const MAX_FOOT_LOAD_FRACTION: f64 = 0.3;
/// Every this many states enter the foot-load median (the load of a standing robot changes slowly).
const FOOT_LOAD_STRIDE: usize = 5;

/// Outcome of the rig-assumption check (part of `report.json`).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct RigCheck {
    /// The log is consistent with a pelvis held still (the diagnosis ran).
    pub suspended: bool,
    pub samples: usize,
    /// Constant rotation between logged and predicted IMU orientation (rotation vector, IMU frame, rad): what a
    /// misalignment or a waist encoder offset explains; removed before the deviations below.
    pub constant_rotation_rad: [f64; 3],
    /// Constant gyroscope offset (rad/s), removed (a gyro bias).
    pub constant_gyro_rad_s: [f64; 3],
    /// Estimated noise standard deviations (largest axis): orientation (rad), gyroscope (rad/s), accelerometer.
    pub noise_orientation_rad: f64,
    pub noise_gyro_rad_s: f64,
    pub noise_acc_m_s2: f64,
    /// Thresholds used.
    pub threshold_orientation_rad: f64,
    pub threshold_gyro_rad_s: f64,
    pub threshold_acc_m_s2: f64,
    /// Whether the accelerometer was checked (logs with an all-zero accelerometer are not).
    pub acc_checked: bool,
    /// 95th percentile and maximum of the deviation beyond the rig's prediction.
    pub p95_orientation_deg: f64,
    pub max_orientation_deg: f64,
    pub p95_gyro_rad_s: f64,
    pub max_gyro_rad_s: f64,
    pub p95_acc_m_s2: f64,
    /// Fraction of samples beyond any threshold.
    pub violating_fraction: f64,
    /// Median vertical force on both feet over the body weight, from the leg torques ([`foot_load`]); `None` when
    /// the log's torque estimates are all zero (not checked).
    #[serde(default)]
    pub foot_load_fraction: Option<f64>,
    /// One line for humans.
    pub message: String,
}

fn uq(a: &[f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(a[0], a[1], a[2], a[3]))
}

fn median(mut x: Vec<f64>) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    x.sort_by(f64::total_cmp);
    x[x.len() / 2]
}

fn percentile(x: &[f64], p: f64) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let mut v = x.to_vec();
    v.sort_by(f64::total_cmp);
    v[((p * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)]
}

/// White-noise standard deviation of a 3-axis series (largest axis): MAD of first differences / √2.
fn noise_sd(series: &[Vector3<f64>]) -> f64 {
    (0..3)
        .map(|k| {
            let d: Vec<f64> = series.windows(2).map(|w| (w[1][k] - w[0][k]).abs()).collect();
            1.4826 * median(d) / std::f64::consts::SQRT_2
        })
        .fold(0.0, f64::max)
}

/// World velocity of the IMU point on the rig for joint state `(q, dq)` (forward kinematics differentiated along
/// the joint velocity).
pub fn imu_point_velocity(model: &RobotModel, q: &[f64], dq: &[f64]) -> Result<Vector3<f64>, GapError> {
    const EPS: f64 = 1e-6;
    let pos = |q: Vec<f64>| -> Result<Vector3<f64>, GapError> {
        let c = GenCoords { base_pos: RIG_BASE_POS, base_quat: [1.0, 0.0, 0.0, 0.0], q };
        let fk = model.fk(&c).map_err(GapError::from)?;
        Ok((fk.link_poses[model.imu.link] * nalgebra::Point3::from(Vector3::from(model.imu.pos))).coords)
    };
    let p0 = pos(q.to_vec())?;
    let p1 = pos(q.iter().zip(dq).map(|(a, b)| a + b * EPS).collect())?;
    Ok((p1 - p0) / EPS)
}

/// Each foot link (ankle link) with the joints on the chain from the pelvis down to it, for [`foot_load`].
#[derive(Debug, Clone)]
pub struct LegChains(Vec<(usize, Vec<usize>)>);

impl LegChains {
    pub fn of(model: &RobotModel, feet: &crate::floating::Feet) -> Self {
        LegChains(
            feet.links
                .iter()
                .map(|&foot| {
                    let mut chain = Vec::new();
                    let mut link = foot;
                    while let Some(j) = model.links[link].parent_joint {
                        chain.push(j);
                        link = model.joints[j].parent_link;
                    }
                    (foot, chain)
                })
                .collect(),
        )
    }
}

/// Vertical force on both feet (N, up positive) that explains a measurement's leg torques beyond those of the
/// legs hanging from a pelvis held upright (quasi-static: gravity and velocity terms, no acceleration, which
/// averages out over a log). Per leg, the six joints from hip to ankle carry a 6-D wrench on the ankle link:
/// `τ_logged − τ_hanging = −Jᵀ w` (the motors hold against the ground), solved by SVD least squares, so a leg
/// near a singular pose gives the minimum-norm wrench instead of an error.
pub fn foot_load(model: &RobotModel, legs: &LegChains, s: &Measurement) -> Result<f64, GapError> {
    let nj = model.nj();
    if s.tau.len() != nj || s.q.len() != nj || s.dq.len() != nj {
        return Err(GapError::Log(format!(
            "a state has {} joint angles and {} torques for a {nj}-joint model",
            s.q.len(),
            s.tau.len()
        )));
    }
    let c = GenCoords { base_pos: RIG_BASE_POS, base_quat: [1.0, 0.0, 0.0, 0.0], q: s.q.clone() };
    let mut v = vec![0.0; model.nv()];
    v[6..].copy_from_slice(&s.dq);
    let g = [0.0, 0.0, -robot_model::GRAVITY_EARTH];
    let hanging = model.rnea(&c, &v, &vec![0.0; model.nv()], g, false).map_err(GapError::from)?;
    let fk = model.fk(&c).map_err(GapError::from)?;
    let mut fz = 0.0;
    for (foot, chain) in &legs.0 {
        let p = fk.link_poses[*foot].translation.vector;
        let mut jt = nalgebra::DMatrix::<f64>::zeros(chain.len(), 6);
        let mut rhs = nalgebra::DVector::<f64>::zeros(chain.len());
        for (r, &j) in chain.iter().enumerate() {
            let a = fk.joint_axes[j].into_inner();
            // τ_j = a · ((p − r) × F) + a · M = F · (a × (p − r)) + M · a.
            let lin = a.cross(&(p - fk.joint_points[j]));
            for k in 0..3 {
                jt[(r, k)] = lin[k];
                jt[(r, 3 + k)] = a[k];
            }
            rhs[r] = -(s.tau[j] - hanging[6 + j]);
        }
        let w = jt.svd(true, true).solve(&rhs, 1e-6).map_err(|e| GapError::Numerics(format!("foot wrench: {e}")))?;
        fz += w[2];
    }
    Ok(fz)
}

/// Checks `log` against the rig assumption for `model`.
pub fn check(model: &RobotModel, log: &RobotLog) -> Result<RigCheck, GapError> {
    let null = Effects::none(model.nj());
    let g = robot_model::GRAVITY_EARTH;
    let n = log.states.len();
    let mut rel = Vec::with_capacity(n); // pred⁻¹ · meas (IMU frame)
    let mut pred_gyro = Vec::with_capacity(n);
    let mut pred_rot = Vec::with_capacity(n);
    for s in &log.states {
        let (quat, gyro) = imu_reading(model, &s.q, &s.dq, &null)?;
        let p = uq(&quat);
        rel.push(p.inverse() * uq(&s.quat));
        pred_gyro.push(Vector3::from(gyro));
        pred_rot.push(p);
    }
    // Constant rotation: sign-aligned quaternion mean of the relative rotations (chordal L2 mean).
    let mut acc = nalgebra::Vector4::zeros();
    for r in &rel {
        let v = r.as_ref().coords;
        acc += if v.dot(&rel[0].as_ref().coords) < 0.0 { -v } else { v };
    }
    let m = if acc.norm() > 0.0 {
        UnitQuaternion::from_quaternion(Quaternion::from(acc))
    } else {
        UnitQuaternion::identity()
    };
    let rot_dev: Vec<Vector3<f64>> = rel.iter().map(|r| (m.inverse() * r).scaled_axis()).collect();
    // Gyro: measured = M⁻¹ · predicted + bias.
    let gyro_res: Vec<Vector3<f64>> =
        log.states.iter().zip(&pred_gyro).map(|(s, pg)| Vector3::from(s.gyro) - m.inverse() * pg).collect();
    let bias = Vector3::from([0, 1, 2].map(|k| median(gyro_res.iter().map(|v| v[k]).collect())));
    let gyro_dev: Vec<Vector3<f64>> = gyro_res.iter().map(|v| v - bias).collect();
    // Accelerometer: specific force of the IMU point on the rig, R⁻¹ (a − g), in the (misaligned) IMU frame, with
    // `a` the central difference of the point's velocity from the joints (the torso swings about the waist); a
    // constant offset is removed. Samples without both neighbours within 20 ms compare gravity alone.
    let acc_checked = log.states.iter().any(|s| s.acc.iter().any(|a| a.abs() > 1e-6));
    let vel: Vec<Vector3<f64>> = if acc_checked {
        log.states.iter().map(|s| imu_point_velocity(model, &s.q, &s.dq)).collect::<Result<_, _>>()?
    } else {
        vec![Vector3::zeros(); n]
    };
    // Only where both neighbouring state intervals are regular (0.5-2x the median): a stalled loop or transport
    // bunches log times and the difference quotient means nothing there.
    let dt_med = median(log.states.windows(2).map(|w| w[1].t - w[0].t).collect());
    let regular = |a: usize, b: usize| {
        let d = log.states[b].t - log.states[a].t;
        d >= crate::noise::TIMING_LO * dt_med && d <= crate::noise::TIMING_HI * dt_med
    };
    let acc_res: Vec<Option<Vector3<f64>>> = (0..n)
        .map(|i| {
            let (a, b) = (i.checked_sub(1)?, i + 1);
            if b >= n || !regular(a, i) || !regular(i, b) {
                return None;
            }
            let acc = (vel[b] - vel[a]) / (log.states[b].t - log.states[a].t);
            Some(Vector3::from(log.states[i].acc) - (pred_rot[i] * m).inverse() * (acc + Vector3::new(0.0, 0.0, g)))
        })
        .collect();
    let acc_ok: Vec<Vector3<f64>> = acc_res.iter().flatten().copied().collect();
    let acc_off = Vector3::from([0, 1, 2].map(|k| median(acc_ok.iter().map(|v| v[k]).collect())));
    let acc_dev: Vec<Vector3<f64>> = acc_ok.iter().map(|v| v - acc_off).collect();

    let (nr, ng, na) = (noise_sd(&rot_dev), noise_sd(&gyro_dev), noise_sd(&acc_dev));
    let thr_r = ORIENTATION_FLOOR_RAD.max(NOISE_MULTIPLE * nr);
    let thr_g = GYRO_FLOOR_RAD_S.max(NOISE_MULTIPLE * ng);
    let thr_a = ACC_FLOOR_M_S2.max(NOISE_MULTIPLE * na);
    let rn: Vec<f64> = rot_dev.iter().map(|v| v.norm()).collect();
    let gn: Vec<f64> = gyro_dev.iter().map(|v| v.norm()).collect();
    let an: Vec<f64> = acc_dev.iter().map(|v| v.norm()).collect();
    let acc_bad: Vec<bool> = acc_res.iter().map(|r| r.is_some_and(|v| (v - acc_off).norm() > thr_a)).collect();
    let bad = (0..n).filter(|&i| rn[i] > thr_r || gn[i] > thr_g || (acc_checked && acc_bad[i])).count();
    let frac = bad as f64 / n.max(1) as f64;
    // Constants beyond what the library can fit are violations too.
    let mis_max = EffectKind::ImuMisalignment.range().1;
    let bias_max = EffectKind::ImuBias.range().1;
    let const_rot = m.scaled_axis();
    let beyond_const = const_rot.norm() > mis_max + thr_r || bias.norm() > bias_max + thr_g;
    // Foot load, where the log has torque estimates and the model has legs.
    let torques_logged = log.states.iter().any(|s| s.tau.iter().any(|t| t.abs() > 1e-9));
    let foot_load_fraction = match (torques_logged, crate::floating::Feet::of(model)) {
        (true, Ok(feet)) => {
            let weight = model.total_mass() * g;
            let legs = LegChains::of(model, &feet);
            let loads = log
                .states
                .iter()
                .step_by(FOOT_LOAD_STRIDE)
                .map(|s| foot_load(model, &legs, s).map(|f| f / weight))
                .collect::<Result<Vec<_>, _>>()?;
            Some(median(loads))
        }
        _ => None,
    };
    let loaded = foot_load_fraction.is_some_and(|f| f > MAX_FOOT_LOAD_FRACTION);
    let suspended = frac <= MAX_VIOLATING_FRACTION && !beyond_const && !loaded;
    let deg = |r: f64| r.to_degrees();
    let (p95r, maxr, p95g, maxg, p95a) = (
        percentile(&rn, 0.95),
        rn.iter().copied().fold(0.0, f64::max),
        percentile(&gn, 0.95),
        gn.iter().copied().fold(0.0, f64::max),
        percentile(&an, 0.95),
    );
    let message = if suspended {
        format!(
            "consistent with a suspended robot: torso IMU follows the joints within {:.1} deg / {:.2} rad/s on {:.1} % of samples (allowed {:.0} %){}",
            deg(thr_r),
            thr_g,
            100.0 * (1.0 - frac),
            100.0 * MAX_VIOLATING_FRACTION,
            match foot_load_fraction {
                Some(f) => format!("; the feet carry {:.0} % of the body weight (allowed {:.0} %)", 100.0 * f, 100.0 * MAX_FOOT_LOAD_FRACTION),
                None => "; foot load not checked (no torque estimates in the log)".into(),
            }
        )
    } else if loaded && frac <= MAX_VIOLATING_FRACTION && !beyond_const {
        format!(
            "log not from a suspended robot: the leg torques put {:.0} % of the body weight on the feet (median; a suspended robot's hanging legs carry none, allowed {:.0} %), so it stands on the ground although its torso IMU follows the joints",
            100.0 * foot_load_fraction.unwrap_or(0.0),
            100.0 * MAX_FOOT_LOAD_FRACTION
        )
    } else if beyond_const && frac <= MAX_VIOLATING_FRACTION {
        format!(
            "log not from a suspended robot: the pelvis is tilted {:.1} deg / the gyroscope offset is {:.2} rad/s, beyond the largest IMU misalignment ({:.1} deg) / bias ({:.2} rad/s) the library fits",
            deg(const_rot.norm()),
            bias.norm(),
            deg(mis_max),
            bias_max
        )
    } else {
        format!(
            "log not from a suspended robot: pelvis rotated {:.1} deg (95th percentile; max {:.1}) / {:.2} rad/s beyond the rig's prediction over {:.1} % of samples (thresholds {:.1} deg, {:.2} rad/s{})",
            deg(p95r),
            deg(maxr),
            p95g,
            100.0 * frac,
            deg(thr_r),
            thr_g,
            if acc_checked { format!(", {thr_a:.1} m/s²") } else { String::new() }
        )
    };
    Ok(RigCheck {
        suspended,
        samples: n,
        constant_rotation_rad: const_rot.into(),
        constant_gyro_rad_s: bias.into(),
        noise_orientation_rad: nr,
        noise_gyro_rad_s: ng,
        noise_acc_m_s2: na,
        threshold_orientation_rad: thr_r,
        threshold_gyro_rad_s: thr_g,
        threshold_acc_m_s2: thr_a,
        acc_checked,
        p95_orientation_deg: deg(p95r),
        max_orientation_deg: deg(maxr),
        p95_gyro_rad_s: p95g,
        max_gyro_rad_s: maxg,
        p95_acc_m_s2: p95a,
        violating_fraction: frac,
        foot_load_fraction,
        message,
    })
}
