//! Judging a calibration (`axcomp fit probe`): the evaluation rows (held-out artefact, else the calibration
//! inliers), the uncorrected method ("before") and the diameter and radial errors of each method on them.
//!
//! Glossary:
//! - **uncorrected** ("before"): contact points with the nominal stylus ball radius (`--stylus-diameter-mm`),
//!   or, without it, with one calibrated effective radius (the plain method).
//! - **after**: contact points with the chosen model (effective radius by direction and speed).
//! - **evaluation rows**: the held-out rows (sphere of `--holdout-diameter-mm`, default the reference
//!   sphere's) when given, else the calibration rows (inliers).

use crate::{
    Calibration, CalibrationResult, ProbeError, Structure, Touch, flag_outliers,
    measured_diameter_mm, radial_about_fitted_centre,
};
use axcomp_numeric::stats::rms;

/// The evaluation of a calibration.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// The evaluation touches (gross outliers of held-out rows left out).
    pub touches: Vec<Touch>,
    /// The evaluated artefact's diameter, mm.
    pub diameter_mm: f64,
    /// `holdout` or `calibration`.
    pub on: &'static str,
    /// Held-out rows flagged as gross outliers (reported, not used): row, radial residual µm.
    pub flagged: Vec<(String, f64)>,
    /// The uncorrected method and its description.
    pub before: Calibration,
    pub before_method: String,
    /// Radial RMS (µm) about the fitted centre on held-out rows: after, before, bilinear reference.
    pub holdout_rms_um: Option<[f64; 3]>,
}

impl Evaluation {
    /// Diameter error (µm) of a free sphere through the evaluation contacts under `cal`, or `None` when it
    /// cannot be fitted.
    pub fn diameter_error_um(&self, cal: &Calibration) -> Option<f64> {
        measured_diameter_mm(&self.touches, |t| cal.effective_radius_mm(t))
            .ok()
            .map(|s| (2.0 * s.radius_mm - self.diameter_mm) * 1000.0)
    }
}

/// A calibration with one fixed effective radius (the uncorrected method with a nominal ball).
pub fn nominal(cal: &Calibration, radius_mm: f64) -> Calibration {
    Calibration {
        structure: Structure::Constant,
        coef_mm: vec![radius_mm],
        stylus_radius_mm: radius_mm,
        ..cal.clone()
    }
}

/// Options of [`evaluate`].
pub struct EvaluationOptions {
    pub sphere_diameter_mm: f64,
    /// Diameter of the held-out artefact (default the reference sphere's).
    pub holdout_diameter_mm: Option<f64>,
    /// Nominal stylus ball diameter: the uncorrected method's radius.
    pub stylus_diameter_mm: Option<f64>,
    pub outlier_mad: f64,
}

/// Evaluates `res` (fitted on `calibration_touches`) on the held-out touches `test` (rows named by
/// `test_labels`) or, without them, on the calibration inliers.
pub fn evaluate(
    res: &CalibrationResult,
    calibration_touches: &[Touch],
    test: &[Touch],
    test_labels: &[String],
    opts: &EvaluationOptions,
) -> Result<Evaluation, ProbeError> {
    let cal = &res.calibration;
    let outlier_idx: Vec<usize> = res.outliers.iter().map(|o| o.index).collect();
    let (touches, diameter_mm, on, flagged) = if test.is_empty() {
        let t: Vec<Touch> = (0..calibration_touches.len())
            .filter(|i| !outlier_idx.contains(i))
            .map(|i| calibration_touches[i])
            .collect();
        (t, opts.sphere_diameter_mm, "calibration", Vec::new())
    } else {
        let d = opts.holdout_diameter_mm.unwrap_or(opts.sphere_diameter_mm);
        for (k, tt) in test.iter().enumerate() {
            cal.check_touch(tt).map_err(|why| ProbeError::BadTouch {
                row: test_labels[k].clone(),
                what: why,
            })?;
        }
        // Glitches of the held-out touches flagged the same way (robust, reported, not used).
        let (_, r) = radial_about_fitted_centre(cal, test, d / 2.0)?;
        let flags = flag_outliers(&r, opts.outlier_mad);
        let mut keep = Vec::new();
        let mut flagged = Vec::new();
        for (k, e) in r.iter().enumerate() {
            if flags[k] {
                flagged.push((test_labels[k].clone(), *e));
            } else {
                keep.push(test[k]);
            }
        }
        (keep, d, "holdout", flagged)
    };
    if touches.len() < 4 {
        return Err(ProbeError::Input(format!(
            "{} evaluation touches: a diameter needs at least 4",
            touches.len()
        )));
    }
    let (before, before_method) = match opts.stylus_diameter_mm {
        Some(d) => (
            nominal(cal, d / 2.0),
            format!("nominal stylus ball Ø{d} mm (no pretravel correction)"),
        ),
        None => (
            res.plain.clone(),
            "one calibrated effective radius (plain method)".to_string(),
        ),
    };
    let r_eval = diameter_mm / 2.0;
    let holdout_rms_um = if test.is_empty() {
        None
    } else {
        let mut v = [0.0; 3];
        for (k, c) in [cal, &before, &res.reference].into_iter().enumerate() {
            v[k] = rms(&radial_about_fitted_centre(c, &touches, r_eval)?.1);
        }
        Some(v)
    };
    Ok(Evaluation {
        touches,
        diameter_mm,
        on,
        flagged,
        before,
        before_method,
        holdout_rms_um,
    })
}

/// The calibration rows (not `held`; with groups, the first group's: the reference pose) and the held-out
/// rows of `ds`. One sphere is fitted to each set, so each must hold one `artefact` (when the column is
/// there).
pub fn split_rows(
    ds: &axcomp_data::Dataset,
    held: &[bool],
    groups: Option<&[String]>,
) -> Result<(Vec<usize>, Vec<usize>), ProbeError> {
    let first_group = groups.and_then(|g| (0..g.len()).find(|&i| !held[i]).map(|i| &g[i]));
    let train: Vec<usize> = (0..ds.n_rows())
        .filter(|&i| !held[i])
        .filter(|&i| match (groups, first_group) {
            (Some(g), Some(f)) => &g[i] == f,
            _ => true,
        })
        .collect();
    let test: Vec<usize> = (0..ds.n_rows()).filter(|&i| held[i]).collect();
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
                return Err(ProbeError::Input(format!(
                    "{}: the {what} touches belong to {} artefacts ({}), but one sphere is fitted to them: {fix}",
                    ds.source(),
                    seen.len(),
                    seen.join(", ")
                )));
            }
        }
    }
    Ok((train, test))
}
