//! The fit's inputs, options, candidate families and results, and the problem the candidates are fitted
//! on (shared by the fit and its smoothing-spline search).

use serde::Serialize;
use thiserror::Error;

use crate::guard::{self, GuardVerdict};
use crate::spline::{PiecewiseCubic, SplineError};
use crate::table_file::TableFile;

/// One measured point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    pub target_mm: f64,
    /// +1 positive approach (forward), −1 negative approach (backward), 0 unknown.
    pub direction: i8,
    /// Cross-validation group (run id); any integer, rows with equal values are left out together.
    pub run: i64,
    pub deviation_um: f64,
}

/// Settings of [`fit`](super::fit).
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// Axis name written into the table.
    pub axis: String,
    /// Number of uniform table segments (≤ 1024); default from the model's knot spacing.
    pub segments: Option<usize>,
    /// Table segment length in mm (alternative to `segments`).
    pub segment_mm: Option<f64>,
    /// Folds used when the data has fewer than 3 runs (every k-th row).
    pub row_folds: usize,
    /// Do-no-harm rule: the cross-validated RMS must be at most this fraction of the raw RMS.
    pub improvement_ratio: f64,
    /// Fraction of runs whose own held-out RMS must improve on their raw RMS.
    pub runs_improved_fraction: f64,
    /// Restrict the candidates to these names (empty = all).
    pub only: Vec<String>,
    /// At most this many cross-validation folds: with more runs, consecutive runs are grouped into this
    /// many folds (`leave-runs-out`), so a campaign of thousands of cycles costs ~`max_folds` fits.
    pub max_folds: usize,
    /// Called with a short note after each candidate kind is cross-validated (progress on large data).
    pub progress: Progress,
}

/// An optional progress callback of [`FitOptions`] (equal to any other: it does not change the fit).
#[derive(Clone, Copy, Default)]
pub struct Progress(pub Option<fn(&str)>);

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "Progress(on)"
        } else {
            "Progress(off)"
        })
    }
}

impl PartialEq for Progress {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            axis: "X".into(),
            segments: None,
            segment_mm: None,
            row_folds: 5,
            improvement_ratio: guard::DEFAULT_IMPROVEMENT_RATIO,
            runs_improved_fraction: guard::DEFAULT_RUNS_IMPROVED_FRACTION,
            only: Vec::new(),
            max_folds: DEFAULT_MAX_FOLDS,
            progress: Progress(None),
        }
    }
}

/// Default [`FitOptions::max_folds`].
pub const DEFAULT_MAX_FOLDS: usize = 20;

/// Why a fit failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FitError {
    #[error("need at least {needed} points with finite target_mm and deviation, got {got}")]
    TooFewPoints { needed: usize, got: usize },
    #[error("row {row}: non-finite value ({what})")]
    NonFinite { row: usize, what: &'static str },
    #[error("all targets are at the same position ({0} mm); nothing to fit along the stroke")]
    NoStroke(f64),
    #[error("table options: {0}")]
    BadTable(String),
    #[error("no candidate model could be fitted: {0}")]
    NoCandidate(String),
    #[error(transparent)]
    Spline(#[from] SplineError),
}

/// Forward and (for bidirectional data) backward deviation curves.
#[derive(Debug, Clone, PartialEq)]
pub struct Curves {
    pub forward: PiecewiseCubic,
    pub backward: Option<PiecewiseCubic>,
}

impl Curves {
    /// Predicted deviation (µm) at `x_mm` approached in `direction` (0 = mean of both).
    pub fn predict(&self, x_mm: f64, direction: i8) -> f64 {
        match (&self.backward, direction) {
            (None, _) => self.forward.eval(x_mm),
            (Some(b), d) if d < 0 => b.eval(x_mm),
            (Some(_), d) if d > 0 => self.forward.eval(x_mm),
            (Some(b), _) => 0.5 * (self.forward.eval(x_mm) + b.eval(x_mm)),
        }
    }
}

/// Curve family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    Linear,
    PiecewiseLinear,
    SplineNatural,
    SplineNotAKnot,
    SmoothingSplineUniform,
    SmoothingSplineFeature,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Linear => "linear",
            Kind::PiecewiseLinear => "piecewise_linear",
            Kind::SplineNatural => "spline_natural",
            Kind::SplineNotAKnot => "spline_not_a_knot",
            Kind::SmoothingSplineUniform => "smoothing_spline_uniform",
            Kind::SmoothingSplineFeature => "smoothing_spline_feature",
        }
    }
    /// Order of simplicity used to break near-ties (lower = simpler).
    pub(super) fn simplicity(self) -> usize {
        match self {
            Kind::Linear => 0,
            Kind::SplineNatural => 1,
            Kind::SplineNotAKnot => 2,
            // Not C2: the table (C2 cubic segments) cannot reproduce its kinks exactly.
            Kind::PiecewiseLinear => 3,
            Kind::SmoothingSplineUniform => 4,
            Kind::SmoothingSplineFeature => 5,
        }
    }
    pub(super) fn is_grid(self) -> bool {
        matches!(
            self,
            Kind::PiecewiseLinear | Kind::SplineNatural | Kind::SplineNotAKnot
        )
    }
}

