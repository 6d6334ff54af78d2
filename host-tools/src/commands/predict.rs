//! `axcomp predict`: apply any fitted model file to the rows of a measurement CSV and write them back with
//! the model's predictions added as columns (contract: "Any fitted model: `axcomp predict`").
//!
//! Model kinds, told apart by the file's `format` field:
//! - positioning table (`axcomp-positioning-table/1`, `axcomp fit positioning --out`): inputs `target_mm`
//!   (and `direction` for a bidirectional table) → `pred_<target>`, the column the table was fitted on (its
//!   provenance's `target`; `pred_deviation_um` for a table without provenance); a target outside the table's stroke
//!   is an error naming the row (the table holds end values there, which is not a prediction).
//! - thermal model (`axcomp-thermal-model/1`, `axcomp fit thermal --out`; a model of `--zero-at-start` adds
//!   back its `target_offset_um` so that `pred_<target>` predicts the target itself): inputs the sensors' `<name>_degC`,
//!   `time_s` when a sensor has a lag, the force columns (or `ap_mm`, `fz_mm` and one `*_rpm` column for a
//!   force given by a law) → `pred_<target>`. The lags run over the rows in file order exactly as in the fit
//!   (start in equilibrium with the first row, restart where time does not increase). A temperature outside
//!   the model's plausibility range is an error naming the row (the firmware would reject it too).
//! - probe calibration (`axcomp-probe-calibration/1`, `axcomp fit probe --out`): inputs `x_mm, y_mm, z_mm,
//!   approach_x, approach_y, approach_z` and `feed_mm_min` when the calibration depends on the speed →
//!   `contact_x_mm, contact_y_mm, contact_z_mm`, the touch corrected to the surface point.
//!
//! - geometry model (`axcomp-geometry-model`, `axcomp fit geometry --out`): inputs `x_mm, y_mm, z_mm` (and
//!   `tool_*_mm`, `beam_*` or `line`) → `pred_ex_um, pred_ey_um, pred_ez_um`, plus `pred_deviation_um` when
//!   the rows' beams are known; a position outside the model's grid is an error naming the row.
//! - rotary-axis location-error model (`"kind": "rtest"`, `axcomp fit rtest --out`): inputs `x_mm, y_mm,
//!   z_mm`, `a_deg`|`b_deg`, `c_deg` (and `setup`, required when the model has several set-ups) →
//!   `pred_dx_um, pred_dy_um, pred_dz_um`.
//!
//! The common options are those of the fit, but a `--rename`/`--scale` naming a column the file does not
//! have is skipped with a note (the measured columns may be absent; see [`load_rows`]).
//!
//! - force law (`axcomp fit force --out`, no `format` field): inputs `ap_mm`, `fz_mm` and one `*_rpm` column
//!   (none when the law does not depend on the speed) → `pred_<force column>` (e.g. `pred_Fc_N`).
//!
//! Nothing is half-written: the output goes to a temporary file beside the target and is renamed.

use std::path::PathBuf;

use anyhow::{Context, bail};
use axcomp_data::{DataError, Dataset};
use axcomp_positioning::TableFile;
use axcomp_probe::Calibration;
use axcomp_probe::touches::read_touches;
use axcomp_thermal::model_file::{ModelForceLaw, ThermalModelFile};
use axcomp_thermal::predict::{check_force_law, predict_force_law, predict_thermal};

