//! Analysis of episodes into a report (`report.md`, `report.json`, SVG plots) with triaged, minimized
//! entries and their reproducers.
use crate::harness::{Bounds, ControllerFactory, EngineFactory, EpisodeResult, Finding, HarnessConfig, Timing};
use crate::phase::ContactPhase;
use crate::repro::{EngineInfo, Reproducer};
use crate::triage::{self, AllowEntry, AllowList, Class};
use crate::{io_err, DiffError, SCHEMA_VERSION};
use robot_model::RobotModel;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// Median and extremes of a sample.
#[derive(Debug, Clone, Copy, Serialize, Default)]
pub struct Stats {
    pub n: usize,
    pub min: f64,
    pub median: f64,
    pub max: f64,
}

impl Stats {
    pub fn of(v: &[f64]) -> Stats {
        let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        if s.is_empty() {
            return Stats { n: 0, ..Default::default() };
        }
        s.sort_by(f64::total_cmp);
        let n = s.len();
        let median = if n % 2 == 1 { s[n / 2] } else { 0.5 * (s[n / 2 - 1] + s[n / 2]) };
        Stats { n, min: s[0], median, max: s[n - 1] }
    }
}

/// Divergence per named item (joint or body).
#[derive(Debug, Clone, Serialize)]
pub struct NamedStats {
    pub name: String,
    pub stats: Stats,
}

/// Divergence per contact phase.
#[derive(Debug, Clone, Serialize)]
pub struct PhaseStats {
    pub phase: ContactPhase,
    pub one_step_joint_vel: Stats,
    pub k_step_link_pos: Stats,
}

/// One engine's divergence from the lead over every window.
#[derive(Debug, Clone, Serialize)]
pub struct EngineDivergence {
    pub engine: String,
    pub windows: usize,
    pub one_step_base_lin_vel: Stats,
    pub one_step_joint_vel: Stats,
    pub one_step_base_ang_vel: Stats,
    pub k_step_link_pos: Stats,
    pub k_step_base_pos: Stats,
    /// k-step joint angle divergence per joint (slot order).
    pub per_joint_k_step: Vec<NamedStats>,
    /// k-step position divergence per body (`model.links` order).
    pub per_body_k_step: Vec<NamedStats>,
    pub per_phase: Vec<PhaseStats>,
}

/// Episode outcomes of one engine over seeds.
#[derive(Debug, Clone, Serialize)]
pub struct OutcomeDistribution {
    pub engine: String,
    pub episodes: usize,
    pub falls: usize,
    pub engine_errors: usize,
    pub fall_time: Stats,
    pub joint_tracking_rms: Stats,
    pub velocity_tracking_rms: Stats,
    /// Two-sided Mann-Whitney U test of joint tracking RMS against the lead's (normal approximation;
    /// None for the lead or with fewer than 2 episodes per side).
    pub joint_tracking_vs_lead_p: Option<f64>,
}

/// Minimization summary of an entry.
#[derive(Debug, Clone, Serialize)]
pub struct MinimizedSummary {
    pub perturbation_scale: f64,
    pub steps: usize,
    pub contact_bodies: usize,
    pub phase: ContactPhase,
    pub value: f64,
    pub bound: f64,
    pub reproducer: String,
}

/// One triaged divergence (a group of findings of the same kind, engine, quantity and phase).
#[derive(Debug, Clone, Serialize)]
pub struct Entry {
    pub id: String,
    pub kind: String,
    pub engine: String,
    pub quantity: String,
    pub phase: ContactPhase,
    pub count: usize,
    pub worst: Finding,
    pub worst_episode_seed: u64,
    pub triage: Class,
    pub minimized: Option<MinimizedSummary>,
    /// Why an entry was not minimized (cap reached, did not reproduce).
    pub minimization_note: Option<String>,
}

/// What one allow-list entry absorbed over the whole run (every finding, not only each group's worst): how much
/// of the run it explains, and how close the absorbed findings came to its cap.
#[derive(Debug, Clone, Serialize)]
pub struct AllowUsage {
    pub id: String,
    /// Findings the entry covers.
    pub findings: usize,
    /// Finding groups (kind, engine, quantity, phase) with at least one covered finding.
    pub groups: usize,
    /// Largest ratio (value / bound) among the covered findings.
    pub max_ratio: f64,
    /// The entry's cap.
    pub cap: f64,
    /// Findings of the entry's engines, kinds, quantities and phases that exceeded the cap (candidate bugs).
    pub over_cap: usize,
    /// Findings under the cap that the entry does not cover because the run took their quantity beyond the cap
    /// elsewhere in the entry's scope ([`triage::WithdrawnCovers`]; candidate bugs too).
    pub withdrawn: usize,
}

