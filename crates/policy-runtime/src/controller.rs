//! [`PolicyController`]: a spec plus its network behind the [`Controller`] interface.

use crate::network::{LstmPolicy, OnnxPolicy, PolicyNetwork};
use crate::observation::{build_frame, ObservationHistory};
use crate::spec::{PolicyKind, PolicySpec, SpecError};
use crate::{Controller, PolicyError, RobotObservation};
use diff_physics::PdTarget;
use std::path::Path;

/// Runs a policy as its deploy script does: observation per spec → network → `q_des = default + scale · action`
/// on the policy's joints; every other slot holds its default angle; gains from the spec; `dq_des = 0`,
/// no feed-forward torque.
#[derive(Debug, Clone)]
pub struct PolicyController {
    spec: PolicySpec,
    network: PolicyNetwork,
    history: ObservationHistory,
    last_action: Vec<f64>,
    last_observation: Vec<f32>,
}

impl PolicyController {
    /// Loads the spec file and its model.
    pub fn load(spec_path: &Path) -> Result<Self, PolicyError> {
        Self::from_spec(PolicySpec::load(spec_path)?)
    }

    /// Loads the spec's model and checks that the spec's observation and action sizes match it.
    pub fn from_spec(spec: PolicySpec) -> Result<Self, PolicyError> {
        let network = match spec.kind {
            PolicyKind::OnnxMlp => PolicyNetwork::Onnx(OnnxPolicy::load(&spec.model_path)?),
            PolicyKind::LstmNpz => PolicyNetwork::Lstm(LstmPolicy::load(&spec.model_path, spec.lstm_initial_state)?),
            PolicyKind::LstmTorchScript => {
                PolicyNetwork::Lstm(LstmPolicy::load_torchscript(&spec.model_path, spec.lstm_initial_state)?)
            }
        };
        Self::with_network(spec, network)
    }

    /// Uses an already loaded network (e.g. one shared by several controllers).
    pub fn with_network(spec: PolicySpec, network: PolicyNetwork) -> Result<Self, PolicyError> {
        if spec.observation_dim() != network.input_dim() {
            return Err(SpecError::DimensionMismatch {
                what: format!("observation size ({} per frame × {} frames)", spec.frame_dim(), spec.history_length),
                spec: spec.observation_dim(),
                model: network.input_dim(),
            }
            .into());
        }
        if spec.action_dim() != network.output_dim() {
            return Err(SpecError::DimensionMismatch {
                what: "action size (policy joints)".into(),
                spec: spec.action_dim(),
                model: network.output_dim(),
            }
            .into());
        }
        let history = ObservationHistory::new(spec.history_length, spec.history_layout);
        let last_action = vec![0.0; spec.action_dim()];
        Ok(PolicyController { spec, network, history, last_action, last_observation: Vec::new() })
    }

    pub fn spec(&self) -> &PolicySpec {
        &self.spec
    }

    pub fn network(&self) -> &PolicyNetwork {
        &self.network
    }

    /// The network input of the last [`Controller::act`] call (empty before the first).
    pub fn last_observation(&self) -> &[f32] {
        &self.last_observation
    }

    /// The last raw action (policy order, after clipping), zeros before the first call.
    pub fn last_action(&self) -> &[f64] {
        &self.last_action
    }

    /// PD targets holding the default pose with the spec's gains (what `act` gives for a zero action).
    pub fn default_target(&self) -> PdTarget {
        let n = self.spec.nj();
        PdTarget {
            q_des: self.spec.joints.iter().map(|j| j.default_q).collect(),
            dq_des: vec![0.0; n],
            kp: self.spec.joints.iter().map(|j| j.kp).collect(),
            kd: self.spec.joints.iter().map(|j| j.kd).collect(),
            tau_ff: vec![0.0; n],
        }
    }
}

impl Controller for PolicyController {
    fn name(&self) -> &str {
        &self.spec.name
    }

    fn period(&self) -> f64 {
        self.spec.control_period
    }

    fn reset(&mut self) {
        self.history.clear();
        self.network.reset();
        self.last_action.iter_mut().for_each(|a| *a = 0.0);
        self.last_observation.clear();
    }

    fn act(&mut self, obs: &RobotObservation) -> Result<PdTarget, PolicyError> {
        let frame = build_frame(&self.spec, obs, &self.last_action)?;
        self.history.push(frame);
        let input = self.history.flatten();
        let raw = self.network.step(&input)?;
        self.last_observation = input;
        if raw.iter().any(|a| !a.is_finite()) {
            return Err(PolicyError::Inference("network output is not finite".into()));
        }
        let clip = self.spec.clip_actions.unwrap_or(f64::INFINITY);
        for (dst, &a) in self.last_action.iter_mut().zip(&raw) {
            *dst = f64::from(a).clamp(-clip, clip);
        }
        let mut target = self.default_target();
        for (&slot, &a) in self.spec.policy_joints.iter().zip(&self.last_action) {
            target.q_des[slot] += self.spec.action_scale * a;
        }
        Ok(target)
    }
}
