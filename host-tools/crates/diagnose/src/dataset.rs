//! Observations from a measurement CSV read by `axcomp-data` (the contract's columns).
//!
//! Glossary: **target** = the error column modelled (`deviation_um` by default, any `*_um` with
//! `--target`); **sensor** = a `*_degC` column; **force** = a `*_N` column; **run** = the `run`/`cycle`
//! label, turned into a group index.

use axcomp_data::{Dataset, HoldoutSpec};

use crate::error::{DiagnoseError, Result};
use crate::obs::{Named, Observations};

fn optional(ds: &Dataset, col: &str) -> Result<Option<Vec<f64>>> {
    if ds.has(col) {
        Ok(Some(ds.numeric(col)?.to_vec()))
    } else {
        Ok(None)
    }
}

/// Builds the observations: `target` column, held-out rows from `holdout` (`COL=V1,V2`, `COL>=X`, ...).
/// Errors name the file, line and column of a bad cell, or the missing column.
pub fn observations(ds: &Dataset, target: &str, holdout: &str) -> Result<Observations> {
    let spec = HoldoutSpec::parse(holdout)?;
    let held_out = spec.mask(ds)?;
    let y = ds.numeric(target)?.to_vec();
    let direction = ds
        .direction()?
        .map(|d| d.into_iter().map(f64::from).collect());
    // Runs by value, as `fit positioning` groups them (`1` and `1.0` are one run).
    let run = if ds.has("run") {
        // An empty label would silently make its rows one more run.
        if let Some(row) = ds.text("run")?.iter().position(|t| t.trim().is_empty()) {
            return Err(DiagnoseError::BadValue {
                at: ds.locate("run", row),
                what: "empty cell where the row's run is required: every row needs one".into(),
            });
        }
        Some(axcomp_data::groups(ds, "run")?.0)
    } else {
        None
    };
    let time_s = if ds.has("time_s") {
        Some(ds.numeric("time_s")?.to_vec())
    } else {
        ds.time_s().map(<[f64]>::to_vec)
    };
    let mut temperatures = Vec::new();
    for s in ds.sensors() {
        let col = format!("{s}_degC");
        temperatures.push(Named {
            name: s,
            values: ds.numeric(&col)?.to_vec(),
        });
    }
    let mut forces = Vec::new();
    for name in ds.column_names() {
        if name.len() > 2 && name.ends_with("_N") {
            forces.push(Named {
                name: name.trim_end_matches("_N").to_string(),
                values: ds.numeric(name)?.to_vec(),
            });
        }
    }
    let obs = Observations {
        target_name: target.to_string(),
        target: y,
        held_out,
        position_mm: optional(ds, "target_mm")?,
        direction,
        run,
        time_s,
        temperatures,
        forces,
        velocity_mm_s: optional(ds, "velocity_mm_s")?,
        accel_mm_s2: optional(ds, "accel_mm_s2")?,
        offset_mm: optional(ds, "offset_mm")?,
    };
    // An explicit NaN or inf is named by file, line and column (the check below knows only the data row).
    let mut used: Vec<(String, &[f64])> = vec![(target.to_string(), &obs.target)];
    used.extend(obs.time_s.as_deref().map(|t| ("time_s".to_string(), t)));
    used.extend(
        obs.temperatures
            .iter()
            .map(|t| (format!("{}_degC", t.name), t.values.as_slice())),
    );
    used.extend(
        obs.forces
            .iter()
            .map(|f| (format!("{}_N", f.name), f.values.as_slice())),
    );
    for (col, v) in [
        ("target_mm", &obs.position_mm),
        ("velocity_mm_s", &obs.velocity_mm_s),
        ("accel_mm_s2", &obs.accel_mm_s2),
        ("offset_mm", &obs.offset_mm),
    ] {
        used.extend(v.as_deref().map(|v| (col.to_string(), v)));
    }
    for (col, values) in &used {
        if let Some(row) = values.iter().position(|v| !v.is_finite()) {
            return Err(DiagnoseError::BadValue {
                at: ds.locate(col, row),
                what: format!(
                    "`{}` is not a finite number; remove the row or fill in the value",
                    values[row]
                ),
            });
        }
    }
    obs.validate().map_err(|e| DiagnoseError::BadValue {
        at: ds.source().to_string(),
        what: e.to_string(),
    })?;
    Ok(obs)
}
