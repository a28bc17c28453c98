//! `blind`: the blind campaign of the cross-engine set (issue 63).
//!
//! ```text
//! blind gen SEED FROM COUNT                     # generated scenes as JSON (what the adapters read)
//! blind campaign PYTHON ADAPTER SEED BUDGET_S OUT_DIR
//! blind replay PYTHON ADAPTER SCENE.json...     # verdict lines of saved scenes on another version
//! blind minimise PYTHON ADAPTER SCENE.json BUDGET_S OUT.json [GOOD_PYTHON]
//! blind bugs                                    # known bugs (cross set, rapier set): engine, bad, good, id
//! ```
//!
//! `campaign` generates scenes from `SEED` and runs them in batches through `PYTHON ADAPTER` (one engine
//! version) until `BUDGET_S` seconds of CPU (this process and its children) are spent. Every flagged scene is a
//! finding; the first finding of each violated invariant is minimised (greedy delta debugging: the first
//! one-step reduction that still violates the same invariant is kept, until none does). Output in `OUT_DIR`:
//! `findings.jsonl` (one line per finding), `scenes/ID.json` (flagged scenes), `scenes/ID-min.json`
//! (minimised) and `summary.json`. The campaign knows nothing of which bug the version has.
//!
//! `ADAPTER` is a Python adapter script run as `PYTHON ADAPTER BATCH.json`, or `-` for a native adapter: then
//! `PYTHON` is the adapter's executable, run as `PYTHON BATCH.json` (the Rust adapters of the rapier versions,
//! `adapters/rapier-*/src/blind.rs`). Both print the same observation lines.
//!
//! `minimise` reduces one saved scene the same way; with `GOOD_PYTHON` (another version of the same engine) a
//! reduction is kept only if it still violates the same invariant on `PYTHON` **and** is judged quiet on
//! `GOOD_PYTHON`, so the minimised scene keeps the version flip instead of drifting to a failure both share.
#![forbid(unsafe_code)]

use anyhow::{anyhow, bail, Context, Result};
use rediscovery_harness::blind::{generate, judge_world, reductions, size, Violation, World};
use rediscovery_harness::cross::{Observation, CROSS_BUGS};
use rediscovery_harness::{Verdict, BUGS};
use std::collections::{HashMap, HashSet};
use std::io::Read;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Scenes per adapter process during the search (one import of the engine per batch).
const BATCH: usize = 16;

struct Engine {
    /// Absolute: the adapter runs with its own directory as the working directory.
    python: PathBuf,
    /// `None`: `python` is a native adapter executable (ADAPTER `-`), run in the work directory.
    adapter: Option<PathBuf>,
    work: PathBuf,
    label: String,
}

impl Engine {
    fn new(python: &str, adapter: &str, work: PathBuf) -> Result<Engine> {
        // Not canonicalised: a venv's interpreter is a symlink that must keep its path.
        let python = std::path::absolute(python).with_context(|| format!("python {python}"))?;
        let adapter = if adapter == "-" {
            None
        } else {
            Some(std::fs::canonicalize(adapter).with_context(|| format!("adapter {adapter}"))?)
        };
        Ok(Engine { python, adapter, work, label: String::new() })
    }

    /// The command that runs one batch file.
    fn command(&self, batch: &std::path::Path) -> Result<Command> {
        let mut c = Command::new(&self.python);
        match &self.adapter {
            Some(a) => {
                let dir = a.parent().ok_or_else(|| anyhow!("adapter path has no directory"))?;
                c.arg(a).current_dir(dir);
            }
            None => {
                c.current_dir(&self.work);
            }
        }
        c.arg(batch);
        Ok(c)
    }
}

fn clock_ticks() -> f64 {
    Command::new("getconf")
        .arg("CLK_TCK")
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .and_then(|s| s.trim().parse::<f64>().ok())
        .unwrap_or(100.0)
}

/// CPU seconds of this process and of its waited-for children (Linux `/proc/self/stat`).
fn cpu_seconds(ticks: f64) -> f64 {
    let Ok(s) = std::fs::read_to_string("/proc/self/stat") else { return 0.0 };
    // Fields after the command name (which is in parentheses and may contain spaces).
    let rest = s.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = rest.split_whitespace().map(|x| x.parse().unwrap_or(0.0)).collect();
    // utime, stime, cutime, cstime are fields 14–17 of the line, i.e. 11–14 after the name.
    f.get(11..15).map_or(0.0, |x| x.iter().sum::<f64>() / ticks)
}

