//! `axcomp fit thermal`: thermo-force error model from temperature / force / error time series.
//!
//! Glossary:
//! - **target**: the `*_um` error channel modelled (`--target`); **sensors**: every `*_degC` column (or the
//!   `--sensors` subset); **forces**: every `*_N` column (unless `--no-forces`), fitted jointly as χ·F terms.
//! - **held-out rows** (`--holdout`): never used for fitting or selection; `raw_rms_um` / `holdout_rms_um`
//!   are the target's RMS on them before / after the model.
//! - **guard**: the model is written (`--out`) only if it is not worse than raw on the held-out rows (or, with
//!   no holdout, in the validation); otherwise the command exits 3 ([`crate::EXIT_GUARD_REFUSED`]);
//!   `--force` writes it anyway.
//!
//! Reading, fitting, summary, JSON and model file are the library's ([`axcomp_thermal::request`],
//! [`axcomp_thermal::fit_thermal`], [`axcomp_thermal::report`]); this command parses, calls and writes.

use std::path::PathBuf;

use anyhow::Context;
use axcomp_data::{Dataset, LoadOptions};
use axcomp_thermal::fit_thermal;
use axcomp_thermal::report::thermal_report_files;
use axcomp_thermal::request::{ThermalRequest, summary};

use crate::cli::DataArgs;
use crate::output::OutputSet;

const LONG_HELP: &str = "\
How it works: sensors are the `*_degC` columns (or the --sensors subset), forces the `*_N` columns (fitted jointly as χ·F terms unless --no-forces), the target a `*_um` column.

Raw figures: the target minus its reference value, the mean of its first N rows (N = 1, or --zero-at-start N), the rows where every sensor's rise ΔT is zero. `raw_rms_um`, `train_raw_rms_um`, the per-condition and the validation raw figures all use it (`raw_reference_um` in the JSON).

Runs (--runs COL): each run's temperatures and target are taken relative to its first row (the readings at switch-on), lags restart per run, and the candidates are judged over runs. The model file records the column; `axcomp predict` applies the same per-run references.

Model choice (default): candidates (plain least squares on every sensor the firmware takes, greedy selection of up to 4 sensors with lags, every sensor with one lag each, forward selection by inner CV, FCM + grey relational analysis, ridge) are each re-run with all their own choices on the data before each judged group and predict it: with --runs, each run of the later half from the runs before it; in one recording, each regime block (heating / cooling) of the later half from the blocks before it; with --cv conditions, each condition left out in turn. The lowest validation RMS wins if it is a simple procedure (plain least squares, greedy with lags); a more elaborate one must beat the better simple procedure by more than one standard error of the per-group paired difference. With one regime among a single recording's training rows only plain least squares and every-sensor-with-lags can be chosen. The plain references (plain least squares on every sensor, greedy + lags) are in the JSON (`references`) with their validation and held-out RMS.

Range guard: on a row where a model sensor has risen beyond the range it was fitted on by more than that range (at least 1 K), that sensor's term is dropped and the others stay (the model file holds the bounds; predict and the firmware apply them).

Lags: y += α(u − y), α = 1 − exp(−Δt/τ) from the actual sample interval, exactly as the firmware runs it; τ per sensor on a grid by inner CV, refined by golden-section search. A sensor whose training trace shows a single episode of change (a heater switched on once, one monotone rise) gets lags only up to a third of that episode: a longer lag of it is only a function of the time since the start. --no-lags leaves lags out.

--select all | greedy | forward | fcm-gra is a forced selection: only that structure is fitted (no comparison; --select all without --lags is plain least squares; greedy is up to 4 sensors each with its lag; FCM runs only for fcm-gra). A refusal by the do-no-harm guard names the plain references that do better than no model and the --select that fits each.

Do-no-harm guard: with --holdout, the model's RMS on the held-out rows must be <= raw on them; without, the default's validation RMS must be <= raw over the same blocks (a forced selection: its leave-one-block-out RMS <= raw on the training rows). When it fails, the JSON and report are still written, no model is written, and the command exits 3, unless --force.

Exit codes: 0 done; 2 bad input (file, column, option); 3 refused by the do-no-harm guard.

