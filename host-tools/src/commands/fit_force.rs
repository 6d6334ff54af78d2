//! `axcomp fit force`: cutting-force laws and milling force coefficients.
//!
//! Glossary:
//! - **power law** (`--kind power`): `F = K·ap^x·fz^y·n^z` from a contract CSV (`ap_mm`, `fz_mm`, a `*_rpm`
//!   column, a `*_N` force column); log-linear start, Levenberg–Marquardt refinement, 95 % intervals from the
//!   Jacobian with Student-t quantiles.
//! - **milling** (`--kind milling`): Kistler DynoWare CSV exports (not contract CSVs), one per feed; mean
//!   forces over whole spindle revolutions → Altintas' slotting identification of Ktc, Krc, Kac, Kte, Kre, Kae.
//!
//! Reading, fitting and reports are the library's ([`axcomp_thermal::force_data`], [`axcomp_thermal::force`],
//! [`axcomp_thermal::milling`]); this command parses, calls and writes.

use std::path::PathBuf;

use anyhow::{Context, bail};
use axcomp_data::LoadOptions;
use axcomp_thermal::force::fit_power_law;
use axcomp_thermal::force_data::{
    milling_report, milling_summary, power_columns, power_report, power_rows_json, power_summary,
    power_validation, set_and_fixed,
};
use axcomp_thermal::milling::{
    AxisMap, DynoWare, MillingCoefficients, fz_from_file_name, mean_forces, slotting_coefficients,
};
use serde_json::json;

use crate::output::OutputSet;

const LONG_HELP: &str = "\
--kind power reads a measurement CSV (--data with --where/--rename/--scale): columns ap_mm, fz_mm, a `*_rpm` column and a force column (--force-col, default the only `*_N` column). A parameter column the file lacks can be given a constant with --set COL=VALUE; the exponent of a parameter that does not vary must be fixed (--fix x_ap=1: Kienzle's force ∝ chip width; --fix z_n=0). Without a `*_rpm` column z_n = 0. Fit: log-linear least squares as start, Levenberg–Marquardt on the force residuals; 95 % intervals θ ± t(0.975, n−p)·sqrt(diag(s²(JᵀJ)⁻¹)). With x_ap fixed at 1 the Kienzle parameters kc1.1 = K and mc = 1 − y are reported. --validate FILE applies the law to a second file (same options plus --validate-rename; --set only fills columns that file lacks) and reports its residuals. --out LAW.json writes the law for `axcomp fit thermal --force-law COL=LAW.json` (the firmware then predicts that force from ap, fz and n).

--kind milling reads Kistler DynoWare CSV exports (--dynoware, one file per feed; header block, `Time,Fx,Fy,Fz`, a units row, data; sampling rate from the header) of slotting tests with --flutes teeth at --n-rpm and axial depth --ap-mm. Feed per tooth from --fz (one per file, same order) or from the file name (`...f300...` = 300 mm/min feed speed, fz = 300/(n·flutes)). Mean forces over whole spindle revolutions, then Altintas' average-force method: a least-squares line per direction over the feeds gives Ktc, Krc, Kac (N/mm²) and Kte, Kre, Kae (N/mm) with 95 % intervals. --axes maps dynamometer channels to the reference axes x = feed, y = normal, z = tool axis (default x=Fy,y=Fx,z=Fz, as the data's author's MATLAB code reads the columns).

Examples:
  axcomp fit force --kind milling --dynoware 6-n6000f*.csv
    --n-rpm 6000 --flutes 2 --ap-mm 3 --json milling.json
  axcomp fit force --data Ks_feed_sweep_Datos_v5.csv
    --rename f_cal=fz_mm --rename Fz=Fz_N --set ap_mm=1 --fix x_ap=1 --fix z_n=0
    --validate fixed_feed_depth_sweep_Datos_v5.csv --validate-rename ap=ap_mm";

