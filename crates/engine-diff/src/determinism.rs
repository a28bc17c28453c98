//! Bit-for-bit reproducibility, measured (issue 62): one fixed episode run closed-loop in each engine, every
//! physics step's state hashed. The same engine library on the same machine class must give the same hash in any
//! process, on any thread count and in any shard of a campaign; committed tables (`corpus/determinism/`, one per
//! machine class, [`read_tables`], [`table_for`]) hold the hashes, and [`compare`] says, engine by engine, whether
//! this run reproduced them.
//!
//! The episode goes through the campaigns' own path ([`harness::free_run_recorded`], the state sampled after
//! every step), so a hash that repeats is a statement about what `ulab diff`, `ulab validate` and the fuzzer
//! compute, not about a separate loop written for the check.
//!
//! Why a machine class: the engines' native code and the C library's `sin`/`exp` choose instruction paths by CPU
//! feature (fused multiply-add, AVX2, AVX-512), which may change the last bit of a result. Hashes are compared
//! only within the class they were measured on; on another class the comparison is reported as not made, never as
//! a pass.
use crate::harness::{self, ControllerFactory, EngineFactory, Trajectory};
use crate::scenario::Scenario;
use crate::DiffError;
use diff_physics::{CommonSettings, LinkPose, State};
use rayon::prelude::*;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::Path;
use std::sync::Arc;

/// Version of the table format ([`HashTable`]).
pub const TABLE_FORMAT: u32 = 1;

/// The fixed episode every engine runs: the built-in excitation input (no policy file needed) from the standing
/// pose with the scenario's own noise, push and command change, at the default timestep.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Probe {
    pub seed: u64,
    /// Episode length (s).
    pub seconds: f64,
}

impl Default for Probe {
    /// 2 s (1000 steps at 2 ms): long enough for the push, the command change and foot contacts to act.
    fn default() -> Self {
        Probe { seed: 1, seconds: 2.0 }
    }
}

/// One engine's hash of the probe episode.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EngineHash {
    pub engine: String,
    /// Engine library and version ([`diff_physics::Engine::version`]).
    pub version: String,
    /// Physics steps run (fewer than the episode's when the robot fell or the engine failed).
    pub steps: u64,
    /// SHA-256 (hex) of every sampled state and link pose, as the bit patterns of their `f64`s.
    pub sha256: String,
}

/// What a table's hashes were measured on.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct MachineClass {
    pub arch: String,
    /// The CPU features that select different floating-point code paths, present on the machine (sorted).
    pub features: Vec<String>,
}

impl MachineClass {
    /// This machine's class.
    pub fn current() -> Self {
        #[cfg(target_arch = "x86_64")]
        let features = [
            ("avx", std::arch::is_x86_feature_detected!("avx")),
            ("avx2", std::arch::is_x86_feature_detected!("avx2")),
            ("avx512f", std::arch::is_x86_feature_detected!("avx512f")),
            ("fma", std::arch::is_x86_feature_detected!("fma")),
        ]
        .iter()
        .filter(|(_, on)| *on)
        .map(|(n, _)| n.to_string())
        .collect();
        #[cfg(not(target_arch = "x86_64"))]
        let features = Vec::new();
        MachineClass { arch: std::env::consts::ARCH.to_string(), features }
    }
}

impl std::fmt::Display for MachineClass {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.arch)?;
        for x in &self.features {
            write!(f, "+{x}")?;
        }
        Ok(())
    }
}

/// The committed table: the probe, the machine class and one hash per engine.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HashTable {
    pub format: u32,
    pub robot: String,
    pub probe: Probe,
    pub machine: MachineClass,
    pub engines: Vec<EngineHash>,
}

fn hash_f64s(h: &mut Sha256, xs: impl IntoIterator<Item = f64>) {
    for x in xs {
        h.update(x.to_bits().to_le_bytes());
    }
}

fn hash_sample(h: &mut Sha256, st: &State, links: &[LinkPose]) {
    hash_f64s(h, st.base_pos.iter().chain(&st.base_quat).chain(&st.q).copied());
    hash_f64s(h, st.base_lin_vel.iter().chain(&st.base_ang_vel).chain(&st.dq).copied());
    for l in links {
        hash_f64s(h, l.pos.iter().chain(&l.quat).copied());
    }
}

