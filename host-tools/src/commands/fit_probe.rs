//! `axcomp fit probe`: touch-probe calibration on a reference sphere (contract: "Touch probe: calibration and
//! correction"; method, evaluation, per-pose centres and report: `axcomp_probe`). This module parses,
//! calls the library and writes every output only after the whole fit succeeded.

use std::path::PathBuf;

use anyhow::bail;
use axcomp_data::HoldoutSpec;
use axcomp_probe::evaluate::{EvaluationOptions, evaluate, split_rows};
use axcomp_probe::poses::{PoseOptions, carried_columns, fit_pose_centres, group_keys, rtest_csv};
use axcomp_probe::report::ProbeReport;
use axcomp_probe::touches::{
    in_probe_frame, parse_machine, probe_frames, probe_tilts, read_touches, touch_warnings,
};
use axcomp_probe::{
    CalibrationOptions, CalibrationResult, DEFAULT_OUTLIER_MAD, ModelChoice, Touch, calibrate,
};

use crate::cli::DataArgs;
use crate::commands::common::{load_dataset, report_warnings, with_warnings};
use crate::output::OutputSet;

const LONG_HELP: &str = "\
Touch CSV: x_mm, y_mm, z_mm (latched stylus-tip centre), approach_x/y/z (unit vector of the probing move, toward the surface), optional feed_mm_min, artefact, run.

How it works: algebraic sphere fit, then Levenberg–Marquardt geometric fits (centre + effective radius with the sphere's diameter fixed; a free-radius fit too). The effective radius r_eff(n, v) = stylus radius − pretravel is modelled by the surface normal's azimuth and elevation and the probing speed: `constant` (one radius), `bilinear` (the seed's azimuth × elevation grid at the calibration directions + one speed slope; the reference method) and `harmonic` (azimuthal harmonics 2..K × even polynomials in sin(elevation) + speed terms). The default (auto) takes the lowest cross-validated radial RMS (folds by direction: every 5th distinct direction held out). First-order direction terms are not modelled: on one sphere they cannot be told from its centre. Outliers (false triggers, bounce) are flagged at 6 robust σ (MAD) of the radial residual, excluded from the fit and listed in the JSON. Repeatability 2σ is pooled over repeated touches (same direction and speed).

Correction (axcomp predict --model CAL): contact = latched + r_eff(n, v)·approach.

Five-axis poses (--group COL,.. --centres-out F.csv, the probe route of `fit rtest`): the probe is calibrated on the first group (pose, in file order: the reference pose); every group's centre is fitted with that calibration (outlier flags iterated about the centre of the kept touches; a pose with fewer than 8 touches is not screened). The R-test row's x_mm, y_mm, z_mm are the group's commanded tool point and dx_um, dy_um, dz_um the fitted centre minus it. The commanded tool point comes from the columns cmd_x_mm, cmd_y_mm, cmd_z_mm (constant within a group: the position the linear axes were commanded to so that, by the nominal kinematics, the tool point sits at the sphere's nominal centre). The R-test rows carry the group columns, `path` and `setup` when the touches have them (constant per group), dx_um, dy_um, dz_um, then the calibration's error every centre shares: zero1_dx_um, zero1_dy_um, zero1_dz_um, zero2_… (the coefficients' covariance from the calibration fit propagated through each centre fit; each triplet one independent standard-uncertainty component, µm; JSON shared_zero), which `fit rtest` propagates into the location errors' standard uncertainties.

Head machines (--machine bc-head, as `fit rtest --machine`): the probe turns with C and tilts with B, so its approach directions, pretravel and calibration belong to the probe's frame. Each touch's position and approach are turned into the probe's frame by the nominal kinematics of its pose (columns b_deg, c_deg; Rc(c)·Rb(b), the tool along −Z at B = C = 0; no pivot length is needed) before the calibration (made at the reference pose, best B = C = 0) corrects it; each pose's fitted centre is turned back into the machine frame. Group on the pose columns and the run (--group b_deg,c_deg,run): a pose revisited later (B = C = 0 at the start and at the end) is a further run, one R-test row of its own. x_mm, y_mm, z_mm are tool-point coordinates (TCPC): without the cmd_* columns the controller aimed the tool point at the same sphere centre at every pose, so every group's commanded tool point is the reference pose's fitted centre (the nominal sphere of `fit rtest --machine bc-head`, whose set-up offsets take up where exactly it is). Then: axcomp fit rtest --data centres.csv --machine bc-head --pivot-mm L. --machine ac-trunnion / bc-trunnion: the probe does not tilt (directions in the machine frame, as without --machine).

diameter_error_um is judged on the held-out rows (--holdout, an artefact of --holdout-diameter-mm); without --holdout it is computed on the calibration rows, where the model fixes the diameter (after ≈ 0 by construction): use a held-out artefact to judge.

