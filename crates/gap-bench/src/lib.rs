//! `gap-bench`: the blind benchmark of the gap diagnosis (issue 6), in its own crate so that `gap-diagnosis` does
//! not depend on the policy runtime that drives its reference robot (issue 18).
//!
//! The blind benchmark: "real" logs from a reference plant that differs from the diagnosing simulator (another
//! MuJoCo integrator, sensor noise, 50 Hz command timing jitter) with a hidden random subset of effects at random
//! magnitudes, labels sealed (salted SHA-256) before diagnosis, then scored. The reference robot hangs on the rig
//! ([`run_trial`]) or walks on the ground under a policy ([`run_floating_trial`], `ulab gap bench --floating`).
//!
//! The reference plants ([`generate_log`] on the rig, [`reference::generate_floating_log`] on the ground) also make
//! the logs of the diagnosis's end-to-end tests (`tests/`).
#![forbid(unsafe_code)]

pub mod out_of_library;
pub mod reference;

use gap_diagnosis::diagnose::{diagnose, AmbiguousSet, DiagnoseOptions, PlantKind, Report};
use gap_diagnosis::effects::{EffectKind, Scope};
use gap_diagnosis::excite;
use gap_diagnosis::log::{Command, Measurement, RobotLog};
use gap_diagnosis::plant::{imu_reading, joint_groups, Effects, EngineChoice, Rig, Stepping, DT, GROUPS};
use gap_diagnosis::GapError;
use policy_runtime::{Controller, PolicyController, PolicySpec, RobotObservation};
use rand::{Rng, SeedableRng};
use rand_distr_free::normal;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

pub use out_of_library::{OutOfLibrary, OutOfLibraryLabel};
pub use reference::{FloatingLog, FloatingRealConfig, SensorNoise};

/// The reference ("real") plant.
#[derive(Debug, Clone)]
pub struct RealConfig {
    /// With another engine than MuJoCo, damping and Coulomb friction effects go through the engine's own joint
    /// parameters ([`in_engine`]) instead of the effect layer.
    pub engine: EngineChoice,
    pub effects: Effects,
    pub noise: SensorNoise,
    /// Command rate (Hz) of the controller driving the plan.
    pub cmd_rate_hz: f64,
    /// Uniform timing jitter of each command (± s).
    pub jitter_s: f64,
    pub duration: f64,
    pub seed: u64,
    /// Scale of the excitation plan's amplitudes (1: the plan; below 1: gentler motion; 0: holding the standing
    /// pose). Unused when a policy drives the plant.
    pub excitation_scale: f64,
    /// The motion of the joints no policy drives: the excitation plan or a gentle chirp.
    pub motion: Motion,
    /// An effect outside the diagnosis's library, hidden in the plant as a torque the actuator does not know of.
    pub out_of_library: Option<OutOfLibrary>,
    /// How the reference rig integrates a control step (the diagnosing simulator's one 2 ms step by default; finer
    /// steps make a plant whose numerics differ, as another simulator's or a robot's do). Rig only.
    pub stepping: Stepping,
}

/// The scripted motion of a trial (of every joint, or of the joints a policy does not drive).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Motion {
    /// The excitation plan ([`excite::command_at`]): chirps to 3 Hz and steps.
    #[default]
    Plan,
    /// A gentle chirp ([`excite::gentle_command_at`]): slow sweeps at a third of the plan's amplitude.
    GentleChirp,
}

impl RealConfig {
    pub fn new(model: &RobotModel, duration: f64, seed: u64) -> Self {
        RealConfig {
            engine: EngineChoice::mujoco("RK4"),
            effects: Effects::none(model.nj()),
            noise: SensorNoise::default(),
            cmd_rate_hz: 50.0,
            jitter_s: 0.002,
            duration,
            seed,
            excitation_scale: 1.0,
            motion: Motion::Plan,
            out_of_library: None,
            stepping: Stepping::DIAGNOSING,
        }
    }
}

