//! Triage of findings: (a) translation problem (the model-equivalence check fails in that state), (b)
//! expected modelling difference (an allow-list entry with rationale and citation), (c) candidate engine
//! bug; and minimization (smallest perturbation, fewest bodies in contact, shortest window).
use crate::harness::{
    self, Bounds, ControllerFactory, Div, EngineFactory, Finding, HarnessConfig, WindowInput, WindowRecord,
};
use crate::phase::PhaseSelector;
use crate::scenario::Scenario;
use crate::DiffError;
use diff_physics::{CommonSettings, State};
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// One allow-list entry: which findings it covers, why, and where that is documented.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct AllowEntry {
    pub id: String,
    /// Engines (compared with the lead) the entry covers.
    pub engines: Vec<String>,
    /// Leads the entry covers for the cross-engine kinds (`one_step_bound`, `k_step_bound`); invariants are one
    /// engine's own and ignore it. Default: MuJoCo, the lead of `ulab diff` and of every fuzz pair it is in.
    #[serde(default = "default_leads")]
    pub leads: Vec<String>,
    /// Finding kinds: `one_step_bound`, `k_step_bound`, `invariant`.
    pub kinds: Vec<String>,
    /// Quantities (empty: any).
    #[serde(default)]
    pub quantities: Vec<String>,
    /// Contact phases (empty: any; `contact` = any phase with a ground contact). A misspelt phase fails reading.
    #[serde(default)]
    pub phases: Vec<PhaseSelector>,
    /// The entry covers a finding only up to this multiple of its bound; beyond, it is a candidate bug.
    pub max_ratio: f64,
    pub rationale: String,
    /// Public documentation or issue threads (URLs).
    pub citation: Vec<String>,
}

impl AllowEntry {
    /// The entry speaks of this finding (engine, lead, kind, quantity, phase), whatever its ratio.
    fn in_scope(&self, f: &Finding) -> bool {
        let phase_ok = self.phases.is_empty() || self.phases.iter().any(|p| p.covers(f.phase));
        let lead_ok = f.kind == "invariant" || self.leads.iter().any(|l| l == &f.lead);
        self.engines.iter().any(|x| x == &f.engine)
            && lead_ok
            && self.kinds.iter().any(|k| k == &f.kind)
            && (self.quantities.is_empty() || self.quantities.iter().any(|q| q == &f.quantity))
            && phase_ok
    }
}

fn default_leads() -> Vec<String> {
    vec!["mujoco".into()]
}

#[derive(Debug, Deserialize)]
struct AllowFile {
    entry: Vec<AllowEntry>,
}

/// The allow-list (one data file: `crates/engine-diff/allowlist.toml`).
#[derive(Debug, Clone, Serialize)]
pub struct AllowList {
    pub entries: Vec<AllowEntry>,
}

impl AllowList {
    /// The project's allow-list, compiled in.
    pub fn builtin() -> Result<Self, DiffError> {
        Self::parse(include_str!("../allowlist.toml"))
    }

    /// Parses and checks an allow-list: every entry needs an id, engines, kinds, a positive ratio cap, a
    /// rationale and at least one https citation.
    pub fn parse(text: &str) -> Result<Self, DiffError> {
        let f: AllowFile = toml::from_str(text).map_err(DiffError::AllowListSyntax)?;
        let mut ids = std::collections::BTreeSet::new();
        for e in &f.entry {
            let bad = |why: &str| Err(DiffError::AllowList(format!("entry {:?}: {why}", e.id)));
            if e.id.trim().is_empty() || !ids.insert(e.id.clone()) {
                return bad("missing or duplicate id");
            }
            if e.engines.is_empty() || e.kinds.is_empty() || e.leads.is_empty() {
                return bad("engines, leads and kinds must not be empty");
            }
            if let Some(k) =
                e.kinds.iter().find(|k| !["one_step_bound", "k_step_bound", "invariant"].contains(&k.as_str()))
            {
                return bad(&format!("unknown kind {k:?}"));
            }
            if !(e.max_ratio.is_finite() && e.max_ratio > 0.0) {
                return bad("max_ratio must be positive and finite");
            }
            if e.rationale.trim().len() < 40 {
                return bad("rationale too short");
            }
            if e.citation.is_empty() || e.citation.iter().any(|c| !c.starts_with("https://")) {
                return bad("needs at least one https citation");
            }
        }
        Ok(AllowList { entries: f.entry })
    }