/// Runs the probe episode in one engine and hashes every step's state.
pub fn engine_hash(
    factory: &dyn EngineFactory,
    model: &RobotModel,
    ctrl: &ControllerFactory,
    probe: Probe,
) -> Result<EngineHash, DiffError> {
    if !(probe.seconds.is_finite() && probe.seconds > 0.0 && probe.seconds <= 600.0) {
        return Err(DiffError::Input(format!("probe length {} s must be in (0, 600]", probe.seconds)));
    }
    let scenario = Scenario::excitation(probe.seed, probe.seconds);
    let common = CommonSettings::default();
    let m = harness::scenario_model(model, &scenario);
    let mut engine = factory.build(&m, &common)?;
    let dt = common.timestep;
    let total_steps = (probe.seconds / dt).round() as usize;
    let name = factory.name();
    let mut traj = Trajectory::new(&name, 1.0 / dt);
    let (_, steps) =
        harness::free_run_recorded(engine.as_mut(), &name, &m, ctrl, &scenario, dt, total_steps, Some(&mut traj))?;
    let mut h = Sha256::new();
    for (st, links) in &traj.samples {
        hash_sample(&mut h, st, links);
    }
    let sha256 = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    Ok(EngineHash { engine: name, version: engine.version(), steps, sha256 })
}

/// Every engine's hash, computed on `threads` worker threads (engines in parallel), in the factories' order.
pub fn hash_table(
    factories: &[Arc<dyn EngineFactory>],
    robot: &str,
    model: &RobotModel,
    ctrl: &ControllerFactory,
    probe: Probe,
    threads: usize,
) -> Result<HashTable, DiffError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .map_err(|e| DiffError::Input(format!("thread pool of {threads}: {e}")))?;
    let engines = pool.install(|| {
        factories.par_iter().map(|f| engine_hash(f.as_ref(), model, ctrl, probe)).collect::<Result<Vec<_>, _>>()
    })?;
    Ok(HashTable { format: TABLE_FORMAT, robot: robot.to_string(), probe, machine: MachineClass::current(), engines })
}

/// How one engine's hash compares with the committed table.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum Comparison {
    /// Same engine version and machine class, same hash.
    Reproduced,
    /// Same engine version and machine class, a different hash: the engine (or our harness) is not
    /// bit-reproducible, or its numerics changed without the table being updated.
    Differs { expected: String, got: String },
    /// Not compared: the table has no entry for this engine, or one of another library version or machine
    /// class (why says which).
    NotCompared { why: String },
}

/// Reads every table (`*.json`) in `dir`: one per robot and machine class (two tables of the same robot and
/// class are an error, as the check could not say which one holds).
pub fn read_tables(dir: &Path) -> Result<Vec<HashTable>, DiffError> {
    let io = |e: std::io::Error| DiffError::Io { path: dir.display().to_string(), source: e };
    let mut paths = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        if path.extension().is_some_and(|x| x == "json") {
            paths.push(path);
        }
    }
    paths.sort();
    let mut tables: Vec<HashTable> = Vec::new();
    for path in paths {
        let text = std::fs::read_to_string(&path)
            .map_err(|e| DiffError::Io { path: path.display().to_string(), source: e })?;
        let t: HashTable = serde_json::from_str(&text)
            .map_err(|e| DiffError::Input(format!("{}: not a hash table: {e}", path.display())))?;
        if tables.iter().any(|o| o.robot == t.robot && o.machine == t.machine) {
            return Err(DiffError::Input(format!(
                "{}: a second table for {} on {}",
                path.display(),
                t.robot,
                t.machine
            )));
        }
        tables.push(t);
    }
    Ok(tables)
}

/// The table of `robot` measured on machine class `machine`, if `tables` has one.
pub fn table_for<'a>(tables: &'a [HashTable], robot: &str, machine: &MachineClass) -> Option<&'a HashTable> {
    tables.iter().find(|t| t.robot == robot && &t.machine == machine)
}

