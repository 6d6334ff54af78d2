//! The default's do-no-harm selection of location errors (`fit rtest` without `--full-model`), judged on the
//! fitted (training) rows only: on data with effects beyond the 11-parameter model (rotary positioning
//! error, wobble, run-out, drift, …) on a machine whose location errors are small, the full model fits those
//! effects with spurious location errors and predicts another path worse than the nominal kinematics with
//! the sphere's set-up offsets (the twin: 11–13 of 20 seeds with the location errors at zero and a C circle
//! held out).
//!
//! Rule (all or nothing): the fitted rows are split into groups (their `path` values, else their `run`
//! values; fewer than two: no selection). The leave-one-group-out RMS of the displacements (linearised
//! refits around the full fit, minimum-norm where a fold does not determine every column) is computed for
//! the full model and for the nominal kinematics with the set-up offsets only. All location errors are
//! fixed at zero (reported `identified: false` with both figures) when the nominal one is lower **and** the
//! location errors explain little of the fitted rows (the nominal's in-sample RMS less than [`RATIO_LIMIT`]
//! × the full model's). Measured on the twin by `cargo run --release -p axcomp-rtest --example
//! rtest_unmodelled` (README, issue 11).
//!
//! Flags (never fixing): each location error's standard uncertainty robust to residuals correlated along a
//! path (cluster-robust over chunks of [`CHUNK`] consecutive poses) and whether it is at least twice that.

use nalgebra::{DMatrix, DVector};

use crate::{Fit, FitOptions, RtestData, RtestError, SharedError, fit_fixed, fit_shared};
use axcomp_kinematics::rotary::N_LOCATION;

/// What the selection did (the JSON's `selection`).
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Whether the selection ran (it needs ≥ 2 groups of training rows; off with `--full-model`).
    pub applied: bool,
    /// What the groups are (`path`, `run`) or why it did not run.
    pub groups: String,
    /// Leave-one-group-out RMS (µm) of the full model, the selected one and the nominal kinematics with the
    /// set-up offsets only.
    pub inner_cv_full_um: f64,
    pub inner_cv_selected_um: f64,
    pub inner_cv_nominal_um: f64,
    /// Location errors fixed at zero by the selection (index, reason).
    pub fixed: Vec<(usize, String)>,
    /// In-sample RMS of the nominal kinematics with the set-up offsets only over the full model's.
    pub fit_rms_ratio: f64,
    /// Per estimated location error: its standard uncertainty robust to residuals correlated along a path
    /// (chunks of [`CHUNK`] consecutive poses) and whether |value| ≥ 2 × it.
    pub robust_std: Vec<(usize, f64, bool)>,
}

/// The selection considers the nominal kinematics only when the full model's in-sample RMS is more than
/// 1/RATIO_LIMIT of theirs (the location errors explain less than 1 − 1/3² ≈ 89 % of the readings'
/// variance beyond the set-up offsets): where they explain more, a path left out of the fitted rows is
/// extrapolated from fewer paths than the full fit sees and that inner judgement is not to be trusted.
pub const RATIO_LIMIT: f64 = 3.0;

