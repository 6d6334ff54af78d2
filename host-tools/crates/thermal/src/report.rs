//! Markdown + SVG report of a thermal fit: selected sensors, predicted vs measured over time, residual per
//! condition.
//!
//! Glossary:
//! - **measured**: the target column; **predicted**: the model's error; **residual** = measured − predicted
//!   (what would remain after compensation).
//! - **held-out span**: a run of consecutive held-out rows, shaded in the time plots.

use std::fmt::Write as _;
use std::path::Path;

use axcomp_files::write_atomic;
use axcomp_plot::{BarChart, Figure, markdown_table, panels_svg};

use crate::thermal::{ThermalFit, ThermalInput};

/// `(xs, ys)` with a gap (NaN) wherever the time starts again (a campaign of runs, each from its own zero),
/// so that a line never joins the end of one run to the start of the next.
fn broken_at_restarts(xs: &[f64], ys: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let (mut bx, mut by) = (Vec::with_capacity(xs.len()), Vec::with_capacity(ys.len()));
    for (i, (&x, &y)) in xs.iter().zip(ys).enumerate() {
        if i > 0 && x < xs[i - 1] {
            bx.push(f64::NAN);
            by.push(f64::NAN);
        }
        bx.push(x);
        by.push(y);
    }
    (bx, by)
}

/// Writes `report.md`, `prediction.svg`, `residual_per_condition.svg` and `sensors.svg` into `dir`
/// (created if needed). Files are written atomically.
pub fn write_thermal_report(
    dir: &Path,
    fit: &ThermalFit,
    input: &ThermalInput,
    target: &str,
) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    for (path, bytes) in thermal_report_files(dir, fit, input, target) {
        write_atomic(&path, &bytes)?;
    }
    Ok(())
}

/// The report's files (`prediction.svg`, `residual_per_condition.svg`, `sensors.svg`, `report.md`) as
/// paths under `dir` and their bytes, nothing written (for an all-or-nothing output set).
pub fn thermal_report_files(
    dir: &Path,
    fit: &ThermalFit,
    input: &ThermalInput,
    target: &str,
) -> Vec<(std::path::PathBuf, Vec<u8>)> {
    let n = input.time_s.len();
    let hours: Vec<f64> = input.time_s.iter().map(|t| t / 3600.0).collect();
    let held = input.holdout.clone().unwrap_or_else(|| vec![false; n]);
    let t = TimeAxis {
        spans: spans(&hours, &held),
        hours,
    };
    // One line naming the data, the model and its figures, shared by the titles.
    let figures = match fit.holdout_rms_um {
        Some(h) => format!(
            "held-out RMS {:.2} µm raw → {h:.2} µm after the model",
            fit.raw_rms_um
        ),
        None => format!("raw RMS {:.2} µm (no held-out rows)", fit.raw_rms_um),
    };
    vec![
        (
            dir.join("prediction.svg"),
            prediction_svg(fit, input, target, &t, &figures),
        ),
        (
            dir.join("residual_per_condition.svg"),
            per_condition_svg(fit, target, &figures),
        ),
        (dir.join("sensors.svg"), sensors_svg(fit, input, &t)),
        (dir.join("report.md"), report_md(fit, target).into_bytes()),
    ]
}

/// The time axis of the plots: hours and the held-out spans.
struct TimeAxis {
    hours: Vec<f64>,
    spans: Vec<(f64, f64)>,
}

/// Measured vs predicted over time, and the residual in a panel of its own.
fn prediction_svg(
    fit: &ThermalFit,
    input: &ThermalInput,
    target: &str,
    t: &TimeAxis,
    figures: &str,
) -> Vec<u8> {
    let (hours, spans) = (&t.hours, &t.spans);
    let used = fit.model.terms.len();
    let all = input.sensors.len();
    // Measured and predicted after the same zeroing as the raw figures (target − its reference value), and
    // the residual in a panel of its own (its scale is much smaller).
    let zero = fit.raw_reference_um;
    let measured: Vec<f64> = input.target.iter().map(|v| v - zero).collect();
    let predicted: Vec<f64> = fit.prediction.iter().map(|v| v - zero).collect();
    let mut f = Figure::new(
        &format!(
            "{target}: measured vs predicted by model `{}` ({used} of {all} sensors) — {figures}",
            fit.chosen_method
        ),
        "time (h)",
        "error − reference value (µm)",
    );
    let (hx, measured) = broken_at_restarts(hours, &measured);
    let (_, predicted) = broken_at_restarts(hours, &predicted);
    f.line("measured", &hx, &measured);
    f.line("predicted", &hx, &predicted);
    for (a, b) in spans {
        f.vspan(*a, *b, "held out");
    }
    let resid: Vec<f64> = input
        .target
        .iter()
        .zip(&fit.prediction)
        .map(|(a, b)| a - b)
        .collect();
    let mut r = Figure::new(
        &format!("{target}: residual (measured − predicted, what compensation leaves)"),
        "time (h)",
        "residual (µm)",
    );
    let (_, resid) = broken_at_restarts(hours, &resid);
    r.line("residual", &hx, &resid).with_colour("#009E73");
    r.hline(0.0, "");
    for (a, b) in spans {
        r.vspan(*a, *b, "held out");
    }
    f.size(900.0, 420.0);
    r.size(900.0, 320.0);
    panels_svg(&[&f, &r], 1).into_bytes()
}

