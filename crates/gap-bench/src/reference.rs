//! The reference ("real") plants' sensors and the floating-base reference plant: what generates the benchmark's and
//! the tests' walking logs (moved out of `gap-diagnosis`, which only reads logs).
use diff_physics::State;
use gap_diagnosis::floating::{BaseState, FloatingPlant};
use gap_diagnosis::log::{Command, Measurement, RobotLog};
use gap_diagnosis::plant::{idle_command, imu_reading_floating, Effects, EngineChoice, DT};
use gap_diagnosis::GapError;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};

/// Standard deviations of the sensor noise of a reference plant (the blind benchmark's "real" robot).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SensorNoise {
    /// Joint position (rad).
    pub q: f64,
    /// Joint velocity (rad/s).
    pub dq: f64,
    /// Estimated joint torque (N·m).
    pub tau: f64,
    /// IMU angular velocity (rad/s).
    pub gyro: f64,
    /// IMU quaternion components.
    pub quat: f64,
    /// Accelerometer (m/s²).
    #[serde(default)]
    pub acc: f64,
}

impl Default for SensorNoise {
    fn default() -> Self {
        SensorNoise { q: 2e-4, dq: 0.01, tau: 0.1, gyro: 0.003, quat: 5e-4, acc: 0.05 }
    }
}

/// The reference ("real") floating-base plant that generates test and benchmark logs.
#[derive(Debug, Clone)]
pub struct FloatingRealConfig {
    pub engine: EngineChoice,
    pub effects: Effects,
    pub noise: SensorNoise,
    /// Controller period (s).
    pub cmd_period: f64,
    /// Each command reaches the log (and the motors) up to this long after it was computed (uniform, s).
    pub jitter_s: f64,
    pub duration: f64,
    pub seed: u64,
}

impl FloatingRealConfig {
    /// MuJoCo RK4, default sensor noise, 50 Hz commands with up to 2 ms delay.
    pub fn new(model: &RobotModel, duration: f64, seed: u64) -> Self {
        FloatingRealConfig {
            engine: EngineChoice::mujoco("RK4"),
            effects: Effects::none(model.nj()),
            noise: SensorNoise::default(),
            cmd_period: 0.02,
            jitter_s: 0.002,
            duration,
            seed,
        }
    }
}

/// A generated log with the reference engine's true base state at every logged state sample.
#[derive(Debug, Clone)]
pub struct FloatingLog {
    pub log: RobotLog,
    /// `truth[i]` is the base state at `log.states[i]`.
    pub truth: Vec<BaseState>,
}

/// A controller of [`generate_floating_log`]: time, true state, latest logged measurement → joint command.
pub type FloatingController<'a> = dyn FnMut(f64, &State, Option<&Measurement>) -> Result<Command, GapError> + 'a;

/// Runs `controller` on the reference plant from the model's standing pose on the ground, and logs what the robot
/// would report. The controller is called every `cmd_period` with the time, the true state and the latest logged
/// measurement (what a controller on the robot sees: noisy joints and torso IMU; `None` before the first one), and
/// returns the joint command.
pub fn generate_floating_log(
    model: &RobotModel,
    cfg: &FloatingRealConfig,
    controller: &mut FloatingController<'_>,
) -> Result<FloatingLog, GapError> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(cfg.seed);
    let fx = &cfg.effects;
    let real_model = fx.apply_to_model(model);
    let mut plant = FloatingPlant::new(&real_model, &cfg.engine, fx)?;
    let s0 = State::standing(model);
    plant.reset(&BaseState::of(&s0), &s0.q, &s0.dq)?;
    let nj = model.nj();
    let decimation = ((cfg.cmd_period / DT).round() as usize).max(1);
    let steps = (cfg.duration / DT).round() as usize;
    let lat = fx.latency_steps as f64 * DT;
    let n = &cfg.noise;
    let mut log = RobotLog::default();
    let mut truth = Vec::with_capacity(steps);
    let normal = |rng: &mut rand_chacha::ChaCha8Rng| -> f64 {
        let u1: f64 = rng.gen_range(1e-12..1.0);
        let u2: f64 = rng.gen_range(0.0..1.0);
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    };
    for i in 0..steps {
        let t = i as f64 * DT;
        if i % decimation == 0 {
            let mut c = controller(t, &plant.state(), log.states.last())?;
            c.t = if i == 0 { 0.0 } else { t + rng.gen_range(0.0..=cfg.jitter_s.max(0.0)) };
            log.commands.push(c);
        }
        let cmd = match log.command_at(t - lat + 1e-9) {
            Some(ci) => log.commands[ci].clone(),
            None => idle_command(model, &s0.q),
        };
        let tau = plant.step(&cmd, fx)?.to_vec();
        let s = plant.state();
        let (quat, gyro) = imu_reading_floating(model, s.base_quat, s.base_ang_vel, &s.q, &s.dq, fx)?;
        let nq = UnitQuaternion::from_quaternion(Quaternion::new(quat[0], quat[1], quat[2], quat[3]))
            * UnitQuaternion::from_scaled_axis(
                Vector3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng)) * n.quat,
            );
        log.states.push(Measurement {
            t: t + DT,
            q: (0..nj).map(|j| s.q[j] + fx.encoder_offset[j] + n.q * normal(&mut rng)).collect(),
            dq: (0..nj).map(|j| s.dq[j] + n.dq * normal(&mut rng)).collect(),
            tau: (0..nj).map(|j| tau[j] + n.tau * normal(&mut rng)).collect(),
            quat: [nq.w, nq.i, nq.j, nq.k],
            gyro: [0, 1, 2].map(|k| gyro[k] + n.gyro * normal(&mut rng)),
            acc: [0.0, 0.0, robot_model::GRAVITY_EARTH],
        });
        truth.push(BaseState::of(&s));
    }
    Ok(FloatingLog { log, truth })
}
