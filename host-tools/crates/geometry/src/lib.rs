//! `axcomp-geometry`: the 21 ISO 230-1 geometric errors of a three-axis machine from laser line
//! measurements.
//!
//! # Glossary
//! - **components, topology, lever arm, signs**: as in `axcomp-kinematics` (ISO 230-1 names `EXX` … `EA0Z`;
//!   errors are the tool point relative to the workpiece, reached − commanded, µm; angles µrad, right-handed;
//!   each function zero at its axis's zero; straightness with zero least-squares slope, the slope between axes
//!   being the squareness).
//! - **reading**: one row of the laser line CSV, the error projected on the beam (`deviation_um`).
//! - **design matrix**: one row per reading, one column per parameter (cubic B-spline coefficients of the 18
//!   functions on each axis's knot grid, constrained to the conventions above, and the 3 squareness values);
//!   the model is linear in them ([`fit::Layout`]).
//! - **identifiability**: the rank and singular values of the column-normalised stacked design; its null
//!   space names the components (or combinations) the lines cannot separate ([`fit::Identifiability`]).
//!   Those are reported `identified: false` with the reason; the default fit estimates them at the damped
//!   minimum norm (a weak prior of size 0 on every parameter, [`fit::DEFAULT_DAMPING`]), the plain and
//!   seven-line methods fix them at 0.
//! - **identifiable floor**: the held-out RMS of the best model the fitted lines can determine (needs the
//!   truth: computed on the twin); `fit geometry` reports its computable parts ([`analysis::FloorInfo`]),
//!   `plan geometry` the further lines that lower it ([`plan::FurtherLine`]).
//! - **seven-line method** (seed 000): line 1 along X, lines 2–3 the XY face diagonals read step-wise, lines
//!   4–7 the body diagonals read step-wise; it yields 17 parameters — EXX, EYY, EZZ; EYX, EZX, EXY, EZY, EXZ,
//!   EYZ; EAX, EBX, ECX, EAY, EBY; EC0Y, EB0Z, EA0Z — and fixes ECY, EAZ, EBZ, ECZ, which have no lever arm
//!   when the reflector is on the tool reference point (eq. 9), so no reading depends on them.
//! - **smoothing**: a second-difference (P-spline) penalty λ on each function's coefficients, λ chosen by
//!   leave-one-line-out cross-validation from a grid that includes 0 (plain least squares).
//! - **evidence prior** (`--prior evidence`): instead, per component kind a roughness and a size precision,
//!   the damping and the knot grid that maximise the marginal likelihood of the training readings
//!   ([`evidence`]).
//! - **standard uncertainty**: from the parameter covariance σ̂²·M⁻¹AᵀA·M⁻¹ (M = AᵀA + λP), σ̂ the residual
//!   standard deviation with the fit's effective degrees of freedom.
//! - **volumetric**: the model's error magnitude |e| over an 11×11×11 grid of the measured axis-position box
//!   (tool offset 0).
//! - **ISO 230-6 figure** of a body diagonal: the range (max − min) of the readings along it, before (raw) and
//!   after (residual) the model.

pub mod analysis;
pub mod data;
mod design;
pub mod evidence;
pub mod export;
pub mod fit;
mod layout;
pub mod model;
pub mod plan;
pub mod report;
pub mod spline;

pub use analysis::{FitReport, Judge, analyse};
pub use data::LineData;
pub use fit::{Fit, FitOptions, Method, fit};
pub use model::{GeometryModel, RowPrediction, predict_rows};

/// Errors of geometry identification.
#[derive(Debug, thiserror::Error)]
pub enum GeometryError {
    #[error(transparent)]
    Data(#[from] axcomp_data::DataError),
    #[error(
        "{at}: column {column}: the value is not a finite number below 1e12 in magnitude (a corrupt cell?)"
    )]
    NonFinite { at: String, column: String },
    #[error("line {line} ({at}): only {targets} distinct targets; a line needs at least 3")]
    TooFewTargets {
        line: String,
        at: String,
        targets: usize,
    },
    #[error(
        "line {line} ({at}): the beam (beam_x, beam_y, beam_z) has length {norm:.6}, not a unit vector"
    )]
    BeamNotUnit { line: String, at: String, norm: f64 },
    #[error("line {line} ({at}): a single target and no beam columns: its direction is unknown")]
    NoBeam { line: String, at: String },
    #[error("no rows to fit (after --where/--holdout)")]
    NoRows,
    #[error("no component can be identified from these lines")]
    NothingIdentifiable,
    #[error("{at}: axis position {q:?} mm lies outside the model's measured range ({range})")]
    OutsideModel {
        at: String,
        q: [f64; 3],
        /// The axis outside and its range, e.g. `Y 0 … 300 mm`.
        range: String,
    },
    #[error(
        "{file}: beam columns {present} without {missing}: give all three of beam_x, beam_y, beam_z (a unit vector), or none (the beam is then the direction from each line's first to its last target)"
    )]
    PartialBeam {
        file: String,
        present: String,
        missing: String,
    },
    #[error("{source_name}: not a geometry model: {reason}")]
    BadModel { source_name: String, reason: String },
    #[error("{source_name}: not a valid geometry model: {entry}: {reason}")]
    BadModelEntry {
        source_name: String,
        entry: String,
        reason: String,
    },
    #[error("{0}")]
    Kinematics(#[from] axcomp_kinematics::KinematicsError),
    #[error("{what}: {cause}")]
    Io {
        what: String,
        #[source]
        cause: std::io::Error,
    },
    #[error("{0}")]
    Plan(String),
}
