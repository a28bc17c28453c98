//! Rollouts in several engines: windowed divergence from identical states, per-engine invariants and
//! free-running episode outcomes.
use crate::phase::{ContactPhase, FootContact};
use crate::scenario::Scenario;
use crate::DiffError;
use diff_physics::pd::pd_torques_into;
use diff_physics::{make_engine, CommonSettings, Contact, Engine, EngineError, EngineKind, LinkPose, PdTarget, State};
use physics_invariants::names;
use policy_runtime::{Controller, RobotObservation};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Builds engines. The built-in kinds come through [`BuiltinEngine`]; a different engine build (another
/// Rapier version, another solver setting) plugs in by implementing this.
pub trait EngineFactory: Send + Sync + std::fmt::Debug {
    /// Stable name used in reports and reproducers.
    fn name(&self) -> String;
    fn build(&self, model: &RobotModel, common: &CommonSettings) -> Result<Box<dyn Engine>, EngineError>;
}

/// One of the project's engines with its default specific settings.
#[derive(Debug, Clone, Copy)]
pub struct BuiltinEngine(pub EngineKind);

impl EngineFactory for BuiltinEngine {
    fn name(&self) -> String {
        self.0.name().to_string()
    }
    fn build(&self, model: &RobotModel, common: &CommonSettings) -> Result<Box<dyn Engine>, EngineError> {
        make_engine(self.0, model, common)
    }
}

/// Factories for engine names (`mujoco`, `rapier-multibody`, `rapier_impulse`, ...).
pub fn builtin_factories(names: &[String]) -> Result<Vec<Arc<dyn EngineFactory>>, DiffError> {
    names
        .iter()
        .map(|n| {
            EngineKind::parse_available(n.trim())
                .map(|k| Arc::new(BuiltinEngine(k)) as Arc<dyn EngineFactory>)
                .map_err(|e| DiffError::Input(e.to_string()))
        })
        .collect()
}

/// Makes a fresh controller for a scenario (each engine's free run gets its own instance).
pub type ControllerFactory = dyn Fn(&Scenario) -> Result<Box<dyn Controller>, DiffError> + Send + Sync;

/// Harness settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct HarnessConfig {
    /// Steps per divergence window (k of the k-step divergence). Default 50 = 0.1 s at dt 2 ms.
    pub window_steps: usize,
    pub common: CommonSettings,
    /// Also run every engine closed-loop over the whole episode (outcomes). Off while fuzzing.
    pub free_runs: bool,
    /// Keep every free run's states at this many frames per second of simulated time
    /// ([`EpisodeResult::trajectories`]): what `ulab diff --video` renders after the run. `None`: keep none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub record_fps: Option<f64>,
}

impl Default for HarnessConfig {
    fn default() -> Self {
        HarnessConfig { window_steps: 50, common: CommonSettings::default(), free_runs: true, record_fps: None }
    }
}

/// Divergence of one engine from the lead at one instant (absolute differences).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Div {
    /// Per joint (rad), slot order.
    pub q: Vec<f64>,
    /// Per joint (rad/s).
    pub dq: Vec<f64>,
    /// Per link origin position (m), `model.links` order.
    pub link_pos: Vec<f64>,
    pub base_pos: f64,
    /// Angle between the pelvis orientations (rad).
    pub base_rot: f64,
    pub base_lin_vel: f64,
    pub base_ang_vel: f64,
}

pub use physics_invariants::exceeds;

fn max_of(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}

fn dist3(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

impl Div {
    pub fn between(lead: &State, lead_links: &[LinkPose], other: &State, other_links: &[LinkPose]) -> Div {
        let abs = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).abs()).collect::<Vec<_>>();
        Div {
            q: abs(&lead.q, &other.q),
            dq: abs(&lead.dq, &other.dq),
            link_pos: lead_links.iter().zip(other_links).map(|(a, b)| dist3(a.pos, b.pos)).collect(),
            base_pos: dist3(lead.base_pos, other.base_pos),
            base_rot: diff_physics::engine::quat_angle(lead.base_quat, other.base_quat),
            base_lin_vel: dist3(lead.base_lin_vel, other.base_lin_vel),
            base_ang_vel: dist3(lead.base_ang_vel, other.base_ang_vel),
        }
    }
    pub fn max_q(&self) -> f64 {
        max_of(&self.q)
    }
    pub fn max_dq(&self) -> f64 {
        max_of(&self.dq)
    }
    pub fn max_link(&self) -> f64 {
        max_of(&self.link_pos)
    }
}

/// The bounds a divergence is compared with: `physics_invariants::Bounds` (2.5 g contact-acceleration gap; one
/// step: base velocity Δv ≤ 2.5·g·dt, joint and base angular velocities 10× that; k steps: link positions
/// ½·2.5·g·(k·dt)²), shared with the rediscovery bench.
pub use physics_invariants::Bounds;