mod rand_distr_free {
    use rand::Rng;
    /// A standard normal sample (Box–Muller), so no extra crate is needed.
    pub fn normal(rng: &mut impl Rng) -> f64 {
        let u1: f64 = rng.gen_range(1e-12..1.0);
        let u2: f64 = rng.gen_range(0.0..1.0);
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// What drives the reference plant in a trial.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InputKind {
    /// The excitation plan ([`gap_diagnosis::excite`]) on every joint.
    Excitation,
    /// A gentle chirp ([`Motion::GentleChirp`]) on every joint: what a user records anyway.
    GentleChirp,
    /// A policy rollout on the policy's joints (the legs) with a velocity command drawn per trial; the other
    /// joints (torso, arms, which the policies only hold) follow the excitation plan's targets for them.
    Policy,
}

/// A policy driving the reference plant: its spec and the velocity command `(vx, vy, wz)` it is given.
#[derive(Debug, Clone)]
pub struct PolicyInput {
    pub spec: PolicySpec,
    pub command: [f64; 3],
}

/// Runs the excitation plan through the reference plant and returns the log the robot would have produced.
pub fn generate_log(model: &RobotModel, cfg: &RealConfig) -> Result<RobotLog, GapError> {
    generate_log_with(model, cfg, None)
}

/// Runs the reference plant driven by the excitation plan (`policy` None) or by a policy closed around the
/// plant's measurements (noisy joints, torso IMU converted to the pelvis frame as the deploy scripts do), at the
/// config's command rate with its timing jitter.
pub fn generate_log_with(
    model: &RobotModel,
    cfg: &RealConfig,
    policy: Option<&PolicyInput>,
) -> Result<RobotLog, GapError> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(cfg.seed);
    let (real_model, engine_fx) = in_engine(&cfg.effects.apply_to_model(model), &cfg.effects, !cfg.engine.is_mujoco());
    let fx = &engine_fx;
    let mut rig = Rig::reference(&real_model, &cfg.engine, cfg.stepping)?;
    let q0 = model.default_q();
    let nj = model.nj();
    rig.reset(&q0, &vec![0.0; nj])?;
    let amp: Vec<f64> = excite::amplitudes(model).iter().map(|a| a * cfg.excitation_scale).collect();
    let groups = joint_groups(model);
    let mut controller = match policy {
        Some(p) => {
            p.spec.check_robot(model).map_err(|e| GapError::Input(format!("policy {}: {e}", p.spec.name)))?;
            let mut c = PolicyController::from_spec(p.spec.clone())
                .map_err(|e| GapError::Input(format!("policy {}: {e}", p.spec.name)))?;
            c.reset();
            Some((c, p.command))
        }
        None => None,
    };
    // Command times: nominal rate with jitter (sorted; a command is computed when its time comes).
    let n_cmd = (cfg.duration * cfg.cmd_rate_hz).floor() as usize;
    let mut times: Vec<f64> = (0..n_cmd)
        .map(|i| {
            let nominal = i as f64 / cfg.cmd_rate_hz;
            if i == 0 {
                0.0
            } else {
                (nominal + rng.gen_range(-cfg.jitter_s..=cfg.jitter_s)).max(0.0)
            }
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let mut log = RobotLog { commands: Vec::with_capacity(n_cmd), states: Vec::new() };
    let steps = (cfg.duration / DT).round() as usize;
    let lat = fx.latency_steps as f64 * DT;
    let mut tau = vec![0.0; nj];
    let n = &cfg.noise;
    let mut next_cmd = 0;
    // True IMU orientation (with misalignment), IMU point velocity and accelerometer noise of every logged state.
    let mut truth: Vec<([f64; 4], nalgebra::Vector3<f64>, [f64; 3])> = Vec::with_capacity(steps);
    for i in 0..steps {
        let t = i as f64 * DT;
        let disturbance = match &cfg.out_of_library {
            Some(o) => {
                let (q, dq) = rig.joints();
                o.torque(model, &q, &dq, &tau, rig.torque_limits())
            }
            None => Vec::new(),
        };
        // Commands whose time has come, computed from the latest measurement (what the controller sees).
        while next_cmd < times.len() && times[next_cmd] <= t + 1e-12 {
            let tc = times[next_cmd];
            let mut cmd = match cfg.motion {
                Motion::Plan => excite::command_at(model, &amp, &groups, cfg.duration, tc),
                Motion::GentleChirp => excite::gentle_command_at(model, &amp, &groups, cfg.duration, tc),
            };
            if let Some((c, vel)) = controller.as_mut() {
                let (q, dq, quat, gyro) = match log.states.last() {
                    Some(m) => (m.q.clone(), m.dq.clone(), m.quat, m.gyro),
                    None => (q0.clone(), vec![0.0; nj], [1.0, 0.0, 0.0, 0.0], [0.0; 3]),
                };
                let obs = RobotObservation::from_torso_imu(tc, quat, gyro, q, dq, *vel)
                    .map_err(|e| GapError::Input(format!("policy observation: {e}")))?;
                let target = c.act(&obs).map_err(|e| GapError::Input(format!("policy step: {e}")))?;
                for &j in &c.spec().policy_joints {
                    cmd.q[j] = target.q_des[j].clamp(model.joints[j].lower, model.joints[j].upper);
                    cmd.dq[j] = target.dq_des[j];
                    cmd.kp[j] = target.kp[j];
                    cmd.kd[j] = target.kd[j];
                    cmd.tau[j] = target.tau_ff[j];
                }
            }
            log.commands.push(cmd);
            next_cmd += 1;
        }
        let Some(ci) = log.command_at(t - lat + 1e-9) else {
            // Before the first command reaches the motors: hold with the first command's gains at the start pose.
            let mut c = log.commands[0].clone();
            c.q = q0.clone();
            tau.copy_from_slice(rig.step_disturbed(&c, fx, &disturbance)?);
            continue;
        };
        let cmd = log.commands[ci].clone();
        tau.copy_from_slice(rig.step_disturbed(&cmd, fx, &disturbance)?);
        let (q, dq) = rig.joints();
        let (quat, gyro) = imu_reading(model, &q, &dq, fx)?;
        let nq =
            nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(quat[0], quat[1], quat[2], quat[3]))
                * nalgebra::UnitQuaternion::from_scaled_axis(
                    nalgebra::Vector3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng)) * n.quat,
                );
        log.states.push(Measurement {
            t: t + DT,
            q: (0..nj).map(|j| q[j] + fx.encoder_offset[j] + n.q * normal(&mut rng)).collect(),
            dq: (0..nj).map(|j| dq[j] + n.dq * normal(&mut rng)).collect(),
            tau: (0..nj).map(|j| tau[j] + n.tau * normal(&mut rng)).collect(),
            quat: [nq.w, nq.i, nq.j, nq.k],
            gyro: [0, 1, 2].map(|k| gyro[k] + n.gyro * normal(&mut rng)),
            acc: [0.0; 3], // filled below
        });
        let acc_noise = [0, 1, 2].map(|_| n.acc * normal(&mut rng));
        truth.push((quat, gap_diagnosis::rig_check::imu_point_velocity(model, &q, &dq)?, acc_noise));
    }
    // Accelerometer: specific force R⁻¹ (a − g) in the (misaligned) IMU frame, `a` the IMU point's acceleration
    // (central difference of its velocity; the torso swings about the waist, the pelvis is still).
    for i in 0..log.states.len() {
        let a = match (i.checked_sub(1), truth.get(i + 1)) {
            (Some(p), Some(nx)) => (nx.1 - truth[p].1) / (2.0 * DT),
            _ => nalgebra::Vector3::zeros(),
        };
        let quat = truth[i].0;
        let r =
            nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(quat[0], quat[1], quat[2], quat[3]));
        let f = r.inverse() * (a + nalgebra::Vector3::new(0.0, 0.0, robot_model::GRAVITY_EARTH));
        log.states[i].acc = [0, 1, 2].map(|k| f[k] + truth[i].2[k]);
    }
    Ok(log)
}

/// Moves the effects the engines model themselves into `model` when `native` is set: extra viscous damping into
/// the joints' damping and extra Coulomb friction into their dry friction (MuJoCo's `frictionloss`, Rapier's dof
/// friction, DART's Coulomb constraint, Bullet's joint motor), so that the reference plant applies them with the
/// engine's own code and not with the effect layer the diagnosis fits; returns the model and the effects left to
/// the effect layer. (Armature, link mass and COM are always the model's, hence the engine's.) A negative damping
/// that the joint's own cannot absorb stays in the effect layer.
pub fn in_engine(model: &RobotModel, fx: &Effects, native: bool) -> (RobotModel, Effects) {
    let mut m = model.clone();
    let mut rest = fx.clone();
    if native {
        for (j, joint) in m.joints.iter_mut().enumerate() {
            if joint.damping + fx.damping[j] >= 0.0 {
                joint.damping += fx.damping[j];
                rest.damping[j] = 0.0;
            }
            if fx.coulomb[j] >= 0.0 {
                joint.frictionloss += fx.coulomb[j];
                rest.coulomb[j] = 0.0;
            }
        }
    }
    (m, rest)
}

/// One injected effect: kind, the unit it acts on (group, joint, `robot`, `imu`) and its magnitude.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Injected {
    pub kind: EffectKind,
    pub unit: String,
    pub value: f64,
}

/// Joints whose encoder offset changes a gravity torque enough to be seen on the rig.
fn gravity_loaded(model: &RobotModel) -> Vec<usize> {
    model
        .joints
        .iter()
        .enumerate()
        .filter(|(_, j)| ["hip_pitch", "knee", "shoulder_pitch", "elbow"].iter().any(|k| j.motor_name.ends_with(k)))
        .map(|(i, _)| i)
        .collect()
}

/// Joints a single-joint effect is drawn on: legs, waist and arms, without the wrists and the ankle rolls, whose
/// light links and small motions under the excitation plan leave a joint-level effect nearly invisible.
pub fn single_joint_candidates(model: &RobotModel) -> Vec<usize> {
    model
        .joints
        .iter()
        .enumerate()
        .filter(|(_, j)| !j.motor_name.contains("wrist") && !j.motor_name.ends_with("ankle_roll"))
        .map(|(i, _)| i)
        .collect()
}

/// A magnitude of `kind` as the rig benchmark injects it: clearly away from the no-effect value, inside the range the
/// library fits.
fn rig_magnitude(kind: EffectKind, rng: &mut impl Rng) -> f64 {
    let sign = |rng: &mut dyn rand::RngCore| if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
    match kind {
        EffectKind::Armature => rng.gen_range(2.0..3.5),
        EffectKind::Damping => rng.gen_range(1.5..4.0),
        EffectKind::Friction => rng.gen_range(1.0..3.0),
        EffectKind::TorqueSaturation => rng.gen_range(0.3..0.5),
        EffectKind::Latency => rng.gen_range(6..=14) as f64,
        EffectKind::GainScale => {
            if rng.gen_bool(0.5) {
                rng.gen_range(0.6..0.75)
            } else {
                rng.gen_range(1.3..1.5)
            }
        }
        EffectKind::Backlash => rng.gen_range(0.02..0.05),
        EffectKind::EncoderOffset => sign(rng) * rng.gen_range(0.04..0.08),
        EffectKind::ImuBias => sign(rng) * rng.gen_range(0.05..0.2),
        EffectKind::ImuMisalignment => sign(rng) * rng.gen_range(0.03..0.1),
        EffectKind::LinkMass => rng.gen_range(1.3..1.7),
        EffectKind::LinkCom => sign(rng) * rng.gen_range(0.03..0.07),
        EffectKind::ContactFriction | EffectKind::ContactStiffness => kind.range().2,
    }
}