    /// The entry written for a finding's pair of engines that covers it, if any (see [`AllowList::covering`]
    /// for pairs without the reference).
    pub fn matching(&self, f: &Finding) -> Option<&AllowEntry> {
        self.entries.iter().find(|e| e.in_scope(f) && f.ratio() <= e.max_ratio)
    }
}

/// The engine every allow-list entry is measured against unless it names other leads: MuJoCo, the lead of
/// `ulab diff`.
pub const REFERENCE_LEAD: &str = "mujoco";

/// Why a finding is not a candidate bug.
#[derive(Debug, Clone, Copy)]
pub enum Cover<'a> {
    /// An entry written for this pair of engines covers it.
    Entry(&'a AllowEntry),
    /// A cross-engine finding between two engines neither of which is the reference: covered by the triangle
    /// inequality when its ratio is at most what each engine may stand from the reference on this kind, quantity
    /// and phase, added (an engine no entry covers may stand up to its bound, ratio 1). Bounds are the same for
    /// every pair (they depend on the timestep and window only) and divergences are max-norms, so a difference
    /// beyond the sum means one of the two engines is beyond its own cap against the reference in that state.
    ViaReference {
        /// Entries of the lead and of the engine against the reference (`None`: within its bound there).
        lead: Option<&'a AllowEntry>,
        engine: Option<&'a AllowEntry>,
        /// The summed cap the finding's ratio is within.
        cap: f64,
    },
}

impl Cover<'_> {
    /// The entry id, or `via-reference:<lead entry>+<engine entry>` (`-` where an engine has none).
    pub fn id(&self) -> String {
        match self {
            Cover::Entry(e) => e.id.clone(),
            Cover::ViaReference { lead, engine, .. } => {
                let id = |e: &Option<&AllowEntry>| e.map_or_else(|| "-".to_string(), |e| e.id.clone());
                format!("via-reference:{}+{}", id(lead), id(engine))
            }
        }
    }

    /// The triage class this cover gives.
    pub fn class(&self) -> Class {
        match self {
            Cover::Entry(e) => Class::ExpectedDifference {
                id: e.id.clone(),
                rationale: e.rationale.clone(),
                citation: e.citation.clone(),
            },
            Cover::ViaReference { lead, engine, cap } => {
                let entries: Vec<&AllowEntry> = lead.iter().chain(engine.iter()).copied().collect();
                let rationale = format!(
                    "both engines differ from the reference ({REFERENCE_LEAD}) by documented modelling differences \
                     ({}); their sum caps this pair at {cap:.1} times the bound. {}",
                    entries.iter().map(|e| e.id.as_str()).collect::<Vec<_>>().join(", "),
                    entries.iter().map(|e| e.rationale.as_str()).collect::<Vec<_>>().join(" ")
                );
                let citation = entries.iter().flat_map(|e| e.citation.iter().cloned()).collect();
                Class::ExpectedDifference { id: self.id(), rationale, citation }
            }
        }
    }
}