Examples (twin data):
  axcomp fit probe --data touches.csv --sphere-diameter-mm 25 --holdout artefact=sphere2
    --holdout-diameter-mm 19.05 --stylus-diameter-mm 3 --out cal.json --json fit.json --report rep
  axcomp sim --machine bc-head --plan probe-rtest --out head-touches.csv --truth truth.json
  axcomp fit probe --data head-touches.csv --sphere-diameter-mm 25 --machine bc-head
    --group b_deg,c_deg,run --centres-out centres.csv
  axcomp fit rtest --data centres.csv --machine bc-head --pivot-mm 250";

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
    /// Columns naming a pose (e.g. a_deg,c_deg, or b_deg,c_deg,run with revisits): fit one sphere centre
    /// per group. Each group's commanded tool point is read from the columns cmd_x_mm, cmd_y_mm, cmd_z_mm
    /// (constant within the group; needed by --centres-out, optional otherwise; see --machine bc-head).
    #[arg(long, value_delimiter = ',', value_name = "COL,..")]
    pub group: Vec<String>,
    /// Machine kind whose nominal kinematics turn each touch into the probe's frame: bc-head (the probe
    /// tilts with B and turns with C; pose columns b_deg, c_deg), ac-trunnion, bc-trunnion (the probe does
    /// not tilt). Default: none (directions in the machine frame). See --help.
    #[arg(long, value_name = "KIND")]
    pub machine: Option<String>,
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

/// The options checked before any data is read.
fn check_options(args: &Args) -> anyhow::Result<(ModelChoice, Option<HoldoutSpec>)> {
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
    if let Some(d) = args.stylus_diameter_mm
        && !(d > 0.0 && d.is_finite())
    {
        bail!("--stylus-diameter-mm {d}: must be > 0");
    }
    if args.outlier_mad.is_nan() || args.outlier_mad <= 0.0 {
        bail!("--outlier-mad {}: must be > 0", args.outlier_mad);
    }
    if args.centres_out.is_some() && args.group.is_empty() {
        bail!("--centres-out needs --group COL,..");
    }
    if let Some(m) = &args.machine {
        parse_machine(m)?;
    }
    let holdout = args
        .holdout
        .as_deref()
        .map(HoldoutSpec::parse)
        .transpose()?;
    Ok((model, holdout))
}

/// Every output planned and checked before the fit; written together at the end.
fn plan_outputs(args: &Args) -> anyhow::Result<OutputSet> {
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
    Ok(outputs)
}

