//! The stacked design of the training readings: one row per reading along its beam, one column per
//! parameter of [`crate::layout::Layout`], its normal equations per line and in total, and the rank and
//! condition of its column-normalised form.

use std::collections::BTreeMap;

use axcomp_kinematics::Topology;
use axcomp_numeric::lsq::symmetric_eigen;
use nalgebra::{DMatrix, DVector};

use crate::GeometryError;
use crate::data::LineData;
use crate::layout::Layout;

/// Normal equations of the rows `rows` of design `a` (n × p) with targets `d`.
fn normal(a: &DMatrix<f64>, d: &DVector<f64>, rows: &[usize]) -> (DMatrix<f64>, DVector<f64>) {
    let sub = a.select_rows(rows.iter());
    let ds = DVector::from_iterator(rows.len(), rows.iter().map(|&r| d[r]));
    (sub.transpose() * &sub, sub.transpose() * ds)
}

/// Tolerance of the rank decisions: singular values below `TOL` × the largest count as zero.
pub(crate) const TOL: f64 = 1e-6;

/// The stacked design of the training readings and its normal equations, per line and in total.
pub(crate) struct Design {
    pub(crate) a: DMatrix<f64>,
    pub(crate) d: DVector<f64>,
    pub(crate) col_norm: Vec<f64>,
    pub(crate) max_norm: f64,
    /// Rows of each line (keyed by the line's label, not its order in the file) and their normal equations.
    pub(crate) folds: Vec<(Vec<usize>, DMatrix<f64>, DVector<f64>)>,
    pub(crate) g_full: DMatrix<f64>,
    pub(crate) r_full: DVector<f64>,
}

impl Design {
    pub(crate) fn new(
        data: &LineData,
        train: &[usize],
        layout: &Layout,
        topo: &Topology,
    ) -> Design {
        let (n, p) = (train.len(), layout.p);
        let mut a = DMatrix::zeros(n, p);
        for (i, &ri) in train.iter().enumerate() {
            let r = &data.readings[ri];
            for (j, v) in layout
                .row(topo, r.q, r.tool, r.beam)
                .into_iter()
                .enumerate()
            {
                a[(i, j)] = v;
            }
        }
        let d = DVector::from_iterator(n, train.iter().map(|&ri| data.readings[ri].deviation_um));
        let col_norm: Vec<f64> = (0..p).map(|j| a.column(j).norm()).collect();
        let max_norm = col_norm.iter().fold(0.0f64, |x, y| x.max(*y));
        let mut line_rows: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
        for (i, &ri) in train.iter().enumerate() {
            line_rows
                .entry(data.lines[data.readings[ri].line].as_str())
                .or_default()
                .push(i);
        }
        let folds: Vec<_> = line_rows
            .into_values()
            .map(|rows| {
                let (g, r) = normal(&a, &d, &rows);
                (rows, g, r)
            })
            .collect();
        let mut g_full = DMatrix::<f64>::zeros(p, p);
        let mut r_full = DVector::<f64>::zeros(p);
        for (_, g, r) in &folds {
            g_full += g;
            r_full += r;
        }
        Design {
            a,
            d,
            col_norm,
            max_norm,
            folds,
            g_full,
            r_full,
        }
    }

    /// The normal matrix of columns `cols`, column-normalised. A parameter no reading is sensitive to (a
    /// B-spline coefficient of a stretch of the axis between its zero and the measured range) is a null
    /// direction: 0, not 0/0 = NaN (NaN would hide every null direction).
    pub(crate) fn normalised(&self, cols: &[usize]) -> DMatrix<f64> {
        let mut g = self
            .g_full
            .select_rows(cols.iter())
            .select_columns(cols.iter());
        for i in 0..cols.len() {
            for j in 0..cols.len() {
                let scale = self.col_norm[cols[i]] * self.col_norm[cols[j]];
                g[(i, j)] = if scale > 0.0 { g[(i, j)] / scale } else { 0.0 };
            }
        }
        g
    }

    /// Norm of the columns of component `i`.
    pub(crate) fn component_norm(&self, layout: &Layout, i: usize) -> f64 {
        let (s, k) = layout.cols[i];
        (s..s + k)
            .map(|j| self.col_norm[j] * self.col_norm[j])
            .sum::<f64>()
            .sqrt()
    }

    /// Rank and singular values (largest first) of the column-normalised design.
    pub(crate) fn rank(&self) -> Result<(usize, Vec<f64>), GeometryError> {
        let p = self.col_norm.len();
        let nz: Vec<usize> = (0..p)
            .filter(|&j| self.col_norm[j] > 1e-9 * self.max_norm)
            .collect();
        if nz.is_empty() {
            return Err(GeometryError::NothingIdentifiable);
        }
        let eig = symmetric_eigen(self.normalised(&nz));
        let mut sv: Vec<f64> = eig.eigenvalues.iter().map(|l| l.max(0.0).sqrt()).collect();
        sv.sort_by(|x, y| y.total_cmp(x));
        let smax = sv.first().copied().unwrap_or(0.0);
        Ok((sv.iter().filter(|s| **s > TOL * smax).count(), sv))
    }

    /// Largest / smallest singular value of the column-normalised design of `cols`.
    pub(crate) fn condition(&self, cols: &[usize]) -> f64 {
        let eig = symmetric_eigen(self.normalised(cols));
        let lmax = eig.eigenvalues.iter().fold(0.0f64, |x, y| x.max(*y));
        let lmin = eig
            .eigenvalues
            .iter()
            .fold(f64::INFINITY, |x, y| x.min(*y))
            .max(0.0);
        (lmax / lmin).sqrt()
    }
}
