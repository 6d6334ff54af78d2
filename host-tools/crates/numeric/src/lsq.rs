//! Least squares by QR decomposition (nalgebra), optional ridge, and collinearity diagnostics.
//!
//! Glossary:
//! - **design matrix** `X`: one row per observation, one column per model term (column 0 is usually the
//!   intercept, all ones).
//! - **ridge** λ: penalty `λ·n·‖β_s‖²` on the coefficients of the *standardized* non-intercept columns
//!   (zero mean, unit standard deviation), solved as an augmented least-squares problem by QR.
//! - **condition number**: ratio of the largest to the smallest singular value of `X` with every column
//!   scaled to unit Euclidean length (Belsley's scaling); above ~30 collinearity starts to hurt, above ~1000
//!   coefficients are unreliable.
//! - **VIF** (variance inflation factor) of a term: `1/(1 − R²)` of that term regressed on all others; the
//!   diagonal of the inverse correlation matrix.

/// The matrix type of [`lstsq`] (re-exported for callers without their own nalgebra).
pub use nalgebra::DMatrix;
use nalgebra::{DVector, Dyn, SymmetricEigen};

/// Why a least-squares solve failed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum LsError {
    #[error("fewer rows ({rows}) than coefficients ({cols})")]
    TooFewRows { rows: usize, cols: usize },
    #[error("design matrix is rank deficient (column {col} is a combination of the others)")]
    RankDeficient { col: usize },
    #[error("non-finite value in the design matrix or target")]
    NonFinite,
}

/// Cholesky factor of the symmetric matrix `m` (normal equations), adding a tiny ridge to its diagonal when
/// it is singular: 0, then 1e-12, 1e-8 and 1e-4 of the largest |diagonal| entry, the first that factors.
/// `None` when none does (the caller falls back to a pseudo-inverse).
pub fn cholesky_with_ridge(m: &DMatrix<f64>) -> Option<nalgebra::Cholesky<f64, nalgebra::Dyn>> {
    let maxd = max_abs_diagonal(m);
    for ridge in [0.0, 1e-12, 1e-8, 1e-4] {
        let mut mm = m.clone();
        for i in 0..mm.nrows() {
            mm[(i, i)] += ridge * maxd;
        }
        if let Some(ch) = mm.cholesky() {
            return Some(ch);
        }
    }
    None
}

/// The largest |diagonal| entry of `m` (at least 1e-300, a scale for relative tolerances).
pub fn max_abs_diagonal(m: &DMatrix<f64>) -> f64 {
    m.diagonal()
        .iter()
        .fold(0.0f64, |a, b| a.max(b.abs()))
        .max(1e-300)
}

/// Result of [`lstsq`].
#[derive(Debug, Clone)]
pub struct LsFit {
    /// Coefficients, one per design column (in the original, unstandardized units).
    pub coef: Vec<f64>,
    /// Residual sum of squares on the fitted rows (without the ridge penalty).
    pub sse: f64,
    /// Rows used.
    pub n: usize,
}

