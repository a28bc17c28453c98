//! Feedback-driven search over perturbations: a corpus of scenarios is mutated and scheduled by divergence
//! per unit of perturbation and by new contact patterns, evaluated in parallel (rayon).
use crate::harness::{self, ControllerFactory, EngineFactory, EngineFailure, EpisodeResult, HarnessConfig};
use crate::scenario::Scenario;
use crate::triage::AllowList;
use crate::DiffError;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use robot_model::RobotModel;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;

/// Fuzzing settings.
#[derive(Debug, Clone)]
pub struct FuzzConfig {
    /// Inputs evaluated in total.
    pub iterations: usize,
    /// Inputs evaluated per round (in parallel); the corpus takes their feedback after each round.
    pub batch: usize,
    pub seed: u64,
}

/// Inputs per round when nothing else is asked for: a constant, not the thread count, so that a campaign draws the
/// same inputs and finds the same results on any machine and with any `--jobs` (a round's inputs run in parallel on
/// whatever threads there are). Four keeps two cores busy while the corpus still learns every four inputs.
pub const DEFAULT_BATCH: usize = 4;

/// A corpus entry with its feedback.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CorpusEntry {
    pub scenario: Scenario,
    /// Largest bound ratio over the rollout (one-step divergence, findings).
    pub divergence: f64,
    pub magnitude: f64,
    /// `divergence / (1 + magnitude)`: what the search maximises.
    pub score: f64,
    pub patterns: Vec<String>,
}

/// What a fuzzing run (or one lane of a campaign) found; a sharded `ulab diff fuzz` stores it per lane.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FuzzOutcome {
    pub corpus: Vec<CorpusEntry>,
    /// For every finding group, the episode with the best score in which it occurred.
    pub episodes: Vec<EpisodeResult>,
    pub evaluated: usize,
    pub failed: usize,
    pub patterns: BTreeSet<String>,
    /// The inputs on which an engine failed, in the order they were evaluated (candidate engine bugs).
    #[serde(default)]
    pub failures: Vec<EngineFailure>,
}

/// Seed of lane `lane` of a campaign seeded `seed`. A campaign of several lanes is that many independent fuzzers
/// (what lets its lanes run on different machines and still give one result); lane 0 keeps the campaign's seed, so a
/// one-lane campaign is the plain fuzzer, and the others are 2^32 apart, so nearby campaign seeds share no lane.
pub fn lane_seed(seed: u64, lane: usize) -> u64 {
    seed.wrapping_add((lane as u64) << 32)
}

/// Inputs of lane `lane` when a campaign spreads `iterations` over `lanes`: as even as possible, the first lanes
/// one more.
pub fn lane_iterations(iterations: usize, lanes: usize, lane: usize) -> usize {
    let lanes = lanes.max(1);
    iterations / lanes + usize::from(lane < iterations % lanes)
}

/// A campaign's outcome from its lanes' outcomes in lane order: every lane's episodes in lane order, the corpora
/// together ordered by score (equal scores in lane order), counts summed, contact patterns united. One lane gives
/// that lane's outcome unchanged.
pub fn combine_lanes(lanes: Vec<FuzzOutcome>) -> FuzzOutcome {
    let mut all = FuzzOutcome {
        corpus: Vec::new(),
        episodes: Vec::new(),
        evaluated: 0,
        failed: 0,
        patterns: BTreeSet::new(),
        failures: Vec::new(),
    };
    for lane in lanes {
        all.corpus.extend(lane.corpus);
        all.episodes.extend(lane.episodes);
        all.evaluated += lane.evaluated;
        all.failed += lane.failed;
        all.failures.extend(lane.failures);
        all.patterns.extend(lane.patterns);
    }
    // Stable: each lane's corpus is already in score order.
    all.corpus.sort_by(|a, b| b.score.total_cmp(&a.score));
    all
}

fn entry_of(r: &EpisodeResult, friction: f64) -> CorpusEntry {
    let divergence = r.worst_ratio();
    let magnitude = r.scenario.magnitude(friction);
    CorpusEntry {
        scenario: r.scenario.clone(),
        divergence,
        magnitude,
        score: divergence / (1.0 + magnitude),
        patterns: r.contact_patterns.iter().cloned().collect(),
    }
}