/// One bar pair per condition (raw, after the model).
fn per_condition_svg(fit: &ThermalFit, target: &str, figures: &str) -> Vec<u8> {
    // One bar pair per condition (raw, after the model); held-out conditions are marked in the name.
    let names: Vec<String> = fit
        .per_condition
        .iter()
        .map(|c| {
            format!(
                "{}{}",
                c.condition,
                if c.held_out && !c.condition.contains("held") {
                    " (held out)"
                } else {
                    ""
                }
            )
        })
        .collect();
    let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let mut bars = BarChart::new(
        &format!(
            "{target}: RMS per condition, raw vs after model `{}` — {figures}",
            fit.chosen_method
        ),
        "RMS (µm)",
        &name_refs,
    );
    bars.magnitude();
    bars.series(
        "raw",
        &fit.per_condition
            .iter()
            .map(|c| c.raw_rms_um)
            .collect::<Vec<_>>(),
    );
    bars.series(
        "after model",
        &fit.per_condition
            .iter()
            .map(|c| c.rms_um)
            .collect::<Vec<_>>(),
    );
    bars.to_svg().into_bytes()
}

/// The sensors the model uses over time.
fn sensors_svg(fit: &ThermalFit, input: &ThermalInput, t: &TimeAxis) -> Vec<u8> {
    let (hours, spans) = (&t.hours, &t.spans);
    let used = fit.model.terms.len();
    let all = input.sensors.len();
    // The sensors the model uses (only those), each named with its coefficient and lag.
    let title = if used == all {
        format!(
            "Temperatures: all {all} sensors, every one used by model `{}`",
            fit.chosen_method
        )
    } else {
        format!(
            "Temperatures: the {used} of {all} sensors used by model `{}` (the others are not shown)",
            fit.chosen_method
        )
    };
    let labels: Vec<String> = fit
        .model
        .terms
        .iter()
        .map(|t| {
            format!(
                "{} ({:+.3} µm/K, τ {:.0} s)",
                t.sensor, t.coef_um_per_k, t.tau_s
            )
        })
        .collect();
    // Wide enough that the legend holds the longest name uncut (the legend takes up to 45 % of the width
    // at ~7.5 px a character plus 50 px).
    let longest = labels.iter().map(|l| l.chars().count()).max().unwrap_or(0);
    let width = ((50.0 + 7.5 * longest as f64) / 0.45 + 10.0).max(900.0);
    let mut f = Figure::new(&title, "time (h)", "temperature (°C)");
    f.size(width, 500.0);
    for (t, label) in fit.model.terms.iter().zip(&labels) {
        if let Some(s) = input.sensors.iter().find(|s| s.name == t.sensor) {
            let (x, y) = broken_at_restarts(hours, &s.values);
            f.line(label, &x, &y);
        }
    }
    for (a, b) in spans {
        f.vspan(*a, *b, "held out");
    }
    f.to_svg().into_bytes()
}

