//! Thermal (thermo-force) error model: per-run references, lags, the model choice, the fit and the
//! do-no-harm guard.
//!
//! Glossary:
//! - **sensor**: a temperature column `NAME_degC`; its **rise** is `ΔT = lag(T, τ) − T_ref`, `T_ref` = the
//!   reference reading: the first row of the file, or with runs ([`crate::runs`]) the first row of each run.
//! - **term**: `b · ΔT` (µm/K) per selected sensor; **force term**: `χ · F` (µm/N) per force column, fitted
//!   jointly with the thermal terms (coupled thermo-force model).
//! - **model**: `e = b0 + Σ b_s ΔT_s + Σ χ_f F_f`, the predicted error (µm), which the firmware subtracts.
//! - **training / held-out rows**: `--holdout` rows are never used for fitting or selection, only to judge.
//! - **raw**: the target minus its reference value (one run: the mean of its first `reference_rows` rows;
//!   several runs: each run's first row); every raw figure uses it.
//! - **model choice**: candidates judged by forward validation over runs or regime blocks, the plain
//!   references beside them, and the rule ([`crate::choice`]).
//! - **lag support**: in a single recording, a sensor whose training trace shows one episode of change gets
//!   lags only up to a third of it ([`LAG_CAP_FRACTION`]); lags never exceed a third of the longest run.
//! - **range guard**: on rows where a model sensor leaves the range it was fitted on by more than that
//!   range, that sensor's term is dropped ([`crate::choice`]).
//! - **do-no-harm guard**: with held-out rows, the model's RMS on them must not exceed raw; without, the
//!   default's validation RMS must not exceed raw over the same groups.

use nalgebra::DMatrix;
use serde::Serialize;

use crate::choice::rank_correlation;
use crate::choice::{self, Design, Kind, Structure};
use crate::prepare::{Prepared, refine_lags};
use crate::select::{self, Candidate};
use axcomp_numeric::lsq::{condition_number, lstsq, vif};
use axcomp_numeric::stats::rms;

pub use crate::input::{
    LAG_CAP_FRACTION, Ridge, Selection, ThermalError, ThermalInput, ThermalOptions,
};

pub use axcomp_effects::thermal_model::{ForceTerm, SensorTerm, Series, ThermalModel};

/// Report of one selection method.
#[derive(Debug, Clone, Serialize)]
pub struct MethodReport {
    pub method: String,
    /// Sensors chosen on all training rows.
    pub sensors: Vec<String>,
    pub tau_s: Vec<f64>,
    /// Inner CV RMS of the final choice (optimistic: the choice saw these folds).
    pub inner_cv_rms_um: f64,
    /// Transfer-validation RMS (the method re-run without each predicted block): the figure the candidates
    /// are compared by (`null` when not run).
    pub nested_cv_rms_um: f64,
    /// False when a forced selection (`--select`) did not run this method.
    pub ran: bool,
}

/// One candidate of the default model choice and its transfer-validation score.
#[derive(Debug, Clone, Serialize)]
pub struct CandidateReport {
    /// `plain_ls`, `greedy_lags`, `forward_lags`, `fcm_gra`, `ridge`.
    pub name: String,
    pub what: String,
    /// Structure chosen on all training rows.
    pub sensors: Vec<String>,
    pub tau_s: Vec<f64>,
    pub penalty: String,
    /// RMS over the predicted blocks, each predicted by the candidate chosen and fitted without it.
    pub validation_rms_um: f64,
    /// Per predicted block (same order as `validation.predicted_blocks`).
    pub validation_block_rms_um: Vec<f64>,
    /// The candidate as fitted on all training rows, on the held-out rows (reported, never used to choose).
    pub holdout_rms_um: Option<f64>,
    /// Sensors of the structure chosen on all training rows.
    pub n_sensors: usize,
    /// False when the firmware cannot take it (more sensors than its limit).
    pub eligible: bool,
    /// Lower validation RMS than plain least squares.
    pub beats_reference: bool,
    pub chosen: bool,
}

