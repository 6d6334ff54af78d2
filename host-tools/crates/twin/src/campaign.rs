//! A simulated measurement campaign: the rows a user would have measured, and the truth behind them.
//!
//! Glossary:
//! - *row*: one measurement, exactly what goes into the contract's CSV (noisy readings).
//! - *truth*: per row, the noise-free deviation, the scale position the drive settled at, the applied
//!   correction and each effect's contribution.
//! - *contribution*: one effect's share of the true deviation at the row's scale position.

use std::io;
use std::path::Path;

use axcomp_numeric::stats::rms;
use serde::Serialize;

use crate::effects::{Conditions, EffectKind};

/// One measured row (the contract's CSV columns).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    pub target_mm: f64,
    /// Measured deviation (truth + measurement noise), µm.
    pub deviation_um: f64,
    pub run: u32,
    pub direction: i8,
    pub time_s: f64,
    /// Measured temperature of each sensor (truth + sensor noise), in [`Campaign::sensor_names`] order.
    pub temps_degc: Vec<f64>,
    /// Measured force (truth + sensor noise).
    pub force_n: f64,
    pub velocity_mm_s: f64,
    pub accel_mm_s2: f64,
    pub offset_mm: f64,
}

/// What really happened at one row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Truth {
    /// Noise-free deviation: position reached minus target.
    pub deviation_um: f64,
    /// Where the scale was when the row was measured (target − correction, in whole counts).
    pub scale_mm: f64,
    /// Correction applied by the compensator (0 without compensation).
    pub correction_um: f64,
    /// Each kind's contribution at `scale_mm`, indexed by [`EffectKind::index`].
    pub contributions_um: [f64; EffectKind::COUNT],
    /// The true conditions (temperatures, force, ...).
    pub conditions: Conditions,
}

/// The result of [`crate::simulate`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Campaign {
    pub axis_name: String,
    pub plan: String,
    pub seed: u64,
    pub compensated: bool,
    /// Sensor names; the CSV columns are `<name>_degC`.
    pub sensor_names: Vec<String>,
    pub rows: Vec<Row>,
    /// One per row.
    pub truth: Vec<Truth>,
    /// Further columns written after the contract's (e.g. `spindle_rpm`, `ap_mm`, `fz_mm`), one value
    /// per row.
    pub extra_columns: Vec<ExtraColumn>,
}

/// A further CSV column.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExtraColumn {
    pub name: String,
    /// Decimals written.
    pub decimals: usize,
    pub values: Vec<f64>,
}

impl Campaign {
    /// The contract's CSV header.
    pub fn csv_header(&self) -> String {
        let mut cols = vec![
            "target_mm".to_owned(),
            "deviation_um".into(),
            "run".into(),
            "direction".into(),
            "time_s".into(),
        ];
        cols.extend(self.sensor_names.iter().map(|n| format!("{n}_degC")));
        cols.extend(["force_N", "velocity_mm_s", "accel_mm_s2", "offset_mm"].map(String::from));
        cols.extend(self.extra_columns.iter().map(|c| c.name.clone()));
        cols.join(",")
    }

    /// The whole campaign as the contract's measurement CSV: two `#` comment lines (what was simulated),
    /// the header, one line per row. Direction is written `1`/`-1`.
    pub fn to_csv_string(&self) -> String {
        let mut out = String::with_capacity(80 * (self.rows.len() + 3));
        self.write_csv_to(&mut out);
        out
    }

    fn write_csv_to(&self, out: &mut String) {
        use std::fmt::Write as _;
        let _ = writeln!(
            out,
            "# axcomp sim: axis {}, plan {}, seed {}, {}",
            self.axis_name,
            self.plan,
            self.seed,
            if self.compensated {
                "compensated"
            } else {
                "uncompensated"
            }
        );
        let _ = writeln!(
            out,
            "# deviation = position reached - target (ISO 230-2), um"
        );
        out.push_str(&self.csv_header());
        out.push('\n');
        for (i, r) in self.rows.iter().enumerate() {
            let _ = write!(
                out,
                "{:.4},{:.4},{},{},{:.3}",
                r.target_mm, r.deviation_um, r.run, r.direction, r.time_s
            );
            for t in &r.temps_degc {
                let _ = write!(out, ",{t:.4}");
            }
            let _ = write!(
                out,
                ",{:.3},{:.4},{:.3},{:.3}",
                r.force_n, r.velocity_mm_s, r.accel_mm_s2, r.offset_mm
            );
            for c in &self.extra_columns {
                let v = c.values.get(i).copied().unwrap_or(f64::NAN);
                let _ = write!(out, ",{v:.prec$}", prec = c.decimals);
            }
            out.push('\n');
        }
    }

    /// Writes [`Campaign::to_csv_string`] to `path` through a temporary file in the same directory
    /// and a rename, so a failed write leaves no half-written file.
    pub fn write_csv(&self, path: impl AsRef<Path>) -> io::Result<()> {
        write_atomic(path.as_ref(), self.to_csv_string().as_bytes())
    }

    /// Contribution of `kind` on row `row` (0 when the axis has no such effect).
    pub fn contribution_um(&self, kind: EffectKind, row: usize) -> f64 {
        self.truth[row].contributions_um[kind.index()]
    }

    /// Largest |contribution| of `kind` over `rows`.
    pub fn peak_contribution_um(
        &self,
        kind: EffectKind,
        rows: impl IntoIterator<Item = usize>,
    ) -> f64 {
        rows.into_iter()
            .map(|i| self.contribution_um(kind, i).abs())
            .fold(0.0, f64::max)
    }

    /// Measured deviations, one per row.
    pub fn deviations_um(&self) -> Vec<f64> {
        self.rows.iter().map(|r| r.deviation_um).collect()
    }

    /// RMS of the measured deviations (0 for a campaign without rows: no rows, no error).
    pub fn rms_deviation_um(&self) -> f64 {
        if self.rows.is_empty() {
            return 0.0;
        }
        rms(self.rows.iter().map(|r| r.deviation_um))
    }

    /// RMS of the noise-free deviations (0 without truth rows: no rows, no error).
    pub fn rms_truth_um(&self) -> f64 {
        if self.truth.is_empty() {
            return 0.0;
        }
        rms(self.truth.iter().map(|t| t.deviation_um))
    }
}

/// The host libraries' one atomic write (temporary sibling, sync, rename): see `axcomp-files`.
use axcomp_files::write_atomic;
