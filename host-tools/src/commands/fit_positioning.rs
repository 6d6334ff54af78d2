//! `axcomp fit positioning`: fit a positioning-error table from ISO 230-2 style runs.
//!
//! Glossary:
//! - *raw*: the measured deviations, i.e. the axis without compensation.
//! - *judged rows*: the rows the figures are computed on: every row with cross-validation (each predicted by
//!   a model that did not see its run), only the held-out rows with `--holdout`.
//! - *guard*: the do-no-harm rule (see `axcomp_positioning::guard`); when it refuses, no table is written
//!   (unless `--force`), the JSON says `"table_written": false` and the exit code is 3.
//!
//! - *data warnings*: per-target outliers, unit mixes and implausible magnitudes (`axcomp_data::sanity`),
//!   and an approach direction measured over part of the stroke only (its curve would be extrapolated);
//!   printed on stderr and listed in the JSON (`warnings`); `--strict` refuses the data (exit 2). A file
//!   holding several `test_id` or `axis` values is always refused: choose one with `--where`.
//! - *after-figures*: ISO 230-2 of the judged runs with the predicted correction subtracted, as a
//!   compensated campaign would measure them: with `--holdout` the held-out runs and the table fitted
//!   without them; with cross-validation each fold's held-out runs and the model fitted without them,
//!   pooled (`iso230_2_after`: every run corrected by a model that never saw it, so A and R are defined
//!   when the campaign has ≥ 2 runs per target and direction), and per fold (`iso230_2_per_fold`) with
//!   their mean (`iso230_2_after_fold_mean`). A figure the runs cannot define is `null` with its reason.
//!
//! Outputs: `--out` the table (`axcomp-positioning-table/1` JSON, with its provenance), `--json` the
//! figures, `--report DIR` a Markdown report and SVG plots. All of them are written together or none
//! (`crate::output::OutputSet`): a bad output path fails before the fit, and nothing is changed.

use std::path::PathBuf;

use anyhow::{Context, bail};
use axcomp_data::sanity::{self, DataWarning};
use axcomp_data::{Dataset, LoadOptions, Split};
use axcomp_positioning::fit::{FitOptions, FitResult, Observation};
use axcomp_positioning::guard::{self, GuardVerdict};
use axcomp_positioning::iso230::{self, Iso230Figures};
use axcomp_positioning::warmup::{self, WarmupFit};
use axcomp_thermal::model_file::{self, ModelSensor, ThermalModelFile};
use serde_json::{Value, json};

use crate::cli::DataArgs;
use crate::output::OutputSet;

/// Exit code when the do-no-harm guard refuses to write a table.
pub use crate::EXIT_GUARD_REFUSED;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub data: DataArgs,
    /// Rows held out from fitting and used only to judge: `COL=V1,V2,..`, `COL>=X`, `COL<X`.
    #[arg(long, value_name = "SPEC", conflicts_with = "cv")]
    pub holdout: Option<String>,
    /// Leave-one-group-out cross-validation over the values of COL (default: `run`/`cycle` when present).
    #[arg(long, value_name = "COL")]
    pub cv: Option<String>,
    /// The error column to model.
    #[arg(long, value_name = "COL", default_value = "deviation_um")]
    pub target: String,
    /// Write the table here (`axcomp-positioning-table/1` JSON).
    #[arg(long, value_name = "TABLE.json")]
    pub out: Option<PathBuf>,
    /// Write the figures as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write a Markdown report and SVG plots into DIR.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Number of uniform table segments (1..=1024).
    #[arg(long, value_name = "N", conflicts_with = "segment_mm")]
    pub segments: Option<usize>,
    /// Table segment length in mm.
    #[arg(long, value_name = "S")]
    pub segment_mm: Option<f64>,
    /// Axis name written into the table (default: the `axis` column when it holds one value, else X).
    #[arg(long)]
    pub axis: Option<String>,
    /// Write the table even when the do-no-harm guard refuses.
    #[arg(long)]
    pub force: bool,
    /// Also model a warm-up drift along COL: `time_s` (seconds since the axis was energised), or the run
    /// column when the runs were measured back to back at a steady pace (then give --run-period-s). The
    /// drift is kept only if it lowers the cross-validated RMS by more than 1 %.
    #[arg(long, value_name = "COL")]
    pub drift: Option<String>,
    /// Duration of one run in seconds, for --drift on a run column: run r is taken as measured at
    /// (r − first run + ½)·period after the axis was energised.
    #[arg(long, value_name = "S", requires = "drift")]
    pub run_period_s: Option<f64>,
    /// Write the warm-up drift as a thermal model file for `axcomp image build --thermal`. Its one input,
    /// `warmup`, must read 0 while the axis is cold or de-energised and 1 while it is energised; the
    /// firmware lags it by the fitted time constant.
    #[arg(long, value_name = "MODEL.json", requires = "drift")]
    pub drift_model: Option<PathBuf>,
    /// Rate at which the drive feeds the `warmup` input, for --drift-model.
    #[arg(long, value_name = "MS", default_value_t = 100)]
    pub drift_period_ms: u32,
    /// Treat data warnings (outliers, mixed units, implausible magnitudes) as errors (exit code 2).
    #[arg(long)]
    pub strict: bool,
    /// At most this many cross-validation folds; with more runs, consecutive runs are grouped.
    #[arg(long, value_name = "N", default_value_t = axcomp_positioning::fit::DEFAULT_MAX_FOLDS)]
    pub max_folds: usize,
}

