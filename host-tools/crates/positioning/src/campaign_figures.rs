//! ISO 230-2 figures of a judged campaign before and after compensation, per fold and pooled, and the
//! per-run RMS: the figure parts of the `fit positioning` JSON.
//!
//! Glossary:
//! - *after-figures*: ISO 230-2 of the judged runs with the predicted correction subtracted, as a
//!   compensated campaign would measure them: with `--holdout` the held-out runs and the table fitted
//!   without them; with cross-validation each fold's held-out runs and the model fitted without them,
//!   pooled (`iso230_2_after`: every run corrected by a model that never saw it, so A and R are defined
//!   when the campaign has ≥ 2 runs per target and direction), and per fold (`iso230_2_per_fold`) with
//!   their mean (`iso230_2_after_fold_mean`). A figure the runs cannot define is `null` with its reason.

use serde_json::{Value, json};

use crate::campaign_types::Judged;
use crate::iso230::{self, Iso230Figures};
use axcomp_numeric::stats::rms;

/// The ISO 230-2 parts of the JSON, each already in its JSON form.
#[derive(Debug, Clone)]
pub struct AfterFigures {
    pub before: Value,
    pub after: Value,
    pub after_method: String,
    pub per_fold: Value,
    pub fold_mean: Value,
    pub after_caveats: Value,
}

fn iso(x: &[f64], d: &[i8], dev: &[f64]) -> Result<Iso230Figures, String> {
    iso230::figures_of_columns(x, d, dev).map_err(|e| e.to_string())
}

fn iso_json(r: &Result<Iso230Figures, String>) -> Value {
    match r {
        Ok(v) => serde_json::to_value(v).unwrap_or(Value::Null),
        Err(e) => json!({ "error": e }),
    }
}

/// Before: the judged rows' deviations. After: with a holdout the held-out runs minus the table; with CV
/// every run minus the model fitted without it, pooled (each fold's figures and their mean beside it).
pub fn after_figures(
    judged: &Judged,
    residual: &[f64],
    fold_of_row: &[usize],
    run_labels: &[String],
    holdout: bool,
) -> AfterFigures {
    let before = iso(&judged.x, &judged.direction, &judged.deviation);
    if holdout {
        return AfterFigures {
            before: iso_json(&before),
            after: iso_json(&iso(&judged.x, &judged.direction, residual)),
            after_method:
                "ISO 230-2 of the held-out runs with the table's predicted correction subtracted"
                    .into(),
            per_fold: Value::Null,
            fold_mean: Value::Null,
            after_caveats: Value::Null,
        };
    }
    let n_folds = fold_of_row.iter().copied().max().map_or(0, |m| m + 1);
    let mut per_fold = Vec::new();
    let mut figs = Vec::new();
    for f in 0..n_folds {
        let rows: Vec<usize> = (0..judged.x.len())
            .filter(|&i| fold_of_row[i] == f)
            .collect();
        if rows.is_empty() {
            continue;
        }
        let pick = |v: &[f64]| rows.iter().map(|&i| v[i]).collect::<Vec<f64>>();
        let fx = pick(&judged.x);
        let fd: Vec<i8> = rows.iter().map(|&i| judged.direction[i]).collect();
        let fr: Vec<i64> = rows.iter().map(|&i| judged.run[i]).collect();
        let b = iso(&fx, &fd, &pick(&judged.deviation));
        let a = iso(&fx, &fd, &pick(residual));
        let mut labels: Vec<&str> = fr
            .iter()
            .map(|&r| run_labels.get((r - 1) as usize).map_or("?", |s| s.as_str()))
            .collect();
        labels.dedup();
        labels.sort_unstable();
        labels.dedup();
        per_fold.push(json!({
            "fold": f + 1, "runs": labels, "rows": rows.len(),
            "before": iso_json(&b), "after": iso_json(&a),
        }));
        figs.push(a);
    }
    let fold_mean = mean_figures(&figs);
    let (pooled, after_caveats) = pooled_after(&judged.x, &judged.direction, residual);
    AfterFigures {
        before: iso_json(&before),
        after: iso_json(&pooled),
        after_method: format!(
            "ISO 230-2 of every run with the correction predicted by the model of the fold that held it \
             out, pooled over the {} folds: a compensated campaign none of whose runs its model saw \
             (the per-fold figures and their mean are beside it)",
            figs.len()
        ),
        per_fold: Value::Array(per_fold),
        fold_mean: iso_json(&fold_mean),
        after_caveats,
    }
}

