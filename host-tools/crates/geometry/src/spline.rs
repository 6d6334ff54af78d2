//! Uniform cubic B-splines on a knot grid over an axis's range, and the constrained bases of the
//! component functions (zero at the axis's zero; straightness also with zero least-squares slope).

use axcomp_numeric::bspline;
use nalgebra::{DMatrix, SymmetricEigen};
use serde::{Deserialize, Serialize};

/// Knot grid of one axis: `intervals` equal spans over `[lo, hi]` (mm), `intervals + 3` basis functions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AxisGrid {
    pub lo: f64,
    pub hi: f64,
    pub intervals: usize,
}

impl AxisGrid {
    pub fn n_basis(&self) -> usize {
        self.intervals + 3
    }

    /// Whether `q` lies on the grid (with 1 µm of slack).
    pub fn contains(&self, q: f64) -> bool {
        q >= self.lo - 1e-3 && q <= self.hi + 1e-3
    }

    /// First basis index and the four non-zero basis values at `q` (clamped to the range): the
    /// workspace's uniform cubic B-spline ([`axcomp_numeric::bspline`]).
    pub fn local(&self, q: f64) -> (usize, [f64; 4]) {
        let (i, t) = bspline::locate(q, self.lo, self.hi, self.intervals);
        (i, bspline::cubic_weights(t))
    }

    /// All basis values at `q`.
    pub fn basis(&self, q: f64) -> Vec<f64> {
        let mut b = vec![0.0; self.n_basis()];
        let (i, v) = self.local(q);
        b[i..i + 4].copy_from_slice(&v);
        b
    }

    /// Evaluates the spline with coefficients `c`.
    pub fn eval(&self, c: &[f64], q: f64) -> f64 {
        let (i, v) = self.local(q);
        (0..4).map(|k| c[i + k] * v[k]).sum()
    }

    /// `n` evenly spaced positions over the range.
    pub fn positions(&self, n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| self.lo + (self.hi - self.lo) * i as f64 / (n - 1).max(1) as f64)
            .collect()
    }

    /// Null-space basis `N` (n_basis × k) of the constraints: value 0 at q = 0, and with `zero_slope` a
    /// zero least-squares slope over the range. Coefficients are `N·β`.
    pub fn constrained_basis(&self, zero_slope: bool) -> DMatrix<f64> {
        let nb = self.n_basis();
        let mut rows = vec![self.basis(0.0)];
        if zero_slope {
            let qs = self.positions(401);
            let mean = 0.5 * (self.lo + self.hi);
            let mut r = vec![0.0; nb];
            for q in &qs {
                for (k, b) in self.basis(*q).iter().enumerate() {
                    r[k] += (q - mean) * b;
                }
            }
            rows.push(r);
        }
        let c = DMatrix::from_fn(rows.len(), nb, |i, j| rows[i][j]);
        // projector onto the null space of C: I − Cᵀ(CCᵀ)⁻¹C; its unit eigenvectors span the null space
        let cct = &c * c.transpose();
        let inv = cct.try_inverse().expect("independent constraints");
        let proj = DMatrix::identity(nb, nb) - c.transpose() * inv * &c;
        let eig = SymmetricEigen::new(proj);
        let keep: Vec<usize> = (0..nb).filter(|&i| eig.eigenvalues[i] > 0.5).collect();
        DMatrix::from_fn(nb, keep.len(), |i, j| eig.eigenvectors[(i, keep[j])])
    }

    /// Second-difference matrix (n_basis − 2 × n_basis), the roughness penalty of P-splines.
    pub fn second_difference(&self) -> DMatrix<f64> {
        self.difference(2)
    }

    /// The `order`-th difference operator of the B-spline coefficients ((n_basis − order) × n_basis; an
    /// empty operator when the grid has too few coefficients): the roughness penalty of a P-spline, whose
    /// null space is the polynomials of degree below `order`.
    pub fn difference(&self, order: usize) -> DMatrix<f64> {
        let nb = self.n_basis();
        let mut d = DMatrix::<f64>::identity(nb, nb);
        for _ in 0..order.min(nb) {
            let m = d.nrows();
            d = DMatrix::from_fn(m - 1, nb, |r, c| d[(r + 1, c)] - d[(r, c)]);
        }
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grid's basis is the workspace's one: reference the explicit uniform cubic B-spline weights
    /// (1−t)³/6, (3t³−6t²+4)/6, (−3t³+3t²+3t+1)/6, t³/6 on the segment holding q; tolerance 1e-12.
    #[test]
    fn basis_is_the_uniform_cubic_b_spline() {
        let g = AxisGrid {
            lo: -120.0,
            hi: 480.0,
            intervals: 7,
        };
        for q in g.positions(301).into_iter().chain([-500.0, 900.0]) {
            let h = (g.hi - g.lo) / g.intervals as f64;
            let s = ((q - g.lo) / h).clamp(0.0, g.intervals as f64);
            let i = (s.floor() as usize).min(g.intervals - 1);
            let t = s - i as f64;
            let want = [
                (1.0 - t) * (1.0 - t) * (1.0 - t) / 6.0,
                (3.0 * t * t * t - 6.0 * t * t + 4.0) / 6.0,
                (-3.0 * t * t * t + 3.0 * t * t + 3.0 * t + 1.0) / 6.0,
                t * t * t / 6.0,
            ];
            let (j, v) = g.local(q);
            assert_eq!(j, i);
            for k in 0..4 {
                assert!((v[k] - want[k]).abs() < 1e-12, "q {q}: {v:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn partition_of_unity_and_constraints() {
        let g = AxisGrid {
            lo: -100.0,
            hi: 500.0,
            intervals: 6,
        };
        for q in g.positions(37) {
            let s: f64 = g.basis(q).iter().sum();
            assert!((s - 1.0).abs() < 1e-12);
        }
        let n = g.constrained_basis(true);
        assert_eq!(n.ncols(), g.n_basis() - 2);
        // every basis column is zero at 0 and has zero LS slope (reference: exact 0, tolerance 1e-9)
        let qs = g.positions(401);
        for j in 0..n.ncols() {
            let c: Vec<f64> = n.column(j).iter().copied().collect();
            assert!(g.eval(&c, 0.0).abs() < 1e-12);
            let mean = 200.0;
            let slope: f64 = qs.iter().map(|q| (q - mean) * g.eval(&c, *q)).sum();
            assert!(slope.abs() < 1e-9, "{slope}");
        }
    }
}