#[derive(Debug, clap::Args)]
#[command(after_long_help = LONG_HELP)]
pub struct Args {
    /// power (contract CSV) or milling (DynoWare exports).
    #[arg(long, default_value = "power", value_name = "KIND")]
    pub kind: String,
    /// The measurement CSV (--kind power).
    #[arg(long, value_name = "FILE")]
    pub data: Option<PathBuf>,
    /// Keep only rows where COL equals VALUE (repeatable).
    #[arg(long = "where", value_name = "COL=VALUE")]
    pub where_: Vec<String>,
    /// Rename a column before anything else (repeatable).
    #[arg(long, value_name = "OLD=NEW")]
    pub rename: Vec<String>,
    /// Multiply a column after renaming (repeatable).
    #[arg(long, value_name = "COL=FACTOR")]
    pub scale: Vec<String>,
    /// Force column (default: the only `*_N` column).
    #[arg(long, value_name = "COL")]
    pub force_col: Option<String>,
    /// Constant value of a parameter column (ap_mm, fz_mm, n_rpm) the file lacks (repeatable).
    #[arg(long, value_name = "COL=VALUE")]
    pub set: Vec<String>,
    /// Hold an exponent fixed: x_ap=V, y_fz=V or z_n=V (repeatable).
    #[arg(long, value_name = "NAME=VALUE")]
    pub fix: Vec<String>,
    /// Apply the fitted law to this second file (same --rename/--scale, plus --validate-rename) and report its
    /// residuals.
    #[arg(long, value_name = "FILE")]
    pub validate: Option<PathBuf>,
    /// Extra renames applied only to the --validate file (repeatable).
    #[arg(long, value_name = "OLD=NEW")]
    pub validate_rename: Vec<String>,
    /// DynoWare CSV exports, one per feed (--kind milling).
    #[arg(long, num_args = 1.., value_name = "FILES")]
    pub dynoware: Vec<PathBuf>,
    /// Spindle speed (rpm) (--kind milling).
    #[arg(long, value_name = "RPM")]
    pub n_rpm: Option<f64>,
    /// Number of flutes (--kind milling).
    #[arg(long, value_name = "N")]
    pub flutes: Option<u32>,
    /// Axial depth of cut (mm) (--kind milling).
    #[arg(long, value_name = "MM")]
    pub ap_mm: Option<f64>,
    /// Feed per tooth per file (mm), comma separated, in --dynoware order (default: from the file names).
    #[arg(long, value_delimiter = ',', value_name = "MM")]
    pub fz: Vec<f64>,
    /// Reference axes from dynamometer channels, e.g. x=Fy,y=Fx,z=Fz or x=-Fy,y=-Fx,z=-Fz.
    #[arg(long, default_value = "x=Fy,y=Fx,z=Fz", value_name = "MAP")]
    pub axes: String,
    /// Machine-readable result.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write report.md and SVG plots into DIR.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Write the fitted law (--kind power) as a force-law file for `axcomp fit thermal --force-law`.
    #[arg(long, value_name = "LAW.json")]
    pub out: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // Every output path is checked before the work; all are written together at the end, or none.
    let mut outputs = OutputSet::new();
    if let Some(p) = &args.data {
        outputs.input(p);
    }
    for p in [&args.out, &args.json].into_iter().flatten() {
        outputs.planned(p);
    }
    if let Some(dir) = &args.report {
        outputs.folder(dir, "--report");
        outputs.planned_in(dir, "report.md");
    }
    outputs.check()?;
    match args.kind.as_str() {
        "power" => run_power(&args, &mut outputs)?,
        "milling" => run_milling(&args, &mut outputs)?,
        k => bail!("--kind `{k}`: expected power or milling"),
    }
    let written = outputs.commit()?;
    if let (Some(p), true) = (&args.out, args.kind == "power") {
        if written.contains(p) {
            println!("force law written to {}", p.display());
        }
    }
    Ok(())
}

