//! Report outputs: `report.md`, `report.json` and SVG plots (plotters, SVG backend).
use crate::diagnose::{Report, Share};
use crate::GapError;
use plotters::prelude::*;
use std::path::Path;

fn est(e: &crate::diagnose::Estimate) -> String {
    format!("{:.3} [{:.3}, {:.3}]", e.value, e.lo, e.hi)
}

fn share_table(title: &str, v: &[Share], top: usize) -> String {
    let mut s = format!("### {title}\n\n| where | mean residual | share |\n|---|---|---|\n");
    for x in v.iter().take(top) {
        s += &format!("| {} | {:.3} | {:.1} % |\n", x.name, x.residual, 100.0 * x.share);
    }
    s + "\n"
}

/// The human-readable report.
pub fn markdown(r: &Report) -> String {
    let mut s = format!("# Sim-to-real gap diagnosis ({})\n\n", r.robot);
    let floating = r.plant == crate::diagnose::PlantKind::Floating;
    let plant = if floating {
        "on flat ground (floating base, plant `floating`)"
    } else {
        "on the suspension rig (plant `rig`)"
    };
    s += &format!(
        "Simulator: `{}` {plant}. Log: {:.1} s; {} training and {} held-out windows of {:.3} s. \
         Gap metric = mean normalised squared residual per window (q / 2 mrad, dq / 0.1 rad/s, tau / 1 % of the limit, IMU), \
         summed over joints and the IMU.\n\n",
        r.engine, r.log_duration_s, r.windows_train, r.windows_held_out, r.window_s
    );
    if floating {
        s += &format!(
            "Windows: settled starts only. Each window starts from a pelvis state estimated from the log (torso IMU through \
             the joint kinematics; height and velocity from the feet in contact, assumed on flat ground at rest), moved \
             to the first sample where every foot in contact has been so for {:.2} s: inside a touchdown transient the \
             estimate is 10-15 times worse. {} nominal window starts had no settled sample within one window and were dropped.\n\n",
            crate::floating::SETTLE_S,
            r.windows_unsettled
        );
        if r.windows_down > 0 {
            s += &format!(
                "**The robot was down** (pelvis tilted beyond {:.0} deg or lower than {} m) in {} nominal windows; they were \
                 dropped (the plant models a robot on its feet). The diagnosis uses the windows before and between.\n\n",
                crate::floating::FALLEN_TILT.to_degrees(),
                crate::floating::FALLEN_HEIGHT,
                r.windows_down
            );
        }
    }
    if r.windows_skipped_fraction > 0.0 {
        s += &format!(
            "{:.1} % of the possible windows were not used (no command in the last 0.1 s, or irregular state timing: log times straying more than 5 ms from a regular grid).\n\n",
            100.0 * r.windows_skipped_fraction
        );
    }
    s += &format!("**Baseline held-out gap metric:** {}\n\n", est(&r.baseline_metric));
    s += "## Verdict\n\n";
    if r.outcome == crate::diagnose::Outcome::RigAssumptionViolated {
        let c = &r.rig_check;
        s += &format!(
            "**Rig assumption violated — {}.** Every effect abstained: the diagnosis replays the log on a robot whose \
             pelvis is held still, and this log's torso IMU does not follow its joints as it would on such a rig. \
             A standing or walking robot's log is diagnosed on the floating base with `--plant auto` (the default) or `--plant floating`.\n\n",
            c.message
        );
        s += &format!(
            "| check | deviation beyond the rig's prediction (95th percentile / max) | threshold | noise sd (estimated) |\n|---|---|---|---|\n\
             | orientation | {:.2} / {:.2} deg | {:.2} deg | {:.4} deg |\n\
             | gyroscope | {:.3} / {:.3} rad/s | {:.3} rad/s | {:.4} rad/s |\n\
             | accelerometer | {} | {:.2} m/s² | {:.3} m/s² |\n\n\
             Samples beyond a threshold: {:.1} % (allowed {:.0} %). Constants removed first (what the library fits): rotation {:.2} deg, \
             gyroscope offset {:.3} rad/s.\n",
            c.p95_orientation_deg,
            c.max_orientation_deg,
            c.threshold_orientation_rad.to_degrees(),
            c.noise_orientation_rad.to_degrees(),
            c.p95_gyro_rad_s,
            c.max_gyro_rad_s,
            c.threshold_gyro_rad_s,
            c.noise_gyro_rad_s,
            if c.acc_checked { format!("{:.2} m/s² (95th percentile)", c.p95_acc_m_s2) } else { "not checked (all-zero in the log)".into() },
            c.threshold_acc_m_s2,
            c.noise_acc_m_s2,
            100.0 * c.violating_fraction,
            100.0 * crate::rig_check::MAX_VIOLATING_FRACTION,
            nalgebra::Vector3::from(c.constant_rotation_rad).norm().to_degrees(),
            nalgebra::Vector3::from(c.constant_gyro_rad_s).norm(),
        );
        return s;
    }
    s += &format!("Rig-assumption check: {}.\n\n", r.rig_check.message);
    s += &replay_section(r);
    if r.unexplained {
        let why = r.steps.last().map_or(String::new(), |st| format!(" ({})", st.reason));
        s += &format!("**No effect is named: the gap is unexplained** by the effect library (abstention){why}.\n\n");
    } else {
        let names: Vec<String> = r
            .effects
            .iter()
            .filter(|e| e.named)
            .map(|e| {
                let p: Vec<String> = e.params.iter().map(|p| format!("{} = {:.4}", p.unit, p.value)).collect();
                format!("{} ({})", e.kind.name(), p.join(", "))
            })
            .collect();
        s += &format!("Named effects, in the order the judge chose them: **{}**.\n\n", names.join("; "));
        if let Some(c) = &r.best_combination {
            s += &format!(
                "Together they leave a held-out metric of {} (relative reduction {}).\n\n",
                est(&c.metric_after),
                est(&c.reduction)
            );
        }
        if let Some(st) = r.steps.last() {
            s += &format!("The selection stopped: {}.\n\n", st.reason);
        }
    }
    for set in &r.ambiguous {
        let members: Vec<String> =
            set.effects.iter().zip(&set.units).map(|(k, u)| format!("{} on {u}", k.name())).collect();
        let how: Vec<String> = set.effects.iter().map(|k| format!("{}: {}", k.name(), k.revealed_by())).collect();
        s += &format!(
            "**This log cannot tell apart {}**; the motion that would: {}.\n\n",
            members.join(" and "),
            how.join("; ")
        );
    }
    s += "## Where the gap lies (baseline)\n\n";
    s += &share_table("By joint group", &r.by_group, 10);
    s += &share_table("By joint (top 10)", &r.by_joint, 10);
    let phase_title = if floating {
        "By phase (foot contact from the kinematic stance estimate; impact: a touchdown within the window)"
    } else {
        "By phase (foot contact estimated from knee torque)"
    };
    s += &share_table(phase_title, &r.by_phase, 10);
    s += &share_table("By frequency band (joint position residual)", &r.by_band, 10);
    s += &judge_section(r);
    s += "\n### Abstentions\n\n";
    for (k, why) in &r.abstentions {
        s += &format!("- {}: {}\n", k.name(), why);
    }
    if !r.ceilings_in_log.is_empty() {
        let rows: Vec<String> = r
            .ceilings_in_log
            .iter()
            .map(|c| {
                format!(
                    "{} at {:.2} of its limit ({} samples held, {:.2} followed below, logged torque {} state \
                     sample(s) behind the demand, of the command {} state sample(s) earlier)",
                    c.joint, c.scale, c.pinned, c.follow, c.lag_samples, c.command_delay_samples
                )
            })
            .collect();
        s += &format!(
            "\nTorque plateaus the log shows (the logged torque held below the nominal limit while the PD law of the \
             log's command asked for more; a measurement, for the reader to weigh): {}.\n",
            rows.join(", ")
        );
    }
    s += &identifiability_section(r);
    s += &numerics_section(r);
    s += &remainder_section(r);
    let stages: Vec<String> = r.stages.iter().map(|t| format!("{} {:.1} s", t.stage, t.s)).collect();
    let stages = if stages.is_empty() { String::new() } else { format!(" ({})", stages.join(", ")) };
    s += &format!("\nDiagnosis time: {:.1} s{stages}. Plots: `by_joint.svg`, `effects.svg`.\n", r.elapsed_s);
    s
}

