//! Fuzzy c-means (FCM) clustering of sensors, with the cluster count chosen by the Xie–Beni index.
//!
//! Glossary:
//! - **point**: one sensor, described by its standardized series (zero mean, unit standard deviation) on the
//!   training rows, subsampled to at most [`MAX_FEATURES`] evenly spaced samples.
//! - **membership** `u[i][k]` ∈ [0, 1]: how much sensor i belongs to cluster k; `Σ_k u[i][k] = 1`.
//! - **fuzzifier** m = 2 (the usual value).
//! - **centre** `v_k = Σ_i u_ik^m x_i / Σ_i u_ik^m`.
//! - **fixed initialisation** (reproducible): the first centre is the sensor farthest from the mean of all
//!   sensors (ties → lowest index), each next centre the sensor farthest from the centres chosen so far
//!   (maximin).
//! - **convergence**: largest membership change below 1e-7, or 500 iterations.
//! - **Xie–Beni index** `XB = Σ_i Σ_k u_ik^m ‖x_i − v_k‖² / (N · min_{k≠l} ‖v_k − v_l‖²)`: compactness over
//!   separation; the cluster count with the smallest XB is chosen.
//! - **partition coefficient** `PC = Σ_i Σ_k u_ik² / N` (1 = crisp), reported alongside.

use serde::Serialize;

/// At most this many samples per sensor enter the clustering.
pub const MAX_FEATURES: usize = 256;

/// Result of one FCM run.
#[derive(Debug, Clone, Serialize)]
pub struct FcmResult {
    pub clusters: usize,
    /// `memberships[i][k]`: sensor i, cluster k.
    pub memberships: Vec<Vec<f64>>,
    pub iterations: usize,
    pub converged: bool,
    pub xie_beni: f64,
    pub partition_coefficient: f64,
    /// Objective `J_m = Σ u^m d²` at every iteration (non-increasing for a correct FCM).
    #[serde(skip)]
    pub objective: Vec<f64>,
}

impl FcmResult {
    /// Hard assignment: the cluster of largest membership per sensor.
    pub fn assignment(&self) -> Vec<usize> {
        self.memberships
            .iter()
            .map(|u| {
                u.iter()
                    .enumerate()
                    .fold(
                        (0, f64::NEG_INFINITY),
                        |b, (k, &v)| if v > b.1 { (k, v) } else { b },
                    )
                    .0
            })
            .collect()
    }
}

/// Standardize and subsample sensor series into FCM points.
pub fn features(series: &[Vec<f64>]) -> Vec<Vec<f64>> {
    series
        .iter()
        .map(|s| {
            let n = s.len();
            let m = s.iter().sum::<f64>() / n as f64;
            let sd = (s.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / n as f64).sqrt();
            let step = n.div_ceil(MAX_FEATURES).max(1);
            s.iter()
                .step_by(step)
                .map(|v| if sd > 0.0 { (v - m) / sd } else { 0.0 })
                .collect()
        })
        .collect()
}

/// `u^m`, exact multiplication for the usual m = 2.
fn pow_m(u: f64, m: f64) -> f64 {
    if m == 2.0 { u * u } else { u.powf(m) }
}

fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Fuzzy c-means with `c` clusters and fuzzifier `m` on `points` (all the same length), fixed initialisation.
pub fn fcm(points: &[Vec<f64>], c: usize, m: f64) -> FcmResult {
    let n = points.len();
    assert!(c >= 1 && c <= n, "fcm: 1 <= c <= number of points");
    let dim = points[0].len();
    // Maximin initial centres.
    let mean: Vec<f64> = (0..dim)
        .map(|d| points.iter().map(|p| p[d]).sum::<f64>() / n as f64)
        .collect();
    let mut chosen: Vec<usize> = Vec::with_capacity(c);
    let first = (0..n)
        .fold((0, -1.0), |b, i| {
            let d = dist2(&points[i], &mean);
            if d > b.1 { (i, d) } else { b }
        })
        .0;
    chosen.push(first);
    while chosen.len() < c {
        let next = (0..n)
            .filter(|i| !chosen.contains(i))
            .fold((usize::MAX, -1.0), |b, i| {
                let d = chosen
                    .iter()
                    .map(|&j| dist2(&points[i], &points[j]))
                    .fold(f64::INFINITY, f64::min);
                if d > b.1 { (i, d) } else { b }
            })
            .0;
        chosen.push(next);
    }
    let mut centres: Vec<Vec<f64>> = chosen.iter().map(|&i| points[i].clone()).collect();
    let mut u = vec![vec![0.0; c]; n];
    update_memberships(points, &centres, m, &mut u);
    let mut objective = vec![];
    let mut converged = false;
    let mut iterations = 0;
    for it in 0..500 {
        iterations = it + 1;
        // Centres from memberships.
        for (k, centre) in centres.iter_mut().enumerate() {
            let mut wsum = 0.0;
            centre.iter_mut().for_each(|v| *v = 0.0);
            for (i, p) in points.iter().enumerate() {
                let w = pow_m(u[i][k], m);
                wsum += w;
                for (cv, pv) in centre.iter_mut().zip(p) {
                    *cv += w * pv;
                }
            }
            if wsum > 0.0 {
                centre.iter_mut().for_each(|v| *v /= wsum);
            }
        }
        let old = u.clone();
        update_memberships(points, &centres, m, &mut u);
        objective.push(objective_value(points, &centres, &u, m));
        let change = old
            .iter()
            .flatten()
            .zip(u.iter().flatten())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if change < 1e-7 {
            converged = true;
            break;
        }
    }
    let xie_beni = xie_beni(points, &centres, &u, m);
    let partition_coefficient = u.iter().flatten().map(|v| v * v).sum::<f64>() / n as f64;
    FcmResult {
        clusters: c,
        memberships: u,
        iterations,
        converged,
        xie_beni,
        partition_coefficient,
        objective,
    }
}

