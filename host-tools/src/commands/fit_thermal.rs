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

use std::path::PathBuf;

use anyhow::{Context, bail};
use axcomp_data::{Dataset, HoldoutSpec, LoadOptions, groups};
use axcomp_thermal::model_file::{ModelForceLaw, ThermalModelFile};
use axcomp_thermal::report::thermal_report_files;
use axcomp_thermal::{Ridge, Selection, Series, ThermalInput, ThermalOptions, fit_thermal};

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

pub fn run(args: Args) -> anyhow::Result<()> {
    // ---- validate options before reading anything ----
    let forced_selection = args.select != "auto";
    let ridge = match args.ridge.as_deref() {
        None if forced_selection => Ridge::Off,
        None => Ridge::Auto,
        Some("auto") => Ridge::Auto,
        Some(s) => match s.parse::<f64>() {
            Ok(l) if l >= 0.0 && l.is_finite() => Ridge::Fixed(l),
            _ => bail!("--ridge `{s}`: expected a number >= 0 or `auto`"),
        },
    };
    let selection = match args.select.as_str() {
        "auto" => Selection::Auto,
        "fcm-gra" | "fcm_gra" => Selection::FcmGra,
        "forward" => Selection::Forward,
        "all" => Selection::All,
        "greedy" => Selection::Greedy,
        s => bail!("--select `{s}`: expected auto, fcm-gra, forward, greedy or all"),
    };
    if args.sensor_period_ms == 0 {
        bail!("--sensor-period-ms must be > 0");
    }
    if let Some(0) = args.zero_at_start {
        bail!("--zero-at-start 0: must be at least 1");
    }
    let mut opts = ThermalOptions {
        // The default choice always compares lagged candidates (unless --no-lags), and so does greedy (the
        // reference with lags); another forced selection fits lags only with --lags.
        lags: if forced_selection && selection != Selection::Greedy {
            args.lags
        } else {
            !args.no_lags
        },
        ridge,
        max_sensors: args.max_sensors,
        selection,
        reference_rows: args.zero_at_start.unwrap_or(1),
        ..ThermalOptions::default()
    }
    .build()?;
    let load = LoadOptions::from_args(&args.data.where_, &args.data.rename, &args.data.scale)?;
    let holdout = args
        .holdout
        .as_deref()
        .map(HoldoutSpec::parse)
        .transpose()?;
    let laws = args
        .force_law
        .iter()
        .map(|s| {
            let (col, path) = s
                .split_once('=')
                .with_context(|| format!("--force-law `{s}`: expected COL=LAW.json"))?;
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("--force-law: reading {path}"))?;
            let law: ModelForceLaw = serde_json::from_str(&text).with_context(|| {
                format!("--force-law: {path} is not a force-law file (k, x_ap, y_fz, z_n)")
            })?;
            if ![law.k, law.x_ap, law.y_fz, law.z_n]
                .iter()
                .all(|v| v.is_finite())
                || law.k <= 0.0
            {
                bail!("--force-law: {path}: k must be > 0 and all values finite");
            }
            Ok((col.trim().to_string(), law))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    // Every output is planned and checked before the fit; written together at the end (the model is
    // dropped from the set when the guard refuses it).
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

    // ---- read ----
    let ds = Dataset::load(&args.data.data, &load)?;
    let n = ds.n_rows();
    if n == 0 {
        bail!("{}: no rows (after --where)", args.data.data.display());
    }
    let mut target = ds.numeric(&args.target)?.to_vec();
    let mut target_offset = 0.0;
    if let Some(k) = args.zero_at_start {
        if k == 0 || k > n {
            bail!("--zero-at-start {k}: must be 1..={n}");
        }
        target_offset = target[..k].iter().sum::<f64>() / k as f64;
        target.iter_mut().for_each(|v| *v -= target_offset);
    }
    // Without the time of each row a lag's time constant would be in rows, not seconds (and `predict` and
    // the firmware read it as seconds): the default choice then has no lagged candidates.
    let mut lags_note: Option<String> = None;
    let time_s: Vec<f64> = match ds.time_s() {
        Some(t) => t.to_vec(),
        None if args.lags => {
            if ds.has("time_s") {
                ds.numeric("time_s")?;
            }
            bail!(
                "--lags needs a `time_s` column (or a `time` column of timestamps) in {}{}",
                args.data.data.display(),
                crate::commands::common::time_hint(&ds)
            );
        }
        None => {
            if ds.has("time_s") {
                ds.numeric("time_s")?;
            }
            if opts.lags {
                opts.lags = false;
                let note = format!(
                    "{}: no `time_s` column (nor a `time` column of timestamps){}: lagged candidates left out \
                     (a time constant needs the time of each row)",
                    args.data.data.display(),
                    crate::commands::common::time_hint(&ds)
                );
                eprintln!("axcomp: note: {note}");
                lags_note = Some(note);
            }
            (0..n).map(|i| i as f64).collect()
        }
    };
    let mut names = ds.sensors();
    if !args.sensors.is_empty() {
        for s in &args.sensors {
            if !names.contains(s) {
                bail!(
                    "--sensors: `{s}` is not a sensor of {} (have: {})",
                    args.data.data.display(),
                    names.join(", ")
                );
            }
        }
        names.retain(|s| args.sensors.contains(s));
    }
    if names.is_empty() {
        bail!("{}: no `*_degC` sensor columns", args.data.data.display());
    }
    let sensors = names
        .iter()
        .map(|s| {
            Ok(Series {
                name: s.clone(),
                values: ds.numeric(&format!("{s}_degC"))?.to_vec(),
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let forces: Vec<Series> = if args.no_forces {
        vec![]
    } else {
        ds.column_names()
            .into_iter()
            .filter(|c| c.len() > 2 && c.ends_with("_N"))
            .map(|c| {
                Ok(Series {
                    name: c.to_string(),
                    values: ds.numeric(c)?.to_vec(),
                })
            })
            .collect::<anyhow::Result<Vec<_>>>()?
    };
    if forces.len() > 3 {
        bail!(
            "{} force columns (`*_N`); the firmware takes at most 3 (use --no-forces or --rename)",
            forces.len()
        );
    }
    // The label of each row in a grouping column (`--cv`, `--runs`).
    let labels_of = |col: &Option<String>| -> anyhow::Result<Option<Vec<String>>> {
        let Some(col) = col else { return Ok(None) };
        let (ids, labels) = groups(&ds, col)?;
        Ok(Some(ids.into_iter().map(|i| labels[i].clone()).collect()))
    };
    let conditions = labels_of(&args.cv)?;
    for (col, _) in &laws {
        if !forces.iter().any(|f| &f.name == col) {
            bail!(
                "--force-law {col}: not a force column of the model (have: {})",
                forces
                    .iter()
                    .map(|f| f.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
    let held = holdout.as_ref().map(|h| h.mask(&ds)).transpose()?;
    let runs = labels_of(&args.runs)?;
    // An explicit NaN or inf is no value the fit can use: named by file, line and column here (the fit
    // itself only knows the data row).
    let mut used: Vec<(String, &[f64])> = vec![(args.target.clone(), &target)];
    if ds.time_s().is_some() {
        used.push(("time_s".into(), &time_s));
    }
    used.extend(
        sensors
            .iter()
            .map(|s| (format!("{}_degC", s.name), s.values.as_slice())),
    );
    used.extend(forces.iter().map(|f| (f.name.clone(), f.values.as_slice())));
    for (col, values) in &used {
        if let Some(row) = values.iter().position(|v| !v.is_finite()) {
            bail!(
                "{}: `{}` is not a finite number; remove the row or fill in the value",
                ds.locate(col, row),
                values[row]
            );
        }
    }
    // A force column that does not vary on the training rows (e.g. a `force_N` of zeros in a record
    // without load) cannot be told from the intercept: it is left out with a note, as a constant sensor is.
    let mut excluded_forces: Vec<String> = Vec::new();
    let mut forces = forces;
    forces.retain(|f| {
        let train = f
            .values
            .iter()
            .enumerate()
            .filter(|(i, _)| !held.as_ref().is_some_and(|h| h[*i]))
            .map(|(_, v)| *v);
        let (lo, hi) = train.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        let constant = hi - lo <= 1e-9 * hi.abs().max(lo.abs()).max(1.0);
        if constant {
            excluded_forces.push(f.name.clone());
        }
        !constant
    });
    for name in &excluded_forces {
        if laws.iter().any(|(col, _)| col == name) {
            bail!(
                "--force-law {name}: the force column `{name}` is constant on the training rows, so the \
                 model has no force term to attach the law to"
            );
        }
        eprintln!(
            "axcomp: note: {}: force column `{name}` is constant on the training rows: left out of the model",
            args.data.data.display()
        );
    }
    let input = ThermalInput {
        time_s,
        sensors,
        forces,
        target,
        conditions,
        holdout: held,
        runs,
    };

    // ---- row quality: glitches and stopped measurements, reported (the fit keeps every row) ----
    let quality_runs = axcomp_thermal::runs::RunIndex::new(input.runs.as_deref(), n);
    let mut quality_cols: Vec<(&str, &[f64])> = vec![(args.target.as_str(), &input.target)];
    quality_cols.extend(
        input
            .sensors
            .iter()
            .map(|s| (s.name.as_str(), s.values.as_slice())),
    );
    let glitches = axcomp_thermal::quality::glitches(&quality_cols, &quality_runs);
    for g in &glitches {
        eprintln!(
            "axcomp: warning: {}: `{}` has {} single-sample glitch(es) (first: {})",
            args.data.data.display(),
            g.column,
            g.rows.len(),
            ds.locate(
                if g.column == args.target {
                    g.column.clone()
                } else {
                    format!("{}_degC", g.column)
                }
                .as_str(),
                g.rows[0] - 1
            )
        );
    }
    let sensor_refs: Vec<&[f64]> = input.sensors.iter().map(|s| s.values.as_slice()).collect();
    let stopped =
        axcomp_thermal::quality::stopped(&input.target, &sensor_refs, &input.time_s, &quality_runs);
    if let Some(s) = stopped.first() {
        eprintln!(
            "axcomp: warning: {}: `{}` holds still while the temperatures move on {} stretch(es) (first: \
             data rows {}–{}, {:.0} s, a sensor moved {:.1} K): a stopped measurement? (e.g. --where to keep \
             the rows where the machine runs)",
            args.data.data.display(),
            args.target,
            stopped.len(),
            s.from_row,
            s.to_row,
            s.duration_s,
            s.sensor_change_k
        );
    }

    // ---- fit ----
    let fit = fit_thermal(&input, &opts)
        .with_context(|| format!("fitting {}", args.data.data.display()))?;
    let write_model = args.out.is_some() && (fit.guard.passed || args.force);

    // ---- outputs ----
    println!("target {}: {}", args.target, fit.formula);
    println!(
        "sensors: {} (method {}: {})",
        fit.sensors.join(", "),
        fit.chosen_method,
        fit.why
    );
    for c in &fit.candidates {
        println!(
            "  candidate {:<13} validation RMS {:>10.4} µm{}{}{}",
            c.name,
            c.validation_rms_um,
            if !c.eligible {
                "  (reported only)"
            } else if c.beats_reference {
                "  (below plain LS)"
            } else {
                ""
            },
            c.holdout_rms_um
                .map_or(String::new(), |h| format!("  (held-out {h:.4} µm)")),
            if c.chosen { "  ← chosen" } else { "" }
        );
    }
    for r in &fit.references {
        println!(
            "  reference {:<13} validation RMS {:>10.4} µm{}",
            r.name,
            r.validation_rms_um,
            r.holdout_rms_um
                .map_or(String::new(), |h| format!("  (held-out {h:.4} µm)"))
        );
    }
    match fit.holdout_rms_um {
        Some(h) => println!(
            "held-out RMS: raw {:.3} µm → {:.3} µm ({} rows; raw = target − {:.3} µm, its reference value)",
            fit.raw_rms_um, h, fit.holdout_rows, fit.raw_reference_um
        ),
        None => println!(
            "RMS: raw {:.3} µm, training residual {:.3} µm",
            fit.raw_rms_um, fit.train_rms_um
        ),
    }
    if let Some(cv) = fit.cv_rms_um {
        println!("leave-one-group-out CV RMS (conditions or runs): {cv:.3} µm");
    }
    println!(
        "condition number {:.1}; guard: {}",
        fit.condition_number, fit.guard.reason
    );
    if let Some(path) = &args.json {
        let mut v = serde_json::to_value(&fit)?;
        let o = v.as_object_mut().expect("fit serializes to an object");
        o.insert("data".into(), args.data.data.display().to_string().into());
        o.insert("target".into(), args.target.clone().into());
        o.insert("target_offset_um".into(), target_offset.into());
        o.insert("model_written".into(), write_model.into());
        if let Some(note) = &lags_note {
            o.insert("lags_note".into(), note.clone().into());
        }
        o.insert("excluded_forces".into(), excluded_forces.clone().into());
        o.insert(
            "row_quality".into(),
            serde_json::json!({ "glitches": glitches, "stopped_target": stopped }),
        );
        let text = serde_json::to_string_pretty(&v)?;
        outputs.file(path, text);
    }
    if let Some(dir) = &args.report {
        for (path, bytes) in thermal_report_files(dir, &fit, &input, &args.target) {
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
        let mut file =
            ThermalModelFile::from_fit(&fit, &input, &args.target, args.sensor_period_ms);
        if args.zero_at_start.is_some() {
            file.target_offset_um = Some(target_offset);
        }
        file.runs_column = args.runs.clone();
        for (col, law) in &laws {
            let f = file
                .forces
                .iter_mut()
                .find(|f| &f.column == col)
                .expect("checked before fitting");
            f.law = Some(*law);
        }
        file.validate()
            .map_err(|e| anyhow::anyhow!("model not written: {e}"))?;
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
