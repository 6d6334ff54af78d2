//! `axcomp fit probe`: touch-probe calibration on a reference sphere (contract: "Touch probe: calibration and
//! correction"; method: `axcomp_probe`, seed 003).
//!
//! Glossary:
//! - **uncorrected** (the "before" of `diameter_error_um`): contact points with the nominal stylus ball
//!   radius (`--stylus-diameter-mm`), or, without it, with one calibrated effective radius (the plain method).
//! - **after**: contact points with the chosen model (effective radius by direction and speed).
//! - **evaluation rows**: the held-out rows (`--holdout`, sphere of `--holdout-diameter-mm`, default the
//!   reference sphere's) when given, else the calibration rows (inliers).
//! - **group** (`--group COL,..`): one pose of a five-axis calibration. The probe is calibrated on the first
//!   group's rows (file order: the reference pose); every group's sphere centre is then fitted with that
//!   calibration (radius fixed). **Commanded tool point** of a group: the columns `cmd_x_mm, cmd_y_mm,
//!   cmd_z_mm` (constant within the group; needed by `--centres-out` only): the position the linear axes were commanded to so that, by the
//!   nominal kinematics, the tool point (stylus-tip centre) sits at the sphere's nominal centre. The R-test
//!   row's `dx_um, dy_um, dz_um` = fitted centre − commanded tool point.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, bail};
use axcomp_data::{Dataset, HoldoutSpec};
use axcomp_plot::{Figure, markdown_table};
use axcomp_probe::{
    Calibration, CalibrationOptions, CalibrationResult, DirSpeed, ModelChoice, SharedCentreError,
    Sphere, Touch, calibrate, fit_center, measured_diameter_mm, shared_centre_error,
};
use serde_json::json;

use crate::cli::DataArgs;
use crate::commands::common::load_dataset;
use crate::commands::predict::read_touches;
use crate::output::OutputSet;

const LONG_HELP: &str = "\
Touch CSV: x_mm, y_mm, z_mm (latched stylus-tip centre), approach_x/y/z (unit vector of the probing move, toward the surface), optional feed_mm_min, artefact, run.

