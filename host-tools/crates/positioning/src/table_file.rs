//! The positioning table file (`axcomp-positioning-table/1`, JSON) and its conversion to the core's
//! [`axcomp_core::TableSpec`].
//!
//! Glossary:
//! - *segment*: one uniform interval of the table, `segment_mm` long; segment `i` starts at
//!   `start_mm + i·segment_mm`.
//! - *t*: the position inside a segment, `t ∈ [0,1)`; the deviation is `c0 + t(c1 + t(c2 + t c3))` µm.
//! - *forward / backward*: tables for positive / negative approach; `backward` empty = one table both ways.
//! - *counts*: scale counts of the firmware, `counts = mm · 1000 / um_per_count`.

use std::path::Path;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::spline::{self, PiecewiseCubic, SplineError};

/// Value of the `format` field.
pub const FORMAT: &str = "axcomp-positioning-table/1";

/// A fitted positioning table in physical units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TableFile {
    /// Always [`FORMAT`].
    pub format: String,
    pub axis: String,
    /// Position of knot 0 (mm).
    pub start_mm: f64,
    /// Uniform segment length (mm).
    pub segment_mm: f64,
    /// Per segment `[c0, c1, c2, c3]` in µm over `t ∈ [0,1)`, positive approach.
    pub forward: Vec<[f64; 4]>,
    /// Same for negative approach; empty = unidirectional.
    #[serde(default)]
    pub backward: Vec<[f64; 4]>,
    /// Name of the model the table was resampled from (e.g. `spline_not_a_knot/separate`).
    pub model: String,
    /// Cross-validated (or held-out) RMS of the residual the model leaves, µm.
    pub cv_rms_um: f64,
    /// RMS of the raw deviations the model was judged on, µm.
    #[serde(default)]
    pub raw_rms_um: f64,
    /// How `cv_rms_um` was obtained (`leave-one-run-out`, `k-fold-by-row`, `holdout`).
    #[serde(default)]
    pub cv_method: String,
    /// Where the table came from: the data file's SHA-256, the filters, the tool version and the date
    /// ([`axcomp_data::Provenance`]; [`axcomp_data::Provenance::header_line`] is the one-line form for an
    /// image header). Absent in tables written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<axcomp_data::Provenance>,
}

/// Why a table file is not usable.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TableError {
    #[error("format is {0:?}, expected \"{FORMAT}\"")]
    Format(String),
    #[error("the table has {0} segments; it needs 1..=1024")]
    SegmentCount(usize),
    #[error(
        "backward has {backward} segments but forward has {forward} (must be equal, or backward empty)"
    )]
    DirectionLengthMismatch { forward: usize, backward: usize },
    #[error("{field} = {value} is not valid ({why})")]
    Bad {
        field: &'static str,
        value: f64,
        why: &'static str,
    },
    #[error("{direction} segment {segment}: coefficient is not finite")]
    NonFinite {
        direction: &'static str,
        segment: usize,
    },
    #[error("{path}: {message}")]
    Io { path: String, message: String },
    #[error(transparent)]
    Spline(#[from] SplineError),
}

/// The table in firmware units, owning its coefficient arrays; [`OwnedTableSpec::spec`] borrows them as
/// the core's [`axcomp_core::TableSpec`].
#[derive(Debug, Clone, PartialEq)]
pub struct OwnedTableSpec {
    pub start_counts: i64,
    pub segment_counts: u32,
    pub forward: Vec<[f32; 4]>,
    pub backward: Vec<[f32; 4]>,
    pub outside: axcomp_core::OutsideStroke,
}

impl OwnedTableSpec {
    pub fn spec(&self) -> axcomp_core::TableSpec<'_> {
        axcomp_core::TableSpec {
            start_counts: self.start_counts,
            segment_counts: self.segment_counts,
            forward: &self.forward,
            backward: &self.backward,
            outside: self.outside,
        }
    }
}

