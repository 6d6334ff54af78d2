//! The Levenberg–Marquardt fit of the location errors, the set-up offsets and, optionally, effect terms
//! ([`crate::effects`]) on a set of rows; identifiability and standard uncertainties as in the crate root's
//! glossary. Effect parameters come after the set-up offsets and are taken last by the identifiability
//! check (the location errors and offsets keep what they share with an effect).

use axcomp_kinematics::rotary::{N_LOCATION, N_SETUP, Pose};
use nalgebra::{DMatrix, DVector};

use crate::effects::EffectSet;
use crate::{
    Fit, FitOptions, Identifiability, RtestData, RtestError, SharedError, ZeroUncertainty,
    head_fixed, identifiability_ordered, model_displacement, sensitivity_matrix, split_params,
};

/// [`crate::fit_fixed`] with `effects` added to the model (their parameters after the set-up offsets).
pub fn fit_effects(
    data: &RtestData,
    rows: &[usize],
    opts: &FitOptions,
    shared: Option<&SharedError>,
    fix: &[Option<String>],
    effects: &EffectSet,
) -> Result<Fit, RtestError> {
    if let Some(s) = opts.head_zero_std_um
        && let Some(v) = s.iter().find(|v| !(v.is_finite() && **v >= 0.0))
    {
        return Err(RtestError::BadValue {
            at: "head zero standard uncertainty".into(),
            what: format!("{v} µm (need a finite value ≥ 0)"),
        });
    }
    let m = &data.machine;
    let ns = data.setup_names.len();
    let n_base = data.n_params();
    let p = n_base + effects.n_params(m.kind);
    let names = param_names_with(data, effects);
    let poses: Vec<Pose> = rows.iter().map(|&r| data.poses[r]).collect();
    let setup: Vec<usize> = rows.iter().map(|&r| data.setup[r]).collect();
    let meas: Vec<[f64; 3]> = rows.iter().map(|&r| data.d_um[r]).collect();
    let j0 = with_effect_columns(
        sensitivity_matrix(m, &poses, &setup, ns),
        data,
        &poses,
        effects,
        &vec![0.0; n_base],
        &setup,
    );
    let mut fixed = head_fixed(n_base, data.free_head_zero);
    fixed.resize(p, None);
    for (k, why) in fix.iter().enumerate().take(N_LOCATION) {
        if why.is_some() {
            fixed[k] = why.clone();
        }
    }
    let ident = identifiability_ordered(&j0, &names, &fixed, n_base);
    let free: Vec<usize> = (0..p).filter(|&k| ident.estimated[k]).collect();
    let nobs = 3 * poses.len();
    if nobs <= free.len() {
        return Err(RtestError::Fit(format!(
            "{} readings for {} free parameters: too few poses to fit",
            nobs,
            free.len()
        )));
    }
    let problem = Problem {
        data,
        effects,
        poses,
        setup,
        meas,
        free,
        n_base,
        nobs,
    };
    let solved = problem.solve(p)?;
    let unc = problem.uncertainty(&solved, rows, opts, shared)?;
    Ok(problem.into_fit(solved, unc, ident))
}

/// The least-squares problem of one fit: the rows' poses, set-ups and readings, and the free parameters.
struct Problem<'a> {
    data: &'a RtestData,
    effects: &'a EffectSet,
    poses: Vec<Pose>,
    setup: Vec<usize>,
    meas: Vec<[f64; 3]>,
    /// Indices (into the full parameter vector) of the estimated parameters, in column order.
    free: Vec<usize>,
    /// Number of location-error and set-up-offset parameters (the effects' come after).
    n_base: usize,
    /// Number of readings (three per pose).
    nobs: usize,
}

/// The Levenberg–Marquardt result: estimate, residuals, cost, iterations and the last Jacobian.
struct Solved {
    theta: Vec<f64>,
    r: DVector<f64>,
    cost: f64,
    iterations: usize,
    j: DMatrix<f64>,
}

/// The standard uncertainties' ingredients: covariance of the free parameters, per-component residual
/// standard deviations, the head-zero uncertainty used and how the zero's uncertainty was propagated.
struct Uncertainty {
    cov: DMatrix<f64>,
    sigma_xyz: [f64; 3],
    head_zero: Option<[f64; 3]>,
    zero: ZeroUncertainty,
}

