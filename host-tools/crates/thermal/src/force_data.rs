//! Reading cutting-force data for a power law and the figures, summaries and reports of the force fits
//! (`axcomp fit force`): the power law's columns from a measurement file, its validation on a second file,
//! and the reports of the power law and of the milling coefficients.
//!
//! Glossary:
//! - **power law**: `F = K·ap^x·fz^y·n^z` ([`crate::force`]); **Kienzle**: with x_ap fixed at 1, kc1.1 = K
//!   and mc = 1 − y.
//! - **milling coefficients**: Ktc, Krc, Kac (cutting) and Kte, Kre, Kae (edge) from slotting tests
//!   ([`crate::milling`]).

use std::fmt::Write as _;

use axcomp_data::{DataError, Dataset, LoadOptions};
use axcomp_plot::{Figure, markdown_table};
use serde_json::{Value, json};

use crate::force::{FixedExponents, PowerLawData, PowerLawFit};
use crate::milling::{Coef, MeanForces, MillingCoefficients};

/// Why force data cannot be read: a message naming the option, file, line or column at fault.
#[derive(Debug, thiserror::Error)]
pub enum ForceInputError {
    #[error("{0}")]
    Input(String),
    #[error(transparent)]
    Data(#[from] DataError),
}

fn input(msg: String) -> ForceInputError {
    ForceInputError::Input(msg)
}

/// `--set` constants (only ap_mm, fz_mm, n_rpm) and `--fix` exponents (x_ap, y_fz, z_n).
pub fn set_and_fixed(
    set: &[String],
    fix: &[String],
) -> Result<(Vec<(String, f64)>, FixedExponents), ForceInputError> {
    let set = parse_pairs("--set", set)?;
    for (k, _) in &set {
        if !["ap_mm", "fz_mm", "n_rpm"].contains(&k.as_str()) {
            return Err(input(format!("--set {k}: only ap_mm, fz_mm or n_rpm")));
        }
    }
    let mut fixed = FixedExponents::default();
    for (k, v) in parse_pairs("--fix", fix)? {
        match k.as_str() {
            "x_ap" => fixed.x_ap = Some(v),
            "y_fz" => fixed.y_fz = Some(v),
            "z_n" => fixed.z_n = Some(v),
            _ => return Err(input(format!("--fix {k}: expected x_ap, y_fz or z_n"))),
        }
    }
    Ok((set, fixed))
}

/// `NAME=VALUE` pairs of option `opt` (`--set`, `--fix`), each value a finite number.
pub fn parse_pairs(opt: &str, v: &[String]) -> Result<Vec<(String, f64)>, ForceInputError> {
    v.iter()
        .map(|s| {
            let (k, val) = s
                .split_once('=')
                .ok_or_else(|| input(format!("{opt} `{s}`: expected NAME=VALUE")))?;
            let x: f64 = val
                .trim()
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .ok_or_else(|| input(format!("{opt} `{s}`: `{val}` is not a finite number")))?;
            Ok((k.trim().to_string(), x))
        })
        .collect()
}

/// The power-law columns of a file: the data, the notes on what was assumed or left out, the force column.
pub struct PowerColumns {
    pub data: PowerLawData,
    pub notes: Vec<String>,
    pub force_col: String,
}

/// Reads the power-law columns of `path`: the force column (`force_col`, else the only `*_N` column),
/// `ap_mm`, `fz_mm` and a `*_rpm` column, or the `set` constants for those the file lacks (with
/// `strict_set`, a constant for a column the file has is an error). Rows without a cut are left out with a
/// note; every value used must be positive and finite.
pub fn power_columns(
    path: &std::path::Path,
    load: &LoadOptions,
    force_col: Option<&str>,
    set: &[(String, f64)],
    strict_set: bool,
) -> Result<PowerColumns, ForceInputError> {
    let ds = Dataset::load(path, load)?;
    let n = ds.n_rows();
    if n == 0 {
        return Err(input(format!(
            "{}: no rows (after --where)",
            path.display()
        )));
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
                [] => {
                    return Err(input(format!(
                        "{}: no `*_N` force column (use --rename or --force-col)",
                        path.display()
                    )));
                }
                many => {
                    return Err(input(format!(
                        "{}: several force columns ({}); choose one with --force-col",
                        path.display(),
                        many.join(", ")
                    )));
                }
            }
        }
    };
    let (ds, n) = without_idle_rows(ds, &force_col, path, &mut notes)?;
    let mut param = |col: &str, rpm: bool| -> Result<Vec<f64>, ForceInputError> {
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
                return Err(input(format!(
                    "--set {col}: {} already has a `{c}` column",
                    path.display()
                )));
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
        return Err(input(format!(
            "{}: no `{col}` column (use --rename, or --set {col}=VALUE for a constant)",
            path.display()
        )));
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
            return Err(input(format!(
                "{}: {} is not a positive finite number (a power law needs > 0)",
                ds.locate(col, row),
                v[row]
            )));
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

/// Rows without a cut (force 0 N with ap_mm, fz_mm or the spindle speed 0: the idle periods of a spindle
/// campaign such as `axcomp sim --plan spindle`'s) are no power-law data: left out with a note. Any other
/// zero or negative value stays an error (checked by the caller).
fn without_idle_rows(
    ds: Dataset,
    force_col: &str,
    path: &std::path::Path,
    notes: &mut Vec<String>,
) -> Result<(Dataset, usize), ForceInputError> {
    let n = ds.n_rows();
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
    let force0 = zero(force_col);
    let (ap0, fz0) = (zero("ap_mm"), zero("fz_mm"));
    let rpm0 = rpm_col.as_deref().map_or(vec![false; n], zero);
    let keep: Vec<bool> = (0..n)
        .map(|i| !(force0[i] && (ap0[i] || fz0[i] || rpm0[i])))
        .collect();
    let idle = keep.iter().filter(|k| !**k).count();
    if idle == 0 {
        Ok((ds, n))
    } else if idle == n {
        return Err(input(format!(
            "{}: no row with a cut (every row has `{force_col}` 0 N and ap_mm, fz_mm or the speed 0)",
            path.display()
        )));
    } else {
        notes.push(format!(
                "{idle} rows without a cut (`{force_col}` 0 N with ap_mm, fz_mm or the speed 0) left out"
            ));
        Ok((ds.select_rows(&keep), n - idle))
    }
}

/// `force_fit.svg` and `report.md` of a power-law fit.
pub fn power_report(
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

/// Per row: the parameters, the measured and predicted force and the residual (JSON rows).
pub fn power_rows_json(fit: &PowerLawFit, d: &PowerLawData) -> Vec<Value> {
    (0..d.force_n.len())
        .map(|i| {
            json!({"ap_mm": d.ap_mm[i], "fz_mm": d.fz_mm[i], "n_rpm": d.n_rpm[i], "force_n": d.force_n[i],
                   "predicted_n": fit.predict(d.ap_mm[i], d.fz_mm[i], d.n_rpm[i]), "residual_n": fit.residuals_n[i]})
        })
        .collect()
}

/// The law, its estimates with their intervals and (with x_ap fixed at 1) the Kienzle parameters, as
/// printed lines; and the Kienzle JSON.
pub fn power_summary(fit: &PowerLawFit, rows: usize) -> (String, Option<Value>) {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "F = {:.4}·ap^{:.4}·fz^{:.4}·n^{:.4}  ({} rows, {} dof, residual RMS {:.3} N)",
        fit.k.value, fit.x_ap.value, fit.y_fz.value, fit.z_n.value, rows, fit.dof, fit.rms_n
    );
    for (name, e) in [
        ("K", fit.k),
        ("x_ap", fit.x_ap),
        ("y_fz", fit.y_fz),
        ("z_n", fit.z_n),
    ] {
        let _ = match (e.fixed, e.ci95) {
            (true, _) => writeln!(s, "  {name} = {} (fixed)", e.value),
            (false, Some([lo, hi])) => {
                writeln!(s, "  {name} = {:.4}, 95 % CI [{lo:.4}, {hi:.4}]", e.value)
            }
            (false, None) => writeln!(
                s,
                "  {name} = {:.4} (no interval: no residual degrees of freedom)",
                e.value
            ),
        };
    }
    let kienzle = (fit.x_ap.fixed && fit.x_ap.value == 1.0).then(|| {
        let mc = 1.0 - fit.y_fz.value;
        let _ = writeln!(
            s,
            "  Kienzle: kc1.1 = {:.1} N/mm², mc = 1 − y = {mc:.4}",
            fit.k.value
        );
        json!({"kc11_n_mm2": fit.k.value, "mc": mc,
               "mc_ci95": fit.y_fz.ci95.map(|[lo, hi]| [1.0 - hi, 1.0 - lo]),
               "kc11_ci95": fit.k.ci95})
    });
    (s, kienzle)
}

/// The law applied to a second file's columns: the validation JSON (residual RMS, largest relative error,
/// rows) and the printed line.
pub fn power_validation(fit: &PowerLawFit, v: &PowerColumns, label: &str) -> (Value, String) {
    let vd = &v.data;
    let pred: Vec<f64> = (0..vd.force_n.len())
        .map(|i| fit.predict(vd.ap_mm[i], vd.fz_mm[i], vd.n_rpm[i]))
        .collect();
    let res: Vec<f64> = vd.force_n.iter().zip(&pred).map(|(a, b)| a - b).collect();
    let rms = axcomp_numeric::stats::rms(&res);
    let max_rel = res
        .iter()
        .zip(&vd.force_n)
        .map(|(r, f)| (r / f).abs())
        .fold(0.0, f64::max);
    let line = format!(
        "validation on {label}: residual RMS {rms:.3} N, largest relative error {:.1} %",
        100.0 * max_rel
    );
    let j = json!({"data": label, "rms_n": rms, "max_rel_error": max_rel, "notes": v.notes,
        "rows": (0..vd.force_n.len()).map(|i| json!({"ap_mm": vd.ap_mm[i], "fz_mm": vd.fz_mm[i], "n_rpm": vd.n_rpm[i],
            "force_n": vd.force_n[i], "predicted_n": pred[i], "residual_n": res[i]})).collect::<Vec<_>>()});
    (j, line)
}

/// The six milling coefficients in print and table order: name, value, unit.
fn milling_coefficients(k: &MillingCoefficients) -> [(&'static str, Coef, &'static str); 6] {
    [
        ("Ktc", k.ktc_n_mm2, "N/mm²"),
        ("Krc", k.krc_n_mm2, "N/mm²"),
        ("Kac", k.kac_n_mm2, "N/mm²"),
        ("Kte", k.kte_n_mm, "N/mm"),
        ("Kre", k.kre_n_mm, "N/mm"),
        ("Kae", k.kae_n_mm, "N/mm"),
    ]
}

/// The mean forces per feed and the coefficients with their 95 % half-widths, as printed lines.
pub fn milling_summary(tests: &[MeanForces], k: &MillingCoefficients, axes: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "mean forces over whole revolutions (reference axes {axes}):"
    );
    for t in tests {
        let _ = writeln!(
            s,
            "  fz {:.4} mm: Fx {:8.2} N, Fy {:8.2} N, Fz {:8.2} N ({} revolutions)",
            t.fz_mm, t.fx_n, t.fy_n, t.fz_n, t.revolutions
        );
    }
    for (n, c, u) in milling_coefficients(k) {
        let _ = writeln!(
            s,
            "  {n} = {:10.2} ± {} {u}",
            c.value,
            c.ci95_half.map_or("–".into(), |h| format!("{h:.2}"))
        );
    }
    s
}

/// `mean_forces.svg` and `report.md` of the milling coefficients.
pub fn milling_report(
    tests: &[MeanForces],
    k: &MillingCoefficients,
    n_rpm: f64,
    flutes: f64,
    ap: f64,
    axes: &str,
) -> Vec<(&'static str, Vec<u8>)> {
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
    let mut md =
        String::from("# Milling force coefficients (slotting, Altintas average-force method)\n\n");
    let _ = writeln!(
        md,
        "n = {n_rpm} rpm, {flutes} flutes, ap = {ap} mm, axes {axes}.\n"
    );
    let rows: Vec<Vec<String>> = milling_coefficients(k)
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
    vec![
        ("mean_forces.svg", f.to_svg().into_bytes()),
        ("report.md", md.into_bytes()),
    ]
}