How it works: algebraic sphere fit, then Levenberg–Marquardt geometric fits (centre + effective radius with the sphere's diameter fixed; a free-radius fit too). The effective radius r_eff(n, v) = stylus radius − pretravel is modelled by the surface normal's azimuth and elevation and the probing speed: `constant` (one radius), `bilinear` (the seed's azimuth × elevation grid at the calibration directions + one speed slope; the reference method) and `harmonic` (azimuthal harmonics 2..K × even polynomials in sin(elevation) + speed terms). The default (auto) takes the lowest cross-validated radial RMS (folds by direction: every 5th distinct direction held out). First-order direction terms are not modelled: on one sphere they cannot be told from its centre. Outliers (false triggers, bounce) are flagged at 6 robust σ (MAD) of the radial residual, excluded from the fit and listed in the JSON. Repeatability 2σ is pooled over repeated touches (same direction and speed).

Correction (axcomp predict --model CAL): contact = latched + r_eff(n, v)·approach.

Five-axis poses (--group COL,.. --centres-out F.csv, the probe route of `fit rtest`): the touch CSV also needs cmd_x_mm, cmd_y_mm, cmd_z_mm, the position the linear axes were commanded to at that pose (constant within a group: the tool point at the sphere's nominal centre by the nominal kinematics); the R-test row's x_mm, y_mm, z_mm are that commanded position and dx_um, dy_um, dz_um the fitted centre minus it. The probe is calibrated on the first group (pose); every group's centre is fitted with that calibration (outlier flags iterated about the centre of the kept touches). The R-test rows carry the group columns, `path` and `setup` when the touches have them (constant per group), dx_um, dy_um, dz_um, then the calibration's error every centre shares: zero1_dx_um, zero1_dy_um, zero1_dz_um, zero2_… (the coefficients' covariance from the calibration fit propagated through each centre fit; each triplet one independent standard-uncertainty component, µm; JSON shared_zero), which `fit rtest` propagates into the location errors' standard uncertainties.

diameter_error_um is judged on the held-out rows (--holdout, an artefact of --holdout-diameter-mm); without --holdout it is computed on the calibration rows, where the model fixes the diameter (after ≈ 0 by construction): use a held-out artefact to judge.

Example (twin data):
  axcomp fit probe --data touches.csv --sphere-diameter-mm 25 --holdout artefact=sphere2
    --holdout-diameter-mm 19.05 --stylus-diameter-mm 3 --out cal.json --json fit.json --report rep";

#[derive(Debug, clap::Args)]
#[command(after_long_help = LONG_HELP)]
pub struct Args {
    #[command(flatten)]
    pub data: DataArgs,
    /// Diameter of the reference sphere (its calibration certificate), mm.
    #[arg(long, value_name = "D")]
    pub sphere_diameter_mm: f64,
    /// Rows held out from the calibration and used only to judge: COL=V1,V2 | COL>=X | COL<X.
    #[arg(long, value_name = "SPEC")]
    pub holdout: Option<String>,
    /// Diameter of the held-out artefact (a sphere), mm (default: the reference sphere's).
    #[arg(long, value_name = "D")]
    pub holdout_diameter_mm: Option<f64>,
    /// Nominal stylus ball diameter, mm: the uncorrected method ("before") uses its radius.
    #[arg(long, value_name = "D")]
    pub stylus_diameter_mm: Option<f64>,
    /// Model of the effective radius: auto (lowest CV), constant, bilinear, harmonic.
    #[arg(long, default_value = "auto", value_name = "MODEL")]
    pub pretravel_model: String,
    /// Outlier threshold in robust standard deviations of the radial residual.
    #[arg(long, default_value_t = DEFAULT_OUTLIER_MAD, value_name = "K")]
    pub outlier_mad: f64,
    /// Columns naming a pose (e.g. a_deg,c_deg): fit one sphere centre per group. Each group's commanded tool
    /// point is read from the columns cmd_x_mm, cmd_y_mm, cmd_z_mm (constant within the group; needed by
    /// --centres-out, optional otherwise).
    #[arg(long, value_delimiter = ',', value_name = "COL,..")]
    pub group: Vec<String>,
    /// With --group: write one R-test row per group (x_mm,y_mm,z_mm,<group cols>[,path,setup],dx_um,
    /// dy_um,dz_um, then zero1_dx_um,…: the calibration's error every centre shares, for `fit rtest`).
    #[arg(long, value_name = "F.csv")]
    pub centres_out: Option<PathBuf>,
    /// Write the calibration (input of `axcomp predict --model`).
    #[arg(long, value_name = "CAL.json")]
    pub out: Option<PathBuf>,
    /// Machine-readable result.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write report.md and SVG plots into DIR.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Refuse the data (exit 2) when a plausibility check warns (units, magnitudes).
    #[arg(long)]
    pub strict: bool,
}

/// Plausibility of touches (see `axcomp_data::sanity`): positions beyond 10 m or of mixed magnitudes
/// (µm taken for mm).
fn touch_warnings(ds: &Dataset, touches: &[Touch]) -> Vec<axcomp_data::sanity::DataWarning> {
    use axcomp_data::sanity;
    let mut w = Vec::new();
    for (k, c) in ["x_mm", "y_mm", "z_mm"].into_iter().enumerate() {
        let v: Vec<f64> = touches.iter().map(|t| t.position_mm[k]).collect();
        w.extend(sanity::unit_mix(ds, c, &v, None));
        w.extend(sanity::implausible_magnitude(
            ds,
            c,
            &v,
            1.0e4,
            "touch positions beyond 10 m are not plausible in mm: µm?",
        ));
    }
    w
}

/// Evaluation rows, the artefact's diameter, which rows (`holdout` / `calibration`), flagged held-out rows.
type Evaluation = (Vec<Touch>, f64, &'static str, Vec<serde_json::Value>);

fn sphere_json(s: &Sphere) -> serde_json::Value {
    json!({ "center_mm": s.center_mm, "radius_mm": s.radius_mm, "rms_um": s.rms_um })
}

/// Diameter error (µm) of a free sphere through the contacts under `r_of`, or None when it cannot be fitted.
fn diameter_error_um(touches: &[Touch], d_mm: f64, r_of: &dyn Fn(&Touch) -> f64) -> Option<f64> {
    measured_diameter_mm(touches, r_of)
        .ok()
        .map(|s| (2.0 * s.radius_mm - d_mm) * 1000.0)
}

/// Radial residuals (µm) of contacts about a sphere of known radius whose centre is fitted.
fn radial_about_fitted_centre(
    cal: &Calibration,
    touches: &[Touch],
    radius_mm: f64,
) -> anyhow::Result<(Sphere, Vec<f64>)> {
    let s = fit_center(cal, touches, radius_mm)?;
    let res = radial_residuals_um(cal, touches, &s, radius_mm);
    Ok((s, res))
}

/// Radial residuals (µm) of contacts about the centre of `s` for a sphere of radius `radius_mm`.
fn radial_residuals_um(
    cal: &Calibration,
    touches: &[Touch],
    s: &Sphere,
    radius_mm: f64,
) -> Vec<f64> {
    touches
        .iter()
        .map(|t| {
            let c = cal.contact_mm(t);
            let d = ((c[0] - s.center_mm[0]).powi(2)
                + (c[1] - s.center_mm[1]).powi(2)
                + (c[2] - s.center_mm[2]).powi(2))
            .sqrt();
            (d - radius_mm) * 1000.0
        })
        .collect()
}

/// Default of `--outlier-mad`: a gross outlier lies more than this many robust σ from the median.
pub(crate) const DEFAULT_OUTLIER_MAD: f64 = 6.0;

/// Outlier flags of one sphere's touches, iterated: the centre is refitted on the touches kept and every
/// touch's residual recomputed about it until the flags no longer change (at most 10 rounds). One pass about
/// a centre fitted with the glitches in it misses the smaller glitches: a 400 µm false trigger moves that
/// centre by µm, the residuals take a once-per-revolution pattern, the robust σ grows, and a 60 µm glitch
/// stays in (seen on the probe route's twin, seed 116: one pose's centre 6 µm RMS off, EC0Y 4.8 std away).
fn iterated_flags(
    cal: &Calibration,
    touches: &[Touch],
    radius_mm: f64,
    k: f64,
) -> anyhow::Result<Vec<bool>> {
    let (_, r) = radial_about_fitted_centre(cal, touches, radius_mm)?;
    let mut flags = axcomp_probe::flag_outliers(&r, k);
    for _ in 0..10 {
        let kept: Vec<Touch> = (0..touches.len())
            .filter(|&i| !flags[i])
            .map(|i| touches[i])
            .collect();
        if kept.len() < 4 {
            break;
        }
        let s = fit_center(cal, &kept, radius_mm)?;
        let r = radial_residuals_um(cal, touches, &s, radius_mm);
        let next = axcomp_probe::flag_outliers(&r, k);
        if next == flags {
            break;
        }
        flags = next;
    }
    Ok(flags)
}

use axcomp_numeric::stats::rms;

/// A calibration with one fixed effective radius (the uncorrected method with a nominal ball).
fn nominal(cal: &Calibration, radius_mm: f64) -> Calibration {
    Calibration {
        structure: axcomp_probe::Structure::Constant,
        coef_mm: vec![radius_mm],
        stylus_radius_mm: radius_mm,
        ..cal.clone()
    }
}

fn group_keys(ds: &Dataset, cols: &[String]) -> anyhow::Result<Vec<String>> {
    let texts: Vec<Vec<&str>> = cols
        .iter()
        .map(|c| ds.text(c).map_err(anyhow::Error::from))
        .collect::<anyhow::Result<_>>()?;
    Ok((0..ds.n_rows())
        .map(|i| {
            texts
                .iter()
                .map(|t| t[i].trim())
                .collect::<Vec<_>>()
                .join("\u{1f}")
        })
        .collect())
}

fn shared_zero_json(z: &SharedCentreError) -> serde_json::Value {
    json!({
        "columns": (1..=z.components()).map(|k| format!("zero{k}_dx_um, zero{k}_dy_um, zero{k}_dz_um")).collect::<Vec<_>>(),
        "std_um": z.std_um,
        "captured_share": z.captured_share,
        "definition": "error every pose's fitted centre shares through the one probe calibration (its coefficients' covariance from the calibration fit, propagated through each pose's centre fit); each column triplet is one independent standard-uncertainty component (µm); `fit rtest` propagates it",
    })
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // ---- options first ----
    let model: ModelChoice = args.pretravel_model.parse()?;
    if !(args.sphere_diameter_mm > 0.0 && args.sphere_diameter_mm.is_finite()) {
        bail!(
            "--sphere-diameter-mm {}: must be > 0",
            args.sphere_diameter_mm
        );
    }
    if let Some(d) = args.holdout_diameter_mm {
        if !(d > 0.0 && d.is_finite()) {
            bail!("--holdout-diameter-mm {d}: must be > 0");
        }
        if args.holdout.is_none() {
            bail!("--holdout-diameter-mm needs --holdout");
        }
    }
    if let Some(d) = args.stylus_diameter_mm {
        if !(d > 0.0 && d.is_finite()) {
            bail!("--stylus-diameter-mm {d}: must be > 0");
        }
    }
    if args.outlier_mad.is_nan() || args.outlier_mad <= 0.0 {
        bail!("--outlier-mad {}: must be > 0", args.outlier_mad);
    }
    if args.centres_out.is_some() && args.group.is_empty() {
        bail!("--centres-out needs --group COL,..");
    }
    let holdout = args
        .holdout
        .as_deref()
        .map(HoldoutSpec::parse)
        .transpose()?;
    // Every output is planned and checked before the fit; written together at the end.
    let mut outputs = OutputSet::new();
    outputs.input(&args.data.data);
    if let Some(dir) = &args.report {
        outputs.folder(dir, "--report");
        for name in [
            "residual_map.svg",
            "residual_map_plain.svg",
            "pretravel_speed.svg",
            "diameter_error.svg",
            "report.md",
        ] {
            outputs.planned_in(dir, name);
        }
    }
    for p in [&args.centres_out, &args.out, &args.json]
        .into_iter()
        .flatten()
    {
        outputs.planned(p);
    }
    outputs.check()?;

    // ---- data ----
    let ds = load_dataset(&args.data)?;
    let (touches, labels) = read_touches(&ds)?;
    axcomp_probe::validate_touches(&touches, &labels)?;
    let warnings = touch_warnings(&ds, &touches);
    crate::commands::common::report_warnings(&warnings, args.strict)?;
    let held: Vec<bool> = match &holdout {
        Some(h) => h.mask(&ds)?,
        None => vec![false; ds.n_rows()],
    };
    let groups = if args.group.is_empty() {
        None
    } else {
        Some(group_keys(&ds, &args.group)?)
    };
    // Calibration rows: not held out (and, with --group, the first group's).
    let first_group = groups
        .as_ref()
        .and_then(|g| (0..g.len()).find(|&i| !held[i]).map(|i| g[i].clone()));
    let train: Vec<usize> = (0..ds.n_rows())
        .filter(|&i| !held[i])
        .filter(|&i| match (&groups, &first_group) {
            (Some(g), Some(f)) => &g[i] == f,
            _ => true,
        })
        .collect();
    let test: Vec<usize> = (0..ds.n_rows()).filter(|&i| held[i]).collect();
    if holdout.is_some() && test.is_empty() {
        bail!(
            "{}: --holdout {} selects no rows",
            ds.source(),
            args.holdout.as_deref().unwrap_or("")
        );
    }
    // One sphere is fitted to the calibration rows and one to the held-out rows: each must be one artefact.
    if ds.has("artefact") {
        let names = ds.text("artefact")?;
        for (rows, what, fix) in [
            (
                &train,
                "calibration",
                "choose the reference sphere with --where artefact=NAME",
            ),
            (&test, "held-out", "hold out one artefact at a time"),
        ] {
            let mut seen: Vec<&str> = Vec::new();
            for &i in rows {
                let a = names[i].trim();
                if !seen.contains(&a) {
                    seen.push(a);
                }
            }
            if seen.len() > 1 {
                bail!(
                    "{}: the {what} touches belong to {} artefacts ({}), but one sphere is fitted to them: {fix}",
                    ds.source(),
                    seen.len(),
                    seen.join(", ")
                );
            }
        }
    }
    let tr_touches: Vec<Touch> = train.iter().map(|&i| touches[i]).collect();
    let tr_labels: Vec<String> = train.iter().map(|&i| labels[i].clone()).collect();
    let opts = CalibrationOptions {
        model,
        outlier_mad: args.outlier_mad,
        ..CalibrationOptions::new(args.sphere_diameter_mm)
    };
    let res = calibrate(&tr_touches, &tr_labels, &opts)?;
    let cal = &res.calibration;
    // The latched tip centres lie |p − C| = R + r_eff from the centre: r_eff ≤ 0 means they lie on or
    // inside the sphere as given, which no stylus does (the diameter is wrong, or the artefact is not a
    // sphere touched from outside).
    if cal.stylus_radius_mm.is_nan() || cal.stylus_radius_mm <= 0.0 {
        bail!(
            "{}: the latched stylus-tip centres lie {:.4} mm from the fitted centre, not more than the sphere's \
             radius {:.4} mm (--sphere-diameter-mm {}): the effective stylus radius would be {:.4} mm ≤ 0. \
             Is the sphere diameter right (the touches fit a sphere of {:.4} mm with a zero-radius stylus)?",
            ds.source(),
            args.sphere_diameter_mm / 2.0 + cal.stylus_radius_mm,
            args.sphere_diameter_mm / 2.0,
            args.sphere_diameter_mm,
            cal.stylus_radius_mm,
            args.sphere_diameter_mm + 2.0 * cal.stylus_radius_mm
        );
    }
    if let Some(d) = args.stylus_diameter_mm {
        if (cal.stylus_radius_mm - d / 2.0).abs() > 0.1 * d / 2.0 {
            eprintln!(
                "axcomp: warning: effective stylus radius {:.4} mm vs the nominal ball's {:.4} mm \
                 (--stylus-diameter-mm {d}): more than 10 % apart, far beyond a pretravel; is \
                 --sphere-diameter-mm {} right?",
                cal.stylus_radius_mm,
                d / 2.0,
                args.sphere_diameter_mm
            );
        }
    }

    // ---- evaluation: held-out rows, else the calibration inliers ----
    let outlier_idx: Vec<usize> = res.outliers.iter().map(|o| o.index).collect();
    let (eval_touches, eval_d, on, eval_outliers): Evaluation = if test.is_empty() {
        let t: Vec<Touch> = (0..tr_touches.len())
            .filter(|i| !outlier_idx.contains(i))
            .map(|i| tr_touches[i])
            .collect();
        (t, args.sphere_diameter_mm, "calibration", Vec::new())
    } else {
        let d = args.holdout_diameter_mm.unwrap_or(args.sphere_diameter_mm);
        let t: Vec<Touch> = test.iter().map(|&i| touches[i]).collect();
        for (k, tt) in t.iter().enumerate() {
            cal.check_touch(tt)
                .map_err(|why| anyhow::anyhow!("{}: {why}", labels[test[k]]))?;
        }
        // Flag glitches of the held-out touches the same way (robust, reported, not used).
        let (_, r) = radial_about_fitted_centre(cal, &t, d / 2.0)?;
        let flags = axcomp_probe::flag_outliers(&r, args.outlier_mad);
        let mut keep = Vec::new();
        let mut flagged = Vec::new();
        for (k, e) in r.iter().enumerate() {
            if flags[k] {
                flagged.push(json!({ "row": labels[test[k]], "residual_um": e }));
            } else {
                keep.push(t[k]);
            }
        }
        (keep, d, "holdout", flagged)
    };
    if eval_touches.len() < 4 {
        bail!(
            "{} evaluation touches: a diameter needs at least 4",
            eval_touches.len()
        );
    }
    let r_eval = eval_d / 2.0;
    let before_cal = match args.stylus_diameter_mm {
        Some(d) => nominal(cal, d / 2.0),
        None => res.plain.clone(),
    };
    let before_method = match args.stylus_diameter_mm {
        Some(d) => format!("nominal stylus ball Ø{d} mm (no pretravel correction)"),
        None => "one calibrated effective radius (plain method)".to_string(),
    };
    let de =
        |c: &Calibration| diameter_error_um(&eval_touches, eval_d, &|t| c.effective_radius_mm(t));
    let (_, after_res) = radial_about_fitted_centre(cal, &eval_touches, r_eval)?;
    let (_, before_res) = radial_about_fitted_centre(&before_cal, &eval_touches, r_eval)?;
    let (_, ref_res) = radial_about_fitted_centre(&res.reference, &eval_touches, r_eval)?;
    let holdout_rms = (!test.is_empty()).then(|| rms(&after_res));

    // ---- groups ----
    let mut group_rows = Vec::new();
    if let Some(g) = &groups {
        let mut order: Vec<String> = Vec::new();
        for k in g {
            if !order.contains(k) {
                order.push(k.clone());
            }
        }
        // The commanded tool point: needed for the R-test rows of --centres-out; without it (and without
        // --centres-out) each group's centre is still fitted and reported.
        let cmd = if args.centres_out.is_some() || ds.has("cmd_x_mm") {
            Some(
                ["cmd_x_mm", "cmd_y_mm", "cmd_z_mm"]
                    .iter()
                    .map(|c| {
                        ds.numeric(c).map(<[f64]>::to_vec).with_context(|| {
                            format!(
                                "--group: each group's commanded tool point comes from `{c}` (see `axcomp fit \
                                 probe --help`)"
                            )
                        })
                    })
                    .collect::<anyhow::Result<Vec<_>>>()?,
            )
        } else {
            None
        };
        // Columns an R-test row carries (path, setup), when the touches have them: constant per group (the
        // touch CSV's `run` is a repeat id of touches; an R-test run goes into --group).
        let carried: Vec<&str> = ["path", "setup"]
            .into_iter()
            .filter(|c| ds.has(c) && !args.group.iter().any(|g| g == c))
            .collect();
        for key in &order {
            let rows: Vec<usize> = (0..ds.n_rows())
                .filter(|&i| &g[i] == key && !held[i])
                .collect();
            if rows.is_empty() {
                continue;
            }
            let mut point = cmd.as_ref().map(|_| [0.0; 3]);
            if let (Some(cmd), Some(point)) = (&cmd, &mut point) {
                for k in 0..3 {
                    point[k] = cmd[k][rows[0]];
                    if let Some(&bad) = rows.iter().find(|&&i| cmd[k][i] != point[k]) {
                        bail!(
                            "{}: the commanded tool point differs within group `{}` (first row {})",
                            ds.locate(["cmd_x_mm", "cmd_y_mm", "cmd_z_mm"][k], bad),
                            key.replace('\u{1f}', ","),
                            labels[rows[0]]
                        );
                    }
                }
            }
            let gt: Vec<Touch> = rows.iter().map(|&i| touches[i]).collect();
            for (k, t) in gt.iter().enumerate() {
                cal.check_touch(t)
                    .map_err(|why| anyhow::anyhow!("{}: {why}", labels[rows[k]]))?;
            }
            let gname = key.replace('\u{1f}', ",");
            let radius = args.sphere_diameter_mm / 2.0;
            // Glitches of this pose's touches: flagged like the calibration's, listed, not used.
            let flags = iterated_flags(cal, &gt, radius, args.outlier_mad)
                .with_context(|| format!("group `{gname}`"))?;
            let kept: Vec<Touch> = (0..gt.len())
                .filter(|&k| !flags[k])
                .map(|k| gt[k])
                .collect();
            let flagged: Vec<String> = (0..gt.len())
                .filter(|&k| flags[k])
                .map(|k| labels[rows[k]].clone())
                .collect();
            let s = fit_center(cal, &kept, radius).with_context(|| format!("group `{gname}`"))?;
            let mut values: Vec<String> = key.split('\u{1f}').map(str::to_string).collect();
            for c in &carried {
                let t = ds.text(c)?;
                let v = t[rows[0]].trim();
                if let Some(&bad) = rows.iter().find(|&&i| t[i].trim() != v) {
                    bail!(
                        "{}: `{c}` differs within group `{}` (`{v}` at {}): each pose's touches carry one {c} into its R-test row",
                        ds.locate(c, bad),
                        key.replace('\u{1f}', ","),
                        labels[rows[0]]
                    );
                }
                values.push(v.to_string());
            }
            group_rows.push((point, values, s, kept.len(), flagged, kept));
        }
    }

    // ---- the error every group's centre shares through the calibration ----
    // The centres are fitted with one calibration: its coefficients' error δβ (covariance C from the
    // calibration fit) moves group g's centre by A_g·δβ (A_g: the centre fit's sensitivity), the same error
    // for every pose. With C = V·Λ·Vᵀ, the stacked loadings B = [A_g·V·Λ^½] (µm) are written as the columns
    // zero1_dx_um … (the left singular vectors of B times its singular values, down to 1e-2 of the largest):
    // `fit rtest` propagates them into the location errors' standard uncertainties.
    let shared_zero = if group_rows.is_empty() {
        None
    } else {
        let inliers: Vec<Touch> = (0..tr_touches.len())
            .filter(|i| !outlier_idx.contains(i))
            .map(|i| tr_touches[i])
            .collect();
        let groups: Vec<(&[Touch], [f64; 3])> = group_rows
            .iter()
            .map(|(_, _, s, _, _, kept)| (kept.as_slice(), s.center_mm))
            .collect();
        Some(
            shared_centre_error(cal, &inliers, &groups)
                .context("the calibration's error shared by the groups' centres")?,
        )
    };

    // ---- outputs: everything computed; now write ----
    let pretravel_table: Vec<serde_json::Value> = {
        let mut v = Vec::new();
        let els: Vec<f64> = match &cal.structure {
            axcomp_probe::Structure::Bilinear {
                elevation_nodes_deg,
                ..
            } => elevation_nodes_deg.clone(),
            _ => vec![0.0, 30.0, 60.0, 90.0],
        };
        let feeds = if cal.feed_range_mm_min[1] > cal.feed_range_mm_min[0] {
            vec![0.0, cal.feed_range_mm_min[0], cal.feed_range_mm_min[1]]
        } else {
            vec![cal.feed_range_mm_min[0]]
        };
        for &el in &els {
            for k in 0..12 {
                let az = 30.0 * k as f64;
                if el >= 89.9 && k > 0 {
                    break;
                }
                for &f in &feeds {
                    let d = DirSpeed {
                        t: el.to_radians().sin(),
                        theta: az.to_radians(),
                        v: f / 60.0,
                    };
                    v.push(
                        json!({ "azimuth_deg": az, "elevation_deg": el, "feed_mm_min": f,
                                   "pretravel_um": cal.pretravel_um(d) }),
                    );
                }
            }
        }
        v
    };
    let speed_slope = |c: &Calibration| -> f64 {
        // Mean over the calibration directions of d(pretravel)/dv, µm per mm/s.
        let d = DirSpeed {
            t: 0.5f64.sqrt(),
            theta: 0.0,
            v: 1.0,
        };
        -c.structure.speed_part(&c.coef_mm, d) * 1000.0
    };
    let report = json!({
        "sphere_center_mm": cal.sphere_center_mm,
        "sphere_diameter_mm": args.sphere_diameter_mm,
        "stylus_radius_mm": cal.stylus_radius_mm,
        "pretravel": {
            "model": cal.structure.name(),
            "structure": cal.structure,
            "coefficients_mm": cal.coef_mm,
            "speed_um_per_mm_s": speed_slope(cal),
            "definition": "pretravel_um = (stylus_radius_mm − r_eff(n, v))·1000; direction = surface normal n = −approach (azimuth, elevation); v = feed_mm_min/60",
            "table": pretravel_table,
            "cv": res.candidates,
            "chosen_why": res.why,
        },
        "repeatability_2sigma_um": res.repeatability_2sigma_um,
        "repeatability_note": if res.repeatability_2sigma_um.is_some() {
            "pooled standard deviation of the radial distance over repeated touches (same direction and speed) \
             of the calibration rows, times 2"
        } else {
            "null: no repeated touches (same direction and speed) among the calibration rows; the data cannot \
             determine the repeatability (held-out rows are not used for it)"
        },
        "repeat_groups": res.repeat_groups,
        "fit_rms_um": cal.fit_rms_um,
        "holdout_rms_um": holdout_rms,
        "holdout_rms_before_um": (!test.is_empty()).then(|| rms(&before_res)),
        "holdout_rms_reference_um": (!test.is_empty()).then(|| rms(&ref_res)),
        "diameter_error_um": {
            "before": de(&before_cal),
            "after": de(cal),
            "reference_bilinear": de(&res.reference),
            "plain_one_radius": de(&res.plain),
            "on": on,
            "artefact_diameter_mm": eval_d,
            "before_method": before_method,
        },
        "outliers": res.outliers,
        "holdout_outliers": eval_outliers,
        "fit": {
            "algebraic": sphere_json(&res.algebraic),
            "geometric_free_radius": sphere_json(&res.geometric_free),
            "reference_bilinear_fit_rms_um": res.reference.fit_rms_um,
            "plain_fit_rms_um": res.plain.fit_rms_um,
        },
        "touches": ds.n_rows(),
        "calibration_touches": train.len(),
        "holdout_touches": test.len(),
        "shared_zero": shared_zero.as_ref().map(shared_zero_json),
        "groups": group_rows.iter().map(|(p, v, s, n, flagged, _)| json!({
            "group": &v[..args.group.len()], "touches": n, "outliers": flagged, "commanded_mm": p, "center_mm": s.center_mm, "rms_um": s.rms_um,
            "dx_um": p.map(|p| (s.center_mm[0] - p[0]) * 1000.0), "dy_um": p.map(|p| (s.center_mm[1] - p[1]) * 1000.0),
            "dz_um": p.map(|p| (s.center_mm[2] - p[2]) * 1000.0) })).collect::<Vec<_>>(),
    });

    let centres_csv = args.centres_out.as_ref().map(|_| {
        let mut s = String::from("x_mm,y_mm,z_mm");
        for c in args.group.iter().map(String::as_str).chain(
            ["path", "setup"]
                .into_iter()
                .filter(|c| ds.has(c) && !args.group.iter().any(|g| g == c)),
        ) {
            s.push(',');
            s.push_str(c);
        }
        s.push_str(",dx_um,dy_um,dz_um");
        let nz = shared_zero.as_ref().map_or(0, |z| z.components());
        for k in 1..=nz {
            let _ = write!(s, ",zero{k}_dx_um,zero{k}_dy_um,zero{k}_dz_um");
        }
        s.push('\n');
        for (g, (p, v, c, _, _, _)) in group_rows.iter().enumerate() {
            let p = p.expect("the commanded point is read whenever --centres-out is given");
            let _ = write!(s, "{},{},{}", p[0], p[1], p[2]);
            for x in v {
                let _ = write!(s, ",{x}");
            }
            let _ = write!(
                s,
                ",{},{},{}",
                (c.center_mm[0] - p[0]) * 1000.0,
                (c.center_mm[1] - p[1]) * 1000.0,
                (c.center_mm[2] - p[2]) * 1000.0
            );
            if let Some(z) = &shared_zero {
                for l in &z.loadings_um[g] {
                    let _ = write!(s, ",{},{},{}", l[0], l[1], l[2]);
                }
            }
            s.push('\n');
        }
        s
    });

    if let Some(dir) = &args.report {
        write_report(
            &mut outputs,
            dir,
            &res,
            &tr_touches,
            &eval_touches,
            eval_d,
            &before_cal,
            &report,
        )?;
    }
    if let (Some(p), Some(text)) = (&args.centres_out, &centres_csv) {
        outputs.file(p, text.as_bytes());
    }
    if let Some(p) = &args.out {
        let provenance =
            crate::provenance::of_data(&args.data, args.holdout.as_deref(), None, "", "fit probe")?;
        outputs.file(
            p,
            crate::provenance::stamp_text(&cal.to_json(), &provenance)?,
        );
    }
    if let Some(p) = &args.json {
        outputs.json(
            p,
            &crate::commands::common::with_warnings(serde_json::to_value(&report)?, &warnings)?,
        )?;
    }
    // Everything together or nothing (the report folder included).
    outputs.commit()?;
    let f = |v: Option<f64>| v.map_or("–".to_string(), |x| format!("{x:+.3}"));
    println!(
        "fit probe: {} touches ({} outliers), model {}; centre [{:.4}, {:.4}, {:.4}] mm, stylus radius {:.4} mm",
        train.len(),
        res.outliers.len(),
        cal.structure.name(),
        cal.sphere_center_mm[0],
        cal.sphere_center_mm[1],
        cal.sphere_center_mm[2],
        cal.stylus_radius_mm
    );
    println!(
        "  fit RMS {:.3} µm; repeatability 2σ {}; diameter error on {on}: before {} µm, after {} µm{}",
        cal.fit_rms_um,
        res.repeatability_2sigma_um
            .map_or("–".into(), |r| format!("{r:.3} µm")),
        f(de(&before_cal)),
        f(de(cal)),
        holdout_rms.map_or(String::new(), |r| format!("; holdout RMS {r:.3} µm"))
    );
    Ok(())
}

#[allow(clippy::too_many_arguments)] // one call site; the report needs each of them
fn write_report(
    outputs: &mut OutputSet,
    dir: &std::path::Path,
    res: &CalibrationResult,
    touches: &[Touch],
    eval_touches: &[Touch],
    eval_d: f64,
    before_cal: &Calibration,
    report: &serde_json::Value,
) -> anyhow::Result<()> {
    let cal = &res.calibration;
    // Radial residual over the sphere: azimuth on x, one series per elevation ring.
    // Per elevation ring (0.1°): azimuths, residuals after, residuals with one radius.
    type Ring = (Vec<f64>, Vec<f64>, Vec<f64>);
    let mut rings: BTreeMap<i64, Ring> = BTreeMap::new();
    let out: Vec<usize> = res.outliers.iter().map(|o| o.index).collect();
    let radius = cal.sphere_diameter_mm / 2.0;
    let plain_c = res.plain.sphere_center_mm;
    for (i, t) in touches.iter().enumerate() {
        if out.contains(&i) {
            continue;
        }
        let d = t.dir_speed();
        let e = rings
            .entry((d.elevation_deg() * 10.0).round() as i64)
            .or_default();
        e.0.push(d.azimuth_deg());
        e.1.push(res.residual_um[i]);
        let dist = ((t.position_mm[0] - plain_c[0]).powi(2)
            + (t.position_mm[1] - plain_c[1]).powi(2)
            + (t.position_mm[2] - plain_c[2]).powi(2))
        .sqrt();
        e.2.push((dist - radius - res.plain.effective_radius_mm(t)) * 1000.0);
    }
    let mut after = Figure::new(
        &format!(
            "Radial residual of each touch over the sphere after correction (chosen model: {}), one series per elevation ring",
            cal.structure.name()
        ),
        &axcomp_plot::label("azimuth of the surface normal", "°"),
        &axcomp_plot::label("radial residual", "µm"),
    );
    let mut before = Figure::new(
        "Radial residual of each touch over the sphere with one effective radius (plain method), one series per elevation ring",
        &axcomp_plot::label("azimuth of the surface normal", "°"),
        &axcomp_plot::label("radial residual", "µm"),
    );
    for (el, (az, r_after, r_plain)) in &rings {
        let name = format!("elevation {:.1}°", *el as f64 / 10.0);
        after.points(&name, az, r_after);
        before.points(&name, az, r_plain);
    }
    after.hline(0.0, "");
    before.hline(0.0, "");
    outputs.folder_file(dir, "residual_map.svg", after.to_svg());
    outputs.folder_file(dir, "residual_map_plain.svg", before.to_svg());

    // Pretravel versus speed: measured (stylus radius − |p − C| + R) per touch, model at a few directions.
    // One colour per approach direction class (the elevation ring of the touch's surface normal): its
    // touches as markers, and the model's pretravel averaged over the same touches' directions as a line.
    let c = cal.sphere_center_mm;
    let mut classes: BTreeMap<i64, Vec<&Touch>> = BTreeMap::new();
    for (i, t) in touches.iter().enumerate() {
        if !out.contains(&i) {
            classes
                .entry((t.dir_speed().elevation_deg() * 10.0).round() as i64)
                .or_default()
                .push(t);
        }
    }
    let fmax = cal.feed_range_mm_min[1].max(1.0) * 1.5;
    let feeds: Vec<f64> = (0..=20).map(|k| fmax * k as f64 / 20.0).collect();
    let mut pv = Figure::new(
        &format!(
            "Pretravel of each touch vs probing speed, by approach elevation, and the calibrated model ({}), fit RMS {:.2} µm",
            cal.structure.name(),
            cal.fit_rms_um
        ),
        &axcomp_plot::label("feed", "mm/min"),
        &axcomp_plot::label("pretravel", "µm"),
    );
    for (el, ts) in &classes {
        let (fx, fy): (Vec<f64>, Vec<f64>) = ts
            .iter()
            .map(|t| {
                let dist = ((t.position_mm[0] - c[0]).powi(2)
                    + (t.position_mm[1] - c[1]).powi(2)
                    + (t.position_mm[2] - c[2]).powi(2))
                .sqrt();
                (
                    t.feed_mm_min,
                    (cal.stylus_radius_mm - (dist - radius)) * 1000.0,
                )
            })
            .unzip();
        let model: Vec<f64> = feeds
            .iter()
            .map(|f| {
                let sum: f64 = ts
                    .iter()
                    .map(|t| {
                        let mut d = t.dir_speed();
                        d.v = f / 60.0;
                        cal.pretravel_um(d)
                    })
                    .sum();
                sum / ts.len() as f64
            })
            .collect();
        let name = format!(
            "elevation {}°",
            axcomp_plot::style::fmt_fixed(*el as f64 / 10.0, 1)
        );
        pv.points(&format!("touches, {name}"), &fx, &fy);
        pv.dashed(&format!("model, {name}"), &feeds, &model)
            .like_previous();
    }
    outputs.folder_file(dir, "pretravel_speed.svg", pv.to_svg());

    // Diameter error by speed on the evaluation rows: before, reference, after.
    let mut speeds: Vec<f64> = eval_touches.iter().map(|t| t.feed_mm_min).collect();
    speeds.sort_by(f64::total_cmp);
    speeds.dedup();
    let mut dfig = Figure::new(
        "",
        &axcomp_plot::label("feed", "mm/min"),
        &axcomp_plot::label("diameter error", "µm"),
    );
    let mut rows_md = Vec::new();
    let mut series: [(String, Vec<f64>); 3] = [
        ("before".into(), Vec::new()),
        ("bilinear reference".into(), Vec::new()),
        ("after".into(), Vec::new()),
    ];
    let mut xs = Vec::new();
    for &f in &speeds {
        let ts: Vec<Touch> = eval_touches
            .iter()
            .copied()
            .filter(|t| t.feed_mm_min == f)
            .collect();
        let cals = [before_cal, &res.reference, cal];
        let vals: Vec<Option<f64>> = cals
            .iter()
            .map(|c| {
                measured_diameter_mm(&ts, |t| c.effective_radius_mm(t))
                    .ok()
                    .map(|s| (2.0 * s.radius_mm - eval_d) * 1000.0)
            })
            .collect();
        if vals.iter().all(Option::is_some) {
            xs.push(f);
            for (k, v) in vals.iter().enumerate() {
                series[k].1.push(v.unwrap());
            }
            rows_md.push(vec![
                format!("{f}"),
                format!("{}", ts.len()),
                format!("{:+.3}", vals[0].unwrap()),
                format!("{:+.3}", vals[1].unwrap()),
                format!("{:+.3}", vals[2].unwrap()),
            ]);
        }
    }
    for (name, ys) in &series {
        dfig.line(name, &xs, ys);
    }
    let worst = |k: usize| series[k].1.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    dfig.set_title(&format!(
        "Diameter error of the {} evaluation touches ({}) by probing speed: worst |error| {:.2} µm before, {:.2} µm after the chosen model ({})",
        eval_touches.len(),
        report["diameter_error_um"]["on"].as_str().unwrap_or("?"),
        worst(0),
        worst(2),
        cal.structure.name()
    ));
    dfig.hline(0.0, "");
    outputs.folder_file(dir, "diameter_error.svg", dfig.to_svg());

    let de = &report["diameter_error_um"];
    let num = |v: &serde_json::Value| v.as_f64().map_or("–".to_string(), |x| format!("{x:+.3}"));
    let mut md = String::new();
    let _ = writeln!(md, "# Probe calibration\n");
    let _ = writeln!(
        md,
        "Sphere centre [{:.4}, {:.4}, {:.4}] mm, Ø{} mm; stylus (effective) radius {:.4} mm at zero speed.\n",
        cal.sphere_center_mm[0],
        cal.sphere_center_mm[1],
        cal.sphere_center_mm[2],
        cal.sphere_diameter_mm,
        cal.stylus_radius_mm
    );
    let _ = writeln!(md, "Model: **{}** — {}.\n", cal.structure.name(), res.why);
    let cand: Vec<Vec<String>> = res
        .candidates
        .iter()
        .map(|c| {
            vec![
                c.model.clone(),
                c.coefficients.to_string(),
                format!("{:.3}", c.cv_rms_um),
            ]
        })
        .collect();
    let _ = writeln!(
        md,
        "{}",
        markdown_table(&["candidate", "coefficients", "CV RMS / µm"], &cand)
    );
    let _ = writeln!(
        md,
        "\nFit RMS {:.3} µm; repeatability 2σ {}; {} outliers (listed in the JSON).\n",
        cal.fit_rms_um,
        res.repeatability_2sigma_um
            .map_or("– (no repeated touches)".into(), |r| format!("{r:.3} µm")),
        res.outliers.len()
    );
    let _ = writeln!(
        md,
        "## Diameter error (on the {} rows, Ø{} mm)\n",
        de["on"].as_str().unwrap_or(""),
        eval_d
    );
    let _ = writeln!(
        md,
        "{}",
        markdown_table(
            &[
                "before",
                "bilinear reference",
                "plain (one radius)",
                "after"
            ],
            &[vec![
                num(&de["before"]),
                num(&de["reference_bilinear"]),
                num(&de["plain_one_radius"]),
                num(&de["after"]),
            ]]
        )
    );
    let _ = writeln!(
        md,
        "\n\"before\" = {}.\n",
        de["before_method"].as_str().unwrap_or("")
    );
    let _ = writeln!(
        md,
        "{}",
        markdown_table(
            &[
                "feed / mm/min",
                "touches",
                "before / µm",
                "bilinear / µm",
                "after / µm"
            ],
            &rows_md
        )
    );
    let _ = writeln!(
        md,
        "\n![diameter error](diameter_error.svg)\n\n## Radial residual over the sphere\n\nEach point is a touch at \
         the azimuth of its surface normal, one series per elevation ring.\n\n![after](residual_map.svg)\n\n\
         ![plain](residual_map_plain.svg)\n\n## Pretravel versus speed\n\n![pretravel](pretravel_speed.svg)"
    );
    outputs.folder_file(dir, "report.md", md);
    Ok(())
}

/// `axcomp sim-probe`: touches of the twin's probe (`axcomp_twin::probe`) as a touch CSV. Kept in this module
/// (not in `sim.rs`) so that `axcomp sim --plan probe-cal|probe-measure` can call it later.
#[derive(Debug, clap::Args)]
pub struct SimArgs {
    /// `probe-cal` (Ø25 mm sphere, rings at 0/22.5/45/67.5/90°, 24 azimuths, 100/300/600 mm/min, 2 runs) or
    /// `probe-measure` (a Ø19.05 mm sphere, a Ø50 mm ring gauge and a plane at --feed).
    #[arg(long, value_name = "PLAN")]
    pub plan: String,
    /// Output touch CSV.
    #[arg(long, value_name = "F.csv")]
    pub out: PathBuf,
    /// Probing speed of `probe-measure`, mm/min.
    #[arg(long, default_value_t = 450.0, value_name = "F")]
    pub feed: f64,
    /// Repeats of the plan.
    #[arg(long, value_name = "N")]
    pub repeats: Option<u32>,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// No bounce and no false triggers.
    #[arg(long)]
    pub no_glitches: bool,
    /// Per-row truth (surface point, normal, pretravel, kind) as CSV.
    #[arg(long, value_name = "F.csv")]
    pub truth: Option<PathBuf>,
}

/// Runs `axcomp sim-probe`.
pub fn sim_probe(args: SimArgs) -> anyhow::Result<()> {
    use axcomp_twin::probe::{ProbeModel, ProbePlan, TouchKind, simulate_touches, touches_csv};
    /// Most repeats of a plan (the calibration plan's 584 touches × 1000; more once aborted the process
    /// when memory ran out instead of saying so).
    const MAX_REPEATS: u32 = 1000;
    if args.repeats.is_some_and(|r| r > MAX_REPEATS) {
        bail!(
            "--repeats {}: at most {MAX_REPEATS} repeats of the plan",
            args.repeats.unwrap_or_default()
        );
    }
    crate::commands::common::check_range("--feed", args.feed, 1e-3, 1e5)?;
    let plan = match args.plan.as_str() {
        "probe-cal" | "cal" => {
            let mut p = ProbePlan::standard_calibration();
            if let Some(r) = args.repeats {
                p = ProbePlan::calibration(
                    [100.0, 50.0, 20.0],
                    25.0,
                    &[0.0, 22.5, 45.0, 67.5, 90.0],
                    24,
                    &[100.0, 300.0, 600.0],
                    r,
                );
            }
            p
        }
        "probe-measure" | "measure" => {
            if !(args.feed.is_finite() && args.feed > 0.0) {
                bail!("--feed {}: must be > 0", args.feed);
            }
            ProbePlan::measurement(args.feed, args.repeats.unwrap_or(1))
        }
        other => bail!("--plan `{other}`: expected probe-cal or probe-measure"),
    };
    if args.repeats == Some(0) {
        bail!("--repeats must be ≥ 1");
    }
    let mut probe = ProbeModel::kinematic_demo();
    if args.no_glitches {
        probe = probe.without_glitches();
    }
    let t = simulate_touches(&probe, &plan, args.seed);
    let csv = touches_csv(&t);
    let truth = args.truth.as_ref().map(|_| {
        let mut s = String::from(
            "surface_x_mm,surface_y_mm,surface_z_mm,normal_x,normal_y,normal_z,pretravel_um,kind\n",
        );
        for x in &t {
            let kind = match x.kind {
                TouchKind::Good => "good",
                TouchKind::Bounce => "bounce",
                TouchKind::FalseTrigger => "false_trigger",
            };
            let _ = writeln!(
                s,
                "{:.7},{:.7},{:.7},{:.9},{:.9},{:.9},{:.4},{kind}",
                x.surface_mm[0],
                x.surface_mm[1],
                x.surface_mm[2],
                x.normal[0],
                x.normal[1],
                x.normal[2],
                x.pretravel_um
            );
        }
        s
    });
    let mut outputs = OutputSet::new();
    if let (Some(p), Some(text)) = (&args.truth, &truth) {
        outputs.file(p, text.as_bytes());
    }
    outputs.file(&args.out, csv);
    outputs.commit()?;
    println!(
        "sim-probe: {} touches ({} bounce / false-trigger rows) → {}",
        t.len(),
        t.iter().filter(|x| x.kind != TouchKind::Good).count(),
        args.out.display()
    );
    Ok(())
}