/// How the log was replayed: its timing and the simulator's numerics, settled before the judge.
fn replay_section(r: &Report) -> String {
    let mut s = String::new();
    if let Some(t) = &r.timing {
        s += &format!(
            "Timing: states every {:.1} ms, commands every {:.1} ms; {}.\n\n",
            1e3 * t.state_period_s,
            1e3 * t.command_period_s,
            t.finding
        );
    }
    if let Some(n) = &r.numerics {
        if !n.finding.is_empty() {
            s += &format!("Numerics: {}.\n\n", n.finding);
        }
    }
    s
}

/// The judge's decision model and its steps.
fn judge_section(r: &Report) -> String {
    let th = &r.thresholds;
    let mut s = format!(
        "## How the judge decided (held-out windows)\n\nAt each step every effect of the library not yet named is \
         fitted on every unit (each limb, each joint, the robot, the IMU) on the training windows with the named \
         effects applied; the most promising are replayed on the held-out windows. The candidate with the largest \
         held-out log-likelihood gain per window (each joint's and each window's residual weighed by its own size) is \
         named when its {:.0} % interval excludes 0 and, over the windows where it acts (where its replay differs from \
         the replay without it), the interval's lower bound reaches {}, its size is at least {:.0} % of the size the \
         library resolves, and no valid candidate acting on the same joints has a gain the log cannot rank below it; at \
         most {} effects. Thresholds and their reasons: `docs/gap/method.md`.\n\n",
        100.0 * th.confidence,
        th.min_gain,
        100.0 * th.min_size,
        th.max_effects
    );
    for (i, st) in r.steps.iter().enumerate() {
        s += &format!("### Step {}\n\n{}.\n\n", i + 1, st.reason);
        if st.candidates.is_empty() {
            continue;
        }
        s += "| candidate | unit | value ± sd | size | gain per window [95 % CI] | where it acts (windows) | on its limb | cut of the gap metric | note |\n|---|---|---|---|---|---|---|---|---|\n";
        for (k, c) in st.candidates.iter().enumerate() {
            let note = if Some(k) == st.winner {
                "winner".to_string()
            } else if st.rivals.contains(&k) {
                "rival".to_string()
            } else {
                c.invalid.clone().unwrap_or_default()
            };
            s += &format!(
                "| {} | {} | {:.4} ± {:.4} | {:.0} % | {} | {} ({}) | {:.3} | {:.1} % | {} |\n",
                c.kind.name(),
                c.unit,
                c.value,
                c.sd,
                100.0 * c.size,
                est(&c.gain),
                est(&c.gain_where_acting),
                c.acting_windows,
                c.local_gain.value,
                100.0 * c.cut.value,
                note
            );
        }
        s += "\n";
    }
    s
}

