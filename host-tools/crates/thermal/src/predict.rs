//! Predictions of a thermal model file and of a force law on the rows of a dataset: the columns
//! `axcomp predict` adds (`pred_<target>`, `pred_<force column>`), computed as the fit and the firmware
//! compute them.
//!
//! Terms:
//! - *run*: one recording from switch-on; a multi-run model references each run to its first row.
//! - *force law*: `F = k·ap^x·fz^y·n^z` of `fit force`, from depth of cut, feed per tooth and spindle speed.

use axcomp_data::{DataError, Dataset};

use crate::model_file::{ModelForceLaw, ThermalModelFile};

/// Why a model cannot predict the rows.
#[derive(Debug, thiserror::Error)]
pub enum PredictError {
    /// A missing input, or a row outside what the model can predict; the message names the file, row or
    /// column.
    #[error("{0}")]
    Input(String),
    /// Reading a column or adding the prediction failed.
    #[error(transparent)]
    Data(#[from] DataError),
}

/// Returns early with a [`PredictError::Input`] built like `format!`.
macro_rules! fail {
    ($($arg:tt)*) => {
        return Err(PredictError::Input(format!($($arg)*)))
    };
}

/// Adds `pred_<target>`. `note` receives what the user should know about the rows (lags restarting, a
/// missing runs column, guarded sensor terms), each without a prefix.
pub fn predict_thermal(
    m: &ThermalModelFile,
    ds: &mut Dataset,
    note: &mut dyn FnMut(String),
) -> Result<Vec<String>, PredictError> {
    let n = ds.n_rows();
    let time = time_column(m, ds, note)?;
    let mut pred = vec![m.b0_um + m.target_offset_um.unwrap_or(0.0); n];
    let sensors = sensor_series(m, ds)?;
    let runs = run_index(m, ds, note)?;
    let thermal = crate::ThermalModel {
        b0_um: 0.0,
        terms: m
            .sensors
            .iter()
            .map(|s| crate::SensorTerm {
                sensor: s.name.clone(),
                reference_degc: s.reference_degc,
                tau_s: s.tau_s,
                coef_um_per_k: s.coef_um_per_k,
            })
            .collect(),
        forces: vec![],
    };
    let bounds: Option<Vec<(f64, f64)>> = m
        .sensors
        .iter()
        .map(|s| Some((s.rise_min_k?, s.rise_max_k?)))
        .collect();
    let (terms, guarded) = crate::runs::predict_campaign(
        &thermal,
        bounds.as_deref(),
        &time,
        &sensors,
        &[],
        runs.as_ref(),
    )
    .map_err(|e| PredictError::Input(format!("{}: {e}", ds.source())))?;
    for (p, t) in pred.iter_mut().zip(terms) {
        *p += t;
    }
    if let Some(first) = guarded.iter().position(|g| *g) {
        note(format!(
            "{}: on {} row(s) (first: data row {}) a model sensor has risen beyond the range it \
             was fitted on by more than that range: that sensor's term is dropped there (as the firmware does)",
            ds.source(),
            guarded.iter().filter(|g| **g).count(),
            first + 1
        ));
    }
    if let (Some(r), true) = (&runs, ds.has(&m.target)) {
        // The model predicts the change since each run's first row; the run's first reading is added back.
        let target = ds.numeric(&m.target)?.to_vec();
        for (p, r0) in pred.iter_mut().zip(r.reference(&target)) {
            *p += r0;
        }
    }
    for f in &m.forces {
        let force: Vec<f64> = match &f.law {
            None => {
                let v = ds.numeric(&f.column)?.to_vec();
                if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                    fail!("{}: force is {}", ds.locate(&f.column, i), v[i]);
                }
                v
            }
            Some(law) => law_force(ds, law, &f.column)?,
        };
        for (p, v) in pred.iter_mut().zip(force) {
            *p += f.chi_um_per_n * v;
        }
    }
    let name = format!("pred_{}", m.target);
    ds.add_numeric_column(&name, pred)?;
    Ok(vec![name])
}

