//! Grey relational analysis (GRA): how closely each sensor's series follows the error series.
//!
//! Glossary:
//! - **reference sequence** `x0`: the error (target) series; **comparison sequences** `x_i`: the sensors.
//! - **normalisation**: each sequence is mapped to [0, 1] by its own range, `(x − min)/(max − min)`.
//! - **grey relational coefficient** at sample k: `ξ_i(k) = (Δmin + ρ Δmax)/(Δ_i(k) + ρ Δmax)` with
//!   `Δ_i(k) = |x0(k) − x_i(k)|` and Δmin, Δmax the smallest and largest Δ over all sensors and samples.
//! - **distinguishing coefficient** ρ = 0.5 (the usual choice, as in the reference patent).
//! - **grey relational grade** `r_i = mean_k ξ_i(k)`, in (0, 1]; higher = more closely related.
//!
//! Note: with range normalisation a sensor that falls while the error rises scores low even if it is a good
//! linear predictor. That is a property of the reference method, kept as is; the forward selection in
//! [`crate::select`] has no such blind spot.

/// Range-normalise a sequence to [0, 1] (a constant sequence maps to all zeros).
pub fn normalise(x: &[f64]) -> Vec<f64> {
    let min = x.iter().cloned().fold(f64::INFINITY, f64::min);
    let max = x.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let r = max - min;
    x.iter()
        .map(|v| if r > 0.0 { (v - min) / r } else { 0.0 })
        .collect()
}

/// Grey relational grades of each comparison sequence to the reference, with distinguishing coefficient `rho`.
/// Sequences are range-normalised first. All sequences must have the reference's length.
pub fn grades(reference: &[f64], comparisons: &[Vec<f64>], rho: f64) -> Vec<f64> {
    let x0 = normalise(reference);
    let xs: Vec<Vec<f64>> = comparisons.iter().map(|c| normalise(c)).collect();
    let deltas: Vec<Vec<f64>> = xs
        .iter()
        .map(|x| x.iter().zip(&x0).map(|(a, b)| (a - b).abs()).collect())
        .collect();
    let dmin = deltas
        .iter()
        .flatten()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    let dmax = deltas
        .iter()
        .flatten()
        .cloned()
        .fold(f64::NEG_INFINITY, f64::max);
    deltas
        .iter()
        .map(|d| {
            if dmax <= 0.0 {
                return 1.0;
            }
            d.iter()
                .map(|v| (dmin + rho * dmax) / (v + rho * dmax))
                .sum::<f64>()
                / d.len() as f64
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grades_match_hand_computation() {
        // Hand-checkable example (3 samples, 2 sensors), ρ = 0.5.
        // x0 = [1,2,3] → [0, .5, 1]; x1 = [2,4,6] → [0, .5, 1] (Δ = 0,0,0); x2 = [3,1,2] → [1, 0, .5]
        // (Δ = 1, .5, .5). Δmin = 0, Δmax = 1.
        // ξ1 = (0 + .5)/(0 + .5) = 1 at all k → r1 = 1.
        // ξ2 = .5/1.5, .5/1, .5/1 = 1/3, 1/2, 1/2 → r2 = (1/3 + 1/2 + 1/2)/3 = 4/9.
        // Tolerance 1e-12.
        let g = grades(
            &[1.0, 2.0, 3.0],
            &[vec![2.0, 4.0, 6.0], vec![3.0, 1.0, 2.0]],
            0.5,
        );
        assert!((g[0] - 1.0).abs() < 1e-12, "{g:?}");
        assert!((g[1] - 4.0 / 9.0).abs() < 1e-12, "{g:?}");
    }
}
