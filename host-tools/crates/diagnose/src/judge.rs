//! The verdict rule for every data kind: one column-level entry point ([`judge`]) that fits a base model
//! given as columns, measures its held-out gap, refits it with each candidate family added and decides
//! which candidate, if any, explains the gap. The single-axis diagnosis ([`crate::engine::diagnose`])
//! and the machine-level ones (laser lines, R-test, probe touches) build their columns and call it, so
//! the rule — Bonferroni-corrected training F-test, material held-out gain, local gain, ties by
//! held-out evidence — has one implementation.
//!
//! # Glossary
//! - **campaign** ([`Campaign`]): the target `y` over all rows (µm), the training and held-out row
//!   indices, and the base model's columns over all rows. Data with several components per point
//!   (e.g. R-test dx, dy, dz) are stacked as rows by the caller.
//! - **base model**: the columns of the model the user says holds (an intercept included when wanted),
//!   fitted by least squares on the training rows; [`Campaign::model`] names its terms (the trailing
//!   columns; leading columns not covered by a term, such as the intercept, are unnamed).
//! - **gap**: the base model's residual; on the held-out rows it is what the model fails to predict.
//! - **candidate family** ([`CandidateFamily`]): an unmodelled effect kind as a set of **variants**
//!   ([`CandidateVariant`]), each a set of columns for one setting of its searched nonlinear parameters
//!   (a period, a time constant, a form); `n_params` = columns + searched parameters. The best variant
//!   of a family is chosen by the training BIC of the whole refit.
//! - **refit**: least squares of base + candidate columns on the training rows (never a fit to the
//!   residual alone).
//! - **train test**: nested-model F-test of the refit against the base model, Bonferroni-corrected over
//!   every searched variant of every candidate.
//! - **σ**: the refit's training residual standard deviation (dof-corrected).
//! - **material**: the refit lowers the held-out RMS by ≥ [`MIN_SHRINK_PCT`] % of the gap and by
//!   ≥ [`MIN_NOISE_FRACTION`]·σ, or — for a localised candidate — by ≥ [`LOCAL_MIN_SHRINK_PCT`] % and
//!   ≥ [`LOCAL_MIN_NOISE_FRACTION`]·σ on the held-out rows where it acts ([`LocalGain`]).
//! - **explains**: passes the train test at `alpha` and is material ([`VERDICT_RULE`]).
//! - **score**: held-out ΔBIC `n_ho·ln(RSS_before/RSS_after) − k·ln(n_ho)` (ordering, not deciding).
//! - **shrink**: `100·(1 − rms_after/rms_before)` of the held-out gap.
//! - **ties**: explaining candidates the leader (lowest held-out RMS) does not beat on the held-out rows;
//!   the simplest of them is the verdict: not a **last resort** ([`CandidateFamily::last_resort`], e.g.
//!   the sensor-free `time_drift`) first, then fewer parameters, then the lower
//!   [`CandidateFamily::simplicity`] rank (a special case before its generalisation). A tied candidate
//!   replaces the simpler pick when it *encompasses* it on the training rows (its columns add
//!   significantly to the pick's refit, the pick's add nothing to its own).
//! - **blocks**: groups of training rows (runs, lines, time blocks) for blocked cross-validation and the
//!   block bootstrap (stability selection); reported, not used for the verdict.
//! - **where**: contiguous regions of the [`Campaign::where_variables`] holding most of the held-out gap.
//!
//! ```no_run
//! use axcomp_diagnose::judge::{judge, Campaign, CandidateFamily, CandidateVariant};
//! use axcomp_diagnose::DiagnoseOptions;
//! # let (y, x, train, holdout): (Vec<f64>, Vec<f64>, Vec<usize>, Vec<usize>) = unimplemented!();
//! let campaign = Campaign {
//!     target: "deviation_um".into(),
//!     y: &y,
//!     base_columns: vec![vec![1.0; y.len()]],
//!     train,
//!     holdout,
//!     where_variables: vec![("x_mm".into(), x.clone())],
//!     ..Campaign::default()
//! };
//! let slope = CandidateFamily::new("slope", vec![CandidateVariant::new(vec![x], Default::default(), 0)]);
//! let d = judge(&campaign, &[slope], &DiagnoseOptions::default()).unwrap();
//! println!("{} ({})", d.verdict, d.note);
//! ```

