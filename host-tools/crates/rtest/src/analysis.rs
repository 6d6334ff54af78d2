//! The whole `fit rtest` analysis: fit on the training rows, judge on held-out rows (or by leave-one-group-out
//! cross-validation), the ISO 10791-6 K4 figures before and after, and the JSON of the contract.

use axcomp_data::{Dataset, Split};
use serde_json::{Map, Value, json};

use crate::{Fit, RtestData, RtestError, RtestModel, SIGN_CONVENTION, ranges, rms3};
use axcomp_kinematics::rotary::{N_LOCATION, N_SETUP};

/// Everything `fit rtest` reports.
#[derive(Debug, Clone)]
pub struct Analysis {
    /// The fit on the training rows (all rows without a split, all rows but the held-out ones with
    /// `--holdout`, all rows with `--cv`).
    pub fit: Fit,
    pub model: RtestModel,
    /// Rows used for the fit.
    pub fit_rows: Vec<usize>,
    /// Rows judged (held out, or every row in CV, or the fitted rows without a split) and their
    /// predictions (held-out / cross-validated / in-sample).
    pub judged_rows: Vec<usize>,
    pub judged_pred: Vec<[f64; 3]>,
    /// `"holdout"`, `"cv"` or `"fit"`.
    pub judged_by: &'static str,
    pub raw_rms_um: f64,
    pub judged_rms_um: f64,
    /// Judged RMS of the full model (every identifiable location error estimated).
    pub full_rms_um: f64,
    /// Judged RMS of the nominal kinematics with only the sphere's set-up offsets fitted.
    pub nominal_setup_rms_um: f64,
    /// The default's selection in the reported fit (`None`: the full model was asked for).
    pub selection: Option<crate::select::Selection>,
    pub k4: Option<K4Figures>,
    /// Poses revisited in later runs and their closure drift ([`crate::revisit`]).
    pub closure: Vec<crate::revisit::Revisit>,
}

/// ISO 10791-6 K4 figures on the judged rows of the K4 path.
#[derive(Debug, Clone, Copy)]
pub struct K4Figures {
    pub rows: usize,
    pub before_um: [f64; 3],
    pub after_um: [f64; 3],
    /// The K4 rows were fitted, not judged (a hold-out of other paths): "after" is the in-sample fit's.
    pub in_sample: bool,
}

/// Rows that belong to the K4 path: `path` equal to `K4` (any case), or every row when no row names a path.
pub fn k4_rows(data: &RtestData, rows: &[usize]) -> Vec<usize> {
    if data.path.iter().all(|p| p.is_empty()) {
        return rows.to_vec();
    }
    rows.iter()
        .copied()
        .filter(|&r| data.path[r].eq_ignore_ascii_case("k4"))
        .collect()
}

fn predict_with(fit: &Fit, data: &RtestData, rows: &[usize]) -> Result<Vec<[f64; 3]>, RtestError> {
    rows.iter()
        .map(|&r| {
            Ok(crate::displacement_with(
                data,
                &data.poses[r],
                data.setup[r],
                &fit.theta,
                &fit.effects,
            ))
        })
        .collect()
}

fn check_setups_known(
    data: &RtestData,
    fit_rows: &[usize],
    judged: &[usize],
) -> Result<(), RtestError> {
    for &r in judged {
        if !fit_rows.iter().any(|&f| data.setup[f] == data.setup[r]) {
            return Err(RtestError::Fit(format!(
                "{} line {}: set-up `{}` has no fitted rows, so its sphere offsets are unknown and the row cannot be predicted",
                data.source, data.lines[r], data.setup_names[data.setup[r]]
            )));
        }
    }
    Ok(())
}