fn run_power(args: &Args, outputs: &mut OutputSet) -> anyhow::Result<()> {
    let data = args
        .data
        .as_ref()
        .context("--kind power needs --data FILE")?;
    let load = LoadOptions::from_args(&args.where_, &args.rename, &args.scale)?;
    let (set, mut fixed) = set_and_fixed(&args.set, &args.fix)?;
    let cols = power_columns(data, &load, args.force_col.as_deref(), &set, true)?;
    if cols.notes.iter().any(|n| n.starts_with("no *_rpm")) && fixed.z_n.is_none() {
        fixed.z_n = Some(0.0);
    }
    let fit =
        fit_power_law(&cols.data, fixed).with_context(|| format!("fitting {}", data.display()))?;
    let rows = power_rows_json(&fit, &cols.data);
    let (summary, kienzle) = power_summary(&fit, cols.data.force_n.len());
    print!("{summary}");
    let validation = match &args.validate {
        Some(vf) => {
            let mut rename = args.rename.clone();
            rename.extend(args.validate_rename.iter().cloned());
            let vload = LoadOptions::from_args(&args.where_, &rename, &args.scale)?;
            let v = power_columns(vf, &vload, args.force_col.as_deref(), &set, false)?;
            let (j, line) = power_validation(&fit, &v, &vf.display().to_string());
            println!("{line}");
            Some(j)
        }
        None => None,
    };
    let out = json!({
        "kind": "power", "data": data.display().to_string(), "force_column": cols.force_col, "notes": cols.notes,
        "law": fit, "kienzle": kienzle, "rows": rows, "validation": validation,
    });
    if let Some(p) = &args.out {
        let law = axcomp_thermal::model_file::ModelForceLaw {
            k: fit.k.value,
            x_ap: fit.x_ap.value,
            y_fz: fit.y_fz.value,
            z_n: fit.z_n.value,
        };
        let provenance = crate::provenance::of_file(
            data,
            &args.where_,
            &args.rename,
            &args.scale,
            None,
            None,
            &cols.force_col,
            "fit force",
        )?;
        outputs.file(p, crate::provenance::stamp(&law, &provenance)?);
    }
    if let Some(j) = &args.json {
        outputs.file(j, serde_json::to_string_pretty(&out)?);
    }
    if let Some(dir) = &args.report {
        for (name, bytes) in power_report(&fit, &cols.data, &out) {
            outputs.folder_file(dir, name, bytes);
        }
    }
    Ok(())
}

fn run_milling(args: &Args, outputs: &mut OutputSet) -> anyhow::Result<()> {
    if args.out.is_some() {
        bail!("--out writes a power law; it applies to --kind power only");
    }
    if args.dynoware.is_empty() {
        bail!("--kind milling needs --dynoware FILES (one DynoWare export per feed)");
    }
    let n_rpm = args
        .n_rpm
        .filter(|v| *v > 0.0 && v.is_finite())
        .context("--kind milling needs --n-rpm > 0")?;
    let flutes = f64::from(
        args.flutes
            .filter(|v| *v > 0)
            .context("--kind milling needs --flutes > 0")?,
    );
    let ap = args
        .ap_mm
        .filter(|v| *v > 0.0 && v.is_finite())
        .context("--kind milling needs --ap-mm > 0")?;
    let axes = AxisMap::parse(&args.axes).map_err(|e| anyhow::anyhow!("--axes {e}"))?;
    if !args.fz.is_empty() && args.fz.len() != args.dynoware.len() {
        bail!(
            "--fz has {} values for {} --dynoware files",
            args.fz.len(),
            args.dynoware.len()
        );
    }
    if args.dynoware.len() < 3 {
        bail!(
            "--kind milling needs at least 3 feeds (files) for lines with intervals; got {}",
            args.dynoware.len()
        );
    }
    let mut tests = vec![];
    for (i, p) in args.dynoware.iter().enumerate() {
        let fz = match args.fz.get(i) {
            Some(v) => *v,
            None => {
                fz_from_file_name(&p.display().to_string(), n_rpm, flutes).with_context(|| {
                    format!(
                        "{}: no feed `f<mm/min>` in the file name; give --fz",
                        p.display()
                    )
                })?
            }
        };
        let d = DynoWare::load(p)?;
        tests.push(mean_forces(&d, fz, n_rpm, axes));
    }
    let k: MillingCoefficients = slotting_coefficients(&tests, flutes, ap);
    print!("{}", milling_summary(&tests, &k, &args.axes));
    if k.ktc_n_mm2.value <= 0.0 {
        eprintln!(
            "warning: Ktc <= 0: the axis mapping (--axes) or the spindle direction is probably the other way round"
        );
    }
    let out = json!({"kind": "milling", "n_rpm": n_rpm, "flutes": flutes, "ap_mm": ap, "axes": args.axes,
                     "tests": tests, "coefficients": k});
    if let Some(j) = &args.json {
        outputs.file(j, serde_json::to_string_pretty(&out)?);
    }
    if let Some(dir) = &args.report {
        for (name, bytes) in milling_report(&tests, &k, n_rpm, flutes, ap, &args.axes) {
            outputs.folder_file(dir, name, bytes);
        }
    }
    Ok(())
}