use crate::cli::DataArgs;
use crate::commands::common::{ModelKind, load_options, model_kind};
use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
#[command(
    after_help = "The measured columns may be absent: a --rename or --scale naming a column the file \
does not have (e.g. the fit's rename of the measured column) is skipped with a note. A row the model cannot \
predict (outside its stroke or range, a missing input) is an error naming the row; nothing is written."
)]
pub struct Args {
    /// A model file written by a `fit` command: positioning table (→ `pred_<target>`, e.g.
    /// `pred_deviation_um`), thermal model (→ `pred_<target>`), geometry model (→ `pred_ex_um`, `pred_ey_um`,
    /// `pred_ez_um`, and `pred_deviation_um` when the beams are known), rotary-axis model of `fit rtest` (→
    /// `pred_dx_um`, `pred_dy_um`, `pred_dz_um`), probe calibration (→ `contact_x_mm`, `contact_y_mm`,
    /// `contact_z_mm`), or a force law of `fit force --out` (→ `pred_<force column>`).
    #[arg(long, value_name = "MODEL")]
    pub model: PathBuf,
    #[command(flatten)]
    pub data: DataArgs,
    /// Output CSV: the input rows with the prediction columns added.
    #[arg(long, value_name = "F.csv")]
    pub out: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let kind = model_kind(&args.model)?;
    let mut outputs = OutputSet::new();
    outputs.input(&args.data.data).input(&args.model);
    outputs.planned(&args.out);
    outputs.check()?;
    let mut ds = load_rows(&args.data)?;
    let added = match kind {
        ModelKind::Positioning => {
            let table = TableFile::load(&args.model)
                .map_err(|e| anyhow::anyhow!("{}: {e}", args.model.display()))?;
            axcomp_positioning::predict::predict_positioning(&table, &mut ds)?
        }
        ModelKind::Thermal => {
            let model = ThermalModelFile::load(&args.model)?;
            predict_thermal(&model, &mut ds, &mut |note| {
                eprintln!("axcomp: note: {note}")
            })?
        }
        ModelKind::Probe => {
            let p = args.model.display().to_string();
            let text = std::fs::read_to_string(&args.model)
                .with_context(|| format!("{p}: cannot read"))?;
            let cal = Calibration::from_json(&p, &text)?;
            predict_probe(&cal, &mut ds)?
        }
        ModelKind::Geometry => {
            let p = args.model.display().to_string();
            let text = std::fs::read_to_string(&args.model)
                .with_context(|| format!("{p}: cannot read"))?;
            let model = axcomp_geometry::GeometryModel::from_json(&text, &p)?;
            predict_geometry(&model, &mut ds)?
        }
        ModelKind::Rtest => {
            let p = args.model.display().to_string();
            let text = std::fs::read_to_string(&args.model)
                .with_context(|| format!("{p}: cannot read"))?;
            let model = axcomp_rtest::RtestModel::from_json(&text, &p)?;
            predict_rtest(&model, &mut ds)?
        }
        ModelKind::ForceLaw => {
            let p = args.model.display().to_string();
            let text = std::fs::read_to_string(&args.model)
                .with_context(|| format!("{p}: cannot read"))?;
            let law: ModelForceLaw = serde_json::from_str(&text)
                .with_context(|| format!("{p}: not a force-law file (k, x_ap, y_fz, z_n)"))?;
            check_force_law(&law).map_err(|why| anyhow::anyhow!("{p}: {why}"))?;
            let v: serde_json::Value = serde_json::from_str(&text)?;
            let column = v["provenance"]["target"].as_str();
            predict_force_law(&law, column, &mut ds)?
        }
    };
    outputs.file(&args.out, ds.to_csv_string());
    outputs.commit()?;
    println!(
        "predict: {} rows, added {} → {}",
        ds.n_rows(),
        added.join(", "),
        args.out.display()
    );
    Ok(())
}

/// Loads `--data` with the common options, except that a `--rename` or `--scale` naming a column the file does
/// not have is skipped with a note on stderr: `predict` needs only the model's inputs (the measured columns
/// may be absent), and a user passes it the fit's options, whose renames and scales of the measured column
/// then have nothing to act on. A model input that is still missing (e.g. a typo in its rename) is an error
/// of the prediction, naming the column.
fn load_rows(args: &DataArgs) -> anyhow::Result<Dataset> {
    let mut opts = load_options(args)?;
    loop {
        match Dataset::load(&args.data, &opts) {
            Ok(ds) => return Ok(ds),
            Err(DataError::MissingColumn {
                file,
                name,
                purpose,
                ..
            }) if purpose.contains("--rename") || purpose.contains("--scale") => {
                let option = if purpose.contains("--rename") {
                    let k = opts.renames.iter().position(|(old, _)| *old == name);
                    k.map(|k| {
                        let (old, new) = opts.renames.remove(k);
                        format!("--rename {old}={new}")
                    })
                } else {
                    let k = opts.scales.iter().position(|(col, _)| *col == name);
                    k.map(|k| {
                        let (col, factor) = opts.scales.remove(k);
                        format!("--scale {col}={factor}")
                    })
                };
                let Some(option) = option else {
                    bail!("{file}: missing column `{name}`{purpose}");
                };
                eprintln!(
                    "axcomp: note: {option}: {file} has no column `{name}` (a measured column predict does not \
                     need?); option skipped"
                );
            }
            Err(e) => return Err(e.into()),
        }
    }
}

