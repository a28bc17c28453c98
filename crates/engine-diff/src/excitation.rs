//! The built-in excitation input: standing PD with randomized joint targets and command-dependent leaning,
//! so that `ulab diff` has something to drive the engines with on a fresh clone (no policy files).
use diff_physics::PdTarget;
use policy_runtime::{Controller, PolicyError, RobotObservation};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robot_model::RobotModel;

/// Standing PD whose targets wander randomly around the standing pose.
///
/// Gains are the model's, except the ankles: the RL gains (ankle kp 40) cannot hold a static pose without
/// a balancing policy (toppling stiffness m·g·h ≈ 690 N·m/rad against 2·40), so the ankles get kp 600 / kd 10
/// as in the standing oracle of `diff_physics::oracle`.
#[derive(Debug)]
pub struct ExcitationController {
    base: PdTarget,
    amplitude: f64,
    seed: u64,
    rng: ChaCha8Rng,
    /// Current and next random offsets; targets blend linearly between them over `hold` seconds.
    from: Vec<f64>,
    to: Vec<f64>,
    segment_start: f64,
    /// Joints that get random offsets (legs get a third of the amplitude so that the feet stay planted).
    scale: Vec<f64>,
    hip_pitch: Vec<usize>,
    hip_yaw: Vec<usize>,
}

impl ExcitationController {
    /// Seconds between random target changes.
    pub const HOLD: f64 = 0.2;
    pub const PERIOD: f64 = 0.02;

    pub fn new(model: &RobotModel, amplitude: f64, seed: u64) -> Self {
        let mut base = PdTarget::hold_standing(model);
        for (i, j) in model.joints.iter().enumerate() {
            if j.motor_name.contains("ankle") {
                base.kp[i] = 600.0;
                base.kd[i] = 10.0;
            }
        }
        let leg = |n: &str| n.contains("hip") || n.contains("knee") || n.contains("ankle");
        let scale = model.joints.iter().map(|j| if leg(&j.motor_name) { 1.0 / 3.0 } else { 1.0 }).collect();
        let find = |pat: &str| {
            model.joints.iter().enumerate().filter(|(_, j)| j.motor_name.contains(pat)).map(|(i, _)| i).collect()
        };
        let n = model.nj();
        let mut c = ExcitationController {
            base,
            amplitude,
            seed,
            rng: ChaCha8Rng::seed_from_u64(seed),
            from: vec![0.0; n],
            to: vec![0.0; n],
            segment_start: 0.0,
            scale,
            hip_pitch: find("hip_pitch"),
            hip_yaw: find("hip_yaw"),
        };
        c.reset();
        c
    }

    fn draw(&mut self) -> Vec<f64> {
        let a = self.amplitude;
        self.scale.iter().map(|s| if a > 0.0 { self.rng.gen_range(-a..=a) * s } else { 0.0 }).collect()
    }
}

impl Controller for ExcitationController {
    fn name(&self) -> &str {
        "excitation"
    }
    fn period(&self) -> f64 {
        Self::PERIOD
    }
    fn reset(&mut self) {
        self.rng = ChaCha8Rng::seed_from_u64(self.seed);
        self.from = vec![0.0; self.base.q_des.len()];
        self.to = self.draw();
        self.segment_start = 0.0;
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
        while obs.time >= self.segment_start + Self::HOLD {
            self.from = std::mem::take(&mut self.to);
            self.to = self.draw();
            self.segment_start += Self::HOLD;
        }
        let w = ((obs.time - self.segment_start) / Self::HOLD).clamp(0.0, 1.0);
        let mut t = self.base.clone();
        for i in 0..n {
            t.q_des[i] += self.from[i] * (1.0 - w) + self.to[i] * w;
        }
        // Command response: lean forward/back with vx (hip pitch) and twist with wz (hip yaw), bounded.
        let [vx, _vy, wz] = obs.command;
        for &i in &self.hip_pitch {
            t.q_des[i] -= 0.1 * vx.clamp(-1.0, 1.0);
        }
        for &i in &self.hip_yaw {
            t.q_des[i] += 0.1 * wz.clamp(-1.0, 1.0);
        }
        Ok(t)
    }
}
