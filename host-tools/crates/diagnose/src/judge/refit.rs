//! The base model's fit and each candidate's refit of the whole model, judged by the verdict rule's
//! numbers (training F-test, held-out shrink, materiality, local gain; see [`super`]).

use serde_json::Value;

use super::fitting::{Fitted, fit_all, max_corr, restrict, select_variant, ss, with_extra};
use super::rule::{is_material, local_gain};
use super::types::{Campaign, Candidate, CandidateFamily, Gap, ModelTerm};
use crate::error::DiagnoseError;
use crate::lsq::Projector;
use crate::stats;

/// The base model fitted on the training rows, and its gap.
pub(super) struct BaseModel {
    pub(super) fitted: Fitted,
    /// Sums of squares of the residual on the training and the held-out rows.
    pub(super) rss_train: f64,
    pub(super) rss_holdout: f64,
    /// Training residual variance (dof-corrected).
    pub(super) noise2: f64,
    pub(super) gap: Gap,
}

impl BaseModel {
    pub(super) fn fit(c: &Campaign) -> BaseModel {
        let base = fit_all(&c.base_columns, c.y, &c.train);
        let (n_tr, n_ho) = (c.train.len(), c.holdout.len());
        let rss0 = ss(&base.resid, &c.train);
        let rss_ho0 = ss(&base.resid, &c.holdout);
        let dof0 = n_tr.saturating_sub(base.fit.rank).max(1);
        let gap = Gap {
            train_rms_um: (rss0 / n_tr as f64).sqrt(),
            holdout_rms_um: (rss_ho0 / n_ho as f64).sqrt(),
            holdout_max_um: c
                .holdout
                .iter()
                .map(|&i| base.resid[i].abs())
                .fold(0.0, f64::max),
        };
        BaseModel {
            rss_train: rss0,
            rss_holdout: rss_ho0,
            noise2: rss0 / dof0 as f64,
            gap,
            fitted: base,
        }
    }

    /// The campaign's model terms with their fitted coefficients (terms of ≤ 4 columns).
    pub(super) fn terms(&self, c: &Campaign) -> Vec<ModelTerm> {
        let mut model_terms = c.model.clone();
        let mut k = c.base_columns.len() - model_terms.iter().map(|t| t.columns).sum::<usize>();
        for t in &mut model_terms {
            let coefs: Vec<f64> = self.fitted.fit.coef[k..k + t.columns].to_vec();
            if coefs.len() <= 4 {
                t.params.insert("coefficients".into(), Value::from(coefs));
            }
            k += t.columns;
        }
        model_terms
    }
}

/// What every candidate's refit is judged against.
pub(super) struct RefitContext<'a> {
    pub(super) c: &'a Campaign<'a>,
    pub(super) base: &'a BaseModel,
    pub(super) proj: Projector,
    /// The base model's training residual, on the training rows.
    pub(super) r_tr: Vec<f64>,
    pub(super) total_variants: usize,
    pub(super) alpha: f64,
}

