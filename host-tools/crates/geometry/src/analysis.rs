//! `axcomp fit geometry` as a library call: fit, judge on held-out lines or by cross-validation, volumetric
//! and ISO 230-6 figures, the contract's JSON.

use std::collections::BTreeMap;

use axcomp_kinematics::{Component, dot};
use serde::Serialize;

use crate::GeometryError;
use crate::data::LineData;
use crate::fit::{Fit, FitOptions, Identifiability, fit};
use crate::model::GeometryModel;

/// How the model is judged.
#[derive(Debug, Clone, PartialEq)]
pub enum Judge {
    /// Fit on all rows; `raw_rms_um` over all rows.
    None,
    /// Rows with `true` are held out (never fitted).
    Holdout(Vec<bool>),
    /// Leave-one-group-out over these group ids (one per row).
    Cv(Vec<usize>),
}

/// One component in the JSON.
#[derive(Debug, Clone, Serialize)]
pub struct ErrorEntry {
    pub identified: bool,
    pub reason: String,
    pub unit: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub samples: Option<Vec<[f64; 2]>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<f64>,
    /// `[position_mm, standard uncertainty]` (squareness: one entry at 0).
    pub uncertainty: Vec<[f64; 2]>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Volumetric {
    pub max_um: f64,
    pub rms_um: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct DiagonalFigure {
    pub line: String,
    pub before_um: f64,
    pub after_um: f64,
    /// Which predictions the after figure uses: `holdout`, `cv` or `fit`.
    pub basis: String,
}

#[derive(Debug, Clone, Serialize)]
pub struct ModelInfo {
    pub method: String,
    pub smoothing_lambda: f64,
    /// `[λ, leave-one-line-out RMS µm]` for every candidate.
    pub lambda_cv_rms_um: Vec<[f64; 2]>,
    /// The prior the evidence chose (with `Prior::Evidence`): per group α (roughness) and β (size)
    /// precisions relative to the data's weight on each component, damping, σ², ln p(y), knot grids.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prior: Option<crate::evidence::Evidence>,
    pub knot_intervals: [usize; 3],
    pub topology: String,
    pub sigma_um: f64,
}

/// What can be said about the identifiable floor (the best any model in the span of the measured lines
/// could do on the judged rows). The floor itself needs the true errors: the twin's validation computes it
/// (`axcomp-validation`, `held_back`); on measured data these are its computable parts.
#[derive(Debug, Clone, Serialize)]
pub struct FloorInfo {
    /// Residual standard deviation of the fit (µm): the reading noise, which no model removes from unseen
    /// readings.
    pub noise_um: f64,
    /// With `--holdout`: √(σ̂² + mean prediction variance over the held-out rows), µm: the held-out RMS a
    /// model that is right in the span of the fitted lines would score with this noise (its estimation
    /// error included, the part of the truth outside the span not).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub expected_holdout_rms_um: Option<f64>,
    /// The floor in µm: always null on measured data (it needs the truth).
    pub floor_um: Option<f64>,
    pub note: String,
}

/// The floor's computable parts for held-out rows `held` (empty: none held out).
fn floor_info(f: &Fit, data: &LineData, held: &[usize]) -> FloorInfo {
    let sigma = f.model.sigma_um;
    let expected_holdout_rms_um = (!held.is_empty()).then(|| {
        let var: f64 = held
            .iter()
            .map(|&i| {
                let r = &data.readings[i];
                let row = f.layout.row(&f.model.topology, r.q, r.tool, r.beam);
                let a: Vec<f64> = f.active_cols.iter().map(|&j| row[j]).collect();
                let mut v = 0.0;
                for (x, ax) in a.iter().enumerate() {
                    for (y, ay) in a.iter().enumerate() {
                        v += ax * f.covariance[(x, y)] * ay;
                    }
                }
                v.max(0.0)
            })
            .sum::<f64>()
            / held.len() as f64;
        (sigma * sigma + var).sqrt()
    });
    FloorInfo {
        noise_um: sigma,
        expected_holdout_rms_um,
        floor_um: None,
        note: "the identifiable floor (the best any model in the span of the fitted lines could do on the judged rows) needs the true errors and is computed on the twin (cargo run --release -p axcomp-validation --example held_back); noise_um is the floor no model beats on unseen readings, expected_holdout_rms_um what a model right in the lines' span would score with this noise".into(),
    }
}

/// The contract's JSON of `axcomp fit geometry` (plus more fields).
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    pub raw_rms_um: f64,
    pub fit_rms_um: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_rms_um: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cv_rms_um: Option<f64>,
    /// Next to the held-out figure: what can be computed of the identifiable floor.
    pub identifiable_floor: FloorInfo,
    pub errors: BTreeMap<String, ErrorEntry>,
    pub identifiability: Identifiability,
    pub volumetric: Volumetric,
    pub iso230_6_body_diagonals: Vec<DiagonalFigure>,
    pub model: ModelInfo,
    pub lines: usize,
    pub rows: usize,
    pub train_rows: usize,
}

/// Everything `fit geometry` produces.
#[derive(Debug, Clone)]
pub struct Analysis {
    pub fit: Fit,
    pub report: FitReport,
    /// Judged predictions per reading (held-out or cross-validated; fitted for the rest), µm along the beam.
    pub judged_pred: Vec<Option<f64>>,
    pub fitted_pred: Vec<f64>,
}

/// Model prediction along each reading's beam.
pub fn predict_readings(model: &GeometryModel, data: &LineData) -> Vec<f64> {
    data.readings
        .iter()
        .map(|r| {
            model
                .error_at(r.q, r.tool)
                .map(|e| dot(e, r.beam))
                .unwrap_or(f64::NAN)
        })
        .collect()
}

use axcomp_numeric::stats::rms;

/// Volumetric figures of a model over its measured box (11³ grid, tool offset 0).
pub fn volumetric(model: &GeometryModel) -> Volumetric {
    let (lo, hi) = (model.volume_min_mm, model.volume_max_mm);
    let mut mags = Vec::new();
    for i in 0..11 {
        for j in 0..11 {
            for k in 0..11 {
                let f = |a: usize, t: usize| lo[a] + (hi[a] - lo[a]) * t as f64 / 10.0;
                let q = [f(0, i), f(1, j), f(2, k)];
                if let Some(e) = model.error_at(q, [0.0; 3]) {
                    mags.push((e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt());
                }
            }
        }
    }
    Volumetric {
        max_um: mags.iter().fold(0.0, |a, b| a.max(*b)),
        rms_um: rms(mags.into_iter()),
    }
}

/// ISO 230-6 figures of the body diagonals (one beam for the whole line, with all three components ≥ 0.3
/// in magnitude; points read along their own beams from a station are not a diagonal): the range of the
/// readings before, and after the judged predictions (`basis`) where every reading of the line has one.
fn body_diagonal_figures(
    data: &LineData,
    judged_pred: &[Option<f64>],
    fitted_pred: &[f64],
    basis: &str,
) -> Vec<DiagonalFigure> {
    let n = data.readings.len();
    let mut diags = Vec::new();
    for (li, name) in data.lines.iter().enumerate() {
        let rows: Vec<usize> = (0..n).filter(|&i| data.readings[i].line == li).collect();
        let b = data.readings[rows[0]].beam;
        let one_beam = rows.iter().all(|&i| {
            let bi = data.readings[i].beam;
            (0..3).all(|k| (bi[k] - b[k]).abs() <= 1e-6)
        });
        if one_beam && b.iter().all(|c| c.abs() >= 0.3) {
            let range = |v: &mut dyn Iterator<Item = f64>| {
                let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(x), b.max(x))
                });
                hi - lo
            };
            let before = range(&mut rows.iter().map(|&i| data.readings[i].deviation_um));
            let line_basis = if rows.iter().all(|&i| judged_pred[i].is_some()) {
                basis
            } else {
                "fit"
            };
            let after = range(&mut rows.iter().map(|&i| {
                data.readings[i].deviation_um - judged_pred[i].unwrap_or(fitted_pred[i])
            }));
            diags.push(DiagonalFigure {
                line: name.clone(),
                before_um: before,
                after_um: after,
                basis: line_basis.to_string(),
            });
        }
    }
    diags
}