/// The rows' `time_s` when a sensor has a lag (zeros otherwise), every value finite; a note where time does
/// not increase (the lags restart there).
fn time_column(
    m: &ThermalModelFile,
    ds: &Dataset,
    note: &mut dyn FnMut(String),
) -> Result<Vec<f64>, PredictError> {
    let n = ds.n_rows();
    let needs_time = m.sensors.iter().any(|s| s.tau_s > 0.0);
    Ok(if needs_time {
        if !ds.has("time_s") {
            fail!(
                "{}: missing column `time_s` (or a `time` column of timestamps){}: the model's sensor lags need \
                 the time of each row",
                ds.source(),
                ds.time_hint()
            );
        }
        let t = ds.numeric("time_s")?.to_vec();
        if let Some(i) = t.iter().position(|v| !v.is_finite()) {
            fail!("{}: time_s is {}", ds.locate("time_s", i), t[i]);
        }
        // The lags restart (in equilibrium with that row) where time does not increase, as in the fit; rows
        // out of time order (e.g. shuffled) would silently lose their lags, so say where it happens.
        let restarts: Vec<usize> = (1..n).filter(|&k| t[k] <= t[k - 1]).collect();
        if let Some(&first) = restarts.first() {
            note(format!(
                "{}: time_s does not increase at {} row(s) (first {}): the model's sensor lags \
                 restart there, in equilibrium with that row, as in the fit (a new recording); sort the rows \
                 by time if they are one recording",
                ds.source(),
                restarts.len(),
                ds.locate("time_s", first)
            ));
        }
        t
    } else {
        vec![0.0; n]
    })
}

/// Each model sensor's `<name>_degC` column, every reading within the model's plausible range.
fn sensor_series(m: &ThermalModelFile, ds: &Dataset) -> Result<Vec<crate::Series>, PredictError> {
    let mut sensors = Vec::with_capacity(m.sensors.len());
    for s in &m.sensors {
        let col = format!("{}_degC", s.name);
        let v = ds.numeric(&col)?.to_vec();
        for (i, &t) in v.iter().enumerate() {
            if !(t >= s.min_degc && t <= s.max_degc) {
                fail!(
                    "{}: {t} °C is outside the model's plausible range [{}, {}] °C for sensor `{}`; the model \
                     cannot predict this row",
                    ds.locate(&col, i),
                    s.min_degc,
                    s.max_degc,
                    s.name
                );
            }
        }
        sensors.push(crate::Series {
            name: s.name.clone(),
            values: v,
        });
    }
    Ok(sensors)
}

/// The rows' runs for a multi-run model (`None` for a single-run model).
fn run_index(
    m: &ThermalModelFile,
    ds: &Dataset,
    note: &mut dyn FnMut(String),
) -> Result<Option<crate::runs::RunIndex>, PredictError> {
    let n = ds.n_rows();
    // A multi-run model: each run's references are its first row (the readings at switch-on); a file
    // without the runs column is one run.
    Ok(match &m.runs_column {
        Some(col) if ds.has(col) => {
            let (ids, labels) = axcomp_data::groups(ds, col)?;
            let l: Vec<String> = ids.into_iter().map(|i| labels[i].clone()).collect();
            Some(crate::runs::RunIndex::new(Some(&l), n))
        }
        Some(col) => {
            note(format!(
                "{}: no `{col}` column: the rows are one run, referenced to its first row",
                ds.source()
            ));
            Some(crate::runs::RunIndex::new(Some(&vec![String::new(); n]), n))
        }
        None => None,
    })
}

/// The force a law `F = k·ap^x·fz^y·n^z` gives on each row, from `ap_mm`, `fz_mm` and the one `*_rpm` column
/// (none needed when z = 0); `what` names the force in messages. A row without a finite force is an error
/// naming the row.
fn law_force(ds: &Dataset, law: &ModelForceLaw, what: &str) -> Result<Vec<f64>, PredictError> {
    let n = ds.n_rows();
    let ap = process_column(ds, "ap_mm")?;
    let fz = process_column(ds, "fz_mm")?;
    let rpm_cols: Vec<String> = ds
        .column_names()
        .into_iter()
        .filter(|c| c.ends_with("_rpm"))
        .map(str::to_string)
        .collect();
    let nn: Vec<f64> = match rpm_cols.as_slice() {
        [c] if law.z_n != 0.0 => process_column(ds, c)?,
        [c] => ds.numeric(c)?.to_vec(),
        [] if law.z_n == 0.0 => vec![1.0; n],
        [] => fail!(
            "{}: missing a `*_rpm` column: the force law of `{what}` depends on the spindle speed",
            ds.source()
        ),
        many => fail!(
            "{}: several `*_rpm` columns ({}): keep one (e.g. with --rename)",
            ds.source(),
            many.join(", ")
        ),
    };
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        // No cut (depth, feed or a speed the law depends on is 0: an idle period) is no force, 0 N, as the
        // firmware outputs (a law with z_n < 0 once made the idle rows of a spindle campaign an error).
        let idle = ap[i] == 0.0 || fz[i] == 0.0 || (law.z_n != 0.0 && nn[i] == 0.0);
        let v = if idle {
            0.0
        } else {
            law.k * ap[i].powf(law.x_ap) * fz[i].powf(law.y_fz) * nn[i].powf(law.z_n)
        };
        if !v.is_finite() {
            fail!(
                "{}: the force law of `{what}` gives no finite force for ap_mm {}, fz_mm {}, n {}",
                ds.row_name(i),
                ap[i],
                fz[i],
                nn[i]
            );
        }
        out.push(v);
    }
    Ok(out)
}