/// A plain reference judged by the same validation in the same run (the `references` of the JSON).
#[derive(Debug, Clone, Serialize)]
pub struct Reference {
    pub name: String,
    pub what: String,
    pub sensors: Vec<String>,
    pub tau_s: Vec<f64>,
    pub validation_rms_um: f64,
    /// Fitted on all training rows, on the held-out rows.
    pub holdout_rms_um: Option<f64>,
}

/// How the candidates were judged.
#[derive(Debug, Clone, Serialize)]
pub struct ValidationReport {
    /// `leave one block out` (`none` for a forced selection).
    pub scheme: String,
    /// The rule that cut the training rows into blocks.
    pub rule: String,
    pub blocks: Vec<String>,
    /// The blocks the scores are computed on.
    pub predicted_blocks: Vec<String>,
    /// RMS of the raw (zeroed) target over the predicted blocks.
    pub raw_rms_um: f64,
    /// Spearman rank correlation between the candidates' validation RMS and their held-out RMS (with
    /// held-out rows and at least 3 candidates).
    pub rank_correlation: Option<f64>,
}

/// Everything a thermal fit reports (serialized into the `--json` file).
#[derive(Debug, Clone, Serialize)]
pub struct ThermalFit {
    /// Selected sensor names.
    pub sensors: Vec<String>,
    /// RMS of the target minus its reference value (`raw_reference_um`) on the held-out rows (all rows
    /// without a holdout), before the model.
    pub raw_rms_um: f64,
    /// RMS of the residual on the held-out rows.
    pub holdout_rms_um: Option<f64>,
    /// Leave-one-condition-out RMS on the training rows (structure fixed, coefficients refit per fold).
    pub cv_rms_um: Option<f64>,
    pub train_raw_rms_um: f64,
    pub train_rms_um: f64,
    pub model: ThermalModel,
    pub formula: String,
    pub chosen_method: String,
    pub why: String,
    pub fcm_gra: MethodReport,
    pub forward: MethodReport,
    /// No selection (every usable sensor); `None` with more than 16 usable sensors.
    pub all_sensors: Option<MethodReport>,
    /// FCM + GRA details (`null` when a forced selection did not run it).
    pub fcm_gra_detail: Option<select::FcmGra>,
    /// The target's reference value (µm): raw figures are the target minus it.
    pub raw_reference_um: f64,
    /// The default's candidates with their validation scores (empty for a forced selection).
    pub candidates: Vec<CandidateReport>,
    /// The plain references judged the same way (empty for a forced selection).
    pub references: Vec<Reference>,
    /// The runs (`--runs`) in order; empty for a single recording.
    pub runs: Vec<String>,
    /// Per model sensor (same order as `model.terms`): the allowed rise (K) of the range guard.
    pub rise_bounds_k: Vec<(f64, f64)>,
    /// Held-out rows on which the range guard dropped a sensor's term.
    pub guarded_rows: usize,
    pub validation: ValidationReport,
    /// Forward selection path: (term added, inner CV RMS after it).
    pub forward_path: Vec<(String, f64)>,
    pub condition_number: f64,
    /// VIF per selected sensor term (same order as `model.terms`).
    pub vif: Vec<(String, f64)>,
    pub ridge_lambda: f64,
    pub lags: bool,
    pub lag_grid_s: Vec<f64>,
    /// Per usable sensor: whether the training rows support a lag for it (two or more separate episodes of
    /// change; otherwise only τ = 0 is tried).
    pub lag_supported: Vec<(String, bool)>,
    /// Per usable sensor (same order): the longest lag tried (s); `null` (infinite) with two or more
    /// episodes of change.
    pub lag_cap_s: Vec<f64>,
    /// How the inner CV grouped the training rows.
    pub inner_groups: String,
    pub per_condition: Vec<ConditionResidual>,
    pub excluded_sensors: Vec<(String, String)>,
    pub training_rows: usize,
    pub holdout_rows: usize,
    pub guard: Guard,
    /// Predictions per row (not serialized; for plots).
    #[serde(skip)]
    pub prediction: Vec<f64>,
}

/// RMS per operating condition (or per train/held-out part).
#[derive(Debug, Clone, Serialize)]
pub struct ConditionResidual {
    pub condition: String,
    pub rows: usize,
    pub held_out: bool,
    pub raw_rms_um: f64,
    pub rms_um: f64,
}