impl AllowList {
    /// What covers a finding: an entry written for its pair ([`AllowList::matching`]) or, for a cross-engine
    /// finding between two engines other than the reference, the entries of both against the reference
    /// ([`Cover::ViaReference`]). `None`: a candidate engine bug.
    pub fn covering(&self, f: &Finding) -> Option<Cover<'_>> {
        if let Some(e) = self.matching(f) {
            return Some(Cover::Entry(e));
        }
        if f.kind == "invariant" || f.lead == REFERENCE_LEAD || f.engine == REFERENCE_LEAD {
            return None;
        }
        let against_reference = |engine: &str| {
            let probe = Finding { engine: engine.to_string(), lead: REFERENCE_LEAD.to_string(), ..f.clone() };
            self.entries.iter().filter(|e| e.in_scope(&probe)).max_by(|a, b| a.max_ratio.total_cmp(&b.max_ratio))
        };
        let (lead, engine) = (against_reference(&f.lead), against_reference(&f.engine));
        if lead.is_none() && engine.is_none() {
            return None;
        }
        let cap = lead.map_or(1.0, |e| e.max_ratio) + engine.map_or(1.0, |e| e.max_ratio);
        (f.ratio() <= cap).then_some(Cover::ViaReference { lead, engine, cap })
    }
}

/// Triage class.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(tag = "class", rename_all = "snake_case")]
pub enum Class {
    /// (a) The engines do not hold the same robot in this state.
    TranslationProblem { detail: String },
    /// (b) A documented modelling difference.
    ExpectedDifference { id: String, rationale: String, citation: Vec<String> },
    /// (c) Neither: looks like an engine bug.
    CandidateEngineBug,
}

impl Class {
    pub fn label(&self) -> &'static str {
        match self {
            Class::TranslationProblem { .. } => "(a) translation problem",
            Class::ExpectedDifference { .. } => "(b) expected modelling difference",
            Class::CandidateEngineBug => "(c) candidate engine bug",
        }
    }
}

/// Model equivalence at a state, for the named engines: per-link masses, link-frame FK positions and the
/// COM against `robot-model`'s reference (the checks of `diff_physics::oracle::model_equivalence`, here at
/// the finding's state rather than random ones). Tolerances as there: 1e-9 kg, 1e-9 m, or the engine's
/// precision-derived ones ([`diff_physics::oracle::precision_tolerance`]). `None`: all equal.
pub fn model_equivalence_at(
    model: &RobotModel,
    factories: &[&Arc<dyn EngineFactory>],
    state: &State,
    common: &CommonSettings,
) -> Result<Option<String>, DiffError> {
    let coords = state.coords();
    let fk = model.fk(&coords)?;
    let com = model.com(&coords)?;
    let mut problems = Vec::new();
    for f in factories {
        let mut e = f.build(model, &CommonSettings { ground: false, ..common.clone() })?;
        e.reset(&State::at_rest(coords.clone()))?;
        let masses = e.link_masses();
        let dm = masses.iter().zip(&model.links).map(|(m, l)| (m - l.inertial.mass).abs()).fold(0.0, f64::max);
        let poses = e.link_poses();
        let dp = poses
            .iter()
            .zip(&fk.link_poses)
            .map(|(p, r)| {
                let t = r.translation.vector;
                ((p.pos[0] - t.x).powi(2) + (p.pos[1] - t.y).powi(2) + (p.pos[2] - t.z).powi(2)).sqrt()
            })
            .fold(0.0, f64::max);
        let c = e.com();
        let dc = ((c[0] - com.x).powi(2) + (c[1] - com.y).powi(2) + (c[2] - com.z).powi(2)).sqrt();
        let counts_ok = masses.len() == model.links.len() && poses.len() == fk.link_poses.len();
        // The oracle's tolerances, widened by its own derivation for engines computing in lower precision (PhysX:
        // f32, where 1e-9 kg would call every rounded mass a translation problem).
        let name = f.name();
        let tol = |check: &str| diff_physics::oracle::precision_tolerance(&name, check, 1e-9);
        let (tm, tp, tc) = (tol("per-link mass"), tol("link-frame FK position"), tol("centre of mass"));
        if !counts_ok || harness::exceeds(dm, tm) || harness::exceeds(dp, tp) || harness::exceeds(dc, tc) {
            problems.push(format!("{}: mass Δ {dm:.3e} kg, link FK Δ {dp:.3e} m, COM Δ {dc:.3e} m", f.name()));
        }
    }
    Ok(if problems.is_empty() { None } else { Some(problems.join("; ")) })
}