/// What the diagnosing simulator's integrator, timestep or PD rate alone does (a baseline mismatch of numerics).
fn numerics_section(r: &Report) -> String {
    let Some(n) = &r.numerics else { return String::new() };
    let mut s = format!(
        "\n## The simulator's own numerics (held-out windows)\n\nThe held-out windows replayed without effects by \
         MuJoCo's other integrators and, on the rig, with finer physics steps or a faster PD rate (the diagnosing \
         simulator: `{}`, {} ms steps, PD every {} ms):\n\n| integrator | timestep | PD period | held-out gap | \
         reduction [95 % CI] | prediction shift (gap metric) |\n|---|---|---|---|---|---|\n",
        n.engine, n.timestep_ms, n.pd_period_ms
    );
    for v in &n.variants {
        s += &format!(
            "| {} | {} ms | {} ms | {:.3} | {} | {:.3} |\n",
            v.engine,
            v.timestep_ms,
            v.pd_period_ms,
            v.held_out_gap,
            est(&v.reduction),
            v.prediction_shift
        );
    }
    s += "\n";
    match n.better_variant() {
        Some(v) => {
            s += &format!(
                "**The log was replayed with {}**: it fits the training windows best and gains {:.3} per held-out \
                 window without any effect (lower bound over the {} a named effect must gain): the log comes from a \
                 plant that integrates differently, and the effects were judged with the numerics it fits.",
                v.label(),
                v.gain.value,
                n.noise_floor,
            )
        }
        None => {
            s += &format!(
                "No other integrator, timestep or PD rate gains the {} per held-out window a named effect must: the \
                 log was replayed with the diagnosing numerics.",
                n.noise_floor
            )
        }
    }
    s += &format!(
        " The numerics alone move the prediction by up to {:.3} ({:.1} % of the baseline gap{})",
        n.largest_shift(),
        100.0 * n.shift_share_of_baseline,
        n.largest_shift_variant().map(|v| format!("; {}", v.label())).unwrap_or_default()
    );
    match &r.unexplained_residual {
        Some(u) if n.largest_shift() > 0.0 => {
            s += &format!(
                "; what remains after the named effects is {:.1} times that.\n",
                u.metric_after / n.largest_shift()
            )
        }
        _ => s += ".\n",
    }
    s
}

