//! The `fit positioning` report: `report.md` (figures, candidates, guard, table) and the plots
//! `positioning.svg` (measured deviation and the fitted table per direction) and `residual.svg` (residual
//! after compensation per row and its range per target).
//!
//! Glossary:
//! - *judged rows*: the rows the figures are computed on (all rows under cross-validation, the held-out
//!   rows with `--holdout`); *after*: the judged rows minus the predicted correction.

use serde_json::Value;

use crate::campaign_types::{Outcome, Request};
use crate::fit::FitResult;
use crate::guard::GuardVerdict;

/// The files `--report DIR` holds.
pub const REPORT_FILES: [&str; 3] = ["report.md", "positioning.svg", "residual.svg"];

fn f3(v: &Value) -> String {
    v.as_f64().map_or("–".into(), |x| format!("{x:.3}"))
}

/// `report.md`: the data, the chosen model, the candidates, ISO 230-2 before and after, the warnings, the
/// guard, the table and the provenance.
pub fn report_markdown(
    req: &Request,
    j: &Value,
    fit: &FitResult,
    verdict: &GuardVerdict,
) -> String {
    let mut s = String::new();
    let judged = if req.holdout.is_some() {
        "holdout_rms_um"
    } else {
        "cv_rms_um"
    };
    s.push_str("# Positioning table fit\n\n");
    s.push_str(&format!(
        "Data: `{}` ({} rows",
        req.data.display(),
        j["rows"]
    ));
    if !req.where_.is_empty() {
        s.push_str(&format!(", where {}", req.where_.join(", ")));
    }
    s.push_str(&format!("), error column `{}`.\n\n", req.target));
    s.push_str(&format!(
        "Judged by **{}** ({} folds). Raw RMS **{} µm**, after compensation **{} µm** ({}).\n\n",
        j["cv"]["method"].as_str().unwrap_or(""),
        fit.split.folds,
        f3(&j["raw_rms_um"]),
        f3(&j[judged]),
        judged
    ));
    s.push_str(&format!(
        "Chosen model: **{}**: {}.\n\n",
        fit.chosen, fit.reason
    ));
    warmup_section(&mut s, j);
    candidates_section(&mut s, fit);
    iso_section(&mut s, j);
    guard_and_table_section(&mut s, req, j, fit, verdict);
    s
}

/// The warm-up drift, when `--drift` was given.
fn warmup_section(s: &mut String, j: &Value) {
    if let Some(w) = j["model"]["warmup"].as_object() {
        s.push_str("## Warm-up drift\n\n");
        s.push_str(&format!(
            "Model: `{}`, age from `--drift {}`. τ = {:.0} s, drift_um (cold → warm) = {:.3} µm, reference state \
             {:.3}; fitted drift over the data {:.2} µm. Leave-one-run-out RMS {} µm with the drift, {} µm \
             with the static table alone (τ chosen again inside every fold: {}).\n\n**{}**\n\n",
            w["model"].as_str().unwrap_or(""),
            w["column"].as_str().unwrap_or(""),
            w["tau_s"].as_f64().unwrap_or(f64::NAN),
            w["drift_um"].as_f64().unwrap_or(f64::NAN),
            w["state_ref"].as_f64().unwrap_or(f64::NAN),
            w["drift_over_data_um"].as_f64().unwrap_or(f64::NAN),
            f3(&w["cv_rms_um_with_drift"]),
            f3(&w["cv_rms_um_static"]),
            w["tau_per_fold_s"]
                .as_array()
                .map(|a| a
                    .iter()
                    .filter_map(Value::as_f64)
                    .map(|t| format!("{t:.0} s"))
                    .collect::<Vec<_>>()
                    .join(", "))
                .unwrap_or_default(),
            w["reason"].as_str().unwrap_or(""),
        ));
        if w["kept"] == true {
            s.push_str(
                "The table below holds the deviation at the reference state; the drive adds \
                 drift_um·(w − reference) from its `warmup` input (0 de-energised, 1 energised) lagged by τ \
                 (`--drift-model`, then `axcomp image build --thermal`). The candidates' CV figures are those \
                 of the static part on the data minus the drift.\n\n",
            );
        }
    }
}

