//! Distribution tails for the nested-model tests (F, Student t) and small descriptive helpers.
//!
//! Glossary: **sf** = survival function `P(X > x)`. The regularised incomplete beta function and the
//! Student-t CDF are `axcomp-thermal`'s ([`axcomp_thermal::stats`]: Numerical Recipes continued fraction,
//! Lanczos `ln Γ`); this module adds the F tail, the one-sided t tail and the paired test on top. `rms`
//! here takes any iterator and is 0 for no values (the thermal one takes a slice and is NaN).

pub use axcomp_thermal::stats::inc_beta;
use axcomp_thermal::stats::student_t_cdf;

/// `P(F > f)` for an F(d1, d2) variable.
pub fn f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    if f.is_nan() || f <= 0.0 {
        return 1.0;
    }
    if !f.is_finite() {
        return 0.0;
    }
    inc_beta(d2 / 2.0, d1 / 2.0, d2 / (d2 + d1 * f))
}

/// `P(T > t)` for a Student t variable with `nu` degrees of freedom (one-sided).
pub fn t_sf(t: f64, nu: f64) -> f64 {
    if t.is_nan() {
        return 1.0;
    }
    // P(T > t) = P(T < −t): the thermal crate's CDF evaluates the lower tail directly from the
    // incomplete beta for negative arguments, so small upper tails keep their precision.
    student_t_cdf(-t, nu)
}

pub fn rms(v: impl IntoIterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in v {
        s += x * x;
        n += 1;
    }
    if n == 0 { 0.0 } else { (s / n as f64).sqrt() }
}

pub fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// One-sided paired test that `mean(d) > 0`: returns (t statistic, p-value).
pub fn paired_t(d: &[f64]) -> (f64, f64) {
    let n = d.len();
    if n < 2 {
        return (0.0, 1.0);
    }
    let m = d.iter().sum::<f64>() / n as f64;
    let var = d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tails_match_tables() {
        // References: F(2, d2) has the closed form sf = (1 + 2f/d2)^(−d2/2) → 1.12^−25; Student t table
        // pt(2.0, 10, lower=FALSE) = 0.036694. Tolerance 1e-5 absolute.
        let f_ref = 1.12f64.powf(-25.0);
        assert!(
            (f_sf(3.0, 2.0, 50.0) - f_ref).abs() < 1e-9,
            "{} vs {f_ref}",
            f_sf(3.0, 2.0, 50.0)
        );
        assert!(
            (t_sf(2.0, 10.0) - 0.036694).abs() < 1e-5,
            "{}",
            t_sf(2.0, 10.0)
        );
        assert!((t_sf(-2.0, 10.0) - (1.0 - 0.036694)).abs() < 1e-5);
    }
}
