//! A small parameterised gait and the optimiser that tunes it in ONE engine (issue 15, item 3): a controller
//! whose exploitation of its training engine is known by construction, to check that [`crate::validate`]
//! flags what a policy learned from one engine's defects.
//!
//! The gait is a periodic pattern of leg joint targets around the standing pose (one frequency, an amplitude
//! and a phase per leg joint, the right leg half a period behind the left, three posture offsets) with two
//! proportional feedback terms from the pelvis attitude to the ankles. It walks only while the command asks for
//! forward speed. [`optimise`] runs the cross-entropy method over its [`GAIT_DIM`] parameters, maximising the
//! mean task score of [`crate::validate::task_score`] for the forward command in the training engine alone.
//! Nothing in the search rewards behaving the same elsewhere: whatever it gains from that engine's contact model,
//! joint handling or integrator is the "cheat" the validation is meant to expose.
use crate::harness::{ControllerFactory, EngineFactory, HarnessConfig};
use crate::validate::{episode_score, CommandCase};
use crate::DiffError;
use diff_physics::PdTarget;
use policy_runtime::{Controller, PolicyError, RobotObservation};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};

/// Number of gait parameters (the layout is documented on [`GaitParams`]).
pub const GAIT_DIM: usize = 16;

/// The leg joints the pattern drives, by motor-name suffix, with the largest amplitude each may get (rad).
const PATTERN_JOINTS: [(&str, f64); 5] =
    [("hip_pitch", 0.5), ("hip_roll", 0.15), ("knee", 0.6), ("ankle_pitch", 0.35), ("ankle_roll", 0.15)];

/// Gait parameters θ ∈ [−1, 1]^[`GAIT_DIM`]; θ = 0 stands still. Layout: `[0]` frequency 1.5 ± 1 Hz;
/// `[1..6]` amplitude |θ|·max of hip pitch, hip roll, knee, ankle pitch, ankle roll; `[6..11]` their phases
/// π·θ; `[11..14]` posture offsets of hip pitch ±0.2, knee ±0.3, ankle pitch ±0.2 rad (both legs, while
/// walking); `[14]` pelvis pitch to ankle pitch gain ±2 rad/rad; `[15]` pelvis roll to ankle roll gain ±2 rad/rad.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GaitParams {
    pub theta: Vec<f64>,
}

impl GaitParams {
    /// The standing pattern (θ = 0).
    pub fn standing() -> Self {
        GaitParams { theta: vec![0.0; GAIT_DIM] }
    }

    fn th(&self, i: usize) -> f64 {
        self.theta.get(i).copied().filter(|x| x.is_finite()).unwrap_or(0.0).clamp(-1.0, 1.0)
    }

    /// Pattern frequency (Hz).
    pub fn frequency(&self) -> f64 {
        1.5 + self.th(0)
    }
}

/// Joint indices of one pattern joint in both legs.
#[derive(Debug, Clone, Copy)]
struct LegPair {
    left: usize,
    right: usize,
    max_amplitude: f64,
}

/// The gait as a [`Controller`] (100 Hz). Gains are the model's, the ankles stiffened to kp 600 / kd 10 as in
/// [`crate::excitation`], because the RL gains cannot hold a pose without a balancing policy.
#[derive(Debug, Clone)]
pub struct GaitController {
    params: GaitParams,
    base: PdTarget,
    pattern: Vec<LegPair>,
    hip_pitch: Option<LegPair>,
    knee: Option<LegPair>,
    ankle_pitch: Option<LegPair>,
    ankle_roll: Option<LegPair>,
    /// Time the forward command started (the pattern ramps in from there).
    walking_since: Option<f64>,
}

/// Seconds over which the pattern ramps in once the command asks for forward speed.
const RAMP_S: f64 = 0.5;
/// Forward command (m/s) above which the gait walks.
const WALK_COMMAND: f64 = 0.05;

impl GaitController {
    pub const PERIOD: f64 = 0.01;