/// ISO 230-2 of the pooled held-out residuals of every fold, with the caveats of its figures. The figures
/// built on each target's mean deviation (E, M, B) are kept but flagged when every target's mean residual is
/// the same to rounding: the folds' models then took each target's value from the other runs (a table
/// through every target, leave-one-out), which makes those means equal by construction, not by
/// compensation; their fold mean (`iso230_2_after_fold_mean`) is the conservative figure then.
fn pooled_after(x: &[f64], d: &[i8], residual: &[f64]) -> (Result<Iso230Figures, String>, Value) {
    let out = iso(x, d, residual);
    let mut sums: std::collections::BTreeMap<(i64, i8), (f64, usize)> = Default::default();
    for ((&xi, &di), &r) in x.iter().zip(d).zip(residual) {
        let e = sums
            .entry(((xi * 1e6).round() as i64, di.signum()))
            .or_insert((0.0, 0));
        (e.0, e.1) = (e.0 + r, e.1 + 1);
    }
    let means: Vec<f64> = sums.values().map(|&(s, n)| s / n as f64).collect();
    let scale = residual.iter().map(|r| r.abs()).sum::<f64>() / residual.len().max(1) as f64;
    let (lo, hi) = means
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &m| {
            (l.min(m), h.max(m))
        });
    let mut caveats = serde_json::Map::new();
    if means.len() >= 2 && hi - lo <= 1e-9 * scale.max(1e-12) {
        let why = "equal target means by construction: each fold's model took every target's value from the \
                   other runs, so the pooled means differ only by rounding; iso230_2_after_fold_mean is the \
                   conservative figure";
        for name in ["E_um", "M_um", "B_um", "B_mean_um", "E_up_um", "E_down_um"] {
            caveats.insert(name.into(), Value::String(why.into()));
        }
    }
    (out, Value::Object(caveats))
}

/// The mean of each figure over the folds; `None` (with the first fold's reason) when any fold lacks it.
fn mean_figures(folds: &[Result<Iso230Figures, String>]) -> Result<Iso230Figures, String> {
    let ok: Vec<&Iso230Figures> = folds.iter().filter_map(|f| f.as_ref().ok()).collect();
    if ok.len() != folds.len() || ok.is_empty() {
        return Err(folds
            .iter()
            .find_map(|f| f.as_ref().err().cloned())
            .unwrap_or_else(|| "no folds".into()));
    }
    let mut out = ok[0].clone();
    let mut reasons = std::collections::BTreeMap::new();
    for name in Iso230Figures::NAMES {
        let v: Vec<Option<f64>> = ok.iter().map(|f| f.get(name)).collect();
        let mean = if v.iter().all(Option::is_some) {
            Some(v.iter().flatten().sum::<f64>() / v.len() as f64)
        } else {
            let why = ok
                .iter()
                .find_map(|f| f.null_reasons.get(name).cloned())
                .unwrap_or_default();
            reasons.insert(name, format!("undefined in a fold: {why}"));
            None
        };
        match name {
            "A_um" => out.a_um = mean,
            "E_um" => out.e_um = mean,
            "M_um" => out.m_um = mean,
            "R_um" => out.r_um = mean,
            "B_um" => out.b_um = mean,
            "B_mean_um" => out.b_mean_um = mean,
            "A_up_um" => out.a_up_um = mean,
            "A_down_um" => out.a_down_um = mean,
            "E_up_um" => out.e_up_um = mean,
            "E_down_um" => out.e_down_um = mean,
            "R_up_um" => out.r_up_um = mean,
            _ => out.r_down_um = mean,
        }
    }
    out.min_runs_per_target = ok.iter().map(|f| f.min_runs_per_target).min().unwrap_or(0);
    out.null_reasons = reasons;
    Ok(out)
}

/// Per run: raw and judged RMS and the mean residual (a drifting mean shows drift between runs).
pub fn per_run_json(judged: &Judged, residual: &[f64], run_labels: &[String]) -> Vec<Value> {
    let mut rows_of_run: Vec<Vec<usize>> = vec![Vec::new(); run_labels.len()];
    for (i, &r) in judged.run.iter().enumerate() {
        if let Some(v) = rows_of_run.get_mut((r - 1) as usize) {
            v.push(i);
        }
    }
    run_labels
        .iter()
        .zip(&rows_of_run)
        .filter_map(|(label, rows)| {
            if rows.is_empty() {
                return None;
            }
            let r: Vec<f64> = rows.iter().map(|&i| residual[i]).collect();
            Some(json!({
                "run": label,
                "rows": rows.len(),
                "raw_rms_um": rms(rows.iter().map(|&i| judged.deviation[i])),
                "rms_um": rms(r.iter().copied()),
                "mean_residual_um": r.iter().sum::<f64>() / r.len() as f64,
            }))
        })
        .collect()
}
