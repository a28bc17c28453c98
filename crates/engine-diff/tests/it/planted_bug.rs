//! A real bug planted in one engine must come out of triage as a candidate engine bug, never as an allow-listed
//! modelling difference (issue 16, item 2).
//!
//! The planted engine is MuJoCo with one defect switched on, under the NAME of a Rapier engine, so that every
//! allow-list entry written for that engine applies to it; the lead is the unmodified MuJoCo. Without the defect
//! the two are the same engine and diverge by exactly zero (`tests/it/harness.rs` shows that), so every finding the
//! planted run adds is caused by the defect. Counterpart: the unmodified engine (the same code minus the defect).
use diff_physics::{CommonSettings, Engine, EngineError, EngineKind, State};
use engine_diff::harness::{self, excitation_factory, BuiltinEngine, EngineFactory, Finding, HarnessConfig};
use engine_diff::scenario::Scenario;
use engine_diff::triage::{classify, AllowList, Class, WithdrawnCovers};
use robot_model::RobotModel;
use std::collections::BTreeSet;
use std::sync::Arc;

/// The defects a test can switch on.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Defect {
    None,
    /// Joint damping with the wrong sign: the engine applies +d·q̇ instead of −d·q̇ (a sign slip in one term).
    DampingSign,
    /// Gravity pointing up (a sign slip in the gravity vector handed to the engine).
    GravitySign,
}

#[derive(Debug)]
struct Planted {
    inner: Box<dyn Engine>,
    defect: Defect,
    damping: Vec<f64>,
}

impl Engine for Planted {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn version(&self) -> String {
        format!("{} with planted defect {:?}", self.inner.version(), self.defect)
    }
    fn settings(&self) -> serde_json::Value {
        self.inner.settings()
    }
    fn step(&mut self, tau: &[f64]) -> Result<(), EngineError> {
        if self.defect == Defect::DampingSign {
            // The engine applies −d·q̇; adding 2·d·q̇ turns it into +d·q̇.
            let dq = self.inner.state().dq;
            let t: Vec<f64> = tau.iter().zip(&dq).zip(&self.damping).map(|((t, v), d)| t + 2.0 * d * v).collect();
            return self.inner.step(&t);
        }
        self.inner.step(tau)
    }
    fn state(&self) -> State {
        self.inner.state()
    }
    delegate_engine!(inner);
}

/// MuJoCo with `defect`, reporting itself as `name` (a Rapier engine covered by allow-list entries).
#[derive(Debug)]
struct PlantedFactory {
    name: String,
    defect: Defect,
}

impl EngineFactory for PlantedFactory {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn build(&self, model: &RobotModel, common: &CommonSettings) -> Result<Box<dyn Engine>, EngineError> {
        let mut c = common.clone();
        if self.defect == Defect::GravitySign {
            c.gravity = c.gravity.map(|g| -g);
        }
        let damping = model.joints.iter().map(|j| if common.joint_damping { j.damping } else { 0.0 }).collect();
        Ok(Box::new(Planted {
            inner: diff_physics::make_engine(EngineKind::Mujoco, model, &c)?,
            defect: self.defect,
            damping,
        }))
    }
}

struct Triaged {
    caused: Vec<(Finding, Class)>,
}

/// Runs the excitation input (with its push) against the lead MuJoCo, and triages every finding of the planted
/// engine that the defect-free run of the same wrapper does not have. `lead`: the name the (unmodified) lead
/// reports; another engine than MuJoCo makes the pair one the allow-list covers only through the reference.
fn run(lead: &str, name: &str, defect: Defect) -> Triaged {
    let m = RobotModel::h1_2().expect("built-in model");
    let allow = AllowList::builtin().expect("allow-list");
    let ctrl = excitation_factory(&m);
    let cfg = HarnessConfig { free_runs: false, ..HarnessConfig::default() };
    let s = Scenario { excitation: 0.5, ..Scenario::excitation(5, 1.0) };
    let episode = |d: Defect| {
        let lead: Arc<dyn EngineFactory> = match lead {
            "mujoco" => Arc::new(BuiltinEngine(EngineKind::Mujoco)),
            other => Arc::new(PlantedFactory { name: other.to_string(), defect: Defect::None }),
        };
        let f: Vec<Arc<dyn EngineFactory>> = vec![lead, Arc::new(PlantedFactory { name: name.to_string(), defect: d })];
        (harness::run_episode(&m, &f, ctrl.as_ref(), &s, &cfg).expect("episode"), f)
    };
    let (clean, _) = episode(Defect::None);
    let clean_keys: BTreeSet<_> = clean.findings.iter().filter(|f| f.engine == name).map(|f| f.group_key()).collect();
    let (r, f) = episode(defect);
    // As the report triages: an entry the run exceeds anywhere in its scope covers none of it.
    let withdrawn = WithdrawnCovers::of(&allow, &r.findings);
    let caused = r
        .findings
        .iter()
        .filter(|x| x.engine == name && !clean_keys.contains(&x.group_key()))
        .map(|x| {
            let start = &r.windows[x.window].input.start;
            let class = withdrawn.apply(x, classify(&m, &f, &cfg.common, &allow, x, start).expect("triage"));
            (x.clone(), class)
        })
        .collect();
    Triaged { caused }
}