impl Problem<'_> {
    /// Readings minus the model at `theta`, three components per pose.
    fn residual(&self, theta: &[f64]) -> DVector<f64> {
        let mut r = DVector::zeros(self.nobs);
        for (i, pose) in self.poses.iter().enumerate() {
            let d = displacement_with(self.data, pose, self.setup[i], theta, self.effects);
            for c in 0..3 {
                r[3 * i + c] = self.meas[i][c] - d[c];
            }
        }
        r
    }

    /// The model's Jacobian in the free parameters at `theta`.
    fn jacobian(&self, theta: &[f64]) -> DMatrix<f64> {
        let m = &self.data.machine;
        let (poses, setup, n_base) = (&self.poses, &self.setup, self.n_base);
        let mut j = DMatrix::zeros(self.nobs, self.free.len());
        // Effect parameters enter linearly: their columns are the signatures at the current estimate.
        let sig: Vec<Vec<[f64; 3]>> = if self.effects.is_empty() {
            Vec::new()
        } else {
            poses
                .iter()
                .enumerate()
                .map(|(i, pose)| {
                    let (le, so) = split_params(theta, setup[i]);
                    self.effects.signatures(m, pose, &le, so)
                })
                .collect()
        };
        let h = 1.0; // 1 µm / 1 µrad: the model is nearly linear, central differences are exact to O(h²θ)
        for (c, &k) in self.free.iter().enumerate() {
            if k >= n_base {
                for (i, s) in sig.iter().enumerate() {
                    for cc in 0..3 {
                        j[(3 * i + cc, c)] = s[k - n_base][cc];
                    }
                }
                continue;
            }
            let mut tp = theta.to_vec();
            let mut tm = theta.to_vec();
            tp[k] += h;
            tm[k] -= h;
            for (i, pose) in poses.iter().enumerate() {
                if k >= N_LOCATION && (k - N_LOCATION) / N_SETUP != setup[i] {
                    continue;
                }
                let a = model_displacement(m, pose, setup[i], &tp);
                let b = model_displacement(m, pose, setup[i], &tm);
                for cc in 0..3 {
                    j[(3 * i + cc, c)] = (a[cc] - b[cc]) / (2.0 * h);
                }
            }
        }
        j
    }

    /// Levenberg–Marquardt from zero over the `p` parameters (only the free ones move).
    fn solve(&self, p: usize) -> Result<Solved, RtestError> {
        let free = &self.free;
        let mut theta = vec![0.0; p];
        let mut r = self.residual(&theta);
        let mut cost = r.norm_squared();
        let mut lambda = 1e-6;
        let mut iterations = 0;
        let mut j = self.jacobian(&theta);
        for _ in 0..30 {
            iterations += 1;
            let jtj = j.transpose() * &j;
            let jtr = j.transpose() * &r;
            let mut a = jtj.clone();
            for d in 0..free.len() {
                a[(d, d)] += lambda * jtj[(d, d)];
            }
            let step = match a.clone().cholesky() {
                Some(ch) => ch.solve(&jtr),
                None => a
                    .svd(true, true)
                    .solve(&jtr, 1e-12)
                    .map_err(|e| RtestError::Fit(e.to_string()))?,
            };
            let mut trial = theta.clone();
            for (c, &k) in free.iter().enumerate() {
                trial[k] += step[c];
            }
            let rt = self.residual(&trial);
            let ct = rt.norm_squared();
            if ct <= cost {
                let done = cost - ct <= 1e-12 * cost.max(1e-30) || step.norm() < 1e-9;
                theta = trial;
                r = rt;
                cost = ct;
                lambda = (lambda / 10.0).max(1e-12);
                if done {
                    break;
                }
                j = self.jacobian(&theta);
            } else {
                lambda *= 10.0;
                if lambda > 1e8 {
                    break;
                }
            }
        }
        Ok(Solved {
            theta,
            r,
            cost,
            iterations,
            j,
        })
    }

    /// Covariance of the free parameters at the solution, with the head zero's uncertainty (given, or the
    /// shared error's columns) propagated.
    fn uncertainty(
        &self,
        s: &Solved,
        rows: &[usize],
        opts: &FitOptions,
        shared: Option<&SharedError>,
    ) -> Result<Uncertainty, RtestError> {
        let (data, poses, nobs, j) = (self.data, &self.poses, self.nobs, &s.j);
        let jtj = j.transpose() * j;
        let inv = jtj
            .clone()
            .try_inverse()
            .or_else(|| jtj.pseudo_inverse(1e-12).ok())
            .ok_or_else(|| RtestError::Fit("singular normal matrix".into()))?;
        // Per-component residual variance (the three components come from different sensors, or from different
        // parts of a probed sphere): σ̂_c² = RSS_c / (n − p/3), and Cov = (JᵀJ)⁻¹·JᵀWJ·(JᵀJ)⁻¹ with
        // W = diag(σ̂_c²) — equal to σ̂²(JᵀJ)⁻¹ when the three are alike.
        let n_poses = poses.len() as f64;
        let dof_c = n_poses - self.free.len() as f64 / 3.0;
        let mut sigma_xyz = [0.0; 3];
        for (c, sc) in sigma_xyz.iter_mut().enumerate() {
            let rss: f64 = (0..poses.len()).map(|i| s.r[3 * i + c].powi(2)).sum();
            *sc = (rss / dof_c).sqrt();
        }
        let mut jw = j.clone();
        for (row, mut v) in jw.row_iter_mut().enumerate() {
            v *= sigma_xyz[row % 3].powi(2);
        }
        let mut cov = &inv * (j.transpose() * jw) * &inv;
        let head_zero = opts.head_zero_std_um.filter(|_| !data.free_head_zero);
        if let Some(sd) = head_zero {
            let g = &inv * (j.transpose() * self.head_zero_columns(&s.theta));
            let sh = DMatrix::from_diagonal(&DVector::from_iterator(3, sd.iter().map(|v| v * v)));
            cov += &g * sh * g.transpose();
        }
        let zero = if let Some(sd) = head_zero {
            ZeroUncertainty::Given(sd)
        } else if let Some(sh) = shared {
            let k = sh.components.len();
            let mut b = DMatrix::zeros(nobs, k);
            for (i, &row) in rows.iter().enumerate() {
                for (kk, l) in sh.loadings_um[row].iter().enumerate() {
                    for c in 0..3 {
                        b[(3 * i + c, kk)] = l[c];
                    }
                }
            }
            let g = &inv * (j.transpose() * b);
            cov += &g * g.transpose();
            ZeroUncertainty::Columns(sh.components.clone())
        } else if data.free_head_zero {
            ZeroUncertainty::Estimated
        } else {
            ZeroUncertainty::Exact
        };
        Ok(Uncertainty {
            cov,
            sigma_xyz,
            head_zero,
            zero,
        })
    }

    /// J_h: the readings' change per µm of the head zero (one offset for every row, whatever its set-up).
    fn head_zero_columns(&self, theta: &[f64]) -> DMatrix<f64> {
        let m = &self.data.machine;
        let mut jh = DMatrix::zeros(self.nobs, 3);
        for (i, pose) in self.poses.iter().enumerate() {
            let s = self.setup[i];
            for c in 0..3 {
                let k = N_LOCATION + N_SETUP * s + 3 + c;
                let mut tp = theta.to_vec();
                let mut tm = theta.to_vec();
                tp[k] += 1.0;
                tm[k] -= 1.0;
                let a = model_displacement(m, pose, s, &tp);
                let b = model_displacement(m, pose, s, &tm);
                for cc in 0..3 {
                    jh[(3 * i + cc, c)] = (a[cc] - b[cc]) / 2.0;
                }
            }
        }
        jh
    }

    /// The fit record: standard uncertainties and strong correlations (|r| > 0.9) of the free parameters.
    fn into_fit(self, s: Solved, u: Uncertainty, ident: Identifiability) -> Fit {
        let (free, cov, p) = (&self.free, &u.cov, s.theta.len());
        let dof = (self.nobs - free.len()) as f64;
        let sigma = (s.cost / dof).sqrt();
        let mut std = vec![None; p];
        for (c, &k) in free.iter().enumerate() {
            std[k] = Some(cov[(c, c)].max(0.0).sqrt());
        }
        let mut correlations = Vec::new();
        for a in 0..free.len() {
            for b in a + 1..free.len() {
                let rr = cov[(a, b)] / (cov[(a, a)] * cov[(b, b)]).sqrt();
                if rr.abs() > 0.9 {
                    correlations.push((free[a], free[b], rr));
                }
            }
        }
        let pred_rms = (s.cost / self.nobs as f64).sqrt();
        Fit {
            effects: self.effects.clone(),
            theta: s.theta,
            std,
            ident,
            correlations,
            fit_rms_um: pred_rms,
            sigma_um: sigma,
            sigma_xyz_um: u.sigma_xyz,
            iterations: s.iterations,
            head_zero_std_um: u.head_zero,
            zero_uncertainty: u.zero,
        }
    }
}