/// (quantity, value, bound) of the one-step checks of a divergence.
pub fn one_step_checks(b: &Bounds, d: &Div) -> [(&'static str, f64, f64); 3] {
    [
        ("base linear velocity", d.base_lin_vel, b.one_step_base_lin_vel),
        ("joint velocity", d.max_dq(), b.one_step_joint_vel),
        ("base angular velocity", d.base_ang_vel, b.one_step_base_ang_vel),
    ]
}

/// Everything needed to replay one window in any engine: the start state, the targets that become active at
/// given step offsets (offset 0 always present) and the pushes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WindowInput {
    pub start: State,
    pub steps: usize,
    pub targets: Vec<(usize, PdTarget)>,
    pub pushes: Vec<(usize, [f64; 3])>,
}

/// One engine's divergence from the lead in one window.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EngineDiv {
    pub engine: String,
    pub one_step: Div,
    pub k_step: Div,
}

/// One window of an episode.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct WindowRecord {
    pub index: usize,
    pub t0: f64,
    /// Contact phase of the lead at the window start.
    pub phase: ContactPhase,
    /// Distinct robot bodies touching the ground in the lead at the window start.
    pub contact_bodies: Vec<String>,
    pub divs: Vec<EngineDiv>,
    pub input: WindowInput,
}

/// What makes findings one group: kind, engine, quantity and contact phase.
pub type GroupKey = (String, String, String, ContactPhase);

/// A measured excess: a cross-engine bound or a per-engine invariant.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Finding {
    /// `one_step_bound`, `k_step_bound` or `invariant`.
    pub kind: String,
    /// Engine the finding is about (compared with the lead for cross-engine kinds).
    pub engine: String,
    pub lead: String,
    pub quantity: String,
    pub value: f64,
    pub bound: f64,
    pub window: usize,
    pub t0: f64,
    pub phase: ContactPhase,
    pub contact_bodies: usize,
}

impl Finding {
    pub fn ratio(&self) -> f64 {
        if self.bound > 0.0 {
            self.value / self.bound
        } else {
            f64::INFINITY
        }
    }
    /// Findings of one group are the same divergence seen several times.
    pub fn group_key(&self) -> GroupKey {
        (self.kind.clone(), self.engine.clone(), self.quantity.clone(), self.phase)
    }
}

/// Free-run outcome of one engine in one episode.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Outcome {
    pub engine: String,
    pub fell: bool,
    pub fall_time: Option<f64>,
    /// RMS over time and joints of (q − q_des) (rad).
    pub joint_tracking_rms: f64,
    /// RMS of planar velocity and yaw-rate errors against the command (m/s, rad/s mixed).
    pub velocity_tracking_rms: f64,
    /// Set when the engine failed (reported, never silently dropped).
    pub error: Option<String>,
    /// Simulated time before the fall (or the engine error), else the whole episode (s).
    #[serde(default)]
    pub survived_s: f64,
    /// Horizontal distance of the pelvis from its start (m).
    #[serde(default)]
    pub distance_m: f64,
    /// Positive mechanical work of the joint torques, Σ max(τ·q̇, 0)·dt (J): the effort a motor pays for.
    #[serde(default)]
    pub energy_j: f64,
    /// Steps at which some joint was within [`LIMIT_MARGIN_RAD`] of a position limit.
    #[serde(default)]
    pub joint_limit_steps: u64,
    /// Mean horizontal speed of the links in ground contact (m/s; 0 without contact samples): foot slip.
    #[serde(default)]
    pub foot_slip_mps: f64,
    /// RMS of each velocity-tracking error: forward (m/s), lateral (m/s), yaw rate (rad/s).
    #[serde(default)]
    pub velocity_error_rms: [f64; 3],
}

impl Outcome {
    /// The outcome of `engine` before its first step: nothing measured, no fall, no error.
    pub fn before_start(engine: &str) -> Outcome {
        Outcome {
            engine: engine.into(),
            fell: false,
            fall_time: None,
            joint_tracking_rms: 0.0,
            velocity_tracking_rms: 0.0,
            error: None,
            survived_s: 0.0,
            distance_m: 0.0,
            energy_j: 0.0,
            joint_limit_steps: 0,
            foot_slip_mps: 0.0,
            velocity_error_rms: [0.0; 3],
        }
    }
}

/// A joint this close to a position limit (rad) counts as hitting it.
pub const LIMIT_MARGIN_RAD: f64 = 0.01;
/// Foot slip is sampled every this many physics steps (link poses are not free in every engine).
const SLIP_EVERY: usize = 5;

/// Links touching the ground, by index in `model.links`.
fn grounded_links(model: &RobotModel, contacts: &[Contact]) -> Vec<usize> {
    let mut v: Vec<usize> = contacts
        .iter()
        .filter_map(|c| match (c.body_a.as_str(), c.body_b.as_str()) {
            ("ground", l) | (l, "ground") => model.link_index(l),
            _ => None,
        })
        .collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// Time split for the benchmark.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct Timing {
    pub engine_s: f64,
    pub total_s: f64,
    pub steps: u64,
}

