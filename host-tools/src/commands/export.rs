//! `axcomp export`: a fitted model in the file format a controller loads.
//!
//! Glossary:
//! - *model kind*: told apart by the model file's `format` / `kind` field (as `predict` does).
//! - *positioning formats*: `linuxcnc0`, `linuxcnc1`, `csv` (`axcomp_positioning::export`), one file at
//!   `--out FILE`.
//! - *geometry / rotary formats*: `tf5280`, `heidenhain`, `linuxcnc-xyzac-trt`, `linuxcnc-xyzbc-trt`
//!   (`axcomp_export`), a folder at `--out DIR` written whole: a later export into it removes the files of
//!   the earlier one it does not write again; the user's own files stay.

use std::path::PathBuf;

use anyhow::{Context, bail};
use axcomp_export::{Format, ModelKind};
use axcomp_positioning::TableFile;
use axcomp_positioning::export::{ExportFormat, export};

use crate::commands::common::{ModelKind as FileKind, model_kind};
use crate::output::OutputSet;

const FORMATS_HELP: &str = "Formats by model kind:
  positioning table (fit positioning):  linuxcnc0, linuxcnc1, csv (--out FILE, --step needed)
  geometry model (fit geometry):        tf5280: TwinCAT TF5280 ISG CSV tables + volcomp.lis
                                        heidenhain: TNC tables X.COM Y.COM Z.COM + AXCOMP.CMA
  rotary-axis model (fit rtest):        linuxcnc-xyzac-trt: xyzac-trt-kins (ac-trunnion)
                                        linuxcnc-xyzbc-trt: xyzbc-trt-kins (bc-trunnion)
Geometry and rotary formats write the folder --out DIR whole: files of an earlier export
that this one does not write are removed, other files are kept. Each file states its
units and sign convention.

Examples:
  axcomp export --model table.json --format linuxcnc1 --step 5 --out x.comp
  axcomp export --model geometry.json --format tf5280 --out tf5280
  axcomp export --model rtest.json --format linuxcnc-xyzac-trt --poses rtest.csv --out kins";

#[derive(Debug, clap::Args)]
#[command(after_help = FORMATS_HELP)]
pub struct Args {
    /// Fitted model: positioning table, geometry model or rotary-axis model (`--table` is an alias).
    #[arg(long, alias = "table", value_name = "MODEL.json")]
    pub model: PathBuf,
    /// Output format (see the list below for the model kind each takes).
    #[arg(long, value_parser = ["linuxcnc0", "linuxcnc1", "csv", "tf5280", "heidenhain", "linuxcnc-xyzac-trt", "linuxcnc-xyzbc-trt"])]
    pub format: String,
    /// Spacing of the exported positions, mm (the last one sits at the table or axis end); required for
    /// positioning formats, default 40 steps per axis for geometry formats.
    #[arg(long, value_name = "MM")]
    pub step: Option<f64>,
    /// Rotary formats: the R-test CSV (the fitted poses) over which the remaining error is stated; default:
    /// the K4 path of `plan rtest`'s default geometry at both sphere heights.
    #[arg(long, value_name = "RTEST.csv")]
    pub poses: Option<PathBuf>,
    /// Rotary formats: the nominal rotary point in machine coordinates, mm (the location errors are added).
    #[arg(long, value_name = "X,Y,Z", default_value = "0,0,0")]
    pub rot_point_mm: String,
    /// Output: a file (positioning formats) or a folder written whole (geometry and rotary formats).
    #[arg(long, value_name = "PATH")]
    pub out: PathBuf,
}

fn kind_name(k: FileKind) -> &'static str {
    match k {
        FileKind::Positioning => ModelKind::Positioning.name(),
        FileKind::Geometry => ModelKind::Geometry.name(),
        FileKind::Rtest => ModelKind::Rotary.name(),
        FileKind::Thermal => "thermal model",
        FileKind::Probe => "probe model",
        FileKind::ForceLaw => "force law",
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let format = Format::parse(&args.format);
    let kind = match (model_kind(&args.model), format) {
        (Ok(k), _) => k,
        // A positioning table the kind reader does not know: the table reader says what is wrong with it.
        (Err(_), None) => return run_positioning(&args),
        (Err(e), Some(_)) => return Err(e),
    };
    let want = match format {
        None => FileKind::Positioning,
        Some(f) if f.model_kind() == ModelKind::Geometry => FileKind::Geometry,
        Some(_) => FileKind::Rtest,
    };
    if kind != want {
        bail!(
            "{}: --format {} takes a {}, and this file is a {} (see `axcomp export --help` for the formats of \
             each model kind)",
            args.model.display(),
            args.format,
            kind_name(want),
            kind_name(kind)
        );
    }
    match format {
        None => run_positioning(&args),
        Some(f) => run_folder(&args, f),
    }
}