/// Everything the command computed, before anything is written.
struct Outcome {
    json: Value,
    /// Data warnings (already printed on stderr).
    #[allow(dead_code)]
    warnings: Vec<DataWarning>,
    /// The warm-up drift as a thermal model file, when the drift was kept and --drift-model asks for it.
    drift_model: Option<ThermalModelFile>,
    report: String,
    fit: FitResult,
    judged: Judged,
    refused: bool,
}

/// The rows the figures are computed on, with their predictions.
struct Judged {
    x: Vec<f64>,
    direction: Vec<i8>,
    run: Vec<i64>,
    deviation: Vec<f64>,
    predicted: Vec<f64>,
}

/// The output files, declared before the work so that a bad path fails first.
fn planned_outputs(args: &Args) -> OutputSet {
    let mut set = OutputSet::new();
    set.input(&args.data.data);
    if let Some(p) = &args.out {
        set.planned(p);
    }
    if let Some(p) = &args.drift_model {
        set.planned(p);
    }
    if let Some(dir) = &args.report {
        set.folder(dir, "--report");
        for name in REPORT_FILES {
            set.planned_in(dir, name);
        }
    }
    if let Some(p) = &args.json {
        set.planned(p);
    }
    set
}

/// The files `--report DIR` holds.
const REPORT_FILES: [&str; 3] = ["report.md", "positioning.svg", "residual.svg"];

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut outputs = planned_outputs(&args);
    outputs.check()?;
    let t0 = std::time::Instant::now();
    let outcome = compute(&args)?;
    // Outputs: the table only when the guard passed (or --force); JSON and report always.
    if let Some(out) = &args.out {
        if !outcome.refused {
            let text = outcome
                .fit
                .table
                .to_json_string()
                .with_context(|| format!("the table for {}", out.display()))?;
            outputs.file(out, text);
        }
    }
    if let (Some(path), Some(model), false) =
        (&args.drift_model, &outcome.drift_model, outcome.refused)
    {
        model
            .validate()
            .map_err(|e| anyhow::anyhow!("the warm-up drift model for {}: {e}", path.display()))?;
        match &outcome.fit.table.provenance {
            Some(p) => outputs.file(path, crate::provenance::stamp(model, p)?),
            None => outputs.json(path, model)?,
        };
    }
    if let Some(dir) = &args.report {
        let big = outcome.judged.x.len() >= PROGRESS_ROWS;
        if big {
            eprintln!(
                "axcomp: [{:.1} s{}] drawing the report ({} rows)",
                t0.elapsed().as_secs_f64(),
                crate::output::peak_memory_note(),
                outcome.judged.x.len()
            );
        }
        for (name, bytes) in report_files(&args, &outcome) {
            outputs.folder_file(dir, name, bytes);
        }
    }
    if let Some(path) = &args.json {
        outputs.json(path, &outcome.json)?;
    }
    let written = outputs.commit()?;
    let written: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    let j = &outcome.json;
    let judged_key = if args.holdout.is_some() {
        "holdout_rms_um"
    } else {
        "cv_rms_um"
    };
    println!(
        "model {}: raw RMS {:.3} µm, {} {:.3} µm ({})",
        outcome.fit.chosen,
        j["raw_rms_um"].as_f64().unwrap_or(f64::NAN),
        judged_key,
        j[judged_key].as_f64().unwrap_or(f64::NAN),
        j["cv"]["method"].as_str().unwrap_or("")
    );
    if !written.is_empty() {
        println!("wrote {}", written.join(", "));
    }
    if outcome.refused {
        let reasons = j["guard"]["reasons"]
            .as_array()
            .map(|r| {
                r.iter()
                    .filter_map(|v| v.as_str())
                    .collect::<Vec<_>>()
                    .join("; ")
            })
            .unwrap_or_default();
        let hint = if args.out.is_some() {
            " (use --force to write it anyway)"
        } else {
            ""
        };
        return Err(crate::Refused {
            code: crate::EXIT_GUARD_REFUSED,
            reason: format!("do-no-harm guard refused to write a table: {reasons}{hint}"),
        }
        .into());
    }
    Ok(())
}

