//! The whole `fit rtest` analysis: fit on the training rows, judge on held-out rows (or by leave-one-group-out
//! cross-validation), the ISO 10791-6 K4 figures before and after, and the JSON of the contract.

use axcomp_data::{Dataset, Split};
use serde_json::{Map, Value, json};

use crate::{
    Fit, RtestData, RtestError, RtestModel, SIGN_CONVENTION, model_displacement, ranges, rms3,
};
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
    pub k4: Option<K4Figures>,
}

/// ISO 10791-6 K4 figures on the judged rows of the K4 path.
#[derive(Debug, Clone, Copy)]
pub struct K4Figures {
    pub rows: usize,
    pub before_um: [f64; 3],
    pub after_um: [f64; 3],
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
            Ok(model_displacement(
                &data.machine,
                &data.poses[r],
                data.setup[r],
                &fit.theta,
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

/// Runs the analysis.
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
    let n = data.poses.len();
    let all: Vec<usize> = (0..n).collect();
    let (fit_rows, judged_rows, judged_pred, judged_by, fit) = match split {
        None => {
            let f = crate::fit_shared(data, &all, opts, shared)?;
            let pred = predict_with(&f, data, &all)?;
            (all.clone(), all.clone(), pred, "fit", f)
        }
        Some(Split::Holdout(h)) => {
            let mask = h.mask(ds)?;
            let train: Vec<usize> = all.iter().copied().filter(|&r| !mask[r]).collect();
            let test: Vec<usize> = all.iter().copied().filter(|&r| mask[r]).collect();
            check_setups_known(data, &train, &test)?;
            let f = crate::fit_shared(data, &train, opts, shared)?;
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
            for g in 0..labels.len() {
                let train: Vec<usize> = all.iter().copied().filter(|&r| ids[r] != g).collect();
                let test: Vec<usize> = all.iter().copied().filter(|&r| ids[r] == g).collect();
                check_setups_known(data, &train, &test)?;
                let f = crate::fit_shared(data, &train, opts, shared).map_err(|e| {
                    RtestError::Fit(format!("--cv {col}: leaving out `{}`: {e}", labels[g]))
                })?;
                for (&r, p) in test.iter().zip(predict_with(&f, data, &test)?) {
                    pred[r] = p;
                }
            }
            let f = crate::fit_shared(data, &all, opts, shared)?;
            (all.clone(), all.clone(), pred, "cv", f)
        }
    };
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
    let k4 = if k4_idx.len() >= 2 {
        let b: Vec<[f64; 3]> = k4_idx.iter().map(|&i| meas[i]).collect();
        let a: Vec<[f64; 3]> = k4_idx.iter().map(|&i| resid[i]).collect();
        Some(K4Figures {
            rows: k4_idx.len(),
            before_um: ranges(&b),
            after_um: ranges(&a),
        })
    } else {
        None
    };
    let model = RtestModel::from_fit(data, &fit);
    Ok(Analysis {
        fit,
        model,
        fit_rows,
        judged_rows,
        judged_pred,
        judged_by,
        raw_rms_um,
        judged_rms_um,
        k4,
    })
}

fn xyz(v: [f64; 3]) -> Value {
    json!({ "dx_um": v[0], "dy_um": v[1], "dz_um": v[2] })
}

impl Analysis {
    /// The contract's JSON.
    pub fn to_json(&self, data: &RtestData) -> Value {
        let names = data.param_names();
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
        match self.judged_by {
            "holdout" => out["holdout_rms_um"] = json!(self.judged_rms_um),
            "cv" => out["cv_rms_um"] = json!(self.judged_rms_um),
            _ => {}
        }
        out["k4"] = match &self.k4 {
            Some(k) => {
                let red = |i: usize| 100.0 * (1.0 - k.after_um[i] / k.before_um[i]);
                json!({
                    "from": match self.judged_by { "holdout" => "held-out prediction", "cv" => "cross-validated prediction", _ => "in-sample fit" },
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
}
