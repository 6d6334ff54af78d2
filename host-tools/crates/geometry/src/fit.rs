//! Identification of the 21 components from laser line readings: stacked design matrix, identifiability
//! (eigen-decomposition of the column-normalised normal matrix = SVD of the design), components fixed at
//! zero where the data cannot separate them, smoothing chosen by cross-validation over lines, standard
//! uncertainties.

use std::collections::BTreeMap;

use axcomp_kinematics::{Axis, Component, ComponentKind, Topology, dot, sensitivities};
use axcomp_numeric::lsq::{cholesky_with_ridge, max_abs_diagonal};
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use serde::Serialize;

use crate::GeometryError;
use crate::data::LineData;
use crate::model::{ComponentModel, GeometryModel, MODEL_FORMAT};
use crate::spline::AxisGrid;

/// Identification method.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// General least squares, smoothing λ chosen by leave-one-line-out cross-validation (λ = 0 included).
    Auto,
    /// General least squares without smoothing (λ = 0): the plain reference.
    Plain,
    /// Seed 000's seven-line method: the 17 parameters of its eq. 9 (ECY, EAZ, EBZ, ECZ fixed at 0 because
    /// with the reflector on the tool reference point they have no lever arm), no smoothing.
    SevenLine,
}

impl Method {
    pub fn parse(s: &str) -> Option<Method> {
        match s {
            "auto" => Some(Method::Auto),
            "plain" => Some(Method::Plain),
            "seven-line" => Some(Method::SevenLine),
            _ => None,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Method::Auto => "auto",
            Method::Plain => "plain",
            Method::SevenLine => "seven-line",
        }
    }
}

/// The four components the seven-line method fixes (no lever arm with zero tool offset, seed eq. 9).
pub const SEVEN_LINE_FIXED: [Component; 4] = [
    Component::ECY,
    Component::EAZ,
    Component::EBZ,
    Component::ECZ,
];

/// Options of [`fit`].
#[derive(Debug, Clone)]
pub struct FitOptions {
    pub topology: Topology,
    pub method: Method,
    /// Knot intervals per axis; `None`: the distinct positions along the axis less 3, 1..=12 (so that
    /// plain least squares is still determined where each target is read).
    pub intervals: Option<usize>,
    /// Smoothing λ candidates for [`Method::Auto`].
    pub lambdas: Vec<f64>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            topology: Topology::default(),
            method: Method::Auto,
            intervals: None,
            lambdas: vec![0.0, 1e-4, 1e-3, 1e-2, 1e-1, 1.0],
        }
    }
}

/// Parameter layout: the constrained spline bases of the 18 functions and the 3 squareness constants.
#[derive(Debug, Clone)]
pub struct Layout {
    pub grids: [AxisGrid; 3],
    pub moved: [bool; 3],
    /// Null-space bases (n_basis × k) of the 18 functions.
    pub bases: Vec<DMatrix<f64>>,
    /// (first column, count) of each of the 21 components.
    pub cols: Vec<(usize, usize)>,
    pub p: usize,
}

impl Layout {
    /// Grids over `[min(0, lo), max(0, hi)]` of the readings' axis positions.
    pub fn new(data: &LineData, intervals: Option<usize>) -> Layout {
        let mut grids = [AxisGrid {
            lo: 0.0,
            hi: 1.0,
            intervals: 1,
        }; 3];
        let mut moved = [false; 3];
        for k in 0..3 {
            let mut v: Vec<i64> = data
                .readings
                .iter()
                .map(|r| (r.q[k] * 1e3).round() as i64)
                .collect();
            v.sort();
            v.dedup();
            let lo = (*v.first().unwrap_or(&0) as f64 / 1e3).min(0.0);
            let hi = (*v.last().unwrap_or(&0) as f64 / 1e3).max(0.0);
            moved[k] = hi - lo > 1e-3 && v.len() >= 2;
            let n = intervals.unwrap_or(v.len().saturating_sub(3).clamp(1, 12));
            grids[k] = if moved[k] {
                AxisGrid {
                    lo,
                    hi,
                    intervals: n.max(1),
                }
            } else {
                AxisGrid {
                    lo: lo.min(-1.0),
                    hi: hi.max(1.0),
                    intervals: 1,
                }
            };
        }
        let mut bases = Vec::new();
        let mut cols = Vec::new();
        let mut p = 0;
        for c in &Component::ALL[..18] {
            let g = grids[c.axis().unwrap().index()];
            let n = g.constrained_basis(c.is_straightness());
            cols.push((p, n.ncols()));
            p += n.ncols();
            bases.push(n);
        }
        for _ in 0..3 {
            cols.push((p, 1));
            p += 1;
        }
        Layout {
            grids,
            moved,
            bases,
            cols,
            p,
        }
    }

