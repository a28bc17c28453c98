//! Reproducers: one minimized finding as a self-contained JSON file (engines with versions and settings,
//! model hash, scenario and seed, the window's start state and targets stored as exact f64 bits) and its
//! replay, which recomputes the window and compares every final state and the finding's value bit for bit.
use crate::harness::{self, BuiltinEngine, EngineFactory, Finding, WindowInput};
use crate::scenario::Scenario;
use crate::triage::{finding_value, Minimized};
use crate::{DiffError, SCHEMA_VERSION};
use diff_physics::{CommonSettings, EngineKind, PdTarget, State};
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// f64 values as 16-hex-digit bit patterns (exact, unlike decimal text).
pub fn to_bits(v: &[f64]) -> Vec<String> {
    v.iter().map(|x| format!("{:016x}", x.to_bits())).collect()
}

pub fn from_bits(v: &[String]) -> Result<Vec<f64>, DiffError> {
    v.iter()
        .map(|s| {
            u64::from_str_radix(s, 16)
                .map(f64::from_bits)
                .map_err(|_| DiffError::Input(format!("bad f64 bit pattern {s:?}")))
        })
        .collect()
}

/// An engine's identity.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct EngineInfo {
    pub name: String,
    pub version: String,
    pub settings: serde_json::Value,
}

/// A PD target in bits.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TargetBits {
    /// Step offset in the window from which it is active.
    pub offset: usize,
    pub q_des: Vec<String>,
    pub dq_des: Vec<String>,
    pub kp: Vec<String>,
    pub kd: Vec<String>,
    pub tau_ff: Vec<String>,
}

/// A state in bits (MuJoCo `qpos` / `qvel` layouts, see `diff_physics::engine`).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct StateBits {
    pub qpos: Vec<String>,
    pub qvel: Vec<String>,
}

impl StateBits {
    pub fn of(s: &State) -> Self {
        StateBits { qpos: to_bits(&s.qpos()), qvel: to_bits(&s.v()) }
    }
    pub fn state(&self) -> Result<State, DiffError> {
        Ok(State::from_qpos_qvel(&from_bits(&self.qpos)?, &from_bits(&self.qvel)?)?)
    }
}

/// The replayable window.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct WindowBits {
    pub start: StateBits,
    pub steps: usize,
    pub targets: Vec<TargetBits>,
    /// `(step offset, dv bits)`.
    pub pushes: Vec<(usize, Vec<String>)>,
}

impl WindowBits {
    pub fn of(w: &WindowInput) -> Self {
        WindowBits {
            start: StateBits::of(&w.start),
            steps: w.steps,
            targets: w
                .targets
                .iter()
                .map(|(o, t)| TargetBits {
                    offset: *o,
                    q_des: to_bits(&t.q_des),
                    dq_des: to_bits(&t.dq_des),
                    kp: to_bits(&t.kp),
                    kd: to_bits(&t.kd),
                    tau_ff: to_bits(&t.tau_ff),
                })
                .collect(),
            pushes: w.pushes.iter().map(|(o, dv)| (*o, to_bits(dv))).collect(),
        }
    }
    pub fn input(&self, nj: usize) -> Result<WindowInput, DiffError> {
        let mut targets = Vec::new();
        for t in &self.targets {
            let p = PdTarget {
                q_des: from_bits(&t.q_des)?,
                dq_des: from_bits(&t.dq_des)?,
                kp: from_bits(&t.kp)?,
                kd: from_bits(&t.kd)?,
                tau_ff: from_bits(&t.tau_ff)?,
            };
            if [&p.q_des, &p.dq_des, &p.kp, &p.kd, &p.tau_ff].iter().any(|v| v.len() != nj) {
                return Err(DiffError::Input(format!("target at offset {} does not have {nj} joints", t.offset)));
            }
            targets.push((t.offset, p));
        }
        let mut pushes = Vec::new();
        for (o, dv) in &self.pushes {
            let v = from_bits(dv)?;
            let [x, y, z] = v[..] else { return Err(DiffError::Input("push dv needs 3 entries".into())) };
            pushes.push((*o, [x, y, z]));
        }
        if self.steps == 0 || self.steps > 100_000 {
            return Err(DiffError::Input("window steps must be in 1..=100000".into()));
        }
        Ok(WindowInput { start: self.start.state()?, steps: self.steps, targets, pushes })
    }
}

/// What the replay must reproduce exactly.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Expected {
    /// Final state of every engine, in `engines` order.
    pub states: Vec<StateBits>,
    /// The finding's value (bits) and, for reading, its decimal form.
    pub value_bits: String,
    pub value: f64,
}

/// A reproducer file.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Reproducer {
    pub schema_version: u32,
    pub robot: String,
    pub model_hash: String,
    /// Lead first.
    pub engines: Vec<EngineInfo>,
    pub common: CommonSettings,
    pub controller: String,
    pub seed: u64,
    /// The (minimized) scenario the window comes from; its ground friction applies to the replay.
    pub scenario: Scenario,
    pub perturbation_scale: f64,
    pub finding: Finding,
    pub window: WindowBits,
    /// Steps of the window replayed (the minimized length).
    pub steps: usize,
    pub expected: Expected,
}