/// Classifies a finding whose window starts at `state`.
pub fn classify(
    model: &RobotModel,
    factories: &[Arc<dyn EngineFactory>],
    common: &CommonSettings,
    allow: &AllowList,
    f: &Finding,
    state: &State,
) -> Result<Class, DiffError> {
    let involved: Vec<&Arc<dyn EngineFactory>> =
        factories.iter().filter(|x| x.name() == f.engine || x.name() == f.lead).collect();
    if let Some(detail) = model_equivalence_at(model, &involved, state, common)? {
        return Ok(Class::TranslationProblem { detail });
    }
    Ok(allow.covering(f).map_or(Class::CandidateEngineBug, |c| c.class()))
}

/// Allow-list covers a run withdraws. An entry is one claim: the mechanism it names keeps an engine's `quantity`
/// within `max_ratio` of its bound everywhere in the entry's scope. When one finding of a run in that scope (same
/// engine, lead, kind and quantity, any of the entry's phases) goes beyond the cap, the claim does not hold for
/// that quantity in this run, and the entry covers none of its findings there: a defect that shows beyond the cap
/// in one contact phase is not absorbed in another where it happens to stay under it
/// (`tests/it/planted_bug.rs`). Covers through the reference are not withdrawn: they are sums of claims, each
/// checked on its own pair.
#[derive(Debug, Clone, Default)]
pub struct WithdrawnCovers {
    /// (entry id, engine, lead, kind, quantity).
    keys: std::collections::BTreeSet<(String, String, String, String, String)>,
}

impl WithdrawnCovers {
    /// The covers `findings` (a whole run) withdraw.
    pub fn of<'a>(allow: &AllowList, findings: impl IntoIterator<Item = &'a Finding>) -> Self {
        let mut keys = std::collections::BTreeSet::new();
        for f in findings {
            for e in allow.entries.iter().filter(|e| e.in_scope(f) && f.ratio() > e.max_ratio) {
                keys.insert(Self::key(&e.id, f));
            }
        }
        WithdrawnCovers { keys }
    }

    fn key(id: &str, f: &Finding) -> (String, String, String, String, String) {
        let lead = if f.kind == "invariant" { String::new() } else { f.lead.clone() };
        (id.to_string(), f.engine.clone(), lead, f.kind.clone(), f.quantity.clone())
    }

    /// Whether the run withdrew entry `id` from `f`'s quantity.
    pub fn withdraws(&self, id: &str, f: &Finding) -> bool {
        self.keys.contains(&Self::key(id, f))
    }

    /// `class` as the run leaves it: an expected difference whose entry the run withdrew is a candidate bug.
    pub fn apply(&self, f: &Finding, class: Class) -> Class {
        match &class {
            Class::ExpectedDifference { id, .. } if self.withdraws(id, f) => Class::CandidateEngineBug,
            _ => class,
        }
    }
}

/// A finding reduced to its smallest reproducing form.
#[derive(Debug, Clone)]
pub struct Minimized {
    /// Perturbation scale kept (1 = as found; 0 = the unperturbed input still shows it).
    pub scale: f64,
    pub scenario: Scenario,
    pub finding: Finding,
    pub window: WindowInput,
    /// Shortest number of steps of that window that still shows the finding.
    pub steps: usize,
}

/// Value of a finding's quantity after a replay of `steps` steps (same definitions as the episode).
pub fn finding_value(kind: &str, quantity: &str, engine_index: usize, run: &harness::WindowRun) -> f64 {
    match kind {
        "invariant" => run
            .invariants
            .get(engine_index)
            .and_then(|v| v.iter().find(|(q, _, _)| q == quantity))
            .map(|x| x.1)
            .unwrap_or(0.0),
        _ => {
            let (Some(l), Some(o)) = (run.after_k.first(), run.after_k.get(engine_index)) else { return 0.0 };
            let d = Div::between(&l.0, &l.1, &o.0, &o.1);
            match quantity {
                "base linear velocity" => d.base_lin_vel,
                "joint velocity" => d.max_dq(),
                "base angular velocity" => d.base_ang_vel,
                _ => d.max_link(),
            }
        }
    }
}