/// Fits `rows` with the selection (see the module doc): `groups[r]` the group id of row `r` (for every row
/// of `data`), `what` names the grouping. Returns the fit and what the selection did.
pub fn fit_selected(
    data: &RtestData,
    rows: &[usize],
    opts: &FitOptions,
    shared: Option<&SharedError>,
    groups: Option<(&[usize], &str)>,
) -> Result<(Fit, Selection), RtestError> {
    let full = fit_shared(data, rows, opts, shared)?;
    let mut sel = Selection {
        applied: false,
        groups: String::new(),
        inner_cv_full_um: f64::NAN,
        inner_cv_selected_um: f64::NAN,
        inner_cv_nominal_um: f64::NAN,
        fixed: Vec::new(),
        fit_rms_ratio: f64::NAN,
        robust_std: Vec::new(),
    };
    let Some((ids, what)) = groups else {
        sel.groups = "no path or run column: nothing to judge a selection on".into();
        return Ok((full, sel));
    };
    let mut labels: Vec<usize> = rows.iter().map(|&r| ids[r]).collect();
    labels.sort();
    labels.dedup();
    if labels.len() < 2 {
        sel.groups =
            format!("the fitted rows hold a single `{what}`: nothing to judge a selection on");
        return Ok((full, sel));
    }
    sel.applied = true;
    sel.groups = format!("{} `{what}` groups of the fitted rows", labels.len());
    // Linearised problem around the full fit: y = d − f(θ) + J·θ_free ≈ J·β.
    let free: Vec<usize> = (0..full.theta.len())
        .filter(|&k| full.ident.estimated[k])
        .collect();
    let n = rows.len();
    let mut j = DMatrix::<f64>::zeros(3 * n, free.len());
    let mut y = DVector::<f64>::zeros(3 * n);
    for (i, &r) in rows.iter().enumerate() {
        let pose = &data.poses[r];
        let s = data.setup[r];
        let f0 = crate::model_displacement(&data.machine, pose, s, &full.theta);
        for c in 0..3 {
            y[3 * i + c] = data.d_um[r][c] - f0[c];
        }
        for (col, &k) in free.iter().enumerate() {
            if k >= N_LOCATION && (k - N_LOCATION) / axcomp_kinematics::rotary::N_SETUP != s {
                continue;
            }
            let mut tp = full.theta.clone();
            let mut tm = full.theta.clone();
            tp[k] += 1.0;
            tm[k] -= 1.0;
            let a = crate::model_displacement(&data.machine, pose, s, &tp);
            let b = crate::model_displacement(&data.machine, pose, s, &tm);
            for c in 0..3 {
                j[(3 * i + c, col)] = (a[c] - b[c]) / 2.0;
            }
        }
    }
    for (col, &k) in free.iter().enumerate() {
        for i in 0..3 * n {
            y[i] += j[(i, col)] * full.theta[k];
        }
    }
    let group_of: Vec<usize> = rows.iter().map(|&r| ids[r]).collect();
    let cv = |cols: &[usize]| -> f64 { inner_cv(&j, &y, cols, &group_of, &labels) };
    let setup_cols: Vec<usize> = (0..free.len()).filter(|&c| free[c] >= N_LOCATION).collect();
    let current: Vec<usize> = (0..free.len()).collect();
    let full_cv = cv(&current);
    sel.inner_cv_full_um = full_cv;
    sel.inner_cv_nominal_um = cv(&setup_cols);
    // Cluster-robust flags: chunks of CHUNK consecutive rows of one group share their residuals' correlation
    // (an effect beyond the model is smooth along a path).
    let chunk_of: Vec<usize> = {
        let mut v = Vec::with_capacity(n);
        let mut count = 0usize;
        let mut cur = usize::MAX;
        let mut last_group = usize::MAX;
        for i in 0..n {
            if group_of[i] != last_group || count == CHUNK {
                cur = cur.wrapping_add(1);
                count = 0;
                last_group = group_of[i];
            }
            v.push(cur);
            count += 1;
        }
        v
    };
    if let Some((beta, sd)) = robust_fit(&j, &y, &current, &chunk_of) {
        for (i, &c) in current.iter().enumerate() {
            if free[c] < N_LOCATION {
                sel.robust_std
                    .push((free[c], sd[i], (beta[i] / sd[i]).abs() >= 2.0));
            }
        }
    }
    // In-sample RMS of the nominal kinematics with the set-up offsets only, against the full model's.
    let nominal_fit_rms = robust_fit(&j, &y, &setup_cols, &chunk_of)
        .map(|(beta, _)| {
            let mut a = DMatrix::<f64>::zeros(3 * n, setup_cols.len());
            for (cc, &col) in setup_cols.iter().enumerate() {
                a.set_column(cc, &j.column(col));
            }
            ((y - a * beta).norm_squared() / (3 * n) as f64).sqrt()
        })
        .unwrap_or(f64::INFINITY);
    sel.fit_rms_ratio = nominal_fit_rms / full.fit_rms_um;
    let removed: Vec<(usize, f64, f64)> =
        if sel.inner_cv_nominal_um < full_cv && sel.fit_rms_ratio < RATIO_LIMIT {
            sel.inner_cv_selected_um = sel.inner_cv_nominal_um;
            current
                .iter()
                .filter(|&&c| free[c] < N_LOCATION)
                .map(|&c| (free[c], full_cv, sel.inner_cv_nominal_um))
                .collect()
        } else {
            sel.inner_cv_selected_um = full_cv;
            Vec::new()
        };
    if removed.is_empty() {
        return Ok((full, sel));
    }
    let mut fix: Vec<Option<String>> = vec![None; N_LOCATION];
    for &(k, before, after) in &removed {
        let why = format!(
            "fixed at zero by the default selection: the nominal kinematics with the set-up offsets only predict the fitted rows better than the location errors do (leave-one-{what}-out RMS {after:.3} µm against {before:.3} µm) and the location errors explain little of them (in-sample RMS ratio {:.2} < {RATIO_LIMIT}): the estimates do not carry over to other {what}s, effects beyond the model?; --full-model estimates it",
            sel.fit_rms_ratio
        );
        fix[k] = Some(why.clone());
        sel.fixed.push((k, why));
    }
    let f = fit_fixed(data, rows, opts, shared, &fix)?;
    Ok((f, sel))
}