    /// Design row (µm per parameter) of one reading along its beam.
    pub fn row(&self, topo: &Topology, q: [f64; 3], t: [f64; 3], beam: [f64; 3]) -> Vec<f64> {
        let s = sensitivities(topo, q, t);
        let mut row = vec![0.0; self.p];
        for (i, c) in Component::ALL.iter().enumerate() {
            let sb = dot(s[i], beam);
            let (start, k) = self.cols[i];
            match c.axis() {
                Some(a) => {
                    if sb == 0.0 {
                        continue;
                    }
                    let g = &self.grids[a.index()];
                    let (j0, v) = g.local(q[a.index()]);
                    let n = &self.bases[i];
                    for col in 0..k {
                        let mut b = 0.0;
                        for m in 0..4 {
                            b += v[m] * n[(j0 + m, col)];
                        }
                        row[start + col] = sb * b;
                    }
                }
                None => row[start] = sb,
            }
        }
        row
    }

    /// Raw spline coefficients of component `i` from its parameters.
    pub fn coefficients(&self, i: usize, params: &[f64]) -> Vec<f64> {
        let (start, k) = self.cols[i];
        let n = &self.bases[i];
        (0..n.nrows())
            .map(|r| (0..k).map(|c| n[(r, c)] * params[start + c]).sum())
            .collect()
    }
}

/// Identifiability of the stacked design.
#[derive(Debug, Clone, Serialize)]
pub struct Identifiability {
    /// Rank of the stacked design (column-normalised; singular values below 1e-6 × the largest count as 0).
    pub rank: usize,
    /// Number of parameters (spline coefficients and constants).
    pub parameters: usize,
    /// Largest / smallest singular value of the design actually solved (after fixing).
    pub condition_number: f64,
    /// Components or combinations the data cannot separate.
    pub not_separable: Vec<Vec<String>>,
    /// Singular values of the column-normalised stacked design, largest first.
    pub singular_values: Vec<f64>,
}

/// Per-component result of the identification.
#[derive(Debug, Clone)]
pub struct ComponentStatus {
    pub identified: bool,
    pub reason: String,
    /// Fixed at zero (not estimated).
    pub fixed: bool,
}

/// A fitted model with everything the JSON and report need.
#[derive(Debug, Clone)]
pub struct Fit {
    pub model: GeometryModel,
    pub layout: Layout,
    pub params: Vec<f64>,
    /// Covariance of the active parameters, indexed like `active_cols`.
    pub covariance: DMatrix<f64>,
    pub active_cols: Vec<usize>,
    pub status: Vec<ComponentStatus>,
    pub identifiability: Identifiability,
    /// λ candidates and their leave-one-line-out RMS (µm) (Auto only).
    pub lambda_cv: Vec<(f64, f64)>,
    pub train_rows: usize,
    pub fit_rms_um: f64,
}

fn priority(c: Component) -> u8 {
    // which member of a non-separable group is fixed first (lowest first): angular, straightness,
    // squareness, positioning (the seed: angular errors matter least)
    match c.kind() {
        ComponentKind::Angular { .. } => 0,
        ComponentKind::Linear { .. } if c.is_straightness() => 1,
        ComponentKind::Squareness => 2,
        _ => 3,
    }
}

