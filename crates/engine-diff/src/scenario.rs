//! The input of one rollout: a controller run plus perturbations (command sequence, observation and action
//! noise, external pushes, initial state, ground friction, timing jitter). Serialisable (corpus entries and
//! reproducers), mutable (fuzzing), and measurable ([`Scenario::magnitude`], the "unit of perturbation").
use crate::DiffError;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// A velocity command `(vx, vy, wz)` in force from `t` (s) on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CommandSegment {
    pub t: f64,
    pub command: [f64; 3],
}

/// A push: an instantaneous change `dv` (m/s, world frame) of the pelvis velocity at time `t`, applied the
/// same way in every engine (state read, velocity changed, engine reset to it), so no engine-specific force
/// API is needed. An impulse `m·dv` on a 70 kg robot: dv = 0.5 m/s is a 35 N·s shove.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Push {
    pub t: f64,
    pub dv: [f64; 3],
}

/// One rollout's input.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    /// Seeds every random stream (excitation targets, noise, jitter, initial offsets).
    pub seed: u64,
    /// Episode length (s).
    pub seconds: f64,
    /// Command sequence (sorted by `t`; before the first segment the command is zero).
    pub commands: Vec<CommandSegment>,
    /// Observation noise: joint angles ±`obs_noise` rad, joint and base angular velocities ±10× that (uniform).
    pub obs_noise: f64,
    /// Action noise: joint targets ±`action_noise` rad (uniform).
    pub action_noise: f64,
    pub pushes: Vec<Push>,
    /// Initial joint offsets from the standing pose, uniform ±`init_q_offset` rad.
    pub init_q_offset: f64,
    /// Initial pelvis height offset (m; positive = dropped from above).
    pub init_height: f64,
    /// Ground friction coefficient (None: the model's).
    pub ground_friction: Option<f64>,
    /// Each control action takes effect 0..=`timing_jitter` physics steps late (uniform per tick).
    pub timing_jitter: u32,
    /// Built-in excitation only: amplitude (rad) of its randomized joint targets.
    pub excitation: f64,
}

impl Scenario {
    /// The built-in excitation input for one seed: standing PD with randomized targets, one push and a
    /// command sequence, mild noise.
    pub fn excitation(seed: u64, seconds: f64) -> Self {
        Scenario {
            seed,
            seconds,
            commands: vec![
                CommandSegment { t: 0.0, command: [0.0, 0.0, 0.0] },
                CommandSegment { t: seconds * 0.5, command: [0.5, 0.0, 0.2] },
            ],
            obs_noise: 0.002,
            action_noise: 0.005,
            pushes: vec![Push { t: seconds * 0.4, dv: [0.15, -0.1, 0.0] }],
            init_q_offset: 0.02,
            init_height: 0.0,
            ground_friction: None,
            timing_jitter: 1,
            excitation: 0.15,
        }
    }

    /// A policy run for one seed: the same command sequence and push, no excitation.
    pub fn policy(seed: u64, seconds: f64) -> Self {
        Scenario { excitation: 0.0, ..Self::excitation(seed, seconds) }
    }

    /// The command in force at `t`.
    pub fn command_at(&self, t: f64) -> [f64; 3] {
        self.commands.iter().rfind(|c| c.t <= t + 1e-12).map(|c| c.command).unwrap_or([0.0; 3])
    }