fn summary(t: &Triaged) -> String {
    t.caused
        .iter()
        .map(|(f, c)| {
            format!("{} {} {} ratio {:.2} at {:.2} s: {}", f.kind, f.quantity, f.phase, f.ratio(), f.t0, c.label())
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The report triages each finding group (kind, engine, quantity, phase) by its worst finding: every group the
/// defect causes must come out as a candidate bug. Single findings of a group may still sit under an entry's cap
/// (they are printed): the group, not each finding, is what a report entry shows. Returns what failed.
fn groups_not_flagged(lead: &str, name: &str, defect: Defect) -> Vec<String> {
    let t = run(lead, name, defect);
    let text = summary(&t);
    eprintln!("{name} with {defect:?} against {lead}:\n{text}");
    if t.caused.is_empty() {
        return vec![format!("{defect:?} under the name {name} against {lead} produced no finding at all")];
    }
    let mut worst: std::collections::BTreeMap<_, &(Finding, Class)> = std::collections::BTreeMap::new();
    for x in &t.caused {
        let e = worst.entry(x.0.group_key()).or_insert(x);
        if x.0.ratio() > e.0.ratio() {
            *e = x;
        }
    }
    let hidden = t.caused.iter().filter(|(_, c)| matches!(c, Class::ExpectedDifference { .. })).count();
    eprintln!("{} of {} caused findings individually under an entry's cap", hidden, t.caused.len());
    worst
        .iter()
        .filter(|(_, (_, c))| *c != Class::CandidateEngineBug)
        .map(|(key, (f, c))| {
            format!(
                "{defect:?} under the name {name} against {lead}: group {key:?} (worst ratio {:.2}) triaged as {}",
                f.ratio(),
                c.label()
            )
        })
        .collect()
}

fn assert_flagged_as_candidate(pairs: &[(&str, &str)], defect: Defect) {
    let failed: Vec<String> = pairs.iter().flat_map(|(lead, name)| groups_not_flagged(lead, name, defect)).collect();
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

/// Every engine name some allow-list entry covers, read from the allow-list itself, so that a new entry is tested
/// the day it is written (Newton's Steel entry, cap 2.7, is the loosest one-step allowance for joint velocity in
/// contact). MuJoCo is the lead, so it is not planted under its own name. Names are strings here: the planted
/// engine is MuJoCo whatever it is called, and no PhysX or Newton build is needed.
fn allow_listed_names() -> Vec<String> {
    let allow = AllowList::builtin().expect("allow-list");
    let names: BTreeSet<String> = allow.entries.iter().flat_map(|e| e.engines.iter().cloned()).collect();
    names.into_iter().filter(|n| n != "mujoco").collect()
}

#[test]
fn a_damping_sign_slip_is_a_candidate_bug_under_every_allow_listed_name() {
    let names = allow_listed_names();
    let pairs: Vec<(&str, &str)> = names.iter().map(|n| ("mujoco", n.as_str())).collect();
    assert_flagged_as_candidate(&pairs, Defect::DampingSign);
}

#[test]
fn a_gravity_sign_slip_is_a_candidate_bug_under_every_allow_listed_name() {
    let names = allow_listed_names();
    let pairs: Vec<(&str, &str)> = names.iter().map(|n| ("mujoco", n.as_str())).collect();
    assert_flagged_as_candidate(&pairs, Defect::GravitySign);
}

/// A pair without the reference is covered by the sum of both engines' allowances against MuJoCo
/// (`AllowList::covering`), the loosest cover there is (Bullet's or DART's rigid contact, cap 15, plus Rapier's
/// soft contact, cap 20). The planted defects must still come out as candidate bugs in such a pair. What this
/// shows, measured: every finding these two defects cause is a per-engine invariant (energy created, free-fall
/// acceleration), which no pair changes; neither defect moves a one-step cross-engine quantity past its bound, so
/// this test does not exercise the summed cap itself (its soundness is the triangle inequality, see `Cover`).
#[test]
fn a_planted_defect_is_a_candidate_bug_between_two_allow_listed_engines() {
    let pairs = [("bullet", "rapier_multibody"), ("dart", "rapier_impulse")];
    assert_flagged_as_candidate(&pairs, Defect::DampingSign);
    assert_flagged_as_candidate(&pairs, Defect::GravitySign);
}
