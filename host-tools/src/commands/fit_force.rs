//! `axcomp fit force`: cutting-force laws and milling force coefficients.
//!
//! Glossary:
//! - **power law** (`--kind power`): `F = K·ap^x·fz^y·n^z` from a contract CSV (`ap_mm`, `fz_mm`, a `*_rpm`
//!   column, a `*_N` force column); log-linear start, Levenberg–Marquardt refinement, 95 % intervals from the
//!   Jacobian with Student-t quantiles.
//! - **milling** (`--kind milling`): Kistler DynoWare CSV exports (not contract CSVs), one per feed; mean
//!   forces over whole spindle revolutions → Altintas' slotting identification of Ktc, Krc, Kac, Kte, Kre, Kae.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, bail};
use axcomp_data::{Dataset, LoadOptions};
use axcomp_plot::{Figure, markdown_table};
use axcomp_thermal::force::{FixedExponents, PowerLawData, PowerLawFit, fit_power_law};
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

fn parse_pairs(opt: &str, v: &[String]) -> anyhow::Result<Vec<(String, f64)>> {
    v.iter()
        .map(|s| {
            let (k, val) = s
                .split_once('=')
                .with_context(|| format!("{opt} `{s}`: expected NAME=VALUE"))?;
            let x: f64 = val
                .trim()
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .with_context(|| format!("{opt} `{s}`: `{val}` is not a finite number"))?;
            Ok((k.trim().to_string(), x))
        })
        .collect()
}

struct PowerColumns {
    data: PowerLawData,
    notes: Vec<String>,
    force_col: String,
}

fn power_columns(
    path: &std::path::Path,
    load: &LoadOptions,
    force_col: Option<&str>,
    set: &[(String, f64)],
    strict_set: bool,
) -> anyhow::Result<PowerColumns> {
    let ds = Dataset::load(path, load)?;
    let n = ds.n_rows();
    if n == 0 {
        bail!("{}: no rows (after --where)", path.display());
    }
    let mut notes = vec![];
    let force_col = match force_col {
        Some(c) => c.to_string(),
        None => {
            let f: Vec<&str> = ds
                .column_names()
                .into_iter()
                .filter(|c| c.len() > 2 && c.ends_with("_N"))
                .collect();
            match f.as_slice() {
                [one] => one.to_string(),
                [] => bail!(
                    "{}: no `*_N` force column (use --rename or --force-col)",
                    path.display()
                ),
                many => bail!(
                    "{}: several force columns ({}); choose one with --force-col",
                    path.display(),
                    many.join(", ")
                ),
            }
        }
    };
    // Rows without a cut (force 0 N with ap_mm, fz_mm or the spindle speed 0: the idle periods of a spindle
    // campaign such as `axcomp sim --plan spindle`'s) are no power-law data: left out with a note. Any other
    // zero or negative value stays an error below.
    let (ds, n) = {
        let zero = |c: &str| -> Vec<bool> {
            match ds.numeric(c) {
                Ok(v) => v.iter().map(|x| *x == 0.0).collect(),
                Err(_) => vec![false; n],
            }
        };
        let rpm_col = ds
            .column_names()
            .into_iter()
            .find(|c| c.ends_with("_rpm"))
            .map(str::to_string);
        let force0 = zero(&force_col);
        let (ap0, fz0) = (zero("ap_mm"), zero("fz_mm"));
        let rpm0 = rpm_col.as_deref().map_or(vec![false; n], zero);
        let keep: Vec<bool> = (0..n)
            .map(|i| !(force0[i] && (ap0[i] || fz0[i] || rpm0[i])))
            .collect();
        let idle = keep.iter().filter(|k| !**k).count();
        if idle == 0 {
            (ds, n)
        } else if idle == n {
            bail!(
                "{}: no row with a cut (every row has `{force_col}` 0 N and ap_mm, fz_mm or the speed 0)",
                path.display()
            );
        } else {
            notes.push(format!(
                "{idle} rows without a cut (`{force_col}` 0 N with ap_mm, fz_mm or the speed 0) left out"
            ));
            (ds.select_rows(&keep), n - idle)
        }
    };
    let mut param = |col: &str, rpm: bool| -> anyhow::Result<Vec<f64>> {
        let name = if rpm {
            ds.column_names()
                .into_iter()
                .find(|c| c.ends_with("_rpm"))
                .map(str::to_string)
        } else {
            ds.has(col).then(|| col.to_string())
        };
        if let Some(c) = name {
            if strict_set && set.iter().any(|(k, _)| k == col) {
                bail!("--set {col}: {} already has a `{c}` column", path.display());
            }
            return Ok(ds.numeric(&c)?.to_vec());
        }
        if let Some((_, v)) = set.iter().find(|(k, _)| k == col) {
            notes.push(format!("{col} = {v} for every row (--set)"));
            return Ok(vec![*v; n]);
        }
        if rpm {
            notes.push("no *_rpm column: z_n fixed at 0".into());
            return Ok(vec![1.0; n]);
        }
        bail!(
            "{}: no `{col}` column (use --rename, or --set {col}=VALUE for a constant)",
            path.display()
        )
    };
    let ap_mm = param("ap_mm", false)?;
    let fz_mm = param("fz_mm", false)?;
    let n_rpm = param("n_rpm", true)?;
    let force_n = ds.numeric(&force_col)?.to_vec();
    // A power law needs positive values: a bad one is named by file, line and column here (the fit only
    // knows the data row).
    let rpm_col = ds
        .column_names()
        .into_iter()
        .find(|c| c.ends_with("_rpm"))
        .map(str::to_string);
    for col in ["ap_mm", "fz_mm", force_col.as_str()]
        .into_iter()
        .chain(rpm_col.as_deref())
    {
        if !ds.has(col) {
            continue;
        }
        let v = ds.numeric(col)?;
        if let Some(row) = v.iter().position(|x| !(x.is_finite() && *x > 0.0)) {
            bail!(
                "{}: {} is not a positive finite number (a power law needs > 0)",
                ds.locate(col, row),
                v[row]
            );
        }
    }
    Ok(PowerColumns {
        data: PowerLawData {
            ap_mm,
            fz_mm,
            n_rpm,
            force_n,
        },
        notes,
        force_col,
    })
}