    /// Checks ranges; a scenario read from a file or built from fuzz bytes must pass before it is run.
    pub fn validate(&self) -> Result<(), DiffError> {
        let bad = |what: &str| Err(DiffError::Input(format!("scenario: {what}")));
        let fin = |x: f64| x.is_finite();
        if !(fin(self.seconds) && self.seconds > 0.0 && self.seconds <= 600.0) {
            return bad("seconds must be in (0, 600]");
        }
        if !(fin(self.obs_noise)
            && (0.0..=0.5).contains(&self.obs_noise)
            && fin(self.action_noise)
            && (0.0..=0.5).contains(&self.action_noise))
        {
            return bad("noise amplitudes must be in [0, 0.5]");
        }
        if !(fin(self.init_q_offset)
            && (0.0..=0.5).contains(&self.init_q_offset)
            && fin(self.init_height)
            && (-0.005..=0.5).contains(&self.init_height))
        {
            return bad("initial offsets out of range (q ≤ 0.5 rad, height −0.005..0.5 m)");
        }
        if let Some(f) = self.ground_friction {
            if !(fin(f) && (0.05..=3.0).contains(&f)) {
                return bad("ground friction must be in [0.05, 3]");
            }
        }
        if self.timing_jitter > 10 || !(fin(self.excitation) && (0.0..=1.0).contains(&self.excitation)) {
            return bad("timing jitter ≤ 10 steps, excitation in [0, 1] rad");
        }
        if self.commands.len() > 64 || self.pushes.len() > 64 {
            return bad("at most 64 command segments and 64 pushes");
        }
        for c in &self.commands {
            if !fin(c.t) || c.command.iter().any(|x| !fin(*x) || x.abs() > 3.0) {
                return bad("commands must be finite, |component| ≤ 3");
            }
        }
        for p in &self.pushes {
            if !fin(p.t) || p.dv.iter().any(|x| !fin(*x) || x.abs() > 3.0) {
                return bad("pushes must be finite, |dv| ≤ 3 m/s per axis");
            }
        }
        Ok(())
    }

    /// Size of the perturbation in "units": each ingredient divided by a typical amount (noise 0.01 rad,
    /// action noise 0.05 rad, push 0.5 m/s, initial offset 0.05 rad / 0.02 m, friction change 0.2, one
    /// jitter step, command 0.5, excitation 0.2 rad). Fuzzing maximises divergence / (1 + magnitude).
    pub fn magnitude(&self, model_friction: f64) -> f64 {
        let pushes: f64 = self.pushes.iter().map(|p| norm3(p.dv)).sum::<f64>() / 0.5;
        let cmd: f64 = self.commands.iter().map(|c| norm3(c.command)).fold(0.0, f64::max) / 0.5;
        let fr = self.ground_friction.map(|f| (f - model_friction).abs() / 0.2).unwrap_or(0.0);
        self.obs_noise / 0.01
            + self.action_noise / 0.05
            + pushes
            + self.init_q_offset / 0.05
            + self.init_height.abs() / 0.02
            + fr
            + f64::from(self.timing_jitter)
            + cmd
            + self.excitation / 0.2
    }

    /// Every perturbation scaled by `a` in [0, 1] (minimization towards the unperturbed run). Times are kept.
    pub fn scaled(&self, a: f64, model_friction: f64) -> Self {
        let mut s = self.clone();
        s.obs_noise *= a;
        s.action_noise *= a;
        s.init_q_offset *= a;
        s.init_height *= a;
        s.excitation *= a;
        s.timing_jitter = (f64::from(s.timing_jitter) * a).round() as u32;
        s.ground_friction = s.ground_friction.map(|f| model_friction + (f - model_friction) * a);
        for p in &mut s.pushes {
            p.dv.iter_mut().for_each(|x| *x *= a);
        }
        for c in &mut s.commands {
            c.command.iter_mut().for_each(|x| *x *= a);
        }
        s
    }

    /// One random mutation (fuzzing), kept inside the valid ranges.
    pub fn mutate(&mut self, rng: &mut impl Rng) {
        let t_max = self.seconds;
        match rng.gen_range(0..10) {
            0 => self.obs_noise = (self.obs_noise * rng.gen_range(0.5..2.0) + rng.gen_range(0.0..0.002)).min(0.05),
            1 => self.action_noise = (self.action_noise * rng.gen_range(0.5..2.0) + rng.gen_range(0.0..0.01)).min(0.2),
            2 => {
                if self.pushes.len() < 4 && rng.gen_bool(0.6) {
                    self.pushes.push(Push {
                        t: rng.gen_range(0.0..t_max),
                        dv: [rng.gen_range(-0.6..0.6), rng.gen_range(-0.6..0.6), rng.gen_range(-0.2..0.2)],
                    });
                } else if !self.pushes.is_empty() {
                    let i = rng.gen_range(0..self.pushes.len());
                    if rng.gen_bool(0.3) {
                        self.pushes.remove(i);
                    } else {
                        let p = &mut self.pushes[i];
                        p.t = (p.t + rng.gen_range(-0.05..0.05)).clamp(0.0, t_max);
                        p.dv.iter_mut().for_each(|x| *x = (*x * rng.gen_range(0.5..1.5)).clamp(-2.0, 2.0));
                    }
                }
            }
            3 => {
                if self.commands.len() < 8 && rng.gen_bool(0.5) {
                    self.commands.push(CommandSegment {
                        t: rng.gen_range(0.0..t_max),
                        command: [rng.gen_range(-1.0..1.0), rng.gen_range(-0.5..0.5), rng.gen_range(-1.0..1.0)],
                    });
                    self.commands.sort_by(|a, b| a.t.total_cmp(&b.t));
                } else if !self.commands.is_empty() {
                    let i = rng.gen_range(0..self.commands.len());
                    self.commands[i]
                        .command
                        .iter_mut()
                        .for_each(|x| *x = (*x + rng.gen_range(-0.3..0.3)).clamp(-1.5, 1.5));
                }
            }
            4 => self.init_q_offset = (self.init_q_offset + rng.gen_range(-0.02..0.04)).clamp(0.0, 0.2),
            5 => self.init_height = (self.init_height + rng.gen_range(-0.01..0.03)).clamp(0.0, 0.1),
            6 => self.ground_friction = Some(rng.gen_range(0.2..1.5)),
            7 => self.timing_jitter = rng.gen_range(0..=4),
            8 => self.excitation = (self.excitation + rng.gen_range(-0.1..0.1)).clamp(0.0, 0.5),
            _ => self.seed = rng.gen(),
        }
    }
}

