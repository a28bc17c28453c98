//! Policy spec files (TOML): everything a deploy script hard-codes around a network — observation terms and
//! their scales, history, action scale, which joints the policy commands and in what order, default pose,
//! PD gains, control period — so that one runtime drives every policy convention.
//!
//! A spec names joints by their URDF joint names (`left_hip_yaw_joint`, …) or by motor slot index, and lists
//! every motor slot (`[joints] slots`, slot order) with its default angle and gains: the policy's joints follow
//! its action vector, the others hold their default pose with their own gains.

use serde::Deserialize;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Errors found while reading or checking a policy spec.
#[derive(Debug, Error)]
pub enum SpecError {
    #[error("cannot read policy spec {path}: {source}")]
    Io { path: String, source: std::io::Error },
    /// The spec is not valid TOML or has unknown or missing keys (the TOML parser's error is the source).
    #[error("policy spec {path}")]
    Parse {
        path: String,
        #[source]
        source: toml::de::Error,
    },
    #[error("unknown observation term `{term}` (known: {known})")]
    UnknownTerm { term: String, known: String },
    #[error("unknown policy kind `{0}` (known: onnx_mlp, lstm_npz, lstm_torchscript)")]
    UnknownKind(String),
    #[error("unknown history layout `{0}` (known: term_major, step_major)")]
    UnknownLayout(String),
    #[error("unknown LSTM initial state `{0}` (known: stored, zeros)")]
    UnknownInitialState(String),
    #[error("unknown joint `{0}` (not a [joints] name or slot of this spec)")]
    UnknownJoint(String),
    #[error("observation term `{term}`: scale has {found} components, expected 1 or {expected}")]
    BadScale { term: String, expected: usize, found: usize },
    #[error("{what}: the spec gives {spec}, the model has {model}")]
    DimensionMismatch { what: String, spec: usize, model: usize },
    #[error("policy model file {path} does not exist")]
    MissingFile { path: String },
    #[error("model path `{0}` uses ${{ULAB_SHARED}} but ULAB_SHARED is not set (set it or pass the model path)")]
    SharedDirUnset(String),
    #[error("spec does not match the robot model: {0}")]
    RobotMismatch(String),
    #[error("invalid policy spec: {0}")]
    Invalid(String),
}

/// Which network family the model file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PolicyKind {
    /// A feed-forward ONNX network with one `1 × n` input and one `1 × m` output, run with tract.
    OnnxMlp,
    /// rsl_rl's `ActorCriticRecurrent` actor exported as plain arrays (`.npz`): one LSTM layer
    /// (`memory.*_l0`), then `actor.<k>.weight/bias` linear layers with ELU between them.
    LstmNpz,
    /// The same actor read straight from the TorchScript archive (`.pt`) legged_gym exports.
    LstmTorchScript,
}

/// What one observation term measures (before scaling).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TermKind {
    /// Pelvis angular velocity, pelvis frame (3).
    AngVel,
    /// Unit gravity direction `(0, 0, −1)` expressed in the pelvis frame (3).
    ProjectedGravity,
    /// Velocity command `(vx, vy, wz)` (3).
    Command,
    /// Policy joints' angle minus their default angle (one per policy joint).
    JointPosRel,
    /// Policy joints' velocity (one per policy joint).
    JointVel,
    /// The previous raw network output (one per policy joint; zeros on the first call).
    LastAction,
    /// `sin(2π φ), cos(2π φ)` with `φ = (time mod period) / period` (2).
    GaitPhaseSinCos { period: f64 },
}

impl TermKind {
    /// Spec-file name of the term.
    pub fn name(&self) -> &'static str {
        match self {
            TermKind::AngVel => "ang_vel",
            TermKind::ProjectedGravity => "projected_gravity",
            TermKind::Command => "command",
            TermKind::JointPosRel => "joint_pos_rel",
            TermKind::JointVel => "joint_vel",
            TermKind::LastAction => "last_action",
            TermKind::GaitPhaseSinCos { .. } => "gait_phase_sin_cos",
        }
    }
}

const KNOWN_TERMS: &str =
    "ang_vel, projected_gravity, command, joint_pos_rel, joint_vel, last_action, gait_phase_sin_cos";

/// One observation term with its per-component scale (`scale.len()` = the term's dimension).
#[derive(Debug, Clone, PartialEq)]
pub struct ObservationTerm {
    pub kind: TermKind,
    pub scale: Vec<f64>,
}