/// Result of a replay.
#[derive(Debug, Clone)]
pub struct ReplayOutcome {
    pub identical: bool,
    pub mismatches: Vec<String>,
    pub value: f64,
}

fn factories_for(names: &[EngineInfo]) -> Result<Vec<Arc<dyn EngineFactory>>, DiffError> {
    names
        .iter()
        .map(|e| {
            EngineKind::parse(&e.name)
                .map(|k| Arc::new(BuiltinEngine(k)) as Arc<dyn EngineFactory>)
                .ok_or_else(|| DiffError::Input(format!("reproducer engine {:?} is not built in", e.name)))
        })
        .collect()
}

fn run(
    model: &RobotModel,
    factories: &[Arc<dyn EngineFactory>],
    common: &CommonSettings,
    scenario: &Scenario,
    w: &WindowInput,
    steps: usize,
    f: &Finding,
) -> Result<(Vec<State>, f64), DiffError> {
    let m = harness::scenario_model(model, scenario);
    let mut engines = harness::build_engines(factories, &m, common)?;
    let r = harness::replay_window(&mut engines, &m, w, steps, common.timestep, false)?;
    let ei = factories.iter().position(|x| x.name() == f.engine).unwrap_or(0);
    let v = finding_value(&f.kind, &f.quantity, ei, &r);
    Ok((r.after_k.into_iter().map(|x| x.0).collect(), v))
}

impl Reproducer {
    /// Builds a reproducer from a minimized finding, recording what the replay must give.
    pub fn new(
        model: &RobotModel,
        factories: &[Arc<dyn EngineFactory>],
        common: &CommonSettings,
        controller: &str,
        m: &Minimized,
    ) -> Result<Self, DiffError> {
        let sm = harness::scenario_model(model, &m.scenario);
        let engines = harness::build_engines(factories, &sm, common)?;
        let infos = engines
            .iter()
            .map(|e| EngineInfo { name: e.name().to_string(), version: e.version(), settings: e.settings() })
            .collect();
        drop(engines);
        let (states, value) = run(model, factories, common, &m.scenario, &m.window, m.steps, &m.finding)?;
        Ok(Reproducer {
            schema_version: SCHEMA_VERSION,
            robot: model.name.clone(),
            model_hash: crate::model_hash(model),
            engines: infos,
            common: common.clone(),
            controller: controller.to_string(),
            seed: m.scenario.seed,
            scenario: m.scenario.clone(),
            perturbation_scale: m.scale,
            finding: m.finding.clone(),
            window: WindowBits::of(&m.window),
            steps: m.steps,
            expected: Expected {
                states: states.iter().map(StateBits::of).collect(),
                value_bits: format!("{:016x}", value.to_bits()),
                value,
            },
        })
    }

    /// Replays on `model` and compares bit for bit (model hash, engine versions, every final state entry,
    /// the finding's value).
    pub fn replay(&self, model: &RobotModel) -> Result<ReplayOutcome, DiffError> {
        if self.schema_version != SCHEMA_VERSION {
            return Err(DiffError::Input(format!(
                "reproducer schema {} (this build reads {SCHEMA_VERSION})",
                self.schema_version
            )));
        }
        self.scenario.validate()?;
        let mut mismatches = Vec::new();
        let hash = crate::model_hash(model);
        if hash != self.model_hash {
            mismatches.push(format!("model hash {hash} differs from the recorded {}", self.model_hash));
        }
        let factories = factories_for(&self.engines)?;
        let w = self.window.input(model.nj())?;
        let (states, value) = run(model, &factories, &self.common, &self.scenario, &w, self.steps, &self.finding)?;
        let sm = harness::scenario_model(model, &self.scenario);
        for (f, info) in factories.iter().zip(&self.engines) {
            let v = f.build(&sm, &self.common)?.version();
            if v != info.version {
                mismatches.push(format!("{}: version {v} differs from the recorded {}", info.name, info.version));
            }
        }
        for (i, (s, exp)) in states.iter().zip(&self.expected.states).enumerate() {
            let got = StateBits::of(s);
            let n =
                got.qpos.iter().zip(&exp.qpos).chain(got.qvel.iter().zip(&exp.qvel)).filter(|(a, b)| a != b).count();
            if n > 0 || got.qpos.len() != exp.qpos.len() || got.qvel.len() != exp.qvel.len() {
                mismatches.push(format!(
                    "{}: {n} state entries differ",
                    self.engines.get(i).map(|e| e.name.as_str()).unwrap_or("?")
                ));
            }
        }
        if states.len() != self.expected.states.len() {
            mismatches.push("engine count differs".into());
        }
        let vb = format!("{:016x}", value.to_bits());
        if vb != self.expected.value_bits {
            mismatches.push(format!(
                "finding value {value:e} (bits {vb}) differs from the recorded {:e}",
                self.expected.value
            ));
        }
        Ok(ReplayOutcome { identical: mismatches.is_empty(), mismatches, value })
    }
}