/// Compares a run with the committed table, engine by engine (the run's order, then the table's entries the run
/// did not hash: their engine is not compiled into this build or was not selected). The probes must be equal.
pub fn compare(table: &HashTable, run: &HashTable) -> Result<Vec<(String, Comparison)>, DiffError> {
    if table.probe != run.probe || table.robot != run.robot || table.format != run.format {
        return Err(DiffError::Input(format!(
            "the table measures {} with seed {} over {} s (format {}); this run {} with seed {} over {} s (format {})",
            table.robot,
            table.probe.seed,
            table.probe.seconds,
            table.format,
            run.robot,
            run.probe.seed,
            run.probe.seconds,
            run.format
        )));
    }
    Ok(run
        .engines
        .iter()
        .map(|e| {
            let c = match table.engines.iter().find(|t| t.engine == e.engine) {
                None => Comparison::NotCompared { why: "no entry in the table".into() },
                Some(_) if table.machine != run.machine => Comparison::NotCompared {
                    why: format!("table measured on {}, this machine is {}", table.machine, run.machine),
                },
                Some(t) if t.version != e.version => Comparison::NotCompared {
                    why: format!("table measured {}, this build has {}", t.version, e.version),
                },
                Some(t) if t.sha256 == e.sha256 && t.steps == e.steps => Comparison::Reproduced,
                Some(t) => Comparison::Differs {
                    expected: format!("{} ({} steps)", t.sha256, t.steps),
                    got: format!("{} ({} steps)", e.sha256, e.steps),
                },
            };
            (e.engine.clone(), c)
        })
        .chain(table.engines.iter().filter(|t| !run.engines.iter().any(|e| e.engine == t.engine)).map(|t| {
            let why = "not hashed in this run (engine not in this build, or not selected)".to_string();
            (t.engine.clone(), Comparison::NotCompared { why })
        }))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(machine: MachineClass, hash: &str) -> HashTable {
        HashTable {
            format: TABLE_FORMAT,
            robot: "h1_2".into(),
            probe: Probe::default(),
            machine,
            engines: vec![EngineHash {
                engine: "mujoco".into(),
                version: "v".into(),
                steps: 1000,
                sha256: hash.into(),
            }],
        }
    }

    #[test]
    fn a_different_hash_differs_and_another_machine_class_is_not_compared() {
        let here = MachineClass { arch: "x86_64".into(), features: vec!["fma".into()] };
        let there = MachineClass { arch: "x86_64".into(), features: vec![] };
        let c = compare(&table(here.clone(), "aa"), &table(here.clone(), "aa")).unwrap();
        assert_eq!(c[0].1, Comparison::Reproduced);
        let c = compare(&table(here.clone(), "aa"), &table(here.clone(), "bb")).unwrap();
        assert!(matches!(c[0].1, Comparison::Differs { .. }));
        let c = compare(&table(there, "aa"), &table(here, "bb")).unwrap();
        assert!(matches!(c[0].1, Comparison::NotCompared { .. }));
    }

    #[test]
    fn an_entry_the_run_did_not_hash_is_not_compared_and_the_table_is_chosen_by_class() {
        let here = MachineClass { arch: "x86_64".into(), features: vec!["fma".into()] };
        let there = MachineClass { arch: "x86_64".into(), features: vec![] };
        let mut t = table(here.clone(), "aa");
        t.engines.push(EngineHash { engine: "physx".into(), version: "p".into(), steps: 1000, sha256: "cc".into() });
        let c = compare(&t, &table(here.clone(), "aa")).unwrap();
        assert_eq!(c.len(), 2);
        assert_eq!(c[0].1, Comparison::Reproduced);
        assert_eq!(c[1].0, "physx");
        assert!(matches!(c[1].1, Comparison::NotCompared { .. }));
        let tables = [table(there.clone(), "bb"), t];
        assert_eq!(table_for(&tables, "h1_2", &here).map(|t| t.engines.len()), Some(2));
        assert_eq!(table_for(&tables, "h1_2", &there).map(|t| t.engines[0].sha256.as_str()), Some("bb"));
        assert!(table_for(&tables, "g1", &here).is_none());
    }

    #[test]
    fn a_table_of_another_probe_is_an_error() {
        let m = MachineClass::current();
        let mut other = table(m.clone(), "aa");
        other.probe.seed = 2;
        assert!(compare(&table(m, "aa"), &other).is_err());
    }
}