fn scene_json(scenes: &[World]) -> Result<String> {
    let mut v = Vec::with_capacity(scenes.len());
    for w in scenes {
        let mut j = serde_json::to_value(w)?;
        if let Some(o) = j.as_object_mut() {
            o.insert("kind".into(), "world".into());
        }
        v.push(j);
    }
    Ok(serde_json::to_string(&v)?)
}

/// Runs the scenes through the adapter, one process per batch; a process that dies or hangs is a verdict about
/// the scene it was running (the first one it did not report), and the rest run in a new process.
fn run(engine: &mut Engine, scenes: &[World]) -> Result<Vec<Observation>> {
    let mut out: Vec<Observation> = Vec::new();
    let mut rest: Vec<World> = scenes.to_vec();
    while !rest.is_empty() {
        let file = engine.work.join("batch.json");
        std::fs::write(&file, scene_json(&rest)?)?;
        let stderr = std::fs::File::create(engine.work.join("adapter.stderr"))?;
        let mut child = engine
            .command(&file)?
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .with_context(|| format!("cannot start {}", engine.python.display()))?;
        let mut stdout = child.stdout.take().ok_or_else(|| anyhow!("no stdout"))?;
        let reader = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = stdout.read_to_string(&mut s);
            s
        });
        // Generous: 60 s to import the engine plus 20 s per scene (a scene is at most 3 s of simulated time).
        let deadline = Instant::now() + Duration::from_secs(60 + 20 * rest.len() as u64);
        let mut timed_out = false;
        let status = loop {
            if let Some(s) = child.try_wait()? {
                break Some(s);
            }
            if Instant::now() > deadline {
                let _ = child.kill();
                timed_out = true;
                break child.wait().ok();
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let text = reader.join().map_err(|_| anyhow!("reader thread panicked"))?;
        let mut got: HashMap<String, Observation> = HashMap::new();
        for line in text.lines() {
            if let Ok(o) = serde_json::from_str::<Observation>(line) {
                if engine.label.is_empty() {
                    engine.label = o.engine.clone();
                }
                got.insert(o.scene.clone(), o);
            } else if let Ok(v) = serde_json::from_str::<serde_json::Value>(line) {
                if let Some(l) = v.get("engine").and_then(|l| l.as_str()) {
                    engine.label = l.to_string();
                }
            }
        }
        let mut next = Vec::new();
        let mut blamed = false;
        for w in rest {
            if let Some(o) = got.remove(&w.id) {
                out.push(o);
            } else if !blamed {
                blamed = true;
                let why = if timed_out {
                    "timed out".to_string()
                } else {
                    format!("process exited with {} before reporting", status.map_or("?".into(), |s| s.to_string()))
                };
                out.push(Observation {
                    engine: engine.label.clone(),
                    scene: w.id.clone(),
                    status: "crashed".into(),
                    detail: why,
                    data: None,
                });
            } else {
                next.push(w);
            }
        }
        rest = next;
    }
    Ok(out)
}

/// Greedy delta debugging: keeps the first one-step reduction that still violates `violation`, until none does
/// or the CPU budget is spent. Returns the smallest failing scene found and its verdict.
fn minimise(
    engine: &mut Engine,
    mut good: Option<&mut Engine>,
    scene: &World,
    violation: Violation,
    verdict: Verdict,
    budget_end: f64,
    ticks: f64,
) -> Result<(World, Verdict, usize)> {
    let (mut cur, mut cur_v, mut runs) = (scene.clone(), verdict, 0usize);
    let mut round = 0usize;
    'outer: while cpu_seconds(ticks) < budget_end {
        let mut cands = reductions(&cur);
        for (k, c) in cands.iter_mut().enumerate() {
            c.id = format!("{}-r{round}-{k}", scene.id);
        }
        for chunk in cands.chunks(BATCH) {
            if cpu_seconds(ticks) >= budget_end {
                break 'outer;
            }
            let obs = run(engine, chunk)?;
            runs += chunk.len();
            let still: Vec<&World> = chunk
                .iter()
                .filter(|c| {
                    obs.iter().find(|o| o.scene == c.id).is_some_and(|o| judge_world(c, o).1 == Some(violation))
                })
                .collect();
            // With a good version: of those, only the ones it runs and judges quiet.
            let keep: Vec<&World> = match good.as_deref_mut() {
                Some(g) if !still.is_empty() => {
                    let gobs = run(g, &still.iter().map(|c| (*c).clone()).collect::<Vec<_>>())?;
                    runs += still.len();
                    still
                        .into_iter()
                        .filter(|c| {
                            gobs.iter().find(|o| o.scene == c.id).is_some_and(|o| {
                                let (v, viol) = judge_world(c, o);
                                viol.is_none() && v.value.is_some()
                            })
                        })
                        .collect()
                }
                _ => still,
            };
            for c in keep {
                if let Some(o) = obs.iter().find(|o| o.scene == c.id) {
                    let (v, viol) = judge_world(c, o);
                    if viol == Some(violation) {
                        cur = c.clone();
                        cur_v = v;
                        round += 1;
                        continue 'outer;
                    }
                }
            }
        }
        break;
    }
    cur.id = format!("{}-min", scene.id);
    Ok((cur, cur_v, runs))
}