fn run_power(args: &Args, outputs: &mut OutputSet) -> anyhow::Result<()> {
    let data = args
        .data
        .as_ref()
        .context("--kind power needs --data FILE")?;
    let load = LoadOptions::from_args(&args.where_, &args.rename, &args.scale)?;
    let set = parse_pairs("--set", &args.set)?;
    for (k, _) in &set {
        if !["ap_mm", "fz_mm", "n_rpm"].contains(&k.as_str()) {
            bail!("--set {k}: only ap_mm, fz_mm or n_rpm");
        }
    }
    let mut fixed = FixedExponents::default();
    for (k, v) in parse_pairs("--fix", &args.fix)? {
        match k.as_str() {
            "x_ap" => fixed.x_ap = Some(v),
            "y_fz" => fixed.y_fz = Some(v),
            "z_n" => fixed.z_n = Some(v),
            _ => bail!("--fix {k}: expected x_ap, y_fz or z_n"),
        }
    }
    let cols = power_columns(data, &load, args.force_col.as_deref(), &set, true)?;
    if cols.notes.iter().any(|n| n.starts_with("no *_rpm")) && fixed.z_n.is_none() {
        fixed.z_n = Some(0.0);
    }
    let fit =
        fit_power_law(&cols.data, fixed).with_context(|| format!("fitting {}", data.display()))?;
    let d = &cols.data;
    let rows: Vec<serde_json::Value> = (0..d.force_n.len())
        .map(|i| {
            json!({"ap_mm": d.ap_mm[i], "fz_mm": d.fz_mm[i], "n_rpm": d.n_rpm[i], "force_n": d.force_n[i],
                   "predicted_n": fit.predict(d.ap_mm[i], d.fz_mm[i], d.n_rpm[i]), "residual_n": fit.residuals_n[i]})
        })
        .collect();
    println!(
        "F = {:.4}·ap^{:.4}·fz^{:.4}·n^{:.4}  ({} rows, {} dof, residual RMS {:.3} N)",
        fit.k.value,
        fit.x_ap.value,
        fit.y_fz.value,
        fit.z_n.value,
        d.force_n.len(),
        fit.dof,
        fit.rms_n
    );
    for (name, e) in [
        ("K", fit.k),
        ("x_ap", fit.x_ap),
        ("y_fz", fit.y_fz),
        ("z_n", fit.z_n),
    ] {
        match (e.fixed, e.ci95) {
            (true, _) => println!("  {name} = {} (fixed)", e.value),
            (false, Some([lo, hi])) => {
                println!("  {name} = {:.4}, 95 % CI [{lo:.4}, {hi:.4}]", e.value)
            }
            (false, None) => println!(
                "  {name} = {:.4} (no interval: no residual degrees of freedom)",
                e.value
            ),
        }
    }
    let kienzle = (fit.x_ap.fixed && fit.x_ap.value == 1.0).then(|| {
        let mc = 1.0 - fit.y_fz.value;
        println!(
            "  Kienzle: kc1.1 = {:.1} N/mm², mc = 1 − y = {mc:.4}",
            fit.k.value
        );
        json!({"kc11_n_mm2": fit.k.value, "mc": mc,
               "mc_ci95": fit.y_fz.ci95.map(|[lo, hi]| [1.0 - hi, 1.0 - lo]),
               "kc11_ci95": fit.k.ci95})
    });
    let validation = match &args.validate {
        Some(vf) => {
            let mut rename = args.rename.clone();
            rename.extend(args.validate_rename.iter().cloned());
            let vload = LoadOptions::from_args(&args.where_, &rename, &args.scale)?;
            let v = power_columns(vf, &vload, args.force_col.as_deref(), &set, false)?;
            let vd = &v.data;
            let pred: Vec<f64> = (0..vd.force_n.len())
                .map(|i| fit.predict(vd.ap_mm[i], vd.fz_mm[i], vd.n_rpm[i]))
                .collect();
            let res: Vec<f64> = vd.force_n.iter().zip(&pred).map(|(a, b)| a - b).collect();
            let rms = axcomp_thermal::stats::rms(&res);
            let max_rel = res
                .iter()
                .zip(&vd.force_n)
                .map(|(r, f)| (r / f).abs())
                .fold(0.0, f64::max);
            println!(
                "validation on {}: residual RMS {rms:.3} N, largest relative error {:.1} %",
                vf.display(),
                100.0 * max_rel
            );
            Some(
                json!({"data": vf.display().to_string(), "rms_n": rms, "max_rel_error": max_rel, "notes": v.notes,
                "rows": (0..vd.force_n.len()).map(|i| json!({"ap_mm": vd.ap_mm[i], "fz_mm": vd.fz_mm[i], "n_rpm": vd.n_rpm[i],
                    "force_n": vd.force_n[i], "predicted_n": pred[i], "residual_n": res[i]})).collect::<Vec<_>>()}),
            )
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
            outputs.folder_file(dir, &name, bytes);
        }
    }
    Ok(())
}

