//! The touch-probe chain of [`crate::all`]: calibration touches and a held-out sphere on the probe
//! twin, calibrated as `axcomp fit probe` does (the probe library's reader, calibration and evaluation),
//! its diameter error before / after on the held-out sphere.

use axcomp_data::sanity::DataWarning;
use axcomp_data::{Dataset, HoldoutSpec, LoadOptions};
use axcomp_probe::evaluate::{EvaluationOptions, evaluate, split_rows};
use axcomp_probe::report::ProbeReport;
use axcomp_probe::touches::{in_probe_frame, probe_frames, read_touches, touch_warnings};
use axcomp_probe::{CalibrationOptions, DEFAULT_OUTLIER_MAD, ModelChoice, Touch, calibrate};
use axcomp_twin::probe::{ProbeModel, ProbePlan, simulate_touches, touches_csv};

use crate::row::{ChainOutputs, Row};
use crate::{DemoError, Result, StepContext};

/// Reference sphere, held-out sphere and nominal stylus ball diameters, mm (the probe twin's).
const SPHERE_DIAMETER_MM: f64 = 25.0;
const HOLDOUT_DIAMETER_MM: f64 = 19.05;
const STYLUS_DIAMETER_MM: f64 = 3.0;
/// The held-out rows: the second sphere.
const HOLDOUT: &str = "artefact=sphere2";

/// What the calibration gives the chain: `fit probe`'s JSON result (with the data warnings) and its
/// console summary.
struct Calibrated {
    json: serde_json::Value,
    summary: String,
}

/// The touches (with the held-out sphere) calibrated and judged as `axcomp fit probe --data …
/// --sphere-diameter-mm 25 --holdout artefact=sphere2 --holdout-diameter-mm 19.05
/// --stylus-diameter-mm 3` does; data warnings and a stylus far from the nominal are added to
/// `warnings`.
fn calibrate_touches(ds: &Dataset, warnings: &mut Vec<String>) -> Result<Calibrated> {
    let (touches, labels) = read_touches(ds)?;
    axcomp_probe::validate_touches(&touches, &labels)?;
    let data_warnings: Vec<DataWarning> = touch_warnings(ds, &touches);
    warnings.extend(data_warnings.iter().map(|w| w.message.clone()));
    let to_machine = probe_frames(ds, None)?;
    let touches: Vec<Touch> = touches
        .iter()
        .zip(&to_machine)
        .map(|(t, r)| in_probe_frame(t, r))
        .collect();
    let held = HoldoutSpec::parse(HOLDOUT)?.mask(ds)?;
    let (train, test) = split_rows(ds, &held, None)?;
    if test.is_empty() {
        return Err(DemoError::Invalid(format!(
            "{}: --holdout {HOLDOUT} selects no rows",
            ds.source()
        )));
    }
    let pick = |rows: &[usize]| -> (Vec<Touch>, Vec<String>) {
        rows.iter()
            .map(|&i| (touches[i], labels[i].clone()))
            .unzip()
    };
    let (tr_touches, tr_labels) = pick(&train);
    let opts = CalibrationOptions {
        model: ModelChoice::Auto,
        outlier_mad: DEFAULT_OUTLIER_MAD,
        ..CalibrationOptions::new(SPHERE_DIAMETER_MM)
    };
    let res = calibrate(&tr_touches, &tr_labels, &opts)?;
    let radius = res.calibration.stylus_radius_mm;
    if radius.is_nan() || radius <= 0.0 {
        return Err(DemoError::Invalid(format!(
            "{}: effective stylus radius {radius:.4} mm ≤ 0 (sphere diameter {SPHERE_DIAMETER_MM} mm)",
            ds.source()
        )));
    }
    if (radius - STYLUS_DIAMETER_MM / 2.0).abs() > 0.1 * STYLUS_DIAMETER_MM / 2.0 {
        warnings.push(format!(
            "effective stylus radius {radius:.4} mm vs the nominal ball's {:.4} mm: more than 10 % apart",
            STYLUS_DIAMETER_MM / 2.0
        ));
    }
    let (te_touches, te_labels) = pick(&test);
    let ev_opts = EvaluationOptions {
        sphere_diameter_mm: SPHERE_DIAMETER_MM,
        holdout_diameter_mm: Some(HOLDOUT_DIAMETER_MM),
        stylus_diameter_mm: Some(STYLUS_DIAMETER_MM),
        outlier_mad: DEFAULT_OUTLIER_MAD,
    };
    let evaluation = evaluate(&res, &tr_touches, &te_touches, &te_labels, &ev_opts)?;
    let report = ProbeReport {
        result: &res,
        sphere_diameter_mm: SPHERE_DIAMETER_MM,
        calibration_touches: &tr_touches,
        evaluation: &evaluation,
        rows: [ds.n_rows(), train.len(), test.len()],
        group_columns: 0,
        poses: &[],
        shared: None,
        machine: None,
    };
    let mut json = report.json();
    let summary = report.summary(&json);
    if let Some(o) = json.as_object_mut() {
        o.insert("warnings".into(), serde_json::to_value(&data_warnings)?);
    }
    Ok(Calibrated { json, summary })
}

/// The touch-probe chain (see the module documentation); the calibration's summary goes to the log.
pub(crate) fn probe(seed: u64, out: &mut ChainOutputs) -> Result<Row> {
    let model = ProbeModel::kinematic_demo();
    let mut t = simulate_touches(&model, &ProbePlan::standard_calibration(), seed);
    let held = simulate_touches(
        &model.without_glitches(),
        &ProbePlan::measurement(450.0, 1),
        seed + 1,
    );
    t.extend(held.into_iter().filter(|m| m.artefact == "sphere2"));
    let csv = touches_csv(&t);
    // Named as the report folder's copy, so that the rows the JSON names point into it.
    let ds = Dataset::from_csv_str("probe_touches.csv", &csv, &LoadOptions::default())?;
    let cal = calibrate_touches(&ds, &mut out.warnings).step(|| "fit probe".into())?;
    out.log.push_str(&cal.summary);
    let de = &cal.json["diameter_error_um"];
    let num = |k: &str| {
        de[k]
            .as_f64()
            .step(|| format!("fit probe JSON: diameter_error_um.{k}"))
    };
    let (before, after) = (num("before")?.abs(), num("after")?.abs());
    out.files
        .push(("probe_touches.csv".into(), csv.into_bytes()));
    out.files.push((
        "probe_fit.json".into(),
        (serde_json::to_string_pretty(&cal.json)? + "\n").into_bytes(),
    ));
    Ok(Row {
        system: "touch probe",
        figure: "|diameter error|, held-out 19.05 mm sphere, µm",
        before,
        after,
        firmware: "none for the calibration: the core's probe stage only latches touches; \
                   `axcomp predict` corrects on the host"
            .into(),
    })
}
