//! Search that learns (issue 16, item 3): the cross-entropy method (CEM) over a fixed-length perturbation of a
//! rollout — command sequence, pushes, action noise, initial offsets, ground friction — maximising the divergence
//! between engines per unit of perturbation, and the two baselines it is compared with at equal compute (the same
//! number of rollouts of the same length): the mutation fuzzer of [`crate::fuzz`] and uniform random
//! perturbations drawn from the same box.
//!
//! The objective is the fuzzer's: `worst_ratio / (1 + magnitude)` ([`crate::harness::EpisodeResult::worst_ratio`],
//! [`Scenario::magnitude`]), so that the three methods are judged on one scale.
use crate::fuzz::{self, FuzzConfig};
use crate::harness::{self, ControllerFactory, EngineFactory, EpisodeResult, HarnessConfig};
use crate::scenario::{CommandSegment, Push, Scenario};
use crate::triage::AllowList;
use crate::DiffError;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::sync::Arc;

/// Dimension of the perturbation vector θ ∈ [−1, 1]^DIM (see [`decode`]).
pub const DIM: usize = 21;

/// The perturbation θ as a scenario around `base` (its seed, length, noise streams and excitation are kept).
/// θ = 0 is the base input without perturbation. Layout: three command segments at t = 0, T/3, 2T/3
/// (vx ±1 m/s, vy ±0.5 m/s, wz ±1 rad/s: 9 entries); two pushes (time over the episode, Δv ±0.6, ±0.6, ±0.2 m/s:
/// 8 entries); action noise |θ|·0.1 rad; initial joint offsets |θ|·0.1 rad; drop height |θ|·0.02 m; ground
/// friction `model ± 0.5` (clamped to [0.2, 1.5]).
pub fn decode(theta: &[f64], base: &Scenario, model_friction: f64) -> Scenario {
    let th = |i: usize| theta.get(i).copied().unwrap_or(0.0).clamp(-1.0, 1.0);
    let t_len = base.seconds;
    let commands = (0..3)
        .map(|k| CommandSegment { t: t_len * k as f64 / 3.0, command: [th(3 * k), 0.5 * th(3 * k + 1), th(3 * k + 2)] })
        .collect();
    let pushes = (0..2)
        .map(|k| {
            let o = 9 + 4 * k;
            Push { t: (th(o) + 1.0) / 2.0 * t_len, dv: [0.6 * th(o + 1), 0.6 * th(o + 2), 0.2 * th(o + 3)] }
        })
        .filter(|p| p.dv.iter().any(|x| *x != 0.0))
        .collect();
    Scenario {
        commands,
        pushes,
        action_noise: 0.1 * th(17).abs(),
        init_q_offset: 0.1 * th(18).abs(),
        init_height: 0.02 * th(19).abs(),
        ground_friction: if th(20) == 0.0 { None } else { Some((model_friction + 0.5 * th(20)).clamp(0.2, 1.5)) },
        ..base.clone()
    }
}

/// Search method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Cross-entropy method over θ.
    Cem,
    /// Uniform random θ.
    Random,
    /// The corpus-based mutation fuzzer ([`crate::fuzz::fuzz`]).
    Mutation,
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::Cem => "cem",
            Method::Random => "random",
            Method::Mutation => "mutation",
        }
    }
}

/// Settings of one search.
#[derive(Debug, Clone)]
pub struct SearchConfig {
    /// Rollouts in total (the compute budget every method gets).
    pub budget: usize,
    /// CEM population per generation.
    pub population: usize,
    /// Fraction of the population kept as elites.
    pub elite_fraction: f64,
    pub seed: u64,
}

impl Default for SearchConfig {
    fn default() -> Self {
        SearchConfig { budget: 64, population: 16, elite_fraction: 0.25, seed: 1 }
    }
}

/// What one method found with its budget.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SearchOutcome {
    pub method: Method,
    pub evaluated: usize,
    /// Rollouts an engine failed on.
    pub failed: usize,
    /// Best divergence per unit of perturbation.
    pub best_score: f64,
    /// Largest normalised divergence (ratio to its bound) over every rollout.
    pub max_divergence: f64,
    /// Distinct finding groups (kind, engine, quantity, phase) over every rollout.
    pub finding_groups: usize,
    /// Of those, groups with at least one finding the allow-list does not cover (candidate bugs before the
    /// translation check).
    pub unexplained_groups: usize,
    /// Those groups, with the largest ratio seen in each: (kind, engine, quantity, phase, ratio).
    pub unexplained: Vec<(String, String, String, crate::phase::ContactPhase, f64)>,
    /// Best score after each rollout (the search's progress curve).
    pub best_so_far: Vec<f64>,
    pub best_scenario: Option<Scenario>,
    pub wall_s: f64,
}

