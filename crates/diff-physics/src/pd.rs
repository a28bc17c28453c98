//! Unitree's joint PD law, computed outside the engines so that every engine receives the same torques:
//! `tau = tau_ff + kp (q_des − q) + kd (dq_des − dq)`, clamped to ±torque_limit per joint.
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};

/// Per-joint command (slot order), as in a LowCmd's motor_cmd entries.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PdTarget {
    pub q_des: Vec<f64>,
    pub dq_des: Vec<f64>,
    pub kp: Vec<f64>,
    pub kd: Vec<f64>,
    pub tau_ff: Vec<f64>,
}

impl PdTarget {
    /// Hold the model's standing pose with its default gains and no feed-forward.
    pub fn hold_standing(model: &RobotModel) -> Self {
        let n = model.nj();
        PdTarget {
            q_des: model.default_q(),
            dq_des: vec![0.0; n],
            kp: model.joints.iter().map(|j| j.kp).collect(),
            kd: model.joints.iter().map(|j| j.kd).collect(),
            tau_ff: vec![0.0; n],
        }
    }

    /// The same command in another joint order: entry `i` of the result is entry `order[i]` of `self` (for engines
    /// whose raw joint arrays are in link or DoF order, not slot order).
    pub fn permuted(&self, order: &[usize]) -> Self {
        let pick = |v: &[f64]| order.iter().map(|&j| v[j]).collect::<Vec<f64>>();
        PdTarget {
            q_des: pick(&self.q_des),
            dq_des: pick(&self.dq_des),
            kp: pick(&self.kp),
            kd: pick(&self.kd),
            tau_ff: pick(&self.tau_ff),
        }
    }
}

/// Computes clamped PD torques into `out` (slot order). `limits` are the per-joint torque limits (>= 0).
/// Entries beyond the shortest input are left untouched. NaN inputs give NaN torques (not hidden by clamping).
pub fn pd_torques_into(t: &PdTarget, q: &[f64], dq: &[f64], limits: &[f64], out: &mut [f64]) {
    let n = [
        t.q_des.len(),
        t.dq_des.len(),
        t.kp.len(),
        t.kd.len(),
        t.tau_ff.len(),
        q.len(),
        dq.len(),
        limits.len(),
        out.len(),
    ]
    .into_iter()
    .min()
    .unwrap_or(0);
    for i in 0..n {
        let raw = t.tau_ff[i] + t.kp[i] * (t.q_des[i] - q[i]) + t.kd[i] * (t.dq_des[i] - dq[i]);
        let lim = limits[i];
        out[i] = if raw.is_nan() { raw } else { raw.clamp(-lim, lim) };
    }
}

/// Clamped PD torques for `model`'s joints (slot order).
pub fn pd_torques(model: &RobotModel, t: &PdTarget, q: &[f64], dq: &[f64]) -> Vec<f64> {
    let limits: Vec<f64> = model.joints.iter().map(|j| j.torque_limit).collect();
    let mut out = vec![0.0; model.nj()];
    pd_torques_into(t, q, dq, &limits, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn law_and_clamp() {
        let t = PdTarget {
            q_des: vec![1.0, 0.0],
            dq_des: vec![0.0, 2.0],
            kp: vec![10.0, 0.0],
            kd: vec![1.0, 3.0],
            tau_ff: vec![0.5, -1.0],
        };
        let mut out = [0.0; 2];
        // joint 0: 0.5 + 10*(1-0.2) + 1*(0-0.1) = 8.4 -> clamped to 5; joint 1: -1 + 3*(2-1) = 2 (within 5)
        pd_torques_into(&t, &[0.2, 0.0], &[0.1, 1.0], &[5.0, 5.0], &mut out);
        assert_eq!(out[0], 5.0);
        assert!((out[1] - 2.0).abs() < 1e-12);
        pd_torques_into(&t, &[0.2, 0.0], &[0.1, 1.0], &[100.0, 1.5], &mut out);
        assert!((out[0] - 8.4).abs() < 1e-12);
        assert_eq!(out[1], 1.5);
    }
}