/// Which effects this log could reveal, and where not.
fn identifiability_section(r: &Report) -> String {
    if r.identifiability.is_empty() {
        return String::new();
    }
    let mut s = format!(
        "\n## What this log can reveal (held-out windows)\n\nAn effect of the size given would give the evidence a named \
         effect needs ({} per held-out window) only on the units listed as identifiable; on the others this log cannot \
         show it, whatever the fit says.\n\n\
         | effect | size asked | identifiable on | not identifiable on | motion that would reveal it |\n|---|---|---|---|---|\n",
        r.thresholds.min_gain
    );
    let list = |names: Vec<&str>| -> String {
        match names.len() {
            0 => "—".into(),
            n if n > 8 => format!("{} and {} more", names[..8].join(", "), n - 8),
            _ => names.join(", "),
        }
    };
    for i in &r.identifiability {
        let not: Vec<&str> = i.units.iter().filter(|u| !u.identifiable()).map(|u| u.unit.as_str()).collect();
        s += &format!(
            "| {} | {} | {} | {} | {} |\n",
            i.kind.name(),
            i.magnitude_text(),
            list(i.identifiable_units()),
            list(not),
            i.revealed_by.as_deref().unwrap_or("—")
        );
    }
    s
}

/// What is left after the best combination: robust statistics, flagged windows and the unexplained residual.
fn remainder_section(r: &Report) -> String {
    let mut s = String::new();
    if let Some(u) = &r.unexplained_residual {
        s += "\n## What is left (held-out windows)\n\n";
        let where_: Vec<String> = u.by_joint.iter().map(|x| format!("{} {:.0} %", x.name, 100.0 * x.share)).collect();
        s += &format!(
            "Remaining gap metric {:.3} = {:.0} % of the baseline; the log's sensor noise alone would leave about {:.3}. {}              It lies mostly on: {}.\n\n",
            u.metric_after,
            100.0 * u.fraction_of_baseline,
            u.noise_metric,
            if u.significant {
                "**Part of the gap is unexplained**: more than twice what noise explains remains after the named effects \
                 (a model mismatch, an effect outside the library, or a difference of the simulators' numerics: timestep, \
                 integrator, PD rate)."
            } else {
                "What remains is within twice the noise level."
            },
            where_.join(", ")
        );
    }
    if let Some(g) = &r.robust {
        let flagged: Vec<String> = g
            .flagged
            .iter()
            .map(|(f, n)| {
                format!(
                    "{} {n}",
                    serde_json::to_value(f).ok().and_then(|v| v.as_str().map(str::to_string)).unwrap_or_default()
                )
            })
            .collect();
        s += &format!(
            "| statistic | baseline | after the best combination | reduction |\n|---|---|---|---|\n\
             | mean (what ranks the effects) | {:.3} | {:.3} | {:.0} % |\n\
             | trimmed mean (largest {} windows dropped, {} of them flagged) | {:.3} | {:.3} | {:.0} % |\n\
             | median | {:.3} | {:.3} | median of per-window reductions {:.0} % |\n\n\
             Held-out windows flagged: {} (per-window residuals and flags in `report.json`, `window_residuals`).\n",
            r.baseline_metric.value,
            r.unexplained_residual.as_ref().map_or(r.baseline_metric.value, |u| u.metric_after),
            100.0 * g.mean_reduction,
            g.trimmed_windows,
            g.trimmed_flagged,
            g.trimmed_mean_baseline,
            g.trimmed_mean_after,
            100.0 * g.trimmed_reduction,
            g.median_baseline,
            g.median_after,
            100.0 * g.median_window_reduction,
            flagged.join(", ")
        );
    }
    s
}

