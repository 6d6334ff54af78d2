//! The diagnosis report: Markdown plus SVG figures of the gap over position / time / velocity with the
//! located regions marked, the ranked candidates with their evidence, and before/after on held-out rows.
//!
//! Glossary: **before** = held-out residual of the model as given; **after** = held-out residual of the
//! whole model refitted with the verdict's effect added.

use std::path::Path;

use axcomp_plot::{Figure, PALETTE, markdown_table};

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

/// Most points drawn per series: larger data are shown as every k-th held-out row (deterministic stride),
/// which keeps every SVG well below a few MB whatever the campaign size.
pub const MAX_POINTS_PER_SERIES: usize = 4000;

/// The time unit of a plot: seconds, minutes or hours, chosen by the span so the ticks read naturally.
pub fn time_unit(span_s: f64) -> (&'static str, f64) {
    if span_s < 600.0 {
        ("s", 1.0)
    } else if span_s < 10.0 * 3600.0 {
        ("min", 60.0)
    } else {
        ("h", 3600.0)
    }
}

/// Every `stride`-th index of `rows` (all of them when they fit [`MAX_POINTS_PER_SERIES`]).
fn thin(rows: &[usize]) -> (Vec<usize>, usize) {
    let stride = rows.len().div_ceil(MAX_POINTS_PER_SERIES).max(1);
    (rows.iter().step_by(stride).cloned().collect(), stride)
}

/// Writes `diagnosis.md` and the figures into `dir` (created if needed). Returns the files written.
/// The files are those of [`report_files`], each written atomically.
pub fn write_report(
    dir: &Path,
    obs: &Observations,
    d: &Diagnosis,
) -> crate::error::Result<Vec<std::path::PathBuf>> {
    use crate::error::DiagnoseError;
    let files = report_files(dir, obs, d)?;
    std::fs::create_dir_all(dir).map_err(|cause| DiagnoseError::Io {
        action: "create",
        path: dir.display().to_string(),
        cause,
    })?;
    let mut written = Vec::new();
    for (path, bytes) in files {
        axcomp_files::write_atomic(&path, &bytes).map_err(|cause| DiagnoseError::Io {
            action: "write",
            path: path.display().to_string(),
            cause,
        })?;
        written.push(path);
    }
    Ok(written)
}

/// The report's files (`diagnosis.md` last, the figures before it) as paths under `dir` and their bytes,
/// nothing written (for an all-or-nothing output set).
///
/// Figures: one per variable (`target_mm`, `time_s`, `velocity_mm_s`) of the held-out gap of the model as
/// given, and, when there is a verdict, a second panel with the gap after refitting with it
/// (`gap_<var>_after.svg`, same colours). When the verdict is `reversal` or the gap lies in one direction,
/// the points are coloured by approach direction (forward blue, reverse orange in both panels). Time is in
/// s, min or h by the span; units are written `quantity (unit)` throughout.
pub fn report_files(
    dir: &Path,
    obs: &Observations,
    d: &Diagnosis,
) -> crate::error::Result<Vec<(std::path::PathBuf, Vec<u8>)>> {
    let hold = obs.holdout_rows();
    let (figs, mut written) = figures(dir, obs, d, &hold);
    let mut md = summary_markdown(d, &hold);
    md.push_str(&where_markdown(d));
    for f in &figs {
        md.push_str(&format!("\n![{f}]({f})\n"));
    }
    md.push_str(&candidates_markdown(d));
    let path = dir.join("diagnosis.md");
    written.push((path, md.into_bytes()));
    Ok(written)
}

/// A figure's file name and bytes.
type FigureFile = (std::path::PathBuf, Vec<u8>);