/// One episode's results: what a sharded `ulab diff` stores per episode for the analysis at merge time.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EpisodeResult {
    pub scenario: Scenario,
    pub engines: Vec<String>,
    pub windows: Vec<WindowRecord>,
    pub findings: Vec<Finding>,
    pub outcomes: Vec<Outcome>,
    pub timing: Timing,
    /// Distinct contact patterns seen at window starts (fuzzing novelty).
    pub contact_patterns: std::collections::BTreeSet<String>,
    /// Per engine, the free run's states when [`HarnessConfig::record_fps`] asks for them (for rendering, not for
    /// the report; not stored: only an unsharded run renders).
    #[serde(skip)]
    pub trajectories: Vec<Trajectory>,
}

/// One engine's free run sampled at a fixed rate of simulated time: sample `k` is the state at the physics step
/// nearest `k / fps` seconds (sample 0 the initial state). It ends where the run ended (a fall, an engine error).
#[derive(Debug, Clone)]
pub struct Trajectory {
    pub engine: String,
    pub fps: f64,
    /// State and link poses (`model.links` order) of each sample.
    pub samples: Vec<(State, Vec<LinkPose>)>,
}

impl Trajectory {
    /// An empty trajectory of `engine` at `fps` samples per second (filled by [`free_run_recorded`]).
    pub fn new(engine: &str, fps: f64) -> Self {
        Trajectory { engine: engine.to_owned(), fps, samples: Vec::new() }
    }

    /// Takes the samples due by physics step `step` (time `step * dt`) from the engine's current state.
    fn sample(&mut self, e: &mut dyn Engine, step: usize, dt: f64) {
        while ((self.samples.len() as f64 / self.fps) / dt).round() as usize <= step {
            self.samples.push((e.state(), e.link_poses()));
        }
    }
}

impl EpisodeResult {
    /// The largest ratio of a cross-engine divergence or invariant to its bound.
    pub fn worst_ratio(&self) -> f64 {
        self.findings.iter().map(Finding::ratio).fold(0.0, f64::max).max(self.divergence_score())
    }
    /// Largest one-step ratio over every window and engine (also below 1).
    pub fn divergence_score(&self) -> f64 {
        let b = Bounds::new(0.002, 1);
        self.windows
            .iter()
            .flat_map(|w| w.divs.iter())
            .flat_map(|d| one_step_checks(&b, &d.one_step).map(|(_, v, bd)| v / bd))
            .fold(0.0, f64::max)
    }
}

/// The model with a scenario's ground friction.
pub fn scenario_model(model: &RobotModel, s: &Scenario) -> RobotModel {
    let mut m = model.clone();
    if let Some(f) = s.ground_friction {
        m.contact.friction = f;
    }
    m
}

/// Standing, with the scenario's initial joint offsets and height. Offsets that bend a leg would push a foot
/// into the ground; the base is raised so that the lowest collision point is no lower than in the standing
/// pose (an initial penetration is a property of the input, not of an engine).
pub fn initial_state(model: &RobotModel, s: &Scenario) -> Result<State, DiffError> {
    let mut st = State::standing(model);
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed ^ 0x1A1_1A1);
    let a = s.init_q_offset;
    if a > 0.0 {
        let standing_low = model.lowest_point_z(&st.coords())?;
        for (i, j) in model.joints.iter().enumerate() {
            st.q[i] = (st.q[i] + rng.gen_range(-a..=a)).clamp(j.lower, j.upper);
        }
        let low = model.lowest_point_z(&st.coords())?;
        st.base_pos[2] += (standing_low - low).max(0.0);
    }
    st.base_pos[2] += s.init_height;
    Ok(st)
}

/// Contact phase and the robot bodies touching the ground.
pub fn phase_of(contacts: &[Contact]) -> (ContactPhase, Vec<String>) {
    let mut bodies: Vec<String> =
        contacts.iter().filter(|c| c.body_a == "ground" && c.normal_force > 0.0).map(|c| c.body_b.clone()).collect();
    bodies.sort();
    bodies.dedup();
    let foot = |side: &str| bodies.iter().any(|b| b.starts_with(side) && b.contains("ankle"));
    let other = bodies.iter().any(|b| !b.contains("ankle"));
    let feet = FootContact::from_feet(foot("left"), foot("right"));
    (ContactPhase { feet, other }, bodies)
}

fn yaw_of(q: [f64; 4]) -> f64 {
    let [w, x, y, z] = q;
    (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z))
}

/// Observation, control, noise and jitter: the part of the loop that is the same for the windowed run and
/// every free run (same random streams, so every engine sees the same noise sequence).
struct Loop {
    ctrl: Box<dyn Controller>,
    ctrl_steps: usize,
    dt: f64,
    obs_rng: ChaCha8Rng,
    act_rng: ChaCha8Rng,
    jit_rng: ChaCha8Rng,
    pending: Vec<(usize, PdTarget)>,
    active: PdTarget,
}