/// A uniform grid on whole counts for a table over `[start, end]` (counts, not necessarily whole) with
/// knot spacing about `spacing` counts: `(start_counts, segment_counts, segments)`, `None` when a
/// segment would exceed `u32::MAX` counts.
///
/// The ends are rounded to the nearest count when they are within 1e-6 of one (the usual case: a
/// stroke of whole mm), else widened to the counts around them. Then the last knot is the stroke's
/// end whenever the span has a divisor `n` within a factor 2 of `span / spacing` (and at most 1024):
/// the smallest one at or above it (the spacing asked for or a little finer), else the largest below
/// it. `image group --geometry` needs the axis table and the geometry model's grid to span one
/// stroke. A span without such a divisor (a prime number of counts, say) takes the covering grid:
/// segments of `round(spacing)` counts, the last knot up to one segment past the end (the table
/// holds its end value there).
pub fn whole_count_grid(start: f64, end: f64, spacing: f64) -> Option<(i64, u32, usize)> {
    let near = |v: f64| (v - v.round()).abs() <= 1e-6 * v.abs().max(1.0);
    let lo = if near(start) {
        start.round()
    } else {
        start.floor()
    };
    let hi = if near(end) { end.round() } else { end.ceil() };
    let span = (hi - lo).max(1.0);
    let max = axcomp_core::MAX_SEGMENTS as u64;
    let wanted = ((span / spacing.max(1.0) - 1e-9).ceil() as u64).clamp(1, max);
    let span_counts = span as u64;
    let divides = |n: &u64| span_counts % n == 0;
    let finer = (wanted..=(2 * wanted).min(max)).find(divides);
    if let Some(n) = finer.or_else(|| (wanted.div_ceil(2)..wanted).rev().find(divides)) {
        let seg = span_counts / n;
        return (seg <= u64::from(u32::MAX)).then_some((lo as i64, seg as u32, n as usize));
    }
    let max = max as f64;
    let mut seg = spacing.round().max(1.0);
    let mut n = (span / seg).ceil().max(1.0);
    while n > max {
        seg += 1.0;
        n = (span / seg).ceil().max(1.0);
    }
    (seg <= u32::MAX as f64).then_some((lo as i64, seg as u32, n as usize))
}

fn horner(c: &[f64; 4], t: f64) -> f64 {
    c[0] + t * (c[1] + t * (c[2] + t * c[3]))
}

impl TableFile {
    pub fn segments(&self) -> usize {
        self.forward.len()
    }
    pub fn end_mm(&self) -> f64 {
        self.start_mm + self.segment_mm * self.forward.len() as f64
    }

    /// Checks format, sizes and finiteness.
    pub fn validate(&self) -> Result<(), TableError> {
        if self.format != FORMAT {
            return Err(TableError::Format(self.format.clone()));
        }
        let n = self.forward.len();
        if n == 0 || n > axcomp_core::MAX_SEGMENTS {
            return Err(TableError::SegmentCount(n));
        }
        if !self.backward.is_empty() && self.backward.len() != n {
            return Err(TableError::DirectionLengthMismatch {
                forward: n,
                backward: self.backward.len(),
            });
        }
        if !self.start_mm.is_finite() {
            return Err(TableError::Bad {
                field: "start_mm",
                value: self.start_mm,
                why: "not finite",
            });
        }
        if !(self.segment_mm > 0.0 && self.segment_mm.is_finite()) {
            return Err(TableError::Bad {
                field: "segment_mm",
                value: self.segment_mm,
                why: "must be > 0",
            });
        }
        for (direction, tab) in [("forward", &self.forward), ("backward", &self.backward)] {
            if let Some(segment) = tab.iter().position(|c| c.iter().any(|v| !v.is_finite())) {
                return Err(TableError::NonFinite { direction, segment });
            }
        }
        Ok(())
    }

    /// Predicted deviation (µm) at `x_mm` approached in `direction` (+1 forward, −1 backward, 0 = mean of
    /// both). Outside the table the end value is held.
    pub fn deviation_um(&self, x_mm: f64, direction: i8) -> f64 {
        let eval = |tab: &[[f64; 4]]| {
            let n = tab.len();
            if n == 0 {
                return 0.0;
            }
            let s = (x_mm - self.start_mm) / self.segment_mm;
            if !(s > 0.0) {
                return tab[0][0];
            }
            if s >= n as f64 {
                return tab[n - 1].iter().sum();
            }
            let i = (s.floor() as usize).min(n - 1);
            horner(&tab[i], s - i as f64)
        };
        if self.backward.is_empty() {
            return eval(&self.forward);
        }
        match direction {
            d if d > 0 => eval(&self.forward),
            d if d < 0 => eval(&self.backward),
            _ => 0.5 * (eval(&self.forward) + eval(&self.backward)),
        }
    }

    /// One direction's table as a piecewise cubic in mm (for resampling).
    fn curve(&self, tab: &[[f64; 4]]) -> PiecewiseCubic {
        let h = self.segment_mm;
        PiecewiseCubic {
            knots: (0..=tab.len())
                .map(|i| self.start_mm + h * i as f64)
                .collect(),
            coeffs: tab
                .iter()
                .map(|c| [c[0], c[1] / h, c[2] / (h * h), c[3] / (h * h * h)])
                .collect(),
        }
    }