/// Adds `contact_x_mm, contact_y_mm, contact_z_mm`.
pub fn predict_probe(cal: &Calibration, ds: &mut Dataset) -> anyhow::Result<Vec<String>> {
    if cal.structure.has_speed() && !ds.has("feed_mm_min") {
        bail!(
            "{}: missing column `feed_mm_min`: the calibration's pretravel depends on the probing speed",
            ds.source()
        );
    }
    if !ds.has("feed_mm_min") && cal.feed_range_mm_min[1] > 0.0 {
        bail!(
            "{}: missing column `feed_mm_min`: the calibration was made at {} … {} mm/min and holds only there",
            ds.source(),
            cal.feed_range_mm_min[0],
            cal.feed_range_mm_min[1]
        );
    }
    let (touches, labels) = read_touches(ds)?;
    axcomp_probe::validate_touches(&touches, &labels)?;
    let mut out = [Vec::new(), Vec::new(), Vec::new()];
    for (i, t) in touches.iter().enumerate() {
        cal.check_touch(t)
            .map_err(|why| anyhow::anyhow!("{}: {why}", labels[i]))?;
        let c = cal.contact_mm(t);
        for k in 0..3 {
            out[k].push(c[k]);
        }
    }
    let names = ["contact_x_mm", "contact_y_mm", "contact_z_mm"];
    for (name, v) in names.iter().zip(out) {
        ds.add_numeric_column(name, v)?;
    }
    Ok(names.iter().map(|s| s.to_string()).collect())
}

/// Adds `pred_ex_um`, `pred_ey_um`, `pred_ez_um` (and `pred_deviation_um` when the beams are known).
pub fn predict_geometry(
    model: &axcomp_geometry::GeometryModel,
    ds: &mut Dataset,
) -> anyhow::Result<Vec<String>> {
    let rows = axcomp_geometry::predict_rows(model, ds)?;
    if rows.len() != ds.n_rows() {
        bail!(
            "{}: {} rows but {} predictions",
            ds.source(),
            ds.n_rows(),
            rows.len()
        );
    }
    let mut names = Vec::new();
    for (k, name) in ["pred_ex_um", "pred_ey_um", "pred_ez_um"]
        .iter()
        .enumerate()
    {
        ds.add_numeric_column(name, rows.iter().map(|r| r.e_um[k]).collect())?;
        names.push(name.to_string());
    }
    if rows.iter().all(|r| r.deviation_um.is_some()) {
        let dev = rows
            .iter()
            .map(|r| r.deviation_um.unwrap_or(f64::NAN))
            .collect();
        ds.add_numeric_column("pred_deviation_um", dev)?;
        names.push("pred_deviation_um".into());
    }
    Ok(names)
}

/// Adds `pred_dx_um`, `pred_dy_um`, `pred_dz_um`.
pub fn predict_rtest(
    model: &axcomp_rtest::RtestModel,
    ds: &mut Dataset,
) -> anyhow::Result<Vec<String>> {
    let rows = axcomp_rtest::predict_rows(model, ds)?;
    let mut names = Vec::new();
    for (k, name) in ["pred_dx_um", "pred_dy_um", "pred_dz_um"]
        .iter()
        .enumerate()
    {
        ds.add_numeric_column(name, rows.iter().map(|r| r[k]).collect())?;
        names.push(name.to_string());
    }
    Ok(names)
}