/// Rows fitted, rows judged, their predictions, how they were judged, and the fit on the fitted rows (all
/// rows with `--cv`), for one way of fitting (`fitter` on a set of rows).
type Judged = (Vec<usize>, Vec<usize>, Vec<[f64; 3]>, &'static str, Fit);

fn judge(
    ds: &Dataset,
    data: &RtestData,
    split: Option<&Split>,
    fitter: &dyn Fn(&[usize]) -> Result<Fit, RtestError>,
) -> Result<Judged, RtestError> {
    let n = data.poses.len();
    let all: Vec<usize> = (0..n).collect();
    Ok(match split {
        None => {
            let f = fitter(&all)?;
            let pred = predict_with(&f, data, &all)?;
            (all.clone(), all.clone(), pred, "fit", f)
        }
        Some(Split::Holdout(h)) => {
            let mask = h.mask(ds)?;
            let train: Vec<usize> = all.iter().copied().filter(|&r| !mask[r]).collect();
            let test: Vec<usize> = all.iter().copied().filter(|&r| mask[r]).collect();
            check_setups_known(data, &train, &test)?;
            let f = fitter(&train)?;
            let pred = predict_with(&f, data, &test)?;
            (train, test, pred, "holdout", f)
        }
        Some(Split::Cv(col)) => {
            let (ids, labels) = axcomp_data::groups(ds, col)?;
            if labels.len() < 2 {
                return Err(RtestError::Fit(format!(
                    "--cv {col}: a single group `{}`, nothing to leave out",
                    labels.first().cloned().unwrap_or_default()
                )));
            }
            let mut pred = vec![[0.0; 3]; n];
            #[allow(clippy::needless_range_loop)] // parallel arrays indexed together
            for g in 0..labels.len() {
                let train: Vec<usize> = all.iter().copied().filter(|&r| ids[r] != g).collect();
                let test: Vec<usize> = all.iter().copied().filter(|&r| ids[r] == g).collect();
                check_setups_known(data, &train, &test)?;
                let f = fitter(&train).map_err(|e| {
                    RtestError::Fit(format!("--cv {col}: leaving out `{}`: {e}", labels[g]))
                })?;
                for (&r, p) in test.iter().zip(predict_with(&f, data, &test)?) {
                    pred[r] = p;
                }
            }
            let f = fitter(&all)?;
            (all.clone(), all.clone(), pred, "cv", f)
        }
    })
}

/// Measured minus predicted on `rows`.
fn residuals(data: &RtestData, rows: &[usize], pred: &[[f64; 3]]) -> Vec<[f64; 3]> {
    rows.iter()
        .zip(pred)
        .map(|(&r, p)| {
            let m = data.d_um[r];
            [m[0] - p[0], m[1] - p[1], m[2] - p[2]]
        })
        .collect()
}

/// Runs the analysis with the full model (every identifiable location error; no selection: what
/// `fit rtest --full-model` does; the CLI's default is [`analyse_selected`]).
pub fn analyse(
    ds: &Dataset,
    data: &RtestData,
    split: Option<&Split>,
) -> Result<Analysis, RtestError> {
    analyse_with(ds, data, split, &crate::FitOptions::default())
}

/// [`analyse`] with fit options (the head zero's uncertainty).
pub fn analyse_with(
    ds: &Dataset,
    data: &RtestData,
    split: Option<&Split>,
    opts: &crate::FitOptions,
) -> Result<Analysis, RtestError> {
    analyse_shared(ds, data, split, opts, None)
}

/// [`analyse_with`] with the zero's shared error ([`crate::SharedError`], e.g. read from the data by
/// [`crate::read_shared_error`]) propagated into every fit's standard uncertainties.
pub fn analyse_shared(
    ds: &Dataset,
    data: &RtestData,
    split: Option<&Split>,
    opts: &crate::FitOptions,
    shared: Option<&crate::SharedError>,
) -> Result<Analysis, RtestError> {
    analyse_selected(ds, data, split, opts, shared, false)
}

/// Groups of rows for the default's selection ([`crate::select`]): the `path` column's values when the
/// file has that column, else the `run` column's when it has at least two; `None` without either. Runs of
/// one path are repeats: one predicting the other says nothing about another path (on the twin, K4 run 1
/// predicts run 2 of K4 well with spurious location errors that predict the circles 6× worse than the
/// set-up offsets alone), so with a `path` column the runs are not cross-checked on.
pub fn selection_groups(ds: &Dataset) -> Result<Option<(Vec<usize>, &'static str)>, RtestError> {
    if ds.has("path") {
        let (ids, _) = axcomp_data::groups(ds, "path")?;
        return Ok(Some((ids, "path")));
    }
    if ds.has("run") {
        let (ids, labels) = axcomp_data::groups(ds, "run")?;
        if labels.len() >= 2 {
            return Ok(Some((ids, "run")));
        }
    }
    Ok(None)
}

/// What `fit rtest` does by default (`select`): [`analyse_shared`] with the do-no-harm selection of
/// location errors ([`crate::select::fit_selected`]) inside every fit — on the training rows of a hold-out,
/// inside every fold of a cross-validation. The full model (every identifiable location error) and the
/// nominal kinematics with the set-up offsets only are judged on the same rows alongside.
pub fn analyse_selected(
    ds: &Dataset,
    data: &RtestData,
    split: Option<&Split>,
    opts: &crate::FitOptions,
    shared: Option<&crate::SharedError>,
    select: bool,
) -> Result<Analysis, RtestError> {
    analyse_effects(
        ds,
        data,
        split,
        opts,
        shared,
        select,
        &crate::effects::EffectSet::default(),
    )
}

/// [`analyse_selected`] with effect terms in the model (`fit rtest --effects`). With effects the full
/// location-error model is fitted alongside them (no do-no-harm selection: it guards against effects the
/// model does not hold, and the named ones are now held); the reports' "full model" is then the
/// location errors alone, fitted the same way, so that the gain of the effects is shown in the same run.
pub fn analyse_effects(
    ds: &Dataset,
    data: &RtestData,
    split: Option<&Split>,
    opts: &crate::FitOptions,
    shared: Option<&crate::SharedError>,
    select: bool,
    effects: &crate::effects::EffectSet,
) -> Result<Analysis, RtestError> {
    let with_effects = !effects.is_empty();
    let select = select && !with_effects;
    let groups = if select { selection_groups(ds)? } else { None };
    let full_fitter = |rows: &[usize]| crate::fit_shared(data, rows, opts, shared);
    let (fit_rows, judged_rows, full_pred, judged_by, full_fit) =
        judge(ds, data, split, &full_fitter)?;
    let full_rms_um = rms3(&residuals(data, &judged_rows, &full_pred));
    let last_selection = std::cell::RefCell::new(None);
    let (judged_pred, fit, selection) = if with_effects {
        let eff_fitter =
            |rows: &[usize]| crate::fit_effects(data, rows, opts, shared, &[], effects);
        let (_, _, pred, _, f) = judge(ds, data, split, &eff_fitter)?;
        (pred, f, None)
    } else if select {
        let sel_fitter = |rows: &[usize]| {
            let (f, s) = crate::select::fit_selected(
                data,
                rows,
                opts,
                shared,
                groups.as_ref().map(|(ids, what)| (ids.as_slice(), *what)),
            )?;
            *last_selection.borrow_mut() = Some(s);
            Ok(f)
        };
        let (_, _, pred, _, f) = judge(ds, data, split, &sel_fitter)?;
        (pred, f, last_selection.into_inner())
    } else {
        (full_pred, full_fit, None)
    };
    // The plain reference: the nominal kinematics with only the sphere's set-up offsets fitted (all 11
    // location errors held at zero), judged on the same rows the same way.
    let nominal_fix: Vec<Option<String>> =
        vec![Some("held at zero: the nominal kinematics (plain reference)".into()); N_LOCATION];
    let nominal_fitter = |rows: &[usize]| crate::fit_fixed(data, rows, opts, shared, &nominal_fix);
    let (_, _, nominal_pred, _, _) = judge(ds, data, split, &nominal_fitter)?;
    let nominal_setup_rms_um = rms3(&residuals(data, &judged_rows, &nominal_pred));
    let meas: Vec<[f64; 3]> = judged_rows.iter().map(|&r| data.d_um[r]).collect();
    let resid: Vec<[f64; 3]> = meas
        .iter()
        .zip(&judged_pred)
        .map(|(m, p)| [m[0] - p[0], m[1] - p[1], m[2] - p[2]])
        .collect();
    let raw_rms_um = rms3(&meas);
    let judged_rms_um = rms3(&resid);
    let k4_idx: Vec<usize> = {
        let k4 = k4_rows(data, &judged_rows);
        judged_rows
            .iter()
            .enumerate()
            .filter(|(_, r)| k4.contains(r))
            .map(|(i, _)| i)
            .collect()
    };
    let k4_fitted = k4_rows(data, &fit_rows);
    let k4 = if k4_idx.len() >= 2 {
        let b: Vec<[f64; 3]> = k4_idx.iter().map(|&i| meas[i]).collect();
        let a: Vec<[f64; 3]> = k4_idx.iter().map(|&i| resid[i]).collect();
        Some(K4Figures {
            rows: k4_idx.len(),
            before_um: ranges(&b),
            after_um: ranges(&a),
            in_sample: judged_by == "fit",
        })
    } else if k4_fitted.len() >= 2 {
        // K4 among the fitted rows only (a hold-out of other paths): the figures from the fit.
        let pred = predict_with(&fit, data, &k4_fitted)?;
        let b: Vec<[f64; 3]> = k4_fitted.iter().map(|&r| data.d_um[r]).collect();
        let a: Vec<[f64; 3]> = b
            .iter()
            .zip(&pred)
            .map(|(m, p)| [m[0] - p[0], m[1] - p[1], m[2] - p[2]])
            .collect();
        Some(K4Figures {
            rows: k4_fitted.len(),
            before_um: ranges(&b),
            after_um: ranges(&a),
            in_sample: true,
        })
    } else {
        None
    };
    let model = RtestModel::from_fit_rows(data, &fit, &fit_rows);
    Ok(Analysis {
        fit,
        model,
        fit_rows,
        judged_rows,
        judged_pred,
        judged_by,
        raw_rms_um,
        judged_rms_um,
        full_rms_um,
        nominal_setup_rms_um,
        selection,
        k4,
        closure: crate::revisit::closure(ds, data),
    })
}

fn xyz(v: [f64; 3]) -> Value {
    json!({ "dx_um": v[0], "dy_um": v[1], "dz_um": v[2] })
}

impl Analysis {
    /// The contract's JSON.
    pub fn to_json(&self, data: &RtestData) -> Value {
        let names = crate::param_names_with(data, &self.fit.effects);
        let f = &self.fit;
        let mut le = Map::new();
        for (name, v) in &self.model.location_errors {
            le.insert(name.clone(), serde_json::to_value(v).expect("plain data"));
        }
        let mut setups = Map::new();
        for (s, sname) in data.setup_names.iter().enumerate() {
            let b = N_LOCATION + N_SETUP * s;
            let head = data.machine.kind == axcomp_kinematics::rotary::MachineKind::BcHead;
            let part = |o: usize, frame: &str| {
                json!({
                    "dx_um": f.theta[b + o], "dy_um": f.theta[b + o + 1], "dz_um": f.theta[b + o + 2],
                    "std_um": [f.std[b + o], f.std[b + o + 1], f.std[b + o + 2]],
                    "identified": [f.ident.identified[b + o], f.ident.identified[b + o + 1], f.ident.identified[b + o + 2]],
                    "frame": frame,
                })
            };
            setups.insert(
                sname.clone(),
                json!({
                    "sphere": part(0, if head { "machine" } else { "table (C frame at zero angles)" }),
                    "head": part(3, if head { "spindle (turns with C and B)" } else { "machine" }),
                }),
            );
        }
        let not_identified: Vec<Value> = (0..names.len())
            .filter(|&k| !f.ident.identified[k])
            .map(|k| json!({ "name": names[k], "reason": f.ident.reasons[k] }))
            .collect();
        let correlations: Vec<Value> = f
            .correlations
            .iter()
            .map(|&(a, b, r)| json!([names[a], names[b], r]))
            .collect();
        let mut out = json!({
            "machine": data.machine.kind.name(),
            "location_errors": Value::Object(le),
            "setup_offsets": Value::Object(setups),
            "condition_number": f.ident.condition_number,
            "identifiability": {
                "rank": f.ident.rank,
                "parameters": names.len(),
                "condition_number": f.ident.condition_number,
                "correlations_above_0_9": correlations,
                "not_identified": not_identified,
            },
            "raw_rms_um": self.raw_rms_um,
            "fit_rms_um": f.fit_rms_um,
            "sigma_um": f.sigma_um,
            "sigma_xyz_um": f.sigma_xyz_um,
            "head_zero_std_um": f.head_zero_std_um,
            "zero_uncertainty": f.zero_uncertainty.to_json(),
            "iterations": f.iterations,
            "rows": { "fit": self.fit_rows.len(), "judged": self.judged_rows.len(), "judged_by": self.judged_by },
            "sign_convention": SIGN_CONVENTION,
        });
        if data.machine.kind == axcomp_kinematics::rotary::MachineKind::BcHead {
            out["pivot_mm"] = json!(data.machine.pivot_mm);
        }
        // Do-no-harm check against the nominal kinematics (no correction) on the judged rows.
        out["beats_nominal"] = json!(self.judged_rms_um < self.raw_rms_um);
        // The same rows predicted by the plain references and the full model, judged the same way.
        out["nominal_rms_um"] = json!(self.raw_rms_um);
        out["nominal_setup_rms_um"] = json!(self.nominal_setup_rms_um);
        out["full_model_rms_um"] = json!(self.full_rms_um);
        out["beats_nominal_setup"] = json!(self.judged_rms_um < self.nominal_setup_rms_um);
        out["comparison"] = json!({
            "judged_by": self.judged_by,
            "model_rms_um": self.judged_rms_um,
            "nominal_rms_um": self.raw_rms_um,
            "nominal_setup_rms_um": self.nominal_setup_rms_um,
            "full_model_rms_um": self.full_rms_um,
            "definition": "RMS over dx, dy, dz of the judged rows: the reported model; the nominal kinematics without correction (the readings themselves); the nominal kinematics with only the sphere's set-up offsets fitted on the same training rows (every location error zero: the plain reference); the full model (every identifiable location error, no selection)",
        });
        out["selection"] = match &self.selection {
            Some(sel) => json!({
                "rule": "default (axcomp_rtest::select): every location error fixed at zero unless, on the fitted rows alone, they explain most of them (in-sample RMS ratio at least ratio_limit) or they predict each path (runs only in a file without a path column) left out better than the nominal kinematics with the set-up offsets by more than gain_z standard errors (cv_gain_um2 > gain_z × cv_gain_std_um2); with a single path (or run) fitted only the ratio can keep them; --full-model turns it off",
                "applied": sel.applied,
                "groups": sel.groups,
                "inner_cv_rms_um": {
                    "full_model": sel.inner_cv_full_um,
                    "selected": sel.inner_cv_selected_um,
                    "nominal_setup": sel.inner_cv_nominal_um,
                },
                "fit_rms_ratio_nominal_to_full": sel.fit_rms_ratio,
                "ratio_limit": crate::select::RATIO_LIMIT,
                "cv_gain_um2": sel.cv_gain_um2,
                "cv_gain_std_um2": sel.cv_gain_std_um2,
                "gain_z": crate::select::GAIN_Z,
                "fixed": sel.fixed.iter().map(|(k, why)| json!({ "name": names[*k], "reason": why })).collect::<Vec<_>>(),
                "robust_std": sel.robust_std.iter().map(|(k, sd, significant)| (names[*k].clone(), json!({ "std": sd, "significant": significant }))).collect::<Map<String, Value>>(),
                "robust_std_definition": format!("standard uncertainty robust to residuals correlated along a path (cluster-robust over chunks of {} consecutive poses of the full model's fit); significant: |value| ≥ 2 × it. A flag: nothing is fixed by it", crate::select::CHUNK),
            }),
            None if !f.effects.is_empty() => {
                json!({ "rule": "--effects: every identifiable location error estimated with the named effects (no do-no-harm selection); full_model_rms_um is the location errors alone", "applied": false })
            }
            None => {
                json!({ "rule": "--full-model: every identifiable location error estimated", "applied": false })
            }
        };
        match self.judged_by {
            "holdout" => out["holdout_rms_um"] = json!(self.judged_rms_um),
            "cv" => out["cv_rms_um"] = json!(self.judged_rms_um),
            _ => {}
        }
        if !f.effects.is_empty() {
            out["effects"] = self.effects_json();
            out["comparison"]["location_errors_only_rms_um"] = json!(self.full_rms_um);
        }
        out["closure"] = crate::revisit::closure_json(
            &self.closure,
            f.sigma_xyz_um,
            data.machine.kind.tilt_letter(),
        );
        out["k4"] = match &self.k4 {
            Some(k) => {
                let red = |i: usize| 100.0 * (1.0 - k.after_um[i] / k.before_um[i]);
                json!({
                    "from": match (k.in_sample, self.judged_by) { (true, _) => "in-sample fit", (_, "holdout") => "held-out prediction", (_, "cv") => "cross-validated prediction", _ => "in-sample fit" },
                    "rows": k.rows,
                    "before": xyz(k.before_um),
                    "after": xyz(k.after_um),
                    "reduction_pct": xyz([red(0), red(1), red(2)]),
                })
            }
            None => Value::Null,
        };
        out
    }

    /// The JSON `effects` object: per kind its parameters (value, unit, std, identified, reason), whether
    /// every parameter is identified, and the RMS of its correction over the fitted poses.
    fn effects_json(&self) -> Value {
        let mut out = Map::new();
        for e in &self.model.effects {
            let params: Map<String, Value> = e
                .parameters
                .iter()
                .map(|(n, p)| (n.clone(), serde_json::to_value(p).expect("plain data")))
                .collect();
            out.insert(
                e.kind.clone(),
                json!({
                    "basis": e.basis,
                    "parameters": params,
                    "identified": e.parameters.iter().all(|(_, p)| p.identified),
                    "identified_count": e.parameters.iter().filter(|(_, p)| p.identified).count(),
                    "rms_over_fit_um": e.rms_over_fit_um,
                }),
            );
        }
        Value::Object(out)
    }
}