Example (Voron frame data, header step_dist = 0.0025 mm, so 2.5 µm per microstep; cooling phase held out):
  axcomp fit thermal --data frame.csv --target z_um
    --rename mcu_pos_z=z_um --scale z_um=2.5
    --rename frame_t=frame_degC --rename chamber_t=chamber_degC
    --rename bed_t=bed_degC --rename he_t=hotend_degC
    --holdout 'bed_target<1' --json fit.json --out model.json";

#[derive(Debug, clap::Args)]
#[command(after_long_help = LONG_HELP)]
pub struct Args {
    #[command(flatten)]
    pub data: DataArgs,
    /// The error column to model (µm).
    #[arg(long, default_value = "deviation_um", value_name = "COL")]
    pub target: String,
    /// Rows held out from fitting and used only to judge: COL=V1,V2 | COL>=X | COL<X.
    #[arg(long, value_name = "SPEC")]
    pub holdout: Option<String>,
    /// The file holds several runs (e.g. one per day, each from a cold machine), told apart by COL: each
    /// run's temperatures and target are taken relative to its first row, lags restart per run, and the
    /// model is judged forward over the runs.
    #[arg(long, value_name = "COL")]
    pub runs: Option<String>,
    /// Leave-one-group-out over the values of COL (operating conditions): inner CV groups and `cv_rms_um`.
    #[arg(long, value_name = "COL")]
    pub cv: Option<String>,
    /// Machine-readable result.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write report.md and SVG plots into DIR.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Attach a force law (from `axcomp fit force --out LAW.json`) to the force term of column COL in the model
    /// file, so the firmware predicts that force from ap, fz and n instead of measuring it (repeatable).
    #[arg(long, value_name = "COL=LAW.json")]
    pub force_law: Vec<String>,
    /// Write the model file (input of `axcomp image build --thermal`).
    #[arg(long, value_name = "MODEL.json")]
    pub out: Option<PathBuf>,
    /// With --select: fit a first-order lag (time constant) per selected sensor. The default choice always has
    /// lagged candidates (unless --no-lags).
    #[arg(long)]
    pub lags: bool,
    /// Leave lagged candidates out of the default choice.
    #[arg(long, conflicts_with = "lags")]
    pub no_lags: bool,
    /// Ridge penalty on the standardized coefficients: a number λ ≥ 0 (applied to the chosen structure; no
    /// shrinkage candidates), or `auto` (default: ridge and elastic net are candidates of the default choice;
    /// with --select, λ chosen by inner CV).
    #[arg(long, value_name = "λ|auto")]
    pub ridge: Option<String>,
    /// Model choice: auto (the candidate with the lowest transfer-validation RMS), or a forced selection that
    /// runs only itself: fcm-gra, forward, greedy (up to 4 sensors, each with its lag), all (every sensor;
    /// plain least squares, with --lags per-sensor lags).
    #[arg(long = "select", default_value = "auto", value_name = "METHOD")]
    pub select: String,
    /// Most sensors in the model (1..=16).
    #[arg(long, default_value_t = 6, value_name = "N")]
    pub max_sensors: usize,
    /// Only these sensors are candidates (names without `_degC`, comma separated).
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    pub sensors: Vec<String>,
    /// Do not use `*_N` force columns as terms.
    #[arg(long)]
    pub no_forces: bool,
    /// Subtract the mean of the target's first N rows (file order, after --where) so the target is the change
    /// since the start (e.g. a homing position instead of a deviation). The model file records that value
    /// (`target_offset_um`): the firmware corrects the change, `axcomp predict` adds it back.
    #[arg(long, value_name = "N")]
    pub zero_at_start: Option<usize>,
    /// Sensor read period of the firmware (ms), written into the model file.
    #[arg(long, default_value_t = 1000, value_name = "MS")]
    pub sensor_period_ms: u32,
    /// Write the model even if the do-no-harm guard fails.
    #[arg(long)]
    pub force: bool,
}

