//! Markdown + SVG report of a thermal fit: selected sensors, predicted vs measured over time, residual per
//! condition.
//!
//! Glossary:
//! - **measured**: the target column; **predicted**: the model's error; **residual** = measured − predicted
//!   (what would remain after compensation).
//! - **held-out span**: a run of consecutive held-out rows, shaded in the time plots.

use std::fmt::Write as _;
use std::path::Path;

use axcomp_plot::{Figure, markdown_table, write_atomic};

use crate::thermal::{ThermalFit, ThermalInput};

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
    let mut files = Vec::new();
    let n = input.time_s.len();
    let hours: Vec<f64> = input.time_s.iter().map(|t| t / 3600.0).collect();
    let held = input.holdout.clone().unwrap_or_else(|| vec![false; n]);
    let spans = spans(&hours, &held);

    let mut f = Figure::new(
        &format!("{target}: measured vs predicted"),
        "time / h",
        "error / µm",
    );
    f.line("measured", &hours, &input.target);
    f.line("predicted", &hours, &fit.prediction);
    let resid: Vec<f64> = input
        .target
        .iter()
        .zip(&fit.prediction)
        .map(|(a, b)| a - b)
        .collect();
    f.dashed("residual", &hours, &resid);
    for (a, b) in &spans {
        f.vspan(*a, *b, "held out");
    }
    files.push((dir.join("prediction.svg"), f.to_svg().into_bytes()));

    let mut f = Figure::new(
        "RMS per condition",
        "condition (index, see report.md)",
        "RMS / µm",
    );
    let xs: Vec<f64> = (0..fit.per_condition.len()).map(|i| i as f64).collect();
    f.points(
        "raw",
        &xs,
        &fit.per_condition
            .iter()
            .map(|c| c.raw_rms_um)
            .collect::<Vec<_>>(),
    );
    f.points(
        "after model",
        &xs,
        &fit.per_condition
            .iter()
            .map(|c| c.rms_um)
            .collect::<Vec<_>>(),
    );
    files.push((
        dir.join("residual_per_condition.svg"),
        f.to_svg().into_bytes(),
    ));

    let mut f = Figure::new("Selected sensors", "time / h", "temperature / °C");
    for t in &fit.model.terms {
        if let Some(s) = input.sensors.iter().find(|s| s.name == t.sensor) {
            f.line(&t.sensor, &hours, &s.values);
        }
    }
    for (a, b) in &spans {
        f.vspan(*a, *b, "held out");
    }
    files.push((dir.join("sensors.svg"), f.to_svg().into_bytes()));

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
        md += &markdown_table(
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
    files.push((dir.join("report.md"), md.into_bytes()));
    files
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