/// Per-entry usage of the allow-list over `episodes`.
pub fn allow_usage(allow: &AllowList, episodes: &[EpisodeResult]) -> Vec<AllowUsage> {
    let withdrawn = triage::WithdrawnCovers::of(allow, episodes.iter().flat_map(|e| e.findings.iter()));
    allow
        .entries
        .iter()
        .map(|entry| {
            let one = AllowList { entries: vec![AllowEntry { max_ratio: f64::INFINITY, ..entry.clone() }] };
            let mut u = AllowUsage {
                id: entry.id.clone(),
                findings: 0,
                groups: 0,
                max_ratio: 0.0,
                cap: entry.max_ratio,
                over_cap: 0,
                withdrawn: 0,
            };
            let mut groups = std::collections::BTreeSet::new();
            for f in episodes.iter().flat_map(|e| e.findings.iter()) {
                // Covered by this entry's scope at all (ignoring the cap), and first in the list to match?
                if one.matching(f).is_none() {
                    continue;
                }
                match allow.matching(f) {
                    Some(m) if m.id == entry.id && withdrawn.withdraws(&m.id, f) => u.withdrawn += 1,
                    Some(m) if m.id == entry.id => {
                        u.findings += 1;
                        u.max_ratio = u.max_ratio.max(f.ratio());
                        groups.insert(f.group_key());
                    }
                    None => u.over_cap += 1,
                    Some(_) => {}
                }
            }
            u.groups = groups.len();
            u
        })
        .collect()
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub schema_version: u32,
    pub robot: String,
    pub model_hash: String,
    pub controller: String,
    pub engines: Vec<EngineInfo>,
    pub lead: String,
    pub config: HarnessConfig,
    pub bounds: Bounds,
    pub episodes: usize,
    pub seconds: f64,
    pub seeds: Vec<u64>,
    pub divergence: Vec<EngineDivergence>,
    pub outcomes: Vec<OutcomeDistribution>,
    pub entries: Vec<Entry>,
    /// Inputs on which an engine failed (`ulab diff fuzz`): candidate engine bugs that have no window to triage.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub engine_failures: Vec<crate::harness::EngineFailure>,
    pub allow_list: AllowList,
    /// What each allow-list entry absorbed.
    pub allow_usage: Vec<AllowUsage>,
    pub timing: Timing,
}

/// What the analysis needs besides the episodes.
pub struct Analysis<'a> {
    pub model: &'a RobotModel,
    pub factories: &'a [Arc<dyn EngineFactory>],
    pub controller: &'a ControllerFactory,
    pub controller_name: &'a str,
    pub cfg: &'a HarnessConfig,
    pub allow: &'a AllowList,
    /// Entries minimized (largest first, candidate bugs before the rest); the others are triaged only.
    pub minimize_limit: usize,
}

impl std::fmt::Debug for Analysis<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Analysis").field("controller", &self.controller_name).finish()
    }
}

