//! A positioning campaign from a measurement file to its judged table: the rows read and checked, the table
//! fitted (with an optional warm-up drift), judged by cross-validation or on held-out rows, and the
//! figures gathered as the `fit positioning` JSON. The command parses its options into a [`Request`] and
//! writes what [`fit_campaign`] returns; the report is [`crate::report`].
//!
//! Glossary:
//! - *raw*: the measured deviations, i.e. the axis without compensation.
//! - *judged rows*: the rows the figures are computed on: every row with cross-validation (each predicted by
//!   a model that did not see its run), only the held-out rows with `--holdout`.
//! - *after-figures*: ISO 230-2 of the judged runs with the predicted correction subtracted, as a
//!   compensated campaign would measure them (see [`crate::campaign_figures`]).
//! - *warm-up drift*: a deviation growing with the time since the axis was energised ([`crate::warmup`]).

use axcomp_data::sanity::{self, DataWarning};
use axcomp_data::{DataError, Dataset, Split};
use serde_json::{Value, json};

use crate::campaign_figures::{after_figures, per_run_json};
pub use crate::campaign_types::{Judged, Outcome, Request};
use crate::fit::{FitError, FitOptions, FitResult, Observation, Progress};
use crate::guard::{self, GuardVerdict};
use crate::warmup::{self, WarmupFit};
use axcomp_numeric::stats::rms;

