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
    if r.unexplained {
        s += "No effect clears the noise floor on held-out windows: **the gap is unexplained** by the effect library (abstention).\n\n";
    } else {
        let names: Vec<&str> = r.ranked.iter().map(|k| k.name()).collect();
        s += &format!("Named effects, most explanatory first: **{}**.\n\n", names.join(", "));
        if let Some(set) = crate::diagnose::leading_set(&r.ranked, &r.ambiguous) {
            let n: Vec<&str> = set.effects.iter().map(|k| k.name()).collect();
            s += &format!(
                "**This log cannot tell apart {}**: each alone changes the prediction the same way (cosine magnitude \
                 {:.2}), so the first of them is not a confident first effect (the motions that would separate them: \
                 \"Effects this log cannot tell apart\").\n\n",
                n.join(" and "),
                set.cosine
            );
            if !set.at_bound.is_empty() {
                let b: Vec<&str> = set.at_bound.iter().map(|k| k.name()).collect();
                s += &format!(
                    "Fitted at the edge of its search range: {} (the optimum may lie beyond what the library allows, \
                     as when an effect stands in for another; a true effect near the edge fits there too).\n\n",
                    b.join(", ")
                );
            }
        }
        if let Some(c) = &r.best_combination {
            let n: Vec<&str> = c.effects.iter().map(|k| k.name()).collect();
            s += &format!(
                "Best combination: {} — held-out metric {} (relative reduction {}).\n\n",
                n.join(" + "),
                est(&c.metric_after),
                est(&c.reduction)
            );
        }
        let away: Vec<&str> = r.effects.iter().filter(|e| !e.explained_by.is_empty()).map(|e| e.kind.name()).collect();
        if !away.is_empty() {
            s += &format!(
                "Explained away (each cuts the gap alone, but adds nothing once the best combination is in; not \
                 named): {}.\n\n",
                away.join(", ")
            );
        }
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
    s += "## Which effect (held-out windows)\n\n| rank | effect | named | relative reduction [95 % CI] | noise floor | metric after | parameters (unit: value ± sd) |\n|---|---|---|---|---|---|---|\n";
    for (i, e) in r.effects.iter().enumerate() {
        let p: Vec<String> = e.params.iter().map(|p| format!("{}: {:.4} ± {:.4}", p.unit, p.value, p.sd)).collect();
        s += &format!(
            "| {} | {} | {} | {} | {:.3} | {} | {} |\n",
            i + 1,
            e.kind.name(),
            if e.named { "yes" } else { "no" },
            est(&e.reduction),
            e.noise_floor,
            est(&e.metric_after),
            if p.is_empty() { "—".into() } else { p.join("; ") }
        );
    }
    s += "\n### Abstentions\n\n";
    for (k, why) in &r.abstentions {
        s += &format!("- {}: {}\n", k.name(), why);
    }
    // Units taken out of a fit, by why: each as "kind on units", the kinds separated by "; ".
    let listed = |units: fn(&crate::diagnose::EffectResult) -> &Vec<String>| -> String {
        let rows: Vec<String> = r
            .effects
            .iter()
            .filter(|e| !units(e).is_empty())
            .map(|e| format!("{} on {}", e.kind.name(), units(e).join(", ")))
            .collect();
        rows.join("; ")
    };
    let dropped = listed(|e| &e.worsening_units);
    if !dropped.is_empty() {
        s += &format!(
            "\nUnits dropped from a fit (each cut its own held-out residual but, alone, left the whole held-out gap no \
             smaller: a value fitted against a mismatch elsewhere): {dropped}.\n"
        );
    }
    let pinned = listed(|e| &e.pinned_units);
    if !pinned.is_empty() {
        s += &format!(
            "\nUnits dropped from a fit alone at the bound of its search range (the fit wanted more than the \
             library allows: a stand-in for another effect, or one larger than the range; the effect may still be \
             named refitted given the effects before it, inside the range): {pinned}.\n"
        );
    }
    let contradicted = listed(|e| &e.contradicted_units);
    if !contradicted.is_empty() {
        s += &format!(
            "\nUnits the log contradicts (their fitted torque ceiling is exceeded by the logged torque, more than \
             {}x it in over {:.0} % of the samples): {contradicted}.\n",
            crate::diagnose::CEILING_MARGIN,
            crate::diagnose::MAX_FRACTION_ABOVE * 100.0,
        );
    }
    let in_log: Vec<String> = r
        .effects
        .iter()
        .flat_map(|e| &e.ceilings_in_log)
        .map(|c| {
            format!(
                "{} at {:.2} of its limit ({} samples held, {:.2} followed below, logged torque {} state sample(s) \
                 behind the demand, of the command {} state sample(s) earlier)",
                c.joint, c.scale, c.pinned, c.follow, c.lag_samples, c.command_delay_samples
            )
        })
        .collect();
    if !in_log.is_empty() {
        s += &format!(
            "\nTorque ceilings the log shows (the logged torque held at a plateau below the nominal limit while the \
             PD law of the log's command asked for over {}x it; named whatever share of the gap they cut): {}.\n",
            crate::diagnose::DEMAND_OVER,
            in_log.join(", ")
        );
    }
    s += &splits_section(r);
    s += &ambiguous_section(r);
    s += &identifiability_section(r);
    s += &numerics_section(r);
    s += &remainder_section(r);
    let stages: Vec<String> = r.stages.iter().map(|t| format!("{} {:.1} s", t.stage, t.s)).collect();
    let stages = if stages.is_empty() { String::new() } else { format!(" ({})", stages.join(", ")) };
    s += &format!("\nDiagnosis time: {:.1} s{stages}. Plots: `by_joint.svg`, `effects.svg`.\n", r.elapsed_s);
    s
}