fn mann_whitney_p(a: &[f64], b: &[f64]) -> Option<f64> {
    let (n1, n2) = (a.len() as f64, b.len() as f64);
    if a.len() < 2 || b.len() < 2 {
        return None;
    }
    let mut u = 0.0;
    for x in a {
        for y in b {
            u += if x > y {
                1.0
            } else if x == y {
                0.5
            } else {
                0.0
            };
        }
    }
    let mu = n1 * n2 / 2.0;
    let sigma = (n1 * n2 * (n1 + n2 + 1.0) / 12.0).sqrt();
    let z = ((u - mu).abs() - 0.5).max(0.0) / sigma;
    // Two-sided p from the normal tail: erfc(z/√2), Abramowitz-Stegun 7.1.26 (|error| < 1.5e-7).
    let x = z / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly =
        t * (0.254_829_592 + t * (-0.284_496_736 + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    Some((poly * (-x * x).exp()).clamp(0.0, 1.0))
}

/// Builds the report (triage and minimization included) and the reproducers (file name, content).
pub fn analyse(a: &Analysis<'_>, episodes: &[EpisodeResult]) -> Result<(Report, Vec<(String, Reproducer)>), DiffError> {
    let model = a.model;
    let names: Vec<String> = a.factories.iter().map(|f| f.name()).collect();
    let lead = names.first().cloned().unwrap_or_default();
    let infos = {
        let engines = crate::harness::build_engines(a.factories, model, &a.cfg.common)?;
        engines
            .iter()
            .map(|e| EngineInfo { name: e.name().to_string(), version: e.version(), settings: e.settings() })
            .collect()
    };
    let k = a.cfg.window_steps;
    let bounds = Bounds::new(a.cfg.common.timestep, k);

    // Divergence per engine.
    let mut divergence = Vec::new();
    for en in names.iter().skip(1) {
        let divs: Vec<(&crate::harness::EngineDiv, ContactPhase)> = episodes
            .iter()
            .flat_map(|e| e.windows.iter())
            .flat_map(|w| w.divs.iter().filter(|d| &d.engine == en).map(move |d| (d, w.phase)))
            .collect();
        let full: Vec<&crate::harness::EngineDiv> = episodes
            .iter()
            .flat_map(|e| e.windows.iter().filter(|w| w.input.steps == k))
            .flat_map(|w| w.divs.iter().filter(|d| &d.engine == en))
            .collect();
        let col = |f: &dyn Fn(&crate::harness::EngineDiv) -> f64, v: &[&crate::harness::EngineDiv]| {
            Stats::of(&v.iter().map(|d| f(d)).collect::<Vec<_>>())
        };
        let all: Vec<&crate::harness::EngineDiv> = divs.iter().map(|d| d.0).collect();
        let mut phases: BTreeMap<ContactPhase, Vec<&crate::harness::EngineDiv>> = BTreeMap::new();
        for (d, p) in &divs {
            phases.entry(*p).or_default().push(d);
        }
        divergence.push(EngineDivergence {
            engine: en.clone(),
            windows: all.len(),
            one_step_base_lin_vel: col(&|d| d.one_step.base_lin_vel, &all),
            one_step_joint_vel: col(&|d| d.one_step.max_dq(), &all),
            one_step_base_ang_vel: col(&|d| d.one_step.base_ang_vel, &all),
            k_step_link_pos: col(&|d| d.k_step.max_link(), &full),
            k_step_base_pos: col(&|d| d.k_step.base_pos, &full),
            per_joint_k_step: model
                .joints
                .iter()
                .enumerate()
                .map(|(j, jt)| NamedStats {
                    name: jt.name.clone(),
                    stats: col(&|d| d.k_step.q.get(j).copied().unwrap_or(f64::NAN), &full),
                })
                .collect(),
            per_body_k_step: model
                .links
                .iter()
                .enumerate()
                .map(|(l, lk)| NamedStats {
                    name: lk.name.clone(),
                    stats: col(&|d| d.k_step.link_pos.get(l).copied().unwrap_or(f64::NAN), &full),
                })
                .collect(),
            per_phase: phases
                .into_iter()
                .map(|(p, v)| PhaseStats {
                    phase: p,
                    one_step_joint_vel: col(&|d| d.one_step.max_dq(), &v),
                    k_step_link_pos: col(&|d| d.k_step.max_link(), &v),
                })
                .collect(),
        });
    }

    // Outcomes as distributions over seeds.
    let lead_track: Vec<f64> = episodes
        .iter()
        .flat_map(|e| e.outcomes.iter().filter(|o| o.engine == lead).map(|o| o.joint_tracking_rms))
        .collect();
    let mut outcomes = Vec::new();
    if episodes.iter().any(|e| !e.outcomes.is_empty()) {
        for en in &names {
            let os: Vec<&crate::harness::Outcome> =
                episodes.iter().flat_map(|e| e.outcomes.iter().filter(|o| &o.engine == en)).collect();
            let track: Vec<f64> = os.iter().map(|o| o.joint_tracking_rms).collect();
            outcomes.push(OutcomeDistribution {
                engine: en.clone(),
                episodes: os.len(),
                falls: os.iter().filter(|o| o.fell).count(),
                engine_errors: os.iter().filter(|o| o.error.is_some()).count(),
                fall_time: Stats::of(&os.iter().filter_map(|o| o.fall_time).collect::<Vec<_>>()),
                joint_tracking_rms: Stats::of(&track),
                velocity_tracking_rms: Stats::of(&os.iter().map(|o| o.velocity_tracking_rms).collect::<Vec<_>>()),
                joint_tracking_vs_lead_p: if en == &lead { None } else { mann_whitney_p(&track, &lead_track) },
            });
        }
    }

    // Group findings, triage the worst of each group, minimize the largest ones.
    type Groups = BTreeMap<crate::harness::GroupKey, (usize, usize, Finding)>;
    let mut groups: Groups = BTreeMap::new();
    for (ei, e) in episodes.iter().enumerate() {
        for f in &e.findings {
            let ent = groups.entry(f.group_key()).or_insert((0, ei, f.clone()));
            ent.0 += 1;
            if f.ratio() > ent.2.ratio() {
                ent.1 = ei;
                ent.2 = f.clone();
            }
        }
    }
    let withdrawn = triage::WithdrawnCovers::of(a.allow, episodes.iter().flat_map(|e| e.findings.iter()));
    let mut entries = Vec::new();
    for (_, (count, ei, f)) in groups {
        let state = &episodes[ei].windows[f.window].input.start;
        let class = withdrawn.apply(&f, triage::classify(model, a.factories, &a.cfg.common, a.allow, &f, state)?);
        entries.push(Entry {
            id: String::new(),
            kind: f.kind.clone(),
            engine: f.engine.clone(),
            quantity: f.quantity.clone(),
            phase: f.phase,
            count,
            worst_episode_seed: episodes[ei].scenario.seed,
            worst: f,
            triage: class,
            minimized: None,
            minimization_note: None,
        });
    }
    let rank = |c: &Class| match c {
        Class::CandidateEngineBug => 0,
        Class::TranslationProblem { .. } => 1,
        Class::ExpectedDifference { .. } => 2,
    };
    entries.sort_by(|x, y| {
        rank(&x.triage)
            .cmp(&rank(&y.triage))
            .then(y.worst.ratio().total_cmp(&x.worst.ratio()))
            .then(x.kind.cmp(&y.kind))
            .then(x.engine.cmp(&y.engine))
            .then(x.quantity.cmp(&y.quantity))
            .then(x.phase.cmp(&y.phase))
    });
    let mut repros = Vec::new();
    for (i, e) in entries.iter_mut().enumerate() {
        e.id = format!("D{:02}", i + 1);
        if i >= a.minimize_limit {
            e.minimization_note = Some(format!("not minimized: only the first {} entries are", a.minimize_limit));
            continue;
        }
        let Some(ep) = episodes.iter().find(|x| {
            x.scenario.seed == e.worst_episode_seed
                && x.findings.iter().any(|f| f.window == e.worst.window && f.group_key() == e.worst.group_key())
        }) else {
            continue;
        };
        match triage::minimize(model, a.factories, a.controller, a.cfg, &ep.scenario, &e.worst) {
            Ok(m) => {
                let file = format!("repro_{}.json", e.id);
                let r = Reproducer::new(model, a.factories, &a.cfg.common, a.controller_name, &m)?;
                e.minimized = Some(MinimizedSummary {
                    perturbation_scale: m.scale,
                    steps: m.steps,
                    contact_bodies: m.finding.contact_bodies,
                    phase: m.finding.phase,
                    value: r.expected.value,
                    bound: triage::finding_bound(&m.finding, a.cfg.common.timestep, m.steps),
                    reproducer: file.clone(),
                });
                repros.push((file, r));
            }
            Err(DiffError::Input(msg)) => e.minimization_note = Some(msg),
            Err(other) => return Err(other),
        }
    }
    let mut timing = Timing::default();
    for e in episodes {
        timing.engine_s += e.timing.engine_s;
        timing.total_s += e.timing.total_s;
        timing.steps += e.timing.steps;
    }
    let report = Report {
        schema_version: SCHEMA_VERSION,
        robot: model.name.clone(),
        model_hash: crate::model_hash(model),
        controller: a.controller_name.to_string(),
        engines: infos,
        lead,
        config: a.cfg.clone(),
        bounds,
        episodes: episodes.len(),
        seconds: episodes.first().map(|e| e.scenario.seconds).unwrap_or(0.0),
        seeds: episodes.iter().map(|e| e.scenario.seed).collect(),
        divergence,
        outcomes,
        entries,
        engine_failures: Vec::new(),
        allow_list: a.allow.clone(),
        allow_usage: allow_usage(a.allow, episodes),
        timing,
    };
    Ok((report, repros))
}

/// Three significant digits (reports stay readable and stable against last-bit differences).
pub fn g3(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if !x.is_finite() {
        format!("{x}")
    } else {
        format!("{x:.2e}")
    }
}

fn stats_cell(s: &Stats) -> String {
    if s.n == 0 {
        "–".into()
    } else {
        format!("{} [{} … {}]", g3(s.median), g3(s.min), g3(s.max))
    }
}

impl Report {
    /// The human-readable report (no timings: it is pinned by snapshot tests).
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        s += &format!("# Engine divergence report: {} driven by `{}`\n\n", self.robot, self.controller);
        s += &format!(
            "Schema {}; model hash `{}`.\n\n",
            self.schema_version,
            &self.model_hash[..16.min(self.model_hash.len())]
        );
        s += "## Engines\n\n| engine | version |\n|---|---|\n";
        for e in &self.engines {
            s += &format!("| {}{} | {} |\n", e.name, if e.name == self.lead { " (lead)" } else { "" }, e.version);
        }
        s += &format!(
            "\n{} episode(s) of {} s, seeds {:?}; dt {} s; windows of {} steps start from the lead's state, loaded into every engine.\n\n",
            self.episodes, self.seconds, self.seeds, self.config.common.timestep, self.config.window_steps
        );
        s += &format!(
            "Bounds (2.5 g contact-acceleration difference): one step base velocity {} m/s, joint and base angular velocity {} (rad/s); k steps link position {} m.\n\n",
            g3(self.bounds.one_step_base_lin_vel), g3(self.bounds.one_step_joint_vel), g3(self.bounds.k_step_link_pos)
        );
        s += "## Divergence from the lead (median [min … max] over windows)\n\n";
        s += "| engine | windows | 1-step base vel (m/s) | 1-step joint vel (rad/s) | 1-step base ang vel (rad/s) | k-step link pos (m) | k-step base pos (m) |\n|---|---|---|---|---|---|---|\n";
        for d in &self.divergence {
            s += &format!(
                "| {} | {} | {} | {} | {} | {} | {} |\n",
                d.engine,
                d.windows,
                stats_cell(&d.one_step_base_lin_vel),
                stats_cell(&d.one_step_joint_vel),
                stats_cell(&d.one_step_base_ang_vel),
                stats_cell(&d.k_step_link_pos),
                stats_cell(&d.k_step_base_pos)
            );
        }
        for d in &self.divergence {
            s += &format!("\n### {} per contact phase\n\n| phase | windows | 1-step joint vel (rad/s) | k-step link pos (m) |\n|---|---|---|---|\n", d.engine);
            for p in &d.per_phase {
                s += &format!(
                    "| {} | {} | {} | {} |\n",
                    p.phase,
                    p.one_step_joint_vel.n,
                    stats_cell(&p.one_step_joint_vel),
                    stats_cell(&p.k_step_link_pos)
                );
            }
            let top = |v: &[NamedStats]| {
                let mut v: Vec<&NamedStats> = v.iter().filter(|x| x.stats.n > 0).collect();
                v.sort_by(|a, b| b.stats.max.total_cmp(&a.stats.max).then(a.name.cmp(&b.name)));
                v.into_iter().take(5).map(|x| format!("{} {}", x.name, g3(x.stats.max))).collect::<Vec<_>>().join(", ")
            };
            s += &format!("\nLargest k-step joint divergence (rad, max): {}.\n", top(&d.per_joint_k_step));
            s += &format!("Largest k-step body divergence (m, max): {}.\n", top(&d.per_body_k_step));
        }
        if !self.outcomes.is_empty() {
            s += "\n## Episode outcomes (free closed-loop runs, distributions over seeds)\n\n| engine | episodes | falls | engine errors | fall time (s) | joint tracking RMS (rad) | velocity tracking RMS | p vs lead (Mann-Whitney) |\n|---|---|---|---|---|---|---|---|\n";
            for o in &self.outcomes {
                s += &format!(
                    "| {} | {} | {} | {} | {} | {} | {} | {} |\n",
                    o.engine,
                    o.episodes,
                    o.falls,
                    o.engine_errors,
                    stats_cell(&o.fall_time),
                    stats_cell(&o.joint_tracking_rms),
                    stats_cell(&o.velocity_tracking_rms),
                    o.joint_tracking_vs_lead_p.map(|p| format!("{p:.2}")).unwrap_or_else(|| "–".into())
                );
            }
        }
        if !self.engine_failures.is_empty() {
            s += "\n## Engine failures\n\nAn engine failed on these inputs (candidate engine bugs; each input is `failures/NN.json`, \
                  replayed by `ulab diff fuzz --corpus DIR/failures`):\n\n| input | engine | failing step from t (s) | error | seed |\n|---|---|---|---|---|\n";
            for (i, f) in self.engine_failures.iter().enumerate() {
                s += &format!("| `{i:02}.json` | {} | {:.4} | {} | {} |\n", f.engine, f.t, f.error, f.scenario.seed);
            }
        }
        s += "\n## Triaged divergences\n\n";
        if self.entries.is_empty() {
            s += "No finding exceeded its bound.\n";
        } else {
            s += "| id | triage | kind | engine | quantity | phase | count | worst / bound | minimized (scale, steps, bodies in contact) | reproducer |\n|---|---|---|---|---|---|---|---|---|---|\n";
            for e in &self.entries {
                let m = e
                    .minimized
                    .as_ref()
                    .map(|m| format!("{}, {}, {}", m.perturbation_scale, m.steps, m.contact_bodies))
                    .unwrap_or_else(|| e.minimization_note.clone().unwrap_or_else(|| "–".into()));
                let r = e.minimized.as_ref().map(|m| format!("`{}`", m.reproducer)).unwrap_or_else(|| "–".into());
                s += &format!(
                    "| {} | {} | {} | {} | {} | {} | {} | {} / {} | {} | {} |\n",
                    e.id,
                    e.triage.label(),
                    e.kind,
                    e.engine,
                    e.quantity,
                    e.phase,
                    e.count,
                    g3(e.worst.value),
                    g3(e.worst.bound),
                    m,
                    r
                );
            }
            s += "\n";
            for e in &self.entries {
                match &e.triage {
                    Class::ExpectedDifference { id, rationale, citation } => {
                        s += &format!("- {}: allow-list `{id}`: {} ({})\n", e.id, rationale.split(". ").next().unwrap_or(""), citation.join(", "));
                    }
                    Class::TranslationProblem { detail } => s += &format!("- {}: model equivalence fails at the window start: {detail}\n", e.id),
                    Class::CandidateEngineBug => s += &format!("- {}: no translation problem, no allow-list entry covers it in this run: candidate engine bug (replay: `ulab diff replay DIR/{}`)\n", e.id, e.minimized.as_ref().map(|m| m.reproducer.as_str()).unwrap_or("-")),
                }
            }
        }
        s += "\n## Allow-list usage\n\n| entry | findings absorbed | groups | largest ratio absorbed | cap | in scope but over the cap | under the cap, withdrawn |\n|---|---|---|---|---|---|---|\n";
        for u in &self.allow_usage {
            s += &format!(
                "| `{}` | {} | {} | {} | {} | {} | {} |\n",
                u.id,
                u.findings,
                u.groups,
                if u.findings > 0 { g3(u.max_ratio) } else { "–".into() },
                g3(u.cap),
                u.over_cap,
                u.withdrawn
            );
        }
        s += "\n## Plots\n\n- `one_step.svg`: per window (x), max one-step joint-velocity divergence (y, linear from 0).\n- `k_step.svg`: per window, k-step link-position divergence.\n- `per_joint.svg`: per joint (x, slot order), max k-step joint-angle divergence.\n\nLines, in engine order after the lead: ";
        s += &self
            .divergence
            .iter()
            .zip(PALETTE_NAMES)
            .map(|(d, c)| format!("{} {c}", d.engine))
            .collect::<Vec<_>>()
            .join(", ");
        s += ".\n";
        s
    }
}

/// One colour per engine after the lead (up to the six engines of the CLI's build, then repeating).
const PALETTE_NAMES: [&str; 6] = ["red", "blue", "green", "magenta", "cyan", "black"];

pub(crate) fn palette(i: usize) -> plotters::style::RGBColor {
    use plotters::style::colors::*;
    [RED, BLUE, GREEN, MAGENTA, CYAN, BLACK][i % PALETTE_NAMES.len()]
}

fn line_plot(path: &Path, series: &[Vec<(f64, f64)>]) -> Result<(), DiffError> {
    use plotters::prelude::*;
    let xmax = series.iter().flatten().map(|p| p.0).fold(1.0, f64::max);
    let ymax = series.iter().flatten().map(|p| p.1).filter(|y| y.is_finite()).fold(0.0, f64::max).max(1e-12) * 1.05;
    let root = SVGBackend::new(path, (800, 400)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| DiffError::Plot(Box::new(e)))?;
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .build_cartesian_2d(0f64..xmax, 0f64..ymax)
        .map_err(|e| DiffError::Plot(Box::new(e)))?;
    for (i, s) in series.iter().enumerate() {
        let pts: Vec<(f64, f64)> = s.iter().copied().filter(|p| p.1.is_finite()).collect();
        chart
            .draw_series(LineSeries::new(pts, palette(i).stroke_width(2)))
            .map_err(|e| DiffError::Plot(Box::new(e)))?;
    }
    root.present().map_err(|e| DiffError::Plot(Box::new(e)))?;
    Ok(())
}

/// Writes `report.md`, `report.json`, the plots and the reproducers into `dir`.
pub fn write_outputs(
    dir: &Path,
    report: &Report,
    repros: &[(String, Reproducer)],
    episodes: &[EpisodeResult],
) -> Result<(), DiffError> {
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    let w = |name: &str, text: String| {
        let p = dir.join(name);
        std::fs::write(&p, text).map_err(io_err(&p))
    };
    w("report.md", report.markdown())?;
    w("report.json", serde_json::to_string_pretty(report)?)?;
    for (name, r) in repros {
        w(name, serde_json::to_string_pretty(r)?)?;
    }
    if !report.engine_failures.is_empty() {
        let d = dir.join("failures");
        std::fs::create_dir_all(&d).map_err(io_err(&d))?;
        for (i, f) in report.engine_failures.iter().enumerate() {
            w(&format!("failures/{i:02}.json"), serde_json::to_string_pretty(&f.scenario)?)?;
        }
    }
    let engines: Vec<&str> = report.divergence.iter().map(|d| d.engine.as_str()).collect();
    let windows: Vec<&crate::harness::WindowRecord> = episodes.iter().flat_map(|e| e.windows.iter()).collect();
    let series = |f: &dyn Fn(&crate::harness::EngineDiv) -> f64| -> Vec<Vec<(f64, f64)>> {
        engines
            .iter()
            .map(|en| {
                windows
                    .iter()
                    .enumerate()
                    .filter_map(|(i, w)| w.divs.iter().find(|d| &d.engine == en).map(|d| (i as f64, f(d))))
                    .collect()
            })
            .collect()
    };
    line_plot(&dir.join("one_step.svg"), &series(&|d| d.one_step.max_dq()))?;
    line_plot(&dir.join("k_step.svg"), &series(&|d| d.k_step.max_link()))?;
    let per_joint: Vec<Vec<(f64, f64)>> = report
        .divergence
        .iter()
        .map(|d| d.per_joint_k_step.iter().enumerate().map(|(j, s)| (j as f64, s.stats.max)).collect())
        .collect();
    line_plot(&dir.join("per_joint.svg"), &per_joint)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_median() {
        let s = Stats::of(&[3.0, 1.0, 2.0, f64::NAN]);
        assert_eq!((s.n, s.min, s.median, s.max), (3, 1.0, 2.0, 3.0));
        assert_eq!(Stats::of(&[1.0, 2.0]).median, 1.5);
    }

    #[test]
    fn mann_whitney_against_python_erfc() {
        // U = 0 (all of one sample below the other), n1 = n2 = 5: Python's math.erfc of the textbook normal
        // approximation with continuity correction, erfc(12 / sqrt(25*11/12) / sqrt(2)) = 0.0121858.
        let p = mann_whitney_p(&[1.0, 2.0, 3.0, 4.0, 5.0], &[6.0, 7.0, 8.0, 9.0, 10.0]).unwrap_or(1.0);
        assert!((p - 0.0121858).abs() < 1e-6, "p = {p}");
        // Identical samples: p = 1.
        let p = mann_whitney_p(&[1.0, 2.0, 3.0], &[1.0, 2.0, 3.0]).unwrap_or(0.0);
        assert!(p > 0.99, "p = {p}");
    }
}
