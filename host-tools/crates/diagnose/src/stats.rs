//! Distribution tails for the nested-model tests (F, Student t) and small descriptive helpers.
//!
//! Glossary: **sf** = survival function `P(X > x)`. The regularised incomplete beta function, the F and
//! Student-t tails are the host numeric layer's ([`axcomp_numeric::stats`]: Numerical
//! Recipes continued fraction, Lanczos `ln Γ`); this module adds the paired test on top.

use axcomp_numeric::stats::t_sf;

/// One-sided paired test that `mean(d) > 0`: returns (t statistic, p-value).
pub fn paired_t(d: &[f64]) -> (f64, f64) {
    let n = d.len();
    if n < 2 {
        return (0.0, 1.0);
    }
    let m = axcomp_numeric::stats::mean(d);
    let var = axcomp_numeric::stats::sample_variance(d, m);
    if var <= 0.0 {
        return if m > 0.0 {
            (f64::INFINITY, 0.0)
        } else {
            (0.0, 1.0)
        };
    }
    let t = m / (var / n as f64).sqrt();
    (t, t_sf(t, (n - 1) as f64))
}