/// Draws one effect of `kind` at a random clearly-present magnitude and applies it to `fx`.
pub fn inject(model: &RobotModel, kind: EffectKind, fx: &mut Effects, rng: &mut impl Rng) -> Injected {
    let groups = joint_groups(model);
    let value = rig_magnitude(kind, rng);
    let unit = match kind.scope() {
        Scope::Global => {
            kind.set(fx, 0, value);
            "robot".to_string()
        }
        Scope::Imu => {
            let axis = rng.gen_range(0..3);
            kind.set(fx, axis, value);
            "imu".to_string()
        }
        Scope::Joint => {
            let cand = gravity_loaded(model);
            let j = cand[rng.gen_range(0..cand.len())];
            kind.set(fx, j, value);
            model.joints[j].motor_name.clone()
        }
        Scope::Group if rng.gen_bool(0.5) => {
            // A single joint (issue 14: a friction on one elbow, a weak gain on one shoulder), as often as a group.
            let cand = single_joint_candidates(model);
            let j = cand[rng.gen_range(0..cand.len())];
            kind.set(fx, j, value);
            model.joints[j].motor_name.clone()
        }
        Scope::Group => {
            // Torso is a single joint; the limbs are where group effects are physical.
            let g = [0usize, 1, 3, 4][rng.gen_range(0..4)];
            (0..model.nj()).filter(|&j| groups[j] == g).for_each(|j| kind.set(fx, j, value));
            GROUPS[g].to_string()
        }
    };
    Injected { kind, unit, value: if kind == EffectKind::Latency { value * DT * 1e3 } else { value } }
}

/// Effect kinds the benchmark injects (the ones identifiable on the suspended rig).
pub fn injectable() -> Vec<EffectKind> {
    EffectKind::ALL.into_iter().filter(|k| k.identifiable_suspended()).collect()
}

/// Labels of one trial.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Labels {
    pub trial: usize,
    pub injected: Vec<Injected>,
    /// An effect outside the library ([`OutOfLibrary`]; its trials hide no library effect).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub out_of_library: Vec<OutOfLibraryLabel>,
}

/// Sealed labels: a salted SHA-256 of the labels' JSON, published before the diagnosis runs.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Seal {
    pub trial: usize,
    pub sha256: String,
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// Seals labels with a salt; returns the seal and the salted text needed to open it.
pub fn seal(labels: &Labels, salt: &[u8; 16]) -> Result<(Seal, String), GapError> {
    let text = format!("{}:{}", hex(salt), serde_json::to_string(labels)?);
    let h = Sha256::digest(text.as_bytes());
    Ok((Seal { trial: labels.trial, sha256: hex(&h) }, text))
}

/// Opens a seal: checks the hash and returns the labels.
pub fn open(seal: &Seal, text: &str) -> Result<Labels, GapError> {
    if hex(&Sha256::digest(text.as_bytes())) != seal.sha256 {
        return Err(GapError::Input(format!("trial {}: the labels do not match their seal", seal.trial)));
    }
    let json = text.split_once(':').map(|(_, j)| j).ok_or_else(|| GapError::Input("malformed sealed labels".into()))?;
    serde_json::from_str(json).map_err(|e| GapError::Input(format!("sealed labels: {e}")))
}

/// Score of one trial.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TrialScore {
    pub trial: usize,
    /// What drove the reference plant.
    #[serde(default = "default_input")]
    pub input: InputKind,
    /// The policy and velocity command of a policy-driven trial.
    #[serde(default)]
    pub policy: Option<String>,
    pub injected: Vec<Injected>,
    /// The hidden effect of an out-of-library trial (scored as its own class: any named effect is a confident
    /// attribution, as on a control).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out_of_library: Option<OutOfLibraryLabel>,
    /// The report found a remainder beyond what sensor noise explains ("part of the gap is unexplained").
    #[serde(default)]
    pub remainder_unexplained: bool,
    pub ranked: Vec<EffectKind>,
    /// Top-ranked unit of each injected kind, when that kind was named.
    pub attributed_units: Vec<Option<String>>,
    pub top1: bool,
    pub top3: bool,
    /// Every injected kind within the top `injected.len()` ranks.
    pub all_found: bool,
    pub joints_correct: usize,
    pub joints_total: usize,
    /// Relative parameter errors of the injected kinds that were named (|fit - true| / |true - none|).
    pub param_errors: Vec<f64>,
    /// Named effects on a no-effect control.
    pub false_confident: usize,
    /// Effect trials: named effects that were not injected ranked above an injected one (an injected effect that
    /// was not named ranks below every named one), a confident misattribution.
    #[serde(default)]
    pub misattributed: usize,
    /// The named effects the report said this log cannot tell apart (an order within a set is not counted as a
    /// misattribution).
    #[serde(default)]
    pub ambiguous: Vec<Vec<EffectKind>>,
    pub abstained: bool,
    pub held_out_reduction: f64,
    pub diagnose_s: f64,
    /// The plant the diagnosis used (floating-base benchmark only; the rig benchmark's scores omit it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plant: Option<PlantKind>,
    /// How often the effect magnitudes were redrawn because the robot fell (floating-base benchmark only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub redraws: Option<usize>,
}

fn default_input() -> InputKind {
    InputKind::Excitation
}

/// Scores a report against opened labels (the trial's input is filled in by [`run_trial`]).
pub fn score(labels: &Labels, report: &Report) -> TrialScore {
    let inj = &labels.injected;
    let ranked = report.ranked.clone();
    let mut attributed_units = Vec::new();
    let (mut jc, mut jt) = (0, 0);
    let mut param_errors = Vec::new();
    for i in inj {
        let r = report.effects.iter().find(|e| e.kind == i.kind && e.named);
        // The unit credited with the largest held-out cut; of equal ones, the first listed (a saturation named from
        // the log lists its joints by evidence, the most samples held at a plateau first).
        let top = r.and_then(|r| {
            r.params.iter().reduce(|a, b| if b.held_out_reduction > a.held_out_reduction { b } else { a })
        });
        attributed_units.push(top.map(|p| p.unit.clone()));
        if matches!(i.kind.scope(), Scope::Group | Scope::Joint) {
            jt += 1;
            if top.is_some_and(|p| p.unit == i.unit) {
                jc += 1;
            }
        }
        if let Some(r) = r {
            let null = i.kind.range().2;
            let fit = match i.kind.scope() {
                Scope::Imu => {
                    r.params.iter().map(|p| p.value).max_by(|a, b| a.abs().total_cmp(&b.abs())).unwrap_or(null)
                }
                _ => r.params.iter().find(|p| p.unit == i.unit).map_or(null, |p| p.value),
            };
            let null = if i.kind == EffectKind::Latency { 0.0 } else { null };
            param_errors.push((fit - i.value).abs() / (i.value - null).abs().max(1e-9));
        }
    }
    let kinds: Vec<EffectKind> = inj.iter().map(|i| i.kind).collect();
    TrialScore {
        trial: labels.trial,
        input: InputKind::Excitation,
        policy: None,
        injected: inj.clone(),
        out_of_library: labels.out_of_library.first().cloned(),
        remainder_unexplained: report.unexplained_residual.as_ref().is_some_and(|u| u.significant),
        attributed_units,
        top1: !kinds.is_empty() && ranked.first().is_some_and(|k| kinds.contains(k)),
        top3: !kinds.is_empty() && ranked.iter().take(3).any(|k| kinds.contains(k)),
        all_found: !kinds.is_empty() && kinds.iter().all(|k| ranked.iter().take(kinds.len()).any(|r| r == k)),
        joints_correct: jc,
        joints_total: jt,
        param_errors,
        false_confident: if kinds.is_empty() { ranked.len() } else { 0 },
        misattributed: misattributed(&kinds, &ranked, &report.ambiguous),
        ambiguous: report.ambiguous.iter().map(|a| a.effects.clone()).collect(),
        abstained: report.unexplained,
        held_out_reduction: report.best_combination.as_ref().map_or(0.0, |c| c.reduction.value),
        diagnose_s: report.elapsed_s,
        ranked,
        plant: None,
        redraws: None,
    }
}