/// `force_fit.svg` and `report.md` of a power-law fit.
fn power_report(
    fit: &PowerLawFit,
    d: &PowerLawData,
    out: &serde_json::Value,
) -> Vec<(&'static str, Vec<u8>)> {
    let pred: Vec<f64> = (0..d.force_n.len())
        .map(|i| fit.predict(d.ap_mm[i], d.fz_mm[i], d.n_rpm[i]))
        .collect();
    // Measured and model force per sample (fitted rows, then the validation rows), so that eight rows read
    // as eight pairs rather than a parity line.
    let n_fit = d.force_n.len();
    let mut xs: Vec<f64> = (1..=n_fit).map(|i| i as f64).collect();
    let mut meas = d.force_n.clone();
    let mut model = pred.clone();
    let validation = out["validation"]["rows"].as_array();
    if let Some(rows) = validation {
        for r in rows {
            if let (Some(m), Some(p)) = (r["force_n"].as_f64(), r["predicted_n"].as_f64()) {
                xs.push(xs.len() as f64 + 1.0);
                meas.push(m);
                model.push(p);
            }
        }
    }
    let val_note = match out["validation"]["max_rel_error"].as_f64() {
        Some(e) => format!(", validation rows worst {:.1} %", 100.0 * e),
        None => String::new(),
    };
    let mut f = Figure::new(
        &format!(
            "Cutting force: measured vs the power law F = K·ap^x·fz^y·n^z ({}), fit RMS {:.2} N{val_note}",
            fit.method.split(" (").next().unwrap_or(&fit.method),
            fit.rms_n
        ),
        "sample (fitted rows, then validation rows)",
        &axcomp_plot::label("force", "N"),
    );
    f.magnitude();
    if xs.len() > n_fit {
        f.vspan(
            n_fit as f64 + 0.5,
            xs.len() as f64 + 0.5,
            "validation rows (not fitted)",
        );
    }
    f.points("measured", &xs, &meas);
    f.points("model", &xs, &model);
    let svg = f.to_svg();
    let mut md = format!(
        "# Force law\n\nF = {:.4}·ap^{:.4}·fz^{:.4}·n^{:.4}, residual RMS {:.3} N ({}).\n\n",
        fit.k.value, fit.x_ap.value, fit.y_fz.value, fit.z_n.value, fit.rms_n, fit.method
    );
    let rows: Vec<Vec<String>> = [
        ("K", fit.k),
        ("x_ap", fit.x_ap),
        ("y_fz", fit.y_fz),
        ("z_n", fit.z_n),
    ]
    .iter()
    .map(|(n, e)| {
        vec![
            n.to_string(),
            format!("{:.5}", e.value),
            if e.fixed {
                "fixed".into()
            } else {
                e.ci95
                    .map_or("–".into(), |[a, b]| format!("[{a:.5}, {b:.5}]"))
            },
        ]
    })
    .collect();
    md += &markdown_table(&["parameter", "value", "95 % CI"], &rows);
    md += "\n![fit](force_fit.svg)\n";
    vec![
        ("force_fit.svg", svg.into_bytes()),
        ("report.md", md.into_bytes()),
    ]
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
    println!(
        "mean forces over whole revolutions (reference axes {}):",
        args.axes
    );
    for t in &tests {
        println!(
            "  fz {:.4} mm: Fx {:8.2} N, Fy {:8.2} N, Fz {:8.2} N ({} revolutions)",
            t.fz_mm, t.fx_n, t.fy_n, t.fz_n, t.revolutions
        );
    }
    let show = |n: &str, c: axcomp_thermal::milling::Coef, u: &str| {
        println!(
            "  {n} = {:10.2} ± {} {u}",
            c.value,
            c.ci95_half.map_or("–".into(), |h| format!("{h:.2}"))
        );
    };
    show("Ktc", k.ktc_n_mm2, "N/mm²");
    show("Krc", k.krc_n_mm2, "N/mm²");
    show("Kac", k.kac_n_mm2, "N/mm²");
    show("Kte", k.kte_n_mm, "N/mm");
    show("Kre", k.kre_n_mm, "N/mm");
    show("Kae", k.kae_n_mm, "N/mm");
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
        let c: Vec<f64> = tests.iter().map(|t| t.fz_mm).collect();
        let mut f = Figure::new(
            &format!(
                "Slotting at {n_rpm} rpm: mean forces vs feed per tooth ({} feeds) and the Altintas lines, Ktc {:.0} N/mm², Kte {:.1} N/mm",
                tests.len(),
                k.ktc_n_mm2.value,
                k.kte_n_mm.value
            ),
            &axcomp_plot::label("feed per tooth fz", "mm"),
            &axcomp_plot::label("mean force", "N"),
        );
        let lines = &k.lines;
        for (i, (name, v)) in [
            ("Fx", tests.iter().map(|t| t.fx_n).collect::<Vec<_>>()),
            ("Fy", tests.iter().map(|t| t.fy_n).collect()),
            ("Fz", tests.iter().map(|t| t.fz_n).collect()),
        ]
        .iter()
        .enumerate()
        {
            let fit: Vec<f64> = c
                .iter()
                .map(|x| lines[i].slope * x + lines[i].intercept)
                .collect();
            f.points(&format!("{name} measured"), &c, v);
            f.line(&format!("{name} line (fitted)"), &c, &fit)
                .like_previous();
        }
        outputs.folder_file(dir, "mean_forces.svg", f.to_svg());
        let mut md = String::from(
            "# Milling force coefficients (slotting, Altintas average-force method)\n\n",
        );
        let _ = writeln!(
            md,
            "n = {n_rpm} rpm, {flutes} flutes, ap = {ap} mm, axes {}.\n",
            args.axes
        );
        let rows: Vec<Vec<String>> = [
            ("Ktc", k.ktc_n_mm2, "N/mm²"),
            ("Krc", k.krc_n_mm2, "N/mm²"),
            ("Kac", k.kac_n_mm2, "N/mm²"),
            ("Kte", k.kte_n_mm, "N/mm"),
            ("Kre", k.kre_n_mm, "N/mm"),
            ("Kae", k.kae_n_mm, "N/mm"),
        ]
        .iter()
        .map(|(n, c, u)| {
            vec![
                n.to_string(),
                format!("{:.2}", c.value),
                c.ci95_half.map_or("–".into(), |h| format!("{h:.2}")),
                u.to_string(),
            ]
        })
        .collect();
        md += &markdown_table(&["coefficient", "value", "± 95 %", "unit"], &rows);
        md += "\n![mean forces](mean_forces.svg)\n";
        outputs.folder_file(dir, "report.md", md);
    }
    Ok(())
}