/// Runs the search. `progress(done)` is called after every evaluated input.
pub fn fuzz(
    model: &RobotModel,
    factories: &[Arc<dyn EngineFactory>],
    ctrl: &ControllerFactory,
    cfg: &HarnessConfig,
    fcfg: &FuzzConfig,
    seeds: Vec<Scenario>,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<FuzzOutcome, DiffError> {
    fuzz_with_observer(model, factories, ctrl, cfg, fcfg, seeds, progress, &|_| {})
}

/// [`fuzz`], also handing every evaluated rollout to `observe` (the search comparison tallies them all).
#[allow(clippy::too_many_arguments)]
pub fn fuzz_with_observer(
    model: &RobotModel,
    factories: &[Arc<dyn EngineFactory>],
    ctrl: &ControllerFactory,
    cfg: &HarnessConfig,
    fcfg: &FuzzConfig,
    seeds: Vec<Scenario>,
    progress: &(dyn Fn(usize) + Sync),
    observe: &(dyn Fn(&Result<EpisodeResult, DiffError>) + Sync),
) -> Result<FuzzOutcome, DiffError> {
    if seeds.is_empty() {
        return Err(DiffError::Input("fuzzing needs at least one seed scenario".into()));
    }
    let cfg = HarnessConfig { free_runs: false, ..cfg.clone() };
    let friction = model.contact.friction;
    let mut rng = ChaCha8Rng::seed_from_u64(fcfg.seed);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let eval = |s: &Scenario| {
        let r = harness::run_episode(model, factories, ctrl, s, &cfg);
        observe(&r);
        progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
        r
    };
    let mut corpus: Vec<CorpusEntry> = Vec::new();
    let mut patterns = BTreeSet::new();
    let mut best: BTreeMap<crate::harness::GroupKey, (f64, usize)> = BTreeMap::new();
    let mut kept: Vec<EpisodeResult> = Vec::new();
    let mut failed = 0;
    let mut absorb =
        |r: EpisodeResult, corpus: &mut Vec<CorpusEntry>, parent_score: f64, patterns: &mut BTreeSet<String>| {
            let e = entry_of(&r, friction);
            let novel = r.contact_patterns.iter().any(|p| !patterns.contains(p));
            patterns.extend(r.contact_patterns.iter().cloned());
            if novel || e.score > parent_score || corpus.is_empty() {
                corpus.push(e.clone());
            }
            // Keep the episode if it holds the best-per-unit instance of some finding group.
            let mut useful = false;
            for f in &r.findings {
                let per_unit = f.ratio() / (1.0 + e.magnitude);
                let slot = best.entry(f.group_key()).or_insert((f64::NEG_INFINITY, usize::MAX));
                if per_unit > slot.0 {
                    *slot = (per_unit, kept.len());
                    useful = true;
                }
            }
            if useful {
                kept.push(r);
            }
        };
    let mut failures = Vec::new();
    let mut fail = |e: DiffError, s: &Scenario| -> Result<(), DiffError> {
        match e {
            DiffError::EngineFailed { engine, t, source } => {
                failures.push(EngineFailure { engine, t, error: source.to_string(), scenario: s.clone() })
            }
            DiffError::Engine(_) => {}
            e => return Err(e),
        }
        failed += 1;
        Ok(())
    };
    let first: Vec<Result<EpisodeResult, DiffError>> = seeds.par_iter().map(&eval).collect();
    let mut evaluated = first.len();
    for (r, s) in first.into_iter().zip(&seeds) {
        match r {
            Ok(r) => absorb(r, &mut corpus, f64::NEG_INFINITY, &mut patterns),
            Err(e) => fail(e, s)?,
        }
    }
    while evaluated < fcfg.iterations.max(seeds.len()) && !corpus.is_empty() {
        let n = fcfg.batch.max(1).min(fcfg.iterations.saturating_sub(evaluated).max(1));
        // Parents by weight 1 + score (capped); novelty acts through admission: an input that brings a new contact
        // pattern joins the corpus whatever its score.
        let weights: Vec<f64> = corpus.iter().map(|c| 1.0 + c.score.min(100.0)).collect();
        let total: f64 = weights.iter().sum();
        let mut children = Vec::new();
        for _ in 0..n {
            let mut x = rng.gen_range(0.0..total);
            let mut pi = 0;
            for (i, w) in weights.iter().enumerate() {
                if x < *w {
                    pi = i;
                    break;
                }
                x -= w;
            }
            let mut child = corpus[pi].scenario.clone();
            for _ in 0..rng.gen_range(1..=3) {
                child.mutate(&mut rng);
            }
            children.push((corpus[pi].score, child));
        }
        let results: Vec<(f64, Result<EpisodeResult, DiffError>)> =
            children.par_iter().map(|(ps, c)| (*ps, eval(c))).collect();
        evaluated += results.len();
        for ((ps, r), (_, c)) in results.into_iter().zip(&children) {
            match r {
                Ok(r) => absorb(r, &mut corpus, ps, &mut patterns),
                Err(e) => fail(e, c)?,
            }
        }
    }
    // Only the episodes that still hold a best instance.
    let keep: BTreeSet<usize> = best.values().map(|v| v.1).collect();
    let episodes = kept.into_iter().enumerate().filter(|(i, _)| keep.contains(i)).map(|(_, e)| e).collect();
    corpus.sort_by(|a, b| b.score.total_cmp(&a.score));
    Ok(FuzzOutcome { corpus, episodes, evaluated, failed, patterns, failures })
}

/// The oracle of the `engine_divergence` cargo-fuzz target: per-engine invariants plus the one-step
/// cross-engine bound, with the allow-list applied (translation checks are left to `ulab diff`). Returns
/// the findings that are neither allow-listed nor within their bounds.
pub fn oracle_findings(result: &EpisodeResult, allow: &AllowList) -> Vec<harness::Finding> {
    result.findings.iter().filter(|f| f.kind != "k_step_bound" && allow.covering(f).is_none()).cloned().collect()
}

/// The whole check of the `engine_divergence` cargo-fuzz target, kept here so that `cargo test` replays the
/// saved inputs (`fuzz/corpus/engine_divergence/{regressions,seeds}/`) through exactly what the fuzzer runs.
/// The input chooses the pair of engines ([`oracle_pair`]). Engines are built once per kind and ground friction
/// and reset per input (`Engine::reset` is a true reset), because building them dominates a 40 ms rollout.
pub struct DivergenceOracle {
    model: RobotModel,
    allow: AllowList,
    ctrl: Box<ControllerFactory>,
    friction_bits: Option<u64>,
    engines: BTreeMap<usize, Box<dyn diff_physics::Engine>>,
}

impl std::fmt::Debug for DivergenceOracle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DivergenceOracle").field("pairs", &oracle_pairs()).finish_non_exhaustive()
    }
}