/// Named effects that were not injected ranked above an injected one (0 for a control). One that the report puts
/// in an ambiguous set with an injected effect below it is not a confident misattribution: the report says the log
/// cannot order them.
pub fn misattributed(injected: &[EffectKind], ranked: &[EffectKind], ambiguous: &[AmbiguousSet]) -> usize {
    if injected.is_empty() {
        return 0;
    }
    let rank = |k: &EffectKind| ranked.iter().position(|r| r == k).unwrap_or(ranked.len());
    ranked
        .iter()
        .enumerate()
        .filter(|(_, r)| !injected.contains(r))
        .filter(|&(i, &r)| injected.iter().any(|k| rank(k) > i && !ambiguous.iter().any(|s| s.links(r, *k))))
        .count()
}

/// Benchmark settings.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    pub trials: usize,
    pub seed: u64,
    /// Length of each generated log (s).
    pub duration: f64,
    pub diagnose: DiagnoseOptions,
    /// Policies for the policy-driven trials (empty: every trial runs the excitation plan).
    pub policies: Vec<PolicySpec>,
    /// The reference ("real") plant's engine on the rig (default MuJoCo RK4). Another engine than MuJoCo makes the
    /// logs independent of the diagnosing simulator (see [`RealConfig::engine`]).
    pub reference: EngineChoice,
    /// The scripted trials' motion (and that of the joints a policy does not drive): the plan or a gentle chirp.
    pub motion: Motion,
    /// Out-of-library trials run after the `trials` regular ones (trial indices `trials..`): each hides one
    /// effect outside the library ([`OutOfLibrary`], ripple and load friction in turn) under the scripted motion.
    pub out_of_library: usize,
}

impl BenchOptions {
    /// `trials` trials of `duration` s from `seed`, excitation plan only, reference MuJoCo RK4.
    pub fn new(trials: usize, seed: u64, duration: f64) -> Self {
        BenchOptions {
            trials,
            seed,
            duration,
            diagnose: DiagnoseOptions { seed, ..DiagnoseOptions::default() },
            policies: Vec::new(),
            reference: EngineChoice::mujoco("RK4"),
            motion: Motion::Plan,
            out_of_library: 0,
        }
    }
}

/// The input of trial `i`: with policies, half the trials, balanced over the single/single/pair/control
/// pattern (blocks of four alternate E P E P and P E P E).
pub fn trial_input(i: usize, have_policies: bool) -> InputKind {
    if have_policies && (i + i / 4) % 2 == 1 {
        InputKind::Policy
    } else {
        InputKind::Excitation
    }
}

/// The policy input of trial `i` (None for excitation trials): policies alternate, the velocity command is drawn
/// per trial (vx in [-0.4, 0.8] m/s, vy in [-0.3, 0.3] m/s, wz in [-0.5, 0.5] rad/s).
pub fn trial_policy(i: usize, opts: &BenchOptions) -> Option<PolicyInput> {
    if trial_input(i, !opts.policies.is_empty()) != InputKind::Policy {
        return None;
    }
    let spec = opts.policies[(i / 2) % opts.policies.len()].clone();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(
        opts.seed ^ 0x005e_ed0f_7011_c1e5 ^ (i as u64).wrapping_mul(0x2545_f491_4f6c_dd1d),
    );
    let command = [rng.gen_range(-0.4..0.8), rng.gen_range(-0.3..0.3), rng.gen_range(-0.5..0.5)];
    Some(PolicyInput { spec, command })
}

/// Number of hidden effects of trial `i`: the pattern single, single, pair, no-effect control repeats.
pub fn trial_plan(i: usize) -> usize {
    match i % 4 {
        0 | 1 => 1,
        2 => 2,
        _ => 0,
    }
}

/// The kinds hidden in trial `i` ([`trial_plan`] of them): the first cycles through `kinds` so a short benchmark
/// still covers them all, the second (pairs) is drawn from `rng`.
fn trial_kinds(i: usize, kinds: &[EffectKind], rng: &mut rand_chacha::ChaCha8Rng) -> Vec<EffectKind> {
    let n = trial_plan(i);
    let mut chosen: Vec<EffectKind> = Vec::new();
    if n >= 1 {
        chosen.push(kinds[(i / 4 * 2 + i % 4) % kinds.len()]);
    }
    while chosen.len() < n {
        let k = kinds[rng.gen_range(0..kinds.len())];
        if !chosen.contains(&k) {
            chosen.push(k);
        }
    }
    chosen
}

/// Draws the hidden effects of trial `i`.
pub fn draw_trial(model: &RobotModel, i: usize, seed: u64) -> (Effects, Labels) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ (0x9e37_79b9_7f4a_7c15u64.wrapping_mul(i as u64 + 1)));
    let mut fx = Effects::none(model.nj());
    let chosen = trial_kinds(i, &injectable(), &mut rng);
    let injected = chosen.into_iter().map(|k| inject(model, k, &mut fx, &mut rng)).collect();
    (fx, Labels { trial: i, injected, out_of_library: Vec::new() })
}

/// The hidden out-of-library effect of trial `i` (no library effect): see [`BenchOptions::out_of_library`].
pub fn draw_out_of_library_trial(model: &RobotModel, i: usize, seed: u64) -> (OutOfLibrary, Labels) {
    let mut rng =
        rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x0001_0b0f_11b7_a77e ^ (i as u64).wrapping_mul(0x9e37));
    let o = OutOfLibrary::draw(model, i, &mut rng);
    let label = o.label(model);
    (o, Labels { trial: i, injected: Vec::new(), out_of_library: vec![label] })
}

/// The salt that seals the labels of trial `i`.
pub fn trial_salt(seed: u64, i: usize) -> [u8; 16] {
    let mut salt = [0u8; 16];
    rand_chacha::ChaCha8Rng::seed_from_u64(seed.wrapping_add(7919 * i as u64)).fill(&mut salt);
    salt
}

/// The reference plant of rig trial `i` (its hidden effects drawn) and its labels: what [`run_trial`] generates
/// and seals (trials from `opts.trials` on hide an out-of-library effect).
pub fn trial_config(model: &RobotModel, i: usize, opts: &BenchOptions) -> (RealConfig, Labels) {
    let (effects, labels, out_of_library) = if i >= opts.trials {
        let (o, labels) = draw_out_of_library_trial(model, i, opts.seed);
        (Effects::none(model.nj()), labels, Some(o))
    } else {
        let (fx, labels) = draw_trial(model, i, opts.seed);
        (fx, labels, None)
    };
    let cfg = RealConfig {
        effects,
        seed: opts.seed.wrapping_mul(31).wrapping_add(i as u64),
        engine: opts.reference.clone(),
        motion: opts.motion,
        out_of_library,
        ..RealConfig::new(model, opts.duration, 0)
    };
    (cfg, labels)
}

