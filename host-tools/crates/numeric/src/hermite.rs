//! The cubic Hermite segment: the cubic through two end values and end slopes.
//!
//! Glossary: *segment parameter* t ∈ [0, 1] across one segment; *scaled slope* the slope times the
//! segment's length (dy/dt).

/// Coefficients `[c0, c1, c2, c3]` of `c0 + c1 t + c2 t² + c3 t³` on t ∈ [0, 1] with value `y0` and
/// scaled slope `m0` at t = 0, value `y1` and scaled slope `m1` at t = 1.
pub fn cubic_hermite(y0: f64, m0: f64, y1: f64, m1: f64) -> [f64; 4] {
    [
        y0,
        m0,
        3.0 * (y1 - y0) - 2.0 * m0 - m1,
        2.0 * (y0 - y1) + m0 + m1,
    ]
}

#[cfg(test)]
mod tests {
    use super::cubic_hermite;

    /// The cubic meets both ends' values and slopes (reference: the definition; tolerance 1e-12), and
    /// reproduces a cubic exactly from its own ends (t³ − 2t² + 0.5t + 3).
    #[test]
    fn meets_the_end_values_and_slopes() {
        let p = |t: f64| t.powi(3) - 2.0 * t * t + 0.5 * t + 3.0;
        let dp = |t: f64| 3.0 * t * t - 4.0 * t + 0.5;
        let c = cubic_hermite(p(0.0), dp(0.0), p(1.0), dp(1.0));
        let expected = [3.0, 0.5, -2.0, 1.0];
        for (a, b) in c.iter().zip(expected) {
            assert!((a - b).abs() < 1e-12, "{c:?}");
        }
        let c = cubic_hermite(1.5, -0.25, -2.0, 4.0);
        let value = |t: f64| c[0] + c[1] * t + c[2] * t * t + c[3] * t * t * t;
        let slope = |t: f64| c[1] + 2.0 * c[2] * t + 3.0 * c[3] * t * t;
        assert!((value(0.0) - 1.5).abs() < 1e-12 && (slope(0.0) + 0.25).abs() < 1e-12);
        assert!((value(1.0) + 2.0).abs() < 1e-12 && (slope(1.0) - 4.0).abs() < 1e-12);
    }
}
