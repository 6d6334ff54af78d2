//! The uniform cubic B-spline basis.
//!
//! Glossary: `k` uniform segments over `[lo, hi]` give `k + 3` basis functions; at a point in segment `j`
//! with local coordinate `t ∈ [0, 1]` the four non-zero functions `j … j+3` are the uniform cubic
//! B-spline weights `(1−t)³/6, (3t³ − 6t² + 4)/6, (−3t³ + 3t² + 3t + 1)/6, t³/6` (they sum to 1).
//! Points outside `[lo, hi]` are clamped to the ends.

/// The four non-zero uniform cubic B-spline weights at local coordinate `t` of a segment.
pub fn cubic_weights(t: f64) -> [f64; 4] {
    [
        (1.0 - t).powi(3) / 6.0,
        (3.0 * t.powi(3) - 6.0 * t * t + 4.0) / 6.0,
        (-3.0 * t.powi(3) + 3.0 * t * t + 3.0 * t + 1.0) / 6.0,
        t.powi(3) / 6.0,
    ]
}

/// Segment index and local coordinate of `x` on `k` uniform segments over `[lo, hi]` (clamped).
pub fn locate(x: f64, lo: f64, hi: f64, k: usize) -> (usize, f64) {
    let h = (hi - lo) / k as f64;
    let u = ((x - lo) / h).clamp(0.0, k as f64);
    let j = (u.floor() as usize).min(k - 1);
    (j, u - j as f64)
}

/// Uniform cubic B-spline basis (`k` segments → `k + 3` columns, one value per point of `x`).
pub fn uniform_cubic_basis(x: &[f64], lo: f64, hi: f64, k: usize) -> Vec<Vec<f64>> {
    let mut cols = vec![vec![0.0; x.len()]; k + 3];
    for (i, &xi) in x.iter().enumerate() {
        let (j, t) = locate(xi, lo, hi, k);
        for (m, bm) in cubic_weights(t).iter().enumerate() {
            cols[j + m][i] = *bm;
        }
    }
    cols
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partition_of_unity_and_knot_values() {
        // Reference: the uniform cubic B-spline takes 1/6, 2/3, 1/6 at a knot and sums to 1 everywhere;
        // tolerance 1e-12.
        let x: Vec<f64> = (0..=40).map(|i| -2.0 + 0.1 * i as f64).collect();
        let b = uniform_cubic_basis(&x, -1.0, 1.0, 5);
        for i in 0..x.len() {
            let s: f64 = b.iter().map(|c| c[i]).sum();
            assert!((s - 1.0).abs() < 1e-12);
        }
        let w = cubic_weights(0.0);
        assert!((w[0] - 1.0 / 6.0).abs() < 1e-12 && (w[1] - 2.0 / 3.0).abs() < 1e-12);
    }
}
