//! Observations from a measurement CSV read by `axcomp-data` (the contract's columns).
//!
//! Glossary: **target** = the error column modelled (`deviation_um` by default, any `*_um` with
//! `--target`); **sensor** = a `*_degC` column; **force** = a `*_N` column; **run** = the `run`/`cycle`
//! label, turned into a group index.

use axcomp_data::{Dataset, HoldoutSpec};

use crate::obs::{Named, Observations};

fn optional(ds: &Dataset, col: &str) -> anyhow::Result<Option<Vec<f64>>> {
    if ds.has(col) {
        Ok(Some(ds.numeric(col)?.to_vec()))
    } else {
        Ok(None)
    }
}

/// Builds the observations: `target` column, held-out rows from `holdout` (`COL=V1,V2`, `COL>=X`, ...).
/// Errors name the file, line and column of a bad cell, or the missing column.
pub fn observations(ds: &Dataset, target: &str, holdout: &str) -> anyhow::Result<Observations> {
    let spec = HoldoutSpec::parse(holdout)?;
    let held_out = spec.mask(ds)?;
    let y = ds.numeric(target)?.to_vec();
    let direction = ds
        .direction()?
        .map(|d| d.into_iter().map(f64::from).collect());
    let run = ds.run().map(|labels| {
        let mut uniq: Vec<String> = Vec::new();
        labels
            .iter()
            .map(|l| match uniq.iter().position(|u| u == l) {
                Some(k) => k,
                None => {
                    uniq.push(l.clone());
                    uniq.len() - 1
                }
            })
            .collect()
    });
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
    obs.validate()
        .map_err(|e| anyhow::anyhow!("{}: {e}", ds.source()))?;
    Ok(obs)
}