fn run_positioning(args: &Args) -> anyhow::Result<()> {
    let format: ExportFormat = args.format.parse()?;
    let Some(step) = args.step else {
        bail!(
            "--format {} needs --step MM (the spacing of the exported positions)",
            args.format
        );
    };
    let mut output = OutputSet::new();
    output.planned(&args.out).input(&args.model);
    output.check()?;
    let table = TableFile::load(&args.model)
        .with_context(|| format!("reading table {}", args.model.display()))?;
    let text = export(&table, format, step)
        .with_context(|| format!("exporting {}", args.model.display()))?;
    output.file(&args.out, text.as_bytes());
    output.commit()?;
    let lines = text.lines().count() - usize::from(format == ExportFormat::Csv);
    println!(
        "wrote {} ({} entries, {:.4} .. {:.4} mm, format {})",
        args.out.display(),
        lines,
        table.start_mm,
        table.end_mm(),
        args.format
    );
    if matches!(format, ExportFormat::LinuxCnc0 | ExportFormat::LinuxCnc1) {
        println!(
            "LinuxCNC: [JOINT_n] COMP_FILE = {} and COMP_FILE_TYPE = {} (machine units mm)",
            args.out.display(),
            if format == ExportFormat::LinuxCnc0 {
                0
            } else {
                1
            }
        );
    }
    Ok(())
}

fn rot_point(s: &str) -> anyhow::Result<[f64; 3]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| anyhow::anyhow!("--rot-point-mm {s}: {e} (give X,Y,Z in mm)"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|a| a.is_finite() && a.abs() < 1e9) => Ok([*x, *y, *z]),
        _ => bail!("--rot-point-mm {s}: give three finite numbers X,Y,Z in mm"),
    }
}

fn run_folder(args: &Args, format: Format) -> anyhow::Result<()> {
    let mut output = OutputSet::new();
    output.folder(&args.out, "--out").input(&args.model);
    if let Some(p) = &args.poses {
        output.input(p);
    }
    output.check()?;
    let rot = rot_point(&args.rot_point_mm)?;
    let text = std::fs::read_to_string(&args.model)
        .with_context(|| format!("{}: cannot read", args.model.display()))?;
    let source = args.model.display().to_string();
    let step = args.step.unwrap_or(0.0);
    if !(step.is_finite() && step >= 0.0) {
        bail!("--step {step}: give a positive spacing in mm");
    }
    let (files, summary) = match format {
        Format::Tf5280 | Format::Heidenhain => {
            let model = axcomp_geometry::GeometryModel::from_json(&text, &source)?;
            if format == Format::Tf5280 {
                let files = axcomp_export::tf5280::export(&model, step)?;
                let summary = format!(
                    "chain {} (workpiece_axes {}), values in mm and rad",
                    axcomp_export::tf5280::chain(&model),
                    model.topology.work.len()
                );
                (files, summary)
            } else {
                let (files, r) = axcomp_export::heidenhain::export(&model, step)?;
                let summary = format!(
                    "not taken: the angular components; remaining |e| RMS {:.3} µm (max {:.3}) over the \
                     measured volume, model error before {:.3} µm",
                    r.after_rms_um, r.after_max_um, r.before_rms_um
                );
                (files, summary)
            }
        }
        _ => {
            let model = axcomp_rtest::RtestModel::from_json(&text, &source)?;
            let (poses, pose_source) = match &args.poses {
                Some(p) => {
                    let ds = axcomp_data::Dataset::load(p, &Default::default())?;
                    let data =
                        axcomp_rtest::RtestData::from_dataset(&ds, model.five_axis(), false)?;
                    (data.poses, format!("{}", p.display()))
                }
                None => (
                    axcomp_export::linuxcnc::default_poses(model.five_axis()),
                    "default K4 paths of plan rtest".to_string(),
                ),
            };
            let (files, r) =
                axcomp_export::linuxcnc::export(&model, format, rot, &poses, &pose_source)?;
            let summary = format!(
                "not taken: rotary-axis tilts and linear squareness; remaining RMS |d| {:.3} µm over {} poses \
                 ({}), {:.3} µm with nominal kinematics",
                r.after_rms_um, r.poses, r.pose_source, r.before_rms_um
            );
            (files, summary)
        }
    };
    for f in &files {
        output.folder_file(&args.out, &f.name, f.text.as_bytes());
    }
    output.commit()?;
    let names: Vec<&str> = files.iter().map(|f| f.name.as_str()).collect();
    println!(
        "wrote {} ({}), format {}: {summary}",
        args.out.display(),
        names.join(", "),
        format.name()
    );
    Ok(())
}
