//! The effect library: each unmodelled effect with its physical parameter, unit of fitting (whole robot, joint
//! group, joint, IMU), search range and "no effect" value.
use crate::plant::Effects;
use serde::{Deserialize, Serialize};

/// What one fitted parameter applies to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scope {
    /// One value for the whole robot.
    Global,
    /// One value per joint group ([`crate::plant::GROUPS`]).
    Group,
    /// One value per joint.
    Joint,
    /// Three values on the IMU, fitted in closed form.
    Imu,
}

/// Effect kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    Armature,
    Damping,
    Friction,
    TorqueSaturation,
    Latency,
    GainScale,
    Backlash,
    EncoderOffset,
    ImuBias,
    ImuMisalignment,
    LinkMass,
    LinkCom,
    ContactFriction,
    ContactStiffness,
}

impl EffectKind {
    pub const ALL: [EffectKind; 14] = [
        EffectKind::Armature,
        EffectKind::Damping,
        EffectKind::Friction,
        EffectKind::TorqueSaturation,
        EffectKind::Latency,
        EffectKind::GainScale,
        EffectKind::Backlash,
        EffectKind::EncoderOffset,
        EffectKind::ImuBias,
        EffectKind::ImuMisalignment,
        EffectKind::LinkMass,
        EffectKind::LinkCom,
        EffectKind::ContactFriction,
        EffectKind::ContactStiffness,
    ];