fn norm3(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Fuzz bytes (`arbitrary`) decoded into a SHORT perturbation of a rollout; every field is bounded by
/// construction, so any byte string gives a valid scenario.
#[derive(Debug, Clone, arbitrary::Arbitrary)]
pub struct FuzzPerturbation {
    pub seed: u16,
    pub obs_noise: u8,
    pub action_noise: u8,
    pub push: Option<(u8, i8, i8, i8)>,
    pub command: (i8, i8, i8),
    pub init_q_offset: u8,
    pub init_height: u8,
    pub friction: Option<u8>,
    pub jitter: u8,
    pub excitation: u8,
    /// Which pair of engines runs it ([`crate::fuzz::oracle_pair`]). Last, so that an input too short to carry it
    /// decodes every other field the same way and runs on the first pair.
    pub engines: u8,
}

impl FuzzPerturbation {
    /// The scenario, `seconds` long.
    pub fn scenario(&self, seconds: f64) -> Scenario {
        let u = |b: u8, max: f64| f64::from(b) / 255.0 * max;
        let s = |b: i8, max: f64| f64::from(b) / 128.0 * max;
        Scenario {
            seed: u64::from(self.seed),
            seconds,
            commands: vec![CommandSegment {
                t: 0.0,
                command: [s(self.command.0, 1.0), s(self.command.1, 0.5), s(self.command.2, 1.0)],
            }],
            obs_noise: u(self.obs_noise, 0.02),
            action_noise: u(self.action_noise, 0.1),
            pushes: self
                .push
                .map(|(t, x, y, z)| Push { t: u(t, seconds), dv: [s(x, 1.0), s(y, 1.0), s(z, 0.3)] })
                .into_iter()
                .collect(),
            init_q_offset: u(self.init_q_offset, 0.1),
            init_height: u(self.init_height, 0.02),
            ground_friction: self.friction.map(|f| 0.1 + u(f, 1.4)),
            timing_jitter: u32::from(self.jitter % 4),
            excitation: u(self.excitation, 0.4),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_to_zero_has_zero_magnitude_and_validates() {
        let s = Scenario::excitation(3, 1.0);
        assert!(s.validate().is_ok());
        assert!(s.magnitude(1.0) > 0.0);
        let z = s.scaled(0.0, 1.0);
        assert_eq!(z.magnitude(1.0), 0.0);
        assert!(z.validate().is_ok());
    }

    #[test]
    fn bad_values_are_rejected() {
        let mut s = Scenario::excitation(3, 1.0);
        s.obs_noise = f64::NAN;
        assert!(s.validate().is_err());
        let mut s = Scenario::excitation(3, 1.0);
        s.ground_friction = Some(-1.0);
        assert!(s.validate().is_err());
    }

    #[test]
    fn mutations_stay_valid() {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut s = Scenario::excitation(1, 0.5);
        for _ in 0..500 {
            s.mutate(&mut rng);
            assert!(s.validate().is_ok(), "{s:?}");
        }
    }
}