fn campaign(args: &[String]) -> Result<()> {
    let [python, adapter, seed, budget, out_dir] = args else {
        bail!("usage: blind campaign PYTHON ADAPTER SEED BUDGET_S OUT_DIR");
    };
    let seed: u64 = seed.parse().context("SEED")?;
    let budget: f64 = budget.parse().context("BUDGET_S")?;
    let out = PathBuf::from(out_dir);
    std::fs::create_dir_all(out.join("scenes"))?;
    let mut engine = Engine::new(python, adapter, out.clone())?;
    let ticks = clock_ticks();
    let t0 = cpu_seconds(ticks);
    let wall0 = Instant::now();
    let end = t0 + budget;
    let mut findings = String::new();
    let mut minimised: HashSet<Violation> = HashSet::new();
    let (mut index, mut n_ok, mut n_unsupported, mut n_flagged) = (0u64, 0usize, 0usize, 0usize);
    let mut first_finding: Option<f64> = None;
    while cpu_seconds(ticks) < end {
        let scenes: Vec<World> = (index..index + BATCH as u64).map(|i| generate(seed, i)).collect();
        index += BATCH as u64;
        let obs = run(&mut engine, &scenes)?;
        for w in &scenes {
            let Some(o) = obs.iter().find(|o| o.scene == w.id) else { continue };
            let (v, viol) = judge_world(w, o);
            match (o.status.as_str(), viol) {
                ("unsupported", _) => n_unsupported += 1,
                (_, None) => n_ok += 1,
                (_, Some(viol)) => {
                    n_flagged += 1;
                    let at = cpu_seconds(ticks) - t0;
                    first_finding.get_or_insert(at);
                    std::fs::write(
                        out.join("scenes").join(format!("{}.json", w.id)),
                        serde_json::to_string_pretty(w)?,
                    )?;
                    let mut rec = serde_json::json!({"engine": engine.label, "scene": w.id, "violation": viol,
                        "cpu_s": at, "size": size(w), "detail": v.detail});
                    if minimised.insert(viol) {
                        let (m, mv, runs) = minimise(&mut engine, None, w, viol, v, end, ticks)?;
                        let file = out.join("scenes").join(format!("{}.json", m.id));
                        std::fs::write(&file, serde_json::to_string_pretty(&m)?)?;
                        if let Some(r) = rec.as_object_mut() {
                            r.insert("min_file".into(), file.display().to_string().into());
                            r.insert("min_size".into(), size(&m).into());
                            r.insert("min_runs".into(), runs.into());
                            r.insert("min_detail".into(), mv.detail.into());
                            r.insert("cpu_s_after_min".into(), (cpu_seconds(ticks) - t0).into());
                        }
                        eprintln!(
                            "{}: {} {:?} size {} -> {} ({} runs)",
                            engine.label,
                            w.id,
                            viol,
                            size(w),
                            size(&m),
                            runs
                        );
                    }
                    findings.push_str(&serde_json::to_string(&rec)?);
                    findings.push('\n');
                }
            }
        }
        std::fs::write(out.join("findings.jsonl"), &findings)?;
    }
    let summary = serde_json::json!({"engine": engine.label, "seed": seed, "budget_cpu_s": budget,
        "cpu_s": cpu_seconds(ticks) - t0, "wall_s": wall0.elapsed().as_secs_f64(), "scenes": index,
        "judged_quiet": n_ok, "unsupported": n_unsupported, "flagged": n_flagged,
        "cpu_s_to_first_finding": first_finding});
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&summary)?)?;
    println!("{summary}");
    Ok(())
}

fn replay(args: &[String]) -> Result<()> {
    let [python, adapter, files @ ..] = args else {
        bail!("usage: blind replay PYTHON ADAPTER SCENE.json...");
    };
    let mut scenes = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(f).with_context(|| f.clone())?;
        scenes.push(serde_json::from_str::<World>(&text).with_context(|| f.clone())?);
    }
    let work = std::env::temp_dir().join(format!("blind-replay-{}", std::process::id()));
    std::fs::create_dir_all(&work)?;
    let mut engine = Engine::new(python, adapter, work.clone())?;
    let obs = run(&mut engine, &scenes)?;
    for w in &scenes {
        if let Some(o) = obs.iter().find(|o| o.scene == w.id) {
            let (v, viol) = judge_world(w, o);
            println!("{}", serde_json::json!({"verdict": v, "violation": viol}));
        }
    }
    let _ = std::fs::remove_dir_all(work);
    Ok(())
}