/// Outcome of the do-no-harm check.
#[derive(Debug, Clone, Serialize)]
pub struct Guard {
    pub passed: bool,
    /// What was compared.
    pub basis: String,
    pub reason: String,
}

fn check(input: &ThermalInput) -> Result<(), ThermalError> {
    let n = input.time_s.len();
    let mut cols: Vec<(&str, &[f64])> = vec![("time_s", &input.time_s), ("target", &input.target)];
    for s in input.sensors.iter().chain(&input.forces) {
        cols.push((&s.name, &s.values));
    }
    for (name, v) in cols {
        if v.len() != n {
            return Err(ThermalError::Length {
                column: name.into(),
                got: v.len(),
                want: n,
            });
        }
        if let Some(row) = v.iter().position(|x| !x.is_finite()) {
            return Err(ThermalError::NonFinite {
                column: name.into(),
                row: row + 1,
            });
        }
    }
    for (what, len) in [
        ("conditions", input.conditions.as_ref().map(|c| c.len())),
        ("holdout", input.holdout.as_ref().map(|c| c.len())),
        ("runs", input.runs.as_ref().map(|c| c.len())),
    ] {
        if let Some(l) = len
            && l != n
        {
            return Err(ThermalError::Length {
                column: what.into(),
                got: l,
                want: n,
            });
        }
    }
    Ok(())
}

/// The candidates of the default choice (or the one forced selection), and the reference kinds.
fn kinds_for(opts: &ThermalOptions, d: &Design) -> Result<Vec<Kind>, ThermalError> {
    let too_many = d.names.len() > d.sensor_limit;
    Ok(match opts.selection {
        Selection::Auto => {
            let mut k = vec![
                Kind::PlainLs,
                Kind::GreedyLags,
                Kind::ForwardLags,
                Kind::FcmGra,
            ];
            if opts.lags {
                k.push(Kind::AllLags);
            }
            if opts.ridge == Ridge::Auto {
                k.push(Kind::Ridge);
            }
            if too_many {
                k.push(Kind::PlainAll);
            }
            k
        }
        Selection::All if too_many => {
            return Err(ThermalError::Option(
                "--select all: more usable sensors than the firmware takes (16)",
            ));
        }
        Selection::All if opts.lags => vec![Kind::AllLags],
        Selection::All => vec![Kind::PlainLs],
        Selection::Forward => vec![Kind::ForwardLags],
        Selection::FcmGra => vec![Kind::FcmGra],
        Selection::Greedy => vec![Kind::GreedyLags],
    })
}

/// The candidates, their validation, references and the decision.
struct Chosen {
    kinds: Vec<Kind>,
    finals: Vec<Structure>,
    validation: choice::Validation,
    holdout: Vec<Option<f64>>,
    chosen: usize,
    why: String,
}

fn holdout_rms(d: &Design, s: &Structure, all: &[usize], held: &[usize]) -> Option<f64> {
    if held.is_empty() {
        return None;
    }
    let f = d.fit(s, all)?;
    let sse: f64 = held
        .iter()
        .map(|&i| (d.y[i] - d.predict_row(s, &f, i)).powi(2))
        .sum();
    Some((sse / held.len() as f64).sqrt())
}