/// The refit of the whole model with family `fi`'s best variant, judged by the verdict rule.
pub(super) fn judge_family(
    rc: &RefitContext,
    fi: usize,
    f: &CandidateFamily,
) -> Result<Candidate, DiagnoseError> {
    let (c, base) = (rc.c, rc.base);
    let (y, train, hold, base_cols) = (c.y, &c.train, &c.holdout, &c.base_columns);
    let (n, n_tr, n_ho) = (y.len(), train.len(), hold.len());
    if f.variants.is_empty() {
        return Err(DiagnoseError::Invalid(format!(
            "candidate `{}` has no variant",
            f.kind
        )));
    }
    let best = select_variant(&f.variants, &rc.proj, &rc.r_tr, train);
    let v = &f.variants[best.0];
    let v_cols = v.columns();
    if let Some(k) = v_cols.iter().position(|col| col.len() != n) {
        return Err(DiagnoseError::Invalid(format!(
            "candidate `{}`: column {k} has {} values, expected {n}",
            f.kind,
            v_cols[k].len()
        )));
    }
    let refit = fit_all(&with_extra(base_cols, &v_cols), y, train);
    let p0 = base.fitted.fit.rank;
    let q = refit.fit.rank.saturating_sub(p0);
    let (rss0, rss_ho0) = (base.rss_train, base.rss_holdout);
    let rss1 = ss(&refit.resid, train).min(rss0);
    let rss_ho1 = ss(&refit.resid, hold);
    let k_pen = (v.n_params - v_cols.len() + q) as f64;
    let dof1 = n_tr.saturating_sub(p0 + q).max(1) as f64;
    let p_train = if q == 0 || rss1 <= 0.0 {
        if q > 0 && rss0 > 0.0 { 0.0 } else { 1.0 }
    } else {
        let fstat = ((rss0 - rss1) / q as f64) / (rss1 / dof1);
        (axcomp_numeric::stats::f_sf(fstat, q as f64, dof1) * rc.total_variants as f64).min(1.0)
    };
    let d: Vec<f64> = hold
        .iter()
        .map(|&i| base.fitted.resid[i].powi(2) - refit.resid[i].powi(2))
        .collect();
    let (_, p_ho) = stats::paired_t(&d);
    let gap_um = base.gap.holdout_rms_um;
    let rms_after = (rss_ho1 / n_ho as f64).sqrt();
    let shrink = if gap_um > 0.0 {
        100.0 * (1.0 - rms_after / gap_um)
    } else {
        0.0
    };
    let score = if rss_ho1 > 0.0 && rss_ho0 > 0.0 {
        n_ho as f64 * (rss_ho0 / rss_ho1).ln() - k_pen * (n_ho as f64).ln()
    } else {
        0.0
    };
    let train_delta_bic = if rss1 > 0.0 && rss0 > 0.0 {
        n_tr as f64 * (rss0 / rss1).ln() - k_pen * (n_tr as f64).ln()
    } else {
        0.0
    };
    let sigma = (rss1 / dof1).sqrt();
    let gain = gap_um - rms_after;
    let coefs: Vec<f64> = refit.fit.coef[base_cols.len()..].to_vec();
    let contribution: Vec<f64> = (0..n)
        .map(|i| v_cols.iter().zip(&coefs).map(|(c, b)| c[i] * b).sum())
        .collect();
    let local = local_gain(&contribution, &base.fitted.resid, &refit.resid, hold, sigma);
    let material = is_material(gain, gap_um, sigma) || local.as_ref().is_some_and(|l| l.material);
    let mut params = v.params.clone();
    let peak = hold
        .iter()
        .map(|&i| contribution[i].abs())
        .fold(0.0, f64::max);
    params.insert("peak_holdout_um".into(), Value::from(peak));
    match &f.decorate {
        Some(decorate) => decorate(&mut params, &coefs),
        None => {
            params.insert("coefficients".into(), Value::from(coefs.clone()));
        }
    }
    Ok(Candidate {
        kind: f.kind.clone(),
        score,
        params,
        holdout_rms_after_um: rms_after,
        shrink_pct: shrink,
        n_params: v.n_params,
        train_rms_after_um: (rss1 / n_tr as f64).sqrt(),
        train_delta_bic,
        train_p_value: p_train,
        holdout_p_value: p_ho,
        holdout_gain_um: gain,
        noise_um: sigma,
        material,
        local,
        explains: p_train < rc.alpha && material,
        residual_correlation: max_corr(&rc.r_tr, &restrict(&v_cols, train)),
        cv_rms_before_um: None,
        cv_rms_after_um: None,
        inclusion_probability: 0.0,
        kind_enum: None,
        family_index: fi,
        variant_index: best.0,
        coefficients: coefs,
        contribution_um: contribution,
        residual_after: refit.resid,
    })
}