impl ObservationTerm {
    /// Number of values the term contributes to one observation frame.
    pub fn dim(&self) -> usize {
        self.scale.len()
    }
}

/// How several frames of history are laid out in the network input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HistoryLayout {
    /// Isaac Lab's: each term's `length` frames (oldest first) together, terms concatenated.
    TermMajor,
    /// Whole frames one after another, oldest first.
    StepMajor,
}

/// Recurrent state at reset, for LSTM policies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LstmInitialState {
    /// The `hidden_state` / `cell_state` arrays stored beside the weights.
    Stored,
    /// Zeros.
    Zeros,
}

/// One motor slot: default angle and PD gains used by the policy's deployment.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpec {
    pub slot: usize,
    /// URDF joint name (e.g. `left_knee_joint`).
    pub name: String,
    pub default_q: f64,
    pub kp: f64,
    pub kd: f64,
}

/// A validated policy spec.
#[derive(Debug, Clone, PartialEq)]
pub struct PolicySpec {
    pub name: String,
    pub kind: PolicyKind,
    /// Model file, resolved (relative paths against the spec file's directory, `${ULAB_SHARED}` expanded).
    pub model_path: PathBuf,
    /// Seconds between two policy calls (e.g. 0.02 for 50 Hz).
    pub control_period: f64,
    /// Terms of one observation frame, in order.
    pub observation: Vec<ObservationTerm>,
    /// Frames of history fed to the network (1 = no history).
    pub history_length: usize,
    pub history_layout: HistoryLayout,
    /// `q_des = default + action_scale · action`.
    pub action_scale: f64,
    /// Raw actions are clamped to `±clip_actions` before use (and before being fed back) when set.
    pub clip_actions: Option<f64>,
    /// Observation values are clamped to `±clip_observations` when set.
    pub clip_observations: Option<f64>,
    /// Every motor slot, slot order (`joints[i].slot == i`).
    pub joints: Vec<JointSpec>,
    /// Slot of each policy joint, in the policy's order (observation joint terms and action vector).
    pub policy_joints: Vec<usize>,
    pub lstm_initial_state: LstmInitialState,
}