/// The gap figures: per variable, the held-out gap of the model as given and, with a verdict, after
/// refitting with it. Returns the file names and the files.
fn figures(
    dir: &Path,
    obs: &Observations,
    d: &Diagnosis,
    hold: &[usize],
) -> (Vec<String>, Vec<FigureFile>) {
    let (shown, stride) = thin(hold);
    let after = d.verdict_candidate().map(|c| &c.residual_after);
    let by_direction = obs.direction.as_ref().filter(|dir| {
        let both = hold.iter().any(|&i| dir[i] > 0.0) && hold.iter().any(|&i| dir[i] < 0.0);
        both && (d.verdict == "reversal" || d.where_.iter().any(|r| r.variable == "direction"))
    });
    let mut written = Vec::new();
    let mut figs = Vec::new();
    for (var, col) in [
        ("target_mm", &obs.position_mm),
        ("time_s", &obs.time_s),
        ("velocity_mm_s", &obs.velocity_mm_s),
    ] {
        let Some(x) = col else { continue };
        if hold.iter().all(|&i| x[i] == x[hold[0]]) {
            continue;
        }
        let (label, scale) = match var {
            "target_mm" => ("target position (mm)".to_string(), 1.0),
            "time_s" => {
                let lo = hold.iter().map(|&i| x[i]).fold(f64::INFINITY, f64::min);
                let hi = hold.iter().map(|&i| x[i]).fold(f64::NEG_INFINITY, f64::max);
                let (u, k) = time_unit(hi - lo);
                (format!("time ({u})"), k)
            }
            _ => ("velocity (mm/s)".to_string(), 1.0),
        };
        let subset = if stride > 1 {
            format!(", 1 in {stride} of {} held-out rows shown", hold.len())
        } else {
            String::new()
        };
        let panels: Vec<(&str, &Vec<f64>, String)> = std::iter::once((
            "",
            &d.residual,
            format!(
                "Held-out gap of {} — model as given (RMS {:.3} µm){subset}",
                d.target, d.gap.holdout_rms_um
            ),
        ))
        .chain(after.map(|a| {
            (
                "_after",
                a,
                format!(
                    "Held-out gap of {} — refitted with {} (RMS {:.3} µm){subset}",
                    d.target,
                    d.verdict,
                    d.verdict_candidate()
                        .map_or(f64::NAN, |c| c.holdout_rms_after_um)
                ),
            )
        }))
        .collect();
        for (suffix, resid, title) in panels {
            let mut f = Figure::new(&title, &label, "residual (µm)");
            let regions = if suffix.is_empty() {
                &d.where_
            } else {
                &d.verdict_where
            };
            for r in regions.iter().filter(|r| r.variable == var) {
                let what = if suffix.is_empty() { "gap" } else { "gain" };
                f.vspan(
                    r.from / scale,
                    r.to / scale,
                    &format!("{:.0} % of {what}", 100.0 * r.share),
                );
            }
            match by_direction {
                Some(dir) => {
                    for (name, colour, sign) in [
                        ("forward (+) approach", PALETTE[0], 1.0),
                        ("reverse (−) approach", PALETTE[1], -1.0),
                    ] {
                        let rows: Vec<usize> = shown
                            .iter()
                            .cloned()
                            .filter(|&i| dir[i] * sign > 0.0)
                            .collect();
                        let xs: Vec<f64> = rows.iter().map(|&i| x[i] / scale).collect();
                        let ys: Vec<f64> = rows.iter().map(|&i| resid[i]).collect();
                        f.points_coloured(name, &xs, &ys, colour);
                    }
                }
                None => {
                    let xs: Vec<f64> = shown.iter().map(|&i| x[i] / scale).collect();
                    let ys: Vec<f64> = shown.iter().map(|&i| resid[i]).collect();
                    f.points_coloured("held-out rows", &xs, &ys, PALETTE[0]);
                }
            }
            f.hline(0.0, "");
            let name = format!("gap_{var}{suffix}.svg");
            let path = dir.join(&name);
            figs.push(name);
            written.push((path, f.to_svg().into_bytes()));
        }
    }
    (figs, written)
}

/// The report's head: the model, the verdict and its rule, and the gap before and after.
fn summary_markdown(d: &Diagnosis, hold: &[usize]) -> String {
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
    md.push_str(&format!("Verdict rule: {}\n\n", d.verdict_rule));
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
    md
}

/// Where the gap lies: the regions holding most of it.
fn where_markdown(d: &Diagnosis) -> String {
    let mut md = String::new();
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
    md
}

/// The candidates table (the whole model refitted with each), what is not applicable and the
/// residual's whiteness.
fn candidates_markdown(d: &Diagnosis) -> String {
    let mut md = String::new();
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
                    } else if c.material {
                        " (not significant on the training rows)"
                    } else {
                        " (not material)"
                    }
                ),
                format!("{:.1}", c.score),
                format!("{:.3}", c.holdout_rms_after_um),
                format!("{:.1}", c.shrink_pct),
                format!(
                    "{:.3} µm = {:.2} σ{}",
                    c.holdout_gain_um,
                    c.holdout_gain_um / c.noise_um,
                    if c.material { " ✓" } else { "" }
                ),
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
            "held-out gain (material ✓)",
            "parameters",
            "train p (Bonferroni)",
            "held-out p (not used: scales with rows)",
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
    md
}