/// How the two directions are modelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Structure {
    Single,
    Separate,
    #[serde(rename = "mean+const_reversal")]
    MeanConstReversal,
    #[serde(rename = "mean+linear_reversal")]
    MeanLinearReversal,
    #[serde(rename = "mean+smooth_reversal")]
    MeanSmoothReversal,
}

impl Structure {
    pub fn name(self) -> &'static str {
        match self {
            Structure::Single => "single",
            Structure::Separate => "separate",
            Structure::MeanConstReversal => "mean+const_reversal",
            Structure::MeanLinearReversal => "mean+linear_reversal",
            Structure::MeanSmoothReversal => "mean+smooth_reversal",
        }
    }
    pub(super) fn simplicity(self) -> usize {
        match self {
            Structure::Single => 0,
            Structure::MeanConstReversal => 1,
            Structure::MeanLinearReversal => 2,
            Structure::MeanSmoothReversal => 3,
            Structure::Separate => 4,
        }
    }
}

/// One candidate model and its cross-validated figure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    /// `kind/structure`, e.g. `spline_not_a_knot/separate`.
    pub name: String,
    pub kind: Kind,
    pub structure: Structure,
    /// Cross-validated RMS (µm) over all rows (each predicted by the model fitted without its fold).
    pub cv_rms_um: f64,
    /// Smoothing parameters chosen by CV for the final fit (smoothing kinds only): `[ρ]` or `[ρ_mean, ρ_reversal]`
    /// (separate: `[ρ_forward, ρ_backward]`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub rho: Vec<f64>,
    /// Number of knot intervals of the fitted curve.
    pub intervals: usize,
}

/// How the rows were split for cross-validation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CvSplit {
    /// `leave-one-run-out` or `k-fold-by-row`.
    pub method: String,
    pub folds: usize,
}

/// Everything [`fit`](super::fit) found.
#[derive(Debug, Clone)]
pub struct FitResult {
    /// The chosen model resampled to the firmware's uniform table.
    pub table: TableFile,
    /// The chosen model's curves (before resampling).
    pub curves: Curves,
    /// Name of the chosen candidate.
    pub chosen: String,
    /// Why it was chosen.
    pub reason: String,
    /// Every candidate with its CV figure, best first.
    pub candidates: Vec<Candidate>,
    /// Per input row: the chosen model's prediction fitted without that row's fold.
    pub cv_predictions: Vec<f64>,
    /// Per input row: its fold index.
    pub fold_of_row: Vec<usize>,
    pub split: CvSplit,
    /// RMS of the deviations (no compensation).
    pub raw_rms_um: f64,
    /// RMS of deviation − cv_prediction.
    pub cv_rms_um: f64,
    /// Largest |table − model curve| over the stroke (resampling error), µm.
    pub resampling_max_um: f64,
    /// Do-no-harm verdict on the cross-validated predictions.
    pub guard: GuardVerdict,
}

/// The observations of one fit with their folds and stroke.
pub(super) struct Problem<'a> {
    pub(super) obs: &'a [Observation],
    pub(super) fold: Vec<usize>,
    pub(super) folds: usize,
    pub(super) lo: f64,
    pub(super) hi: f64,
    /// Sorted unique targets when the data lies on a grid of repeated targets.
    pub(super) grid: Option<Vec<f64>>,
}

/// One candidate structure evaluated: the curves fitted without each fold, the curves fitted on all rows,
/// and the smoothing parameters chosen for them.
pub(super) type Evaluation = (Vec<Curves>, Curves, Vec<f64>);