// ---- raw file format ----

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSpec {
    name: String,
    kind: String,
    model: String,
    control_period: f64,
    history: Option<RawHistory>,
    lstm: Option<RawLstm>,
    action: RawAction,
    observation: Vec<RawTerm>,
    joints: RawJoints,
    clip_observations: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawJoints {
    slots: Vec<RawJoint>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHistory {
    length: usize,
    layout: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLstm {
    initial_state: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAction {
    scale: f64,
    joints: Vec<JointRef>,
    clip: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum JointRef {
    Slot(usize),
    Name(String),
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum RawScale {
    Scalar(f64),
    Vector(Vec<f64>),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTerm {
    term: String,
    scale: Option<RawScale>,
    period: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawJoint {
    slot: usize,
    name: String,
    default: f64,
    kp: f64,
    kd: f64,
}

const SHARED_VAR: &str = "${ULAB_SHARED}";

impl PolicySpec {
    /// Reads and validates a spec file; the model path is resolved against the file's directory.
    pub fn load(path: &Path) -> Result<Self, SpecError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| SpecError::Io { path: path.display().to_string(), source })?;
        let base = path.parent().unwrap_or_else(|| Path::new("."));
        Self::parse(&text, base, &path.display().to_string())
    }

    /// Parses and validates spec text; a relative model path is resolved against `base_dir`.
    pub fn from_toml_str(text: &str, base_dir: &Path) -> Result<Self, SpecError> {
        Self::parse(text, base_dir, "<text>")
    }

    /// The same spec with another model file (e.g. a retrained network with the same conventions).
    pub fn with_model_path(mut self, path: impl Into<PathBuf>) -> Self {
        self.model_path = path.into();
        self
    }

    /// Values in one observation frame.
    pub fn frame_dim(&self) -> usize {
        self.observation.iter().map(ObservationTerm::dim).sum()
    }

    /// Values in the network input (`frame_dim × history_length`).
    pub fn observation_dim(&self) -> usize {
        self.frame_dim() * self.history_length
    }

    /// Values in the network output (one per policy joint).
    pub fn action_dim(&self) -> usize {
        self.policy_joints.len()
    }

    /// Number of motor slots the spec drives.
    pub fn nj(&self) -> usize {
        self.joints.len()
    }

    /// Physics steps per policy call at timestep `dt`; the period must be a whole number of steps.
    pub fn decimation(&self, dt: f64) -> Result<usize, SpecError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(SpecError::Invalid(format!("timestep {dt} must be finite and > 0")));
        }
        let ratio = self.control_period / dt;
        let n = ratio.round();
        if n < 1.0 || (ratio - n).abs() > 1e-6 * ratio.max(1.0) {
            return Err(SpecError::Invalid(format!(
                "control period {} s is not a whole number of {dt} s steps",
                self.control_period
            )));
        }
        Ok(n as usize)
    }

    /// Checks that the spec's slots carry the robot model's joints (same count, same names at each slot).
    pub fn check_robot(&self, model: &robot_model::RobotModel) -> Result<(), SpecError> {
        if model.nj() != self.nj() {
            return Err(SpecError::RobotMismatch(format!(
                "spec lists {} joints, model `{}` has {}",
                self.nj(),
                model.name,
                model.nj()
            )));
        }
        for (j, m) in self.joints.iter().zip(&model.joints) {
            if j.name != m.name || j.slot != m.slot {
                return Err(SpecError::RobotMismatch(format!(
                    "slot {}: spec joint `{}`, model joint `{}` (slot {})",
                    j.slot, j.name, m.name, m.slot
                )));
            }
        }
        Ok(())
    }

    fn parse(text: &str, base_dir: &Path, origin: &str) -> Result<Self, SpecError> {
        let raw: RawSpec =
            toml::from_str(text).map_err(|source| SpecError::Parse { path: origin.to_string(), source })?;
        let kind = match raw.kind.as_str() {
            "onnx_mlp" => PolicyKind::OnnxMlp,
            "lstm_npz" => PolicyKind::LstmNpz,
            "lstm_torchscript" => PolicyKind::LstmTorchScript,
            other => return Err(SpecError::UnknownKind(other.to_string())),
        };
        positive("control_period", raw.control_period)?;
        if raw.name.trim().is_empty() {
            return Err(SpecError::Invalid("`name` is empty".into()));
        }

        // Joints: every slot, in order.
        if raw.joints.slots.is_empty() {
            return Err(SpecError::Invalid("[joints] slots is empty".into()));
        }
        let mut joints = Vec::with_capacity(raw.joints.slots.len());
        for (i, j) in raw.joints.slots.into_iter().enumerate() {
            if j.slot != i {
                return Err(SpecError::Invalid(format!(
                    "[joints] slots must list slots 0, 1, 2, … in order; entry {i} has slot {}",
                    j.slot
                )));
            }
            if joints.iter().any(|k: &JointSpec| k.name == j.name) {
                return Err(SpecError::Invalid(format!("joint `{}` listed twice", j.name)));
            }
            for (what, v) in [("default", j.default), ("kp", j.kp), ("kd", j.kd)] {
                if !v.is_finite() {
                    return Err(SpecError::Invalid(format!("joint `{}`: {what} is not finite", j.name)));
                }
            }
            if j.kp < 0.0 || j.kd < 0.0 {
                return Err(SpecError::Invalid(format!("joint `{}`: negative gain", j.name)));
            }
            joints.push(JointSpec { slot: j.slot, name: j.name, default_q: j.default, kp: j.kp, kd: j.kd });
        }

        // Policy joints (action order).
        let mut policy_joints = Vec::with_capacity(raw.action.joints.len());
        for r in &raw.action.joints {
            let slot = match r {
                JointRef::Slot(s) if *s < joints.len() => *s,
                JointRef::Slot(s) => return Err(SpecError::UnknownJoint(format!("slot {s}"))),
                JointRef::Name(n) => {
                    joints.iter().position(|j| &j.name == n).ok_or_else(|| SpecError::UnknownJoint(n.clone()))?
                }
            };
            if policy_joints.contains(&slot) {
                return Err(SpecError::Invalid(format!("policy joint `{}` listed twice", joints[slot].name)));
            }
            policy_joints.push(slot);
        }
        if policy_joints.is_empty() {
            return Err(SpecError::Invalid("[action] joints is empty".into()));
        }
        let n_act = policy_joints.len();

        // Observation terms.
        if raw.observation.is_empty() {
            return Err(SpecError::Invalid("no [[observation]] terms".into()));
        }
        let mut observation = Vec::with_capacity(raw.observation.len());
        for t in raw.observation {
            let kind = match t.term.as_str() {
                "ang_vel" => TermKind::AngVel,
                "projected_gravity" => TermKind::ProjectedGravity,
                "command" => TermKind::Command,
                "joint_pos_rel" => TermKind::JointPosRel,
                "joint_vel" => TermKind::JointVel,
                "last_action" => TermKind::LastAction,
                "gait_phase_sin_cos" => {
                    let period = t.period.ok_or_else(|| {
                        SpecError::Invalid("observation term `gait_phase_sin_cos` needs `period`".into())
                    })?;
                    positive("gait_phase_sin_cos period", period)?;
                    TermKind::GaitPhaseSinCos { period }
                }
                other => return Err(SpecError::UnknownTerm { term: other.to_string(), known: KNOWN_TERMS.into() }),
            };
            if t.period.is_some() && !matches!(kind, TermKind::GaitPhaseSinCos { .. }) {
                return Err(SpecError::Invalid(format!("observation term `{}` takes no `period`", t.term)));
            }
            let dim = match kind {
                TermKind::AngVel | TermKind::ProjectedGravity | TermKind::Command => 3,
                TermKind::JointPosRel | TermKind::JointVel | TermKind::LastAction => n_act,
                TermKind::GaitPhaseSinCos { .. } => 2,
            };
            let scale = match t.scale {
                None => vec![1.0; dim],
                Some(RawScale::Scalar(s)) => vec![s; dim],
                Some(RawScale::Vector(v)) if v.len() == dim => v,
                Some(RawScale::Vector(v)) if v.len() == 1 => vec![v[0]; dim],
                Some(RawScale::Vector(v)) => {
                    return Err(SpecError::BadScale { term: t.term, expected: dim, found: v.len() })
                }
            };
            if scale.iter().any(|s| !s.is_finite()) {
                return Err(SpecError::Invalid(format!("observation term `{}`: scale is not finite", t.term)));
            }
            observation.push(ObservationTerm { kind, scale });
        }

        let (history_length, history_layout) = match raw.history {
            None => (1, HistoryLayout::TermMajor),
            Some(h) => {
                if h.length == 0 {
                    return Err(SpecError::Invalid("history length must be >= 1".into()));
                }
                let layout = match h.layout.as_deref() {
                    None | Some("term_major") => HistoryLayout::TermMajor,
                    Some("step_major") => HistoryLayout::StepMajor,
                    Some(other) => return Err(SpecError::UnknownLayout(other.to_string())),
                };
                (h.length, layout)
            }
        };
        let lstm_initial_state = match raw.lstm.as_ref().map(|l| l.initial_state.as_str()) {
            None | Some("stored") => LstmInitialState::Stored,
            Some("zeros") => LstmInitialState::Zeros,
            Some(other) => return Err(SpecError::UnknownInitialState(other.to_string())),
        };
        if raw.lstm.is_some() && kind == PolicyKind::OnnxMlp {
            return Err(SpecError::Invalid("[lstm] given for a non-LSTM policy".into()));
        }
        if !raw.action.scale.is_finite() {
            return Err(SpecError::Invalid("[action] scale is not finite".into()));
        }
        if let Some(c) = raw.action.clip {
            positive("[action] clip", c)?;
        }
        if let Some(c) = raw.clip_observations {
            positive("clip_observations", c)?;
        }

        Ok(PolicySpec {
            name: raw.name,
            kind,
            model_path: resolve_model_path(&raw.model, base_dir)?,
            control_period: raw.control_period,
            observation,
            history_length,
            history_layout,
            action_scale: raw.action.scale,
            clip_actions: raw.action.clip,
            clip_observations: raw.clip_observations,
            joints,
            policy_joints,
            lstm_initial_state,
        })
    }
}

fn positive(what: &str, v: f64) -> Result<(), SpecError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(SpecError::Invalid(format!("{what} must be finite and > 0, got {v}")))
    }
}

/// `${ULAB_SHARED}/…` → the variable's value; relative → against `base_dir`; absolute as is.
fn resolve_model_path(model: &str, base_dir: &Path) -> Result<PathBuf, SpecError> {
    if let Some(rest) = model.strip_prefix(SHARED_VAR) {
        let shared = std::env::var("ULAB_SHARED").ok().filter(|s| !s.is_empty());
        let shared = shared.ok_or_else(|| SpecError::SharedDirUnset(model.to_string()))?;
        return Ok(PathBuf::from(shared).join(rest.trim_start_matches('/')));
    }
    let p = PathBuf::from(model);
    Ok(if p.is_absolute() { p } else { base_dir.join(p) })
}
