//! Cross-validated linear fits from per-group Gram matrices, and the two sensor-selection methods.
//!
//! Glossary:
//! - **candidate**: one column a model term can be built from: a sensor's temperature rise, optionally
//!   through a lag of time constant τ (one candidate per sensor and τ on the grid), or a force column.
//! - **group**: a set of training rows left out together in cross-validation: an operating condition
//!   (`--cv COL`) or, without one, a contiguous block of rows in time.
//! - **Gram matrix** of a group: `Zᵀ Z` with `Z = [1, standardized candidates…, y]` over the group's rows.
//!   Sums of Gram matrices give the normal equations of any union of groups, so leave-one-group-out errors
//!   of any term subset cost a few small solves, not a pass over the data.
//! - **CV RMS**: root of the summed squared prediction errors of each group predicted by a fit on the other
//!   groups, over the number of rows.
//! - **forward selection**: start from the forced terms (forces), repeatedly add the candidate (at most one
//!   per sensor) that lowers the CV RMS most; stop when the best addition gains less than 1 % or at the
//!   term limit.
//! - **FCM + GRA** (reference method, patent 004): cluster the sensors by fuzzy c-means (m = 2, cluster count by
//!   the Xie–Beni index), keep per cluster the sensor with the highest grey relational grade to the error.

use nalgebra::{DMatrix, DVector};

use crate::{fcm, gra};

/// Per-group Gram matrices over `[1, candidates…, y]` (candidates standardized over all grouped rows).
#[derive(Debug, Clone)]
pub struct GramSet {
    /// Number of candidate columns.
    pub k: usize,
    grams: Vec<DMatrix<f64>>,
    /// Rows per group.
    pub rows: Vec<usize>,
    /// Mean and standard deviation of each candidate column over the grouped rows (the standardization).
    pub col_stats: Vec<(f64, f64)>,
    /// Mean of the target over the grouped rows (the target is centred, not scaled).
    pub y_mean: f64,
}

impl GramSet {
    /// `cols`: candidate columns (full length), `y`: target, `group_of_row[i]`: the row's group or `None`
    /// (row not used, e.g. held out).
    pub fn new(
        cols: &[&[f64]],
        y: &[f64],
        group_of_row: &[Option<usize>],
        n_groups: usize,
    ) -> GramSet {
        let k = cols.len();
        let d = k + 2;
        let used: Vec<usize> = (0..y.len())
            .filter(|&i| group_of_row[i].is_some())
            .collect();
        let nu = used.len().max(1) as f64;
        let stats = |c: &[f64]| {
            let m = used.iter().map(|&i| c[i]).sum::<f64>() / nu;
            let s = (used.iter().map(|&i| (c[i] - m).powi(2)).sum::<f64>() / nu).sqrt();
            (m, if s > 0.0 { s } else { 1.0 })
        };
        let cstats: Vec<(f64, f64)> = cols.iter().map(|c| stats(c)).collect();
        let ystat = stats(y);
        let mut grams = vec![vec![0.0f64; d * d]; n_groups];
        let mut rows = vec![0usize; n_groups];
        let mut z = vec![0.0; d];
        for &i in &used {
            let g = group_of_row[i].unwrap();
            rows[g] += 1;
            z[0] = 1.0;
            for (j, c) in cols.iter().enumerate() {
                z[j + 1] = (c[i] - cstats[j].0) / cstats[j].1;
            }
            z[d - 1] = y[i] - ystat.0;
            let gm = &mut grams[g];
            for a in 0..d {
                let za = z[a];
                let row = &mut gm[a * d..a * d + d];
                for b in a..d {
                    row[b] += za * z[b];
                }
            }
        }
        let grams = grams
            .into_iter()
            .map(|g| {
                DMatrix::from_fn(
                    d,
                    d,
                    |a, b| if a <= b { g[a * d + b] } else { g[b * d + a] },
                )
            })
            .collect();
        GramSet {
            k,
            grams,
            rows,
            col_stats: cstats,
            y_mean: ystat.0,
        }
    }