use axcomp_positioning::fit::rms;

fn iso(x: &[f64], d: &[i8], _run: &[i64], dev: &[f64]) -> Result<Iso230Figures, String> {
    iso230::figures_of_columns(x, d, dev).map_err(|e| e.to_string())
}

/// ISO 230-2 of the pooled held-out residuals of every fold, with the caveats of its figures. The figures
/// built on each target's mean deviation (E, M, B) are kept but flagged when every target's mean residual is
/// the same to rounding: the folds' models then took each target's value from the other runs (a table
/// through every target, leave-one-out), which makes those means equal by construction, not by
/// compensation; their fold mean (`iso230_2_after_fold_mean`) is the conservative figure then.
fn pooled_after(x: &[f64], d: &[i8], residual: &[f64]) -> (Result<Iso230Figures, String>, Value) {
    let out = iso(x, d, &[], residual);
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

fn iso_json(r: &Result<Iso230Figures, String>) -> Value {
    match r {
        Ok(v) => serde_json::to_value(v).unwrap_or(Value::Null),
        Err(e) => json!({ "error": e }),
    }
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
/// direction's end value (`axcomp_positioning::fit`), a guess the data do not support.
fn direction_coverage(obs: &[Observation], held: Option<&[bool]>) -> Option<DataWarning> {
    let fitted: Vec<Observation> = match held {
        Some(h) => (0..obs.len()).filter(|&i| !h[i]).map(|i| obs[i]).collect(),
        None => obs.to_vec(),
    };
    let [Some(fwd), Some(bwd)] = axcomp_positioning::fit::direction_ranges(&fitted) else {
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

/// Rows from which the command reports its steps on stderr (each can take seconds).
const PROGRESS_ROWS: usize = 200_000;

/// When the command started (for the progress lines of the fit).
static STARTED: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();

fn fit_progress(note: &str) {
    let t = STARTED.get_or_init(std::time::Instant::now);
    eprintln!(
        "axcomp: [{:.1} s{}] {note}",
        t.elapsed().as_secs_f64(),
        crate::output::peak_memory_note()
    );
}

fn compute(args: &Args) -> anyhow::Result<Outcome> {
    let t0 = *STARTED.get_or_init(std::time::Instant::now);
    let load = LoadOptions::from_args(&args.data.where_, &args.data.rename, &args.data.scale)?;
    let ds = Dataset::load(&args.data.data, &load)?;
    if ds.n_rows() == 0 {
        bail!("{}: no rows left after --where", args.data.data.display());
    }
    let big = ds.n_rows() >= PROGRESS_ROWS;
    let progress = |what: &str| {
        if big {
            eprintln!(
                "axcomp: [{:.1} s{}] {what}",
                t0.elapsed().as_secs_f64(),
                crate::output::peak_memory_note()
            );
        }
    };
    progress(&format!("read {} rows", ds.n_rows()));
    sanity::single_campaign(&ds, &["test_id", "axis"])?;
    let split = Split::from_args(args.holdout.as_deref(), args.cv.as_deref())?;
    let mut x = ds.numeric("target_mm")?.to_vec();
    let mut dev = ds.numeric(&args.target)?.to_vec();
    let mut dir = ds.direction()?.unwrap_or_else(|| vec![0; ds.n_rows()]);
    let cv_col: Option<String> = match &split {
        Some(Split::Cv(c)) => Some(c.clone()),
        _ if ds.has("run") => Some("run".to_string()),
        _ => None,
    };
    let (mut run, run_labels): (Vec<i64>, Vec<String>) = match &cv_col {
        Some(c) => {
            // An empty label would silently make its rows one more run.
            if let Some(row) = ds.text(c)?.iter().position(|t| t.trim().is_empty()) {
                bail!(
                    "{}: empty cell where the row's run (`{c}`) is required: every row needs one",
                    ds.locate(c, row)
                );
            }
            let (ids, labels) = axcomp_data::groups(&ds, c)?;
            (ids.into_iter().map(|g| g as i64 + 1).collect(), labels)
        }
        None => (vec![1; ds.n_rows()], vec!["all".to_string()]),
    };
    for (i, (&xi, &di)) in x.iter().zip(&dev).enumerate() {
        if !xi.is_finite() {
            bail!("{}: target_mm is not finite", ds.locate("target_mm", i));
        }
        if !di.is_finite() {
            bail!(
                "{}: {} is not finite",
                ds.locate(&args.target, i),
                args.target
            );
        }
    }
    let holdout_mask = match &split {
        Some(Split::Holdout(h)) => Some(h.mask(&ds)?),
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
    let mut warnings = data_warnings(&ds, &args.target, &x, &dev, &dir);
    warnings.extend(direction_coverage(&obs, holdout_mask.as_deref()));
    crate::commands::common::report_warnings(&warnings, args.strict)?;
    let provenance = crate::provenance::of_data(
        &args.data,
        args.holdout.as_deref(),
        args.cv.as_deref(),
        &args.target,
        "fit positioning",
    )?;
    let axis = match &args.axis {
        Some(a) => a.clone(),
        None => match ds.text("axis") {
            Ok(t) if !t.is_empty() && t.iter().all(|v| *v == t[0]) => t[0].to_string(),
            _ => "X".to_string(),
        },
    };
    let opts = FitOptions {
        axis,
        segments: args.segments,
        segment_mm: args.segment_mm,
        max_folds: args.max_folds,
        progress: axcomp_positioning::fit::Progress(big.then_some(fit_progress as fn(&str))),
        ..FitOptions::default()
    };
    if args.max_folds < 3 {
        bail!("--max-folds {}: needs at least 3", args.max_folds);
    }

    let ages = match &args.drift {
        Some(col) => Some(drift_ages(&ds, col, args.run_period_s)?),
        None => None,
    };
    // Everything needed from the dataset has been taken: free it before the fit (large files).
    let n_rows = ds.n_rows();
    drop(ds);
    let warm_json: Value;
    let kept_warmup: Option<WarmupFit>;
    progress("fitting the candidates (cross-validated)");
    let (mut fit, judged, verdict, judged_rms, method) = match &holdout_mask {
        None => {
            let static_fit = axcomp_positioning::fit(&obs, &opts)
                .with_context(|| args.data.data.display().to_string())?;
            let (mut fit, kept, wj) = with_warmup(args, &obs, ages.as_deref(), &opts, static_fit)?;
            warm_json = wj;
            let (predicted, verdict, cv) = match &kept {
                Some(w) => (w.cv_predictions.clone(), w.guard.clone(), w.cv_rms_um),
                None => (
                    std::mem::take(&mut fit.cv_predictions),
                    fit.guard.clone(),
                    fit.cv_rms_um,
                ),
            };
            kept_warmup = kept;
            let judged = Judged {
                // Moved, not copied: the judged rows are all rows (large campaigns).
                x: std::mem::take(&mut x),
                direction: std::mem::take(&mut dir),
                run: std::mem::take(&mut run),
                deviation: std::mem::take(&mut dev),
                predicted,
            };
            let method = fit.split.method.clone();
            (fit, judged, verdict, cv, method)
        }
        Some(mask) => {
            let train_rows: Vec<usize> = (0..obs.len()).filter(|&i| !mask[i]).collect();
            let train: Vec<Observation> = train_rows.iter().map(|&i| obs[i]).collect();
            let static_fit = axcomp_positioning::fit(&train, &opts).with_context(|| {
                format!(
                    "{}: fitting on the rows not held out",
                    args.data.data.display()
                )
            })?;
            let train_ages: Option<Vec<f64>> = ages
                .as_ref()
                .map(|a| train_rows.iter().map(|&i| a[i]).collect());
            let (mut fit, kept, wj) =
                with_warmup(args, &train, train_ages.as_deref(), &opts, static_fit)
                    .context("on the rows not held out")?;
            warm_json = wj;
            kept_warmup = kept;
            let idx: Vec<usize> = (0..obs.len()).filter(|&i| mask[i]).collect();
            let drift_at = |i: usize| match (&kept_warmup, &ages) {
                (Some(w), Some(a)) => w.warmup.offset_um(a[i]),
                _ => 0.0,
            };
            let judged = Judged {
                x: idx.iter().map(|&i| x[i]).collect(),
                direction: idx.iter().map(|&i| dir[i]).collect(),
                run: idx.iter().map(|&i| run[i]).collect(),
                deviation: idx.iter().map(|&i| dev[i]).collect(),
                // The held-out rows are judged with the table the firmware would apply (plus the drift).
                predicted: idx
                    .iter()
                    .map(|&i| fit.table.deviation_um(x[i], dir[i]) + drift_at(i))
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
                opts.improvement_ratio,
                opts.runs_improved_fraction,
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
            (fit, judged, verdict, hr, "holdout".to_string())
        }
    };
    if let (Some(Split::Cv(c)), false) = (&split, fit.split.method == "leave-one-run-out") {
        eprintln!(
            "axcomp: note: --cv {c} has fewer than 3 distinct values; cross-validated by {} folds of every k-th row instead",
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
    progress("ISO 230-2 before and after");
    let before = iso(&judged.x, &judged.direction, &judged.run, &judged.deviation);
    // After: with --holdout the held-out runs minus the table; with CV every run minus the model fitted
    // without it, pooled (each fold's figures and their mean reported beside).
    let mut fold_mean: Option<Result<Iso230Figures, String>> = None;
    let mut after_caveats = Value::Null;
    let (after, per_fold_json, after_method) = if holdout_mask.is_some() {
        (
            iso(&judged.x, &judged.direction, &judged.run, &residual),
            Value::Null,
            "ISO 230-2 of the held-out runs with the table's predicted correction subtracted"
                .to_string(),
        )
    } else {
        let folds = &fit.fold_of_row;
        let n_folds = folds.iter().copied().max().map_or(0, |m| m + 1);
        let mut per_fold = Vec::new();
        let mut figs = Vec::new();
        for f in 0..n_folds {
            let rows: Vec<usize> = (0..judged.x.len()).filter(|&i| folds[i] == f).collect();
            if rows.is_empty() {
                continue;
            }
            let pick = |v: &[f64]| rows.iter().map(|&i| v[i]).collect::<Vec<f64>>();
            let fx = pick(&judged.x);
            let fd: Vec<i8> = rows.iter().map(|&i| judged.direction[i]).collect();
            let fr: Vec<i64> = rows.iter().map(|&i| judged.run[i]).collect();
            let b = iso(&fx, &fd, &fr, &pick(&judged.deviation));
            let a = iso(&fx, &fd, &fr, &pick(&residual));
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
        fold_mean = Some(mean_figures(&figs));
        let pooled;
        (pooled, after_caveats) = pooled_after(&judged.x, &judged.direction, &residual);
        (
            pooled,
            Value::Array(per_fold),
            format!(
                "ISO 230-2 of every run with the correction predicted by the model of the fold that held it \
                 out, pooled over the {} folds: a compensated campaign none of whose runs its model saw \
                 (the per-fold figures and their mean are beside it)",
                figs.len()
            ),
        )
    };
    let refused = !verdict.passed && !args.force;
    // Per run: raw and judged RMS and the mean residual (a drifting mean shows drift between runs).
    let mut rows_of_run: Vec<Vec<usize>> = vec![Vec::new(); run_labels.len()];
    for (i, &r) in judged.run.iter().enumerate() {
        if let Some(v) = rows_of_run.get_mut((r - 1) as usize) {
            v.push(i);
        }
    }
    let per_run: Vec<Value> = run_labels
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
        .collect();
    drop(rows_of_run);
    let table_written = args.out.is_some() && !refused;

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
        "data": args.data.data.display().to_string(),
        "target": args.target,
        "rows": n_rows,
        "rows_judged": judged.x.len(),
        "raw_rms_um": raw_rms,
        "iso230_2_before": iso_json(&before),
        "iso230_2_after": iso_json(&after),
        "iso230_2_after_method": after_method,
        "iso230_2_per_fold": per_fold_json,
        "iso230_2_after_fold_mean": fold_mean.as_ref().map_or(Value::Null, iso_json),
        "iso230_2_after_caveats": after_caveats,
        "warnings": warnings,
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
        "cv": { "method": method, "column": cv_col, "folds": fit.split.folds, "max_folds": args.max_folds,
                 "grouped": fit.split.method == "leave-runs-out",
                 "note": if fit.split.method == "leave-runs-out" {
                     json!(format!("{} runs grouped into {} folds of consecutive runs (--max-folds)", run_labels.len(), fit.split.folds))
                 } else { Value::Null },
                 "per_run": per_run },
        "guard": guard_json(&verdict, refused, args.force),
        "table_written": table_written,
        "table": {
            "path": args.out.as_ref().map(|p| p.display().to_string()),
            "axis": fit.table.axis,
            "start_mm": fit.table.start_mm,
            "segment_mm": fit.table.segment_mm,
            "segments": fit.table.forward.len(),
            "bidirectional": !fit.table.backward.is_empty(),
            "resampling_max_um": fit.resampling_max_um,
        },
    });
    if holdout_mask.is_some() {
        j["holdout_rms_um"] = json!(judged_rms);
        j["holdout"] = json!(args.holdout);
    } else {
        j["cv_rms_um"] = json!(judged_rms);
    }
    let drift_model = match (&kept_warmup, &args.drift_model) {
        (Some(w), Some(_)) => Some(drift_model_file(args, w, raw_rms, judged_rms)?),
        (None, Some(path)) => {
            eprintln!(
                "axcomp: note: the warm-up drift was not kept (it does not lower the cross-validated RMS); {} not written",
                path.display()
            );
            None
        }
        _ => None,
    };
    j["drift_model_written"] = json!(drift_model.is_some() && !refused);
    fit.table.provenance = Some(provenance);
    let report = report_markdown(args, &j, &fit, &verdict);
    Ok(Outcome {
        drift_model,
        warnings,
        json: j,
        report,
        fit,
        judged,
        refused,
    })
}

/// With `--drift` (`ages` given): fits the warm-up drift on `obs` and keeps it when it lowers the CV RMS
/// on these rows by more than 1 % and is plausible as warm-up (smaller over the data than the raw error
/// itself; a larger "drift" is slip, lost steps or a moving reference far more often than warm-up, and must
/// not be extrapolated). Returns the fit to use (the drift-free static part when kept; its table's
/// `cv_rms_um` is the whole model's), the kept drift, and the `model.warmup` JSON (null without `--drift`).
fn with_warmup(
    args: &Args,
    obs: &[Observation],
    ages: Option<&[f64]>,
    opts: &FitOptions,
    static_fit: FitResult,
) -> anyhow::Result<(FitResult, Option<WarmupFit>, Value)> {
    let Some(ages) = ages else {
        return Ok((static_fit, None, Value::Null));
    };
    let w =
        warmup::fit_with_warmup(obs, ages, opts).context("fitting the warm-up drift (--drift)")?;
    let kept = w.cv_rms_um <= 0.99 * static_fit.cv_rms_um
        && w.drift_over_data_um.abs() <= static_fit.raw_rms_um;
    let j = warmup_json(args, &w, &static_fit, kept);
    if !kept {
        return Ok((static_fit, None, j));
    }
    let mut fit = w.static_part.clone();
    fit.table.cv_rms_um = w.cv_rms_um;
    fit.table.model = format!("{} + warmup_drift", fit.table.model);
    Ok((fit, Some(w), j))
}

/// Warm-up age (s) per row for `--drift COL`.
fn drift_ages(ds: &Dataset, col: &str, run_period_s: Option<f64>) -> anyhow::Result<Vec<f64>> {
    let v = ds
        .numeric(col)
        .with_context(|| format!("--drift {col}: the column must be numeric"))?;
    if let Some(i) = v.iter().position(|a| !a.is_finite()) {
        bail!("{}: --drift {col}: not a finite number", ds.locate(col, i));
    }
    if col.ends_with("_s") {
        if run_period_s.is_some() {
            bail!("--run-period-s is for a run column; --drift {col} is already in seconds");
        }
        if let Some(i) = v.iter().position(|&a| a < 0.0) {
            bail!(
                "{}: --drift {col}: {} s is before the axis was energised (ages must be ≥ 0)",
                ds.locate(col, i),
                v[i]
            );
        }
        return Ok(v.to_vec());
    }
    let period = run_period_s.ok_or_else(|| {
        anyhow::anyhow!(
            "--drift {col}: `{col}` counts runs, not seconds; give --run-period-s (the duration of one run) \
             so the warm-up time constant comes out in seconds, or use a time_s column"
        )
    })?;
    if !(period.is_finite() && period > 0.0) {
        bail!("--run-period-s {period}: must be a finite number of seconds > 0");
    }
    let first = v.iter().copied().fold(f64::INFINITY, f64::min);
    Ok(v.iter().map(|&r| (r - first + 0.5) * period).collect())
}

fn warmup_json(args: &Args, w: &WarmupFit, static_fit: &FitResult, kept: bool) -> Value {
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
        "column": args.drift,
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

/// The kept warm-up drift as a thermal model file with one input, `warmup`.
fn drift_model_file(
    args: &Args,
    w: &WarmupFit,
    raw_rms: f64,
    judged_rms: f64,
) -> anyhow::Result<ThermalModelFile> {
    if args.drift_period_ms == 0 {
        bail!("--drift-period-ms must be > 0");
    }
    let m = ThermalModelFile {
        format: model_file::FORMAT.into(),
        target: args.target.clone(),
        sensor_period_ms: args.drift_period_ms,
        b0_um: -w.warmup.drift_um * w.warmup.state_ref,
        sensors: vec![ModelSensor {
            name: "warmup".into(),
            reference_degc: 0.0,
            tau_s: w.warmup.tau,
            coef_um_per_k: w.warmup.drift_um,
            // The input is 0 or 1; any step between them is plausible.
            min_degc: -0.5,
            max_degc: 1.5,
            max_rate_degc_per_s: 1.0e6,
            stale_timeout_ms: (10 * args.drift_period_ms).max(10_000),
            rise_min_k: None,
            rise_max_k: None,
        }],
        forces: vec![],
        raw_rms_um: raw_rms,
        holdout_rms_um: Some(judged_rms),
        target_offset_um: None,
        runs_column: None,
    };
    m.validate()
        .map_err(|e| anyhow::anyhow!("the warm-up drift model is not usable: {e}"))?;
    Ok(m)
}

fn guard_json(v: &GuardVerdict, refused: bool, forced: bool) -> Value {
    let mut g = serde_json::to_value(v).unwrap_or(Value::Null);
    g["refused"] = json!(refused);
    g["forced"] = json!(forced && !v.passed);
    g
}

fn f3(v: &Value) -> String {
    v.as_f64().map_or("–".into(), |x| format!("{x:.3}"))
}

fn report_markdown(args: &Args, j: &Value, fit: &FitResult, verdict: &GuardVerdict) -> String {
    let mut s = String::new();
    let judged = if args.holdout.is_some() {
        "holdout_rms_um"
    } else {
        "cv_rms_um"
    };
    s.push_str("# Positioning table fit\n\n");
    s.push_str(&format!(
        "Data: `{}` ({} rows",
        args.data.data.display(),
        j["rows"]
    ));
    if !args.data.where_.is_empty() {
        s.push_str(&format!(", where {}", args.data.where_.join(", ")));
    }
    s.push_str(&format!("), error column `{}`.\n\n", args.target));
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
            if args.force {
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
    s
}

/// What the plots are about: the `--where` filters, else the data file's name.
fn data_label(args: &Args) -> String {
    if args.data.where_.is_empty() {
        args.data.data.file_name().map_or_else(
            || args.data.data.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        )
    } else {
        args.data
            .where_
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
fn report_files(args: &Args, o: &Outcome) -> Vec<(&'static str, Vec<u8>)> {
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
    let judged_key = if args.holdout.is_some() {
        "holdout"
    } else {
        "CV"
    };
    let raw = o.json["raw_rms_um"].as_f64().unwrap_or(f64::NAN);
    let after = o.json[if args.holdout.is_some() {
        "holdout_rms_um"
    } else {
        "cv_rms_um"
    }]
    .as_f64()
    .unwrap_or(f64::NAN);
    let label = data_label(args);
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