/// Least squares `min ‖X β − y‖² (+ ridge)` by Householder QR. `intercept_col`: the column not penalised by
/// the ridge (and not standardized); `None` when the design has no intercept. `ridge` ≥ 0.
pub fn lstsq(
    x: &DMatrix<f64>,
    y: &[f64],
    ridge: f64,
    intercept_col: Option<usize>,
) -> Result<LsFit, LsError> {
    let (n, p) = x.shape();
    if n < p {
        return Err(LsError::TooFewRows { rows: n, cols: p });
    }
    if x.iter().any(|v| !v.is_finite()) || y.iter().any(|v| !v.is_finite()) {
        return Err(LsError::NonFinite);
    }
    // Standardize the non-intercept columns (improves conditioning; makes the ridge scale-free).
    let mut mean = vec![0.0; p];
    let mut scale = vec![1.0; p];
    let has_icpt = intercept_col.is_some();
    for j in 0..p {
        if Some(j) == intercept_col {
            continue;
        }
        let col = x.column(j);
        let m = if has_icpt { col.mean() } else { 0.0 };
        let s = (col.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / n as f64).sqrt();
        mean[j] = m;
        scale[j] = if s > 0.0 { s } else { 1.0 };
    }
    let extra = if ridge > 0.0 {
        p - usize::from(has_icpt)
    } else {
        0
    };
    let mut a = DMatrix::<f64>::zeros(n + extra, p);
    for j in 0..p {
        for i in 0..n {
            a[(i, j)] = (x[(i, j)] - mean[j]) / scale[j];
        }
    }
    let mut b = DVector::<f64>::zeros(n + extra);
    for i in 0..n {
        b[i] = y[i];
    }
    if extra > 0 {
        let w = (ridge * n as f64).sqrt();
        let mut r = n;
        for j in 0..p {
            if Some(j) == intercept_col {
                continue;
            }
            a[(r, j)] = w;
            r += 1;
        }
    }
    let qr = a.qr();
    let r = qr.r();
    let rmax = (0..p).map(|j| r[(j, j)].abs()).fold(0.0, f64::max);
    for j in 0..p {
        if r[(j, j)].abs() <= rmax * 1e-12 || rmax == 0.0 {
            return Err(LsError::RankDeficient { col: j });
        }
    }
    let qtb = qr.q().transpose() * &b;
    let beta_s = r
        .solve_upper_triangular(&qtb)
        .ok_or(LsError::RankDeficient { col: 0 })?;
    // Undo standardization: y = Σ β_s,j (x_j − m_j)/s_j + β_icpt.
    let mut coef = vec![0.0; p];
    let mut shift = 0.0;
    for j in 0..p {
        if Some(j) == intercept_col {
            continue;
        }
        coef[j] = beta_s[j] / scale[j];
        shift += coef[j] * mean[j];
    }
    if let Some(ic) = intercept_col {
        coef[ic] = beta_s[ic] - shift;
    }
    let pred = x * DVector::from_column_slice(&coef);
    let sse = (0..n).map(|i| (y[i] - pred[i]).powi(2)).sum();
    Ok(LsFit { coef, sse, n })
}

/// Condition number of `x` with columns scaled to unit length (Belsley). Infinite if a column is zero or the
/// matrix is singular.
pub fn condition_number(x: &DMatrix<f64>) -> f64 {
    let mut a = x.clone();
    for mut col in a.column_iter_mut() {
        let norm = col.norm();
        if norm == 0.0 {
            return f64::INFINITY;
        }
        col /= norm;
    }
    let sv = a.singular_values();
    let max = sv.iter().cloned().fold(0.0, f64::max);
    let min = sv.iter().cloned().fold(f64::INFINITY, f64::min);
    if min <= 0.0 { f64::INFINITY } else { max / min }
}

/// Rank and conditioning of a design matrix, reported with every fit that asks for it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RankReport {
    /// Numerical rank: singular values of the column-scaled matrix above `1e-12 ×` the largest.
    pub rank: usize,
    /// Columns of the design.
    pub cols: usize,
    /// Belsley condition number (see [`condition_number`]).
    pub condition: f64,
}

impl RankReport {
    /// Whether every column is determined by the data.
    pub fn full_rank(&self) -> bool {
        self.rank == self.cols
    }
}

/// Rank and condition number of `x` (columns scaled to unit length; a zero column counts as lost rank).
pub fn rank_report(x: &DMatrix<f64>) -> RankReport {
    let cols = x.ncols();
    let mut a = x.clone();
    let mut zero_cols = 0;
    for mut col in a.column_iter_mut() {
        let norm = col.norm();
        if norm == 0.0 {
            zero_cols += 1;
        } else {
            col /= norm;
        }
    }
    let sv = a.singular_values();
    let max = sv.iter().cloned().fold(0.0, f64::max);
    let rank = sv.iter().filter(|&&s| max > 0.0 && s > max * 1e-12).count();
    RankReport {
        rank: rank.min(cols - zero_cols.min(cols)),
        cols,
        condition: condition_number(x),
    }
}