    /// Elastic-net coefficients (intercept first, standardized units, usable with [`GramSet::sse`]) of a fit
    /// of `terms` on `groups`: minimises `(1/2n)‖y − Xβ‖² + λ(α‖β‖₁ + (1 − α)/2 ‖β‖²)` over the non-intercept
    /// coefficients by cyclic coordinate descent on the centred Gram matrix (α = 1: LASSO, α = 0: ridge with
    /// the same scale as [`GramSet::fit`]). `None` with fewer rows than terms.
    pub fn fit_enet(
        &self,
        terms: &[usize],
        groups: &[usize],
        lambda: f64,
        alpha: f64,
    ) -> Option<DVector<f64>> {
        let s = Self::idx(terms);
        let p = s.len();
        let n: usize = groups.iter().map(|&g| self.rows[g]).sum();
        if n < p || n == 0 {
            return None;
        }
        let nf = n as f64;
        let (a, b) = self.normal_equations(&s, groups);
        // Centred cross products / n (index 0 is the intercept).
        let q = p - 1;
        let cxx = DMatrix::from_fn(q, q, |r, c| {
            (a[(r + 1, c + 1)] - a[(0, r + 1)] * a[(0, c + 1)] / nf) / nf
        });
        let cxy = DVector::from_fn(q, |r, _| (b[r + 1] - a[(0, r + 1)] * b[0] / nf) / nf);
        let beta = enet_gram(&cxx, &cxy, lambda, alpha);
        let mut out = DVector::<f64>::zeros(p);
        let mut icpt = b[0];
        for j in 0..q {
            out[j + 1] = beta[j];
            icpt -= a[(0, j + 1)] * beta[j];
        }
        out[0] = icpt / nf;
        Some(out)
    }

    /// The largest λ of [`GramSet::fit_enet`] that keeps any coefficient non-zero, for `terms` on `groups`.
    pub fn enet_lambda_max(&self, terms: &[usize], groups: &[usize], alpha: f64) -> f64 {
        let s = Self::idx(terms);
        let y = self.k + 1;
        let n: f64 = groups.iter().map(|&g| self.rows[g] as f64).sum();
        if n <= 0.0 {
            return 0.0;
        }
        let mut a0 = vec![0.0; s.len()];
        let mut by = vec![0.0; s.len()];
        for &g in groups {
            let m = &self.grams[g];
            for (r, &i) in s.iter().enumerate() {
                a0[r] += m[(0, i)];
                by[r] += m[(i, y)];
            }
        }
        (1..s.len())
            .map(|r| ((by[r] - a0[r] * by[0] / n) / n).abs())
            .fold(0.0, f64::max)
            / alpha.max(1e-3)
    }

    /// Leave-one-group-out CV RMS of the elastic net (see [`GramSet::fit_enet`]).
    pub fn cv_rms_enet(&self, terms: &[usize], groups: &[usize], lambda: f64, alpha: f64) -> f64 {
        let mut sse = 0.0;
        let mut n = 0;
        for &g in groups {
            let rest: Vec<usize> = groups.iter().cloned().filter(|&h| h != g).collect();
            match self.fit_enet(terms, &rest, lambda, alpha) {
                Some(beta) => sse += self.sse(terms, &beta, g),
                None => return f64::INFINITY,
            }
            n += self.rows[g];
        }
        (sse / n.max(1) as f64).sqrt()
    }

    /// Number of groups.
    pub fn groups(&self) -> usize {
        self.grams.len()
    }