    /// A gait for `model`; errors if the model lacks the leg joints the pattern drives.
    pub fn new(model: &RobotModel, params: GaitParams) -> Result<Self, DiffError> {
        if params.theta.len() != GAIT_DIM {
            return Err(DiffError::Input(format!("gait needs {GAIT_DIM} parameters, got {}", params.theta.len())));
        }
        let mut base = PdTarget::hold_standing(model);
        for (i, j) in model.joints.iter().enumerate() {
            if j.motor_name.contains("ankle") {
                base.kp[i] = 600.0;
                base.kd[i] = 10.0;
            }
        }
        let find = |side: &str, suffix: &str| {
            model.joints.iter().position(|j| j.motor_name.starts_with(side) && j.motor_name.ends_with(suffix))
        };
        let pair = |suffix: &str, max_amplitude: f64| -> Result<LegPair, DiffError> {
            match (find("left", suffix), find("right", suffix)) {
                (Some(left), Some(right)) => Ok(LegPair { left, right, max_amplitude }),
                _ => Err(DiffError::Input(format!("model {} has no left/right {suffix} joint", model.name))),
            }
        };
        let pattern = PATTERN_JOINTS.iter().map(|(s, a)| pair(s, *a)).collect::<Result<Vec<_>, _>>()?;
        let by = |s: &str| PATTERN_JOINTS.iter().position(|(n, _)| *n == s).map(|i| pattern[i]);
        Ok(GaitController {
            hip_pitch: by("hip_pitch"),
            knee: by("knee"),
            ankle_pitch: by("ankle_pitch"),
            ankle_roll: by("ankle_roll"),
            params,
            base,
            pattern,
            walking_since: None,
        })
    }

    /// A [`ControllerFactory`] of this gait (each episode gets a fresh copy).
    pub fn factory(model: &RobotModel, params: GaitParams) -> Result<Box<ControllerFactory>, DiffError> {
        let proto = GaitController::new(model, params)?;
        Ok(Box::new(move |_s| Ok(Box::new(proto.clone()) as Box<dyn Controller>)))
    }
}

/// Pelvis (roll, pitch) from the `[w, x, y, z]` quaternion.
fn roll_pitch(q: [f64; 4]) -> (f64, f64) {
    let [w, x, y, z] = q;
    let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
    let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
    (roll, pitch)
}

impl Controller for GaitController {
    fn name(&self) -> &str {
        "gait"
    }
    fn period(&self) -> f64 {
        Self::PERIOD
    }
    fn reset(&mut self) {
        self.walking_since = None;
    }
    fn act(&mut self, obs: &RobotObservation) -> Result<PdTarget, PolicyError> {
        let n = self.base.q_des.len();
        if obs.q.len() != n || obs.dq.len() != n {
            return Err(PolicyError::Observation(format!(
                "expected {n} joints, got {} / {}",
                obs.q.len(),
                obs.dq.len()
            )));
        }
        let mut t = self.base.clone();
        if obs.command[0] > WALK_COMMAND {
            self.walking_since.get_or_insert(obs.time);
        } else {
            self.walking_since = None;
        }
        let Some(since) = self.walking_since else { return Ok(t) };
        let p = &self.params;
        let ramp = ((obs.time - since) / RAMP_S).clamp(0.0, 1.0);
        let phase = 2.0 * std::f64::consts::PI * p.frequency() * (obs.time - since);
        for (k, leg) in self.pattern.iter().enumerate() {
            let amplitude = ramp * leg.max_amplitude * p.th(1 + k).abs();
            let offset = std::f64::consts::PI * p.th(6 + k);
            t.q_des[leg.left] += amplitude * (phase + offset).sin();
            t.q_des[leg.right] += amplitude * (phase + offset + std::f64::consts::PI).sin();
        }
        let posture =
            [(self.hip_pitch, 0.2 * p.th(11)), (self.knee, 0.3 * p.th(12)), (self.ankle_pitch, 0.2 * p.th(13))];
        for (leg, off) in posture.into_iter().filter_map(|(l, o)| l.map(|l| (l, o))) {
            t.q_des[leg.left] += ramp * off;
            t.q_des[leg.right] += ramp * off;
        }
        let (roll, pitch) = roll_pitch(obs.base_quat);
        let fb = [(self.ankle_pitch, 2.0 * p.th(14) * pitch), (self.ankle_roll, 2.0 * p.th(15) * roll)];
        for (leg, d) in fb.into_iter().filter_map(|(l, d)| l.map(|l| (l, d))) {
            t.q_des[leg.left] += ramp * d;
            t.q_des[leg.right] += ramp * d;
        }
        Ok(t)
    }
}