/// The latched tip centres lie |p − C| = R + r_eff from the centre: r_eff ≤ 0 means they lie on or inside
/// the sphere as given, which no stylus does (the diameter is wrong, or the artefact is not a sphere touched
/// from outside). A radius far from the nominal ball's is warned about.
fn check_stylus(args: &Args, source: &str, res: &CalibrationResult) -> anyhow::Result<()> {
    let cal = &res.calibration;
    let d = args.sphere_diameter_mm;
    if cal.stylus_radius_mm.is_nan() || cal.stylus_radius_mm <= 0.0 {
        bail!(
            "{source}: the latched stylus-tip centres lie {:.4} mm from the fitted centre, not more than the \
             sphere's radius {:.4} mm (--sphere-diameter-mm {d}): the effective stylus radius would be {:.4} \
             mm ≤ 0. Is the sphere diameter right (the touches fit a sphere of {:.4} mm with a zero-radius \
             stylus)?",
            d / 2.0 + cal.stylus_radius_mm,
            d / 2.0,
            cal.stylus_radius_mm,
            d + 2.0 * cal.stylus_radius_mm
        );
    }
    if let Some(s) = args.stylus_diameter_mm
        && (cal.stylus_radius_mm - s / 2.0).abs() > 0.1 * s / 2.0
    {
        eprintln!(
            "axcomp: warning: effective stylus radius {:.4} mm vs the nominal ball's {:.4} mm \
             (--stylus-diameter-mm {s}): more than 10 % apart, far beyond a pretravel; is \
             --sphere-diameter-mm {d} right?",
            cal.stylus_radius_mm,
            s / 2.0,
        );
    }
    Ok(())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (model, holdout) = check_options(&args)?;
    let outputs = plan_outputs(&args)?;

    // ---- data: touches, in the probe's frame where the probe tilts ----
    let ds = load_dataset(&args.data)?;
    let (touches, labels) = read_touches(&ds)?;
    axcomp_probe::validate_touches(&touches, &labels)?;
    let warnings = touch_warnings(&ds, &touches);
    report_warnings(&warnings, args.strict)?;
    let machine = args.machine.as_deref().map(parse_machine).transpose()?;
    let to_machine = probe_frames(&ds, machine)?;
    let touches: Vec<Touch> = touches
        .iter()
        .zip(&to_machine)
        .map(|(t, r)| in_probe_frame(t, r))
        .collect();
    let held: Vec<bool> = match &holdout {
        Some(h) => h.mask(&ds)?,
        None => vec![false; ds.n_rows()],
    };
    let groups = (!args.group.is_empty())
        .then(|| group_keys(&ds, &args.group))
        .transpose()?;
    let (train, test) = split_rows(&ds, &held, groups.as_deref())?;
    if holdout.is_some() && test.is_empty() {
        bail!(
            "{}: --holdout {} selects no rows",
            ds.source(),
            args.holdout.as_deref().unwrap_or("")
        );
    }

    // ---- calibration, evaluation, per-pose centres ----
    let pick = |rows: &[usize]| -> (Vec<Touch>, Vec<String>) {
        rows.iter()
            .map(|&i| (touches[i], labels[i].clone()))
            .unzip()
    };
    let (tr_touches, tr_labels) = pick(&train);
    let opts = CalibrationOptions {
        model,
        outlier_mad: args.outlier_mad,
        ..CalibrationOptions::new(args.sphere_diameter_mm)
    };
    let res = calibrate(&tr_touches, &tr_labels, &opts)?;
    check_stylus(&args, ds.source(), &res)?;
    let cal = &res.calibration;
    let (te_touches, te_labels) = pick(&test);
    let ev_opts = EvaluationOptions {
        sphere_diameter_mm: args.sphere_diameter_mm,
        holdout_diameter_mm: args.holdout_diameter_mm,
        stylus_diameter_mm: args.stylus_diameter_mm,
        outlier_mad: args.outlier_mad,
    };
    let evaluation = evaluate(&res, &tr_touches, &te_touches, &te_labels, &ev_opts)?;
    let pose_opts = PoseOptions {
        group: &args.group,
        radius_mm: args.sphere_diameter_mm / 2.0,
        outlier_mad: args.outlier_mad,
        to_machine: &to_machine,
        need_commanded: args.centres_out.is_some(),
        tcpc_reference: machine.is_some_and(probe_tilts),
    };
    let poses = if groups.is_some() {
        fit_pose_centres(&ds, &touches, &labels, &held, cal, &pose_opts)?
    } else {
        Vec::new()
    };
    // The error every pose's centre shares through the one calibration (see `axcomp_probe::poses`).
    let shared = (!poses.is_empty())
        .then(|| axcomp_probe::poses::shared_error(&res, &tr_touches, &poses))
        .transpose()
        .map_err(|e| {
            anyhow::anyhow!("the calibration's error shared by the groups' centres: {e}")
        })?;

    // ---- outputs: everything computed; now write ----
    let report = ProbeReport {
        result: &res,
        sphere_diameter_mm: args.sphere_diameter_mm,
        calibration_touches: &tr_touches,
        evaluation: &evaluation,
        rows: [ds.n_rows(), train.len(), test.len()],
        group_columns: args.group.len(),
        poses: &poses,
        shared: shared.as_ref(),
        machine: machine.map(|m| m.name()),
    };
    let columns: Vec<&str> = args
        .group
        .iter()
        .map(String::as_str)
        .chain(carried_columns(&ds, &args.group))
        .collect();
    let centres = args
        .centres_out
        .is_some()
        .then(|| rtest_csv(&columns, &poses, shared.as_ref()))
        .transpose()?;
    write_outputs(&args, outputs, &report, centres, &warnings)
}

/// Writes every output together (or nothing, the report folder included) and prints the summary.
fn write_outputs(
    args: &Args,
    mut outputs: OutputSet,
    report: &ProbeReport,
    centres_csv: Option<String>,
    warnings: &[axcomp_data::sanity::DataWarning],
) -> anyhow::Result<()> {
    let json = report.json();
    if let Some(dir) = &args.report {
        for (name, text) in report.files(&json) {
            outputs.folder_file(dir, &name, text);
        }
    }
    if let (Some(p), Some(text)) = (&args.centres_out, centres_csv) {
        outputs.file(p, text);
    }
    if let Some(p) = &args.out {
        let provenance =
            crate::provenance::of_data(&args.data, args.holdout.as_deref(), None, "", "fit probe")?;
        outputs.file(
            p,
            crate::provenance::stamp_text(&report.result.calibration.to_json(), &provenance)?,
        );
    }
    if let Some(p) = &args.json {
        outputs.json(p, &with_warnings(json.clone(), warnings)?)?;
    }
    outputs.commit()?;
    print!("{}", report.summary(&json));
    Ok(())
}
