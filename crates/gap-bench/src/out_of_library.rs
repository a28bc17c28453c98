//! Effects outside the diagnosis's library (issue 14 item 5): a benchmark trial may hide one of these in the
//! reference plant, where the diagnosis has nothing to fit them with. It must not name a library effect
//! confidently on them; the benchmark scores such trials as their own class. Both act as a torque the actuator
//! does not know of ([`gap_diagnosis::plant::Rig::step_disturbed`]): the logged motor torque does not include it.
use gap_diagnosis::plant::{joint_groups, GROUPS};
use rand::Rng;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};

/// Velocity scale of the load-dependent friction's sign (rad/s), as the library's Coulomb law.
const FRICTION_EPS: f64 = gap_diagnosis::plant::COULOMB_EPS;

/// One effect outside the library.
#[derive(Debug, Clone, PartialEq)]
pub enum OutOfLibrary {
    /// Torque ripple periodic in the joint angle (cogging seen through the gearbox): `-a · limit · sin(k q)` on one
    /// joint; no library effect depends on the angle periodically.
    TorqueRipple { joint: usize, fraction: f64, per_rad: f64 },
    /// Friction proportional to the torque the transmission carries (a gear's load-dependent loss):
    /// `-mu · |motor torque| · tanh(dq / eps)` on every joint of a group; the library's friction is constant.
    LoadFriction { group: usize, mu: f64 },
}

/// The sealed label of an out-of-library effect.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutOfLibraryLabel {
    /// `torque_ripple` or `load_friction`.
    pub kind: String,
    /// Joint or group.
    pub unit: String,
    /// Ripple: amplitude as a fraction of the torque limit; load friction: the coefficient.
    pub value: f64,
}

impl OutOfLibrary {
    /// Draws trial `k`'s effect (ripple and load friction alternate) with `rng`.
    pub fn draw(model: &RobotModel, k: usize, rng: &mut impl Rng) -> Self {
        if k.is_multiple_of(2) {
            OutOfLibrary::TorqueRipple {
                joint: rng.gen_range(0..model.nj().max(1)),
                fraction: rng.gen_range(0.03..0.06),
                per_rad: rng.gen_range(10.0..20.0),
            }
        } else {
            OutOfLibrary::LoadFriction { group: rng.gen_range(0..GROUPS.len()), mu: rng.gen_range(0.1..0.2) }
        }
    }

    /// Its label.
    pub fn label(&self, model: &RobotModel) -> OutOfLibraryLabel {
        match *self {
            OutOfLibrary::TorqueRipple { joint, fraction, .. } => OutOfLibraryLabel {
                kind: "torque_ripple".into(),
                unit: model.joints.get(joint).map_or_else(|| format!("joint {joint}"), |j| j.motor_name.clone()),
                value: fraction,
            },
            OutOfLibrary::LoadFriction { group, mu } => OutOfLibraryLabel {
                kind: "load_friction".into(),
                unit: GROUPS.get(group).map_or_else(|| format!("group {group}"), |g| g.to_string()),
                value: mu,
            },
        }
    }

    /// The disturbance torque on every joint at true state `q`, `dq`, with the last step's motor torques `motor`
    /// and the joints' torque limits.
    pub fn torque(&self, model: &RobotModel, q: &[f64], dq: &[f64], motor: &[f64], limits: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; q.len()];
        match *self {
            OutOfLibrary::TorqueRipple { joint, fraction, per_rad } => {
                if let (Some(o), Some(&qj), Some(&lim)) = (out.get_mut(joint), q.get(joint), limits.get(joint)) {
                    *o = -fraction * lim * (per_rad * qj).sin();
                }
            }
            OutOfLibrary::LoadFriction { group, mu } => {
                for (j, g) in joint_groups(model).into_iter().enumerate() {
                    if g == group {
                        let (v, m) = (dq.get(j).copied().unwrap_or(0.0), motor.get(j).copied().unwrap_or(0.0));
                        out[j] = -mu * m.abs() * (v / FRICTION_EPS).tanh();
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_disturbances_act_where_and_how_they_say() {
        let m = robot_model::builtin("h1_2").expect("model");
        let nj = m.nj();
        let limits = vec![100.0; nj];
        let ripple = OutOfLibrary::TorqueRipple { joint: 3, fraction: 0.05, per_rad: 10.0 };
        let mut q = vec![0.0; nj];
        q[3] = std::f64::consts::FRAC_PI_2 / 10.0; // sin(k q) = 1
        let t = ripple.torque(&m, &q, &vec![0.0; nj], &vec![0.0; nj], &limits);
        assert!((t[3] + 5.0).abs() < 1e-9 && t.iter().enumerate().all(|(j, x)| j == 3 || *x == 0.0), "{t:?}");
        // Load friction opposes motion, in proportion to the carried torque, only in its group.
        let groups = joint_groups(&m);
        let lf = OutOfLibrary::LoadFriction { group: groups[0], mu: 0.1 };
        let t = lf.torque(&m, &vec![0.0; nj], &vec![1.0; nj], &vec![-50.0; nj], &limits);
        for j in 0..nj {
            let want = if groups[j] == groups[0] { -0.1 * 50.0 * (1.0 / FRICTION_EPS).tanh() } else { 0.0 };
            assert!((t[j] - want).abs() < 1e-9, "joint {j}: {} vs {want}", t[j]);
        }
    }
}
