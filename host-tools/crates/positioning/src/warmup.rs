//! Warm-up drift: the part of the deviation that moves with the axis's warm-up, fitted together with the
//! static table and judged on runs the fit never saw.
//!
//! Glossary:
//! - *age*: time since the axis was energised (s, or any unit the caller keeps consistent), per row.
//! - *warm-up state*: w(age) = 1 − exp(−age/τ), 0 cold … 1 warm; the first-order response of the motor's
//!   temperature to a steady heat input switched on at age 0, with time constant τ.
//! - *drift*: k, the deviation change (µm) from cold (w = 0) to warm (w = 1). The model is
//!   `deviation = table(x, direction) + k·(w − w_ref)`, position-independent (the contract's
//!   `thermal_lag` with one input).
//! - *reference state* w_ref: the mean warm-up state of the fitting rows; the table holds the deviation at
//!   w_ref, so the table alone is as good as a static fit, and the drift term corrects around it.
//! - *group*: the rows of one target approached in one direction; the drift is estimated within groups
//!   (each group keeps its own mean), which needs targets repeated over runs (ISO 230-2 runs).
//!
//! How it is judged (nothing here sees the run it predicts): for each run r, τ is chosen by
//! leave-one-run-out among the *other* runs, k and w_ref are fitted on them, the static models are fitted
//! (and chosen, by their own cross-validation) on their deviations minus the drift, and run r is predicted
//! as `table(x, d) + k·(w(age) − w_ref)`. The drive applies the same sum: the table from the positioning
//! image and the drift as one lagged input of the thermo-force term (see [`WarmupModel`]).

use std::collections::HashMap;

use thiserror::Error;

use crate::fit::{FitError, FitOptions, FitResult, Observation, fit};
use crate::guard::{self, GuardVerdict};
use axcomp_numeric::stats::rms;

/// Candidate time constants, as multiples of the age span of the data (geometric, factor √2).
pub const TAU_SPAN_FACTORS: [f64; 13] = [
    0.125, 0.177, 0.25, 0.354, 0.5, 0.707, 1.0, 1.414, 2.0, 2.828, 4.0, 5.657, 8.0,
];

/// The warm-up state w(age) = 1 − exp(−age/τ) (0 for age ≤ 0).
pub fn state(age: f64, tau: f64) -> f64 {
    if age <= 0.0 {
        0.0
    } else {
        -(-age / tau).exp_m1()
    }
}

/// A fitted warm-up drift.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct WarmupModel {
    /// Time constant τ, in the unit of the ages.
    pub tau: f64,
    /// k: deviation change from cold to warm, µm.
    pub drift_um: f64,
    /// Mean warm-up state of the fitting rows (the table holds the deviation at this state).
    pub state_ref: f64,
    /// Leave-one-run-out RMS (µm) of the per-target model with drift for every candidate τ, as `(τ, rms)`.
    pub tau_scores: Vec<(f64, f64)>,
}

impl WarmupModel {
    /// The drift term at `age`: k·(w(age) − w_ref), µm.
    pub fn offset_um(&self, age: f64) -> f64 {
        self.drift_um * (state(age, self.tau) - self.state_ref)
    }
}

/// Why a warm-up drift cannot be fitted.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum WarmupError {
    #[error("row {row}: the warm-up age {age} is not a finite number ≥ 0")]
    BadAge { row: usize, age: f64 },
    #[error("{ages} ages for {rows} rows")]
    Length { ages: usize, rows: usize },
    #[error(
        "a warm-up drift needs targets measured repeatedly at different ages (ISO 230-2 runs); no target is"
    )]
    NoRepeats,
    #[error("a warm-up drift needs at least 3 runs to choose its time constant, got {0}")]
    TooFewRuns(usize),
    #[error(transparent)]
    Fit(#[from] FitError),
}

/// Group id per row: (target, direction).
fn groups(obs: &[Observation]) -> Vec<usize> {
    let mut index: HashMap<(i64, i8), usize> = HashMap::new();
    obs.iter()
        .map(|o| {
            let key = ((o.target_mm * 1e6).round() as i64, o.direction.signum());
            let n = index.len();
            *index.entry(key).or_insert(n)
        })
        .collect()
}