    /// The normal equations of the columns `s` (indices into the Gram matrices, intercept first) summed
    /// over `groups`: (XᵀX, Xᵀy).
    fn normal_equations(&self, s: &[usize], groups: &[usize]) -> (DMatrix<f64>, DVector<f64>) {
        let p = s.len();
        let y = self.k + 1;
        let mut a = DMatrix::<f64>::zeros(p, p);
        let mut b = DVector::<f64>::zeros(p);
        for &g in groups {
            let m = &self.grams[g];
            for (r, &i) in s.iter().enumerate() {
                b[r] += m[(i, y)];
                for (c, &j) in s.iter().enumerate() {
                    a[(r, c)] += m[(i, j)];
                }
            }
        }
        (a, b)
    }

    fn idx(terms: &[usize]) -> Vec<usize> {
        std::iter::once(0)
            .chain(terms.iter().map(|t| t + 1))
            .collect()
    }

    /// Coefficients (intercept first, standardized units) of a fit of `terms` on `groups`, ridge `lambda`
    /// (penalty λ·n on the standardized coefficients). `None` if singular.
    pub fn fit(&self, terms: &[usize], groups: &[usize], lambda: f64) -> Option<DVector<f64>> {
        let s = Self::idx(terms);
        let p = s.len();
        let n: usize = groups.iter().map(|&g| self.rows[g]).sum();
        if n < p {
            return None;
        }
        let (mut a, b) = self.normal_equations(&s, groups);
        // A tiny ridge (1e-10 relative) keeps exactly collinear candidates from breaking the solve.
        for r in 1..p {
            a[(r, r)] += (lambda + 1e-10) * n as f64;
        }
        a.cholesky().map(|c| c.solve(&b))
    }

    /// Sum of squared residuals of `beta` (from [`GramSet::fit`] with the same `terms`) on group `g`.
    pub fn sse(&self, terms: &[usize], beta: &DVector<f64>, g: usize) -> f64 {
        let s = Self::idx(terms);
        let y = self.k + 1;
        let m = &self.grams[g];
        let mut v = m[(y, y)];
        for (r, &i) in s.iter().enumerate() {
            v -= 2.0 * beta[r] * m[(i, y)];
            for (c, &j) in s.iter().enumerate() {
                v += beta[r] * beta[c] * m[(i, j)];
            }
        }
        v.max(0.0)
    }

    /// Leave-one-group-out CV over `groups`: (sum of squared prediction errors, rows). Infinite if a fit is
    /// singular. The normal equations of all groups are summed once and each group's part subtracted.
    pub fn cv(&self, terms: &[usize], groups: &[usize], lambda: f64) -> (f64, usize) {
        let s = Self::idx(terms);
        let p = s.len();
        let (a_all, b_all) = self.normal_equations(&s, groups);
        let n_all: usize = groups.iter().map(|&g| self.rows[g]).sum();
        let y = self.k + 1;
        let mut sse = 0.0;
        let mut n = 0;
        for &g in groups {
            let n_fit = n_all - self.rows[g];
            if n_fit < p {
                return (f64::INFINITY, 1);
            }
            let m = &self.grams[g];
            let mut a = a_all.clone();
            let mut b = b_all.clone();
            for (r, &i) in s.iter().enumerate() {
                b[r] -= m[(i, y)];
                for (c, &j) in s.iter().enumerate() {
                    a[(r, c)] -= m[(i, j)];
                }
            }
            for r in 1..p {
                a[(r, r)] += (lambda + 1e-10) * n_fit as f64;
            }
            match a.cholesky() {
                Some(ch) => sse += self.sse(terms, &ch.solve(&b), g),
                None => return (f64::INFINITY, 1),
            }
            n += self.rows[g];
        }
        (sse, n.max(1))
    }

    /// CV RMS (see [`GramSet::cv`]).
    pub fn cv_rms(&self, terms: &[usize], groups: &[usize], lambda: f64) -> f64 {
        let (s, n) = self.cv(terms, groups, lambda);
        (s / n as f64).sqrt()
    }
}