/// Normal equations of the rows `rows` of design `a` (n × p) with targets `d`.
fn normal(a: &DMatrix<f64>, d: &DVector<f64>, rows: &[usize]) -> (DMatrix<f64>, DVector<f64>) {
    let sub = a.select_rows(rows.iter());
    let ds = DVector::from_iterator(rows.len(), rows.iter().map(|&r| d[r]));
    (sub.transpose() * &sub, sub.transpose() * ds)
}

/// Solves `(g + λP) β = r` by Cholesky, adding a tiny ridge (1e-12, then 1e-8 of the largest diagonal)
/// when the system is singular (components the fold's lines do not reach stay at their prior 0).
fn solve(m: &DMatrix<f64>, r: &DVector<f64>) -> (DVector<f64>, DMatrix<f64>) {
    if let Some(ch) = cholesky_with_ridge(m) {
        let inv = ch.inverse();
        return (&inv * r, inv);
    }
    let pinv = m
        .clone()
        .pseudo_inverse(1e-12 * max_abs_diagonal(m))
        .expect("finite matrix");
    (&pinv * r, pinv)
}

/// Solves `m β = r` (Cholesky, tiny ridge when singular) without forming the inverse.
fn solve_only(m: &DMatrix<f64>, r: &DVector<f64>) -> DVector<f64> {
    match cholesky_with_ridge(m) {
        Some(ch) => ch.solve(r),
        None => solve(m, r).0,
    }
}