/// Trial `i`'s reference plant with its `k`-th hidden effect removed and everything else (motion, noise, timing
/// jitter, the other hidden effect) as in the trial: the log the plant would have written without that effect. The
/// difference between the two logs is what the effect shows in the log, with nothing of the diagnosis in it
/// (`ulab gap bench --counterfactuals`, bench/gap-eval/visibility.py). None when the trial hides fewer effects.
pub fn trial_config_without(model: &RobotModel, i: usize, opts: &BenchOptions, k: usize) -> Option<RealConfig> {
    let (mut cfg, labels) = trial_config(model, i, opts);
    let kind = labels.injected.get(k)?.kind;
    // The effects of one trial are of different kinds, so resetting the kind removes exactly this effect.
    kind.copy(&Effects::none(model.nj()), &mut cfg.effects);
    Some(cfg)
}

/// Length of the oracle's replay windows (s): the diagnosis's window ([`oracle_differences`]).
pub const ORACLE_WINDOW_S: f64 = 0.1;

/// What hidden effect `k` of trial `i` shows to a replay that models the trial's plant perfectly, window by window as
/// the diagnosis replays: for each window of [`ORACLE_WINDOW_S`] of `log` (the trial's log), back to back, the
/// trial's own plant (its engine, with every hidden effect) and the same plant without effect `k` both replay the
/// logged commands from the logged state, and the window's row holds, per column (each joint, then the IMU), the mean
/// squared difference of the two predictions in the diagnosis's residual scales (angle, speed, torque averaged per
/// joint; orientation and gyro averaged over the IMU's six components). Rig trials only; None when the trial hides
/// fewer effects. The reference plant replays in its own engine, not in the diagnosing MuJoCo.
pub fn oracle_differences(
    model: &RobotModel,
    i: usize,
    opts: &BenchOptions,
    log: &RobotLog,
    k: usize,
) -> Result<Option<Vec<Vec<f64>>>, GapError> {
    let Some(without) = trial_config_without(model, i, opts, k) else { return Ok(None) };
    let (with, _) = trial_config(model, i, opts);
    let mut plants = Vec::with_capacity(2);
    for cfg in [&with, &without] {
        let (real_model, fx) = in_engine(&cfg.effects.apply_to_model(model), &cfg.effects, !cfg.engine.is_mujoco());
        let rig = Rig::reference(&real_model, &cfg.engine, cfg.stepping)?;
        plants.push((real_model, fx, rig));
    }
    let nj = model.nj();
    let sigma_tau = gap_diagnosis::noise::torque_scales(model);
    let mut rows = Vec::new();
    let mut start = 0;
    while let Some(s0) = log.states.get(start) {
        let len = log.states[start + 1..].iter().take_while(|s| s.t < s0.t + ORACLE_WINDOW_S).count();
        if len == 0 || start + len >= log.states.len() {
            break;
        }
        let mut preds = Vec::with_capacity(2);
        for (real_model, fx, rig) in plants.iter_mut() {
            preds.push(gap_diagnosis::plant::predict_window(rig, real_model, log, fx, start, len, true)?);
        }
        let mut row = vec![0.0; nj + 1];
        for (a, b) in preds[0].iter().zip(&preds[1]) {
            gap_diagnosis::noise::add_joint_terms(&sigma_tau, a, b, &mut row[..nj]);
            let angle = rotation_angle(&a.quat, &b.quat);
            let gyro: f64 = (0..3).map(|c| ((a.gyro[c] - b.gyro[c]) / gap_diagnosis::noise::SIGMA_GYRO).powi(2)).sum();
            row[nj] += ((angle / gap_diagnosis::noise::SIGMA_QUAT).powi(2) + gyro) / 6.0;
        }
        let n = preds[0].len().max(1) as f64;
        row.iter_mut().for_each(|x| *x /= n);
        rows.push(row);
        start += len;
    }
    Ok(Some(rows))
}

/// Angle (rad) of the rotation between two unit quaternions `[w, x, y, z]`.
fn rotation_angle(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let qa = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(a[0], a[1], a[2], a[3]));
    let qb = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(b[0], b[1], b[2], b[3]));
    qa.angle_to(&qb)
}

/// Runs one trial end to end (generate, seal, diagnose, open, score). The caller may write the log with
/// `on_log` (e.g. as MCAP, so the diagnosis reads it through the same path as a recorded log).
pub fn run_trial(
    model: &RobotModel,
    i: usize,
    opts: &BenchOptions,
    on_log: &mut dyn FnMut(usize, &RobotLog) -> Result<RobotLog, GapError>,
) -> Result<(Seal, TrialScore, Report), GapError> {
    let (cfg, labels) = trial_config(model, i, opts);
    let (sealed, text) = seal(&labels, &trial_salt(opts.seed, i))?;
    drop(labels);
    let input = if i >= opts.trials { None } else { trial_policy(i, opts) };
    let log = generate_log_with(model, &cfg, input.as_ref())?;
    let log = on_log(i, &log)?;
    let report = diagnose(model, &log, &opts.diagnose)?;
    let labels = open(&sealed, &text)?;
    let mut s = score(&labels, &report);
    if opts.motion == Motion::GentleChirp {
        s.input = InputKind::GentleChirp;
    }
    if let Some(p) = &input {
        s.input = InputKind::Policy;
        s.policy =
            Some(format!("{} (vx {:.2}, vy {:.2}, wz {:.2})", p.spec.name, p.command[0], p.command[1], p.command[2]));
    }
    Ok((sealed, s, report))
}

/// Aggregate results.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BenchSummary {
    pub trials: usize,
    pub singles: usize,
    pub pairs: usize,
    pub controls: usize,
    pub top1_single: f64,
    /// Single effects named first or within the ambiguous set the ranking opens with (the report's first answer
    /// when it says the log cannot tell its first effects apart); not a target, the strict row is.
    #[serde(default)]
    pub top1_set_single: f64,
    pub top3_single: f64,
    pub both_pairs: f64,
    pub top3_pairs: f64,
    pub joint_accuracy: f64,
    pub median_param_error: f64,
    pub false_confident_controls: usize,
    /// Sum over effect trials of [`TrialScore::misattributed`].
    #[serde(default)]
    pub misattributions: usize,
    /// Effects named over the effect trials, and how many of them were injected: a report that names a stand-in
    /// beside the true effect is right first and still wrong.
    #[serde(default)]
    pub named_in_effect_trials: usize,
    #[serde(default)]
    pub named_injected: usize,
    pub abstention_effects: f64,
    pub abstention_controls: f64,
    pub mean_held_out_reduction: f64,
    pub mean_diagnose_s: f64,
    /// Out-of-library trials, those in which some library effect was named (a confident attribution: target 0),
    /// and those whose report found part of the gap unexplained.
    #[serde(default)]
    pub out_of_library: usize,
    #[serde(default)]
    pub out_of_library_named: usize,
    /// Out-of-library trials whose first named effect is in no ambiguous set: named without the report saying
    /// another effect explains the log as well (not the target; the row above is).
    #[serde(default)]
    pub out_of_library_confident: usize,
    #[serde(default)]
    pub out_of_library_unexplained: usize,
}

