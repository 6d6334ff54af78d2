//! Least squares on column lists, robust to rank deficiency.
//!
//! Glossary: **design** = the regressor columns over *all* rows (training and held-out); **rows** = the
//! indices a fit uses; **projector** = an orthonormal basis of the design's column space over the training
//! rows, used to score candidate columns by the exact drop of the residual sum of squares a full refit
//! would give (`‖P_{Z̃} r‖²` with `Z̃` the candidate columns made orthogonal to the model).
//!
//! Method: columns are scaled to unit RMS, the Gram matrix is eigen-decomposed and eigenvalues below
//! `1e-9·λ_max` are treated as zero (minimum-norm pseudo-inverse solution).

use nalgebra::{DMatrix, DVector, SymmetricEigen};

const REL_EIG_TOL: f64 = 1e-9;

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

fn scales<C: AsRef<[f64]>>(cols: &[C], rows: &[usize]) -> Vec<f64> {
    cols.iter()
        .map(|c| {
            let c = c.as_ref();
            let ss: f64 = rows.iter().map(|&i| c[i] * c[i]).sum();
            let rms = (ss / rows.len().max(1) as f64).sqrt();
            if rms.is_finite() && rms > 1e-300 {
                rms
            } else {
                0.0
            }
        })
        .collect()
}

fn gram<C: AsRef<[f64]>>(cols: &[C], s: &[f64], rows: &[usize]) -> DMatrix<f64> {
    let p = cols.len();
    let mut g = DMatrix::<f64>::zeros(p, p);
    for a in 0..p {
        if s[a] == 0.0 {
            continue;
        }
        for b in a..p {
            if s[b] == 0.0 {
                continue;
            }
            let (ca, cb) = (cols[a].as_ref(), cols[b].as_ref());
            let v: f64 = rows.iter().map(|&i| ca[i] * cb[i]).sum::<f64>() / (s[a] * s[b]);
            g[(a, b)] = v;
            g[(b, a)] = v;
        }
    }
    g
}

/// Least-squares fit of `y` on `cols` using `rows`.
pub fn fit<C: AsRef<[f64]>>(cols: &[C], y: &[f64], rows: &[usize]) -> LsFit {
    let p = cols.len();
    if p == 0 {
        return LsFit {
            coef: vec![],
            rank: 0,
        };
    }
    let s = scales(cols, rows);
    let g = gram(cols, &s, rows);
    let mut xty = DVector::<f64>::zeros(p);
    for a in 0..p {
        if s[a] != 0.0 {
            let c = cols[a].as_ref();
            xty[a] = rows.iter().map(|&i| c[i] * y[i]).sum::<f64>() / s[a];
        }
    }
    let eig = SymmetricEigen::new(g);
    let lmax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let mut beta = DVector::<f64>::zeros(p);
    let mut rank = 0;
    for k in 0..p {
        let l = eig.eigenvalues[k];
        if l > REL_EIG_TOL * lmax && l > 0.0 {
            rank += 1;
            let v = eig.eigenvectors.column(k);
            let w = v.dot(&xty) / l;
            beta += v * w;
        }
    }
    let coef = (0..p)
        .map(|a| if s[a] != 0.0 { beta[a] / s[a] } else { 0.0 })
        .collect();
    LsFit { coef, rank }
}

/// Orthonormal basis of the column space of `cols` restricted to `rows` (vectors indexed by position in
/// `rows`).
#[derive(Debug, Clone)]
pub struct Projector {
    q: Vec<Vec<f64>>,
}

impl Projector {
    pub fn new<C: AsRef<[f64]>>(cols: &[C], rows: &[usize]) -> Projector {
        let p = cols.len();
        if p == 0 {
            return Projector { q: vec![] };
        }
        let s = scales(cols, rows);
        let g = gram(cols, &s, rows);
        let eig = SymmetricEigen::new(g);
        let lmax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
        let mut q: Vec<Vec<f64>> = Vec::new();
        for k in 0..p {
            let l = eig.eigenvalues[k];
            if !(l > REL_EIG_TOL * lmax && l > 0.0) {
                continue;
            }
            let v = eig.eigenvectors.column(k);
            let mut col = vec![0.0; rows.len()];
            for a in 0..p {
                if s[a] == 0.0 || v[a] == 0.0 {
                    continue;
                }
                let w = v[a] / s[a];
                let ca = cols[a].as_ref();
                for (j, &i) in rows.iter().enumerate() {
                    col[j] += ca[i] * w;
                }
            }
            // Re-orthonormalise against earlier vectors (guards against the squared condition).
            for prev in &q {
                let d = dot(prev, &col);
                axpy(-d, prev, &mut col);
            }
            let nrm = dot(&col, &col).sqrt();
            if nrm > 1e-6 {
                col.iter_mut().for_each(|c| *c /= nrm);
                q.push(col);
            }
        }
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
        let mut g = DMatrix::<f64>::zeros(m, m);
        let mut b = DVector::<f64>::zeros(m);
        for a in 0..m {
            b[a] = dot(&zt[a], r);
            for c in a..m {
                let v = dot(&zt[a], &zt[c]);
                g[(a, c)] = v;
                g[(c, a)] = v;
            }
        }
        let tr: f64 = (0..m).map(|a| g[(a, a)]).sum();
        if tr <= 0.0 {
            return 0.0;
        }
        let eig = SymmetricEigen::new(g);
        let lmax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
        let mut drop = 0.0;
        for k in 0..m {
            let l = eig.eigenvalues[k];
            // Columns (nearly) inside the model's span carry no new information.
            if l > 1e-9 * lmax && l > 1e-12 * tr {
                let w = eig.eigenvectors.column(k).dot(&b);
                drop += w * w / l;
            }
        }
        drop
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