fn bar_chart(path: &Path, title: &str, items: &[(String, f64)], floor: Option<f64>) -> Result<(), GapError> {
    let io = |e: Box<dyn std::error::Error + Send + Sync>| GapError::Plot { path: path.to_owned(), source: e };
    let n = items.len().max(1);
    let height = 80 + 22 * n as u32;
    let root = SVGBackend::new(path, (900, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| io(Box::new(e)))?;
    let maxv = items.iter().map(|x| x.1).fold(floor.unwrap_or(0.0), f64::max).max(1e-9) * 1.1;
    let minv = items.iter().map(|x| x.1).fold(0.0, f64::min);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(180)
        .build_cartesian_2d(minv..maxv, 0..n)
        .map_err(|e| io(Box::new(e)))?;
    let labels: Vec<String> = items.iter().map(|x| x.0.clone()).collect();
    chart
        .configure_mesh()
        .disable_y_mesh()
        .y_labels(n)
        .y_label_formatter(&|y| labels.get(n.saturating_sub(1).saturating_sub(*y)).cloned().unwrap_or_default())
        .draw()
        .map_err(|e| io(Box::new(e)))?;
    chart
        .draw_series(items.iter().enumerate().map(|(i, (_, v))| {
            let y = n - 1 - i;
            Rectangle::new([(0.0_f64.min(*v), y), (v.max(0.0), y + 1)], BLUE.mix(0.6).filled())
        }))
        .map_err(|e| io(Box::new(e)))?;
    if let Some(f) = floor {
        chart.draw_series(std::iter::once(PathElement::new(vec![(f, 0), (f, n)], RED))).map_err(|e| io(Box::new(e)))?;
    }
    root.present().map_err(|e| io(Box::new(e)))?;
    Ok(())
}

/// Writes `report.md`, `report.json`, `by_joint.svg` and `effects.svg` into `dir`.
pub fn write_all(r: &Report, dir: &Path) -> Result<(), GapError> {
    std::fs::create_dir_all(dir).map_err(|source| GapError::File { path: dir.to_owned(), source })?;
    let w = |name: &str, text: String| {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|source| GapError::File { path, source })
    };
    w("report.md", markdown(r))?;
    w("report.json", serde_json::to_string_pretty(r)?)?;
    let joints: Vec<(String, f64)> = r.by_joint.iter().map(|s| (s.name.clone(), s.residual)).collect();
    bar_chart(&dir.join("by_joint.svg"), "Baseline residual by joint (mean normalised)", &joints, None)?;
    let eff: Vec<(String, f64)> = r.effects.iter().map(|e| (e.kind.name().to_string(), e.gain.value)).collect();
    let floor = r.effects.iter().map(|e| e.noise_floor).fold(0.0, f64::max);
    bar_chart(
        &dir.join("effects.svg"),
        "Held-out log-likelihood gain per window: named, or best candidate (red: the judge's floor)",
        &eff,
        Some(floor),
    )?;
    Ok(())
}