fn choose(p: &Prepared, d: &Design, opts: &ThermalOptions) -> Result<Chosen, ThermalError> {
    let kinds = kinds_for(opts, d)?;
    let all: Vec<usize> = d.order.clone();
    let requested = opts.selection != Selection::Auto;
    let validation = if requested {
        choice::Validation {
            folds: vec![],
            sse: vec![vec![]; kinds.len()],
            rows: vec![],
        }
    } else {
        d.validate(&kinds)
    };
    let finals: Vec<Structure> = kinds.iter().map(|&k| d.structure(k, &all)).collect();
    let held_idx: Vec<usize> = (0..p.n).filter(|&i| p.held[i]).collect();
    let holdout = finals
        .iter()
        .map(|s| holdout_rms(d, s, &all, &held_idx))
        .collect();
    let (chosen, why) = if requested {
        (
            0,
            format!(
                "requested {} (a forced selection: no comparison of candidates was run)",
                kinds[0].name()
            ),
        )
    } else {
        // One regime among the training rows of a single recording: they cannot show how dropping
        // collinear sensors transfers to another regime; plain least squares is the only eligible one.
        let single_regime = !p.runs.per_run && !p.blocks.by_condition && p.blocks.regimes < 2;
        let eligible: Vec<bool> = kinds
            .iter()
            .zip(&finals)
            .map(|(&k, s)| {
                k != Kind::PlainAll
                    && d.sensors_in(s) <= d.sensor_limit
                    && (!single_regime || matches!(k, Kind::PlainLs | Kind::AllLags))
            })
            .collect();
        let simple: Vec<bool> = kinds
            .iter()
            .map(|k| matches!(k, Kind::PlainLs | Kind::GreedyLags))
            .collect();
        let dec = choice::decide(&kinds, &validation, &eligible, &simple, 0);
        let table = (0..kinds.len())
            .map(|k| format!("{} {:.4} µm", kinds[k].name(), validation.pooled_rms(k)))
            .collect::<Vec<_>>()
            .join(", ");
        let why = format!(
            "{} validation ({}): {table} → {}: {}",
            if d.forward {
                "forward"
            } else {
                "leave-one-condition-out"
            },
            p.blocks.rule,
            kinds[dec.chosen].name(),
            dec.why
        );
        (dec.chosen, why)
    };
    Ok(Chosen {
        kinds,
        finals,
        validation,
        holdout,
        chosen,
        why,
    })
}

fn describe(d: &Design, terms: &[usize]) -> (Vec<String>, Vec<f64>) {
    terms
        .iter()
        .filter_map(|&t| match d.cands[t] {
            Candidate::Sensor { sensor, tau_s } => Some((d.names[sensor].clone(), tau_s)),
            _ => None,
        })
        .unzip()
}

fn candidate_reports(d: &Design, c: &Chosen) -> Vec<CandidateReport> {
    let plain = c.validation.pooled_rms(0);
    (0..c.kinds.len())
        .filter(|&k| c.kinds[k] != Kind::PlainAll)
        .map(|k| {
            let (sensors, tau_s) = describe(d, &c.finals[k].terms);
            let n_sensors = sensors.len();
            CandidateReport {
                name: c.kinds[k].name().into(),
                what: c.kinds[k].what().into(),
                sensors,
                tau_s,
                penalty: if c.finals[k].ridge > 0.0 {
                    format!("ridge λ = {:e}", c.finals[k].ridge)
                } else {
                    "none".into()
                },
                validation_rms_um: c.validation.pooled_rms(k),
                validation_block_rms_um: c.validation.fold_rms(k),
                holdout_rms_um: c.holdout[k],
                n_sensors,
                eligible: n_sensors <= d.sensor_limit,
                beats_reference: k != 0 && c.validation.pooled_rms(k) < plain,
                chosen: k == c.chosen,
            }
        })
        .collect()
}

fn references(d: &Design, c: &Chosen) -> Vec<Reference> {
    let pick = |kind: Kind| c.kinds.iter().position(|&k| k == kind);
    let plain = pick(Kind::PlainAll).or(pick(Kind::PlainLs));
    [(plain, "plain_ls"), (pick(Kind::GreedyLags), "greedy_lags")]
        .into_iter()
        .filter_map(|(k, name)| {
            let k = k?;
            let (sensors, tau_s) = describe(d, &c.finals[k].terms);
            Some(Reference {
                name: name.into(),
                what: Kind::what(c.kinds[k]).into(),
                sensors,
                tau_s,
                validation_rms_um: c.validation.pooled_rms(k),
                holdout_rms_um: c.holdout[k],
            })
        })
        .collect()
}