/// Why a campaign cannot be fitted: a message naming the option, file, line or column at fault.
#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    #[error("{0}")]
    Input(String),
    #[error(transparent)]
    Data(#[from] DataError),
    #[error("{context}")]
    Context {
        context: String,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

impl CampaignError {
    fn context(
        context: impl Into<String>,
        source: impl Into<Box<dyn std::error::Error + Send + Sync>>,
    ) -> Self {
        CampaignError::Context {
            context: context.into(),
            source: source.into(),
        }
    }
}

fn input(msg: String) -> CampaignError {
    CampaignError::Input(msg)
}

/// A campaign read from its file: the observations and what the fit needs besides them.
#[derive(Debug)]
pub struct Campaign {
    x: Vec<f64>,
    dev: Vec<f64>,
    dir: Vec<i8>,
    run: Vec<i64>,
    run_labels: Vec<String>,
    cv_col: Option<String>,
    split: Option<Split>,
    holdout_mask: Option<Vec<bool>>,
    obs: Vec<Observation>,
    /// Data warnings (outliers, unit mixes, implausible magnitudes, one-sided direction coverage).
    pub warnings: Vec<DataWarning>,
    n_rows: usize,
    opts: FitOptions,
    ages: Option<Vec<f64>>,
}

impl Campaign {
    /// Reads the rows of `ds` (one campaign: one `test_id` and `axis`), checks them and lists the data
    /// warnings; [`Campaign::finish_reading`] takes the rest once the warnings are reported.
    pub fn read(ds: &Dataset, req: &Request) -> Result<Campaign, CampaignError> {
        sanity::single_campaign(ds, &["test_id", "axis"])?;
        let split = Split::from_args(req.holdout.as_deref(), req.cv.as_deref())?;
        let x = ds.numeric("target_mm")?.to_vec();
        let dev = ds.numeric(&req.target)?.to_vec();
        let dir = ds.direction()?.unwrap_or_else(|| vec![0; ds.n_rows()]);
        let cv_col: Option<String> = match &split {
            Some(Split::Cv(c)) => Some(c.clone()),
            _ if ds.has("run") => Some("run".to_string()),
            _ => None,
        };
        let (run, run_labels) = read_runs(ds, cv_col.as_deref())?;
        for (i, (&xi, &di)) in x.iter().zip(&dev).enumerate() {
            if !xi.is_finite() {
                return Err(input(format!(
                    "{}: target_mm is not finite",
                    ds.locate("target_mm", i)
                )));
            }
            if !di.is_finite() {
                return Err(input(format!(
                    "{}: {} is not finite",
                    ds.locate(&req.target, i),
                    req.target
                )));
            }
        }
        let holdout_mask = match &split {
            Some(Split::Holdout(h)) => Some(h.mask(ds)?),
            _ => None,
        };
        let obs: Vec<Observation> = (0..ds.n_rows())
            .map(|i| Observation {
                target_mm: x[i],
                direction: dir[i],
                run: run[i],
                deviation_um: dev[i],
            })
            .collect();
        let mut warnings = data_warnings(ds, &req.target, &x, &dev, &dir);
        warnings.extend(direction_coverage(&obs, holdout_mask.as_deref()));
        Ok(Campaign {
            x,
            dev,
            dir,
            run,
            run_labels,
            cv_col,
            split,
            holdout_mask,
            obs,
            warnings,
            n_rows: ds.n_rows(),
            opts: FitOptions::default(),
            ages: None,
        })
    }

    /// The axis name, the fit options and the warm-up ages (`--drift`): the last things taken from `ds`,
    /// which the caller may then drop before the fit.
    pub fn finish_reading(&mut self, ds: &Dataset, req: &Request) -> Result<(), CampaignError> {
        let axis = match &req.axis {
            Some(a) => a.clone(),
            None => match ds.text("axis") {
                Ok(t) if !t.is_empty() && t.iter().all(|v| *v == t[0]) => t[0].to_string(),
                _ => "X".to_string(),
            },
        };
        self.opts = FitOptions {
            axis,
            segments: req.segments,
            segment_mm: req.segment_mm,
            max_folds: req.max_folds,
            progress: Progress(req.progress),
            ..FitOptions::default()
        };
        if req.max_folds < 3 {
            return Err(input(format!(
                "--max-folds {}: needs at least 3",
                req.max_folds
            )));
        }
        self.ages = match &req.drift {
            Some(col) => Some(drift_ages(ds, col, req.run_period_s)?),
            None => None,
        };
        Ok(())
    }
}

/// Each row's run number (1-based, in the order of the labels) and the labels, from the grouping column.
fn read_runs(ds: &Dataset, cv_col: Option<&str>) -> Result<(Vec<i64>, Vec<String>), CampaignError> {
    let Some(c) = cv_col else {
        return Ok((vec![1; ds.n_rows()], vec!["all".to_string()]));
    };
    // An empty label would silently make its rows one more run.
    if let Some(row) = ds.text(c)?.iter().position(|t| t.trim().is_empty()) {
        return Err(input(format!(
            "{}: empty cell where the row's run (`{c}`) is required: every row needs one",
            ds.locate(c, row)
        )));
    }
    let (ids, labels) = axcomp_data::groups(ds, c)?;
    Ok((ids.into_iter().map(|g| g as i64 + 1).collect(), labels))
}

/// The table as fitted and judged, before the figures.
struct Judgement {
    fit: FitResult,
    judged: Judged,
    verdict: GuardVerdict,
    judged_rms: f64,
    method: String,
    warm_json: Value,
    kept_warmup: Option<WarmupFit>,
}

/// Fits the campaign's table (and warm-up drift), judges it and gathers the figures, the JSON and the
/// report. `provenance` is recorded in the table and the JSON.
pub fn fit_campaign(
    mut c: Campaign,
    req: &Request,
    provenance: axcomp_data::Provenance,
) -> Result<Outcome, CampaignError> {
    req.note("fitting the candidates (cross-validated)");
    let judgement = match &c.holdout_mask {
        None => judge_by_cv(&mut c, req)?,
        Some(mask) => judge_on_holdout(&c, req, mask)?,
    };
    let Judgement {
        mut fit,
        judged,
        verdict,
        judged_rms,
        method,
        warm_json,
        kept_warmup,
    } = judgement;
    if let (Some(Split::Cv(col)), false) = (&c.split, fit.split.method == "leave-one-run-out") {
        eprintln!(
            "axcomp: note: --cv {col} has fewer than 3 distinct values; cross-validated by {} folds of every k-th row instead",
            fit.split.folds
        );
    }
    let raw_rms = rms(judged.deviation.iter().copied());
    let residual: Vec<f64> = judged
        .deviation
        .iter()
        .zip(&judged.predicted)
        .map(|(d, p)| d - p)
        .collect();
    req.note("ISO 230-2 before and after");
    let figures = after_figures(
        &judged,
        &residual,
        &fit.fold_of_row,
        &c.run_labels,
        c.holdout_mask.is_some(),
    );
    let refused = !verdict.passed && !req.force;
    let per_run = per_run_json(&judged, &residual, &c.run_labels);
    let table_written = req.out.is_some() && !refused;
    let candidates: Vec<Value> = fit
        .candidates
        .iter()
        .map(|c| {
            json!({
                "name": c.name, "kind": c.kind.name(), "structure": c.structure.name(),
                "cv_rms_um": c.cv_rms_um, "rho": c.rho, "intervals": c.intervals,
            })
        })
        .collect();
    let mut j = json!({
        "command": "fit positioning",
        "data": req.data.display().to_string(),
        "target": req.target,
        "rows": c.n_rows,
        "rows_judged": judged.x.len(),
        "raw_rms_um": raw_rms,
        "iso230_2_before": figures.before,
        "iso230_2_after": figures.after,
        "iso230_2_after_method": figures.after_method,
        "iso230_2_per_fold": figures.per_fold,
        "iso230_2_after_fold_mean": figures.fold_mean,
        "iso230_2_after_caveats": figures.after_caveats,
        "warnings": c.warnings,
        "provenance": provenance,
        "model": {
            "chosen": fit.chosen,
            "reason": fit.reason,
            "selection": format!("lowest {} RMS on the fitting rows; near-ties (≤1 %) go to the simpler model", fit.split.method),
            "cv_method": fit.split.method,
            "cv_folds": fit.split.folds,
            "cv_rms_um_on_fitting_rows": fit.cv_rms_um,
            "candidates": candidates,
            "warmup": warm_json,
        },
        "cv": { "method": method, "column": c.cv_col, "folds": fit.split.folds, "max_folds": req.max_folds,
                 "grouped": fit.split.method == "leave-runs-out",
                 "note": if fit.split.method == "leave-runs-out" {
                     json!(format!("{} runs grouped into {} folds of consecutive runs (--max-folds)", c.run_labels.len(), fit.split.folds))
                 } else { Value::Null },
                 "per_run": per_run },
        "guard": guard_json(&verdict, refused, req.force),
        "table_written": table_written,
        "table": {
            "path": req.out.as_ref().map(|p| p.display().to_string()),
            "axis": fit.table.axis,
            "start_mm": fit.table.start_mm,
            "segment_mm": fit.table.segment_mm,
            "segments": fit.table.forward.len(),
            "bidirectional": !fit.table.backward.is_empty(),
            "resampling_max_um": fit.resampling_max_um,
        },
    });
    if c.holdout_mask.is_some() {
        j["holdout_rms_um"] = json!(judged_rms);
        j["holdout"] = json!(req.holdout);
    } else {
        j["cv_rms_um"] = json!(judged_rms);
    }
    fit.table.provenance = Some(provenance);
    let report = crate::report::report_markdown(req, &j, &fit, &verdict);
    Ok(Outcome {
        json: j,
        report,
        fit,
        judged,
        refused,
        warmup: kept_warmup,
        raw_rms_um: raw_rms,
        judged_rms_um: judged_rms,
    })
}

/// Cross-validation: every row is judged by the model of the fold that held its run out.
fn judge_by_cv(c: &mut Campaign, req: &Request) -> Result<Judgement, CampaignError> {
    let static_fit = crate::fit(&c.obs, &c.opts)
        .map_err(|e| CampaignError::context(req.data.display().to_string(), e))?;
    let (mut fit, kept, warm_json) =
        with_warmup(req, &c.obs, c.ages.as_deref(), &c.opts, static_fit)?;
    let (predicted, verdict, cv) = match &kept {
        Some(w) => (w.cv_predictions.clone(), w.guard.clone(), w.cv_rms_um),
        None => (
            std::mem::take(&mut fit.cv_predictions),
            fit.guard.clone(),
            fit.cv_rms_um,
        ),
    };
    let judged = Judged {
        // Moved, not copied: the judged rows are all rows (large campaigns).
        x: std::mem::take(&mut c.x),
        direction: std::mem::take(&mut c.dir),
        run: std::mem::take(&mut c.run),
        deviation: std::mem::take(&mut c.dev),
        predicted,
    };
    let method = fit.split.method.clone();
    Ok(Judgement {
        fit,
        judged,
        verdict,
        judged_rms: cv,
        method,
        warm_json,
        kept_warmup: kept,
    })
}

/// `--holdout`: the table fitted on the other rows, the held-out rows judged with the table the firmware
/// would apply (plus the drift).
fn judge_on_holdout(
    c: &Campaign,
    req: &Request,
    mask: &[bool],
) -> Result<Judgement, CampaignError> {
    let obs = &c.obs;
    let train_rows: Vec<usize> = (0..obs.len()).filter(|&i| !mask[i]).collect();
    let train: Vec<Observation> = train_rows.iter().map(|&i| obs[i]).collect();
    let static_fit = crate::fit(&train, &c.opts).map_err(|e: FitError| {
        CampaignError::context(
            format!("{}: fitting on the rows not held out", req.data.display()),
            e,
        )
    })?;
    let train_ages: Option<Vec<f64>> = c
        .ages
        .as_ref()
        .map(|a| train_rows.iter().map(|&i| a[i]).collect());
    let (mut fit, kept_warmup, warm_json) =
        with_warmup(req, &train, train_ages.as_deref(), &c.opts, static_fit)
            .map_err(|e| CampaignError::context("on the rows not held out", e))?;
    let idx: Vec<usize> = (0..obs.len()).filter(|&i| mask[i]).collect();
    let drift_at = |i: usize| match (&kept_warmup, &c.ages) {
        (Some(w), Some(a)) => w.warmup.offset_um(a[i]),
        _ => 0.0,
    };
    let judged = Judged {
        x: idx.iter().map(|&i| c.x[i]).collect(),
        direction: idx.iter().map(|&i| c.dir[i]).collect(),
        run: idx.iter().map(|&i| c.run[i]).collect(),
        deviation: idx.iter().map(|&i| c.dev[i]).collect(),
        predicted: idx
            .iter()
            .map(|&i| fit.table.deviation_um(c.x[i], c.dir[i]) + drift_at(i))
            .collect(),
    };
    let mut runs: Vec<i64> = judged.run.clone();
    runs.sort_unstable();
    runs.dedup();
    let fold: Vec<usize> = judged
        .run
        .iter()
        .map(|r| runs.binary_search(r).unwrap())
        .collect();
    let verdict = guard::judge(
        &judged.deviation,
        &judged.predicted,
        &fold,
        c.opts.improvement_ratio,
        c.opts.runs_improved_fraction,
        "holdout",
    );
    let hr = rms(judged
        .deviation
        .iter()
        .zip(&judged.predicted)
        .map(|(d, p)| d - p));
    fit.table.cv_rms_um = hr;
    fit.table.raw_rms_um = rms(judged.deviation.iter().copied());
    fit.table.cv_method = "holdout".into();
    Ok(Judgement {
        fit,
        judged,
        verdict,
        judged_rms: hr,
        method: "holdout".to_string(),
        warm_json,
        kept_warmup,
    })
}

/// Data warnings (see `axcomp_data::sanity`) on the error column and the targets.
fn data_warnings(
    ds: &Dataset,
    target: &str,
    x: &[f64],
    dev: &[f64],
    dir: &[i8],
) -> Vec<DataWarning> {
    let dir1: Vec<i8> = dir.iter().map(|&d| if d < 0 { -1 } else { 1 }).collect();
    let mut w = Vec::new();
    w.extend(sanity::unit_mix(ds, target, dev, Some((x, &dir1))));
    w.extend(sanity::unit_mix(ds, "target_mm", x, None));
    // An outlier test on mixed units would only repeat the unit finding row by row.
    if w.is_empty() {
        w.extend(sanity::per_target_outliers(ds, target, dev, x, &dir1));
    }
    w.extend(sanity::implausible_magnitude(
        ds,
        target,
        dev,
        5000.0,
        "a positioning error of more than 5 mm is not plausible in µm: nm, or not a deviation column?",
    ));
    w.extend(sanity::implausible_magnitude(
        ds,
        "target_mm",
        x,
        1.0e5,
        "targets beyond 100 m are not plausible in mm: µm?",
    ));
    w
}

/// A warning when one approach direction's targets, on the rows the table is fitted on (`held`: true =
/// held out), span less of the stroke than the other's: beyond its last targets the table holds that
/// direction's end value ([`crate::fit`]), a guess the data do not support.
fn direction_coverage(obs: &[Observation], held: Option<&[bool]>) -> Option<DataWarning> {
    let fitted: Vec<Observation> = match held {
        Some(h) => (0..obs.len()).filter(|&i| !h[i]).map(|i| obs[i]).collect(),
        None => obs.to_vec(),
    };
    let [Some(fwd), Some(bwd)] = crate::fit::direction_ranges(&fitted) else {
        return None;
    };
    let (lo, hi) = (fwd.0.min(bwd.0), fwd.1.max(bwd.1));
    let tol = 1e-9 * (hi - lo).abs().max(1.0);
    let short = [("positive", fwd), ("negative", bwd)]
        .into_iter()
        .find(|(_, (a, b))| *a > lo + tol || *b < hi - tol)?;
    let (name, (a, b)) = short;
    Some(DataWarning {
        kind: "direction_coverage",
        column: "target_mm".into(),
        message: format!(
            "the {name}-approach rows{} cover only {a} .. {b} mm of the stroke {lo} .. {hi} mm: the table \
             holds that direction's value at its last targets beyond them, which no reading supports; \
             measure both directions over the stroke, or leave out the targets only one direction reached",
            if held.is_some() {
                " fitted on (not held out)"
            } else {
                ""
            }
        ),
        lines: Vec::new(),
    })
}

/// With `--drift` (`ages` given): fits the warm-up drift on `obs` and keeps it when it lowers the CV RMS
/// on these rows by more than 1 % and is plausible as warm-up (smaller over the data than the raw error
/// itself; a larger "drift" is slip, lost steps or a moving reference far more often than warm-up, and must
/// not be extrapolated). Returns the fit to use (the drift-free static part when kept; its table's
/// `cv_rms_um` is the whole model's), the kept drift, and the `model.warmup` JSON (null without `--drift`).
fn with_warmup(
    req: &Request,
    obs: &[Observation],
    ages: Option<&[f64]>,
    opts: &FitOptions,
    static_fit: FitResult,
) -> Result<(FitResult, Option<WarmupFit>, Value), CampaignError> {
    let Some(ages) = ages else {
        return Ok((static_fit, None, Value::Null));
    };
    let w = warmup::fit_with_warmup(obs, ages, opts)
        .map_err(|e| CampaignError::context("fitting the warm-up drift (--drift)", e))?;
    let kept = w.cv_rms_um <= 0.99 * static_fit.cv_rms_um
        && w.drift_over_data_um.abs() <= static_fit.raw_rms_um;
    let j = warmup_json(req, &w, &static_fit, kept);
    if !kept {
        return Ok((static_fit, None, j));
    }
    let mut fit = w.static_part.clone();
    fit.table.cv_rms_um = w.cv_rms_um;
    fit.table.model = format!("{} + warmup_drift", fit.table.model);
    Ok((fit, Some(w), j))
}

/// Warm-up age (s) per row for `--drift COL`.
fn drift_ages(
    ds: &Dataset,
    col: &str,
    run_period_s: Option<f64>,
) -> Result<Vec<f64>, CampaignError> {
    let v = ds.numeric(col).map_err(|e| {
        CampaignError::context(format!("--drift {col}: the column must be numeric"), e)
    })?;
    if let Some(i) = v.iter().position(|a| !a.is_finite()) {
        return Err(input(format!(
            "{}: --drift {col}: not a finite number",
            ds.locate(col, i)
        )));
    }
    if col.ends_with("_s") {
        if run_period_s.is_some() {
            return Err(input(format!(
                "--run-period-s is for a run column; --drift {col} is already in seconds"
            )));
        }
        if let Some(i) = v.iter().position(|&a| a < 0.0) {
            return Err(input(format!(
                "{}: --drift {col}: {} s is before the axis was energised (ages must be ≥ 0)",
                ds.locate(col, i),
                v[i]
            )));
        }
        return Ok(v.to_vec());
    }
    let period = run_period_s.ok_or_else(|| {
        input(format!(
            "--drift {col}: `{col}` counts runs, not seconds; give --run-period-s (the duration of one run) \
             so the warm-up time constant comes out in seconds, or use a time_s column"
        ))
    })?;
    if !(period.is_finite() && period > 0.0) {
        return Err(input(format!(
            "--run-period-s {period}: must be a finite number of seconds > 0"
        )));
    }
    let first = v.iter().copied().fold(f64::INFINITY, f64::min);
    Ok(v.iter().map(|&r| (r - first + 0.5) * period).collect())
}

fn warmup_json(req: &Request, w: &WarmupFit, static_fit: &FitResult, kept: bool) -> Value {
    let static_cv = static_fit.cv_rms_um;
    let raw = static_fit.raw_rms_um;
    let why = if kept {
        format!(
            "kept: leave-one-run-out RMS {:.3} µm with the drift vs {:.3} µm without, and the drift over the \
             data ({:.2} µm) is within the raw RMS ({:.3} µm)",
            w.cv_rms_um, static_cv, w.drift_over_data_um, raw
        )
    } else if w.drift_over_data_um.abs() > raw {
        format!(
            "not kept: the fitted drift over the data ({:.2} µm) exceeds the raw RMS ({:.3} µm); a drift that \
             large is slip, lost steps or a moving reference more often than warm-up, and is not extrapolated",
            w.drift_over_data_um, raw
        )
    } else {
        format!(
            "not kept: leave-one-run-out RMS {:.3} µm with the drift is not more than 1 % below {:.3} µm without",
            w.cv_rms_um, static_cv
        )
    };
    json!({
        "column": req.drift,
        "kept": kept,
        "reason": why,
        "rule": "kept when the leave-one-run-out RMS with the drift is ≤ 0.99 × the static table's and the drift over the data is ≤ the raw RMS",
        "cv_rms_um_static": static_cv,
        "cv_rms_um_with_drift": w.cv_rms_um,
        "tau_s": w.warmup.tau,
        "drift_um": w.warmup.drift_um,
        "state_ref": w.warmup.state_ref,
        "drift_over_data_um": w.drift_over_data_um,
        "tau_per_fold_s": w.tau_per_fold,
        "tau_scores": w.warmup.tau_scores.iter().map(|(t, r)| json!({"tau_s": t, "cv_rms_um": r})).collect::<Vec<_>>(),
        "static_part": w.static_part.chosen,
        "model": "deviation = table(x, direction) + drift_um·(w − state_ref), w = 1 − exp(−age/tau_s)",
    })
}

fn guard_json(v: &GuardVerdict, refused: bool, forced: bool) -> Value {
    let mut g = serde_json::to_value(v).unwrap_or(Value::Null);
    g["refused"] = json!(refused);
    g["forced"] = json!(forced && !v.passed);
    g
}