    /// The table in scale counts for the firmware image, holding the end values outside the stroke.
    ///
    /// When `start_mm` and `segment_mm` are whole numbers of counts the coefficients are copied (as f32);
    /// otherwise the table is resampled (C2, same method as the fit) onto a whole-count grid of at most
    /// 1024 segments from the table's start to its end ([`whole_count_grid`]).
    pub fn try_to_core(&self, um_per_count: f64) -> Result<OwnedTableSpec, TableError> {
        self.validate()?;
        if !(um_per_count > 0.0 && um_per_count.is_finite()) {
            return Err(TableError::Bad {
                field: "um_per_count",
                value: um_per_count,
                why: "must be > 0",
            });
        }
        let per_mm = 1000.0 / um_per_count;
        let start = self.start_mm * per_mm;
        let seg = self.segment_mm * per_mm;
        let whole = |v: f64| (v - v.round()).abs() <= 1e-6 * v.abs().max(1.0);
        let to_f32 = |t: &[[f64; 4]]| t.iter().map(|c| c.map(|v| v as f32)).collect::<Vec<_>>();
        if whole(start) && whole(seg) && seg.round() >= 1.0 && seg.round() <= u32::MAX as f64 {
            return Ok(OwnedTableSpec {
                start_counts: start.round() as i64,
                segment_counts: seg.round() as u32,
                forward: to_f32(&self.forward),
                backward: to_f32(&self.backward),
                outside: axcomp_core::OutsideStroke::Hold,
            });
        }
        // Resample onto a whole-count grid whose last knot is the table's end (see [`whole_count_grid`]).
        let (start_counts, seg_counts, n) = whole_count_grid(start, self.end_mm() * per_mm, seg)
            .ok_or(TableError::Bad {
                field: "segment_mm",
                value: self.segment_mm,
                why: "too many counts",
            })?;
        let seg_counts = seg_counts as f64;
        let new_start_mm = start_counts as f64 / per_mm;
        let new_seg_mm = seg_counts / per_mm;
        let resample = |tab: &[[f64; 4]]| -> Result<Vec<[f32; 4]>, TableError> {
            let u = spline::resample_uniform(&self.curve(tab), new_start_mm, new_seg_mm, n)?;
            Ok(to_f32(&u.coeffs))
        };
        Ok(OwnedTableSpec {
            start_counts,
            segment_counts: seg_counts as u32,
            forward: resample(&self.forward)?,
            backward: if self.backward.is_empty() {
                Vec::new()
            } else {
                resample(&self.backward)?
            },
            outside: axcomp_core::OutsideStroke::Hold,
        })
    }

    /// [`TableFile::try_to_core`] for a table known to be valid.
    ///
    /// # Panics
    /// When the table does not validate or `um_per_count` is not finite and positive; use
    /// [`TableFile::try_to_core`] to get the error instead.
    pub fn to_core(&self, um_per_count: f64) -> OwnedTableSpec {
        match self.try_to_core(um_per_count) {
            Ok(t) => t,
            Err(e) => panic!("TableFile::to_core: {e}"),
        }
    }

    /// Reads and validates a table file.
    pub fn load(path: &Path) -> Result<TableFile, TableError> {
        let io = |m: String| TableError::Io {
            path: path.display().to_string(),
            message: m,
        };
        let bytes = std::fs::read(path).map_err(|e| io(e.to_string()))?;
        let text = axcomp_files::model_text(&bytes).map_err(io)?;
        // Another kind of model file: say so before serde's first missing field does.
        if let Some(why) = axcomp_files::wrong_format(text, FORMAT, "positioning table") {
            return Err(io(why));
        }
        let t: TableFile =
            serde_json::from_str(text).map_err(|e| io(format!("not a table file: {e}")))?;
        t.validate()?;
        Ok(t)
    }

    /// Writes the table as JSON through a temporary file and a rename (never half-written).
    pub fn save(&self, path: &Path) -> Result<(), TableError> {
        let text = self.to_json_string()?;
        write_atomic(path, text.as_bytes()).map_err(|e| TableError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })
    }

    /// The validated table as the JSON text [`TableFile::save`] writes (for writers that collect several
    /// outputs before writing any).
    pub fn to_json_string(&self) -> Result<String, TableError> {
        self.validate()?;
        let mut text = serde_json::to_string_pretty(self).map_err(|e| TableError::Io {
            path: String::new(),
            message: e.to_string(),
        })?;
        text.push('\n');
        Ok(text)
    }
}