fn method_report(d: &Design, c: &Chosen, kind: Kind, method: &str) -> MethodReport {
    match c.kinds.iter().position(|&k| k == kind) {
        Some(k) => {
            let (sensors, tau_s) = describe(d, &c.finals[k].terms);
            MethodReport {
                method: method.into(),
                sensors,
                tau_s,
                inner_cv_rms_um: d.gs.cv_rms(&c.finals[k].terms, &d.order, 0.0),
                nested_cv_rms_um: c.validation.pooled_rms(k),
                ran: true,
            }
        }
        None => MethodReport {
            method: method.into(),
            sensors: vec![],
            tau_s: vec![],
            inner_cv_rms_um: f64::NAN,
            nested_cv_rms_um: f64::NAN,
            ran: false,
        },
    }
}

/// The final model: the chosen structure, its lags refined, coefficients by least squares on the training
/// rows. Returns the model, the design matrix's condition number and the VIFs.
fn final_model(
    p: &Prepared,
    input: &ThermalInput,
    d: &Design,
    s: &Structure,
    refine: bool,
) -> Result<(ThermalModel, f64, Vec<(String, f64)>), ThermalError> {
    let mut sel: Vec<(usize, f64)> = s
        .terms
        .iter()
        .filter_map(|&t| match d.cands[t] {
            Candidate::Sensor { sensor, tau_s } => Some((sensor, tau_s)),
            _ => None,
        })
        .collect();
    if refine && p.grid.len() > 1 && sel.len() <= 8 {
        refine_lags(p, input, &mut sel, s.ridge);
    }
    let cols: Vec<Vec<f64>> = sel
        .iter()
        .map(|&(k, t)| p.sensor_rise(input, k, t))
        .chain(input.forces.iter().map(|f| f.values.clone()))
        .collect();
    let x = DMatrix::from_fn(p.train_idx.len(), cols.len() + 1, |r, c| {
        if c == 0 {
            1.0
        } else {
            cols[c - 1][p.train_idx[r]]
        }
    });
    let y: Vec<f64> = p.train_idx.iter().map(|&i| p.y_fit[i]).collect();
    let ls = lstsq(&x, &y, s.ridge, Some(0))?;
    let cond = condition_number(&x);
    let vifs = vif(&(0..sel.len())
        .map(|j| {
            p.train_idx
                .iter()
                .map(|&i| cols[j][i])
                .collect::<Vec<f64>>()
        })
        .collect::<Vec<_>>());
    let model = ThermalModel {
        b0_um: ls.coef[0],
        terms: sel
            .iter()
            .enumerate()
            .map(|(j, &(k, t))| SensorTerm {
                sensor: d.names[k].clone(),
                reference_degc: input.sensors[p.sens[k]].values[0],
                tau_s: t,
                coef_um_per_k: ls.coef[j + 1],
            })
            .collect(),
        forces: input
            .forces
            .iter()
            .enumerate()
            .map(|(f, s)| ForceTerm {
                column: s.name.clone(),
                chi_um_per_n: ls.coef[sel.len() + 1 + f],
            })
            .collect(),
    };
    let vif_named = sel
        .iter()
        .enumerate()
        .map(|(j, &(k, _))| (d.names[k].clone(), vifs[j]))
        .collect();
    Ok((model, cond, vif_named))
}

/// RMS per `--cv` condition, per run, or per training / held-out part.
fn per_condition(input: &ThermalInput, p: &Prepared, resid: &[f64]) -> Vec<ConditionResidual> {
    let labels: Vec<String> = match (&input.conditions, p.runs.per_run) {
        (Some(c), _) => c.clone(),
        (None, true) => p
            .runs
            .of_row
            .iter()
            .map(|&r| format!("run {}", p.runs.names[r]))
            .collect(),
        (None, false) => p
            .held
            .iter()
            .map(|&h| if h { "held-out rows" } else { "training rows" }.to_string())
            .collect(),
    };
    let mut order: Vec<&String> = vec![];
    for l in &labels {
        if !order.contains(&l) {
            order.push(l);
        }
    }
    order
        .into_iter()
        .map(|l| {
            let rows: Vec<usize> = (0..p.n).filter(|&i| &labels[i] == l).collect();
            ConditionResidual {
                condition: l.clone(),
                rows: rows.len(),
                held_out: rows.iter().all(|&i| p.held[i]),
                raw_rms_um: rms(&rows.iter().map(|&i| p.zeroed[i]).collect::<Vec<_>>()),
                rms_um: rms(&rows.iter().map(|&i| resid[i]).collect::<Vec<_>>()),
            }
        })
        .collect()
}