use crate::locate;
use crate::lsq::Projector;

mod evidence;
mod fitting;
mod refit;
mod rule;
mod types;
mod verdict;

use crate::error::DiagnoseError;
pub(crate) use fitting::{Progress, fit_all, lag1};
pub use fitting::{best_variant, select_variant};
use refit::{BaseModel, RefitContext, judge_family};
pub use rule::*;
pub use types::*;

/// Judges the candidates against the campaign's base model by the verdict rule ([`VERDICT_RULE`]; see
/// the module docs). Uses `opts.alpha` and `opts.progress`. The returned [`Diagnosis::model_columns`]
/// are the campaign's base columns as given.
pub fn judge(
    c: &Campaign,
    candidates: &[CandidateFamily],
    opts: &DiagnoseOptions,
) -> Result<Diagnosis, DiagnoseError> {
    c.validate()?;
    let progress = Progress {
        on: opts.progress,
        t0: std::time::Instant::now(),
    };
    let (train, hold) = (&c.train, &c.holdout);
    let base = BaseModel::fit(c);
    let where_vars: Vec<(&str, &[f64])> = c
        .where_variables
        .iter()
        .map(|(name, v)| (name.as_str(), v.as_slice()))
        .collect();
    let where_ = locate::locate_variables(&where_vars, hold, &base.fitted.resid, base.noise2);

    let total_variants: usize = candidates
        .iter()
        .map(|f| f.variants.len())
        .sum::<usize>()
        .max(1);
    let rc = RefitContext {
        c,
        base: &base,
        proj: Projector::new(&c.base_columns, train),
        r_tr: train.iter().map(|&i| base.fitted.resid[i]).collect(),
        total_variants,
        alpha: opts.alpha,
    };
    let mut effects = Vec::new();
    for (fi, f) in candidates.iter().enumerate() {
        progress.step(|| format!("searching {} ({} variants)", f.kind, f.variants.len()));
        effects.push(judge_family(&rc, fi, f)?);
    }
    drop(rc);
    evidence::add_evidence(&mut effects, candidates, c, opts.alpha, &progress);
    let setting = verdict::Setting {
        y: c.y,
        base_columns: &c.base_columns,
        train,
        hold,
        rss_holdout: base.rss_holdout,
        holdout_rms_um: base.gap.holdout_rms_um,
        total_variants,
        alpha: opts.alpha,
    };
    let verdict::Verdict {
        verdict,
        ties,
        note,
    } = verdict::decide(&mut effects, candidates, &setting);

    let verdict_where = match effects.first() {
        Some(e) if e.kind == verdict => {
            locate::locate_gain_variables(&where_vars, hold, &base.fitted.resid, &e.residual_after)
        }
        _ => Vec::new(),
    };
    // Only the verdict keeps its full-length columns (the report and the harness use them).
    for e in effects.iter_mut().filter(|e| e.kind != verdict) {
        e.residual_after = Vec::new();
        e.contribution_um = Vec::new();
    }
    let residual_checks = residual_checks(c, &base.fitted.resid);
    progress.step(|| format!("verdict {verdict}"));

    Ok(Diagnosis {
        target: c.target.clone(),
        n_train: train.len(),
        n_holdout: hold.len(),
        model: base.terms(c),
        gap: base.gap.clone(),
        where_,
        verdict_where,
        effects,
        verdict,
        verdict_rule: VERDICT_RULE.to_string(),
        note,
        ties,
        not_applicable: c.not_applicable.clone(),
        residual_checks,
        noise_um: base.noise2.sqrt(),
        residual: base.fitted.resid,
        model_columns: c.base_columns.clone(),
    })
}