/// The host libraries' one atomic write (temporary sibling, sync, rename): see `axcomp-files`.
use axcomp_files::write_atomic;

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> TableFile {
        TableFile {
            format: FORMAT.into(),
            axis: "X".into(),
            start_mm: -20.0,
            segment_mm: 1.25,
            forward: (0..32).map(|i| [i as f64, 1.0, -0.5, 0.25]).collect(),
            backward: (0..32)
                .map(|i| [i as f64 - 10.0, 1.0, -0.5, 0.25])
                .collect(),
            model: "test".into(),
            cv_rms_um: 1.0,
            raw_rms_um: 2.0,
            cv_method: "leave-one-run-out".into(),
            provenance: None,
        }
    }

    #[test]
    fn deviation_is_horner_per_segment() {
        let t = table();
        // x = -20 + 1.25·(3 + 0.5): segment 3, t = 0.5 → 3 + 0.5 − 0.125 + 0.03125.
        let x = -20.0 + 1.25 * 3.5;
        assert!((t.deviation_um(x, 1) - 3.40625).abs() < 1e-12);
        assert!((t.deviation_um(x, -1) - (3.40625 - 10.0)).abs() < 1e-12);
        assert!((t.deviation_um(x, 0) - (3.40625 - 5.0)).abs() < 1e-12);
        assert_eq!(t.deviation_um(-100.0, 1), 0.0); // held start value
    }

    #[test]
    fn to_core_copies_whole_count_grids_and_resamples_others() {
        let t = table();
        let c = t.to_core(0.1); // 1.25 mm = 12500 counts, −20 mm = −200000 counts
        assert_eq!((c.start_counts, c.segment_counts), (-200_000, 12_500));
        assert_eq!(c.forward.len(), 32);
        assert_eq!(c.forward[3], [3.0, 1.0, -0.5, 0.25]);
        let spec = c.spec();
        assert_eq!(spec.backward.len(), 32);
        // 0.3 µm per count: 1.25 mm = 4166.67 counts → resampled onto a whole-count grid. Reference: the
        // original (C2) table; tolerance 1e-3 µm (re-interpolation error of a smooth table, h⁴ small).
        let x: Vec<f64> = (0..9).map(|i| -20.0 + 5.0 * i as f64).collect();
        let y: Vec<f64> = x.iter().map(|v| 30.0 * (v / 9.0).sin()).collect();
        let s = spline::interpolate(&x, &y, spline::EndCondition::NotAKnot).unwrap();
        let u = spline::resample_uniform(&s, -20.0, 1.25, 32).unwrap();
        let smooth = TableFile {
            forward: u.coeffs,
            backward: Vec::new(),
            ..table()
        };
        let r = smooth.to_core(0.3);
        assert_eq!(r.segment_counts, 4167);
        assert!(r.backward.is_empty() && r.forward.len() <= 1024);
        let per_mm = 1000.0 / 0.3;
        for k in 0..=400 {
            let xmm = -19.9 + 0.099 * k as f64;
            let s = (xmm * per_mm - r.start_counts as f64) / r.segment_counts as f64;
            let i = (s.floor() as usize).min(r.forward.len() - 1);
            let tt = s - i as f64;
            let c = r.forward[i].map(|v| v as f64);
            let got = c[0] + tt * (c[1] + tt * (c[2] + tt * c[3]));
            assert!((got - smooth.deviation_um(xmm, 1)).abs() < 1e-3, "x={xmm}");
        }
    }

    /// An 800 mm stroke fitted with 397 segments (2.0151… mm, not whole counts of 0.1 µm) must not be
    /// resampled onto 20 151-count segments ending at 802.0194 mm, past the stroke: the last knot is the
    /// stroke's end, exactly (400 segments of 20 000 counts: the first divisor of 8 000 000 counts at
    /// or above 397); a span with no divisor near the spacing keeps the covering grid.
    #[test]
    fn the_last_knot_is_the_end_of_the_stroke() {
        let (start, seg, n) = whole_count_grid(0.0, 8_000_000.000_000_1, 8e6 / 397.0).unwrap();
        assert_eq!((start, seg, n), (0, 20_000, 400));
        let t = TableFile {
            start_mm: 0.0,
            segment_mm: 800.0 / 397.0,
            forward: vec![[1.0, 0.0, 0.0, 0.0]; 397],
            backward: Vec::new(),
            ..table()
        };
        let c = t.to_core(0.1);
        assert_eq!(
            c.start_counts + i64::from(c.segment_counts) * c.forward.len() as i64,
            8_000_000
        );
        // 133 334 counts = 2 · 163 · 409: no divisor within a factor 2 of 32 segments.
        let (_, seg, n) = whole_count_grid(-66_666.67, 66_666.67, 4166.67).unwrap();
        assert_eq!((seg, n), (4167, 32));
    }

    #[test]
    fn validation_names_the_problem() {
        let mut t = table();
        t.backward.pop();
        assert!(matches!(
            t.validate(),
            Err(TableError::DirectionLengthMismatch { .. })
        ));
        let mut t = table();
        t.forward[5][2] = f64::NAN;
        assert_eq!(
            t.validate(),
            Err(TableError::NonFinite {
                direction: "forward",
                segment: 5
            })
        );
        assert!(table().try_to_core(0.0).is_err());
    }

    #[test]
    fn save_and_load_round_trip() {
        let dir = std::env::temp_dir().join(format!("axcomp-table-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("t.json");
        table().save(&p).unwrap();
        assert_eq!(TableFile::load(&p).unwrap(), table());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