#[derive(Default)]
struct Tally {
    evaluated: usize,
    failed: usize,
    best_score: f64,
    max_divergence: f64,
    groups: BTreeSet<crate::harness::GroupKey>,
    unexplained: std::collections::BTreeMap<crate::harness::GroupKey, f64>,
    best_so_far: Vec<f64>,
    best: Option<Scenario>,
}

impl Tally {
    fn absorb(&mut self, r: &Result<EpisodeResult, DiffError>, allow: &AllowList, friction: f64) -> Option<f64> {
        self.evaluated += 1;
        let score = match r {
            Ok(r) => {
                let d = r.worst_ratio();
                let score = d / (1.0 + r.scenario.magnitude(friction));
                self.max_divergence = self.max_divergence.max(d);
                for f in &r.findings {
                    self.groups.insert(f.group_key());
                    if allow.covering(f).is_none() {
                        let r = self.unexplained.entry(f.group_key()).or_insert(0.0);
                        *r = r.max(f.ratio());
                    }
                }
                if score > self.best_score || self.best.is_none() {
                    self.best_score = score.max(self.best_score);
                    self.best = Some(r.scenario.clone());
                }
                Some(score)
            }
            Err(_) => {
                self.failed += 1;
                None
            }
        };
        self.best_so_far.push(self.best_score);
        score
    }

    fn outcome(self, method: Method, wall_s: f64) -> SearchOutcome {
        SearchOutcome {
            method,
            evaluated: self.evaluated,
            failed: self.failed,
            best_score: self.best_score,
            max_divergence: self.max_divergence,
            finding_groups: self.groups.len(),
            unexplained_groups: self.unexplained.len(),
            unexplained: self.unexplained.into_iter().map(|((k, e, q, p), r)| (k, e, q, p, r)).collect(),
            best_so_far: self.best_so_far,
            best_scenario: self.best,
            wall_s,
        }
    }
}

/// Everything a search needs besides its own settings.
pub struct SearchSetup<'a> {
    pub model: &'a RobotModel,
    pub factories: &'a [Arc<dyn EngineFactory>],
    pub controller: &'a ControllerFactory,
    pub cfg: &'a HarnessConfig,
    pub allow: &'a AllowList,
    /// The unperturbed input (a policy or excitation rollout); its seed and length are kept.
    pub base: Scenario,
}

impl std::fmt::Debug for SearchSetup<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SearchSetup").field("base", &self.base).finish_non_exhaustive()
    }
}

fn episodes(s: &SearchSetup<'_>, scenarios: &[Scenario]) -> Vec<Result<EpisodeResult, DiffError>> {
    let cfg = HarnessConfig { free_runs: false, ..s.cfg.clone() };
    scenarios.par_iter().map(|sc| harness::run_episode(s.model, s.factories, s.controller, sc, &cfg)).collect()
}

fn unexpected(r: &[Result<EpisodeResult, DiffError>]) -> Result<(), DiffError> {
    // Engine failures are counted; anything else (bad input, policy errors) stops the search.
    for x in r {
        if let Err(e) = x {
            if !matches!(e, DiffError::Engine(_) | DiffError::EngineFailed { .. }) {
                return Err(DiffError::Input(format!("search rollout failed: {e}")));
            }
        }
    }
    Ok(())
}