/// The candidates and their cross-validated RMS.
fn candidates_section(s: &mut String, fit: &FitResult) {
    s.push_str("## Candidates (cross-validated on the fitting rows)\n\n");
    let rows: Vec<Vec<String>> = fit
        .candidates
        .iter()
        .map(|c| {
            vec![
                c.name.clone(),
                format!("{:.3}", c.cv_rms_um),
                if c.rho.is_empty() {
                    "–".into()
                } else {
                    c.rho
                        .iter()
                        .map(|r| format!("{r:.1e}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                },
                c.intervals.to_string(),
                if c.name == fit.chosen {
                    "chosen".into()
                } else {
                    String::new()
                },
            ]
        })
        .collect();
    s.push_str(&axcomp_plot::markdown_table(
        &[
            "model",
            "CV RMS / µm",
            "ρ (CV-chosen)",
            "knot intervals",
            "",
        ],
        &rows,
    ));
}

/// ISO 230-2 before and after, with the reasons of what is undefined.
fn iso_section(s: &mut String, j: &Value) {
    let bidirectional = j["iso230_2_before"]["bidirectional"] == true;
    let directions = j["iso230_2_before"]["directions"].as_str().unwrap_or("");
    if bidirectional {
        s.push_str("\n## ISO 230-2 (bidirectional), judged rows\n\n");
    } else {
        s.push_str(&format!(
            "\n## ISO 230-2 ({}), judged rows\n\nThe data holds {directions} approaches: unidirectional figures \
             only; the bidirectional ones (A, E, M, R, B) are not defined (–).\n\n",
            if directions.is_empty() { "not evaluable" } else { "unidirectional" }
        ));
    }
    let keys = if bidirectional {
        vec!["A_um", "E_um", "M_um", "R_um", "B_um"]
    } else if directions == "negative only" {
        vec!["A_down_um", "E_down_um", "R_down_um"]
    } else {
        vec!["A_up_um", "E_up_um", "R_up_um"]
    };
    let has_fold_mean = j["iso230_2_after_fold_mean"].is_object();
    let iso_rows: Vec<Vec<String>> = keys
        .iter()
        .map(|k| {
            let mut row = vec![
                k.to_string(),
                f3(&j["iso230_2_before"][k]),
                f3(&j["iso230_2_after"][k]),
            ];
            if has_fold_mean {
                row.push(f3(&j["iso230_2_after_fold_mean"][k]));
            }
            row
        })
        .collect();
    let mut header = vec!["figure", "before / µm", "after / µm"];
    if has_fold_mean {
        header = vec![
            "figure",
            "before / µm",
            "after, pooled / µm",
            "after, mean of folds / µm",
        ];
    }
    s.push_str(&axcomp_plot::markdown_table(&header, &iso_rows));
    if let Some(c) = j["iso230_2_after_caveats"].as_object() {
        for k in &keys {
            if let Some(why) = c.get(*k).and_then(Value::as_str) {
                s.push_str(&format!(
                    "
iso230_2_after.{k}: {why}.
"
                ));
            }
        }
    }
    for part in [
        "iso230_2_before",
        "iso230_2_after",
        "iso230_2_after_fold_mean",
    ] {
        if let Some(e) = j[part]["error"].as_str() {
            s.push_str(&format!("\n{part}: not evaluable on these rows: {e}\n"));
        }
        if let Some(r) = j[part]["null_reasons"].as_object() {
            for k in &keys {
                if let Some(why) = r.get(*k).and_then(Value::as_str) {
                    s.push_str(&format!("\n{part}.{k} is not defined: {why}.\n"));
                }
            }
        }
    }
    s.push_str(&format!(
        "\n“After”: {}. A static correction leaves the scatter between runs as it is, so R after should be \
         about R before; A after contains the held-out runs' own scatter and their offset from the runs the model \
         was fitted on (drift between runs).\n",
        j["iso230_2_after_method"].as_str().unwrap_or("")
    ));
}

/// The data warnings, the do-no-harm guard, the table and the provenance.
fn guard_and_table_section(
    s: &mut String,
    req: &Request,
    j: &Value,
    fit: &FitResult,
    verdict: &GuardVerdict,
) {
    if let Some(w) = j["warnings"].as_array().filter(|w| !w.is_empty()) {
        s.push_str("\n## Data warnings\n\n");
        for x in w {
            s.push_str(&format!("- {}\n", x["message"].as_str().unwrap_or("")));
        }
    }
    s.push_str("\n## Do-no-harm guard\n\n");
    s.push_str(&format!("Rule: {}.\n\n", verdict.rule));
    s.push_str(&format!(
        "Ratio {:.3}; runs improved {} of {}. ",
        verdict.ratio, verdict.runs_improved, verdict.runs
    ));
    if verdict.passed {
        s.push_str("**Passed.**\n");
    } else {
        s.push_str(&format!(
            "**Refused**{}:\n\n",
            if req.force {
                " (overridden by --force)"
            } else {
                ""
            }
        ));
        for r in &verdict.reasons {
            s.push_str(&format!("- {r}\n"));
        }
    }
    s.push_str(&format!(
        "\n## Table\n\n{} uniform segments of {:.4} mm from {:.4} mm ({}), resampling error ≤ {:.2e} µm. Written: {}.\n",
        fit.table.forward.len(),
        fit.table.segment_mm,
        fit.table.start_mm,
        if fit.table.backward.is_empty() { "one table" } else { "forward and backward" },
        fit.resampling_max_um,
        j["table_written"]
    ));
    s.push_str("\nPlots: `positioning.svg` (measured deviation and the fitted table per direction), `residual.svg` (residual after compensation per row and its range per target).\n");
    if let Some(p) = j["provenance"].as_object() {
        s.push_str(&format!(
            "\n## Provenance\n\nData SHA-256 `{}` ({} bytes); written by {} on {} (also in the table file).\n",
            p["source_sha256"].as_str().unwrap_or(""),
            p["source_bytes"],
            p["tool"].as_str().unwrap_or(""),
            p["created_utc"].as_str().unwrap_or("")
        ));
    }
}

/// What the plots are about: the `--where` filters, else the data file's name.
fn data_label(req: &Request) -> String {
    if req.where_.is_empty() {
        req.data.file_name().map_or_else(
            || req.data.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        )
    } else {
        req.where_
            .iter()
            .map(|w| w.split_once('=').map_or(w.as_str(), |(_, v)| v))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Colours per approach direction (the same in every plot): forward/positive, backward/negative, one table.
const DIRECTION_COLOURS: [&str; 3] = [
    axcomp_plot::PALETTE[0],
    axcomp_plot::PALETTE[1],
    axcomp_plot::PALETTE[2],
];

/// `report.md`, `positioning.svg` and `residual.svg` (the names in [`REPORT_FILES`]).
pub fn report_files(req: &Request, o: &Outcome) -> Vec<(&'static str, Vec<u8>)> {
    let j = &o.judged;
    let table = &o.fit.table;
    let lo =
        j.x.iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
            .min(table.start_mm);
    let hi =
        j.x.iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max)
            .max(table.end_mm());
    let xs: Vec<f64> = (0..=400)
        .map(|k| lo + (hi - lo) * k as f64 / 400.0)
        .collect();
    let judged_key = if req.holdout.is_some() {
        "holdout"
    } else {
        "CV"
    };
    let raw = o.json["raw_rms_um"].as_f64().unwrap_or(f64::NAN);
    let after = o.json[if req.holdout.is_some() {
        "holdout_rms_um"
    } else {
        "cv_rms_um"
    }]
    .as_f64()
    .unwrap_or(f64::NAN);
    let label = data_label(req);
    let mut fig = axcomp_plot::Figure::new(
        &format!(
            "{label}: measured deviation and fitted table ({}, {judged_key} RMS {after:.2} µm, raw {raw:.2} µm)",
            o.fit.chosen
        ),
        "target position (mm)",
        "deviation (µm)",
    );
    let mut res = axcomp_plot::Figure::new(
        &format!(
            "{label}: residual after compensation, each row predicted by a model that did not see it ({judged_key} RMS {after:.2} µm)"
        ),
        "target position (mm)",
        "residual (µm)",
    );
    let bidir = !table.backward.is_empty();
    let has_dir = j.direction.iter().any(|&d| d != 0);
    let dirs: Vec<(i8, &str, &str)> = if bidir {
        vec![
            (1, "forward (+)", DIRECTION_COLOURS[0]),
            (-1, "backward (−)", DIRECTION_COLOURS[1]),
        ]
    } else if has_dir && j.direction.iter().all(|&d| d == j.direction[0]) {
        let name = if j.direction[0] < 0 {
            "backward (−)"
        } else {
            "forward (+)"
        };
        vec![(
            j.direction[0],
            name,
            DIRECTION_COLOURS[usize::from(j.direction[0] < 0)],
        )]
    } else {
        vec![(1, "both directions", DIRECTION_COLOURS[2])]
    };
    for &(d, name, colour) in &dirs {
        let sel: Vec<usize> = (0..j.x.len())
            .filter(|&i| !bidir || (j.direction[i] < 0) == (d < 0))
            .collect();
        let px: Vec<f64> = sel.iter().map(|&i| j.x[i]).collect();
        let py: Vec<f64> = sel.iter().map(|&i| j.deviation[i]).collect();
        let ry: Vec<f64> = sel
            .iter()
            .map(|&i| j.deviation[i] - j.predicted[i])
            .collect();
        let ty: Vec<f64> = xs.iter().map(|&x| table.deviation_um(x, d)).collect();
        fig.points(&format!("measured {name}"), &px, &py)
            .with_colour(colour);
        fig.line(&format!("table {name}"), &xs, &ty)
            .with_colour(colour);
        // Residual range per target (or per bin for scattered positions).
        let (bx, blo, bhi) = residual_band(&px, &ry, lo, hi);
        if !bx.is_empty() {
            res.band(&format!("range {name}"), &bx, &blo, &bhi)
                .with_colour(colour);
        }
        res.points(&format!("residual {name}"), &px, &ry)
            .with_colour(colour);
    }
    fig.hline(0.0, "");
    res.hline(0.0, "");
    vec![
        ("report.md", o.report.clone().into_bytes()),
        ("positioning.svg", fig.to_svg().into_bytes()),
        ("residual.svg", res.to_svg().into_bytes()),
    ]
}

/// Min/max of the residuals per distinct position (≤ 64 positions) or per bin of 40 equal bins.
fn residual_band(x: &[f64], r: &[f64], lo: f64, hi: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut uniq: Vec<f64> = x.to_vec();
    uniq.sort_by(f64::total_cmp);
    uniq.dedup();
    let (centers, key): (Vec<f64>, Box<dyn Fn(f64) -> usize>) = if uniq.len() <= 64 {
        let u = uniq.clone();
        (
            uniq,
            Box::new(move |v| u.partition_point(|&k| k < v).min(u.len() - 1)),
        )
    } else {
        let bins = 40;
        let w = (hi - lo) / bins as f64;
        (
            (0..bins).map(|b| lo + w * (b as f64 + 0.5)).collect(),
            Box::new(move |v| (((v - lo) / w) as usize).min(bins - 1)),
        )
    };
    if centers.is_empty() {
        return (vec![], vec![], vec![]);
    }
    let mut blo = vec![f64::INFINITY; centers.len()];
    let mut bhi = vec![f64::NEG_INFINITY; centers.len()];
    for (&xi, &ri) in x.iter().zip(r) {
        let k = key(xi);
        blo[k] = blo[k].min(ri);
        bhi[k] = bhi[k].max(ri);
    }
    let keep: Vec<usize> = (0..centers.len()).filter(|&k| blo[k].is_finite()).collect();
    (
        keep.iter().map(|&k| centers[k]).collect(),
        keep.iter().map(|&k| blo[k]).collect(),
        keep.iter().map(|&k| bhi[k]).collect(),
    )
}