/// Cyclic coordinate descent for the elastic net on a centred Gram matrix: `cxx` = XᵀX/n, `cxy` = Xᵀy/n
/// (centred columns), objective `½βᵀcxxβ − cxyᵀβ + λ(α‖β‖₁ + (1 − α)/2 ‖β‖²)`. Stops when no coefficient
/// moves by more than 1e-9 (relative to the largest) or after 2000 sweeps.
pub fn enet_gram(cxx: &DMatrix<f64>, cxy: &DVector<f64>, lambda: f64, alpha: f64) -> DVector<f64> {
    let q = cxy.len();
    let mut beta = DVector::<f64>::zeros(q);
    let l1 = lambda * alpha;
    let l2 = lambda * (1.0 - alpha);
    for _ in 0..2000 {
        let mut moved: f64 = 0.0;
        let mut big: f64 = 0.0;
        for j in 0..q {
            let d = cxx[(j, j)];
            if d <= 0.0 {
                continue;
            }
            let mut rho = cxy[j];
            for k in 0..q {
                if k != j {
                    rho -= cxx[(j, k)] * beta[k];
                }
            }
            let soft = if rho > l1 {
                rho - l1
            } else if rho < -l1 {
                rho + l1
            } else {
                0.0
            };
            let nb = soft / (d + l2);
            moved = moved.max((nb - beta[j]).abs());
            big = big.max(nb.abs());
            beta[j] = nb;
        }
        if moved <= 1e-9 * big.max(1e-12) {
            break;
        }
    }
    beta
}

/// One candidate column: which sensor (index into the sensor list) or force, and its lag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Candidate {
    Sensor { sensor: usize, tau_s: f64 },
    Force { force: usize },
}

/// One step of forward selection: the candidate added and the CV RMS after adding it.
#[derive(Debug, Clone)]
pub struct ForwardStep {
    pub candidate: usize,
    pub cv_rms: f64,
}

/// Result of forward selection.
#[derive(Debug, Clone)]
pub struct Forward {
    /// CV RMS of the forced terms alone.
    pub start_cv_rms: f64,
    pub steps: Vec<ForwardStep>,
    /// Selected candidate indices (forced first).
    pub terms: Vec<usize>,
    pub cv_rms: f64,
}

/// Forward selection over `candidates` (indices into the Gram columns) with `forced` always in, scored by
/// leave-one-group-out CV over `groups`. At most one candidate per sensor.
pub fn forward(
    gs: &GramSet,
    cands: &[Candidate],
    forced: &[usize],
    groups: &[usize],
    max_sensors: usize,
    min_gain: f64,
) -> Forward {
    let mut terms: Vec<usize> = forced.to_vec();
    let start = gs.cv_rms(&terms, groups, 0.0);
    let mut cur = start;
    let mut steps = vec![];
    let mut used_sensors: Vec<usize> = vec![];
    while used_sensors.len() < max_sensors {
        let mut best: Option<(usize, f64)> = None;
        for (ci, c) in cands.iter().enumerate() {
            let Candidate::Sensor { sensor, .. } = *c else {
                continue;
            };
            if used_sensors.contains(&sensor) {
                continue;
            }
            let mut t = terms.clone();
            t.push(ci);
            let r = gs.cv_rms(&t, groups, 0.0);
            if best.is_none_or(|b| r < b.1) {
                best = Some((ci, r));
            }
        }
        let Some((ci, r)) = best else { break };
        if r.is_nan() || r >= cur * (1.0 - min_gain) {
            break;
        }
        terms.push(ci);
        if let Candidate::Sensor { sensor, .. } = cands[ci] {
            used_sensors.push(sensor);
        }
        steps.push(ForwardStep {
            candidate: ci,
            cv_rms: r,
        });
        cur = r;
        // Revisit the lags of the sensors already in (a new term can change which lag fits best).
        cur = improve_lags(gs, cands, &mut terms, groups, cur);
    }
    Forward {
        start_cv_rms: start,
        steps,
        terms,
        cv_rms: cur,
    }
}

