//! Least squares on column lists, robust to rank deficiency, through the host numeric layer
//! (`axcomp_numeric::lsq`: minimum-norm least squares and column-space bases by SVD).
//!
//! Glossary: **design** = the regressor columns over *all* rows (training and held-out); **rows** = the
//! indices a fit uses; **projector** = an orthonormal basis of the design's column space over the training
//! rows, used to score candidate columns by the exact drop of the residual sum of squares a full refit
//! would give (`‖P_{Z̃} r‖²` with `Z̃` the candidate columns made orthogonal to the model).
//!
//! Method: columns are scaled to unit RMS and decomposed by a thin SVD; singular values below
//! `√1e-9·σ_max` (the eigenvalues of the scaled Gram matrix below `1e-9·λ_max`) are treated as zero
//! (minimum-norm pseudo-inverse solution).

use axcomp_numeric::lsq::{DMatrix, column_space, column_space_scaled, lstsq_min_norm};

/// Singular values of the unit-RMS design at or below this fraction of the largest count as zero
/// (= eigenvalues of its Gram matrix below 1e-9 of the largest).
const REL_SV_TOL: f64 = 3.162_277_660_168_379_5e-5;

/// Coefficients of one least-squares fit.
#[derive(Debug, Clone)]
pub struct LsFit {
    /// One per design column (0 for a column without support on the fitted rows).
    pub coef: Vec<f64>,
    /// Numerical rank of the design on the fitted rows.
    pub rank: usize,
}

impl LsFit {
    /// Prediction for row `i`.
    pub fn predict<C: AsRef<[f64]>>(&self, cols: &[C], i: usize) -> f64 {
        cols.iter()
            .zip(&self.coef)
            .map(|(c, b)| c.as_ref()[i] * b)
            .sum()
    }
}

/// The design restricted to `rows` (one matrix row per entry of `rows`).
fn design<C: AsRef<[f64]>>(cols: &[C], rows: &[usize]) -> DMatrix<f64> {
    DMatrix::from_fn(rows.len(), cols.len(), |r, c| cols[c].as_ref()[rows[r]])
}

/// Least-squares fit of `y` on `cols` using `rows`.
pub fn fit<C: AsRef<[f64]>>(cols: &[C], y: &[f64], rows: &[usize]) -> LsFit {
    if cols.is_empty() {
        return LsFit {
            coef: vec![],
            rank: 0,
        };
    }
    let yr: Vec<f64> = rows.iter().map(|&i| y[i]).collect();
    let f = lstsq_min_norm(&design(cols, rows), &yr, REL_SV_TOL);
    LsFit {
        coef: f.coef,
        rank: f.rank,
    }
}

/// Orthonormal basis of the column space of `cols` restricted to `rows` (vectors indexed by position in
/// `rows`).
#[derive(Debug, Clone)]
pub struct Projector {
    q: Vec<Vec<f64>>,
}

impl Projector {
    pub fn new<C: AsRef<[f64]>>(cols: &[C], rows: &[usize]) -> Projector {
        if cols.is_empty() {
            return Projector { q: vec![] };
        }
        let cs = column_space_scaled(&design(cols, rows), REL_SV_TOL);
        let q = cs
            .basis
            .column_iter()
            .map(|c| c.iter().copied().collect())
            .collect();
        Projector { q }
    }

    /// `z − Q Qᵀ z`.
    pub fn residualize(&self, z: &[f64]) -> Vec<f64> {
        let mut out = z.to_vec();
        for qk in &self.q {
            let d = dot(qk, &out);
            axpy(-d, qk, &mut out);
        }
        out
    }

    /// Exact drop of the training RSS when the columns `zs` (indexed like the projector's rows) are added
    /// to the model whose residual is `r` (`r` must be orthogonal to the model's columns).
    pub fn rss_drop(&self, r: &[f64], zs: &[Vec<f64>]) -> f64 {
        let zt: Vec<Vec<f64>> = zs.iter().map(|z| self.residualize(z)).collect();
        let m = zt.len();
        let n = r.len();
        if m == 0 {
            return 0.0;
        }
        // Trace of the candidates' Gram matrix = squared Frobenius norm.
        let tr: f64 = zt.iter().map(|z| dot(z, z)).sum();
        if tr <= 0.0 {
            return 0.0;
        }
        let z = DMatrix::from_fn(n, m, |i, c| zt[c][i]);
        let cs = column_space(&z, REL_SV_TOL);
        // Columns (nearly) inside the model's span carry no new information: besides the relative
        // threshold, a direction must carry more than 1e-12 of the candidates' total energy.
        cs.basis
            .column_iter()
            .zip(&cs.singular_values)
            .filter(|(_, s)| *s * *s > 1e-12 * tr)
            .map(|(u, _)| {
                let w: f64 = u.iter().zip(r).map(|(a, b)| a * b).sum();
                w * w
            })
            .sum()
    }
}

pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    y.iter_mut().zip(x).for_each(|(yi, xi)| *yi += a * xi);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_fit_and_rank_deficiency() {
        // y = 2 + 3x exactly; a duplicated column must not break the fit (reference: exact algebra, tol 1e-9).
        let x: Vec<f64> = (0..20).map(|i| i as f64 * 0.5).collect();
        let one = vec![1.0; 20];
        let y: Vec<f64> = x.iter().map(|v| 2.0 + 3.0 * v).collect();
        let cols = vec![one, x.clone(), x.clone()];
        let rows: Vec<usize> = (0..20).collect();
        let f = fit(&cols, &y, &rows);
        assert_eq!(f.rank, 2);
        for (i, yi) in y.iter().enumerate() {
            assert!((f.predict(&cols, i) - yi).abs() < 1e-9, "row {i}");
        }
    }

    #[test]
    fn rss_drop_equals_refit() {
        // The projector's drop must equal RSS(base) − RSS(base + z) of an explicit refit (tol 1e-8 relative).
        let n = 50;
        let x: Vec<f64> = (0..n).map(|i| i as f64 / n as f64).collect();
        let y: Vec<f64> = x.iter().map(|v| (7.0 * v).sin() + 0.3 * v).collect();
        let base = vec![vec![1.0; n], x.clone()];
        let z: Vec<f64> = x.iter().map(|v| v * v).collect();
        let rows: Vec<usize> = (0..n).collect();
        let f0 = fit(&base, &y, &rows);
        let r: Vec<f64> = (0..n).map(|i| y[i] - f0.predict(&base, i)).collect();
        let rss0 = dot(&r, &r);
        let mut full = base.clone();
        full.push(z.clone());
        let f1 = fit(&full, &y, &rows);
        let rss1: f64 = (0..n).map(|i| (y[i] - f1.predict(&full, i)).powi(2)).sum();
        let p = Projector::new(&base, &rows);
        let d = p.rss_drop(&r, &[z]);
        assert!(
            ((rss0 - rss1) - d).abs() < 1e-8 * rss0,
            "{} vs {}",
            rss0 - rss1,
            d
        );
    }
}