/// Consecutive poses of one group whose residuals are taken as correlated (cluster-robust std).
pub const CHUNK: usize = 8;

/// Least squares `y ≈ J[:, cols]·β` and the cluster-robust standard deviations of β (clusters `chunk`):
/// `(JᵀJ)⁻¹·(Σ_c J_cᵀ·r_c·r_cᵀ·J_c)·(JᵀJ)⁻¹` with the small-sample factor `G/(G−1)·(N−1)/(N−P)`.
fn robust_fit(
    j: &DMatrix<f64>,
    y: &DVector<f64>,
    cols: &[usize],
    chunk: &[usize],
) -> Option<(DVector<f64>, Vec<f64>)> {
    let n = chunk.len();
    let mut a = DMatrix::<f64>::zeros(3 * n, cols.len());
    for (cc, &col) in cols.iter().enumerate() {
        a.set_column(cc, &j.column(col));
    }
    let ata = a.transpose() * &a;
    let inv = ata.try_inverse()?;
    let beta = &inv * (a.transpose() * y);
    let r = y - &a * &beta;
    let n_chunks = chunk.iter().max().map_or(0, |m| m + 1);
    let mut meat = DMatrix::<f64>::zeros(cols.len(), cols.len());
    for g in 0..n_chunks {
        let mut s = DVector::<f64>::zeros(cols.len());
        for i in (0..n).filter(|&i| chunk[i] == g) {
            for c in 0..3 {
                let row = 3 * i + c;
                for cc in 0..cols.len() {
                    s[cc] += a[(row, cc)] * r[row];
                }
            }
        }
        meat += &s * s.transpose();
    }
    let (gn, nn, pp) = (n_chunks as f64, (3 * n) as f64, cols.len() as f64);
    if gn < 2.0 || nn <= pp {
        return None;
    }
    let factor = gn / (gn - 1.0) * (nn - 1.0) / (nn - pp);
    let cov = &inv * meat * &inv * factor;
    Some((
        beta,
        (0..cols.len())
            .map(|c| cov[(c, c)].max(0.0).sqrt())
            .collect(),
    ))
}

/// Leave-one-group-out RMS (µm) of the linear least-squares fit `y ≈ J[:, cols]·β`: each group predicted
/// from the others (minimum-norm solution where the others do not determine every column).
fn inner_cv(
    j: &DMatrix<f64>,
    y: &DVector<f64>,
    cols: &[usize],
    group: &[usize],
    labels: &[usize],
) -> f64 {
    let (mut sse, mut count) = (0.0, 0usize);
    for &g in labels {
        let train: Vec<usize> = (0..group.len()).filter(|&i| group[i] != g).collect();
        let test: Vec<usize> = (0..group.len()).filter(|&i| group[i] == g).collect();
        let use_cols = cols;
        let mut a = DMatrix::<f64>::zeros(3 * train.len(), use_cols.len());
        let mut b = DVector::<f64>::zeros(3 * train.len());
        for (ti, &i) in train.iter().enumerate() {
            for c in 0..3 {
                b[3 * ti + c] = y[3 * i + c];
                for (cc, &col) in use_cols.iter().enumerate() {
                    a[(3 * ti + c, cc)] = j[(3 * i + c, col)];
                }
            }
        }
        let beta = if use_cols.is_empty() {
            DVector::zeros(0)
        } else {
            let svd = a.svd(true, true);
            let smax = svd.singular_values.iter().fold(0.0f64, |m, v| m.max(*v));
            match svd.solve(&b, 1e-9 * smax.max(1e-300)) {
                Ok(x) => x,
                Err(_) => return f64::INFINITY,
            }
        };
        for &i in &test {
            for c in 0..3 {
                let mut pr = 0.0;
                for (cc, &col) in use_cols.iter().enumerate() {
                    pr += j[(3 * i + c, col)] * beta[cc];
                }
                sse += (y[3 * i + c] - pr).powi(2);
                count += 1;
            }
        }
    }
    (sse / count.max(1) as f64).sqrt()
}