/// Each friction-like effect that cleared the floor, refitted on the halves of the training windows by load and
/// by speed, and each gain scale by the braking share of its joints' power.
fn splits_section(r: &Report) -> String {
    use crate::diagnose::SplitBy;
    let rows: Vec<String> = r
        .effects
        .iter()
        .flat_map(|e| e.splits.iter().map(move |l| (e, l)))
        .map(|(e, l)| {
            let est = |x: &crate::diagnose::Estimate| format!("{:.2}x [{:.2}, {:.2}]", x.value, x.lo, x.hi);
            let cut =
                |x: &crate::diagnose::Estimate| format!("cut {:.3} [{:.3}, {:.3}] per window", x.value, x.lo, x.hi);
            let (by, q, verdict): (_, fn(f64) -> String, _) = match l.by {
                SplitBy::Load => (
                    "load",
                    |x| format!("{:.1} %", x * 100.0),
                    match (l.set_aside, l.load_paced && l.scales_contradict()) {
                        (true, true) => format!(
                            "grows with the load, and so does its cut ({} light, {} heavy): not named",
                            cut(&l.cut_low),
                            cut(&l.cut_high)
                        ),
                        (true, false) => "grows with the load: not named".to_string(),
                        (false, true) => format!(
                            "a wider band under load, yet it cuts the light half's gap too ({} light, {} heavy, \
                             less per unit of load): kept",
                            cut(&l.cut_low),
                            cut(&l.cut_high)
                        ),
                        (false, false) => "holds at both loads".to_string(),
                    },
                ),
                SplitBy::Speed if l.by_cut => (
                    "speed",
                    |x| format!("{x:.2} rad/s"),
                    if l.set_aside { "cuts only the slow half: not named" } else { "cuts both halves" }.to_string(),
                ),
                SplitBy::Speed => (
                    "speed",
                    |x| format!("{x:.2} rad/s"),
                    if l.set_aside { "falls with speed: not named" } else { "holds at both speeds" }.to_string(),
                ),
                SplitBy::Power => (
                    "power",
                    |x| format!("{:.0} % braking", x * 100.0),
                    if l.set_aside { "weaker only while driving: not named" } else { "holds driving and braking" }
                        .to_string(),
                ),
            };
            let (low, high) =
                if l.by_cut { (cut(&l.cut_low), cut(&l.cut_high)) } else { (est(&l.scale_low), est(&l.scale_high)) };
            let part = if l.set_aside && l.loosened_by_route() { " (cleared on part)" } else { "" };
            format!(
                "| {} | {by} | {} | {} | {} | {} | {verdict}{part} |\n",
                e.kind.name(),
                q(l.low),
                low,
                q(l.high),
                high,
            )
        })
        .collect();
    if rows.is_empty() {
        return String::new();
    }
    format!(
        "\n## Does the effect hold on every part of the motion (training windows)\n\nA damping, friction or dead \
         band of the library has one size whatever torque the joint carries and however fast it turns; a friction \
         that grows with the load (a gear's) does not, and the library's effects fit it as an average. Each such \
         effect that cleared the floor is refitted, as one scale of its fitted values, on the half of the training \
         windows where its joints carry the least torque and on the half where they carry the most (load: mean \
         |torque| of its joints, in % of their limits), and on the half where they move slowest and the half \
         where they move fastest (mean |velocity|); scales with a 95 % bootstrap interval over the half's \
         windows. A high-load scale at least {r:.1}x the low-load one, or a slow-half scale at least {r:.1}x the \
         fast-half one, with intervals apart, sets the effect aside; the intervals need not be apart when the \
         effect cleared the floor only on part of the held-out windows (verdict marked \"cleared on part\"). A \
         friction or a backlash split by speed is judged by what its fitted value cuts of each half's gap instead \
         (a Coulomb torque keeps its size at speed, a dead band its width): set aside when it cuts the slow \
         half's {r:.1}x as much as the fast half's, intervals apart (again, not when it cleared on part). A backlash whose scales grow with the load \
         is set aside only when its fitted value also cuts the heavy half's gap at least as much per unit of load \
         as the light half's: a band is lost at every reversal, so it cuts the light windows' gap too, where a \
         torque growing with the load is nothing there. A gain scale is refitted on the half of the training windows \
         where its joints' motors mostly drive them and the half where they mostly brake (power: the braking share \
         of torque x velocity): a gain acts alike on both, a friction fitted as a weaker gain wants it only while \
         driving; a driving-half scale at least {r:.1}x the braking-half one sets it aside as above.\n\n| effect | split by | low half | \
         scale there | high half | scale there | verdict |\n|---|---|---|---|---|---|---|\n{}",
        rows.concat(),
        r = crate::diagnose::SCALE_RATIO,
    )
}

