//! Least-squares helpers of the verdict rule: fits on the training rows, residual sums, column views,
//! the variant search by training BIC, and the progress lines.

use super::types::CandidateVariant;
use crate::lsq::{self, Projector};

pub(crate) struct Fitted {
    pub(crate) fit: lsq::LsFit,
    pub(crate) resid: Vec<f64>,
}

pub(crate) fn fit_all<C: AsRef<[f64]>>(cols: &[C], y: &[f64], train: &[usize]) -> Fitted {
    let fit = lsq::fit(cols, y, train);
    let resid = (0..y.len()).map(|i| y[i] - fit.predict(cols, i)).collect();
    Fitted { fit, resid }
}

/// Sum of squared residuals on `rows` of a fit on `rows`.
pub(crate) fn rss_on<C: AsRef<[f64]>>(cols: &[C], y: &[f64], rows: &[usize]) -> f64 {
    let fit = lsq::fit(cols, y, rows);
    rows.iter()
        .map(|&i| (y[i] - fit.predict(cols, i)).powi(2))
        .sum()
}

/// The base columns followed by `extra`, by reference (no copy of the data).
pub(crate) fn with_extra<'a>(base: &'a [Vec<f64>], extra: &'a [Vec<f64>]) -> Vec<&'a [f64]> {
    base.iter()
        .chain(extra)
        .map(|c| c.as_slice())
        .collect::<Vec<&[f64]>>()
}

pub(super) fn max_corr(r: &[f64], cols: &[Vec<f64>]) -> f64 {
    let n = r.len() as f64;
    let mr = r.iter().sum::<f64>() / n;
    let sr = r.iter().map(|v| (v - mr).powi(2)).sum::<f64>().sqrt();
    cols.iter()
        .map(|c| {
            let mc = c.iter().sum::<f64>() / n;
            let sc = c.iter().map(|v| (v - mc).powi(2)).sum::<f64>().sqrt();
            let cov: f64 = r.iter().zip(c).map(|(a, b)| (a - mr) * (b - mc)).sum();
            if sr > 0.0 && sc > 0.0 {
                (cov / (sr * sc)).abs()
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
}

pub(super) fn restrict(cols: &[Vec<f64>], rows: &[usize]) -> Vec<Vec<f64>> {
    cols.iter()
        .map(|c| rows.iter().map(|&i| c[i]).collect())
        .collect()
}

pub(crate) fn ss(v: &[f64], rows: &[usize]) -> f64 {
    rows.iter().map(|&i| v[i] * v[i]).sum()
}

pub(crate) fn lag1(v: &[f64], order: &[usize]) -> f64 {
    if order.len() < 3 {
        return 0.0;
    }
    let m = order.iter().map(|&i| v[i]).sum::<f64>() / order.len() as f64;
    let den: f64 = order.iter().map(|&i| (v[i] - m).powi(2)).sum();
    let num: f64 = order
        .windows(2)
        .map(|w| (v[w[0]] - m) * (v[w[1]] - m))
        .sum();
    if den > 0.0 { num / den } else { 0.0 }
}

/// Elapsed-time progress on stderr (when asked for).
pub(crate) struct Progress {
    pub(crate) on: bool,
    pub(crate) t0: std::time::Instant,
}

impl Progress {
    pub(crate) fn step(&self, what: impl FnOnce() -> String) {
        if self.on {
            eprintln!(
                "[{:>6.1} s] diagnose: {}",
                self.t0.elapsed().as_secs_f64(),
                what()
            );
        }
    }
}

/// Best variant of `variants` by the training BIC of the whole refit, given the projector and the
/// training residual `r` of the other columns: maximises `n·ln(RSS₀/(RSS₀ − drop)) − k·ln n` (`drop` =
/// exact refit RSS drop). The variants' columns are built one at a time. Returns (index, drop).
pub fn select_variant(
    variants: &[CandidateVariant],
    proj: &Projector,
    r: &[f64],
    train: &[usize],
) -> (usize, f64) {
    let n = train.len() as f64;
    let rss0 = lsq::dot(r, r);
    let mut best = (0, f64::NEG_INFINITY, 0.0);
    for (k, v) in variants.iter().enumerate() {
        let d = proj.rss_drop(r, &v.columns_on(train)).clamp(0.0, rss0);
        let rest = (rss0 - d).max(rss0 * 1e-15).max(1e-300);
        let crit = n * (rss0.max(1e-300) / rest).ln() - v.n_params as f64 * n.ln();
        if crit > best.1 {
            best = (k, crit, d);
        }
    }
    (best.0, best.2)
}

/// Best variant of `variants` given the other columns `others` (fitted on `train`).
pub fn best_variant(
    variants: &[CandidateVariant],
    others: &[Vec<f64>],
    y: &[f64],
    train: &[usize],
) -> (usize, f64) {
    let proj = Projector::new(others, train);
    let base = fit_all(others, y, train);
    let r: Vec<f64> = train.iter().map(|&i| base.resid[i]).collect();
    select_variant(variants, &proj, &r, train)
}
