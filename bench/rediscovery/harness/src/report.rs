//! Markdown tables from the verdict lines the engine binaries print.

use crate::{Verdict, BUGS};
use std::fmt::Write as _;

/// Parses JSON verdict lines (blank lines are skipped).
pub fn parse_lines(text: &str) -> Result<Vec<Verdict>, serde_json::Error> {
    text.lines().filter(|l| !l.trim().is_empty()).map(serde_json::from_str).collect()
}

fn cell(v: &Verdict) -> String {
    let value = v.value.map_or_else(
        || "n/a".to_string(),
        |x| if x != 0.0 && x.abs() < 1e-3 { format!("{x:.1e}") } else { format!("{x:.3}") },
    );
    let word = if v.flagged { "**FLAGGED**" } else { "quiet" };
    if v.value.is_none() && !v.flagged {
        "n/a (analytic reference)".to_string()
    } else {
        format!("{value} → {word}")
    }
}

fn find<'a>(all: &'a [Verdict], engine: &str, bug: &str) -> Option<&'a Verdict> {
    all.iter().find(|v| v.engine == engine && v.bug == bug)
}

/// The headline table (one row per bug: last-bad and first-good versions), then the full matrix of
/// every engine on every scene.
pub fn markdown(all: &[Verdict], reference_engine: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "| bug | scene | metric | threshold | {reference_engine} | last bad | verdict | first good | verdict | scene runtime bad / good (ms) | versions from |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
    for bug in &BUGS {
        let bad_engine = format!("rapier3d {}", bug.last_bad);
        let good_engine = format!("rapier3d {}", bug.first_good);
        let bad = find(all, &bad_engine, bug.id);
        let good = find(all, &good_engine, bug.id);
        let reference = find(all, reference_engine, bug.id);
        let (metric, threshold) =
            bad.or(good).map_or(("?".to_string(), "?".to_string()), |v| (v.metric.clone(), v.threshold.clone()));
        let show = |v: Option<&Verdict>| v.map_or("not run".to_string(), cell);
        let ms = |v: Option<&Verdict>| v.map_or("-".to_string(), |v| format!("{:.0}", v.runtime_ms));
        let _ = writeln!(
            s,
            "| [{}]({}) | `{}` | {} | {} | {} | {} | {} | {} | {} | {} / {} | {} |",
            bug.id,
            bug.url,
            bug.scene,
            metric,
            threshold,
            show(reference),
            bug.last_bad,
            show(bad),
            bug.first_good,
            show(good),
            ms(bad),
            ms(good),
            bug.note
        );
    }
    // The cross-engine set (MuJoCo, Bullet, DART versions from their wheels), judged by the project's invariants.
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "| bug | engine | scene | oracle (invariant) | threshold | other engines on the scene | last bad | verdict | first good | verdict | versions from |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
    for bug in &crate::cross::CROSS_BUGS {
        let bad = find(all, &format!("{} {}", bug.engine, bug.last_bad), bug.id);
        let good = find(all, &format!("{} {}", bug.engine, bug.first_good), bug.id);
        let (metric, threshold) =
            bad.or(good).map_or(("?".to_string(), "?".to_string()), |v| (v.metric.clone(), v.threshold.clone()));
        let others: Vec<String> = all
            .iter()
            .filter(|v| v.bug == bug.id && !v.engine.starts_with(bug.engine) && !v.detail.starts_with("not run"))
            .map(|v| format!("{}: {}", v.engine, cell(v)))
            .collect();
        let show = |v: Option<&Verdict>| v.map_or("not run".to_string(), cell);
        let _ = writeln!(
            s,
            "| [{}]({}) | {} | `{}` | {} | {} | {} | {} | {} | {} | {} | {} |",
            bug.id,
            bug.url,
            bug.engine,
            bug.scene,
            metric,
            threshold,
            if others.is_empty() { "-".to_string() } else { others.join("; ") },
            bug.last_bad,
            show(bad),
            bug.first_good,
            show(good),
            bug.note
        );
    }
    // Every cross-set version on every cross-set bug (when each bug appears and disappears).
    let mut cross_engines: Vec<&str> = Vec::new();
    for v in all {
        let cross = crate::cross::CROSS_BUGS.iter().any(|b| b.id == v.bug);
        if cross && !v.detail.starts_with("not run") && !cross_engines.contains(&v.engine.as_str()) {
            cross_engines.push(&v.engine);
        }
    }
    let _ = writeln!(s);
    let _ = write!(s, "| bug |");
    for e in &cross_engines {
        let _ = write!(s, " {e} |");
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "|---|{}", "---|".repeat(cross_engines.len()));
    for bug in &crate::cross::CROSS_BUGS {
        let _ = write!(s, "| {} |", bug.id);
        for e in &cross_engines {
            let c = find(all, e, bug.id).filter(|v| !v.detail.starts_with("not run")).map_or("-".to_string(), |v| {
                if v.flagged {
                    "**F**".to_string()
                } else {
                    "q".to_string()
                }
            });
            let _ = write!(s, " {c} |");
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "(F: flagged, q: quiet, -: scene not run on that engine.)");
    let found = BUGS
        .iter()
        .map(|b| (format!("rapier3d {}", b.last_bad), format!("rapier3d {}", b.first_good), b.id))
        .chain(
            crate::cross::CROSS_BUGS
                .iter()
                .map(|b| (format!("{} {}", b.engine, b.last_bad), format!("{} {}", b.engine, b.first_good), b.id)),
        )
        .filter(|(bad, good, id)| {
            find(all, bad, id).is_some_and(|v| v.flagged) && find(all, good, id).is_some_and(|v| !v.flagged)
        })
        .count();
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "Rediscovered (flagged on the last bad version, quiet on the first good one): {found} of {}.",
        BUGS.len() + crate::cross::CROSS_BUGS.len()
    );
    let mut engines: Vec<&str> = Vec::new();
    for v in all {
        let rapier_set = v.engine.starts_with("rapier3d") || v.engine == reference_engine;
        if rapier_set && !engines.contains(&v.engine.as_str()) {
            engines.push(&v.engine);
        }
    }
    let _ = writeln!(s);
    let _ = write!(s, "| bug |");
    for e in &engines {
        let _ = write!(s, " {e} |");
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "|---|{}", "---|".repeat(engines.len()));
    for bug in &BUGS {
        let _ = write!(s, "| {} |", bug.id);
        for e in &engines {
            let _ = write!(s, " {} |", find(all, e, bug.id).map_or("-".to_string(), cell));
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "Details:");
    let _ = writeln!(s);
    for v in all {
        let _ = writeln!(s, "- {} {}: {}", v.engine, v.bug, v.detail);
    }
    s
}