/// The candidates compared, with their validation and held-out RMS.
fn candidates_md(md: &mut String, fit: &ThermalFit) {
    if fit.candidates.is_empty() {
        let _ = writeln!(md, "No candidates compared (forced selection).\n");
    } else {
        let _ = writeln!(
            md,
            "Candidates judged by {} validation on blocks the candidate (and all its choices) never saw; \
             blocks: {} ({}). Raw RMS over the predicted blocks {:.4} µm.\n",
            fit.validation.scheme,
            fit.validation.blocks.join("; "),
            fit.validation.rule,
            fit.validation.raw_rms_um
        );
        let rows: Vec<Vec<String>> = fit
            .candidates
            .iter()
            .map(|c| {
                vec![
                    format!("{}{}", c.name, if c.chosen { " (chosen)" } else { "" }),
                    c.sensors.join(", "),
                    c.tau_s
                        .iter()
                        .map(|t| format!("{t:.0}"))
                        .collect::<Vec<_>>()
                        .join(", "),
                    c.penalty.clone(),
                    format!("{:.4}", c.validation_rms_um),
                    c.holdout_rms_um.map_or("–".into(), |h| format!("{h:.4}")),
                ]
            })
            .collect();
        *md += &markdown_table(
            &[
                "candidate",
                "sensors",
                "τ / s",
                "penalty",
                "validation RMS / µm",
                "held-out RMS / µm (not used to choose)",
            ],
            &rows,
        );
    }
}

/// `report.md`: model, figures, sensor selection, terms and residual per condition.
fn report_md(fit: &ThermalFit, target: &str) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Thermal model of `{target}`\n");
    let _ = writeln!(md, "Model: `{}`\n", fit.formula);
    let _ = writeln!(
        md,
        "Raw RMS {:.3} µm, after the model {} (held-out rows: {}, training rows: {}). Guard: {} — {}.\n",
        fit.raw_rms_um,
        fit.holdout_rms_um
            .map_or("n/a (no holdout)".into(), |h| format!("{h:.3} µm")),
        fit.holdout_rows,
        fit.training_rows,
        if fit.guard.passed { "passed" } else { "FAILED" },
        fit.guard.reason
    );
    let _ = writeln!(
        md,
        "## Sensor selection\n\nChosen: **{}** ({}).\n",
        fit.chosen_method, fit.why
    );
    candidates_md(&mut md, fit);
    if let Some(fg) = &fit.fcm_gra_detail {
        let _ = writeln!(
            md,
            "\nFCM: {} clusters (Xie–Beni {:?}); grey relational grades: {}.\n",
            fg.clusters,
            fg.xie_beni
                .iter()
                .map(|(c, x)| format!("c={c}: {x:.4}"))
                .collect::<Vec<_>>(),
            fg.grades
                .iter()
                .map(|g| format!("{g:.3}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let _ = writeln!(
        md,
        "## Terms\n\nCondition number {:.1}, ridge λ = {}.\n",
        fit.condition_number, fit.ridge_lambda
    );
    let rows: Vec<Vec<String>> = fit
        .model
        .terms
        .iter()
        .zip(&fit.vif)
        .map(|(t, v)| {
            vec![
                t.sensor.clone(),
                format!("{:.4}", t.coef_um_per_k),
                format!("{:.0}", t.tau_s),
                format!("{:.3}", t.reference_degc),
                format!("{:.2}", v.1),
            ]
        })
        .collect();
    md += &markdown_table(&["sensor", "b / µm/K", "τ / s", "T_ref / °C", "VIF"], &rows);
    if !fit.model.forces.is_empty() {
        let rows: Vec<Vec<String>> = fit
            .model
            .forces
            .iter()
            .map(|f| vec![f.column.clone(), format!("{:.6}", f.chi_um_per_n)])
            .collect();
        md.push('\n');
        md += &markdown_table(&["force", "χ / µm/N"], &rows);
    }
    let _ = writeln!(md, "\n## Residual per condition\n");
    let rows: Vec<Vec<String>> = fit
        .per_condition
        .iter()
        .enumerate()
        .map(|(i, c)| {
            vec![
                i.to_string(),
                c.condition.clone(),
                c.rows.to_string(),
                if c.held_out { "yes" } else { "no" }.to_string(),
                format!("{:.3}", c.raw_rms_um),
                format!("{:.3}", c.rms_um),
            ]
        })
        .collect();
    md += &markdown_table(
        &[
            "index",
            "condition",
            "rows",
            "held out",
            "raw RMS / µm",
            "RMS after / µm",
        ],
        &rows,
    );
    md += "\n![prediction](prediction.svg)\n\n![residual per condition](residual_per_condition.svg)\n\n![sensors](sensors.svg)\n";
    md
}

/// Consecutive runs of `true` in `mask` as (x_from, x_to).
pub fn spans(x: &[f64], mask: &[bool]) -> Vec<(f64, f64)> {
    let mut out = vec![];
    let mut start = None;
    for i in 0..mask.len() {
        match (mask[i], start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                out.push((x[s], x[i - 1]));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((x[s], x[mask.len() - 1]));
    }
    out
}