/// [`lstsq`] together with the design's [`RankReport`].
pub fn lstsq_with_report(
    x: &DMatrix<f64>,
    y: &[f64],
    ridge: f64,
    intercept_col: Option<usize>,
) -> (Result<LsFit, LsError>, RankReport) {
    (lstsq(x, y, ridge, intercept_col), rank_report(x))
}

/// Result of [`lstsq_min_norm`].
#[derive(Debug, Clone)]
pub struct MinNormFit {
    /// Coefficients, one per design column (0 for a column without support on the rows).
    pub coef: Vec<f64>,
    /// Numerical rank: singular values of the column-scaled design above `rel_tol ×` the largest.
    pub rank: usize,
    /// Largest over smallest retained singular value of the column-scaled design (1 for rank ≤ 1,
    /// infinite for rank 0).
    pub condition: f64,
}

/// Unit-RMS scale of each column of `x` (0 for a zero or non-finite column).
fn rms_scales(x: &DMatrix<f64>) -> Vec<f64> {
    let n = x.nrows().max(1) as f64;
    x.column_iter()
        .map(|c| {
            let rms = (c.norm_squared() / n).sqrt();
            if rms.is_finite() && rms > 1e-300 {
                rms
            } else {
                0.0
            }
        })
        .collect()
}

/// `x` with every column divided by its scale (a zero scale gives a zero column).
fn scaled(x: &DMatrix<f64>, s: &[f64]) -> DMatrix<f64> {
    let mut a = x.clone();
    for (mut col, &sj) in a.column_iter_mut().zip(s) {
        if sj == 0.0 {
            col.fill(0.0);
        } else {
            col /= sj;
        }
    }
    a
}

/// An orthonormal basis of the column space of a matrix (see [`column_space`]).
#[derive(Debug, Clone)]
pub struct ColumnSpace {
    /// `n × rank`, orthonormal columns: the left singular vectors kept.
    pub basis: DMatrix<f64>,
    /// Their singular values, in the order of `basis`'s columns.
    pub singular_values: Vec<f64>,
}

impl ColumnSpace {
    /// Numerical rank (columns of `basis`).
    pub fn rank(&self) -> usize {
        self.basis.ncols()
    }
}

/// Orthonormal basis of the column space of `x` by a thin SVD: the left singular vectors whose
/// singular value exceeds `rel_tol ×` the largest (and 0). `x` is taken as given (scale its
/// columns first if their units differ).
pub fn column_space(x: &DMatrix<f64>, rel_tol: f64) -> ColumnSpace {
    let (n, p) = x.shape();
    if n == 0 || p == 0 {
        return ColumnSpace {
            basis: DMatrix::zeros(n, 0),
            singular_values: vec![],
        };
    }
    let svd = x.clone().svd(true, false);
    let smax = svd.singular_values.iter().cloned().fold(0.0, f64::max);
    let keep: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&k| {
            let s = svd.singular_values[k];
            s > rel_tol * smax && s > 0.0
        })
        .collect();
    let u = svd.u.as_ref().expect("SVD computed with U");
    let mut basis = DMatrix::zeros(n, keep.len());
    for (j, &k) in keep.iter().enumerate() {
        basis.set_column(j, &u.column(k));
    }
    ColumnSpace {
        basis,
        singular_values: keep.iter().map(|&k| svd.singular_values[k]).collect(),
    }
}

