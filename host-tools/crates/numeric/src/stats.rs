//! Small statistics helpers: RMS, Student-t quantiles for confidence intervals.
//!
//! Glossary:
//! - **RMS**: root mean square of a residual or error series, `sqrt(Σ e² / n)`.
//! - **dof**: degrees of freedom of a residual variance estimate, `n − p`.
//! - **t quantile**: `t_{q, dof}`, the value a Student-t variable stays below with probability `q`; a two-sided
//!   95 % confidence interval is `estimate ± t_{0.975, dof} · standard error`.

/// Root mean square `sqrt(Σ x² / n)` of a slice, a vector or any iterator of values (by value or by
/// reference). NaN when there are no values: the RMS of nothing is undefined (it serialises as JSON `null`),
/// and a caller for whom "no rows" means "no error" says so where it calls. The sum of squares is taken in
/// order, then one division and one root.
pub fn rms<I>(values: I) -> f64
where
    I: IntoIterator,
    I::Item: std::borrow::Borrow<f64>,
{
    let (mut s, mut n) = (0.0, 0usize);
    for x in values {
        let x = *std::borrow::Borrow::<f64>::borrow(&x);
        s += x * x;
        n += 1;
    }
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

/// Mean of `v` (NaN for an empty slice).
pub fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.iter().sum::<f64>() / v.len() as f64
}

/// Population standard deviation of `v`.
pub fn std_dev(v: &[f64]) -> f64 {
    let m = mean(v);
    (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / v.len() as f64).sqrt()
}

/// RMS of `v` over the rows where `mask` is true.
pub fn rms_masked(v: &[f64], mask: &[bool]) -> f64 {
    let sel: Vec<f64> = v
        .iter()
        .zip(mask)
        .filter(|(_, m)| **m)
        .map(|(x, _)| *x)
        .collect();
    rms(&sel)
}

/// ln Γ(x) for x > 0 (Lanczos, g = 7, 9 terms; relative error < 1e-13).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection.
        let pi = core::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * core::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularized incomplete beta function I_x(a, b) (continued fraction, Numerical Recipes `betacf`).
pub fn inc_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    let front = ln_front.exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_cf(a, b, x) / a
    } else {
        1.0 - front * beta_cf(b, a, 1.0 - x) / b
    }
}

fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..300 {
        let m = m as f64;
        let m2 = 2.0 * m;
        // Even step, then odd step (modified Lentz: each returns the factor d·c of the convergent).
        h *= lentz_step(m * (b - m) * x / ((qam + m2) * (a + m2)), &mut c, &mut d);
        let del = lentz_step(
            -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2)),
            &mut c,
            &mut d,
        );
        h *= del;
        if (del - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// One step of the modified Lentz method for the continued fraction term `aa`: updates `c` and `d`
/// (kept away from 0 by `TINY`) and returns the convergent's factor `d·c`.
fn lentz_step(aa: f64, c: &mut f64, d: &mut f64) -> f64 {
    const TINY: f64 = 1e-300;
    *d = 1.0 + aa * *d;
    if d.abs() < TINY {
        *d = TINY;
    }
    *c = 1.0 + aa / *c;
    if c.abs() < TINY {
        *c = TINY;
    }
    *d = 1.0 / *d;
    *d * *c
}

/// Student-t cumulative distribution function with `dof` degrees of freedom.
pub fn student_t_cdf(t: f64, dof: f64) -> f64 {
    let x = dof / (dof + t * t);
    let tail = 0.5 * inc_beta(dof / 2.0, 0.5, x);
    if t >= 0.0 { 1.0 - tail } else { tail }
}

/// Student-t quantile `t_{q, dof}` (bisection on the CDF to 1e-12), `q` in (0, 1).
pub fn student_t_quantile(q: f64, dof: f64) -> f64 {
    assert!(
        q > 0.0 && q < 1.0 && dof > 0.0,
        "student_t_quantile: q in (0,1), dof > 0"
    );
    let (mut lo, mut hi) = (-1e4, 1e4);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if student_t_cdf(mid, dof) < q {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-12 {
            break;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantiles_match_tables() {
        // Reference: standard Student-t tables (e.g. NIST/SEMATECH e-Handbook 1.3.6.7.2), 3 decimals given,
        // tolerance 1e-3.
        for (dof, want) in [
            (1.0, 12.706),
            (2.0, 4.303),
            (3.0, 3.182),
            (5.0, 2.571),
            (10.0, 2.228),
            (30.0, 2.042),
        ] {
            let got = student_t_quantile(0.975, dof);
            assert!(
                (got - want).abs() < 1e-3,
                "t(0.975,{dof}) = {got}, table {want}"
            );
        }
    }

    #[test]
    fn ln_gamma_factorials() {
        // Γ(n) = (n-1)!; tolerance 1e-10 relative.
        let mut f = 1.0f64;
        for n in 1..15 {
            if n > 1 {
                f *= (n - 1) as f64;
            }
            assert!((ln_gamma(n as f64) - f.ln()).abs() < 1e-10 * f.ln().abs().max(1.0));
        }
    }
}

/// Median of `v` (sorted in place with `total_cmp`; mean of the two middle values for an even count; NaN
/// when empty).
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

/// Upper median of `v`: sorted in place with `total_cmp`, the value at index n/2 (for an even count the
/// upper of the two middle values, always one of the values); NaN when empty. The summaries' "typical
/// value" (median time step, grid gap, time per case), where [`median`] would average two values.
pub fn upper_median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Sample variance `Σ(x − m)² / (n − 1)` about the mean `m` (the ISO 230-2 estimator s², the paired
/// t-test's); needs n ≥ 2 (NaN or ∞ otherwise).
pub fn sample_variance(x: &[f64], m: f64) -> f64 {
    x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (x.len() - 1) as f64
}

/// `P(F > f)` for an F(d1, d2) variable (survival function, through [`inc_beta`]).
pub fn f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    if f.is_nan() || f <= 0.0 {
        return 1.0;
    }
    if !f.is_finite() {
        return 0.0;
    }
    inc_beta(d2 / 2.0, d1 / 2.0, d2 / (d2 + d1 * f))
}

/// `P(T > t)` for a Student t variable with `nu` degrees of freedom (one-sided upper tail).
pub fn t_sf(t: f64, nu: f64) -> f64 {
    if t.is_nan() {
        return 1.0;
    }
    // P(T > t) = P(T < −t): the CDF evaluates the lower tail directly from the incomplete beta for
    // negative arguments, so small upper tails keep their precision.
    student_t_cdf(-t, nu)
}

#[cfg(test)]
mod distribution_tests {
    use super::*;

    #[test]
    fn tails_match_tables() {
        // References: F(2, d2) has the closed form sf = (1 + 2f/d2)^(−d2/2) → 1.12^−25 (tolerance 1e-9);
        // Student t table pt(2.0, 10, lower=FALSE) = 0.036694 (tolerance 1e-5 absolute).
        let f_ref = 1.12f64.powf(-25.0);
        assert!((f_sf(3.0, 2.0, 50.0) - f_ref).abs() < 1e-9);
        assert!((t_sf(2.0, 10.0) - 0.036694).abs() < 1e-5);
        assert!((t_sf(-2.0, 10.0) - (1.0 - 0.036694)).abs() < 1e-5);
    }

    #[test]
    fn rms_conventions_and_median() {
        // Reference: hand arithmetic; exact.
        assert_eq!(
            rms([3.0, 4.0].into_iter().chain([0.0; 0])),
            (12.5f64).sqrt()
        );
        // The same value from a slice, a vector by reference and an iterator by value: one function.
        assert_eq!(rms(&[3.0, 4.0][..]), (12.5f64).sqrt());
        assert_eq!(rms(&vec![3.0, 4.0]), (12.5f64).sqrt());
        // No values: NaN (documented), from every form.
        assert!(rms(std::iter::empty::<f64>()).is_nan());
        assert!(rms(&[0.0f64; 0][..]).is_nan());
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
        // Upper median: the value at n/2 after sorting; sample variance of {1, 2, 3, 6}: mean 3,
        // Σ(x − 3)² = 14, /3 (hand-computed; exact in binary to 1 ulp).
        assert_eq!(upper_median(&mut [4.0, 1.0, 2.0, 3.0]), 3.0);
        assert!(upper_median(&mut []).is_nan());
        assert!((sample_variance(&[1.0, 2.0, 3.0, 6.0], 3.0) - 14.0 / 3.0).abs() < 1e-15);
    }
}