/// The named effects the log cannot tell apart, with the motion that would reveal each.
fn ambiguous_section(r: &Report) -> String {
    if r.ambiguous.is_empty() {
        return String::new();
    }
    let mut s = format!(
        "\n## Effects this log cannot tell apart\n\nA *collinear* set's effects, fitted alone, change the predicted measurements of the held-out windows in nearly the same direction (|cosine| at least {:.2}) and leave held-out gaps that the log cannot rank (their difference is under the noise floor, or its 95 % interval holds 0): their order in the ranking is not evidence for one over the other. An *equal-cut* set is a masked effect named after the others and the masked effects that, refitted with those others applied, each cut what they leave on the same limb beyond its floor by a cut the log cannot rank against it: only the first is named, the others are as likely (cosine and gap difference given the effects before them, the difference relative to what those leave).\n\n| effects (rank order) | why | smallest cosine magnitude | largest gap difference | fitted at the edge of its range | motion that would reveal each |\n|---|---|---|---|---|---|\n",
        crate::diagnose::AMBIGUOUS_COSINE
    );
    for set in &r.ambiguous {
        let n: Vec<&str> = set.effects.iter().map(|k| k.name()).collect();
        let how: Vec<String> = set.effects.iter().map(|k| format!("{}: {}", k.name(), k.revealed_by())).collect();
        let edge: Vec<&str> = set.at_bound.iter().map(|k| k.name()).collect();
        s += &format!(
            "| {} | {} | {:.3} | {:.1} % | {} | {} |\n",
            n.join(", "),
            match set.reason {
                crate::diagnose::Ambiguity::Collinear => "collinear",
                crate::diagnose::Ambiguity::EqualCut => "equal cut",
            },
            set.cosine,
            100.0 * set.gap_difference,
            if edge.is_empty() { "—".to_string() } else { edge.join(", ") },
            how.join("; ")
        );
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
                "**Part of the baseline gap is numerics**: with {} the held-out gap is {:.0} % smaller without any \
                 effect, beyond the noise floor ({:.0} %, by the lower bound of its interval): the log comes from a \
                 plant that integrates differently. The effects above are judged against `{}`, {} ms steps, PD every \
                 {} ms; to judge them against the numerics the log fits, diagnose again with `{}`.",
                v.label(),
                100.0 * v.reduction.value,
                100.0 * n.noise_floor,
                n.engine,
                n.timestep_ms,
                n.pd_period_ms,
                v.diagnose_flags()
            )
        }
        None => {
            s += &format!(
                "No other integrator, timestep or PD rate fits the log better beyond the noise floor ({:.0} %): the \
                 gap is not a numerics mismatch of these kinds.",
                100.0 * n.noise_floor
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
        "\n## What this log can reveal (held-out windows)\n\nAn effect of the size given would move a unit's residual by \
         at least the floor a fit must clear there ({:.0} % of the unit's baseline residual) only on the units listed \
         as identifiable; on the others this log cannot show it, whatever the fit says.\n\n\
         | effect | size asked | identifiable on | not identifiable on | motion that would reveal it |\n|---|---|---|---|---|\n",
        100.0 * crate::diagnose::UNIT_FLOOR_FRAC
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
    let eff: Vec<(String, f64)> = r.effects.iter().map(|e| (e.kind.name().to_string(), e.reduction.value)).collect();
    let floor = r.effects.iter().map(|e| e.noise_floor).fold(0.0, f64::max);
    bar_chart(
        &dir.join("effects.svg"),
        "Held-out relative reduction per effect (red: noise floor)",
        &eff,
        Some(floor),
    )?;
    Ok(())
}
