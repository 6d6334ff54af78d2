//! One campaign as plain columns, independent of the CSV reader.
//!
//! Glossary: **target** = the error column being modelled (µm); **held out** = rows used only to judge;
//! **ΔT** = a sensor's temperature minus its value at the campaign's first (earliest) row.
use crate::error::DiagnoseError;

/// A named numeric column.
#[derive(Debug, Clone)]
pub struct Named {
    pub name: String,
    pub values: Vec<f64>,
}

/// The columns the diagnosis can use. Every present vector has `target.len()` entries.
#[derive(Debug, Clone, Default)]
pub struct Observations {
    /// Name of the target column (for reports).
    pub target_name: String,
    /// The error being modelled, µm.
    pub target: Vec<f64>,
    /// `true` = held out (judging only).
    pub held_out: Vec<bool>,
    pub position_mm: Option<Vec<f64>>,
    /// Approach direction, +1 / −1.
    pub direction: Option<Vec<f64>>,
    /// Run / cycle group index.
    pub run: Option<Vec<usize>>,
    pub time_s: Option<Vec<f64>>,
    /// Temperatures, °C (name without the `_degC` suffix).
    pub temperatures: Vec<Named>,
    /// Forces, N.
    pub forces: Vec<Named>,
    pub velocity_mm_s: Option<Vec<f64>>,
    pub accel_mm_s2: Option<Vec<f64>>,
    pub offset_mm: Option<Vec<f64>>,
}

impl Observations {
    pub fn n_rows(&self) -> usize {
        self.target.len()
    }

    /// Indices of the training rows.
    pub fn train_rows(&self) -> Vec<usize> {
        (0..self.n_rows()).filter(|&i| !self.held_out[i]).collect()
    }

    /// Indices of the held-out rows.
    pub fn holdout_rows(&self) -> Vec<usize> {
        (0..self.n_rows()).filter(|&i| self.held_out[i]).collect()
    }

    /// Checks lengths and finiteness; names the offending column and row (0-based data row).
    pub fn validate(&self) -> Result<(), DiagnoseError> {
        let n = self.target.len();
        if n == 0 {
            return Err(DiagnoseError::Invalid("no rows".into()));
        }
        let check = |name: &str, v: &[f64]| check_column(name, v, n);
        check(&self.target_name, &self.target)?;
        if self.held_out.len() != n {
            return Err(DiagnoseError::Invalid(
                "held-out mask has the wrong length".into(),
            ));
        }
        for (name, v) in [
            ("target_mm", &self.position_mm),
            ("direction", &self.direction),
            ("time_s", &self.time_s),
            ("velocity_mm_s", &self.velocity_mm_s),
            ("accel_mm_s2", &self.accel_mm_s2),
            ("offset_mm", &self.offset_mm),
        ] {
            if let Some(v) = v {
                check(name, v)?;
            }
        }
        for t in self.temperatures.iter().chain(&self.forces) {
            check(&t.name, &t.values)?;
        }
        check_holdout(&self.held_out, "the holdout", "row")
    }

    /// Row order by time (stable; row order when there is no time).
    pub fn time_order(&self) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..self.n_rows()).collect();
        if let Some(t) = &self.time_s {
            idx.sort_by(|&a, &b| t[a].total_cmp(&t[b]));
        }
        idx
    }

    /// ΔT per sensor relative to the earliest row.
    pub fn delta_t(&self) -> Vec<Named> {
        let order = self.time_order();
        self.temperatures
            .iter()
            .map(|t| {
                let t0 = t.values[order[0]];
                Named {
                    name: t.name.clone(),
                    values: t.values.iter().map(|v| v - t0).collect(),
                }
            })
            .collect()
    }
}

/// Checks that the held-out mask holds out at least one row and not every row; the message says what
/// selected them (`by`: `the holdout`, `--holdout`) and what a row is (`unit`: `row`, `touch`, `pose`).
pub fn check_holdout(held_out: &[bool], by: &str, unit: &str) -> Result<(), DiagnoseError> {
    let n_ho = held_out.iter().filter(|&&h| h).count();
    if n_ho == 0 {
        return Err(DiagnoseError::Invalid(format!(
            "{by} selects no {unit}: nothing to judge the model on"
        )));
    }
    if n_ho == held_out.len() {
        return Err(DiagnoseError::Invalid(format!(
            "{by} selects every {unit}: nothing left to fit the model on"
        )));
    }
    Ok(())
}

/// Checks that column `name` has `n` values, all finite; the error names the column and the first
/// offending data row (1-based).
pub fn check_column(name: &str, v: &[f64], n: usize) -> Result<(), DiagnoseError> {
    if v.len() != n {
        return Err(DiagnoseError::Invalid(format!(
            "column `{name}` has {} values, expected {n}",
            v.len()
        )));
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(DiagnoseError::Invalid(format!(
            "column `{name}`: value in data row {} is not finite",
            i + 1
        )));
    }
    Ok(())
}