/// The contract's `errors` object: each component's identification, samples (functions) or value
/// (squareness), and uncertainty.
fn error_entries(model: &GeometryModel) -> BTreeMap<String, ErrorEntry> {
    let mut errors = BTreeMap::new();
    for (i, c) in Component::ALL.iter().enumerate() {
        let m = &model.components[i];
        let (samples, value) = match c.axis() {
            Some(_) => (
                Some(
                    m.uncertainty
                        .iter()
                        .map(|[q, _]| [*q, model.component_value(*c, *q)])
                        .collect(),
                ),
                None,
            ),
            None => (None, Some(m.value)),
        };
        errors.insert(
            c.name().to_string(),
            ErrorEntry {
                identified: m.identified,
                reason: m.reason.clone(),
                unit: m.unit.clone(),
                samples,
                value,
                uncertainty: m.uncertainty.clone(),
            },
        );
    }
    errors
}

/// Fits on the training rows, judges per `judge`, and builds the contract's JSON.
pub fn analyse(
    data: &LineData,
    judge: &Judge,
    opts: &FitOptions,
) -> Result<Analysis, GeometryError> {
    let n = data.readings.len();
    let train: Vec<usize> = match judge {
        Judge::Holdout(mask) => (0..n).filter(|&i| !mask[i]).collect(),
        _ => (0..n).collect(),
    };
    let f = fit(data, &train, opts)?;
    // the RMS figures sum in the fit's row order (independent of the file's)
    let all = data.canonical_order(&(0..n).collect::<Vec<_>>());
    let fitted_pred = predict_readings(&f.model, data);
    let mut judged_pred: Vec<Option<f64>> = vec![None; n];
    let mut holdout_rms_um = None;
    let mut cv_rms_um = None;
    let mut basis = "fit";
    let mut held_rows: Vec<usize> = Vec::new();
    let raw_rms_um;
    match judge {
        Judge::Holdout(mask) => {
            let held: Vec<usize> = all.iter().copied().filter(|&i| mask[i]).collect();
            for &i in &held {
                judged_pred[i] = Some(fitted_pred[i]);
            }
            raw_rms_um = rms(held.iter().map(|&i| data.readings[i].deviation_um));
            holdout_rms_um = Some(rms(held
                .iter()
                .map(|&i| data.readings[i].deviation_um - fitted_pred[i])));
            basis = "holdout";
            held_rows = held;
        }
        Judge::Cv(groups) => {
            let mut ids: Vec<usize> = groups.clone();
            ids.sort();
            ids.dedup();
            let fold_opts = FitOptions {
                lambdas: vec![f.model.smoothing_lambda],
                ..opts.clone()
            };
            for g in ids {
                let tr: Vec<usize> = (0..n).filter(|&i| groups[i] != g).collect();
                if tr.is_empty() {
                    continue;
                }
                let ff = fit(data, &tr, &fold_opts)?;
                let p = predict_readings(&ff.model, data);
                for i in (0..n).filter(|&i| groups[i] == g) {
                    judged_pred[i] = Some(p[i]);
                }
            }
            raw_rms_um = rms(all.iter().map(|&i| data.readings[i].deviation_um));
            cv_rms_um = Some(rms(all.iter().filter_map(|&i| {
                judged_pred[i].map(|p| data.readings[i].deviation_um - p)
            })));
            basis = "cv";
        }
        Judge::None => {
            raw_rms_um = rms(all.iter().map(|&i| data.readings[i].deviation_um));
        }
    }
    let diags = body_diagonal_figures(data, &judged_pred, &fitted_pred, basis);
    let errors = error_entries(&f.model);
    let report = FitReport {
        raw_rms_um,
        fit_rms_um: f.fit_rms_um,
        holdout_rms_um,
        cv_rms_um,
        identifiable_floor: floor_info(&f, data, &held_rows),
        errors,
        identifiability: f.identifiability.clone(),
        volumetric: volumetric(&f.model),
        iso230_6_body_diagonals: diags,
        model: ModelInfo {
            method: f.model.method.clone(),
            smoothing_lambda: f.model.smoothing_lambda,
            lambda_cv_rms_um: f.lambda_cv.iter().map(|(l, r)| [*l, *r]).collect(),
            prior: f.evidence.clone(),
            knot_intervals: [
                f.model.grids[0].intervals,
                f.model.grids[1].intervals,
                f.model.grids[2].intervals,
            ],
            topology: f.model.topology.label(),
            sigma_um: f.model.sigma_um,
        },
        lines: data.lines.len(),
        rows: n,
        train_rows: f.train_rows,
    };
    Ok(Analysis {
        fit: f,
        report,
        judged_pred,
        fitted_pred,
    })
}
