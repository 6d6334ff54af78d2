//! `axcomp fit rtest`: rotary-axis location errors of a five-axis machine (ISO 230-7 names) from R-test
//! readings or probed sphere centres in the R-test form (contract: "Location errors of a five-axis machine's
//! rotary axes"). The work is in `axcomp_rtest`; this module parses, runs, and writes every output only after
//! the whole analysis succeeded.

use std::path::PathBuf;

use anyhow::bail;
use axcomp_rtest::analysis::analyse_effects;
use axcomp_rtest::report::report_files;
use axcomp_rtest::warnings::rtest_warnings;
use axcomp_rtest::{FitOptions, RtestData, RtestModel, read_shared_error};

use crate::cli::DataArgs;
use crate::commands::common::{
    load_dataset, machine_from, report_warnings, split_from, with_warnings,
};
use crate::output::OutputSet;

const LONG_HELP: &str = "\
Columns: x_mm, y_mm, z_mm (commanded tool point, tool length included, origin at the nominal intersection of the rotary axes), a_deg (ac-trunnion) or b_deg (bc-trunnion, bc-head), c_deg, dx_um, dy_um, dz_um (sphere centre relative to the R-test head along machine X, Y, Z); optional path (K4, C-circle, ...), run, setup (one sphere placement per value: its own set-up offsets), time_s. A probed-sphere campaign gives the same rows: each pose's fitted sphere centre minus the commanded tool point.

Model: the exact homogeneous-transform chain with the 11 location errors (C: EX0C EY0C EA0C EB0C; A: EY0A EZ0A EB0A EC0A or B: EX0B EZ0B EA0B EC0B; squareness EA0Z EB0Z EC0Y) and the sphere's set-up offsets (nuisance). Levenberg–Marquardt; standard uncertainties from (JᵀJ)⁻¹·JᵀWJ·(JᵀJ)⁻¹, W the residual variance of each component X, Y, Z; the head's / probe's zero uncertainty is added, propagated (a constant zero error moves EX0C, EY0A, EZ0A and the set-up offsets): by default from the data's optional columns zero1_dx_um, zero1_dy_um, zero1_dz_um, zero2_… (what `axcomp fit probe --centres-out` writes: the probe calibration's error shared by every pose's centre, each triplet one standard-uncertainty component, µm), or from --head-zero-std-um, which overrides them; without either the zero is taken as exact. The JSON's zero_uncertainty says which was used. Parameters the poses cannot separate are fixed to 0 and reported identified: false with the reason (and those that absorb them too); parameters whose uncertainty is inflated more than 32× by correlation stay estimated but are reported identified: false; `axcomp plan rtest` says which paths to add.

Default selection (do no harm on data with effects beyond the model): on the fitted rows alone, each path (else run) is left out in turn and predicted by the full model and by the nominal kinematics with the set-up offsets only (linearised refits); when the nominal one predicts better and the location errors explain little of the fitted rows (in-sample RMS ratio below 3), every location error is fixed at zero (identified: false, with the figures). --full-model turns it off. The JSON's comparison gives the judged rows' RMS of this model, the full model, the nominal kinematics without correction and with the set-up offsets only; selection.robust_std flags each location error against its standard uncertainty robust to residuals correlated along a path.

With --free-head-zero the R-test head's zero (tool length, radial offset) is estimated per set-up too; then the rotary axes' absolute position relative to the spindle (e.g. EX0C, EY0A, EZ0A on an AC trunnion) cannot be determined and is reported so.