    pub fn name(self) -> &'static str {
        match self {
            EffectKind::Armature => "armature",
            EffectKind::Damping => "damping",
            EffectKind::Friction => "friction",
            EffectKind::TorqueSaturation => "torque_saturation",
            EffectKind::Latency => "latency",
            EffectKind::GainScale => "gain_scale",
            EffectKind::Backlash => "backlash",
            EffectKind::EncoderOffset => "encoder_offset",
            EffectKind::ImuBias => "imu_bias",
            EffectKind::ImuMisalignment => "imu_misalignment",
            EffectKind::LinkMass => "link_mass",
            EffectKind::LinkCom => "link_com",
            EffectKind::ContactFriction => "contact_friction",
            EffectKind::ContactStiffness => "contact_stiffness",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == s)
    }

    pub fn scope(self) -> Scope {
        match self {
            EffectKind::Latency | EffectKind::ContactFriction | EffectKind::ContactStiffness => Scope::Global,
            EffectKind::EncoderOffset => Scope::Joint,
            EffectKind::ImuBias | EffectKind::ImuMisalignment => Scope::Imu,
            _ => Scope::Group,
        }
    }

    /// What the parameter means, with its unit.
    pub fn parameter(self) -> &'static str {
        match self {
            EffectKind::Armature => "armature multiplier (reflected rotor inertia, x model value)",
            EffectKind::Damping => "extra viscous damping (N·m·s/rad)",
            EffectKind::Friction => "extra Coulomb friction (N·m), stiction 1.5x near zero speed",
            EffectKind::TorqueSaturation => "available torque (x nominal limit) with a torque-speed line",
            EffectKind::Latency => "command latency (ms)",
            EffectKind::GainScale => "kp/kd multiplier",
            EffectKind::Backlash => "dead band width (rad)",
            EffectKind::EncoderOffset => "encoder offset (rad)",
            EffectKind::ImuBias => "gyroscope bias (rad/s, IMU frame)",
            EffectKind::ImuMisalignment => "IMU mounting rotation (rad, rotation vector)",
            EffectKind::LinkMass => "link mass and inertia multiplier",
            EffectKind::LinkCom => "link COM shift along the link z axis (m)",
            EffectKind::ContactFriction => "foot-ground friction coefficient",
            EffectKind::ContactStiffness => "foot-ground contact time constant (s)",
        }
    }

    /// Needs a new engine (model-level effect; the contact parameters are built into the engine's ground).
    pub fn model_level(self) -> bool {
        matches!(
            self,
            EffectKind::Armature
                | EffectKind::LinkMass
                | EffectKind::LinkCom
                | EffectKind::ContactFriction
                | EffectKind::ContactStiffness
        )
    }

    /// Fitting range `(lo, hi)` and the no-effect value: what is physically plausible for a humanoid's actuators and
    /// links (up to five times the modelled armature, a few N·m of damping or friction, a dead band of a few degrees,
    /// 50 ms of latency, half or twice the gains, a link 2.5 times heavier or 12 cm off); a fit that wants more stands
    /// in for another effect ([`crate::diagnose::Thresholds`]).
    pub fn range(self) -> (f64, f64, f64) {
        match self {
            EffectKind::Armature => (0.3, 5.0, 1.0),
            EffectKind::Damping => (-0.8, 6.0, 0.0),
            EffectKind::Friction => (0.0, 6.0, 0.0),
            EffectKind::TorqueSaturation => (0.2, 1.0, 1.0),
            EffectKind::Latency => (0.0, 25.0, 0.0),
            EffectKind::GainScale => (0.4, 2.0, 1.0),
            EffectKind::Backlash => (0.0, 0.1, 0.0),
            EffectKind::EncoderOffset => (-0.15, 0.15, 0.0),
            EffectKind::ImuBias => (-0.5, 0.5, 0.0),
            EffectKind::ImuMisalignment => (-0.2, 0.2, 0.0),
            EffectKind::LinkMass => (0.5, 2.5, 1.0),
            EffectKind::LinkCom => (-0.12, 0.12, 0.0),
            EffectKind::ContactFriction => (0.2, 1.5, 1.0),
            EffectKind::ContactStiffness => (0.005, 0.05, 0.02),
        }
    }

    /// The size of this effect that a diagnosis should be able to see, in the fitting parameter's units (latency:
    /// plant steps): of the order of the errors found on real actuators and models (a tenth to a fifth of a
    /// nominal value, a centimetre, a degree, 10 ms). The identifiability stage asks whether the log would show
    /// an effect this large ([`crate::diagnose::Identifiability`]).
    pub fn magnitude_of_interest(self) -> f64 {
        match self {
            EffectKind::Armature => 1.5,
            EffectKind::Damping => 1.0,
            EffectKind::Friction => 1.0,
            EffectKind::TorqueSaturation => 0.8,
            EffectKind::Latency => 5.0,
            EffectKind::GainScale => 0.8,
            EffectKind::Backlash => 0.02,
            EffectKind::EncoderOffset => 0.02,
            EffectKind::ImuBias => 0.05,
            EffectKind::ImuMisalignment => 0.02,
            EffectKind::LinkMass => 1.2,
            EffectKind::LinkCom => 0.02,
            EffectKind::ContactFriction => 0.5,
            EffectKind::ContactStiffness => 0.04,
        }
    }

    /// The motion that makes this effect show in a log (what to record when it is not identifiable).
    pub fn revealed_by(self) -> &'static str {
        match self {
            EffectKind::Armature => "fast joint accelerations (chirps or steps above a few hertz)",
            EffectKind::Damping => "sustained joint velocity in both directions",
            EffectKind::Friction => "slow motion with velocity reversals",
            EffectKind::TorqueSaturation => "commands that drive the joint torque to its limit",
            EffectKind::Latency => "fast command changes (steps, chirps above a few hertz)",
            EffectKind::GainScale => "tracking errors under load (steps, holds against gravity)",
            EffectKind::Backlash => "load reversals at low speed",
            EffectKind::EncoderOffset => "holding several poses under different gravity loads",
            EffectKind::ImuBias | EffectKind::ImuMisalignment => "a logged IMU at rest and turning",
            EffectKind::LinkMass | EffectKind::LinkCom => "holding the limb at several angles and accelerating it",
            EffectKind::ContactFriction => "foot slip on the ground (pushes, turns)",
            EffectKind::ContactStiffness => "landings and weight shifts between the feet",
        }
    }

    /// Can be identified on the suspension rig (no foot contact).
    pub fn identifiable_suspended(self) -> bool {
        !matches!(self, EffectKind::ContactFriction | EffectKind::ContactStiffness)
    }

    /// Sets the parameter of joint `j` (Group/Joint scopes) or the global value.
    pub fn set(self, fx: &mut Effects, j: usize, v: f64) {
        match self {
            EffectKind::Armature => fx.armature_scale[j] = v,
            EffectKind::Damping => fx.damping[j] = v,
            EffectKind::Friction => fx.coulomb[j] = v,
            EffectKind::TorqueSaturation => fx.torque_scale[j] = v,
            EffectKind::Latency => fx.latency_steps = v.round().max(0.0) as usize,
            EffectKind::GainScale => fx.gain_scale[j] = v,
            EffectKind::Backlash => fx.backlash[j] = v,
            EffectKind::EncoderOffset => fx.encoder_offset[j] = v,
            EffectKind::ImuBias => fx.imu_gyro_bias[j.min(2)] = v,
            EffectKind::ImuMisalignment => fx.imu_misalignment[j.min(2)] = v,
            EffectKind::LinkMass => fx.mass_scale[j] = v,
            EffectKind::LinkCom => fx.com_shift[j] = v,
            // Kept physical when a fit steps past the range's end (a coefficient > 0; MuJoCo needs a time constant of
            // at least two timesteps).
            EffectKind::ContactFriction => fx.contact_friction = Some(v.max(0.05)),
            EffectKind::ContactStiffness => fx.contact_timeconst = Some(v.max(2.0 * crate::plant::DT)),
        }
    }

    /// Reads the parameter of joint `j` back.
    pub fn get(self, fx: &Effects, j: usize) -> f64 {
        match self {
            EffectKind::Armature => fx.armature_scale[j],
            EffectKind::Damping => fx.damping[j],
            EffectKind::Friction => fx.coulomb[j],
            EffectKind::TorqueSaturation => fx.torque_scale[j],
            EffectKind::Latency => fx.latency_steps as f64,
            EffectKind::GainScale => fx.gain_scale[j],
            EffectKind::Backlash => fx.backlash[j],
            EffectKind::EncoderOffset => fx.encoder_offset[j],
            EffectKind::ImuBias => fx.imu_gyro_bias[j.min(2)],
            EffectKind::ImuMisalignment => fx.imu_misalignment[j.min(2)],
            EffectKind::LinkMass => fx.mass_scale[j],
            EffectKind::LinkCom => fx.com_shift[j],
            // `None`: the model's / engine's value, which is the range's no-effect value.
            EffectKind::ContactFriction => fx.contact_friction.unwrap_or(self.range().2),
            EffectKind::ContactStiffness => fx.contact_timeconst.unwrap_or(self.range().2),
        }
    }

    /// Copies this kind's parameters from `src` into `dst`.
    pub fn copy(self, src: &Effects, dst: &mut Effects) {
        let n = src.damping.len();
        match self.scope() {
            Scope::Global => self.set(dst, 0, self.get(src, 0)),
            Scope::Imu => (0..3).for_each(|k| self.set(dst, k, self.get(src, k))),
            _ => (0..n).for_each(|j| self.set(dst, j, self.get(src, j))),
        }
    }
}
