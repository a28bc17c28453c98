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
    s += &format!(
        "Simulator: `{}` on the suspension rig. Log: {:.1} s; {} training and {} held-out windows of {:.3} s. \
         Gap metric = mean normalised squared residual per window (q / 2 mrad, dq / 0.1 rad/s, tau / 1 % of the limit, IMU), \
         summed over joints and the IMU.\n\n",
        r.engine, r.log_duration_s, r.windows_train, r.windows_held_out, r.window_s
    );
    s += &format!("**Baseline held-out gap metric:** {}\n\n", est(&r.baseline_metric));
    s += "## Verdict\n\n";
    if r.unexplained {
        s += "No effect clears the noise floor on held-out windows: **the gap is unexplained** by the effect library (abstention).\n\n";
    } else {
        let names: Vec<&str> = r.ranked.iter().map(|k| k.name()).collect();
        s += &format!("Named effects, most explanatory first: **{}**.\n\n", names.join(", "));
        if let Some(c) = &r.best_combination {
            let n: Vec<&str> = c.effects.iter().map(|k| k.name()).collect();
            s += &format!(
                "Best combination: {} — held-out metric {} (relative reduction {}).\n\n",
                n.join(" + "),
                est(&c.metric_after),
                est(&c.reduction)
            );
        }
    }
    s += "## Where the gap lies (baseline)\n\n";
    s += &share_table("By joint group", &r.by_group, 10);
    s += &share_table("By joint (top 10)", &r.by_joint, 10);
    s += &share_table("By phase (foot contact estimated from knee torque)", &r.by_phase, 10);
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
    s += &format!("\nDiagnosis time: {:.1} s. Plots: `by_joint.svg`, `effects.svg`.\n", r.elapsed_s);
    s
}

fn bar_chart(path: &Path, title: &str, items: &[(String, f64)], floor: Option<f64>) -> Result<(), GapError> {
    let io = |e: String| GapError::Io(format!("{}: {e}", path.display()));
    let n = items.len().max(1);
    let height = 80 + 22 * n as u32;
    let root = SVGBackend::new(path, (900, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| io(e.to_string()))?;
    let maxv = items.iter().map(|x| x.1).fold(floor.unwrap_or(0.0), f64::max).max(1e-9) * 1.1;
    let minv = items.iter().map(|x| x.1).fold(0.0, f64::min);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(180)
        .build_cartesian_2d(minv..maxv, 0..n)
        .map_err(|e| io(e.to_string()))?;
    let labels: Vec<String> = items.iter().map(|x| x.0.clone()).collect();
    chart
        .configure_mesh()
        .disable_y_mesh()
        .y_labels(n)
        .y_label_formatter(&|y| labels.get(n.saturating_sub(1).saturating_sub(*y)).cloned().unwrap_or_default())
        .draw()
        .map_err(|e| io(e.to_string()))?;
    chart
        .draw_series(items.iter().enumerate().map(|(i, (_, v))| {
            let y = n - 1 - i;
            Rectangle::new([(0.0_f64.min(*v), y), (v.max(0.0), y + 1)], BLUE.mix(0.6).filled())
        }))
        .map_err(|e| io(e.to_string()))?;
    if let Some(f) = floor {
        chart.draw_series(std::iter::once(PathElement::new(vec![(f, 0), (f, n)], RED))).map_err(|e| io(e.to_string()))?;
    }
    root.present().map_err(|e| io(e.to_string()))?;
    Ok(())
}

/// Writes `report.md`, `report.json`, `by_joint.svg` and `effects.svg` into `dir`.
pub fn write_all(r: &Report, dir: &Path) -> Result<(), GapError> {
    std::fs::create_dir_all(dir).map_err(|e| GapError::Io(format!("{}: {e}", dir.display())))?;
    let w = |name: &str, text: String| std::fs::write(dir.join(name), text).map_err(|e| GapError::Io(format!("{name}: {e}")));
    w("report.md", markdown(r))?;
    w("report.json", serde_json::to_string_pretty(r).map_err(|e| GapError::Io(e.to_string()))?)?;
    let joints: Vec<(String, f64)> = r.by_joint.iter().map(|s| (s.name.clone(), s.residual)).collect();
    bar_chart(&dir.join("by_joint.svg"), "Baseline residual by joint (mean normalised)", &joints, None)?;
    let eff: Vec<(String, f64)> = r.effects.iter().map(|e| (e.kind.name().to_string(), e.reduction.value)).collect();
    let floor = r.effects.iter().map(|e| e.noise_floor).fold(0.0, f64::max);
    bar_chart(&dir.join("effects.svg"), "Held-out relative reduction per effect (red: noise floor)", &eff, Some(floor))?;
    Ok(())
}