--effects KIND[,KIND] adds effects beyond the location errors (the kinds `axcomp diagnose` names), each with the parametrisation the diagnosis refits it with (axcomp_rtest::effects): rotary_positioning — the angular positioning error of C as harmonics 0…4 of its angle and of the tilt axis as a polynomial of degree 2 in its angle (what a rotary axis's compensation table holds); rotary_wobble — C tilting about the two axes perpendicular to it and moving radially at 1, 2, 3 per turn, and the tilt axis likewise as powers 1, 2 of its angle; linear_geometry — the tool point's error along X, Y, Z as Legendre polynomials of degree 1…3 of each linear axis over the range the poses move it (its constant and linear parts are shared with the set-up offsets and the squareness / location errors, which keep them; nothing beyond the measured range: `predict` refuses rows outside it). Parameters the poses cannot separate are fixed to 0 and reported identified: false. The location errors are then all estimated (no do-no-harm selection); the JSON's effects object gives each parameter with its std and identified, and comparison.location_errors_only_rms_um the same rows without the effects. The drifts (setup_drift, thermal_drift, time_drift) are not model terms: a drift over one campaign's time does not predict another; the closure figure (revisited poses) reports them.

Revisits: a pose measured again later (a closure check) is a further run of its path; a run may hold a single pose (the readings of a set-up are absolute against its set-up offsets). The JSON's closure gives each revisited pose's drift, last visit minus first.

Example: axcomp fit rtest --data rtest.csv --holdout run=2 --json fit.json --report rtest-report --out rtest-model.json";

#[derive(Debug, clap::Args)]
#[command(after_long_help = LONG_HELP)]
pub struct Args {
    #[command(flatten)]
    pub data: DataArgs,
    /// Machine kind: ac-trunnion, bc-trunnion, bc-head.
    #[arg(long, default_value = "ac-trunnion", value_name = "KIND")]
    pub machine: String,
    /// bc-head: nominal distance from the B axis to the tool point, mm.
    #[arg(long, value_name = "L")]
    pub pivot_mm: Option<f64>,
    /// Rows held out from fitting and used only to judge: COL=V1,V2 | COL>=X | COL<X.
    #[arg(long, value_name = "SPEC")]
    pub holdout: Option<String>,
    /// Leave-one-group-out cross-validation over the values of COL (e.g. path).
    #[arg(long, value_name = "COL")]
    pub cv: Option<String>,
    /// Estimate the R-test head's zero (tool length, radial offset) per set-up as a nuisance too.
    #[arg(long)]
    pub free_head_zero: bool,
    /// The R-test head's / touch probe's zero is known only to this standard uncertainty (µm; one value or
    /// X,Y,Z, from its own calibration): propagated into the location errors' standard uncertainties.
    /// Overrides the data's zero*_d*_um columns (the probe route's calibration uncertainty).
    #[arg(
        long,
        value_name = "S|SX,SY,SZ",
        conflicts_with = "free_head_zero",
        allow_hyphen_values = true
    )]
    pub head_zero_std_um: Option<String>,
    /// Estimate every identifiable location error (no do-no-harm selection: see --help).
    #[arg(long)]
    pub full_model: bool,
    /// Add effects beyond the location errors to the model: rotary_positioning, rotary_wobble,
    /// linear_geometry (comma-separated; e.g. the verdict of `axcomp diagnose`). See --help.
    #[arg(long, value_name = "KIND[,KIND]")]
    pub effects: Option<String>,
    /// Write the model file (for `axcomp predict`).
    #[arg(long, value_name = "MODEL.json")]
    pub out: Option<PathBuf>,
    /// Machine-readable result.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write report.md and SVG figures into DIR.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Refuse the data (exit 2) when a plausibility check warns (outliers, units, magnitudes, a file
    /// that names another machine kind).
    #[arg(long)]
    pub strict: bool,
}

/// `--head-zero-std-um S` or `SX,SY,SZ` (µm, finite, ≥ 0).
fn parse_head_zero_std(s: &str) -> anyhow::Result<[f64; 3]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| anyhow::anyhow!("--head-zero-std-um `{s}`: {e}"))?;
    let v = match v[..] {
        [a] => [a, a, a],
        [a, b, c] => [a, b, c],
        _ => bail!("--head-zero-std-um `{s}`: need one value or three (X,Y,Z), µm"),
    };
    if v.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
        bail!("--head-zero-std-um `{s}`: need finite values ≥ 0 µm");
    }
    Ok(v)
}