/// The library's request from the command line.
fn request(args: &Args) -> ThermalRequest {
    ThermalRequest {
        data: args.data.data.clone(),
        target: args.target.clone(),
        holdout: args.holdout.clone(),
        runs: args.runs.clone(),
        cv: args.cv.clone(),
        force_law: args.force_law.clone(),
        lags: args.lags,
        no_lags: args.no_lags,
        ridge: args.ridge.clone(),
        select: args.select.clone(),
        max_sensors: args.max_sensors,
        sensors: args.sensors.clone(),
        no_forces: args.no_forces,
        zero_at_start: args.zero_at_start,
        sensor_period_ms: args.sensor_period_ms,
    }
}

/// Every output planned and checked before the fit; written together at the end (the model is dropped
/// from the set when the guard refuses it).
fn planned_outputs(args: &Args) -> anyhow::Result<OutputSet> {
    let mut outputs = OutputSet::new();
    outputs.input(&args.data.data);
    if let Some(dir) = &args.report {
        outputs.folder(dir, "--report");
        for name in [
            "prediction.svg",
            "residual_per_condition.svg",
            "sensors.svg",
            "report.md",
        ] {
            outputs.planned_in(dir, name);
        }
    }
    for p in [&args.json, &args.out].into_iter().flatten() {
        outputs.planned(p);
    }
    outputs.check()?;
    Ok(outputs)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // ---- validate options before reading anything ----
    let req = request(&args);
    let mut opts = req.options()?;
    let load = LoadOptions::from_args(&args.data.where_, &args.data.rename, &args.data.scale)?;
    let holdout = req.holdout_spec()?;
    let laws = req.force_laws()?;
    let mut outputs = planned_outputs(&args)?;

    // ---- read, and the rows' quality (reported; the fit keeps every row) ----
    let ds = Dataset::load(&args.data.data, &load)?;
    let mut notice = |line: String| eprintln!("axcomp: {line}");
    let read = req.read_input(
        &ds,
        holdout.as_ref(),
        &laws,
        &mut opts,
        crate::commands::common::time_hint(&ds),
        &mut notice,
    )?;
    let quality = req.row_quality(&ds, &read.input, &mut notice);

    // ---- fit ----
    let fit = fit_thermal(&read.input, &opts)
        .with_context(|| format!("fitting {}", args.data.data.display()))?;
    let write_model = args.out.is_some() && (fit.guard.passed || args.force);

    // ---- outputs ----
    print!("{}", summary(&fit, &args.target));
    if let Some(path) = &args.json {
        let v = req.json(&fit, &read, &quality, write_model)?;
        outputs.file(path, serde_json::to_string_pretty(&v)?);
    }
    if let Some(dir) = &args.report {
        for (path, bytes) in thermal_report_files(dir, &fit, &read.input, &args.target) {
            outputs.folder_file(dir, &crate::commands::common::file_name(&path), bytes);
        }
    }
    if !fit.guard.passed && !args.force {
        // The JSON and the report are written; the refused model is not.
        if let Some(out) = &args.out {
            outputs.remove(out);
        }
        outputs.commit()?;
        return Err(crate::Refused {
            code: crate::EXIT_GUARD_REFUSED,
            reason: match &args.out {
                Some(out) => format!(
                    "do-no-harm guard: {}; the model was not written to {} (use --force to write it anyway)",
                    fit.guard.reason,
                    out.display()
                ),
                None => format!("do-no-harm guard: {}", fit.guard.reason),
            },
        }
        .into());
    }
    if let Some(out) = &args.out {
        let file = req.model_file(&fit, &read, &laws)?;
        if let Some((_, why)) = axcomp_image::board::thermal_model_refusal(&file) {
            eprintln!(
                "axcomp: warning: {}: `image build` cannot put this model into a firmware image: {why}",
                out.display()
            );
        }
        let provenance = crate::provenance::of_data(
            &args.data,
            args.holdout.as_deref(),
            args.cv.as_deref(),
            &args.target,
            "fit thermal",
        )?;
        outputs.file(out, crate::provenance::stamp(&file, &provenance)?);
    }
    outputs.commit()?;
    if let Some(out) = &args.out {
        println!("model written to {}", out.display());
    }
    Ok(())
}