impl Loop {
    fn new(ctrl_factory: &ControllerFactory, model: &RobotModel, s: &Scenario, dt: f64) -> Result<Self, DiffError> {
        let mut ctrl = ctrl_factory(s)?;
        ctrl.reset();
        let p = ctrl.period();
        if !(p.is_finite() && p > 0.0) {
            return Err(DiffError::Input(format!("controller period {p} must be positive")));
        }
        Ok(Loop {
            ctrl,
            ctrl_steps: ((p / dt).round() as usize).max(1),
            dt,
            obs_rng: ChaCha8Rng::seed_from_u64(s.seed ^ 0x0B5_0B5),
            act_rng: ChaCha8Rng::seed_from_u64(s.seed ^ 0xAC7_AC7),
            jit_rng: ChaCha8Rng::seed_from_u64(s.seed ^ 0x717_717),
            pending: Vec::new(),
            active: PdTarget::hold_standing(model),
        })
    }

    /// The target active at global step `g` given the state the robot reports; true when it changed.
    fn target(&mut self, g: usize, st: &State, s: &Scenario) -> Result<bool, DiffError> {
        if g.is_multiple_of(self.ctrl_steps) {
            let t = g as f64 * self.dt;
            let n = s.obs_noise;
            let mut noise = |scale: f64| if n > 0.0 { self.obs_rng.gen_range(-n..=n) * scale } else { 0.0 };
            let obs = RobotObservation {
                time: t,
                base_quat: st.base_quat,
                base_ang_vel: [
                    st.base_ang_vel[0] + noise(10.0),
                    st.base_ang_vel[1] + noise(10.0),
                    st.base_ang_vel[2] + noise(10.0),
                ],
                q: st.q.iter().map(|x| x + noise(1.0)).collect(),
                dq: st.dq.iter().map(|x| x + noise(10.0)).collect(),
                command: s.command_at(t),
            };
            let mut target = self.ctrl.act(&obs)?;
            let a = s.action_noise;
            if a > 0.0 {
                target.q_des.iter_mut().for_each(|x| *x += self.act_rng.gen_range(-a..=a));
            }
            if target
                .q_des
                .iter()
                .chain(&target.kp)
                .chain(&target.kd)
                .chain(&target.tau_ff)
                .chain(&target.dq_des)
                .any(|x| !x.is_finite())
            {
                return Err(DiffError::Input(format!("controller {} returned a non-finite target", self.ctrl.name())));
            }
            let delay = if s.timing_jitter > 0 { self.jit_rng.gen_range(0..=s.timing_jitter as usize) } else { 0 };
            self.pending.push((g + delay, target));
        }
        let mut changed = false;
        // Latest due target wins; later-due ones stay pending.
        while let Some(i) = self.pending.iter().position(|(due, _)| *due <= g) {
            let (_, t) = self.pending.remove(i);
            self.active = t;
            changed = true;
        }
        Ok(changed)
    }
}

/// A push due at global step `g` (pushes are quantized to the physics step).
fn pushes_at(s: &Scenario, g: usize, dt: f64) -> Vec<[f64; 3]> {
    s.pushes.iter().filter(|p| (p.t / dt).round() as usize == g).map(|p| p.dv).collect()
}

fn apply_push(e: &mut dyn Engine, dv: [f64; 3]) -> Result<(), EngineError> {
    let mut st = e.state();
    for (v, d) in st.base_lin_vel.iter_mut().zip(dv) {
        *v += d;
    }
    e.reset(&st)
}

