//! What a campaign fit is asked ([`Request`]) and what it returns ([`Outcome`], with the [`Judged`] rows):
//! a leaf below the campaign fit, its figures and its report, which all name these types.

use std::path::PathBuf;

use serde_json::Value;

use crate::fit::FitResult;
use crate::warmup::WarmupFit;

/// The options of one campaign fit, as the command line gives them.
#[derive(Debug, Clone, Default)]
pub struct Request {
    /// The measurement file (named in messages, the JSON and the report).
    pub data: PathBuf,
    /// The `--where` filters applied when reading it (named in the report and the plots).
    pub where_: Vec<String>,
    /// The error column modelled.
    pub target: String,
    /// `--holdout SPEC`: rows judged only.
    pub holdout: Option<String>,
    /// `--cv COL`: the grouping column of the cross-validation.
    pub cv: Option<String>,
    pub segments: Option<usize>,
    pub segment_mm: Option<f64>,
    /// Axis name written into the table (default: the file's one `axis` value, else X).
    pub axis: Option<String>,
    /// Write the table even when the do-no-harm guard refuses.
    pub force: bool,
    /// `--drift COL`: the warm-up age column.
    pub drift: Option<String>,
    pub run_period_s: Option<f64>,
    pub max_folds: usize,
    /// Where the table is to be written (`table.path` and `table_written` in the JSON).
    pub out: Option<PathBuf>,
    /// Reports each step of a large fit on stderr (`None`: silent).
    pub progress: Option<fn(&str)>,
}

impl Request {
    pub(crate) fn note(&self, what: &str) {
        if let Some(p) = self.progress {
            p(what);
        }
    }

    /// `true` when the judged rows are held out (`--holdout`), `false` under cross-validation.
    pub fn is_holdout(&self) -> bool {
        self.holdout.is_some()
    }

    /// The JSON key of the judged RMS: `holdout_rms_um` or `cv_rms_um`.
    pub fn judged_key(&self) -> &'static str {
        if self.is_holdout() {
            "holdout_rms_um"
        } else {
            "cv_rms_um"
        }
    }
}

/// The rows the figures are computed on, with their predictions.
#[derive(Debug, Clone, Default)]
pub struct Judged {
    pub x: Vec<f64>,
    pub direction: Vec<i8>,
    pub run: Vec<i64>,
    pub deviation: Vec<f64>,
    pub predicted: Vec<f64>,
}

/// Everything a campaign fit computed, before anything is written.
#[derive(Debug)]
pub struct Outcome {
    /// The `fit positioning` JSON.
    pub json: Value,
    /// The Markdown report.
    pub report: String,
    pub fit: FitResult,
    pub judged: Judged,
    /// The guard refused and `--force` was not given: no table is written.
    pub refused: bool,
    /// The warm-up drift, when it was kept.
    pub warmup: Option<WarmupFit>,
    /// Raw and judged RMS of the judged rows (µm).
    pub raw_rms_um: f64,
    pub judged_rms_um: f64,
}