/// Settings of the cross-entropy search.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GaitSearchConfig {
    pub population: usize,
    pub elites: usize,
    pub iterations: usize,
    /// Initial standard deviation of every θ component.
    pub sigma0: f64,
    /// Floor of the standard deviation (keeps the search from collapsing early).
    pub min_sigma: f64,
    /// Episode seeds the fitness averages over (the validation should use other seeds).
    pub seeds: Vec<u64>,
    pub seconds: f64,
    /// Seed of the search's own random stream.
    pub rng_seed: u64,
}

impl Default for GaitSearchConfig {
    fn default() -> Self {
        GaitSearchConfig {
            population: 16,
            elites: 4,
            iterations: 10,
            sigma0: 0.5,
            min_sigma: 0.05,
            seeds: vec![101, 102],
            seconds: 4.0,
            rng_seed: 7,
        }
    }
}

/// The result of a search: the best parameters found, their fitness and the best fitness per iteration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GaitOptimum {
    pub params: GaitParams,
    pub fitness: f64,
    pub engine: String,
    pub history: Vec<f64>,
    pub episodes: usize,
}

/// Mean task score of `params` for `case` over the configured seeds in one engine.
pub fn fitness(
    model: &RobotModel,
    engine: &dyn EngineFactory,
    params: &GaitParams,
    case: &CommandCase,
    c: &GaitSearchConfig,
    cfg: &HarnessConfig,
) -> Result<f64, DiffError> {
    let ctrl = GaitController::factory(model, params.clone())?;
    let mut sum = 0.0;
    for &seed in &c.seeds {
        sum += episode_score(model, engine, ctrl.as_ref(), case, seed, c.seconds, cfg)?.score;
    }
    Ok(sum / c.seeds.len().max(1) as f64)
}