fn update_memberships(points: &[Vec<f64>], centres: &[Vec<f64>], m: f64, u: &mut [Vec<f64>]) {
    let c = centres.len();
    let e = 1.0 / (m - 1.0);
    for (i, p) in points.iter().enumerate() {
        let d: Vec<f64> = centres.iter().map(|v| dist2(p, v)).collect();
        if let Some(k0) = d.iter().position(|&x| x <= 1e-300) {
            // The point sits on a centre: crisp membership.
            for (k, uk) in u[i].iter_mut().enumerate() {
                *uk = if k == k0 { 1.0 } else { 0.0 };
            }
            continue;
        }
        for k in 0..c {
            // u_ik = 1 / Σ_j (d_ik² / d_ij²)^(1/(m−1))
            let s: f64 = if e == 1.0 {
                d.iter().map(|dj| d[k] / dj).sum()
            } else {
                d.iter().map(|dj| (d[k] / dj).powf(e)).sum()
            };
            u[i][k] = 1.0 / s;
        }
    }
}

fn objective_value(points: &[Vec<f64>], centres: &[Vec<f64>], u: &[Vec<f64>], m: f64) -> f64 {
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            centres
                .iter()
                .enumerate()
                .map(|(k, v)| pow_m(u[i][k], m) * dist2(p, v))
                .sum::<f64>()
        })
        .sum()
}

fn xie_beni(points: &[Vec<f64>], centres: &[Vec<f64>], u: &[Vec<f64>], m: f64) -> f64 {
    let c = centres.len();
    let mut sep = f64::INFINITY;
    for k in 0..c {
        for l in k + 1..c {
            sep = sep.min(dist2(&centres[k], &centres[l]));
        }
    }
    if c < 2 || sep <= 0.0 {
        return f64::INFINITY;
    }
    objective_value(points, centres, u, m) / (points.len() as f64 * sep)
}

/// Run FCM for c = 2..=c_max and return all runs and the index of the one with the smallest Xie–Beni index.
pub fn choose_clusters(points: &[Vec<f64>], c_max: usize, m: f64) -> (Vec<FcmResult>, usize) {
    let n = points.len();
    let c_max = c_max.min(n.saturating_sub(1)).max(2).min(n);
    let runs: Vec<FcmResult> = (2..=c_max).map(|c| fcm(points, c, m)).collect();
    let best = runs
        .iter()
        .enumerate()
        .fold((0, f64::INFINITY), |b, (i, r)| {
            if r.xie_beni < b.1 { (i, r.xie_beni) } else { b }
        })
        .0;
    (runs, best)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memberships_sum_to_one_and_converge_on_two_groups() {
        // Two obvious groups of 1-D points: {0, 0.1, 0.2} and {5, 5.1, 5.2}.
        let pts: Vec<Vec<f64>> = [0.0, 0.1, 0.2, 5.0, 5.1, 5.2]
            .iter()
            .map(|&x| vec![x])
            .collect();
        let r = fcm(&pts, 2, 2.0);
        assert!(
            r.converged,
            "did not converge in {} iterations",
            r.iterations
        );
        for u in &r.memberships {
            // Memberships sum to 1 (tolerance 1e-12).
            assert!((u.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{u:?}");
        }
        let a = r.assignment();
        assert!(
            a[0] == a[1] && a[1] == a[2] && a[3] == a[4] && a[4] == a[5] && a[0] != a[3],
            "{a:?}"
        );
        // FCM objective is non-increasing (alternating optimisation); tolerance 1e-12 relative.
        for w in r.objective.windows(2) {
            assert!(
                w[1] <= w[0] * (1.0 + 1e-12),
                "objective rose: {:?}",
                r.objective
            );
        }
        // Hand check of one membership: with converged centres v1≈0.1, v2≈5.1 (symmetry), the point 0.0 has
        // d1² = 0.01, d2² = 26.01 → u = 1/(1 + 0.01/26.01) ≈ 0.999616 (tolerance 1e-4, the centres are only
        // approximately 0.1/5.1 because the far group pulls them slightly).
        let k0 = a[0];
        assert!(
            (r.memberships[0][k0] - 1.0 / (1.0 + 0.01 / 26.01)).abs() < 1e-4,
            "{:?}",
            r.memberships[0]
        );
    }

    #[test]
    fn xie_beni_picks_three_groups() {
        let pts: Vec<Vec<f64>> = [0.0, 0.2, 5.0, 5.2, 10.0, 10.2, 10.1]
            .iter()
            .map(|&x| vec![x, 0.5 * x])
            .collect();
        let (runs, best) = choose_clusters(&pts, 5, 2.0);
        assert_eq!(
            runs[best].clusters,
            3,
            "XB: {:?}",
            runs.iter().map(|r| r.xie_beni).collect::<Vec<_>>()
        );
    }
}