/// Minimum-norm least squares `min ‖X β − y‖²` of a possibly rank-deficient design, by a thin SVD
/// of `X` with its columns scaled to unit RMS: singular values at or below `rel_tol ×` the largest
/// count as zero (pseudo-inverse), so duplicated or collinear columns share their coefficient
/// instead of failing the solve. Never fails: a zero column gets coefficient 0, an empty design
/// an empty fit. (`rel_tol` on singular values; `1e-9` on the eigenvalues of the Gram matrix, as
/// the diagnose crate used, is `rel_tol` = √1e-9.)
pub fn lstsq_min_norm(x: &DMatrix<f64>, y: &[f64], rel_tol: f64) -> MinNormFit {
    let (n, p) = x.shape();
    if p == 0 || n == 0 {
        return MinNormFit {
            coef: vec![0.0; p],
            rank: 0,
            condition: f64::INFINITY,
        };
    }
    let s = rms_scales(x);
    let a = scaled(x, &s);
    let svd = a.svd(true, true);
    let smax = svd.singular_values.iter().cloned().fold(0.0, f64::max);
    let u = svd.u.as_ref().expect("SVD computed with U");
    let vt = svd.v_t.as_ref().expect("SVD computed with Vᵀ");
    let yv = DVector::from_column_slice(&y[..n.min(y.len())]);
    let mut beta = DVector::<f64>::zeros(p);
    let (mut rank, mut smin) = (0, f64::INFINITY);
    for k in 0..svd.singular_values.len() {
        let sk = svd.singular_values[k];
        if sk > rel_tol * smax && sk > 0.0 {
            rank += 1;
            smin = smin.min(sk);
            let w = u.column(k).dot(&yv) / sk;
            beta += vt.row(k).transpose() * w;
        }
    }
    let coef = (0..p)
        .map(|j| if s[j] != 0.0 { beta[j] / s[j] } else { 0.0 })
        .collect();
    MinNormFit {
        coef,
        rank,
        condition: if rank == 0 {
            f64::INFINITY
        } else {
            smax / smin
        },
    }
}

/// [`column_space`] of `x` with its columns scaled to unit RMS first (the basis spans the same
/// space as `x`'s columns; the scaling only decides which directions count as numerically zero).
pub fn column_space_scaled(x: &DMatrix<f64>, rel_tol: f64) -> ColumnSpace {
    column_space(&scaled(x, &rms_scales(x)), rel_tol)
}

/// Variance inflation factor of each column of `cols` (the non-intercept terms), computed as the diagonal of
/// the inverse of their correlation matrix. One column → `[1.0]`. Singular → infinite.
pub fn vif(cols: &[Vec<f64>]) -> Vec<f64> {
    let p = cols.len();
    if p == 0 {
        return vec![];
    }
    if p == 1 {
        return vec![1.0];
    }
    let n = cols[0].len();
    let std: Vec<Vec<f64>> = cols
        .iter()
        .map(|c| {
            let m = c.iter().sum::<f64>() / n as f64;
            let s = (c.iter().map(|v| (v - m) * (v - m)).sum::<f64>()).sqrt();
            c.iter()
                .map(|v| if s > 0.0 { (v - m) / s } else { 0.0 })
                .collect()
        })
        .collect();
    let corr = DMatrix::from_fn(p, p, |i, j| {
        std[i].iter().zip(&std[j]).map(|(a, b)| a * b).sum::<f64>()
    });
    match corr.try_inverse() {
        Some(inv) => (0..p).map(|i| inv[(i, i)]).collect(),
        None => vec![f64::INFINITY; p],
    }
}