/// The bound of a finding's quantity for a window of `steps` steps.
pub fn finding_bound(f: &Finding, dt: f64, steps: usize) -> f64 {
    match f.kind.as_str() {
        "k_step_bound" => Bounds::new(dt, steps).k_step_link_pos,
        _ => f.bound,
    }
}

/// Minimizes a finding: (1) the smallest perturbation scale in {0, 1/8, 1/4, 1/2, 1} at which an episode
/// (cut just after the finding's window) still shows the same kind/engine/quantity; (2) among those windows,
/// the one with the fewest bodies in contact (then the largest ratio); (3) the shortest prefix of that window
/// still exceeding the bound (one-step findings are one step by definition).
pub fn minimize(
    model: &RobotModel,
    factories: &[Arc<dyn EngineFactory>],
    ctrl: &ControllerFactory,
    cfg: &HarnessConfig,
    scenario: &Scenario,
    f: &Finding,
) -> Result<Minimized, DiffError> {
    let cfg = HarnessConfig { free_runs: false, ..cfg.clone() };
    let dt = cfg.common.timestep;
    let window_s = cfg.window_steps as f64 * dt;
    let friction = model.contact.friction;
    let mut chosen: Option<(f64, Scenario, Finding, WindowRecord)> = None;
    for a in [0.0, 0.125, 0.25, 0.5, 1.0] {
        let mut s = scenario.scaled(a, friction);
        s.seconds = (f.t0 + window_s).min(scenario.seconds);
        let r = harness::run_episode(model, factories, ctrl, &s, &cfg)?;
        let best = r
            .findings
            .iter()
            .filter(|g| g.kind == f.kind && g.engine == f.engine && g.quantity == f.quantity)
            .min_by(|x, y| x.contact_bodies.cmp(&y.contact_bodies).then(y.ratio().total_cmp(&x.ratio())));
        if let Some(g) = best {
            if let Some(w) = r.windows.get(g.window) {
                chosen = Some((a, s.clone(), g.clone(), w.clone()));
                break;
            }
        }
    }
    let Some((scale, s, g, w)) = chosen else {
        return Err(DiffError::Input(format!("finding {} / {} / {} did not reproduce", f.kind, f.engine, f.quantity)));
    };
    let m = harness::scenario_model(model, &s);
    let mut engines = harness::build_engines(factories, &m, &cfg.common)?;
    let ei = factories.iter().position(|x| x.name() == g.engine).unwrap_or(1);
    let steps = match g.kind.as_str() {
        "one_step_bound" => 1,
        "k_step_bound" => {
            let run = harness::replay_window(&mut engines, &m, &w.input, w.input.steps, dt, true)?;
            let mut best = w.input.steps;
            for (i, row) in run.trace.iter().enumerate() {
                if let (Some(l), Some(o)) = (row.first(), row.get(ei)) {
                    let d = Div::between(&l.0, &l.1, &o.0, &o.1);
                    if d.max_link() > Bounds::new(dt, i + 1).k_step_link_pos {
                        best = i + 1;
                        break;
                    }
                }
            }
            best
        }
        _ => {
            // Invariants: bisect on the prefix length (the worst value over a prefix only grows).
            let (mut lo, mut hi) = (1usize, w.input.steps);
            while lo < hi {
                let mid = (lo + hi) / 2;
                let run = harness::replay_window(&mut engines, &m, &w.input, mid, dt, false)?;
                if finding_value(&g.kind, &g.quantity, ei, &run) > g.bound {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            lo
        }
    };
    Ok(Minimized { scale, scenario: s, finding: g, window: w.input, steps })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn finding(kind: &str, lead: &str, engine: &str, ratio: f64) -> Finding {
        Finding {
            kind: kind.into(),
            engine: engine.into(),
            lead: lead.into(),
            quantity: "joint velocity".into(),
            value: ratio,
            bound: 1.0,
            window: 0,
            t0: 0.0,
            phase: crate::phase::ContactPhase::DOUBLE,
            contact_bodies: 2,
        }
    }

    /// The built-in caps of Bullet (rigid contact) and Rapier (speculative contact) against MuJoCo, for joint
    /// velocity, as `allowlist.toml` has them.
    #[test]
    fn a_pair_without_the_reference_gets_the_sum_of_both_caps_and_no_more() {
        let allow = AllowList::builtin().expect("allow-list");
        let cap = |id: &str| allow.entries.iter().find(|e| e.id == id).expect("entry").max_ratio;
        let (rapier, bullet) = (cap("soft-vs-speculative-contact"), cap("rigid-vs-soft-contact"));
        let cover = |f: &Finding| allow.covering(f).map(|c| c.id());
        assert_eq!(
            cover(&finding("one_step_bound", "mujoco", "rapier_multibody", rapier - 1.0)).as_deref(),
            Some("soft-vs-speculative-contact")
        );
        assert_eq!(
            cover(&finding("one_step_bound", "mujoco", "rapier_multibody", rapier + 1.0)),
            None,
            "the reference pair keeps its cap"
        );
        let via = cover(&finding("one_step_bound", "bullet", "rapier_multibody", rapier + bullet - 1.0));
        assert_eq!(via.as_deref(), Some("via-reference:rigid-vs-soft-contact+soft-vs-speculative-contact"));
        assert_eq!(cover(&finding("one_step_bound", "bullet", "rapier_multibody", rapier + bullet + 1.0)), None);
        // An engine no entry covers may stand at its bound from the reference: over k steps in contact Bullet has
        // no entry (1) and Rapier multibody the friction-cone entry (1.5).
        let k = |r| Finding {
            quantity: "link position".into(),
            ..finding("k_step_bound", "bullet", "rapier_multibody", r)
        };
        assert_eq!(cover(&k(2.4)).as_deref(), Some("via-reference:-+friction-cone-and-stiction"));
        assert_eq!(cover(&k(2.6)), None);
        // Invariants are one engine's own: no pair loosens them.
        let inv = Finding {
            quantity: "joint limit overrun".into(),
            ..finding("invariant", "bullet", "rapier_multibody", 1.2)
        };
        assert_eq!(cover(&inv), None);
    }

    /// One finding beyond Steel's cap in double support withdraws the entry from every finding of that quantity on
    /// that engine pair in the run, in any of its phases; another quantity, another engine or a run that stays
    /// under the cap keeps it.
    #[test]
    fn a_run_beyond_an_entry_cap_anywhere_in_its_scope_withdraws_it_for_that_quantity() {
        let allow = AllowList::builtin().expect("allow-list");
        let cap = allow.entries.iter().find(|e| e.id == "steel-rigid-contact-rows").expect("entry").max_ratio;
        let under = Finding {
            phase: crate::phase::ContactPhase { feet: crate::phase::FootContact::Left, other: false },
            ..finding("one_step_bound", "mujoco", "newton_steel", cap - 0.5)
        };
        let class = |f: &Finding| allow.covering(f).map_or(Class::CandidateEngineBug, |c| c.class());
        assert!(matches!(class(&under), Class::ExpectedDifference { .. }));
        let quiet = WithdrawnCovers::of(&allow, [&under]);
        assert!(matches!(quiet.apply(&under, class(&under)), Class::ExpectedDifference { .. }));
        let beyond = finding("one_step_bound", "mujoco", "newton_steel", cap + 0.5);
        let other_quantity = Finding { quantity: "base linear velocity".into(), ..beyond.clone() };
        let other_engine = finding("one_step_bound", "mujoco", "rapier_multibody", cap + 0.5);
        let w = WithdrawnCovers::of(&allow, [&under, &other_quantity, &other_engine]);
        assert!(matches!(w.apply(&under, class(&under)), Class::ExpectedDifference { .. }));
        let w = WithdrawnCovers::of(&allow, [&under, &beyond]);
        assert_eq!(w.apply(&under, class(&under)), Class::CandidateEngineBug);
    }
}
