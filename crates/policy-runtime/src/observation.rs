//! Building the network input from a [`RobotObservation`]: per-term values, scales, history.

use crate::spec::{HistoryLayout, ObservationTerm, PolicySpec, TermKind};
use crate::{PolicyError, RobotObservation};
use std::collections::VecDeque;

/// Gravity direction `(0, 0, −1)` (world) in the frame of a body with orientation `quat` (`[w, x, y, z]`,
/// body-to-world): `Rᵀ (0, 0, −1)`. The quaternion is normalized first; a zero or non-finite one is an error.
pub fn projected_gravity(quat: [f64; 4]) -> Result<[f64; 3], PolicyError> {
    let n = quat.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(n.is_finite() && n > 1e-9) {
        return Err(PolicyError::Observation(format!("base quaternion {quat:?} is not a rotation")));
    }
    let [w, x, y, z] = quat.map(|v| v / n);
    // Third row of R (world z in body coordinates), negated.
    Ok([-2.0 * (x * z - w * y), -2.0 * (y * z + w * x), -(1.0 - 2.0 * (x * x + y * y))])
}

/// `(sin 2πφ, cos 2πφ)` with `φ = (time mod period) / period`.
pub fn gait_phase_sin_cos(time: f64, period: f64) -> [f64; 2] {
    let phase = time.rem_euclid(period) / period;
    let a = 2.0 * std::f64::consts::PI * phase;
    [a.sin(), a.cos()]
}

/// One observation frame, term by term (scaled, clipped when the spec says so).
pub fn build_frame(
    spec: &PolicySpec,
    obs: &RobotObservation,
    last_action: &[f64],
) -> Result<Vec<Vec<f64>>, PolicyError> {
    let nj = spec.nj();
    if obs.q.len() != nj || obs.dq.len() != nj {
        return Err(PolicyError::Observation(format!(
            "q has {} and dq {} entries; the spec drives {nj} joints",
            obs.q.len(),
            obs.dq.len()
        )));
    }
    if last_action.len() != spec.action_dim() {
        return Err(PolicyError::Observation(format!(
            "last action has {} entries, expected {}",
            last_action.len(),
            spec.action_dim()
        )));
    }
    let finite = obs.time.is_finite()
        && obs.base_quat.iter().chain(&obs.base_ang_vel).chain(&obs.command).all(|v| v.is_finite())
        && obs.q.iter().chain(&obs.dq).all(|v| v.is_finite());
    if !finite {
        return Err(PolicyError::Observation("non-finite value in the robot observation".into()));
    }
    spec.observation.iter().map(|term| term_values(spec, term, obs, last_action)).collect()
}

fn term_values(
    spec: &PolicySpec,
    term: &ObservationTerm,
    obs: &RobotObservation,
    last_action: &[f64],
) -> Result<Vec<f64>, PolicyError> {
    let raw: Vec<f64> = match term.kind {
        TermKind::AngVel => obs.base_ang_vel.to_vec(),
        TermKind::ProjectedGravity => projected_gravity(obs.base_quat)?.to_vec(),
        TermKind::Command => obs.command.to_vec(),
        TermKind::JointPosRel => spec.policy_joints.iter().map(|&s| obs.q[s] - spec.joints[s].default_q).collect(),
        TermKind::JointVel => spec.policy_joints.iter().map(|&s| obs.dq[s]).collect(),
        TermKind::LastAction => last_action.to_vec(),
        TermKind::GaitPhaseSinCos { period } => gait_phase_sin_cos(obs.time, period).to_vec(),
    };
    let clip = spec.clip_observations.unwrap_or(f64::INFINITY);
    Ok(raw.iter().zip(&term.scale).map(|(v, s)| (v * s).clamp(-clip, clip)).collect())
}

/// The last `length` frames of every term. The first push after a reset fills the whole history with copies
/// of that frame (Isaac Lab's and the deploy scripts' convention), so the network never sees zeros.
#[derive(Debug, Clone)]
pub struct ObservationHistory {
    length: usize,
    layout: HistoryLayout,
    /// Per term, oldest frame first.
    terms: Vec<VecDeque<Vec<f64>>>,
}

impl ObservationHistory {
    pub fn new(length: usize, layout: HistoryLayout) -> Self {
        ObservationHistory { length: length.max(1), layout, terms: Vec::new() }
    }

    pub fn clear(&mut self) {
        self.terms.clear();
    }

    /// Appends one frame (as returned by [`build_frame`]).
    pub fn push(&mut self, frame: Vec<Vec<f64>>) {
        if self.terms.len() != frame.len() {
            self.terms =
                frame.into_iter().map(|t| std::iter::repeat_n(t, self.length).collect::<VecDeque<_>>()).collect();
            return;
        }
        for (hist, t) in self.terms.iter_mut().zip(frame) {
            if hist.len() == self.length {
                hist.pop_front();
            }
            hist.push_back(t);
        }
    }

    /// The network input, in the spec's layout, as `f32`.
    pub fn flatten(&self) -> Vec<f32> {
        let mut out = Vec::new();
        match self.layout {
            HistoryLayout::TermMajor => {
                for hist in &self.terms {
                    for frame in hist {
                        out.extend(frame.iter().map(|&v| v as f32));
                    }
                }
            }
            HistoryLayout::StepMajor => {
                for step in 0..self.length {
                    for hist in &self.terms {
                        if let Some(frame) = hist.get(step) {
                            out.extend(frame.iter().map(|&v| v as f32));
                        }
                    }
                }
            }
        }
        out
    }
}