/// Lag-1 autocorrelation of the base model's training residual in position and time order.
fn residual_checks(c: &Campaign, resid: &[f64]) -> ResidualChecks {
    let l1p = c.position_order.as_ref().map(|o| lag1(resid, o));
    let l1t = lag1(resid, &c.time_order);
    let sq = (c.train.len() as f64).sqrt();
    ResidualChecks {
        lag1_autocorr_position: l1p,
        lag1_autocorr_time: l1t,
        white_position: l1p.map(|r| r.abs() * sq < 3.0),
        white_time: l1t.abs() * sq < 3.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use axcomp_numeric::noise::TestNoise as Noise;
    use serde_json::{Map, Value};

    /// 600 rows on x ∈ [0, 100): y = 0.02·x + optional bump·sin(2πx/25) + N(0, 0.3²); every 4th block of
    /// 50 rows held out; base model = intercept + x.
    fn campaign_data(bump: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut rng = Noise(seed);
        let x: Vec<f64> = (0..600).map(|i| (i as f64 * 0.61803) % 100.0).collect();
        let y = x
            .iter()
            .map(|&x| {
                0.02 * x + bump * (2.0 * std::f64::consts::PI * x / 25.0).sin() + 0.3 * rng.normal()
            })
            .collect();
        (x, y)
    }

    fn judge_on(x: &[f64], y: &[f64]) -> Diagnosis {
        let train: Vec<usize> = (0..y.len()).filter(|i| (i / 50) % 4 != 3).collect();
        let holdout: Vec<usize> = (0..y.len()).filter(|i| (i / 50) % 4 == 3).collect();
        let campaign = Campaign {
            target: "e_um".into(),
            y,
            base_columns: vec![vec![1.0; y.len()], x.to_vec()],
            model: vec![ModelTerm {
                kind: "slope".into(),
                params: Map::new(),
                columns: 1,
            }],
            blocks: train.chunks(50).map(|b| b.to_vec()).collect(),
            train,
            holdout,
            where_variables: vec![("x_mm".into(), x.to_vec())],
            ..Campaign::default()
        };
        // A periodic family searched over 3 periods (one is right), and a quadratic.
        let periodic = CandidateFamily::new(
            "periodic",
            [10.0, 25.0, 40.0]
                .iter()
                .map(|&p| {
                    let cols = vec![
                        x.iter()
                            .map(|&x| (2.0 * std::f64::consts::PI * x / p).sin())
                            .collect(),
                        x.iter()
                            .map(|&x| (2.0 * std::f64::consts::PI * x / p).cos())
                            .collect(),
                    ];
                    let mut params = Map::new();
                    params.insert("period_mm".into(), Value::from(p));
                    CandidateVariant::new(cols, params, 1)
                })
                .collect(),
        );
        let quadratic = CandidateFamily::new(
            "quadratic",
            vec![CandidateVariant::new(
                vec![x.iter().map(|x| x * x).collect()],
                Map::new(),
                0,
            )],
        );
        judge(
            &campaign,
            &[periodic, quadratic],
            &DiagnoseOptions::default(),
        )
        .unwrap()
    }

    #[test]
    fn names_the_withheld_family_and_says_none_without_it() {
        // A 0.6 µm periodic term (2σ) withheld: the verdict is `periodic` with the right period, and the
        // held-out RMS after the refit is the noise σ = 0.3 within 20 % (150 held-out rows).
        let (x, y) = campaign_data(0.6, 7);
        let d = judge_on(&x, &y);
        assert_eq!(d.verdict, "periodic", "{}", d.note);
        let c = d.verdict_candidate().unwrap();
        assert_eq!(c.params["period_mm"], 25.0);
        assert!((c.holdout_rms_after_um - 0.3).abs() < 0.06, "{c:?}");
        assert_eq!(d.model_columns.len(), 2);
        // Nothing withheld: `none` on several noise draws.
        for seed in 1..=5 {
            let (x, y) = campaign_data(0.0, seed);
            let d = judge_on(&x, &y);
            assert_eq!(d.verdict, "none", "seed {seed}: {}", d.note);
            // The slope's coefficient (≤ 4 columns: reported) is 0.02 within 0.002 (its standard error
            // is 0.3/(29·√450) ≈ 0.0005: 4 standard errors).
            let slope = d.model[0].params["coefficients"][0].as_f64().unwrap();
            assert!((slope - 0.02).abs() < 0.002, "seed {seed}: {slope}");
        }
    }

    #[test]
    fn rejects_overlapping_rows_and_short_columns() {
        let y = vec![0.0; 10];
        let mut c = Campaign {
            y: &y,
            base_columns: vec![vec![1.0; 10]],
            train: (0..6).collect(),
            holdout: (5..10).collect(),
            ..Campaign::default()
        };
        assert!(c.validate().unwrap_err().to_string().contains("row 5"));
        c.holdout = (6..10).collect();
        c.base_columns.push(vec![1.0; 9]);
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("base column 1")
        );
    }
}