pub fn summarize(scores: &[TrialScore]) -> BenchSummary {
    let frac = |xs: Vec<bool>| {
        if xs.is_empty() {
            f64::NAN
        } else {
            xs.iter().filter(|x| **x).count() as f64 / xs.len() as f64
        }
    };
    let singles: Vec<&TrialScore> = scores.iter().filter(|s| s.injected.len() == 1).collect();
    let pairs: Vec<&TrialScore> = scores.iter().filter(|s| s.injected.len() == 2).collect();
    let controls: Vec<&TrialScore> =
        scores.iter().filter(|s| s.injected.is_empty() && s.out_of_library.is_none()).collect();
    let ool: Vec<&TrialScore> = scores.iter().filter(|s| s.out_of_library.is_some()).collect();
    let effects: Vec<&TrialScore> = scores.iter().filter(|s| !s.injected.is_empty()).collect();
    let mut pe: Vec<f64> = scores.iter().flat_map(|s| s.param_errors.clone()).collect();
    pe.sort_by(f64::total_cmp);
    let (jc, jt) = scores.iter().fold((0, 0), |a, s| (a.0 + s.joints_correct, a.1 + s.joints_total));
    BenchSummary {
        trials: scores.len(),
        singles: singles.len(),
        pairs: pairs.len(),
        controls: controls.len(),
        top1_single: frac(singles.iter().map(|s| s.top1).collect()),
        top1_set_single: frac(singles.iter().map(|s| s.injected.iter().all(|i| in_leading_set(s, i.kind))).collect()),
        top3_single: frac(singles.iter().map(|s| s.top3).collect()),
        both_pairs: frac(pairs.iter().map(|s| s.all_found).collect()),
        top3_pairs: frac(
            pairs.iter().map(|s| s.injected.iter().all(|i| s.ranked.iter().take(3).any(|r| *r == i.kind))).collect(),
        ),
        joint_accuracy: if jt == 0 { f64::NAN } else { jc as f64 / jt as f64 },
        median_param_error: pe.get(pe.len() / 2).copied().unwrap_or(f64::NAN),
        false_confident_controls: controls.iter().map(|s| s.false_confident).sum(),
        misattributions: effects.iter().map(|s| s.misattributed).sum(),
        named_in_effect_trials: effects.iter().map(|s| s.ranked.len()).sum(),
        named_injected: effects
            .iter()
            .map(|s| s.ranked.iter().filter(|k| s.injected.iter().any(|i| i.kind == **k)).count())
            .sum(),
        abstention_effects: frac(effects.iter().map(|s| s.abstained).collect()),
        abstention_controls: frac(controls.iter().map(|s| s.abstained).collect()),
        mean_held_out_reduction: if effects.is_empty() {
            f64::NAN
        } else {
            effects.iter().map(|s| s.held_out_reduction).sum::<f64>() / effects.len() as f64
        },
        mean_diagnose_s: if scores.is_empty() {
            f64::NAN
        } else {
            scores.iter().map(|s| s.diagnose_s).sum::<f64>() / scores.len() as f64
        },
        out_of_library: ool.len(),
        out_of_library_named: ool.iter().filter(|s| !s.ranked.is_empty()).count(),
        out_of_library_confident: ool
            .iter()
            .filter(|s| s.ranked.first().is_some_and(|f| !s.ambiguous.iter().any(|set| set.contains(f))))
            .count(),
        out_of_library_unexplained: ool.iter().filter(|s| s.remainder_unexplained).count(),
    }
}

/// Whether `kind` is ranked first in a trial, or is in the ambiguous set that holds the first-ranked effect.
fn in_leading_set(s: &TrialScore, kind: EffectKind) -> bool {
    match s.ranked.first() {
        Some(&first) if first == kind => true,
        Some(&first) => s.ambiguous.iter().any(|set| set.contains(&first) && set.contains(&kind)),
        None => false,
    }
}

/// The results table split by input kind (all, then one column per kind that ran: excitation plan, gentle
/// chirp, policy rollout), when more than one kind ran.
pub fn table_by_input(scores: &[TrialScore]) -> String {
    let all = summarize(scores);
    let kinds: Vec<(InputKind, &str)> = [
        (InputKind::Excitation, "excitation plan"),
        (InputKind::GentleChirp, "gentle chirp"),
        (InputKind::Policy, "policy rollout"),
    ]
    .into_iter()
    .filter(|(k, _)| scores.iter().any(|s| s.input == *k))
    .collect();
    if kinds.len() < 2 {
        return table(&all);
    }
    let columns: Vec<Vec<(String, String, String)>> = kinds
        .iter()
        .map(|(k, _)| table_rows(&summarize(&scores.iter().filter(|s| s.input == *k).cloned().collect::<Vec<_>>())))
        .collect();
    let names: Vec<&str> = kinds.iter().map(|(_, n)| *n).collect();
    let mut t =
        format!("| metric | all | {} | target |\n|---|---|{}---|\n", names.join(" | "), "---|".repeat(kinds.len()));
    for (i, a) in table_rows(&all).iter().enumerate() {
        let vals: Vec<&str> = columns.iter().map(|c| c.get(i).map_or("", |r| r.1.as_str())).collect();
        t += &format!("| {} | {} | {} | {} |\n", a.0, a.1, vals.join(" | "), a.2);
    }
    t
}

/// The results table (Markdown).
pub fn table(s: &BenchSummary) -> String {
    let mut t = String::from("| metric | value | target |\n|---|---|---|\n");
    for (m, v, target) in table_rows(s) {
        t += &format!("| {m} | {v} | {target} |\n");
    }
    t
}

/// (metric, value, target) rows of the table.
fn table_rows(s: &BenchSummary) -> Vec<(String, String, String)> {
    let pct = |x: f64| if x.is_nan() { "n/a".to_string() } else { format!("{:.0} %", 100.0 * x) };
    let row = |m: &str, v: String, t: &str| (m.to_string(), v, t.to_string());
    let of_ool =
        |k: usize| if s.out_of_library == 0 { "—".to_string() } else { format!("{k} of {}", s.out_of_library) };
    vec![
        row(
            "trials (single / pair / control)",
            if s.out_of_library == 0 {
                format!("{} ({} / {} / {})", s.trials, s.singles, s.pairs, s.controls)
            } else {
                format!(
                    "{} ({} / {} / {} + {} out-of-library)",
                    s.trials, s.singles, s.pairs, s.controls, s.out_of_library
                )
            },
            "",
        ),
        row("top-1 effect, single effects", pct(s.top1_single), "≥ 90 %"),
        row("top-1 effect or in the leading ambiguous set, single effects", pct(s.top1_set_single), ""),
        row("top-3 effect, single effects", pct(s.top3_single), ""),
        row("both effects in the top 2, pairs", pct(s.both_pairs), "≥ 70 %"),
        row("both effects in the top 3, pairs", pct(s.top3_pairs), ""),
        row("joint/group attribution", pct(s.joint_accuracy), ""),
        row("median relative parameter error", format!("{:.2}", s.median_param_error), ""),
        row("confident attributions on no-effect controls", s.false_confident_controls.to_string(), "0"),
        row(
            "confident misattributions in effect trials (a named effect not injected ranked above an injected one)",
            s.misattributions.to_string(),
            "0",
        ),
        row(
            "named effects that were injected, effect trials",
            if s.named_in_effect_trials == 0 {
                "n/a".to_string()
            } else {
                format!(
                    "{} of {} ({})",
                    s.named_injected,
                    s.named_in_effect_trials,
                    pct(s.named_injected as f64 / s.named_in_effect_trials as f64)
                )
            },
            "",
        ),
        row(
            "abstention rate, effect trials / controls",
            format!("{} / {}", pct(s.abstention_effects), pct(s.abstention_controls)),
            "",
        ),
        row("mean held-out gap reduction (best combination)", pct(s.mean_held_out_reduction), ""),
        row(
            "out-of-library trials (torque ripple, load-dependent friction): a library effect named",
            of_ool(s.out_of_library_named),
            "0",
        ),
        row(
            "out-of-library trials: the first named effect in no ambiguous set",
            of_ool(s.out_of_library_confident),
            "",
        ),
        row("out-of-library trials: part of the gap reported unexplained", of_ool(s.out_of_library_unexplained), ""),
        row("mean diagnosis time per log", format!("{:.1} s", s.mean_diagnose_s), ""),
    ]
}

// ---------------------------------------------------------------------------------------------------------------
// Floating-base benchmark (`ulab gap bench --floating`): the robot walks on the ground under a policy, the
// diagnosis must pick the floating plant by itself (plant auto). Same sealing, scoring and table as the rig's.