fn minimise_one(args: &[String]) -> Result<()> {
    let [python, adapter, file, budget, out, good @ ..] = args else {
        bail!("usage: blind minimise PYTHON ADAPTER SCENE.json BUDGET_S OUT.json [GOOD_PYTHON]");
    };
    let budget: f64 = budget.parse().context("BUDGET_S")?;
    let text = std::fs::read_to_string(file).with_context(|| file.clone())?;
    let scene: World = serde_json::from_str(&text).with_context(|| file.clone())?;
    let work = std::env::temp_dir().join(format!("blind-minimise-{}", std::process::id()));
    std::fs::create_dir_all(work.join("good"))?;
    let mut engine = Engine::new(python, adapter, work.clone())?;
    let mut good_engine = match good {
        [] => None,
        [g] => Some(Engine::new(g, adapter, work.join("good"))?),
        _ => bail!("at most one GOOD_PYTHON"),
    };
    let ticks = clock_ticks();
    let end = cpu_seconds(ticks) + budget;
    let obs = run(&mut engine, std::slice::from_ref(&scene))?;
    let o = obs.first().ok_or_else(|| anyhow!("no observation of {}", scene.id))?;
    let (v, viol) = judge_world(&scene, o);
    let Some(viol) = viol else { bail!("{} is not flagged on {}: {}", scene.id, engine.label, v.detail) };
    let (m, mv, runs) = minimise(&mut engine, good_engine.as_mut(), &scene, viol, v, end, ticks)?;
    std::fs::write(out, serde_json::to_string_pretty(&m)?)?;
    println!(
        "{}",
        serde_json::json!({"engine": engine.label, "scene": scene.id, "violation": viol, "size": size(&scene),
            "min_size": size(&m), "runs": runs, "detail": mv.detail, "out": out})
    );
    let _ = std::fs::remove_dir_all(work);
    Ok(())
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("gen") => {
            let [seed, from, count] = &args[1..] else { bail!("usage: blind gen SEED FROM COUNT") };
            let (seed, from, count): (u64, u64, u64) = (seed.parse()?, from.parse()?, count.parse()?);
            let scenes: Vec<World> = (from..from + count).map(|i| generate(seed, i)).collect();
            println!("{}", scene_json(&scenes)?);
        }
        Some("campaign") => campaign(&args[1..])?,
        Some("replay") => replay(&args[1..])?,
        Some("minimise") => minimise_one(&args[1..])?,
        Some("bugs") => {
            for b in CROSS_BUGS {
                println!("{}\t{}\t{}\t{}", b.engine, b.last_bad, b.first_good, b.id);
            }
            // The rapier set's bugs (engine label "rapier3d VERSION" of the Rust adapters).
            for b in BUGS {
                println!("rapier3d\t{}\t{}\t{}", b.last_bad, b.first_good, b.id);
            }
        }
        _ => bail!("usage: blind gen|campaign|replay|minimise|bugs ... (see the source's header)"),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(c: &Command) -> Vec<String> {
        c.get_args().map(|a| a.to_string_lossy().into_owned()).collect()
    }

    #[test]
    fn a_native_adapter_gets_only_the_batch_file_and_a_script_gets_both() -> Result<()> {
        let work = std::env::temp_dir();
        let batch = work.join("batch.json");
        let native = Engine::new("/bin/true", "-", work.clone())?;
        let c = native.command(&batch)?;
        assert_eq!(args(&c), vec![batch.display().to_string()]);
        assert_eq!(c.get_current_dir(), Some(work.as_path()));
        // A script: the interpreter gets the script, then the batch, and runs in the script's directory.
        let script = std::fs::canonicalize(file!()).or_else(|_| std::fs::canonicalize("src/bin/blind.rs"))?;
        let py = Engine::new("/bin/true", &script.display().to_string(), work)?;
        let c = py.command(&batch)?;
        assert_eq!(args(&c), vec![script.display().to_string(), batch.display().to_string()]);
        assert_eq!(c.get_current_dir(), script.parent());
        // A missing script is an error, never taken for a native adapter.
        assert!(Engine::new("/bin/true", "no-such-adapter.py", std::env::temp_dir()).is_err());
        Ok(())
    }
}