/// Rollout length per input: two 50 Hz control ticks.
pub const ORACLE_SECONDS: f64 = 0.04;

/// The pairs the fuzz target compares: every pair of the engines of this build, lead first. The pairs with
/// MuJoCo (the reference: the lead of `ulab diff`, against which every allow-list entry is written and
/// measured) come first (MuJoCo is first in [`diff_physics::EngineKind::ALL`]), so the first pair is MuJoCo against Rapier
/// multibody; then every other pair, the earlier engine of `ALL` leading. A pair without the reference is judged
/// through it ([`crate::triage::Cover::ViaReference`]): its allowance is the sum of what each engine may differ
/// from MuJoCo, and its rollout follows the other lead's dynamics into states MuJoCo-led runs never reach.
pub fn oracle_pairs() -> Vec<[diff_physics::EngineKind; 2]> {
    let kinds = diff_physics::EngineKind::available();
    let mut pairs: Vec<[diff_physics::EngineKind; 2]> = Vec::new();
    for (i, &a) in kinds.iter().enumerate() {
        pairs.extend(kinds[i + 1..].iter().map(|&b| [a, b]));
    }
    pairs
}

/// The pair an input's `engines` byte chooses: `byte % pairs`. Byte 0 is the first pair (MuJoCo against Rapier
/// multibody): an input too short to carry the byte decodes it as 0 and runs on the reference pair, in every
/// build. `None` with fewer than two engines.
pub fn oracle_pair(choice: u8) -> Option<[diff_physics::EngineKind; 2]> {
    let pairs = oracle_pairs();
    (!pairs.is_empty()).then(|| pairs[usize::from(choice) % pairs.len()])
}