/// Effect kinds the floating-base benchmark injects, in the order the single-effect trials cycle through them:
/// the actuator and inertia kinds a walking leg excites, and the two ground-contact kinds (docs/gap/floating-base.md).
/// Not injected: the IMU kinds and encoder offset (the base is estimated from the IMU and the joints, so they are
/// partly absorbed by the estimate), torque saturation (the legs would give way), backlash and link COM (not
/// measured on the ground).
pub fn injectable_floating() -> Vec<EffectKind> {
    vec![
        EffectKind::Damping,
        EffectKind::ContactStiffness,
        EffectKind::LinkMass,
        EffectKind::ContactFriction,
        EffectKind::Armature,
        EffectKind::GainScale,
        EffectKind::Friction,
        EffectKind::Latency,
    ]
}

/// Draws one effect of `kind` for the floating-base benchmark and applies it to `fx`. Group effects go on one leg
/// (the walking policy moves the legs; the arms only hold their pose); the magnitudes are the rig benchmark's,
/// except the contact kinds: a foot-ground friction coefficient of 0.25–0.45 (model 1.0) and a softer ground,
/// contact time constant 0.035–0.05 s (MuJoCo's 0.02 s).
pub fn inject_floating(model: &RobotModel, kind: EffectKind, fx: &mut Effects, rng: &mut impl Rng) -> Injected {
    let groups = joint_groups(model);
    let value = match kind {
        EffectKind::ContactFriction => rng.gen_range(0.25..0.45),
        EffectKind::ContactStiffness => rng.gen_range(0.035..0.05),
        EffectKind::Armature
        | EffectKind::Damping
        | EffectKind::Friction
        | EffectKind::Latency
        | EffectKind::GainScale
        | EffectKind::LinkMass => rig_magnitude(kind, rng),
        // Not in `injectable_floating`; drawn as on the rig should a caller ask for them.
        other => return inject(model, other, fx, rng),
    };
    let unit = match kind.scope() {
        Scope::Group => {
            let g = rng.gen_range(0..2usize);
            (0..model.nj()).filter(|&j| groups[j] == g).for_each(|j| kind.set(fx, j, value));
            GROUPS[g].to_string()
        }
        _ => {
            kind.set(fx, 0, value);
            "robot".to_string()
        }
    };
    Injected { kind, unit, value: if kind == EffectKind::Latency { value * DT * 1e3 } else { value } }
}

/// Draws the hidden effects of floating trial `i`; `attempt` > 0 redraws the magnitudes (and units) of the same
/// kinds after the robot fell. The kinds follow the rig's pattern (single, single, pair, control; singles cycle
/// through [`injectable_floating`]) and do not depend on `attempt`.
pub fn draw_floating_trial(model: &RobotModel, i: usize, seed: u64, attempt: usize) -> (Effects, Labels) {
    let base = seed ^ 0xf1_0a71_0000_0000 ^ 0x9e37_79b9_7f4a_7c15u64.wrapping_mul(i as u64 + 1);
    let mut kind_rng = rand_chacha::ChaCha8Rng::seed_from_u64(base);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(
        base.wrapping_add(0x2545_f491_4f6c_dd1d_u64.wrapping_mul(attempt as u64 + 1)),
    );
    let chosen = trial_kinds(i, &injectable_floating(), &mut kind_rng);
    let mut fx = Effects::none(model.nj());
    let injected = chosen.into_iter().map(|k| inject_floating(model, k, &mut fx, &mut rng)).collect();
    (fx, Labels { trial: i, injected, out_of_library: Vec::new() })
}

/// The walking policy of floating trial `i`: policies alternate trial by trial; the velocity command is drawn per
/// trial within what the base estimate was built for (walking at ≤ 0.6 m/s: vx in [0, 0.6] m/s, vy in
/// [-0.2, 0.2] m/s, wz in [-0.3, 0.3] rad/s). None without policies.
pub fn floating_trial_policy(i: usize, opts: &BenchOptions) -> Option<PolicyInput> {
    if opts.policies.is_empty() {
        return None;
    }
    let spec = opts.policies[i % opts.policies.len()].clone();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(
        opts.seed ^ 0x0f10_a7ed_c0de_0001 ^ (i as u64).wrapping_mul(0x2545_f491_4f6c_dd1d),
    );
    let command = [rng.gen_range(0.0..0.6), rng.gen_range(-0.2..0.2), rng.gen_range(-0.3..0.3)];
    Some(PolicyInput { spec, command })
}

pub use gap_diagnosis::floating::{FALLEN_HEIGHT, FALLEN_TILT};
/// Magnitude draws per trial before the benchmark gives up on it.
pub const MAX_DRAWS: usize = 8;

/// The first logged sample at which the reference robot is down (pelvis below [`FALLEN_HEIGHT`] or tilted more
/// than [`FALLEN_TILT`]), if any.
pub fn fell_at(log: &FloatingLog) -> Option<usize> {
    log.truth.iter().position(|b| gap_diagnosis::floating::is_down(b.pos[2], b.quat))
}

/// Generates the reference log of a floating trial: `policy` closed every 20 ms around what the reference robot
/// reports (noisy joints and torso IMU, as on the robot), MuJoCo RK4 with ground, sensor noise, 0–2 ms command
/// jitter.
pub fn generate_walking_log(
    model: &RobotModel,
    fx: Effects,
    duration: f64,
    seed: u64,
    policy: &PolicyInput,
) -> Result<FloatingLog, GapError> {
    policy.spec.check_robot(model).map_err(|e| GapError::Input(format!("policy {}: {e}", policy.spec.name)))?;
    let mut ctl = PolicyController::from_spec(policy.spec.clone())
        .map_err(|e| GapError::Input(format!("policy {}: {e}", policy.spec.name)))?;
    ctl.reset();
    let cfg = FloatingRealConfig { effects: fx, ..FloatingRealConfig::new(model, duration, seed) };
    let vel = policy.command;
    // The policy sees what the robot reports (noisy joints, the torso IMU turned into the pelvis frame through the
    // waist, as the deploy scripts do); before the first report, the standing pose at rest.
    let mut act = |t: f64, s: &diff_physics::State, m: Option<&Measurement>| -> Result<Command, GapError> {
        let obs = match m {
            Some(m) => RobotObservation::from_torso_imu(t, m.quat, m.gyro, m.q.clone(), m.dq.clone(), vel)
                .map_err(|e| GapError::Input(format!("policy observation: {e}")))?,
            None => RobotObservation {
                time: t,
                base_quat: s.base_quat,
                base_ang_vel: s.base_ang_vel,
                q: s.q.clone(),
                dq: s.dq.clone(),
                command: vel,
            },
        };
        let p = ctl.act(&obs).map_err(|e| GapError::Input(format!("policy step: {e}")))?;
        Ok(Command { t, q: p.q_des, dq: p.dq_des, kp: p.kp, kd: p.kd, tau: p.tau_ff })
    };
    reference::generate_floating_log(model, &cfg, &mut act)
}

/// Runs floating trial `i` end to end with the benchmark's own draw ([`draw_floating_trial`]).
pub fn run_floating_trial(
    model: &RobotModel,
    i: usize,
    opts: &BenchOptions,
    on_log: &mut dyn FnMut(usize, &RobotLog, &Seal) -> Result<RobotLog, GapError>,
) -> Result<(Seal, TrialScore, Report), GapError> {
    run_floating_trial_drawn(model, i, opts, &mut |attempt| draw_floating_trial(model, i, opts.seed, attempt), on_log)
}

