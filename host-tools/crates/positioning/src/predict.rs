//! The prediction of a positioning table on the rows of a dataset: the column `axcomp predict` adds
//! (`pred_<target>`, the column the table was fitted on).
//!
//! Terms:
//! - *stroke*: the range of `target_mm` the table covers; outside it the table holds end values, which is
//!   not a prediction, so a row there is an error naming it.
//! - *bidirectional table*: one curve per approach direction; every row then needs its `direction`.

use axcomp_data::{DataError, Dataset};

use crate::TableFile;

/// Why a table cannot predict the rows.
#[derive(Debug, thiserror::Error)]
pub enum PredictError {
    /// A missing input, or a row outside the stroke; the message names the file, row or column.
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

/// Adds `pred_<target>`: the column the table was fitted on (`pred_deviation_um` by default).
pub fn predict_positioning(
    table: &TableFile,
    ds: &mut Dataset,
) -> Result<Vec<String>, PredictError> {
    let x = ds.numeric("target_mm")?.to_vec();
    let dir = ds.direction()?;
    if !table.backward.is_empty() && dir.is_none() {
        fail!(
            "{}: missing column `direction`: the table is bidirectional (forward and backward), so every row \
             needs its approach direction",
            ds.source()
        );
    }
    let (lo, hi) = (table.start_mm, table.end_mm());
    let tol = 1e-9 * (hi - lo).abs().max(1.0);
    let mut pred = Vec::with_capacity(x.len());
    for (i, &xi) in x.iter().enumerate() {
        if !xi.is_finite() {
            fail!("{}: target_mm is {xi}", ds.locate("target_mm", i));
        }
        if xi < lo - tol || xi > hi + tol {
            fail!(
                "{}: target_mm {xi} is outside the table's stroke [{lo}, {hi}] mm; the model cannot predict it",
                ds.row_name(i)
            );
        }
        let d = dir.as_ref().map_or(0, |d| d[i]);
        pred.push(table.deviation_um(xi, d));
    }
    let target = table
        .provenance
        .as_ref()
        .map(|p| p.target.as_str())
        .filter(|t| !t.is_empty())
        .unwrap_or("deviation_um");
    let name = format!("pred_{target}");
    ds.add_numeric_column(&name, pred)?;
    Ok(vec![name])
}