/// The fitted poses' readings (3 per pose) must at least match the unknowns: the 11 location errors and
/// each set-up's sphere offsets (and head zero with `--free-head-zero`). Fewer is an error, not a model
/// whose "identified" values fit the noise.
fn check_enough_poses(
    ds: &axcomp_data::Dataset,
    data: &RtestData,
    split: Option<&axcomp_data::Split>,
) -> anyhow::Result<()> {
    let fitted = match split {
        Some(axcomp_data::Split::Holdout(h)) => h.mask(ds)?.iter().filter(|m| !**m).count(),
        _ => data.poses.len(),
    };
    let per_setup = if data.free_head_zero { 6 } else { 3 };
    let unknowns = axcomp_kinematics::rotary::N_LOCATION + per_setup * data.setup_names.len();
    if 3 * fitted < unknowns {
        bail!(
            "{}: {fitted} poses to fit give {} readings (dx, dy, dz), fewer than the {unknowns} unknowns \
             ({} location errors, {per_setup} set-up offsets for each of {} set-ups): need at least {} poses",
            data.source,
            3 * fitted,
            axcomp_kinematics::rotary::N_LOCATION,
            data.setup_names.len(),
            unknowns.div_ceil(3)
        );
    }
    Ok(())
}

/// `--effects KIND[,KIND]` into the model's effect terms (their parametrisation over the file's poses).
fn effect_set(list: &str, data: &RtestData) -> anyhow::Result<axcomp_rtest::effects::EffectSet> {
    use axcomp_effects::RotaryEffect;
    use axcomp_rtest::effects::{EffectTerm, MODELLED};
    let modelled: Vec<&str> = MODELLED.iter().map(|k| k.name()).collect();
    let mut set = axcomp_rtest::effects::EffectSet::default();
    for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let kind: RotaryEffect = name
            .parse()
            .map_err(|e| anyhow::anyhow!("--effects: {e}"))?;
        if !MODELLED.contains(&kind) {
            bail!(
                "--effects {name}: not a model term of `fit rtest` (it models {}): a drift over one campaign's time does not predict another campaign; the JSON's closure reports the drift between revisits",
                modelled.join(", ")
            );
        }
        if set.terms.iter().any(|t| t.kind == kind) {
            continue;
        }
        let term = EffectTerm::richest(kind, &data.machine, &data.poses).ok_or_else(|| {
            anyhow::anyhow!(
                "--effects {name}: cannot be built on these poses (no linear axis moves)"
            )
        })?;
        set.terms.push(term);
    }
    if set.is_empty() {
        bail!(
            "--effects `{list}`: no effect named (expected {})",
            modelled.join(", ")
        );
    }
    Ok(set)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let machine = machine_from(&args.machine, args.pivot_mm)?;
    let head_zero_std_um = args
        .head_zero_std_um
        .as_deref()
        .map(parse_head_zero_std)
        .transpose()?;
    let split = split_from(args.holdout.as_deref(), args.cv.as_deref())?;
    // Every output path is checked before the fit; all files are written together at the end.
    let mut outputs = OutputSet::new();
    outputs.input(&args.data.data);
    if let Some(dir) = &args.report {
        outputs.folder(dir, "--report");
    }
    for p in [&args.json, &args.out].into_iter().flatten() {
        outputs.planned(p);
    }
    outputs.check()?;
    let ds = load_dataset(&args.data)?;
    let mut data = RtestData::from_dataset(&ds, machine, true)?;
    let warnings = rtest_warnings(&args.data.data, &ds, &data)?;
    report_warnings(&warnings, args.strict)?;
    data.free_head_zero = args.free_head_zero;
    check_enough_poses(&ds, &data, split.as_ref())?;
    let opts = FitOptions { head_zero_std_um };
    // The probe route's centres carry their calibration's shared error (zero1_dx_um, …): used unless
    // --head-zero-std-um overrides it.
    let shared = read_shared_error(&ds)?;
    let effects = match args.effects.as_deref() {
        Some(list) => effect_set(list, &data)?,
        None => axcomp_rtest::effects::EffectSet::default(),
    };
    let a = analyse_effects(
        &ds,
        &data,
        split.as_ref(),
        &opts,
        shared.as_ref(),
        !args.full_model,
        &effects,
    )?;
    let json = a.to_json(&data);
    let model: RtestModel = a.model.clone();
    if let Some(dir) = &args.report {
        for (name, text) in report_files(&a, &data) {
            outputs.folder_file(dir, &name, text);
        }
    }
    if let Some(p) = &args.json {
        outputs.json(p, &with_warnings(json.clone(), &warnings)?)?;
    }
    if let Some(p) = &args.out {
        let provenance = crate::provenance::of_data(
            &args.data,
            args.holdout.as_deref(),
            args.cv.as_deref(),
            "",
            "fit rtest",
        )?;
        outputs.file(p, crate::provenance::stamp(&model, &provenance)?);
    }
    outputs.commit()?;
    print_summary(&a, &data, &json);
    if a.judged_by != "fit" && a.judged_rms_um >= a.nominal_setup_rms_um {
        eprintln!(
            "axcomp: warning: the model predicts the {} rows no better than the nominal kinematics with the sphere's set-up offsets only ({:.3} µm vs {:.3} µm): effects beyond the location-error model? (axcomp diagnose --model location_errors)",
            a.judged_by, a.judged_rms_um, a.nominal_setup_rms_um
        );
    }
    if a.judged_rms_um >= a.raw_rms_um {
        eprintln!(
            "axcomp: warning: the model predicts the {} rows no better than the nominal kinematics ({:.3} µm vs {:.3} µm): do not use it for compensation",
            a.judged_by, a.judged_rms_um, a.raw_rms_um
        );
    }
    Ok(())
}