/// Every parameter's name: the location errors and set-up offsets ([`RtestData::param_names`]), then each
/// effect's as `kind.name` (`rotary_positioning.C_cos1`).
pub fn param_names_with(data: &RtestData, effects: &EffectSet) -> Vec<String> {
    let mut names = data.param_names();
    for t in &effects.terms {
        names.extend(
            t.param_names(data.machine.kind)
                .into_iter()
                .map(|(n, _)| format!("{}.{n}", t.kind)),
        );
    }
    names
}

/// Exact model displacement (µm) of `pose` in set-up `s` with parameters `theta` (location errors, set-up
/// offsets, then the effects' parameters).
pub fn displacement_with(
    data: &RtestData,
    pose: &Pose,
    s: usize,
    theta: &[f64],
    effects: &EffectSet,
) -> [f64; 3] {
    let mut d = model_displacement(&data.machine, pose, s, theta);
    if !effects.is_empty() {
        let (le, so) = split_params(theta, s);
        let e = effects.displacement(&data.machine, pose, &le, so, &theta[data.n_params()..]);
        for c in 0..3 {
            d[c] += e[c];
        }
    }
    d
}

/// `j` with the effects' signature columns (at the parameters `theta`) appended.
fn with_effect_columns(
    j: DMatrix<f64>,
    data: &RtestData,
    poses: &[Pose],
    effects: &EffectSet,
    theta: &[f64],
    setup: &[usize],
) -> DMatrix<f64> {
    let ne = effects.n_params(data.machine.kind);
    if ne == 0 {
        return j;
    }
    let p = j.ncols();
    let mut out = j.resize_horizontally(p + ne, 0.0);
    for (i, pose) in poses.iter().enumerate() {
        let (le, so) = split_params(theta, setup[i]);
        for (k, s) in effects
            .signatures(&data.machine, pose, &le, so)
            .iter()
            .enumerate()
        {
            for c in 0..3 {
                out[(3 * i + c, p + k)] = s[c];
            }
        }
    }
    out
}