/// Runs one method with the budget of `c`.
pub fn search(s: &SearchSetup<'_>, method: Method, c: &SearchConfig) -> Result<SearchOutcome, DiffError> {
    if c.budget == 0 {
        return Err(DiffError::Input("search budget must be at least 1".into()));
    }
    let t0 = std::time::Instant::now();
    let friction = s.model.contact.friction;
    let mut tally = Tally::default();
    let mut rng = ChaCha8Rng::seed_from_u64(c.seed ^ 0xCE_CE);
    match method {
        Method::Random => {
            let scenarios: Vec<Scenario> = (0..c.budget)
                .map(|_| {
                    let th: Vec<f64> = (0..DIM).map(|_| rng.gen_range(-1.0..=1.0)).collect();
                    decode(&th, &s.base, friction)
                })
                .collect();
            let r = episodes(s, &scenarios);
            unexpected(&r)?;
            for x in &r {
                tally.absorb(x, s.allow, friction);
            }
        }
        Method::Cem => {
            let pop = c.population.clamp(2, c.budget.max(2));
            let n_elite = ((pop as f64 * c.elite_fraction).round() as usize).clamp(1, pop);
            let mut mean = [0.0; DIM];
            let mut std = [0.5; DIM];
            while tally.evaluated < c.budget {
                let n = pop.min(c.budget - tally.evaluated);
                let thetas: Vec<Vec<f64>> = (0..n)
                    .map(|_| {
                        (0..DIM)
                            .map(|i| {
                                // Box–Muller normal sample, clipped to the box.
                                let (u1, u2): (f64, f64) = (rng.gen_range(1e-12..1.0), rng.gen_range(0.0..1.0));
                                let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
                                (mean[i] + std[i] * z).clamp(-1.0, 1.0)
                            })
                            .collect()
                    })
                    .collect();
                let scenarios: Vec<Scenario> = thetas.iter().map(|t| decode(t, &s.base, friction)).collect();
                let r = episodes(s, &scenarios);
                unexpected(&r)?;
                let mut scored: Vec<(f64, &Vec<f64>)> = r
                    .iter()
                    .zip(&thetas)
                    .filter_map(|(x, t)| tally.absorb(x, s.allow, friction).map(|sc| (sc, t)))
                    .collect();
                scored.sort_by(|a, b| b.0.total_cmp(&a.0));
                let elites: Vec<&Vec<f64>> = scored.iter().take(n_elite).map(|x| x.1).collect();
                if elites.is_empty() {
                    continue;
                }
                // Smoothed update (α = 0.7) with a floor on σ so that the search keeps exploring.
                for i in 0..DIM {
                    let m = elites.iter().map(|e| e[i]).sum::<f64>() / elites.len() as f64;
                    let v = elites.iter().map(|e| (e[i] - m).powi(2)).sum::<f64>() / elites.len() as f64;
                    mean[i] = 0.7 * m + 0.3 * mean[i];
                    std[i] = (0.7 * v.sqrt() + 0.3 * std[i]).max(0.05);
                }
            }
        }
        Method::Mutation => {
            // The fuzzer keeps only the episodes that hold a best finding; re-score its corpus for the tally by
            // re-running nothing: its feedback is the same objective.
            let fcfg = FuzzConfig { iterations: c.budget, batch: fuzz::DEFAULT_BATCH, seed: c.seed };
            let seen = std::sync::Mutex::new(Vec::new());
            let record = |_n: usize| {};
            let o = fuzz::fuzz_with_observer(
                s.model,
                s.factories,
                s.controller,
                s.cfg,
                &fcfg,
                vec![s.base.clone()],
                &record,
                &|r: &Result<EpisodeResult, DiffError>| {
                    if let Ok(mut v) = seen.lock() {
                        v.push(match r {
                            Ok(e) => Ok(e.clone()),
                            Err(_) => Err(()),
                        });
                    }
                },
            )?;
            let all = seen.into_inner().unwrap_or_default();
            for x in all {
                let r = x.map_err(|_| DiffError::Input("engine failure".into()));
                tally.absorb(&r, s.allow, friction);
            }
            tally.failed = o.failed;
        }
    }
    Ok(tally.outcome(method, t0.elapsed().as_secs_f64()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_is_the_unperturbed_base_and_every_theta_is_valid() {
        let base = Scenario {
            pushes: vec![],
            commands: vec![],
            action_noise: 0.0,
            obs_noise: 0.0,
            timing_jitter: 0,
            init_q_offset: 0.0,
            ..Scenario::policy(3, 0.4)
        };
        let z = decode(&[0.0; DIM], &base, 1.0);
        assert_eq!(z.magnitude(1.0), 0.0);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for _ in 0..200 {
            let th: Vec<f64> = (0..DIM).map(|_| rng.gen_range(-1.5..=1.5)).collect();
            let s = decode(&th, &base, 1.0);
            assert!(s.validate().is_ok(), "{s:?}");
            assert_eq!((s.seed, s.seconds), (base.seed, base.seconds));
        }
    }
}
