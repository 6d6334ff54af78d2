//! Which parameters the poses determine: the identifiability of the location errors, the set-up
//! offsets and the effect parameters (see the crate's glossary: *identifiable*).

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::{CONFOUND_TOL, N_LOCATION, PRIORITY, VIF_LIMIT};

/// Which parameters the poses determine (see the glossary).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Identifiability {
    /// Number of parameters estimated (structurally separable on these poses).
    pub rank: usize,
    /// Condition number of the column-scaled sensitivity matrix of the estimated parameters.
    pub condition_number: f64,
    /// Estimated in the fit (not fixed to 0).
    pub estimated: Vec<bool>,
    /// Estimated, separable and not weakly determined: a value to rely on.
    pub identified: Vec<bool>,
    /// Why a parameter is not identified (`None` when it is).
    pub reasons: Vec<Option<String>>,
}

/// Identifiability of `j`'s columns (`names` for messages). Set-up offsets (index ≥ 11) are taken first.
/// Parameters with `fixed[k] = Some(reason)` are held at zero by assumption.
///
/// - *not separable* (own signature < [`CONFOUND_TOL`]): fixed to 0, not identified; the location errors it
///   is confounded with then absorb its effect, so they are not identified either ("only in combination").
/// - *weakly determined* (variance inflation > [`VIF_LIMIT`]): still estimated (its standard uncertainty
///   says how poorly), but not identified.
pub fn identifiability(
    j: &DMatrix<f64>,
    names: &[String],
    fixed: &[Option<String>],
) -> Identifiability {
    identifiability_ordered(j, names, fixed, j.ncols())
}

/// [`identifiability`] of a model whose columns from `n_base` on are effect parameters
/// ([`effects`]): taken after the location errors, and checked for variance inflation like them.
pub fn identifiability_ordered(
    j: &DMatrix<f64>,
    names: &[String],
    fixed: &[Option<String>],
    n_base: usize,
) -> Identifiability {
    let p = j.ncols();
    let is_setup = |k: usize| (N_LOCATION..n_base).contains(&k);
    let norms: Vec<f64> = (0..p).map(|k| j.column(k).norm()).collect();
    let scaled = |cols: &[usize]| -> DMatrix<f64> {
        let mut m = DMatrix::zeros(j.nrows(), cols.len());
        for (c, &k) in cols.iter().enumerate() {
            m.set_column(c, &(j.column(k) / norms[k]));
        }
        m
    };
    let order: Vec<usize> = (N_LOCATION..n_base)
        .chain(PRIORITY.iter().copied())
        .chain(n_base..p)
        .collect();
    let mut chosen: Vec<usize> = Vec::new();
    let mut estimated = vec![false; p];
    let mut reasons: Vec<Option<String>> = vec![None; p];
    // Location errors whose value absorbs a fixed one: (k, names of the fixed ones).
    let mut absorbs: Vec<Vec<String>> = vec![Vec::new(); p];
    for &k in &order {
        if let Some(r) = &fixed[k] {
            reasons[k] = Some(r.clone());
            continue;
        }
        if norms[k] < 1e-12 {
            reasons[k] = Some("no effect on any measured pose; fixed to 0".into());
            continue;
        }
        let col = j.column(k) / norms[k];
        if chosen.is_empty() {
            chosen.push(k);
            estimated[k] = true;
            continue;
        }
        let a = scaled(&chosen);
        let svd = a.clone().svd(true, true);
        let beta = svd
            .solve(&col, 1e-12)
            .unwrap_or_else(|_| DVector::zeros(chosen.len()));
        let resid = (&col - &a * &beta).norm();
        if resid >= CONFOUND_TOL {
            chosen.push(k);
            estimated[k] = true;
        } else {
            let bmax = beta.iter().fold(0.0f64, |m, b| m.max(b.abs()));
            let mut partners: Vec<(f64, usize)> = chosen
                .iter()
                .zip(beta.iter())
                .filter(|(_, b)| b.abs() > 0.05 * bmax)
                .map(|(&c, b)| (b.abs(), c))
                .collect();
            partners.sort_by(|a, b| b.0.total_cmp(&a.0));
            let list: Vec<&str> = partners.iter().map(|p| names[p.1].as_str()).collect();
            for &(_, c) in &partners {
                if !is_setup(c) {
                    absorbs[c].push(names[k].clone());
                }
            }
            reasons[k] = Some(format!(
                "not separable from {} on these poses (only {:.1e} of its signature is its own); fixed to 0",
                list.join(", "),
                resid
            ));
        }
    }
    let mut identified = estimated.clone();
    for k in 0..p {
        if estimated[k] && !absorbs[k].is_empty() {
            identified[k] = false;
            reasons[k] = Some(format!(
                "determined only in combination with {} (fixed to 0): its value absorbs their effect",
                absorbs[k].join(", ")
            ));
        }
    }
    let mut idx = chosen.clone();
    idx.sort_unstable();
    let a = scaled(&idx);
    if let Some(inv) = (a.transpose() * &a).try_inverse() {
        for (c, &k) in idx.iter().enumerate() {
            let vif = inv[(c, c)];
            if is_setup(k) || vif <= VIF_LIMIT || !identified[k] {
                continue;
            }
            let mut partners: Vec<(f64, &str)> = idx
                .iter()
                .enumerate()
                .filter(|(d, _)| *d != c)
                .map(|(d, &kk)| {
                    (
                        (inv[(c, d)] / (inv[(c, c)] * inv[(d, d)]).sqrt()).abs(),
                        names[kk].as_str(),
                    )
                })
                .filter(|(r, _)| *r > 0.9)
                .collect();
            partners.sort_by(|a, b| b.0.total_cmp(&a.0));
            let list: Vec<String> = partners
                .iter()
                .take(4)
                .map(|(r, n)| format!("{n} (|r| {r:.2})"))
                .collect();
            identified[k] = false;
            reasons[k] = Some(format!(
                "weakly determined on these poses: its uncertainty is inflated {:.0}× by correlation with {}; estimated, see std",
                vif.sqrt(),
                if list.is_empty() {
                    "several parameters".to_string()
                } else {
                    list.join(", ")
                }
            ));
        }
    }
    let sv = a.singular_values();
    let smax = sv.iter().fold(0.0f64, |m, s| m.max(*s));
    let smin = sv.iter().fold(f64::INFINITY, |m, s| m.min(*s));
    Identifiability {
        rank: chosen.len(),
        condition_number: smax / smin,
        estimated,
        identified,
        reasons,
    }
}