/// Runs floating trial `i` with hidden effects from `draw(attempt)`: generate the walking log, redraw (attempt + 1)
/// while the robot falls (at most [`MAX_DRAWS`] draws), seal the labels, hand the log and the seal to `on_log`
/// (which may write both, e.g. the log as MCAP), diagnose with `opts.diagnose`, open the seal, score.
pub fn run_floating_trial_drawn(
    model: &RobotModel,
    i: usize,
    opts: &BenchOptions,
    draw: &mut dyn FnMut(usize) -> (Effects, Labels),
    on_log: &mut dyn FnMut(usize, &RobotLog, &Seal) -> Result<RobotLog, GapError>,
) -> Result<(Seal, TrialScore, Report), GapError> {
    let input = floating_trial_policy(i, opts)
        .ok_or_else(|| GapError::Input("the floating-base benchmark needs at least one walking policy".into()))?;
    let seed = opts.seed.wrapping_mul(31).wrapping_add(i as u64);
    let mut attempt = 0;
    let (labels, log) = loop {
        let (fx, labels) = draw(attempt);
        let log = generate_walking_log(model, fx, opts.duration, seed, &input)?;
        match fell_at(&log) {
            None => break (labels, log.log),
            Some(k) if attempt + 1 >= MAX_DRAWS || labels.injected.is_empty() => {
                return Err(GapError::Input(format!(
                    "trial {i}: the robot falls at t = {:.2} s under {} (vx {:.2}, vy {:.2}, wz {:.2}) {}",
                    log.log.states.get(k).map_or(0.0, |m| m.t),
                    input.spec.name,
                    input.command[0],
                    input.command[1],
                    input.command[2],
                    if labels.injected.is_empty() {
                        "without any effect".to_string()
                    } else {
                        format!("in each of {MAX_DRAWS} effect draws")
                    }
                )))
            }
            Some(_) => attempt += 1,
        }
    };
    let (sealed, text) = seal(&labels, &trial_salt(opts.seed, i))?;
    drop(labels);
    let log = on_log(i, &log, &sealed)?;
    let report = diagnose(model, &log, &opts.diagnose)?;
    let labels = open(&sealed, &text)?;
    let mut s = score(&labels, &report);
    s.input = InputKind::Policy;
    s.policy = Some(format!(
        "{} (vx {:.2}, vy {:.2}, wz {:.2})",
        input.spec.name, input.command[0], input.command[1], input.command[2]
    ));
    s.plant = Some(report.plant);
    s.redraws = Some(attempt);
    Ok((sealed, s, report))
}

#[cfg(test)]
mod misattribution_tests {
    use super::{misattributed, AmbiguousSet};
    use gap_diagnosis::EffectKind::{Armature, Damping, EncoderOffset, Friction, GainScale, Latency};

    #[test]
    fn only_effects_ranked_above_an_injected_one_count() {
        // Injected damping named first: a friction after it is a secondary effect, not a misattribution.
        assert_eq!(misattributed(&[Damping], &[Damping, Friction], &[]), 0);
        // Armature named before the injected damping.
        assert_eq!(misattributed(&[Damping], &[Armature, Damping, Friction], &[]), 1);
        // An injected effect not named ranks below every named one.
        assert_eq!(misattributed(&[Damping, Latency], &[Damping, Friction, EncoderOffset], &[]), 2);
        assert_eq!(misattributed(&[Damping], &[], &[]), 0);
        // Controls are scored by their own row.
        assert_eq!(misattributed(&[], &[Friction], &[]), 0);
        // Armature above the injected damping, but the report says it cannot tell them apart: not confident.
        let set_of = |effects: Vec<gap_diagnosis::effects::EffectKind>| AmbiguousSet { effects, units: vec![] };
        let set = set_of(vec![Armature, Damping]);
        assert_eq!(misattributed(&[Damping], &[Armature, Damping], std::slice::from_ref(&set)), 0);
        // A set that does not hold the injected effect does not excuse it.
        let other = set_of(vec![Armature, Friction]);
        assert_eq!(misattributed(&[Damping], &[Armature, Friction, Damping], &[other]), 2);
    }

    fn trial(
        input: super::InputKind,
        injected: &[gap_diagnosis::EffectKind],
        ranked: &[gap_diagnosis::EffectKind],
        ool: bool,
    ) -> super::TrialScore {
        let kinds = injected.to_vec();
        super::TrialScore {
            trial: 0,
            input,
            policy: None,
            injected: kinds.iter().map(|&kind| super::Injected { kind, unit: "robot".into(), value: 1.0 }).collect(),
            out_of_library: ool.then(|| super::OutOfLibraryLabel {
                kind: "torque_ripple".into(),
                unit: "left_knee".into(),
                value: 0.05,
            }),
            remainder_unexplained: ool,
            ranked: ranked.to_vec(),
            attributed_units: vec![],
            top1: !kinds.is_empty() && ranked.first().is_some_and(|k| kinds.contains(k)),
            top3: false,
            all_found: false,
            joints_correct: 0,
            joints_total: 0,
            param_errors: vec![],
            false_confident: if kinds.is_empty() { ranked.len() } else { 0 },
            misattributed: 0,
            ambiguous: vec![],
            abstained: ranked.is_empty(),
            held_out_reduction: 0.0,
            diagnose_s: 1.0,
            plant: None,
            redraws: None,
        }
    }

    #[test]
    fn out_of_library_trials_are_their_own_class_and_each_input_kind_its_own_column() {
        use super::InputKind::{Excitation, GentleChirp, Policy};
        let scores = vec![
            trial(Excitation, &[Damping], &[Damping], false),
            trial(GentleChirp, &[Damping], &[Friction], false),
            trial(Policy, &[], &[], false),
            trial(Excitation, &[], &[Friction], true),
            trial(Excitation, &[], &[], true),
        ];
        let s = super::summarize(&scores);
        // The out-of-library trials are neither controls nor effect trials of the single-effect rows.
        assert_eq!((s.singles, s.controls, s.false_confident_controls), (2, 1, 0));
        assert_eq!((s.out_of_library, s.out_of_library_named, s.out_of_library_unexplained), (2, 1, 2));
        let t = super::table_by_input(&scores);
        assert!(t.starts_with("| metric | all | excitation plan | gentle chirp | policy rollout | target |"), "{t}");
        assert!(t.contains("| top-1 effect, single effects | 50 % | 100 % | 0 % | n/a | ≥ 90 % |"), "{t}");
        assert!(t.contains("a library effect named | 1 of 2 | 1 of 2 | — | — | 0 |"), "{t}");
        assert_eq!(s.out_of_library_confident, 1);
        // Named first, but in a set with an effect that explains the log as well: named, not confident.
        let mut in_set = trial(Excitation, &[], &[GainScale], true);
        in_set.ambiguous = vec![vec![GainScale, Armature]];
        let mut other_set = trial(Excitation, &[], &[GainScale, Friction], true);
        other_set.ambiguous = vec![vec![Friction, Armature]];
        let s = super::summarize(&[in_set, other_set]);
        assert_eq!((s.out_of_library_named, s.out_of_library_confident), (2, 1));
    }

    #[test]
    fn named_effects_are_counted_against_the_injected_ones_in_effect_trials_only() {
        use super::InputKind::Excitation;
        let scores = vec![
            // The injected damping and a stand-in for it; a pair with one member found; a control and an
            // out-of-library trial naming something (their own rows).
            trial(Excitation, &[Damping], &[Damping, Friction], false),
            trial(Excitation, &[Damping, Latency], &[Latency], false),
            trial(Excitation, &[], &[Armature], false),
            trial(Excitation, &[], &[Friction], true),
        ];
        let s = super::summarize(&scores);
        assert_eq!((s.named_injected, s.named_in_effect_trials), (2, 3));
        let t = super::table_by_input(&scores);
        assert!(t.contains("| named effects that were injected, effect trials | 2 of 3 (67 %) |  |"), "{t}");
    }
}