fn print_summary(a: &axcomp_rtest::analysis::Analysis, data: &RtestData, json: &serde_json::Value) {
    println!(
        "fit rtest ({}): {} rows fitted, judged by {}",
        data.machine.kind.name(),
        a.fit_rows.len(),
        a.judged_by
    );
    for (name, v) in &a.model.location_errors {
        match (v.identified, v.std) {
            (true, Some(s)) => println!("  {name:5} {:10.3} ± {:7.3} {}", v.value, s, v.unit),
            _ => println!(
                "  {name:5} not identified: {}",
                v.reason.as_deref().unwrap_or("")
            ),
        }
    }
    println!(
        "  condition number {:.1}; RMS raw {:.3} µm, fit {:.3} µm, {} {:.3} µm",
        a.fit.ident.condition_number, a.raw_rms_um, a.fit.fit_rms_um, a.judged_by, a.judged_rms_um
    );
    println!(
        "  {} RMS: this model {:.3} µm, full model {:.3} µm, nominal kinematics {:.3} µm (no correction), {:.3} µm (set-up offsets only)",
        a.judged_by, a.judged_rms_um, a.full_rms_um, a.raw_rms_um, a.nominal_setup_rms_um
    );
    if let Some(sel) = a.selection.as_ref().filter(|s| !s.fixed.is_empty()) {
        let evidence = if sel.cv_gain_um2.is_finite() {
            format!(
                "leave-one-out RMS of the fitted rows: set-up offsets only {:.3} µm, full {:.3} µm; gain {:.3} µm² per reading, not above {} × its standard error {:.3} µm²",
                sel.inner_cv_nominal_um,
                sel.inner_cv_full_um,
                sel.cv_gain_um2,
                axcomp_rtest::select::GAIN_Z,
                sel.cv_gain_std_um2
            )
        } else {
            sel.groups.clone()
        };
        println!(
            "  default selection: every location error fixed at zero ({evidence}; in-sample RMS ratio {:.2} < {}; --full-model estimates them)",
            sel.fit_rms_ratio,
            axcomp_rtest::select::RATIO_LIMIT
        );
    }
    for e in &a.model.effects {
        let n_id = e.parameters.iter().filter(|(_, p)| p.identified).count();
        println!(
            "  effect {}: {n_id} of {} parameters identified, correction RMS {:.3} µm over the fitted poses; location errors alone {:.3} µm on the {} rows",
            e.kind,
            e.parameters.len(),
            e.rms_over_fit_um,
            a.full_rms_um,
            a.judged_by
        );
    }
    if let Some(c) = json["closure"]["max_magnitude_um"].as_f64() {
        println!(
            "  closure: {} revisited pose(s), largest drift {c:.3} µm (last visit − first)",
            a.closure.len()
        );
    }
    if let Some(k) = json.get("k4").filter(|k| !k.is_null()) {
        println!("  K4 ranges before {} after {}", k["before"], k["after"]);
    }
}