/// Within-group least squares of deviation on w over `rows`: k, or None when w does not vary within groups.
fn within_group_drift(
    obs: &[Observation],
    w: &[f64],
    group: &[usize],
    rows: &[usize],
) -> Option<f64> {
    let n_groups = group.iter().copied().max().map_or(0, |m| m + 1);
    let mut sum = vec![(0.0f64, 0.0f64, 0usize); n_groups];
    for &i in rows {
        let s = &mut sum[group[i]];
        s.0 += w[i];
        s.1 += obs[i].deviation_um;
        s.2 += 1;
    }
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for &i in rows {
        let (sw, sy, n) = sum[group[i]];
        let dw = w[i] - sw / n as f64;
        sxy += dw * (obs[i].deviation_um - sy / n as f64);
        sxx += dw * dw;
    }
    (sxx > 1e-12 * rows.len() as f64).then(|| sxy / sxx)
}

/// Leave-one-run-out RMS, over `rows`, of the per-group-mean model with a drift of time constant `tau`.
fn per_group_cv(
    obs: &[Observation],
    age: &[f64],
    group: &[usize],
    rows: &[usize],
    tau: f64,
) -> f64 {
    let w: Vec<f64> = age.iter().map(|&a| state(a, tau)).collect();
    let mut runs: Vec<i64> = rows.iter().map(|&i| obs[i].run).collect();
    runs.sort_unstable();
    runs.dedup();
    let n_groups = group.iter().copied().max().map_or(0, |m| m + 1);
    let mut residuals = Vec::with_capacity(rows.len());
    for &r in &runs {
        let train: Vec<usize> = rows.iter().copied().filter(|&i| obs[i].run != r).collect();
        let k = within_group_drift(obs, &w, group, &train).unwrap_or(0.0);
        let mut mean = vec![(0.0f64, 0usize); n_groups];
        for &i in &train {
            mean[group[i]].0 += obs[i].deviation_um - k * w[i];
            mean[group[i]].1 += 1;
        }
        for &i in rows.iter().filter(|&&i| obs[i].run == r) {
            let (s, n) = mean[group[i]];
            if n > 0 {
                residuals.push(obs[i].deviation_um - (s / n as f64 + k * w[i]));
            }
        }
    }
    rms(residuals)
}

/// Fits τ (leave-one-run-out over `rows`), k and w_ref on `rows`.
fn fit_model(obs: &[Observation], age: &[f64], group: &[usize], rows: &[usize]) -> WarmupModel {
    let lo = rows.iter().map(|&i| age[i]).fold(f64::INFINITY, f64::min);
    let hi = rows
        .iter()
        .map(|&i| age[i])
        .fold(f64::NEG_INFINITY, f64::max);
    // The span of ages seen, and at least the oldest age (a run measured long after energising).
    let span = (hi - lo).max(hi * 0.25).max(f64::MIN_POSITIVE);
    let tau_scores: Vec<(f64, f64)> = TAU_SPAN_FACTORS
        .iter()
        .map(|f| {
            let tau = f * span;
            (tau, per_group_cv(obs, age, group, rows, tau))
        })
        .collect();
    // Lowest score; ties (within 0.1 %) go to the longer τ (the gentler extrapolation).
    let best = tau_scores
        .iter()
        .filter(|s| s.1.is_finite())
        .map(|s| s.1)
        .fold(f64::INFINITY, f64::min);
    let tau = tau_scores
        .iter()
        .rev()
        .find(|s| s.1 <= best * 1.001)
        .map_or(span, |s| s.0);
    let w: Vec<f64> = age.iter().map(|&a| state(a, tau)).collect();
    let drift_um = within_group_drift(obs, &w, group, rows).unwrap_or(0.0);
    let state_ref = rows.iter().map(|&i| w[i]).sum::<f64>() / rows.len().max(1) as f64;
    WarmupModel {
        tau,
        drift_um,
        state_ref,
        tau_scores,
    }
}

/// The observations of `rows` with the drift term removed (the static part).
fn without_drift(
    obs: &[Observation],
    age: &[f64],
    rows: &[usize],
    m: &WarmupModel,
) -> Vec<Observation> {
    rows.iter()
        .map(|&i| Observation {
            deviation_um: obs[i].deviation_um - m.offset_um(age[i]),
            ..obs[i]
        })
        .collect()
}