/// Eigen-decomposition of a symmetric matrix that holds exactly zero rows (a parameter no observation
/// reaches): those rows are null eigenvectors (unit vectors, eigenvalue 0), and the rest is decomposed
/// alone. nalgebra's `SymmetricEigen` can return NaN or not converge on such a matrix
/// (dimforge/nalgebra#379), which `plan geometry --measured` met. Eigenvalues are not sorted.
pub fn symmetric_eigen(m: DMatrix<f64>) -> SymmetricEigen<f64, Dyn> {
    let n = m.nrows();
    let live: Vec<usize> = (0..n)
        .filter(|&i| m.row(i).iter().any(|x| *x != 0.0))
        .collect();
    if live.len() == n {
        return SymmetricEigen::new(m);
    }
    let part = SymmetricEigen::new(m.select_rows(live.iter()).select_columns(live.iter()));
    let mut eigenvalues = DVector::zeros(n);
    let mut eigenvectors = DMatrix::zeros(n, n);
    for k in 0..live.len() {
        eigenvalues[k] = part.eigenvalues[k];
        for (r, &i) in live.iter().enumerate() {
            eigenvectors[(i, k)] = part.eigenvectors[(r, k)];
        }
    }
    for (k, i) in (0..n).filter(|i| !live.contains(i)).enumerate() {
        eigenvectors[(i, live.len() + k)] = 1.0;
    }
    SymmetricEigen {
        eigenvalues,
        eigenvectors,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric matrix with zero rows: reference the decomposition's definition, `M v = λ v` for every
    /// pair and orthonormal vectors; tolerance 1e-12. The zero rows' unit vectors carry eigenvalue 0.
    #[test]
    fn symmetric_eigen_with_zero_rows() {
        let mut m = DMatrix::zeros(5, 5);
        for (i, j, v) in [
            (0, 0, 4.0),
            (0, 3, 1.0),
            (3, 0, 1.0),
            (3, 3, 2.0),
            (1, 1, 0.5),
        ] {
            m[(i, j)] = v;
        }
        let e = symmetric_eigen(m.clone());
        let v = &e.eigenvectors;
        assert!((v.transpose() * v - DMatrix::identity(5, 5)).norm() < 1e-12);
        for k in 0..5 {
            let r = &m * v.column(k) - v.column(k) * e.eigenvalues[k];
            assert!(r.norm() < 1e-12, "pair {k}: {r}");
        }
        assert_eq!(e.eigenvalues.iter().filter(|l| **l == 0.0).count(), 2);
    }

    #[test]
    fn rank_report_sees_a_collinear_column() {
        // Reference: column 2 = column 0 + column 1 exactly, so rank 2 of 3 and an infinite or huge
        // condition number (> 1e12); a well-posed 2-column design has rank 2 and condition < 10.
        let x = DMatrix::from_row_slice(
            4,
            3,
            &[1.0, 0.0, 1.0, 1.0, 1.0, 2.0, 1.0, 2.0, 3.0, 1.0, 3.0, 4.0],
        );
        let r = rank_report(&x);
        assert_eq!((r.rank, r.cols), (2, 3));
        assert!(!r.full_rank() && r.condition > 1e12);
        let r2 = rank_report(&x.columns(0, 2).into_owned());
        assert!(r2.full_rank() && r2.condition < 10.0);
    }

    #[test]
    fn exact_line_is_recovered() {
        // y = 2 + 3x exactly: coefficients to 1e-12 (reference: the generating line).
        let xs: Vec<f64> = (0..20).map(|i| i as f64 * 0.5).collect();
        let x = DMatrix::from_fn(20, 2, |i, j| if j == 0 { 1.0 } else { xs[i] });
        let y: Vec<f64> = xs.iter().map(|v| 2.0 + 3.0 * v).collect();
        let fit = lstsq(&x, &y, 0.0, Some(0)).unwrap();
        assert!(
            (fit.coef[0] - 2.0).abs() < 1e-12 && (fit.coef[1] - 3.0).abs() < 1e-12,
            "{:?}",
            fit.coef
        );
        assert!(fit.sse < 1e-20);
    }

    #[test]
    fn ridge_shrinks_toward_zero() {
        let xs: Vec<f64> = (0..30).map(|i| (i as f64 * 0.37).sin()).collect();
        let x = DMatrix::from_fn(30, 2, |i, j| if j == 0 { 1.0 } else { xs[i] });
        let y: Vec<f64> = xs.iter().map(|v| 1.0 + 4.0 * v).collect();
        let f0 = lstsq(&x, &y, 0.0, Some(0)).unwrap();
        let f1 = lstsq(&x, &y, 1.0, Some(0)).unwrap();
        // With λ = 1 on a standardized column the slope shrinks by exactly 1/(1+λ) = 0.5 (closed form for one
        // centered regressor); tolerance 1e-9.
        assert!(
            (f1.coef[1] - 0.5 * f0.coef[1]).abs() < 1e-9,
            "{:?} vs {:?}",
            f1.coef,
            f0.coef
        );
    }

    #[test]
    fn vif_of_independent_and_collinear_columns() {
        // Orthogonal columns (sin/cos over whole periods) have VIF 1 (tolerance 1e-9).
        let n = 64;
        let a: Vec<f64> = (0..n)
            .map(|i| (i as f64 * std::f64::consts::TAU / n as f64).sin())
            .collect();
        let b: Vec<f64> = (0..n)
            .map(|i| (i as f64 * std::f64::consts::TAU / n as f64).cos())
            .collect();
        let v = vif(&[a.clone(), b.clone()]);
        assert!(
            (v[0] - 1.0).abs() < 1e-9 && (v[1] - 1.0).abs() < 1e-9,
            "{v:?}"
        );
        // c = a + 0.1 b: R² of c on a = 1/(1+0.01) → VIF = 1/(1-R²) = 101 (tolerance 1e-6).
        let c: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + 0.1 * y).collect();
        let v = vif(&[a, c]);
        assert!((v[0] - 101.0).abs() < 1e-6, "{v:?}");
    }

    /// Reference: exact algebra — y = 2 + 3x on a design with the x column duplicated; the
    /// minimum-norm solution splits 3 evenly between the twins (tolerance 1e-9), rank 2.
    #[test]
    fn min_norm_fit_of_a_rank_deficient_design() {
        let n = 20;
        let x = DMatrix::from_fn(n, 3, |i, j| if j == 0 { 1.0 } else { i as f64 * 0.5 });
        let y: Vec<f64> = (0..n).map(|i| 2.0 + 3.0 * (i as f64 * 0.5)).collect();
        let f = lstsq_min_norm(&x, &y, 1e-9f64.sqrt());
        assert_eq!(f.rank, 2);
        assert!((f.coef[0] - 2.0).abs() < 1e-9, "{:?}", f.coef);
        assert!((f.coef[1] - 1.5).abs() < 1e-9 && (f.coef[2] - 1.5).abs() < 1e-9);
        assert!(f.condition.is_finite() && f.condition >= 1.0);
        // A zero column gets 0 and lowers the rank.
        let x0 = DMatrix::from_fn(n, 2, |i, j| if j == 0 { i as f64 } else { 0.0 });
        let f0 = lstsq_min_norm(&x0, &y, 1e-6);
        assert_eq!((f0.rank, f0.coef[1]), (1, 0.0));
    }

    /// Reference: the QR solve of [`lstsq`] on a full-rank design (tolerance 1e-10 relative), and
    /// the column space's basis is orthonormal and reproduces the projection (tolerance 1e-12).
    #[test]
    fn min_norm_fit_equals_qr_on_full_rank_and_basis_is_orthonormal() {
        let n = 40;
        let x = DMatrix::from_fn(n, 3, |i, j| {
            (i as f64 * 0.37 * (1 + j) as f64).sin() * (1 + j) as f64
        });
        let y: Vec<f64> = (0..n).map(|i| (i as f64 * 0.11).cos()).collect();
        let qr = lstsq(&x, &y, 0.0, None).unwrap();
        let mn = lstsq_min_norm(&x, &y, 1e-12);
        assert_eq!(mn.rank, 3);
        for (a, b) in qr.coef.iter().zip(&mn.coef) {
            assert!((a - b).abs() <= 1e-10 * a.abs().max(1.0), "{a} vs {b}");
        }
        let cs = column_space_scaled(&x, 1e-9);
        assert_eq!(cs.rank(), 3);
        let g = cs.basis.transpose() * &cs.basis;
        assert!((g - DMatrix::<f64>::identity(3, 3)).abs().max() < 1e-12);
    }
}