/// Fits the model to the readings in `train` (indices into `data.readings`).
pub fn fit(data: &LineData, train: &[usize], opts: &FitOptions) -> Result<Fit, GeometryError> {
    if train.is_empty() {
        return Err(GeometryError::NoRows);
    }
    // the design's rows, and so every floating-point sum below, in an order independent of the file's
    let train = &data.canonical_order(train)[..];
    let topo = &opts.topology;
    let layout = Layout::new(data, opts.intervals);
    let p = layout.p;
    let n = train.len();
    let a = DMatrix::from_fn(n, p, |_, _| 0.0);
    let mut a = a;
    for (i, &ri) in train.iter().enumerate() {
        let r = &data.readings[ri];
        let row = layout.row(topo, r.q, r.tool, r.beam);
        for (j, v) in row.into_iter().enumerate() {
            a[(i, j)] = v;
        }
    }
    let d = DVector::from_iterator(n, train.iter().map(|&ri| data.readings[ri].deviation_um));

    // --- identifiability -------------------------------------------------------------------------
    let mut status: Vec<ComponentStatus> = Component::ALL
        .iter()
        .map(|_| ComponentStatus {
            identified: true,
            reason: String::new(),
            fixed: false,
        })
        .collect();
    let mut not_separable: Vec<Vec<String>> = Vec::new();
    let col_norm: Vec<f64> = (0..p).map(|j| a.column(j).norm()).collect();
    let max_norm = col_norm.iter().fold(0.0f64, |x, y| x.max(*y));
    if opts.method == Method::SevenLine {
        for c in SEVEN_LINE_FIXED {
            let st = &mut status[c.index()];
            st.fixed = true;
            st.identified = false;
            st.reason = "fixed at 0 by the seven-line method: with the reflector on the tool reference point it has no lever arm (seed 000 eq. 9); measure lines with tool offsets to identify it".into();
        }
    }
    for (i, c) in Component::ALL.iter().enumerate() {
        if status[i].fixed {
            continue;
        }
        let (s, k) = layout.cols[i];
        let norm: f64 = (s..s + k)
            .map(|j| col_norm[j] * col_norm[j])
            .sum::<f64>()
            .sqrt();
        if norm <= 1e-9 * max_norm.max(1e-300) {
            let reason = match c.axis() {
                Some(ax) if !layout.moved[ax.index()] => {
                    format!("axis {} does not move in these lines; fixed at 0", ax.letter())
                }
                _ => match c.kind() {
                    ComponentKind::Angular { .. } => "no reading is sensitive to it: no line gives it a lever arm across its rotation (zero tool offset and no travel of the axes stacked after it in that direction); fixed at 0".to_string(),
                    _ => "no reading is sensitive to it (no beam has a component along it); fixed at 0".to_string(),
                },
            };
            status[i] = ComponentStatus {
                identified: false,
                reason,
                fixed: true,
            };
            not_separable.push(vec![c.name().to_string()]);
        }
    }
    let active_of = |status: &[ComponentStatus]| -> Vec<usize> {
        let mut v = Vec::new();
        for (i, st) in status.iter().enumerate() {
            if !st.fixed {
                let (s, k) = layout.cols[i];
                v.extend(s..s + k);
            }
        }
        v
    };
    // normal equations per line (the folds of the cross-validation) and in total, computed once
    // (keyed by the line's label, not its order of first appearance in the file)
    let mut line_rows: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (i, &ri) in train.iter().enumerate() {
        line_rows
            .entry(data.lines[data.readings[ri].line].as_str())
            .or_default()
            .push(i);
    }
    let fold_full: Vec<(Vec<usize>, DMatrix<f64>, DVector<f64>)> = line_rows
        .values()
        .map(|rows| {
            let (g, r) = normal(&a, &d, rows);
            (rows.clone(), g, r)
        })
        .collect();
    let mut g_full = DMatrix::<f64>::zeros(p, p);
    let mut r_full = DVector::<f64>::zeros(p);
    for (_, g, r) in &fold_full {
        g_full += g;
        r_full += r;
    }
    // rank of the full stacked design (column-normalised)
    let nz: Vec<usize> = (0..p).filter(|&j| col_norm[j] > 1e-9 * max_norm).collect();
    let normalised = |cols: &[usize]| -> DMatrix<f64> {
        let mut g = g_full.select_rows(cols.iter()).select_columns(cols.iter());
        for i in 0..cols.len() {
            for j in 0..cols.len() {
                // a parameter no reading is sensitive to (a B-spline coefficient of a stretch of the axis
                // between its zero and the measured range) is a null direction: 0, not 0/0 = NaN (NaN
                // hid every null direction and reported a rank-deficient design as identified)
                let scale = col_norm[cols[i]] * col_norm[cols[j]];
                g[(i, j)] = if scale > 0.0 { g[(i, j)] / scale } else { 0.0 };
            }
        }
        g
    };
    const TOL: f64 = 1e-6;
    if nz.is_empty() {
        return Err(GeometryError::NothingIdentifiable);
    }
    let eig = SymmetricEigen::new(normalised(&nz));
    let mut sv: Vec<f64> = eig.eigenvalues.iter().map(|l| l.max(0.0).sqrt()).collect();
    sv.sort_by(|x, y| y.total_cmp(x));
    let smax = sv.first().copied().unwrap_or(0.0);
    let rank = sv.iter().filter(|s| **s > TOL * smax).count();
    // fix components of null directions until the remaining design has full column rank
    for _ in 0..21 {
        let active = active_of(&status);
        if active.is_empty() {
            break;
        }
        let eig = SymmetricEigen::new(normalised(&active));
        let lmax = eig.eigenvalues.iter().fold(0.0f64, |x, y| x.max(*y));
        let null: Vec<usize> = (0..active.len())
            .filter(|&i| eig.eigenvalues[i] <= TOL * TOL * lmax)
            .collect();
        if null.is_empty() {
            break;
        }
        // component share of each null vector; union of components over null vectors
        let comp_of_col = |col: usize| {
            (0..21).find(|&i| {
                let (s, k) = layout.cols[i];
                col >= s && col < s + k
            })
        };
        let mut groups: Vec<Vec<usize>> = Vec::new();
        let mut share_total = [0.0f64; 21];
        for &ni in &null {
            let v = eig.eigenvectors.column(ni);
            let mut share = [0.0f64; 21];
            for (r, &col) in active.iter().enumerate() {
                share[comp_of_col(col).unwrap()] += v[r] * v[r];
            }
            let members: Vec<usize> = (0..21).filter(|&i| share[i] > 0.01).collect();
            for i in 0..21 {
                share_total[i] += share[i];
            }
            // merge with overlapping groups
            let mut merged = members.clone();
            groups.retain(|g| {
                if g.iter().any(|m| merged.contains(m)) {
                    for m in g {
                        if !merged.contains(m) {
                            merged.push(*m);
                        }
                    }
                    false
                } else {
                    true
                }
            });
            merged.sort();
            groups.push(merged);
        }
        for g in &groups {
            let fix = *g
                .iter()
                .min_by(|&&x, &&y| {
                    priority(Component::ALL[x])
                        .cmp(&priority(Component::ALL[y]))
                        .then(share_total[y].total_cmp(&share_total[x]))
                })
                .unwrap();
            let names: Vec<String> = g
                .iter()
                .map(|&i| Component::ALL[i].name().to_string())
                .collect();
            if g.len() == 1 {
                status[fix] = ComponentStatus {
                    identified: false,
                    reason: "its shape along the axis is not determined by these lines (too few distinct positions where a reading is sensitive to it); fixed at 0".into(),
                    fixed: true,
                };
            } else {
                let others: Vec<String> = names
                    .iter()
                    .filter(|n| *n != Component::ALL[fix].name())
                    .cloned()
                    .collect();
                status[fix] = ComponentStatus {
                    identified: false,
                    reason: format!(
                        "not separable from {} with these lines; fixed at 0",
                        others.join(", ")
                    ),
                    fixed: true,
                };
                for &i in g {
                    if i != fix && !status[i].fixed {
                        status[i].identified = false;
                        status[i].reason = format!(
                            "only its combination with {} is determined ({} fixed at 0); the value carries that combination",
                            names
                                .iter()
                                .filter(|n| *n != Component::ALL[i].name())
                                .cloned()
                                .collect::<Vec<_>>()
                                .join(", "),
                            Component::ALL[fix].name()
                        );
                    }
                }
            }
            if !not_separable.contains(&names) {
                not_separable.push(names);
            }
        }
    }
    let active = active_of(&status);
    if active.is_empty() {
        return Err(GeometryError::NothingIdentifiable);
    }
    let ga = normalised(&active);
    let eig = SymmetricEigen::new(ga);
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |x, y| x.max(*y));
    let lmin = eig
        .eigenvalues
        .iter()
        .fold(f64::INFINITY, |x, y| x.min(*y))
        .max(0.0);
    let condition_number = (lmax / lmin).sqrt();

    // --- smoothing penalty on the active parameters ---------------------------------------------
    let pa = active.len();
    let mut pen = DMatrix::zeros(pa, pa);
    for (i, st) in status.iter().enumerate().take(18) {
        if st.fixed {
            continue;
        }
        let (s, k) = layout.cols[i];
        let pos0 = active.iter().position(|&c| c == s).unwrap();
        let g = &layout.grids[Component::ALL[i].axis().unwrap().index()];
        let dn = g.second_difference() * &layout.bases[i];
        let block = dn.transpose() * &dn;
        let w: f64 = (s..s + k).map(|j| col_norm[j] * col_norm[j]).sum::<f64>() / k as f64;
        for r in 0..k {
            for c2 in 0..k {
                pen[(pos0 + r, pos0 + c2)] = w * block[(r, c2)];
            }
        }
    }
    let aa = a.select_columns(active.iter());
    let sel = |g: &DMatrix<f64>| g.select_rows(active.iter()).select_columns(active.iter());
    let selv =
        |r: &DVector<f64>| DVector::from_iterator(active.len(), active.iter().map(|&j| r[j]));
    let g_all = sel(&g_full);
    let r_all = selv(&r_full);

    // --- λ by leave-one-line-out cross-validation -----------------------------------------------
    let mut lambda_cv = Vec::new();
    // Set when no fold is informative: every line's removal leaves some parameter undetermined, so the
    // held-out readings of every fold fall on directions the other lines do not reach, and the scores differ
    // by rounding only. λ is then not chosen by them: no smoothing, the plain reference's solution.
    let mut cv_cannot_choose = false;
    let lambda = match opts.method {
        Method::Auto if line_rows.len() >= 3 && opts.lambdas.len() > 1 => {
            let folds: Vec<(Vec<usize>, DMatrix<f64>, DVector<f64>)> = fold_full
                .iter()
                .map(|(rows, g, r)| (rows.clone(), sel(g), selv(r)))
                .collect();
            // A fold whose removal leaves some parameter undetermined (an essential line) cannot be
            // predicted by any λ; it is left out of the score (pivot of the fold's Cholesky factor below
            // 1e-9 of the column's own diagonal).
            let informative: Vec<bool> = folds
                .iter()
                .map(|(_, gf, _)| {
                    let m = &g_all - gf;
                    match m.clone().cholesky() {
                        Some(ch) => {
                            let l = ch.l();
                            (0..m.nrows()).all(|i| l[(i, i)] * l[(i, i)] > 1e-9 * m[(i, i)].abs())
                        }
                        None => false,
                    }
                })
                .collect();
            let any = informative.iter().any(|x| *x);
            let mut best = (f64::INFINITY, 0.0);
            for &lam in &opts.lambdas {
                let mut sse = 0.0;
                let mut count = 0usize;
                for (fi, (rows, gf, rf)) in folds.iter().enumerate() {
                    if any && !informative[fi] {
                        continue;
                    }
                    let m = &g_all - gf + &pen * lam;
                    let beta = solve_only(&m, &(&r_all - rf));
                    for &i in rows {
                        let pred = aa.row(i).dot(&beta.transpose());
                        sse += (d[i] - pred).powi(2);
                        count += 1;
                    }
                }
                let rms = (sse / count.max(1) as f64).sqrt();
                lambda_cv.push((lam, rms));
                // prefer less smoothing unless more smoothing is better by 0.1 %
                if rms < best.0 * 0.999 {
                    best = (rms, lam);
                }
            }
            if any {
                best.1
            } else {
                cv_cannot_choose = true;
                0.0
            }
        }
        Method::Auto if opts.lambdas.len() == 1 => opts.lambdas[0],
        _ => 0.0,
    };

    // --- final solve, residual σ, covariance ----------------------------------------------------
    let m = &g_all + &pen * lambda;
    let (beta, minv) = solve(&m, &r_all);
    let resid = &d - &aa * &beta;
    let rss = resid.norm_squared();
    let edf = (&minv * &g_all).trace();
    let sigma2 = rss / (n as f64 - edf).max(1.0);
    let cov = &minv * &g_all * &minv * sigma2;
    // smoothing bias, estimated per parameter as the difference from the unsmoothed solution; it is added
    // to the reported uncertainty of each function value (u² = variance + bias²)
    let beta_plain = if lambda > 0.0 {
        Some(solve_only(&g_all, &r_all))
    } else {
        None
    };
    let mut params = vec![0.0; p];
    for (k, &c) in active.iter().enumerate() {
        params[c] = beta[k];
    }
    let fit_rms_um = (rss / n as f64).sqrt();

    // --- model file -----------------------------------------------------------------------------
    let mut volume_min = [f64::INFINITY; 3];
    let mut volume_max = [f64::NEG_INFINITY; 3];
    for r in &data.readings {
        for k in 0..3 {
            volume_min[k] = volume_min[k].min(r.q[k]);
            volume_max[k] = volume_max[k].max(r.q[k]);
        }
    }
    let mut components = Vec::new();
    for (i, c) in Component::ALL.iter().enumerate() {
        let (s, k) = layout.cols[i];
        let idx: Vec<Option<usize>> = (s..s + k)
            .map(|j| active.iter().position(|&x| x == j))
            .collect();
        let u_at = |g: &[f64]| -> f64 {
            let mut v = 0.0;
            if let Some(bp) = &beta_plain {
                let mut b = 0.0;
                for (a1, i1) in idx.iter().enumerate() {
                    if let Some(x) = i1 {
                        b += g[a1] * (beta[*x] - bp[*x]);
                    }
                }
                v += b * b;
            }
            for (a1, i1) in idx.iter().enumerate() {
                for (a2, i2) in idx.iter().enumerate() {
                    if let (Some(x), Some(y)) = (i1, i2) {
                        v += g[a1] * cov[(*x, *y)] * g[a2];
                    }
                }
            }
            v.max(0.0).sqrt()
        };
        let (coefficients, value, uncertainty) = match c.axis() {
            Some(ax) => {
                let grid = layout.grids[ax.index()];
                let coef = layout.coefficients(i, &params);
                let n = &layout.bases[i];
                let unc = grid
                    .positions(21)
                    .into_iter()
                    .map(|q| {
                        let b = grid.basis(q);
                        let g: Vec<f64> = (0..k)
                            .map(|col| (0..b.len()).map(|r| b[r] * n[(r, col)]).sum())
                            .collect();
                        [q, u_at(&g)]
                    })
                    .collect();
                (coef, 0.0, unc)
            }
            None => (Vec::new(), params[s], vec![[0.0, u_at(&[1.0])]]),
        };
        let st = &status[i];
        let reason = if st.identified {
            format!(
                "identified ({} readings sensitive to it)",
                (0..n)
                    .filter(|&r| (s..s + k).any(|j| a[(r, j)] != 0.0))
                    .count()
            )
        } else {
            st.reason.clone()
        };
        components.push(ComponentModel {
            name: c.name().to_string(),
            identified: st.identified,
            reason,
            unit: c.unit().to_string(),
            coefficients,
            value,
            uncertainty,
        });
    }
    let method = match opts.method {
        Method::Auto if cv_cannot_choose => format!(
            "general least squares on cubic B-splines (knot intervals X {}, Y {}, Z {}), no smoothing (λ = 0, as the plain reference): leave-one-line-out cross-validation cannot choose λ on these lines, since removing any one of them leaves parameters undetermined (the scores in lambda_cv_rms_um differ by rounding only)",
            layout.grids[0].intervals, layout.grids[1].intervals, layout.grids[2].intervals
        ),
        Method::Auto => format!(
            "general least squares on cubic B-splines (knot intervals X {}, Y {}, Z {}), smoothing λ = {} chosen by leave-one-line-out cross-validation",
            layout.grids[0].intervals, layout.grids[1].intervals, layout.grids[2].intervals, lambda
        ),
        Method::Plain => "general least squares on cubic B-splines, no smoothing (plain reference)".to_string(),
        Method::SevenLine => "seven-line method (seed 000): 17 parameters by least squares, ECY, EAZ, EBZ, ECZ fixed at 0".to_string(),
    };
    let model = GeometryModel {
        format: MODEL_FORMAT.to_string(),
        version: crate::model::MODEL_VERSION,
        topology: topo.clone(),
        grids: layout.grids,
        components,
        method,
        smoothing_lambda: lambda,
        sigma_um: sigma2.sqrt(),
        volume_min_mm: volume_min,
        volume_max_mm: volume_max,
    };
    Ok(Fit {
        model,
        params,
        covariance: cov,
        active_cols: active,
        status,
        identifiability: Identifiability {
            rank,
            parameters: p,
            condition_number,
            not_separable,
            singular_values: sv,
        },
        lambda_cv,
        train_rows: n,
        fit_rms_um,
        layout,
    })
}

/// Unused-axis helper for callers: the letter of an axis index.
pub fn axis_letter(k: usize) -> char {
    Axis::ALL[k].letter()
}
