//! `axcomp-export`: fitted models in the files controllers load, and readers of those files' grammars (the
//! tests parse every written file back with them).
//!
//! # Glossary
//! - **export**: the set of files ([`ExportFile`]) one format writes for one model; the command writes them
//!   into one folder, whole (no file of an earlier export is left beside them).
//! - **format** ([`Format`]): what a controller reads. Geometry model (`fit geometry`): [`Format::Tf5280`]
//!   (Beckhoff TwinCAT TF5280 / ISG volumetric compensation, [`tf5280`]) and [`Format::Heidenhain`]
//!   (TNC compensation value tables `.COM` with their assignment table `.CMA`, [`heidenhain`]). Rotary model
//!   (`fit rtest`): [`Format::LinuxCncXyzacTrt`] / [`Format::LinuxCncXyzbcTrt`] (LinuxCNC's
//!   `xyzac-trt-kins` / `xyzbc-trt-kins` rotary-point and offset values, [`linuxcnc`]). Positioning tables
//!   keep their formats in `axcomp_positioning::export`.
//! - **model error** `e`: as the models state it (`axcomp_kinematics`): the tool point relative to the
//!   workpiece, reached − commanded. Each writer states the sign the controller wants and how it was derived.
//! - **what it cannot take**: errors of the model a format has no place for; each export lists them and,
//!   where the project's kinematics can evaluate it, the error that remains without them.

pub mod heidenhain;
pub mod linuxcnc;
pub mod tf5280;

/// One written file: its name inside the export folder and its text.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportFile {
    pub name: String,
    pub text: String,
}

impl ExportFile {
    pub fn new(name: impl Into<String>, text: impl Into<String>) -> ExportFile {
        ExportFile {
            name: name.into(),
            text: text.into(),
        }
    }
}

/// Model kinds an export reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelKind {
    Positioning,
    Geometry,
    Rotary,
}

impl ModelKind {
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Positioning => "positioning table (fit positioning)",
            ModelKind::Geometry => "geometry model (fit geometry)",
            ModelKind::Rotary => "rotary-axis model (fit rtest)",
        }
    }
}

/// Formats of the geometry and rotary models (the positioning formats live in `axcomp_positioning`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Tf5280,
    Heidenhain,
    LinuxCncXyzacTrt,
    LinuxCncXyzbcTrt,
}

impl Format {
    pub const ALL: [Format; 4] = [
        Format::Tf5280,
        Format::Heidenhain,
        Format::LinuxCncXyzacTrt,
        Format::LinuxCncXyzbcTrt,
    ];

    /// The `--format` name.
    pub fn name(self) -> &'static str {
        match self {
            Format::Tf5280 => "tf5280",
            Format::Heidenhain => "heidenhain",
            Format::LinuxCncXyzacTrt => "linuxcnc-xyzac-trt",
            Format::LinuxCncXyzbcTrt => "linuxcnc-xyzbc-trt",
        }
    }

    pub fn parse(s: &str) -> Option<Format> {
        Format::ALL.into_iter().find(|f| f.name() == s.trim())
    }

    /// The model kind the format is written from.
    pub fn model_kind(self) -> ModelKind {
        match self {
            Format::Tf5280 | Format::Heidenhain => ModelKind::Geometry,
            _ => ModelKind::Rotary,
        }
    }
}

/// Errors of an export (each names what and why).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ExportError {
    #[error("format {format} takes a {want}, not a {got}")]
    WrongModel {
        format: &'static str,
        want: &'static str,
        got: &'static str,
    },
    #[error("format {format} is for a {want} machine; the model is of a {got} machine")]
    WrongMachine {
        format: &'static str,
        want: &'static str,
        got: &'static str,
    },
    #[error("--step {step}: {why}")]
    BadStep { step: f64, why: String },
    #[error("no poses to evaluate the remaining error on")]
    NoPoses,
}

/// Positions from `lo` to `hi` (mm) every `step` mm, the last one at `hi`; `step` ≤ 0 means 40 steps.
/// At most `max` positions (a finer step is an error naming the step).
pub fn positions(lo: f64, hi: f64, step: f64, max: usize) -> Result<Vec<f64>, ExportError> {
    let step = if step > 0.0 { step } else { (hi - lo) / 40.0 };
    if !step.is_finite() {
        return Err(ExportError::BadStep {
            step,
            why: "not a finite number".into(),
        });
    }
    let n = ((hi - lo) / step - 1e-9).ceil().max(0.0) + 1.0;
    if n > max as f64 {
        return Err(ExportError::BadStep {
            step,
            why: format!(
                "{n} positions over {lo} … {hi} mm; this format takes at most {max} (give a larger step)"
            ),
        });
    }
    let mut v: Vec<f64> = (0..n as usize - 1).map(|k| lo + k as f64 * step).collect();
    v.push(hi);
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_end_at_the_range_end_and_respect_the_limit() {
        assert_eq!(
            positions(0.0, 10.0, 4.0, 10).unwrap(),
            vec![0.0, 4.0, 8.0, 10.0]
        );
        assert_eq!(positions(0.0, 8.0, 4.0, 10).unwrap(), vec![0.0, 4.0, 8.0]);
        assert_eq!(positions(0.0, 800.0, 0.0, 100).unwrap().len(), 41);
        assert!(positions(0.0, 800.0, 1.0, 256).is_err());
        for f in Format::ALL {
            assert_eq!(Format::parse(f.name()), Some(f));
        }
    }
}