/// Search over the lag grid: every sensor term's other lag candidates are tried, and the one change that
/// lowers the CV RMS most is kept; repeated while a change helps (at most 2 changes per sensor term). Taking
/// the best change over all terms, not the first term's first, makes the result independent of the order
/// of the sensor columns in the file (an exact tie keeps the change found first). Returns the new CV RMS.
pub fn improve_lags(
    gs: &GramSet,
    cands: &[Candidate],
    terms: &mut [usize],
    groups: &[usize],
    mut cur: f64,
) -> f64 {
    let sensor_terms = terms
        .iter()
        .filter(|&&t| matches!(cands[t], Candidate::Sensor { .. }))
        .count();
    for _change in 0..2 * sensor_terms {
        let mut best: Option<(usize, usize, f64)> = None;
        for pos in 0..terms.len() {
            let Candidate::Sensor { sensor, .. } = cands[terms[pos]] else {
                continue;
            };
            let old = terms[pos];
            for (ci, c) in cands.iter().enumerate() {
                let Candidate::Sensor { sensor: s2, .. } = *c else {
                    continue;
                };
                if s2 != sensor || ci == old {
                    continue;
                }
                terms[pos] = ci;
                let r = gs.cv_rms(terms, groups, 0.0);
                if r < best.map_or(cur * (1.0 - 1e-9), |(_, _, b)| b) {
                    best = Some((pos, ci, r));
                }
            }
            terms[pos] = old;
        }
        match best {
            Some((pos, ci, r)) => {
                terms[pos] = ci;
                cur = r;
            }
            None => break,
        }
    }
    cur
}

/// Result of the FCM + GRA selection.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FcmGra {
    /// Xie–Beni index per tried cluster count (c = 2, 3, …).
    pub xie_beni: Vec<(usize, f64)>,
    pub partition_coefficient: Vec<(usize, f64)>,
    pub clusters: usize,
    pub iterations: usize,
    pub converged: bool,
    /// Hard cluster of each sensor.
    pub cluster_of: Vec<usize>,
    pub memberships: Vec<Vec<f64>>,
    /// Grey relational grade of each sensor to the error (ρ = 0.5).
    pub grades: Vec<f64>,
    /// Chosen sensors (indices), one per non-empty cluster, highest grade.
    pub selected: Vec<usize>,
}

/// FCM + GRA on the given training series (`sensors[i]` = sensor i's values on the training rows).
pub fn fcm_gra(sensors: &[Vec<f64>], target: &[f64], c_max: usize) -> FcmGra {
    let n = sensors.len();
    let grades = gra::grades(target, sensors, 0.5);
    if n <= 2 {
        // Too few sensors to cluster: every sensor is its own cluster.
        return FcmGra {
            xie_beni: vec![],
            partition_coefficient: vec![],
            clusters: n,
            iterations: 0,
            converged: true,
            cluster_of: (0..n).collect(),
            memberships: (0..n)
                .map(|i| (0..n).map(|k| f64::from(u8::from(i == k))).collect())
                .collect(),
            grades,
            selected: (0..n).collect(),
        };
    }
    let pts = fcm::features(sensors);
    let (runs, best) = fcm::choose_clusters(&pts, c_max, 2.0);
    let r = &runs[best];
    let cluster_of = r.assignment();
    let mut selected = vec![];
    for k in 0..r.clusters {
        let best = (0..n)
            .filter(|&i| cluster_of[i] == k)
            .fold(None::<usize>, |b, i| match b {
                Some(j) if grades[j] >= grades[i] => Some(j),
                _ => Some(i),
            });
        if let Some(i) = best {
            selected.push(i);
        }
    }
    selected.sort();
    FcmGra {
        xie_beni: runs.iter().map(|r| (r.clusters, r.xie_beni)).collect(),
        partition_coefficient: runs
            .iter()
            .map(|r| (r.clusters, r.partition_coefficient))
            .collect(),
        clusters: r.clusters,
        iterations: r.iterations,
        converged: r.converged,
        cluster_of,
        memberships: r.memberships.clone(),
        grades,
        selected,
    }
}