/// Per-engine invariants checked every step, with the thresholds of `physics_invariants` (derivations there):
/// quaternion norm, contact forces finite and ≥ 0, penetration, joint-limit overrun; passivity per window.
#[derive(Debug, Default)]
struct InvariantState {
    worst: std::collections::BTreeMap<(usize, &'static str), (f64, f64)>,
    /// Largest value of every invariant checked, violated or not (what an experiment measures).
    peak: std::collections::BTreeMap<(usize, &'static str), (f64, f64)>,
    energy_start: Vec<f64>,
    work: Vec<f64>,
    abs_work: Vec<f64>,
    /// Per engine: centre-of-mass positions of the current run of contact-free steps (free-fall check).
    free_com: Vec<Vec<[f64; 3]>>,
}

fn note(inv: &mut InvariantState, e: usize, what: &'static str, value: f64, bound: f64) {
    let v = if value.is_nan() { f64::INFINITY } else { value };
    let p = inv.peak.entry((e, what)).or_insert((v, bound));
    if v > p.0 {
        *p = (v, bound);
    }
    if v > bound {
        let ent = inv.worst.entry((e, what)).or_insert((v, bound));
        if v > ent.0 {
            *ent = (v, bound);
        }
    }
}

fn check_step(inv: &mut InvariantState, i: usize, e: &dyn Engine, st: &State, limits: &[(f64, f64)]) {
    let n: f64 = st.base_quat.iter().map(|x| x * x).sum::<f64>().sqrt();
    note(inv, i, names::QUAT_NORM, (n - 1.0).abs(), physics_invariants::QUAT_NORM_TOL);
    for c in e.contacts() {
        if !c.normal_force.is_finite() || c.normal_force < 0.0 {
            note(inv, i, names::CONTACT_FORCE, c.normal_force.abs().max(1e-300), 0.0);
        }
        note(inv, i, names::PENETRATION, c.depth, physics_invariants::PENETRATION_MAX);
    }
    let over = st.q.iter().zip(limits).map(|(q, (lo, hi))| (lo - q).max(q - hi)).fold(0.0, f64::max);
    note(inv, i, names::JOINT_LIMIT, over, physics_invariants::JOINT_LIMIT_OVERRUN_MAX);
}

/// The result of simulating one window in every engine.
#[derive(Debug)]
pub struct WindowRun {
    /// Per engine: state and link poses after the first step and after the last.
    pub after_one: Vec<(State, Vec<LinkPose>)>,
    pub after_k: Vec<(State, Vec<LinkPose>)>,
    /// Per engine `(quantity, value, bound)` of violated invariants.
    pub invariants: Vec<Vec<(String, f64, f64)>>,
    /// Per engine `(quantity, largest value, bound)` of every invariant checked in the window, violated or not:
    /// how far below its bound an engine stayed (the allow-list experiments measure with it).
    pub invariant_peaks: Vec<Vec<(String, f64, f64)>>,
    pub engine_time: Duration,
    /// When requested: per step, per engine, state and link poses.
    pub trace: Vec<Vec<(State, Vec<LinkPose>)>>,
}

/// Resets every engine to `input.start` and runs `steps` steps (≤ `input.steps`) with the input's targets and
/// pushes, PD torques computed from each engine's own state. `live` (the episode) may produce targets online
/// from the lead's state; replay passes `None` and uses `input.targets`.
/// An engine's error while it runs a window, with the engine's name and time.
fn failed(e: &dyn Engine, source: diff_physics::EngineError) -> DiffError {
    DiffError::EngineFailed { engine: e.name().to_string(), t: e.time(), source: Box::new(source) }
}

/// An input on which an engine failed (`ulab diff fuzz` keeps and reports them: a diverging engine is the
/// plainest engine bug there is, not an input to skip).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EngineFailure {
    pub engine: String,
    /// Simulated time at the start of the step that failed (s).
    pub t: f64,
    /// The engine's error.
    pub error: String,
    /// The input, replayable as a seed corpus entry (`ulab diff fuzz --corpus`).
    pub scenario: Scenario,
}

fn simulate_window(
    engines: &mut [Box<dyn Engine>],
    model: &RobotModel,
    input: &mut WindowInput,
    steps: usize,
    mut live: Option<(&mut Loop, &Scenario, usize)>,
    dt: f64,
    trace: bool,
) -> Result<WindowRun, DiffError> {
    let mut tr = Vec::new();
    let torque_limits: Vec<f64> = model.joints.iter().map(|j| j.torque_limit).collect();
    let joint_limits: Vec<(f64, f64)> = model.joints.iter().map(|j| (j.lower, j.upper)).collect();
    let ne = engines.len();
    let mut inv = InvariantState {
        energy_start: vec![0.0; ne],
        work: vec![0.0; ne],
        abs_work: vec![0.0; ne],
        free_com: vec![Vec::new(); ne],
        ..Default::default()
    };
    let mut engine_time = Duration::ZERO;
    let gravity = engines.first().map_or([0.0, 0.0, -robot_model::GRAVITY_EARTH], |e| e.common().gravity);
    for (i, e) in engines.iter_mut().enumerate() {
        e.reset(&input.start).map_err(|source| failed(e.as_ref(), source))?;
        inv.energy_start[i] = e.energy().total();
    }
    let mut tau = vec![0.0; model.nj()];
    let mut target = input.targets.first().map(|t| t.1.clone()).unwrap_or_else(|| PdTarget::hold_standing(model));
    let (mut after_one, mut after_k) = (Vec::new(), Vec::new());
    for s in 0..steps {
        let mut row = Vec::new();
        if let Some((lp, sc, g0)) = live.as_mut() {
            let lead = engines[0].state();
            if lp.target(*g0 + s, &lead, sc)? || s == 0 {
                target = lp.active.clone();
                input.targets.retain(|(o, _)| *o != s);
                input.targets.push((s, target.clone()));
            }
            for dv in pushes_at(sc, *g0 + s, dt) {
                input.pushes.push((s, dv));
            }
        } else if let Some((_, t)) = input.targets.iter().rev().find(|(o, _)| *o == s) {
            target = t.clone();
        }
        let pushes: Vec<[f64; 3]> = input.pushes.iter().filter(|(o, _)| *o == s).map(|p| p.1).collect();
        for (i, e) in engines.iter_mut().enumerate() {
            for &dv in &pushes {
                let before = e.energy().total();
                apply_push(e.as_mut(), dv)?;
                inv.work[i] += e.energy().total() - before;
            }
            let st = e.state();
            pd_torques_into(&target, &st.q, &st.dq, &torque_limits, &mut tau);
            let t0 = Instant::now();
            e.step(&tau).map_err(|source| failed(e.as_ref(), source))?;
            engine_time += t0.elapsed();
            let after = e.state();
            let w: f64 = tau.iter().zip(after.q.iter().zip(&st.q)).map(|(t, (a, b))| t * (a - b)).sum();
            inv.work[i] += w;
            inv.abs_work[i] +=
                tau.iter().zip(after.q.iter().zip(&st.q)).map(|(t, (a, b))| (t * (a - b)).abs()).sum::<f64>();
            check_step(&mut inv, i, e.as_ref(), &after, &joint_limits);
            // Free fall: three consecutive contact-free samples without a push in between.
            if e.contacts().is_empty() && pushes.is_empty() {
                let c = e.com();
                let h = &mut inv.free_com[i];
                h.push(c);
                if h.len() >= 3 {
                    let n = h.len();
                    // Judged against the lead's gravity: the world every engine is supposed to simulate.
                    let err = physics_invariants::free_fall_error([h[n - 3], h[n - 2], h[n - 1]], dt, gravity);
                    let g = gravity.iter().map(|x| x * x).sum::<f64>().sqrt();
                    note(&mut inv, i, names::FREE_FALL, err, physics_invariants::FREE_FALL_ACCEL_TOL_FRACTION * g);
                }
            } else {
                inv.free_com[i].clear();
            }
            if s == 0 {
                after_one.push((after.clone(), e.link_poses()));
            }
            if trace {
                row.push((after.clone(), e.link_poses()));
            }
            if s + 1 == steps {
                after_k.push((after, e.link_poses()));
            }
        }
        if trace {
            tr.push(row);
        }
    }
    // Passivity: with PD torques as the only actuation, mechanical energy can grow at most by the actuator
    // work Σ τ·Δq (plus push energy); damping, friction and contacts dissipate. Tolerance 1 J + 5% of the
    // gross actuator work (the discrete work estimate uses τ held over the step: O(dt) relative error).
    for (i, e) in engines.iter_mut().enumerate() {
        let gain = e.energy().total() - inv.energy_start[i] - inv.work[i];
        let tol = physics_invariants::energy_tolerance(inv.abs_work[i]);
        note(&mut inv, i, names::ENERGY, gain, tol);
    }
    let mut invariants = vec![Vec::new(); ne];
    for ((i, what), (v, b)) in inv.worst {
        invariants[i].push((what.to_string(), v, b));
    }
    let mut invariant_peaks = vec![Vec::new(); ne];
    for ((i, what), (v, b)) in inv.peak {
        invariant_peaks[i].push((what.to_string(), v, b));
    }
    Ok(WindowRun { after_one, after_k, invariants, invariant_peaks, engine_time, trace: tr })
}

/// Replays a window (no controller): the same function the episode used, so results are bit-identical.
pub fn replay_window(
    engines: &mut [Box<dyn Engine>],
    model: &RobotModel,
    input: &WindowInput,
    steps: usize,
    dt: f64,
    trace: bool,
) -> Result<WindowRun, DiffError> {
    let mut inp = input.clone();
    simulate_window(engines, model, &mut inp, steps.min(input.steps).max(1), None, dt, trace)
}

/// Builds every engine for a scenario's model.
pub fn build_engines(
    factories: &[Arc<dyn EngineFactory>],
    model: &RobotModel,
    common: &CommonSettings,
) -> Result<Vec<Box<dyn Engine>>, DiffError> {
    factories.iter().map(|f| f.build(model, common).map_err(DiffError::from)).collect()
}

/// Runs one episode: windowed divergence (lead = first factory) and, if configured, free runs.
pub fn run_episode(
    model: &RobotModel,
    factories: &[Arc<dyn EngineFactory>],
    ctrl_factory: &ControllerFactory,
    scenario: &Scenario,
    cfg: &HarnessConfig,
) -> Result<EpisodeResult, DiffError> {
    let wall = Instant::now();
    if factories.len() < 2 {
        return Err(DiffError::Input("at least two engines are needed".into()));
    }
    let m = scenario_model(model, scenario);
    let mut engines = build_engines(factories, &m, &cfg.common)?;
    let names: Vec<String> = factories.iter().map(|f| f.name()).collect();
    let mut r = run_episode_on(&mut engines, &names, &m, ctrl_factory, scenario, cfg)?;
    r.timing.total_s = wall.elapsed().as_secs_f64();
    Ok(r)
}

/// [`run_episode`] on engines already built for `scenario_model(model, scenario)` (the fuzz target keeps
/// its engines between inputs; `reset` is a true reset by the `Engine` contract).
pub fn run_episode_on(
    engines: &mut [Box<dyn Engine>],
    names: &[String],
    m: &RobotModel,
    ctrl_factory: &ControllerFactory,
    scenario: &Scenario,
    cfg: &HarnessConfig,
) -> Result<EpisodeResult, DiffError> {
    let wall = Instant::now();
    scenario.validate()?;
    if engines.len() < 2 || names.len() != engines.len() {
        return Err(DiffError::Input("at least two engines (with names) are needed".into()));
    }
    let m = m.clone();
    let k = cfg.window_steps.max(1);
    let dt = cfg.common.timestep;
    let total_steps = ((scenario.seconds / dt).round() as usize).max(1);
    let bounds = Bounds::new(dt, k);
    let mut lp = Loop::new(ctrl_factory, &m, scenario, dt)?;
    let mut state = initial_state(&m, scenario)?;
    let mut windows = Vec::new();
    let mut findings = Vec::new();
    let mut patterns = std::collections::BTreeSet::new();
    let mut timing = Timing::default();
    engines[0].reset(&state)?;
    let mut lead_contacts = engines[0].contacts();
    let mut g0 = 0;
    let mut index = 0;
    while g0 < total_steps {
        let steps = k.min(total_steps - g0);
        let (phase, bodies) = phase_of(&lead_contacts);
        patterns.insert(format!("{phase}:{}", bodies.join(",")));
        let mut input = WindowInput { start: state.clone(), steps, targets: Vec::new(), pushes: Vec::new() };
        let run = simulate_window(engines, &m, &mut input, steps, Some((&mut lp, scenario, g0)), dt, false)?;
        timing.engine_s += run.engine_time.as_secs_f64();
        timing.steps += (steps * engines.len()) as u64;
        let t0 = g0 as f64 * dt;
        let mk = |kind: &str, engine: &str, quantity: &str, value: f64, bound: f64| Finding {
            kind: kind.into(),
            engine: engine.into(),
            lead: names[0].clone(),
            quantity: quantity.into(),
            value,
            bound,
            window: index,
            t0,
            phase,
            contact_bodies: bodies.len(),
        };
        let mut divs = Vec::new();
        #[allow(clippy::needless_range_loop)]
        for i in 1..engines.len() {
            let one = Div::between(&run.after_one[0].0, &run.after_one[0].1, &run.after_one[i].0, &run.after_one[i].1);
            let kd = Div::between(&run.after_k[0].0, &run.after_k[0].1, &run.after_k[i].0, &run.after_k[i].1);
            for (q, v, b) in one_step_checks(&bounds, &one) {
                if exceeds(v, b) {
                    findings.push(mk("one_step_bound", &names[i], q, v, b));
                }
            }
            if steps == k && exceeds(kd.max_link(), bounds.k_step_link_pos) {
                findings.push(mk("k_step_bound", &names[i], "link position", kd.max_link(), bounds.k_step_link_pos));
            }
            divs.push(EngineDiv { engine: names[i].clone(), one_step: one, k_step: kd });
        }
        for (i, inv) in run.invariants.iter().enumerate() {
            for (q, v, b) in inv {
                findings.push(mk("invariant", &names[i], q, *v, *b));
            }
        }
        windows.push(WindowRecord { index, t0, phase, contact_bodies: bodies, divs, input });
        state = run.after_k[0].0.clone();
        lead_contacts = engines[0].contacts();
        g0 += steps;
        index += 1;
    }
    let mut outcomes = Vec::new();
    let mut trajectories = Vec::new();
    if cfg.free_runs {
        for (i, e) in engines.iter_mut().enumerate() {
            let mut traj = cfg.record_fps.map(|fps| Trajectory::new(&names[i], fps));
            let (o, steps) =
                free_run_recorded(e.as_mut(), &names[i], &m, ctrl_factory, scenario, dt, total_steps, traj.as_mut())?;
            timing.engine_s += o.1;
            timing.steps += steps;
            outcomes.push(o.0);
            trajectories.extend(traj);
        }
    }
    timing.total_s = wall.elapsed().as_secs_f64();
    Ok(EpisodeResult {
        scenario: scenario.clone(),
        engines: names.to_vec(),
        windows,
        findings,
        outcomes,
        timing,
        contact_patterns: patterns,
        trajectories,
    })
}

/// Whether the robot has fallen: pelvis below half its standing height or tilted more than 1 rad.
pub fn fallen(model: &RobotModel, st: &State) -> bool {
    st.base_pos[2] < 0.5 * model.standing.base_pos[2] || robot_model::tilt_from_vertical(st.base_quat) > 1.0
}

/// One engine closed-loop over the episode (its own controller instance, the same noise streams).
/// Returns the outcome with the seconds spent inside `Engine::step`, and the number of steps.
#[allow(clippy::type_complexity)]
pub fn free_run(
    e: &mut dyn Engine,
    name: &str,
    model: &RobotModel,
    ctrl_factory: &ControllerFactory,
    s: &Scenario,
    dt: f64,
    total_steps: usize,
) -> Result<((Outcome, f64), u64), DiffError> {
    free_run_recorded(e, name, model, ctrl_factory, s, dt, total_steps, None)
}

/// [`free_run`], also sampling the states into `traj` when given (a video of the run).
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
pub fn free_run_recorded(
    e: &mut dyn Engine,
    name: &str,
    model: &RobotModel,
    ctrl_factory: &ControllerFactory,
    s: &Scenario,
    dt: f64,
    total_steps: usize,
    mut traj: Option<&mut Trajectory>,
) -> Result<((Outcome, f64), u64), DiffError> {
    if let Some(t) = &traj {
        if !(t.fps.is_finite() && t.fps > 0.0) {
            return Err(DiffError::Input(format!("trajectory rate {} frames/s must be positive", t.fps)));
        }
    }
    let mut lp = Loop::new(ctrl_factory, model, s, dt)?;
    let limits: Vec<f64> = model.joints.iter().map(|j| j.torque_limit).collect();
    let mut tau = vec![0.0; model.nj()];
    let mut out = Outcome::before_start(name);
    let (mut jsum, mut vsum, mut n) = (0.0, 0.0, 0usize);
    let mut vcomp = [0.0; 3];
    let mut engine_s = 0.0;
    let mut steps = 0u64;
    let (mut slip_sum, mut slip_n) = (0.0, 0usize);
    let mut start_xy = [0.0; 2];
    // Grounded links and their positions at the previous slip sample.
    let mut grounded: Vec<(usize, [f64; 3])> = Vec::new();
    let res: Result<(), DiffError> = (|| {
        let init = initial_state(model, s)?;
        start_xy = [init.base_pos[0], init.base_pos[1]];
        e.reset(&init)?;
        if let Some(t) = traj.as_deref_mut() {
            t.sample(&mut *e, 0, dt);
        }
        for g in 0..total_steps {
            let st = e.state();
            lp.target(g, &st, s)?;
            for dv in pushes_at(s, g, dt) {
                apply_push(e, dv)?;
            }
            let st = e.state();
            pd_torques_into(&lp.active, &st.q, &st.dq, &limits, &mut tau);
            let t0 = Instant::now();
            e.step(&tau)?;
            engine_s += t0.elapsed().as_secs_f64();
            steps += 1;
            if let Some(t) = traj.as_deref_mut() {
                t.sample(&mut *e, g + 1, dt);
            }
            let st = e.state();
            out.survived_s = (g + 1) as f64 * dt;
            out.distance_m = (st.base_pos[0] - start_xy[0]).hypot(st.base_pos[1] - start_xy[1]);
            out.energy_j += tau.iter().zip(&st.dq).map(|(t, v)| (t * v).max(0.0)).sum::<f64>() * dt;
            if model
                .joints
                .iter()
                .zip(&st.q)
                .any(|(j, q)| *q < j.lower + LIMIT_MARGIN_RAD || *q > j.upper - LIMIT_MARGIN_RAD)
            {
                out.joint_limit_steps += 1;
            }
            if g.is_multiple_of(SLIP_EVERY) {
                let now = grounded_links(model, &e.contacts());
                let poses = e.link_poses();
                for &(l, p0) in &grounded {
                    if let (true, Some(p1)) = (now.contains(&l), poses.get(l)) {
                        slip_sum += (p1.pos[0] - p0[0]).hypot(p1.pos[1] - p0[1]) / (SLIP_EVERY as f64 * dt);
                        slip_n += 1;
                    }
                }
                grounded = now.iter().filter_map(|&l| poses.get(l).map(|p| (l, p.pos))).collect();
            }
            let nj = st.q.len().max(1) as f64;
            jsum += st.q.iter().zip(&lp.active.q_des).map(|(q, d)| (q - d).powi(2)).sum::<f64>() / nj;
            let cmd = s.command_at(g as f64 * dt);
            let yaw = yaw_of(st.base_quat);
            let (c, sn) = (yaw.cos(), yaw.sin());
            let vx = c * st.base_lin_vel[0] + sn * st.base_lin_vel[1];
            let vy = -sn * st.base_lin_vel[0] + c * st.base_lin_vel[1];
            let err = [(vx - cmd[0]).powi(2), (vy - cmd[1]).powi(2), (st.base_ang_vel[2] - cmd[2]).powi(2)];
            vsum += err.iter().sum::<f64>() / 3.0;
            vcomp.iter_mut().zip(err).for_each(|(a, e)| *a += e);
            n += 1;
            if fallen(model, &st) {
                out.fell = true;
                out.fall_time = Some((g + 1) as f64 * dt);
                break;
            }
        }
        Ok(())
    })();
    if let Err(err) = res {
        match err {
            DiffError::Engine(ee) => {
                out.error = Some(ee.to_string());
                out.fell = true;
            }
            other => return Err(other),
        }
    }
    out.joint_tracking_rms = (jsum / n.max(1) as f64).sqrt();
    out.velocity_tracking_rms = (vsum / n.max(1) as f64).sqrt();
    out.foot_slip_mps = if slip_n > 0 { slip_sum / slip_n as f64 } else { 0.0 };
    out.velocity_error_rms = vcomp.map(|a| (a / n.max(1) as f64).sqrt());
    Ok(((out, engine_s), steps))
}

/// The built-in excitation controller factory.
pub fn excitation_factory(model: &RobotModel) -> Box<ControllerFactory> {
    let m = model.clone();
    Box::new(move |s: &Scenario| {
        Ok(Box::new(crate::excitation::ExcitationController::new(&m, s.excitation, s.seed)) as Box<dyn Controller>)
    })
}