fn kind_index(k: diff_physics::EngineKind) -> usize {
    diff_physics::EngineKind::ALL.iter().position(|&x| x == k).unwrap_or(usize::MAX)
}

impl DivergenceOracle {
    /// The built-in H1-2 under the built-in excitation controller and allow-list.
    pub fn h1_2() -> Result<Self, DiffError> {
        if oracle_pairs().is_empty() {
            return Err(DiffError::Input(format!(
                "the divergence oracle needs two engines; this build has {}",
                diff_physics::EngineKind::available_names()
            )));
        }
        let model = RobotModel::h1_2()?;
        Ok(DivergenceOracle {
            allow: AllowList::builtin()?,
            ctrl: harness::excitation_factory(&model),
            friction_bits: None,
            engines: BTreeMap::new(),
            model,
        })
    }

    /// Runs one perturbation (two windows of 10 steps) on the pair of engines it chooses and returns the
    /// findings that are neither allow-listed nor within bounds: each one is a candidate engine bug. An engine
    /// error on a valid input is returned as the error.
    pub fn check(&mut self, p: &crate::scenario::FuzzPerturbation) -> Result<Vec<harness::Finding>, DiffError> {
        let pair = oracle_pair(p.engines).ok_or_else(|| DiffError::Input("fewer than two engines".into()))?;
        self.check_pair(p, pair)
    }

    /// [`DivergenceOracle::check`] on a given pair (lead first), whatever the input's choice.
    pub fn check_pair(
        &mut self,
        p: &crate::scenario::FuzzPerturbation,
        pair: [diff_physics::EngineKind; 2],
    ) -> Result<Vec<harness::Finding>, DiffError> {
        let all = self.findings_on_pair(p, pair)?;
        Ok(all.into_iter().filter(|f| self.allow.covering(f).is_none()).collect())
    }

    /// Every finding the oracle judges (invariants and one-step bounds) on a given pair, before the allow-list:
    /// what the allow-list's caps are measured on.
    pub fn findings_on_pair(
        &mut self,
        p: &crate::scenario::FuzzPerturbation,
        pair: [diff_physics::EngineKind; 2],
    ) -> Result<Vec<harness::Finding>, DiffError> {
        let s = p.scenario(ORACLE_SECONDS);
        let m = harness::scenario_model(&self.model, &s);
        let key = s.ground_friction.map(f64::to_bits);
        if key != self.friction_bits {
            self.engines.clear();
            self.friction_bits = key;
        }
        let mut engines = Vec::with_capacity(2);
        for k in pair {
            let e = match self.engines.remove(&kind_index(k)) {
                Some(e) => e,
                None => diff_physics::make_engine(k, &m, &diff_physics::CommonSettings::default())?,
            };
            engines.push(e);
        }
        let names: Vec<String> = pair.iter().map(|k| k.name().to_string()).collect();
        let cfg = HarnessConfig { window_steps: 10, free_runs: false, ..HarnessConfig::default() };
        let r = harness::run_episode_on(&mut engines, &names, &m, self.ctrl.as_ref(), &s, &cfg);
        for (k, e) in pair.into_iter().zip(engines) {
            self.engines.insert(kind_index(k), e);
        }
        Ok(r?.findings.into_iter().filter(|f| f.kind != "k_step_bound").collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_share_the_iterations_evenly_and_lane_zero_keeps_the_seed() {
        for (iterations, lanes) in [(10, 3), (3, 3), (7, 1), (32, 5)] {
            let each: Vec<usize> = (0..lanes).map(|k| lane_iterations(iterations, lanes, k)).collect();
            assert_eq!(each.iter().sum::<usize>(), iterations, "{each:?}");
            assert!(each.iter().max().unwrap_or(&0) - each.iter().min().unwrap_or(&0) <= 1, "{each:?}");
        }
        assert_eq!(lane_seed(5, 0), 5);
        assert!((0..4).all(|k| (1..4).all(|d| lane_seed(5, k) != lane_seed(5 + d, 0))));
    }
}
