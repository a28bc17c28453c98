//! What a diagnosis is asked to do ([`DiagnoseOptions`]) and which plant replays its windows. A leaf beside
//! [`super::stats`]: every stage reads the options, none of them is read back from a stage.
use crate::effects::EffectKind;
use crate::plant::{EngineChoice, Stepping};
use crate::GapError;
use serde::{Deserialize, Serialize};

/// Default window cap on the floating base ([`PlantKind::default_max_windows`]).
pub const FLOATING_MAX_WINDOWS: usize = 120;

/// Default window cap on the suspension rig ([`PlantKind::default_max_windows`]).
pub const RIG_MAX_WINDOWS: usize = 64;

/// Options of a diagnosis.
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    pub engine: EngineChoice,
    /// Window length (s).
    pub window_s: f64,
    /// At most this many windows (spread evenly over the log); `None`: the plant's default
    /// ([`PlantKind::default_max_windows`]).
    pub max_windows: Option<usize>,
    /// Train/held-out blocks alternate every `block_s` seconds.
    pub block_s: f64,
    /// Bootstrap resamples for confidence intervals.
    pub bootstrap: usize,
    pub seed: u64,
    /// Restrict the effect library (None: all).
    pub kinds: Option<Vec<EffectKind>>,
    /// Which plant replays the windows.
    pub plant: PlantChoice,
    /// How the diagnosing plant integrates a control step (one 2 ms step; the numerics stage replays others).
    pub stepping: Stepping,
}

/// The plant requested for a diagnosis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlantChoice {
    /// The rig when the log passes the rig-assumption check, the floating base otherwise.
    #[default]
    Auto,
    /// The suspension rig only: a log that fails the rig check is not diagnosed (every effect abstains).
    Rig,
    /// The floating base on flat ground ([`crate::floating`]), whatever the rig check says.
    Floating,
}

impl PlantChoice {
    /// Parses `auto`, `rig` or `floating`.
    pub fn parse(s: &str) -> Result<Self, GapError> {
        match s {
            "auto" => Ok(PlantChoice::Auto),
            "rig" => Ok(PlantChoice::Rig),
            "floating" => Ok(PlantChoice::Floating),
            other => Err(GapError::Input(format!("unknown plant {other:?} (auto, rig, floating)"))),
        }
    }

    /// The plant that replays the windows given the rig check's verdict; `None` when the rig was requested and the
    /// log is not from a suspended robot (the diagnosis then abstains instead of fitting the wrong plant).
    pub(super) fn resolve(self, suspended: bool) -> Option<PlantKind> {
        match self {
            PlantChoice::Rig if !suspended => None,
            PlantChoice::Rig => Some(PlantKind::Rig),
            PlantChoice::Auto if suspended => Some(PlantKind::Rig),
            PlantChoice::Auto | PlantChoice::Floating => Some(PlantKind::Floating),
        }
    }
}

/// The plant a diagnosis used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlantKind {
    /// The robot on the suspension rig ([`crate::plant::Rig`]).
    #[default]
    Rig,
    /// The robot on flat ground, base state estimated from the log ([`crate::floating::FloatingPlant`]).
    Floating,
}

impl PlantKind {
    /// Default window cap, which sets a diagnosis's cost: every candidate fit replays its training windows (MuJoCo's
    /// step is nearly all of the time), so the time grows with the windows and not with the log's length. On the rig
    /// 64 windows (32 training, 32 held-out) give each held-out interval 32 samples, enough for a percentile
    /// bootstrap, at a cost independent of the log's length (a 6 s log holds fewer). A floating-base window (ground
    /// contact, a base estimate per start) costs about three rig windows, so its cap is 120 of them.
    pub fn default_max_windows(self) -> usize {
        match self {
            PlantKind::Rig => RIG_MAX_WINDOWS,
            PlantKind::Floating => FLOATING_MAX_WINDOWS,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            PlantKind::Rig => "rig",
            PlantKind::Floating => "floating",
        }
    }
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            engine: EngineChoice::mujoco("implicitfast"),
            window_s: 0.1,
            max_windows: None,
            block_s: 1.0,
            bootstrap: 200,
            seed: 1,
            kinds: None,
            plant: PlantChoice::Auto,
            stepping: Stepping::DIAGNOSING,
        }
    }
}