/// The do-no-harm guard (module docs).
fn do_no_harm(
    holdout: Option<(f64, f64)>,
    validation: Option<(f64, f64)>,
    cv: Option<(f64, f64)>,
    basis: &str,
) -> Guard {
    let verdict = |what: &str, got: f64, raw: f64, basis: String| Guard {
        passed: got <= raw,
        basis,
        reason: if got <= raw {
            format!("{what} RMS {got:.3} µm <= raw {raw:.3} µm")
        } else {
            format!("{what} RMS {got:.3} µm is worse than raw {raw:.3} µm (no compensation)")
        },
    };
    match (holdout, validation, cv) {
        (Some((h, raw)), v, _) => {
            let mut g = verdict("held-out", h, raw, "held-out rows".into());
            if let Some((v, vr)) = v {
                g.reason += &format!("; forward-validation RMS {v:.3} µm vs raw {vr:.3} µm");
            }
            g
        }
        (None, Some((v, raw)), _) => verdict(
            "forward-validation",
            v,
            raw,
            format!("forward validation over {basis}"),
        ),
        (None, None, Some((c, raw))) => verdict("cross-validated", c, raw, basis.into()),
        (None, None, None) => Guard {
            passed: true,
            basis: "none".into(),
            reason: "nothing to judge the model on (too few groups and no held-out rows)".into(),
        },
    }
}

/// Fits a thermo-force model (see the module docs and [`crate::choice`] for the procedure).
pub fn fit_thermal(
    input: &ThermalInput,
    opts: &ThermalOptions,
) -> Result<ThermalFit, ThermalError> {
    let opts = opts.build()?;
    check(input)?;
    let p = Prepared::new(input, &opts)?;
    let d = p.design(input, &opts);
    let c = choose(&p, &d, &opts)?;
    let requested = opts.selection != Selection::Auto;
    let mut chosen = c.finals[c.chosen].clone();
    // A fixed --ridge λ applies to the chosen structure.
    if let Ridge::Fixed(l) = opts.ridge {
        chosen.ridge = l;
    }
    let chosen = &chosen;
    // Lags are refined between grid points only in a single recording: with runs, the validated structure
    // (grid lags) is the model.
    let (model, cond, vif_named) = final_model(&p, input, &d, chosen, !p.runs.per_run)?;
    let all: Vec<usize> = d.order.clone();
    let rise_bounds_k = rise_bounds_of(&d, &model);
    let runs = if p.runs.per_run { Some(&p.runs) } else { None };
    let (prediction, guarded) = crate::runs::predict_campaign(
        &model,
        Some(&rise_bounds_k),
        &input.time_s,
        &input.sensors,
        &input.forces,
        runs,
    )
    .expect("model built from these columns");
    let f = residual_figures(&p, input.holdout.is_some(), &prediction, &guarded);
    let (train_raw, raw_rms, holdout_rms) = (f.train_raw, f.raw_rms, f.holdout_rms);
    let val_rows: usize = c.validation.rows.iter().sum();
    let val_raw = validation_raw_rms(&p, &d, &c);
    let cv_rms = p
        .blocks
        .by_condition
        .then(|| d.gs.cv_rms(&chosen.terms, &all, chosen.ridge));
    let validation =
        (!requested && val_rows > 0).then(|| (c.validation.pooled_rms(c.chosen), val_raw));
    let mut guard = do_no_harm(
        holdout_rms.map(|h| (h, raw_rms)),
        validation,
        cv_rms
            .or_else(|| Some(d.gs.cv_rms(&chosen.terms, &all, chosen.ridge)))
            .map(|v| (v, train_raw)),
        &p.blocks.rule,
    );
    let (candidates, references, rank_correlation) = if requested {
        (vec![], vec![], None)
    } else {
        ranked_reports(&p, &d, &c)
    };
    if !guard.passed {
        guard.reason += &helpful_references(&references, holdout_rms.map(|_| raw_rms), val_raw);
    }
    Ok(ThermalFit {
        sensors: model.terms.iter().map(|t| t.sensor.clone()).collect(),
        raw_rms_um: raw_rms,
        holdout_rms_um: holdout_rms,
        cv_rms_um: cv_rms,
        train_raw_rms_um: train_raw,
        train_rms_um: f.train_rms,
        formula: model.formula(),
        vif: vif_named,
        chosen_method: c.kinds[c.chosen].method_name().into(),
        why: c.why.clone(),
        fcm_gra: method_report(&d, &c, Kind::FcmGra, "fcm_gra"),
        forward: method_report(&d, &c, Kind::ForwardLags, "forward_cv"),
        all_sensors: (d.names.len() <= d.sensor_limit)
            .then(|| method_report(&d, &c, Kind::PlainLs, "all")),
        fcm_gra_detail: c.kinds.contains(&Kind::FcmGra).then(|| d.fcm_detail(&all)),
        raw_reference_um: p.target_ref,
        candidates,
        references,
        runs: if p.runs.per_run {
            p.runs.names.clone()
        } else {
            vec![]
        },
        rise_bounds_k,
        guarded_rows: f.guarded_rows,
        validation: validation_report(&p, &d, &c, requested, val_raw, rank_correlation),
        forward_path: forward_path(input, &d, &c),
        condition_number: cond,
        ridge_lambda: chosen.ridge,
        lags: opts.lags,
        lag_grid_s: p.grid.clone(),
        lag_cap_s: p.lag_cap.clone(),
        lag_supported: d
            .names
            .iter()
            .cloned()
            .zip(
                p.lag_cap
                    .iter()
                    .map(|cap| *cap >= p.grid.get(1).copied().unwrap_or(f64::INFINITY)),
            )
            .collect(),
        inner_groups: p.blocks.rule.clone(),
        per_condition: per_condition(input, &p, &f.resid),
        excluded_sensors: p.excluded.clone(),
        training_rows: p.train_idx.len(),
        holdout_rows: p.n - p.train_idx.len(),
        guard,
        model,
        prediction,
    })
}