/// A force law's terms are finite, `k` of plausible size and the exponents within ±100 (a fitted law
/// has exponents near 1; beyond, the power overflows on ordinary process values).
pub fn check_force_law(law: &ModelForceLaw) -> Result<(), String> {
    let terms = [
        ("k", law.k, 1e12),
        ("x_ap", law.x_ap, 100.0),
        ("y_fz", law.y_fz, 100.0),
        ("z_n", law.z_n, 100.0),
    ];
    match terms
        .iter()
        .find(|(_, v, max)| !(v.is_finite() && v.abs() <= *max))
    {
        Some((name, v, max)) => Err(format!(
            "force law term `{name}` is {v}, not a finite number within ±{max}"
        )),
        None => Ok(()),
    }
}

/// A process parameter of a force law (`ap_mm`, `fz_mm`, the speed): a negative or non-finite value is an
/// error naming the cell, as in `fit force` (with an exponent of 1, fixed as in Kienzle's law, a negative
/// depth of cut once gave a negative force instead). Zero is a row without a cut: 0 N (see [`law_force`]).
fn process_column(ds: &Dataset, col: &str) -> Result<Vec<f64>, PredictError> {
    let v = ds.numeric(col)?.to_vec();
    if let Some(i) = v.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
        fail!(
            "{}: {} is not a finite number ≥ 0 (a process parameter of the force law); the model cannot \
             predict this row",
            ds.locate(col, i),
            v[i]
        );
    }
    Ok(v)
}

/// Adds `pred_<force column>` (the column the law was fitted on, from its provenance; `pred_force_N` for a
/// law without provenance).
pub fn predict_force_law(
    law: &ModelForceLaw,
    force_column: Option<&str>,
    ds: &mut Dataset,
) -> Result<Vec<String>, PredictError> {
    let column = force_column.filter(|c| !c.is_empty()).unwrap_or("force_N");
    let force = law_force(ds, law, column)?;
    let name = format!("pred_{column}");
    ds.add_numeric_column(&name, force)?;
    Ok(vec![name])
}

#[cfg(test)]
mod tests {
    use super::*;
    use axcomp_data::LoadOptions;

    fn rows(csv: &str) -> Dataset {
        Dataset::from_csv_str("rows.csv", csv, &LoadOptions::default()).unwrap()
    }

    #[test]
    fn force_law_gives_the_law_on_a_cut_and_zero_when_idle() {
        let law = ModelForceLaw {
            k: 1500.0,
            x_ap: 0.9,
            y_fz: 0.75,
            z_n: -0.1,
        };
        let mut ds = rows("ap_mm,fz_mm,spindle_rpm\n2,0.1,3000\n0,0.1,3000\n");
        let names = predict_force_law(&law, Some("Fc_N"), &mut ds).unwrap();
        assert_eq!(names, ["pred_Fc_N"]);
        let f = ds.numeric("pred_Fc_N").unwrap();
        // Reference: the law evaluated by hand; tolerance 1e-12 relative (the same powers, in one order).
        let want = 1500.0 * 2f64.powf(0.9) * 0.1f64.powf(0.75) * 3000f64.powf(-0.1);
        assert!((f[0] - want).abs() <= 1e-12 * want, "{} vs {want}", f[0]);
        assert_eq!(f[1], 0.0, "an idle row (ap 0) is no force");
    }

    #[test]
    fn a_negative_process_value_is_an_error_naming_the_cell() {
        let law = ModelForceLaw {
            k: 1.0,
            x_ap: 1.0,
            y_fz: 1.0,
            z_n: 0.0,
        };
        let mut ds = rows("ap_mm,fz_mm\n1,0.1\n-1,0.1\n");
        let err = predict_force_law(&law, None, &mut ds)
            .unwrap_err()
            .to_string();
        assert!(err.contains("rows.csv") && err.contains("ap_mm"), "{err}");
        assert!(err.contains("not a finite number ≥ 0"), "{err}");
        assert!(check_force_law(&ModelForceLaw { k: f64::NAN, ..law }).is_err());
        assert!(check_force_law(&law).is_ok());
    }
}
