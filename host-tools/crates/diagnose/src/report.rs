//! The diagnosis report: Markdown plus SVG figures of the gap over position / time / velocity with the
//! located regions marked, the ranked candidates with their evidence, and before/after on held-out rows.
//!
//! Glossary: **before** = held-out residual of the model as given; **after** = held-out residual of the
//! whole model refitted with the verdict's effect added.

use std::path::Path;

use axcomp_plot::{Figure, markdown_table};

use crate::engine::Diagnosis;
use crate::obs::Observations;

fn fmt_params(p: &serde_json::Map<String, serde_json::Value>) -> String {
    p.iter()
        .filter(|(k, _)| k.as_str() != "coefficients")
        .map(|(k, v)| match v.as_f64() {
            Some(x) => format!("{k}={x:.4}"),
            None => format!("{k}={v}"),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Writes `diagnosis.md` and the figures into `dir` (created if needed). Returns the files written.
pub fn write_report(
    dir: &Path,
    obs: &Observations,
    d: &Diagnosis,
) -> anyhow::Result<Vec<std::path::PathBuf>> {
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    let hold = obs.holdout_rows();
    let after = d.verdict_candidate().map(|c| &c.residual_after);
    let mut written = Vec::new();
    let mut figs = Vec::new();
    for (var, col, unit) in [
        ("target_mm", &obs.position_mm, "target position (mm)"),
        ("time_s", &obs.time_s, "time (s)"),
        ("velocity_mm_s", &obs.velocity_mm_s, "velocity (mm/s)"),
    ] {
        let Some(x) = col else { continue };
        let xs: Vec<f64> = hold.iter().map(|&i| x[i]).collect();
        if xs.iter().all(|v| *v == xs[0]) {
            continue;
        }
        let before: Vec<f64> = hold.iter().map(|&i| d.residual[i]).collect();
        let mut f = Figure::new(
            &format!("Held-out gap of {} over {var}", d.target),
            unit,
            &format!("{} residual (µm)", d.target),
        );
        for r in d.where_.iter().filter(|r| r.variable == var) {
            f.vspan(r.from, r.to, &format!("{:.0} % of gap", 100.0 * r.share));
        }
        f.points("model as given (held out)", &xs, &before);
        if let Some(a) = after {
            let ys: Vec<f64> = hold.iter().map(|&i| a[i]).collect();
            f.points(&format!("refitted with {} (held out)", d.verdict), &xs, &ys);
        }
        let name = format!("gap_{var}.svg");
        let path = dir.join(&name);
        f.save_svg(&path)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
        figs.push(name);
        written.push(path);
    }

    let mut md = String::new();
    md.push_str(&format!("# Gap diagnosis of `{}`\n\n", d.target));
    let model: Vec<&str> = d.model.iter().map(|m| m.kind.as_str()).collect();
    md.push_str(&format!(
        "Model: {} (+ intercept), fitted on {} training rows; judged on {} held-out rows.\n\n",
        if model.is_empty() {
            "nothing".to_string()
        } else {
            model.join(", ")
        },
        d.n_train,
        d.n_holdout
    ));
    md.push_str(&format!("**Verdict: `{}`** — {}.\n\n", d.verdict, d.note));
    md.push_str("## Gap\n\n");
    md.push_str(&markdown_table(
        &["", "RMS (µm)", "max (µm)"],
        &[
            vec![
                "training rows".to_string(),
                format!("{:.3}", d.gap.train_rms_um),
                "–".to_string(),
            ],
            vec![
                "held-out rows, model as given".to_string(),
                format!("{:.3}", d.gap.holdout_rms_um),
                format!("{:.3}", d.gap.holdout_max_um),
            ],
            match d.verdict_candidate() {
                Some(c) => vec![
                    format!("held-out rows, refitted with `{}`", c.kind),
                    format!(
                        "{:.3} (shrink {:.1} %)",
                        c.holdout_rms_after_um, c.shrink_pct
                    ),
                    format!(
                        "{:.3}",
                        hold.iter()
                            .map(|&i| c.residual_after[i].abs())
                            .fold(0.0, f64::max)
                    ),
                ],
                None => vec![
                    "held-out rows, refitted".to_string(),
                    "no verdict".to_string(),
                    "–".to_string(),
                ],
            },
        ],
    ));
    md.push_str("\n## Where the gap lies\n\n");
    if d.where_.is_empty() {
        md.push_str("No region holds more of the gap than noise.\n");
    } else {
        let rows: Vec<Vec<String>> = d
            .where_
            .iter()
            .map(|r| {
                vec![
                    r.variable.clone(),
                    format!("{:.4} … {:.4}", r.from, r.to),
                    format!("{:.1} %", 100.0 * r.share),
                    format!("{:.1} %", 100.0 * r.rows_fraction),
                    format!("{:.2}", r.lift),
                ]
            })
            .collect();
        md.push_str(&markdown_table(
            &[
                "variable",
                "region",
                "share of gap",
                "share of rows",
                "lift",
            ],
            &rows,
        ));
    }
    for f in &figs {
        md.push_str(&format!("\n![{f}]({f})\n"));
    }
    md.push_str("\n## Candidates (whole model refitted with each)\n\n");
    let rows: Vec<Vec<String>> = d
        .effects
        .iter()
        .map(|c| {
            vec![
                format!(
                    "`{}`{}",
                    c.kind,
                    if c.explains {
                        ""
                    } else {
                        " (not beyond noise)"
                    }
                ),
                format!("{:.1}", c.score),
                format!("{:.3}", c.holdout_rms_after_um),
                format!("{:.1}", c.shrink_pct),
                c.n_params.to_string(),
                format!("{:.2e}", c.train_p_value),
                format!("{:.2e}", c.holdout_p_value),
                format!("{:.1}", c.train_delta_bic),
                fmt_params(&c.params),
            ]
        })
        .collect();
    md.push_str(&markdown_table(
        &[
            "kind",
            "score (held-out ΔBIC)",
            "held-out RMS after (µm)",
            "shrink %",
            "parameters",
            "train p (Bonferroni)",
            "held-out p",
            "train ΔBIC",
            "searched / derived parameters",
        ],
        &rows,
    ));
    if !d.not_applicable.is_empty() {
        md.push_str(&format!(
            "\nNot applicable to these columns: {}.\n",
            d.not_applicable.join(", ")
        ));
    }
    md.push_str(&format!(
        "\nResidual whiteness (training rows, lag-1 autocorrelation): time order {:.3}{}.\n",
        d.residual_checks.lag1_autocorr_time,
        d.residual_checks
            .lag1_autocorr_position
            .map_or(String::new(), |r| format!(", position order {r:.3}"))
    ));
    let path = dir.join("diagnosis.md");
    axcomp_plot::write_atomic(&path, md.as_bytes())
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
    written.push(path);
    Ok(written)
}
