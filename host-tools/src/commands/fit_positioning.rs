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
//! The reading, fitting, figures and report are the library's ([`axcomp_positioning::campaign`],
//! [`axcomp_positioning::report`]); this command parses, calls and writes.
//!
//! Outputs: `--out` the table (`axcomp-positioning-table/1` JSON, with its provenance), `--json` the
//! figures, `--report DIR` a Markdown report and SVG plots. All of them are written together or none
//! (`crate::output::OutputSet`): a bad output path fails before the fit, and nothing is changed.

use std::path::PathBuf;

use anyhow::Context;
use axcomp_data::{Dataset, LoadOptions};
use axcomp_positioning::campaign::{self, Campaign, Outcome, Request};
use axcomp_positioning::report::{REPORT_FILES, report_files};
use axcomp_thermal::model_file::ThermalModelFile;
use serde_json::json;

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

/// The library's request from the command line.
fn request(args: &Args, big: bool) -> Request {
    Request {
        data: args.data.data.clone(),
        where_: args.data.where_.clone(),
        target: args.target.clone(),
        holdout: args.holdout.clone(),
        cv: args.cv.clone(),
        segments: args.segments,
        segment_mm: args.segment_mm,
        axis: args.axis.clone(),
        force: args.force,
        drift: args.drift.clone(),
        run_period_s: args.run_period_s,
        max_folds: args.max_folds,
        out: args.out.clone(),
        progress: big.then_some(fit_progress as fn(&str)),
    }
}

/// Reads the campaign (warnings printed, `--strict` applied), fits and judges it; with `--drift-model`,
/// the kept warm-up drift as a thermal model file.
fn compute(args: &Args) -> anyhow::Result<(Request, Outcome, Option<ThermalModelFile>)> {
    STARTED.get_or_init(std::time::Instant::now);
    let load = LoadOptions::from_args(&args.data.where_, &args.data.rename, &args.data.scale)?;
    let ds = Dataset::load(&args.data.data, &load)?;
    if ds.n_rows() == 0 {
        anyhow::bail!("{}: no rows left after --where", args.data.data.display());
    }
    let req = request(args, ds.n_rows() >= PROGRESS_ROWS);
    if req.progress.is_some() {
        fit_progress(&format!("read {} rows", ds.n_rows()));
    }
    let mut c = Campaign::read(&ds, &req)?;
    crate::commands::common::report_warnings(&c.warnings, args.strict)?;
    let provenance = crate::provenance::of_data(
        &args.data,
        args.holdout.as_deref(),
        args.cv.as_deref(),
        &args.target,
        "fit positioning",
    )?;
    c.finish_reading(&ds, &req)?;
    // Everything needed from the dataset has been taken: free it before the fit (large files).
    drop(ds);
    let mut outcome = campaign::fit_campaign(c, &req, provenance)?;
    let drift_model = match (&outcome.warmup, &args.drift_model) {
        (Some(w), Some(_)) => Some(
            ThermalModelFile::warmup_drift(
                &args.target,
                args.drift_period_ms,
                w.warmup.tau,
                w.warmup.drift_um,
                w.warmup.state_ref,
                outcome.raw_rms_um,
                outcome.judged_rms_um,
            )
            .map_err(anyhow::Error::msg)?,
        ),
        (None, Some(path)) => {
            eprintln!(
                "axcomp: note: the warm-up drift was not kept (it does not lower the cross-validated RMS); {} not written",
                path.display()
            );
            None
        }
        _ => None,
    };
    outcome.json["drift_model_written"] = json!(drift_model.is_some() && !outcome.refused);
    Ok((req, outcome, drift_model))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut outputs = planned_outputs(&args);
    outputs.check()?;
    let t0 = std::time::Instant::now();
    let (req, outcome, drift_model) = compute(&args)?;
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
    if let (Some(path), Some(model), false) = (&args.drift_model, &drift_model, outcome.refused) {
        model
            .validate()
            .map_err(|e| anyhow::anyhow!("the warm-up drift model for {}: {e}", path.display()))?;
        match &outcome.fit.table.provenance {
            Some(p) => outputs.file(path, crate::provenance::stamp(model, p)?),
            None => outputs.json(path, model)?,
        };
    }
    if let Some(dir) = &args.report {
        if outcome.judged.x.len() >= PROGRESS_ROWS {
            eprintln!(
                "axcomp: [{:.1} s{}] drawing the report ({} rows)",
                t0.elapsed().as_secs_f64(),
                crate::output::peak_memory_note(),
                outcome.judged.x.len()
            );
        }
        for (name, bytes) in report_files(&req, &outcome) {
            outputs.folder_file(dir, name, bytes);
        }
    }
    if let Some(path) = &args.json {
        outputs.json(path, &outcome.json)?;
    }
    let written = outputs.commit()?;
    print_summary(&req, &outcome, &written);
    if outcome.refused {
        let reasons = outcome.json["guard"]["reasons"]
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

/// The one-line result and the files written, on stdout.
fn print_summary(req: &Request, outcome: &Outcome, written: &[PathBuf]) {
    let j = &outcome.json;
    let judged_key = req.judged_key();
    println!(
        "model {}: raw RMS {:.3} µm, {} {:.3} µm ({})",
        outcome.fit.chosen,
        j["raw_rms_um"].as_f64().unwrap_or(f64::NAN),
        judged_key,
        j[judged_key].as_f64().unwrap_or(f64::NAN),
        j["cv"]["method"].as_str().unwrap_or("")
    );
    let written: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    if !written.is_empty() {
        println!("wrote {}", written.join(", "));
    }
}