/// The fitted model's residuals and RMS figures on the training and held-out rows.
struct Figures {
    resid: Vec<f64>,
    train_raw: f64,
    train_rms: f64,
    /// Raw RMS on the held-out rows (on every row without a holdout).
    raw_rms: f64,
    holdout_rms: Option<f64>,
    /// Held-out rows on which the range guard dropped a term.
    guarded_rows: usize,
}

fn residual_figures(
    p: &Prepared,
    has_holdout: bool,
    prediction: &[f64],
    guarded: &[bool],
) -> Figures {
    let resid: Vec<f64> = p.y_fit.iter().zip(prediction).map(|(y, q)| y - q).collect();
    let pick = |v: &[f64], h: bool| -> Vec<f64> {
        (0..p.n).filter(|&i| p.held[i] == h).map(|i| v[i]).collect()
    };
    let (raw_rms, holdout_rms) = if has_holdout {
        (rms(&pick(&p.zeroed, true)), Some(rms(&pick(&resid, true))))
    } else {
        (rms(&p.zeroed), None)
    };
    Figures {
        train_raw: rms(&pick(&p.zeroed, false)),
        train_rms: rms(&pick(&resid, false)),
        raw_rms,
        holdout_rms,
        guarded_rows: (0..p.n).filter(|&i| p.held[i] && guarded[i]).count(),
        resid,
    }
}

/// For a refusal: the plain references that are better than no model (on the held-out rows when there
/// are, else in validation), with the option that fits each.
fn helpful_references(references: &[Reference], holdout_raw: Option<f64>, val_raw: f64) -> String {
    let helpful: Vec<String> = references
        .iter()
        .filter_map(|r| {
            let (what, got, raw) = match (holdout_raw, r.holdout_rms_um) {
                (Some(raw), Some(h)) => ("held-out", h, raw),
                _ => ("validation", r.validation_rms_um, val_raw),
            };
            let how = match r.name.as_str() {
                "greedy_lags" => "--select greedy",
                _ if r.sensors.len() <= axcomp_core::MAX_SENSORS => "--select all",
                _ => "--select all --sensors with at most 16 of them",
            };
            (got < raw).then(|| {
                format!(
                    "{} ({how}): {what} RMS {got:.3} µm < raw {raw:.3} µm",
                    r.name
                )
            })
        })
        .collect();
    if helpful.is_empty() {
        "; no plain reference is better than no model either".into()
    } else {
        format!("; better than no model: {}", helpful.join(", "))
    }
}