/// Everything [`fit_with_warmup`] found.
#[derive(Debug, Clone)]
pub struct WarmupFit {
    /// The drift fitted on all rows.
    pub warmup: WarmupModel,
    /// The static part: chosen and fitted (by [`fit`]) on all rows minus the drift. Its `cv_*` fields describe
    /// that static fit on drift-free data; the figures of the whole model are below.
    pub static_part: FitResult,
    /// Per row: table + drift from a model that never saw the row's run.
    pub cv_predictions: Vec<f64>,
    /// Per row: its run's fold index.
    pub fold_of_row: Vec<usize>,
    /// RMS of deviation − cv_prediction.
    pub cv_rms_um: f64,
    /// τ chosen in each outer fold (nested choice), in fold order.
    pub tau_per_fold: Vec<f64>,
    /// Do-no-harm verdict on the cross-validated predictions.
    pub guard: GuardVerdict,
    /// The fitted drift between the youngest and the oldest row: k·(w(age_max) − w(age_min)), µm.
    pub drift_over_data_um: f64,
}

/// Fits a static table plus a warm-up drift, and judges the whole procedure by leave-one-run-out.
///
/// `age[i]` is row i's time since the axis was energised. The static models are those of [`fit`], chosen
/// by its own cross-validation inside each outer fold.
pub fn fit_with_warmup(
    obs: &[Observation],
    age: &[f64],
    opts: &FitOptions,
) -> Result<WarmupFit, WarmupError> {
    if age.len() != obs.len() {
        return Err(WarmupError::Length {
            ages: age.len(),
            rows: obs.len(),
        });
    }
    if let Some((row, &a)) = age
        .iter()
        .enumerate()
        .find(|(_, a)| !(a.is_finite() && **a >= 0.0))
    {
        return Err(WarmupError::BadAge { row, age: a });
    }
    let mut runs: Vec<i64> = obs.iter().map(|o| o.run).collect();
    runs.sort_unstable();
    runs.dedup();
    if runs.len() < 3 {
        return Err(WarmupError::TooFewRuns(runs.len()));
    }
    let group = groups(obs);
    let all: Vec<usize> = (0..obs.len()).collect();
    {
        // Some group must hold rows of different ages.
        let mut seen: HashMap<usize, f64> = HashMap::new();
        let repeated = all.iter().any(|&i| match seen.get(&group[i]) {
            Some(&a) => a != age[i],
            None => {
                seen.insert(group[i], age[i]);
                false
            }
        });
        if !repeated {
            return Err(WarmupError::NoRepeats);
        }
    }
    let fold_of_row: Vec<usize> = obs
        .iter()
        .map(|o| runs.binary_search(&o.run).unwrap_or(0))
        .collect();
    let mut cv_predictions = vec![f64::NAN; obs.len()];
    let mut tau_per_fold = Vec::with_capacity(runs.len());
    for (f, _) in runs.iter().enumerate() {
        let train: Vec<usize> = all
            .iter()
            .copied()
            .filter(|&i| fold_of_row[i] != f)
            .collect();
        let test: Vec<usize> = all
            .iter()
            .copied()
            .filter(|&i| fold_of_row[i] == f)
            .collect();
        let m = fit_model(obs, age, &group, &train);
        let static_fit = fit(&without_drift(obs, age, &train, &m), opts)?;
        for &i in &test {
            cv_predictions[i] = static_fit
                .curves
                .predict(obs[i].target_mm, obs[i].direction)
                + m.offset_um(age[i]);
        }
        tau_per_fold.push(m.tau);
    }
    let warmup = fit_model(obs, age, &group, &all);
    let static_part = fit(&without_drift(obs, age, &all, &warmup), opts)?;
    let dev: Vec<f64> = obs.iter().map(|o| o.deviation_um).collect();
    let cv_rms_um = rms(dev.iter().zip(&cv_predictions).map(|(d, p)| d - p));
    let guard = guard::judge(
        &dev,
        &cv_predictions,
        &fold_of_row,
        opts.improvement_ratio,
        opts.runs_improved_fraction,
        "leave-one-run-out",
    );
    let age_min = age.iter().copied().fold(f64::INFINITY, f64::min);
    let age_max = age.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let drift_over_data_um = warmup.offset_um(age_max) - warmup.offset_um(age_min);
    Ok(WarmupFit {
        drift_over_data_um,
        warmup,
        static_part,
        cv_predictions,
        fold_of_row,
        cv_rms_um,
        tau_per_fold,
        guard,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::tests::Noise;

    /// ISO-style runs: 11 targets × 2 directions × `runs`, a pitch pattern, a reversal, and a warm-up
    /// drift of `k` µm with time constant `tau` (ages in run periods, run r measured at age r − 0.5).
    fn runs(runs: i64, k: f64, tau: f64, sigma: f64, seed: u64) -> (Vec<Observation>, Vec<f64>) {
        let mut noise = Noise(seed);
        let (mut obs, mut age) = (Vec::new(), Vec::new());
        for r in 1..=runs {
            for d in [1i8, -1] {
                for t in 0..11 {
                    let x = -50.0 + 10.0 * t as f64;
                    let a = r as f64 - 0.5;
                    let truth = 8.0 * (x / 30.0).sin() + 2.5 * f64::from(d) + k * state(a, tau);
                    obs.push(Observation {
                        target_mm: x,
                        direction: d,
                        run: r,
                        deviation_um: truth + sigma * noise.normal(),
                    });
                    age.push(a);
                }
            }
        }
        (obs, age)
    }

    #[test]
    fn state_is_a_first_order_step_response() {
        assert_eq!(state(0.0, 2.0), 0.0);
        assert_eq!(state(-1.0, 2.0), 0.0);
        // Reference: 1 − e^−1 = 0.632120558828558 (to 1e-15).
        assert!((state(2.0, 2.0) - 0.632_120_558_828_558).abs() < 1e-15);
        assert!((state(1e9, 2.0) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn recovers_a_known_drift_and_judges_it_at_the_noise_floor() {
        // Truth: k = −12 µm, τ = 3 run periods, σ = 0.5 µm, 8 runs.
        let (obs, age) = runs(8, -12.0, 3.0, 0.5, 7);
        let f = fit_with_warmup(&obs, &age, &FitOptions::default()).unwrap();
        // τ on a √2 grid: the chosen one within a factor 2 of the truth; k then absorbs the shape.
        assert!(
            f.warmup.tau > 1.5 && f.warmup.tau < 6.0,
            "τ {}",
            f.warmup.tau
        );
        // The drift over the campaign (age 0.5 → 7.5) within 5 % of the truth's.
        let truth_span = -12.0 * (state(7.5, 3.0) - state(0.5, 3.0));
        let fitted_span = f.warmup.offset_um(7.5) - f.warmup.offset_um(0.5);
        assert!(
            (fitted_span - truth_span).abs() < 0.05 * truth_span.abs(),
            "drift over the campaign {fitted_span} vs truth {truth_span}"
        );
        // Leave-one-run-out with drift: within 1.25 σ (the per-target model's own n/(n−1) inflation and
        // the extrapolation to the first and last run), while the static fit is far above.
        let static_cv = fit(&obs, &FitOptions::default()).unwrap().cv_rms_um;
        println!(
            "truth τ 3, k −12 µm, σ 0.5 µm: fitted τ {:.2}, drift over the campaign {fitted_span:.3} µm \
             (truth {truth_span:.3}), CV {:.3} µm with drift, {static_cv:.3} µm static",
            f.warmup.tau, f.cv_rms_um
        );
        assert!(f.cv_rms_um < 1.25 * 0.5, "cv {}", f.cv_rms_um);
        assert!(static_cv > 4.0 * f.cv_rms_um, "static {static_cv}");
        assert!(f.guard.passed);
        assert!(f.cv_predictions.iter().all(|p| p.is_finite()));
    }

    #[test]
    fn no_drift_means_a_small_drift() {
        let (obs, age) = runs(6, 0.0, 3.0, 0.5, 11);
        let f = fit_with_warmup(&obs, &age, &FitOptions::default()).unwrap();
        let span = f.warmup.offset_um(5.5) - f.warmup.offset_um(0.5);
        // Reference: the standard error of a within-group slope here is ~0.1 µm; allow 4×.
        assert!(span.abs() < 0.4, "fitted drift over the campaign {span} µm");
    }

    #[test]
    fn bad_ages_and_unrepeated_targets_are_errors() {
        let (obs, mut age) = runs(4, -5.0, 2.0, 0.5, 3);
        age[5] = f64::NAN;
        assert!(matches!(
            fit_with_warmup(&obs, &age, &FitOptions::default()),
            Err(WarmupError::BadAge { row: 5, .. })
        ));
        let (obs, age) = runs(4, -5.0, 2.0, 0.5, 3);
        assert!(matches!(
            fit_with_warmup(&obs, &age[1..], &FitOptions::default()),
            Err(WarmupError::Length { .. })
        ));
        let flat = vec![1.0; obs.len()];
        assert_eq!(
            fit_with_warmup(&obs, &flat, &FitOptions::default()).unwrap_err(),
            WarmupError::NoRepeats
        );
        let two: Vec<Observation> = obs.iter().copied().filter(|o| o.run <= 2).collect();
        assert_eq!(
            fit_with_warmup(&two, &age[..two.len()], &FitOptions::default()).unwrap_err(),
            WarmupError::TooFewRuns(2)
        );
    }
}