/// Cross-entropy search of the gait parameters for `case` in `engine` alone (deterministic for a config).
pub fn optimise(
    model: &RobotModel,
    engine: &dyn EngineFactory,
    case: &CommandCase,
    c: &GaitSearchConfig,
    cfg: &HarnessConfig,
) -> Result<GaitOptimum, DiffError> {
    if c.population == 0 || c.elites == 0 || c.elites > c.population || c.seeds.is_empty() {
        return Err(DiffError::Input(format!(
            "gait search needs 0 < elites ({}) <= population ({}) and at least one seed",
            c.elites, c.population
        )));
    }
    if !(c.sigma0.is_finite() && c.sigma0 > 0.0 && c.min_sigma.is_finite() && c.min_sigma >= 0.0) {
        return Err(DiffError::Input("gait search sigmas must be finite and positive".into()));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(c.rng_seed);
    let mut mean = [0.0; GAIT_DIM];
    let mut sigma = [c.sigma0; GAIT_DIM];
    let mut best = (GaitParams::standing(), f64::NEG_INFINITY);
    let mut history = Vec::with_capacity(c.iterations);
    let mut episodes = 0;
    for _ in 0..c.iterations {
        let mut samples: Vec<GaitParams> = (0..c.population)
            .map(|_| GaitParams {
                theta: (0..GAIT_DIM)
                    .map(|i| {
                        // Box-Muller: one standard normal from two uniforms.
                        let (u1, u2): (f64, f64) = (rng.gen_range(f64::EPSILON..1.0), rng.gen());
                        let z = (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos();
                        (mean[i] + sigma[i] * z).clamp(-1.0, 1.0)
                    })
                    .collect(),
            })
            .collect();
        // The incumbent is re-evaluated with the population (elitism keeps the best found so far).
        samples.push(best.0.clone());
        let scores =
            samples.par_iter().map(|p| fitness(model, engine, p, case, c, cfg)).collect::<Result<Vec<f64>, _>>()?;
        episodes += samples.len() * c.seeds.len();
        let mut order: Vec<usize> = (0..samples.len()).collect();
        order.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]));
        if scores[order[0]] > best.1 || order[0] == samples.len() - 1 {
            best = (samples[order[0]].clone(), scores[order[0]]);
        }
        history.push(best.1);
        let elite = &order[..c.elites];
        for i in 0..GAIT_DIM {
            let m = elite.iter().map(|&k| samples[k].theta[i]).sum::<f64>() / c.elites as f64;
            let v = elite.iter().map(|&k| (samples[k].theta[i] - m).powi(2)).sum::<f64>() / c.elites as f64;
            mean[i] = m;
            sigma[i] = v.sqrt().max(c.min_sigma);
        }
    }
    Ok(GaitOptimum { params: best.0, fitness: best.1, engine: engine.name(), history, episodes })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(model: &RobotModel, time: f64, vx: f64) -> RobotObservation {
        RobotObservation {
            time,
            base_quat: [1.0, 0.0, 0.0, 0.0],
            base_ang_vel: [0.0; 3],
            q: model.default_q(),
            dq: vec![0.0; model.nj()],
            command: [vx, 0.0, 0.0],
        }
    }

    #[test]
    fn standing_params_or_no_command_hold_the_standing_pose() {
        let model = RobotModel::h1_2().expect("model");
        let stand = PdTarget::hold_standing(&model).q_des;
        let mut walk = GaitController::new(&model, GaitParams { theta: vec![0.7; GAIT_DIM] }).expect("gait");
        assert_eq!(walk.act(&obs(&model, 0.3, 0.0)).expect("act").q_des, stand);
        let mut still = GaitController::new(&model, GaitParams::standing()).expect("gait");
        still.act(&obs(&model, 0.0, 0.5)).expect("act");
        assert_eq!(still.act(&obs(&model, 1.3, 0.5)).expect("act").q_des, stand);
    }

    #[test]
    fn legs_move_half_a_period_apart_once_walking() {
        let model = RobotModel::h1_2().expect("model");
        let mut th = vec![0.0; GAIT_DIM];
        th[1] = 1.0; // hip pitch amplitude 0.5 rad, phase 0
        let mut g = GaitController::new(&model, GaitParams { theta: th.clone() }).expect("gait");
        g.act(&obs(&model, 1.0, 0.5)).expect("act");
        // A period and a quarter after the start (the ramp is over): sin = 1 on the left, −1 on the right.
        let t = 1.0 + 1.25 / GaitParams { theta: th }.frequency();
        assert!(t - 1.0 > RAMP_S);
        let q = g.act(&obs(&model, t, 0.5)).expect("act").q_des;
        let stand = PdTarget::hold_standing(&model).q_des;
        let l = model.joints.iter().position(|j| j.motor_name == "left_hip_pitch").expect("joint");
        let r = model.joints.iter().position(|j| j.motor_name == "right_hip_pitch").expect("joint");
        assert!((q[l] - stand[l] - 0.5).abs() < 1e-9 && (q[r] - stand[r] + 0.5).abs() < 1e-9, "{q:?}");
    }

    #[test]
    fn bad_parameter_counts_and_search_settings_are_typed_errors() {
        let model = RobotModel::h1_2().expect("model");
        assert!(matches!(GaitController::new(&model, GaitParams { theta: vec![0.0; 3] }), Err(DiffError::Input(_))));
        let f = crate::harness::builtin_factories(&["mujoco".to_string()]).expect("engine");
        let case = CommandCase { name: "forward".into(), command: [0.5, 0.0, 0.0] };
        let bad = GaitSearchConfig { elites: 20, ..GaitSearchConfig::default() };
        assert!(matches!(
            optimise(&model, f[0].as_ref(), &case, &bad, &HarnessConfig::default()),
            Err(DiffError::Input(_))
        ));
    }
}