/// How the candidates were judged (scheme, groups, the raw RMS over the predicted groups, rank correlation).
fn validation_report(
    p: &Prepared,
    d: &Design,
    c: &Chosen,
    requested: bool,
    val_raw: f64,
    rank_correlation: Option<f64>,
) -> ValidationReport {
    ValidationReport {
        scheme: if requested {
            "none (forced selection)".into()
        } else if d.forward {
            "forward in time".into()
        } else {
            "leave one condition out".into()
        },
        rule: p.blocks.rule.clone(),
        blocks: p.blocks.names.clone(),
        predicted_blocks: c
            .validation
            .folds
            .iter()
            .map(|(_, g)| p.blocks.names[*g].clone())
            .collect(),
        raw_rms_um: val_raw,
        rank_correlation,
    }
}

/// Per model term: the range guard's bounds of its sensor after fitting on every group.
fn rise_bounds_of(d: &Design, model: &ThermalModel) -> Vec<(f64, f64)> {
    let bounds_all = d.bounds(&d.order);
    model
        .terms
        .iter()
        .map(|t| {
            bounds_all[d
                .names
                .iter()
                .position(|n| *n == t.sensor)
                .expect("model sensor")]
        })
        .collect()
}

/// RMS of the raw (zeroed) target over the validation's predicted groups (NaN without folds).
fn validation_raw_rms(p: &Prepared, d: &Design, c: &Chosen) -> f64 {
    let rows: usize = c.validation.rows.iter().sum();
    if rows == 0 {
        return f64::NAN;
    }
    let sq: f64 = c
        .validation
        .folds
        .iter()
        .flat_map(|(_, g)| d.group_rows[*g].iter())
        .map(|&i| p.zeroed[i].powi(2))
        .sum();
    (sq / rows as f64).sqrt()
}

/// The candidates' reports (eligibility as the rule saw it), the plain references and the rank
/// correlation between the candidates' validation and held-out RMS.
fn ranked_reports(
    p: &Prepared,
    d: &Design,
    c: &Chosen,
) -> (Vec<CandidateReport>, Vec<Reference>, Option<f64>) {
    let single_regime = !p.runs.per_run && !p.blocks.by_condition && p.blocks.regimes < 2;
    let mut candidates = candidate_reports(d, c);
    if single_regime {
        candidates.iter_mut().for_each(|k| {
            k.eligible &= k.name == Kind::PlainLs.name() || k.name == Kind::AllLags.name()
        });
    }
    let (a, b): (Vec<f64>, Vec<f64>) = candidates
        .iter()
        .filter_map(|k| Some((k.validation_rms_um, k.holdout_rms_um?)))
        .unzip();
    let rank = rank_correlation(&a, &b);
    candidates
        .iter_mut()
        .for_each(|k| k.eligible &= k.name != Kind::PlainAll.name());
    (candidates, references(d, c), rank)
}

/// The forward-selection path on every group (sensor or force, inner CV RMS after adding it).
fn forward_path(input: &ThermalInput, d: &Design, c: &Chosen) -> Vec<(String, f64)> {
    if !c.kinds.contains(&Kind::ForwardLags) {
        return vec![];
    }
    let fb = select::forward(&d.gs, &d.cands, &d.forced, &d.order, d.max_sensors, 0.01);
    fb.steps
        .iter()
        .map(|s| match d.cands[s.candidate] {
            Candidate::Sensor { sensor, tau_s } => {
                (format!("{} (τ={:.0} s)", d.names[sensor], tau_s), s.cv_rms)
            }
            Candidate::Force { force } => (input.forces[force].name.clone(), s.cv_rms),
        })
        .collect()
}
