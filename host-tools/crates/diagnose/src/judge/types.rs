//! The verdict rule's inputs and results: the campaign as columns, the candidate families and their
//! variants, the options, and the diagnosis with its judged candidates.

use serde::Serialize;
use serde_json::{Map, Value};

use crate::EffectKind;
use crate::error::DiagnoseError;
use crate::locate::Region;

/// Builds a variant's columns over all rows on demand (a family with hundreds of searched variants then
/// holds only their parameters: memory O(rows), not O(rows·variants)).
pub type ColumnsFn<'a> = Box<dyn Fn() -> Vec<Vec<f64>> + 'a>;

/// The campaign's `not_applicable` lines (`kind: why`) from (kind, why) pairs.
pub fn not_applicable_lines<K: std::fmt::Display>(v: &[(K, String)]) -> Vec<String> {
    v.iter().map(|(k, why)| format!("{k}: {why}")).collect()
}

/// One variant of a candidate family with its columns built over all (stacked) rows: what the probe and
/// R-test diagnoses build before handing them to [`judge`](super::judge) as [`CandidateVariant`]s.
#[derive(Debug, Clone)]
pub struct BuiltVariant {
    pub columns: Vec<Vec<f64>>,
    pub params: Map<String, Value>,
    /// Added columns + searched parameters.
    pub n_params: usize,
}

/// A candidate family of effect kind `K` built from the data's columns.
#[derive(Debug, Clone)]
pub struct BuiltFamily<K> {
    pub kind: K,
    pub variants: Vec<BuiltVariant>,
}

impl<K> BuiltFamily<K> {
    /// The family as the verdict rule takes it: named `name`, tie-break rank `simplicity`, each variant's
    /// searched parameters = `n_params` − its columns.
    pub fn candidate(&self, name: &str, simplicity: u8) -> CandidateFamily<'static> {
        let mut fam = CandidateFamily::new(
            name,
            self.variants
                .iter()
                .map(|v| {
                    let searched = v.n_params.saturating_sub(v.columns.len());
                    CandidateVariant::new(v.columns.clone(), v.params.clone(), searched)
                })
                .collect(),
        );
        fam.simplicity = simplicity;
        fam
    }
}

/// A variant's columns: built, or built on demand.
pub enum Columns<'a> {
    Built(Vec<Vec<f64>>),
    OnDemand(ColumnsFn<'a>),
}

/// One setting of a candidate family: its columns over all rows and its parameters.
pub struct CandidateVariant<'a> {
    pub columns: Columns<'a>,
    /// Searched (and descriptive) parameters, reported as the candidate's `params`.
    pub params: Map<String, Value>,
    /// Columns + searched nonlinear parameters (the penalty of BIC and "the simpler explanation").
    pub n_params: usize,
}

impl<'a> CandidateVariant<'a> {
    /// A variant with built columns and `searched` nonlinear parameters (`n_params` = columns + searched).
    pub fn new(columns: Vec<Vec<f64>>, params: Map<String, Value>, searched: usize) -> Self {
        let n_params = columns.len() + searched;
        CandidateVariant {
            columns: Columns::Built(columns),
            params,
            n_params,
        }
    }

    /// A variant whose columns are built when needed; `n_params` = columns + searched parameters.
    pub fn on_demand(
        params: Map<String, Value>,
        n_params: usize,
        build: impl Fn() -> Vec<Vec<f64>> + 'a,
    ) -> Self {
        CandidateVariant {
            columns: Columns::OnDemand(Box::new(build)),
            params,
            n_params,
        }
    }

    /// The columns over all rows.
    pub fn columns(&self) -> std::borrow::Cow<'_, [Vec<f64>]> {
        match &self.columns {
            Columns::Built(c) => std::borrow::Cow::Borrowed(c.as_slice()),
            Columns::OnDemand(f) => std::borrow::Cow::Owned(f()),
        }
    }

    /// The columns restricted to `rows` (indexed by position in `rows`).
    pub fn columns_on(&self, rows: &[usize]) -> Vec<Vec<f64>> {
        self.columns()
            .iter()
            .map(|c| rows.iter().map(|&i| c[i]).collect())
            .collect()
    }
}

/// Adds physically meaningful parameters to a candidate's `params` from its fitted coefficients
/// (default: `coefficients`, the list).
pub type Decorate<'a> = Box<dyn Fn(&mut Map<String, Value>, &[f64]) + 'a>;

/// An unmodelled effect kind: the variants of its columns.
pub struct CandidateFamily<'a> {
    /// The contract name of the effect kind.
    pub kind: String,
    pub variants: Vec<CandidateVariant<'a>>,
    /// Tie-break rank among candidates with as many parameters: lower = simpler, preferred (a special
    /// case before its generalisation).
    pub simplicity: u8,
    /// A sensor-free stand-in ("something changed with time"): blamed only when no other candidate
    /// explains the gap as well, whatever the parameter counts.
    pub last_resort: bool,
    /// Parameters derived from the fitted coefficients (None: the coefficients as a list).
    pub decorate: Option<Decorate<'a>>,
}

impl<'a> CandidateFamily<'a> {
    /// A family with simplicity rank 2, not a last resort, coefficients reported as a list.
    pub fn new(kind: impl Into<String>, variants: Vec<CandidateVariant<'a>>) -> Self {
        CandidateFamily {
            kind: kind.into(),
            variants,
            simplicity: 2,
            last_resort: false,
            decorate: None,
        }
    }
}

/// One campaign as columns (see the module glossary).
#[derive(Debug, Clone, Default)]
pub struct Campaign<'a> {
    /// Name of the target (for reports).
    pub target: String,
    /// The target over all rows, µm.
    pub y: &'a [f64],
    /// The base model's columns over all rows (intercept included if wanted).
    pub base_columns: Vec<Vec<f64>>,
    /// Named terms of the base model: they cover the trailing `Σ columns` base columns, in order
    /// (coefficients are filled in by [`judge`](super::judge) for terms of ≤ 4 columns).
    pub model: Vec<ModelTerm>,
    /// Training rows (fit) and held-out rows (judge only); disjoint, both non-empty.
    pub train: Vec<usize>,
    pub holdout: Vec<usize>,
    /// Training blocks for blocked CV (≥ 3 blocks) and the block bootstrap (≥ 2); may be empty.
    pub blocks: Vec<Vec<usize>>,
    /// Variables whose regions `where` reports (values over all rows).
    pub where_variables: Vec<(String, Vec<f64>)>,
    /// Training rows in position order, for the residual's lag-1 check (None: no position).
    pub position_order: Option<Vec<usize>>,
    /// Training rows in time order (row order without time), for the residual's lag-1 check.
    pub time_order: Vec<usize>,
    /// Kinds not considered, with why (reported as given).
    pub not_applicable: Vec<String>,
}

impl Campaign<'_> {
    /// Checks the shapes: columns of `y.len()` finite values, valid disjoint row sets.
    pub fn validate(&self) -> Result<(), DiagnoseError> {
        let n = self.y.len();
        if self.train.is_empty() {
            return Err(DiagnoseError::Invalid(
                "no training rows: nothing to fit the model on".into(),
            ));
        }
        if self.holdout.is_empty() {
            return Err(DiagnoseError::Invalid(
                "the holdout selects no rows: nothing to judge the model on".into(),
            ));
        }
        let mut seen = vec![0u8; n];
        for (set, rows) in [(1u8, &self.train), (2u8, &self.holdout)] {
            for &i in rows.iter() {
                if i >= n {
                    return Err(DiagnoseError::Invalid(format!(
                        "row index {i} out of range ({n} rows)"
                    )));
                }
                if seen[i] != 0 {
                    return Err(DiagnoseError::Invalid(format!(
                        "row {i} is listed twice (training and held-out rows must be disjoint)"
                    )));
                }
                seen[i] = set;
            }
        }
        if let Some(i) = self.y.iter().position(|v| !v.is_finite()) {
            return Err(DiagnoseError::Invalid(format!(
                "target `{}`: row {i} is not finite",
                self.target
            )));
        }
        for (k, c) in self.base_columns.iter().enumerate() {
            if c.len() != n {
                return Err(DiagnoseError::Invalid(format!(
                    "base column {k} has {} values, expected {n}",
                    c.len()
                )));
            }
            if let Some(i) = c.iter().position(|v| !v.is_finite()) {
                return Err(DiagnoseError::Invalid(format!(
                    "base column {k}: row {i} is not finite"
                )));
            }
        }
        let named: usize = self.model.iter().map(|t| t.columns).sum();
        if named > self.base_columns.len() {
            return Err(DiagnoseError::Invalid(format!(
                "the model terms name {named} columns, the base model has {}",
                self.base_columns.len()
            )));
        }
        for (name, v) in &self.where_variables {
            if v.len() != n {
                return Err(DiagnoseError::Invalid(format!(
                    "where variable `{name}` has {} values, expected {n}",
                    v.len()
                )));
            }
        }
        Ok(())
    }
}

/// Settings of the diagnosis (validated by [`DiagnoseOptions::build`]).
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Level of the training F-test (after Bonferroni over every searched variant).
    pub alpha: f64,
    /// Upper bound of the pitch-error spline segments.
    pub pitch_segments_max: usize,
    /// Candidates to consider (default: every kind not in the model).
    pub candidates: Option<Vec<EffectKind>>,
    /// Print the steps (with elapsed seconds) on stderr.
    pub progress: bool,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            alpha: 0.01,
            pitch_segments_max: 8,
            candidates: None,
            progress: false,
        }
    }
}

impl DiagnoseOptions {
    pub fn build(self) -> Result<Self, DiagnoseError> {
        if !(self.alpha > 0.0 && self.alpha < 0.5) {
            return Err(DiagnoseError::Options(format!(
                "alpha must be in (0, 0.5), got {}",
                self.alpha
            )));
        }
        if self.pitch_segments_max == 0 {
            return Err(DiagnoseError::Options(
                "pitch_segments_max must be ≥ 1".into(),
            ));
        }
        Ok(self)
    }
}

/// The model's error on training and held-out rows.
#[derive(Debug, Clone, Serialize)]
pub struct Gap {
    pub train_rms_um: f64,
    pub holdout_rms_um: f64,
    pub holdout_max_um: f64,
}

/// One fitted term of the base model.
#[derive(Debug, Clone, Serialize)]
pub struct ModelTerm {
    pub kind: String,
    pub params: Map<String, Value>,
    pub columns: usize,
}

/// An unmodelled effect, judged by refitting the whole model with it.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    pub kind: String,
    pub score: f64,
    pub params: Map<String, Value>,
    pub holdout_rms_after_um: f64,
    pub shrink_pct: f64,
    /// Added columns + searched parameters.
    pub n_params: usize,
    pub train_rms_after_um: f64,
    /// Training ΔBIC of the refit against the base model (positive = better).
    pub train_delta_bic: f64,
    /// F-test p-value, Bonferroni-corrected over all searched variants of all candidates.
    pub train_p_value: f64,
    /// One-sided paired test of the held-out squared residuals (reported, not used for the verdict: it
    /// scales with the number of held-out rows).
    pub holdout_p_value: f64,
    /// Held-out RMS reduction, µm (`gap − holdout_rms_after_um`).
    pub holdout_gain_um: f64,
    /// The noise σ the materiality test uses: the refit's training residual standard deviation, µm.
    pub noise_um: f64,
    /// The held-out gain is material: ≥ [`MIN_SHRINK_PCT`] % of the gap and ≥ [`MIN_NOISE_FRACTION`]·σ.
    ///
    /// [`MIN_SHRINK_PCT`]: super::rule::MIN_SHRINK_PCT
    /// [`MIN_NOISE_FRACTION`]: super::rule::MIN_NOISE_FRACTION
    pub material: bool,
    /// The held-out gain where the candidate acts (None when it acts on more than [`LOCAL_MAX_SHARE`] of
    /// the held-out rows or on fewer than [`LOCAL_MIN_ROWS`]).
    ///
    /// [`LOCAL_MAX_SHARE`]: super::rule::LOCAL_MAX_SHARE
    /// [`LOCAL_MIN_ROWS`]: super::rule::LOCAL_MIN_ROWS
    pub local: Option<LocalGain>,
    /// The train test passes at `alpha` and the held-out gain is material (the verdict rule).
    pub explains: bool,
    /// Largest |correlation| between the base model's training residual and one of the candidate's
    /// columns (residual cross-correlation with the candidate inputs).
    pub residual_correlation: f64,
    /// Blocked cross-validation on the training rows (blocks = runs, or time blocks without runs): RMS of
    /// the base model and of the refit (None when there are fewer than 3 blocks or the candidate fails
    /// the training test).
    pub cv_rms_before_um: Option<f64>,
    pub cv_rms_after_um: Option<f64>,
    /// Stability selection: share of 20 block-bootstrap resamples of the training rows in which this
    /// candidate has the best training ΔBIC (positive) of the candidates passing the training test.
    pub inclusion_probability: f64,
    /// The axis vocabulary's kind (set by [`crate::engine::diagnose`]; None for other data kinds).
    #[serde(skip)]
    pub kind_enum: Option<EffectKind>,
    /// Index of the candidate's family in the slice given to [`judge`](super::judge).
    #[serde(skip)]
    pub family_index: usize,
    /// Index of the chosen variant in its family.
    #[serde(skip)]
    pub variant_index: usize,
    /// The fitted coefficients of the chosen variant's columns in the refit.
    #[serde(skip)]
    pub coefficients: Vec<f64>,
    /// The candidate's own fitted contribution over all rows (µm).
    #[serde(skip)]
    pub contribution_um: Vec<f64>,
    /// Residual of the refit over all rows.
    #[serde(skip)]
    pub residual_after: Vec<f64>,
}

/// The held-out gain of a localised candidate on the rows where it acts (see [`LOCAL_SUPPORT_FRACTION`]).
///
/// [`LOCAL_SUPPORT_FRACTION`]: super::rule::LOCAL_SUPPORT_FRACTION
#[derive(Debug, Clone, Serialize)]
pub struct LocalGain {
    /// Held-out rows where the candidate's contribution is ≥ [`LOCAL_SUPPORT_FRACTION`] of its peak.
    ///
    /// [`LOCAL_SUPPORT_FRACTION`]: super::rule::LOCAL_SUPPORT_FRACTION
    pub rows: usize,
    /// The base model's held-out RMS on those rows, µm.
    pub rms_before_um: f64,
    /// The refit's held-out RMS on those rows, µm.
    pub rms_after_um: f64,
    pub shrink_pct: f64,
    /// ≥ [`LOCAL_MIN_SHRINK_PCT`] % and ≥ [`LOCAL_MIN_NOISE_FRACTION`]·σ.
    ///
    /// [`LOCAL_MIN_SHRINK_PCT`]: super::rule::LOCAL_MIN_SHRINK_PCT
    /// [`LOCAL_MIN_NOISE_FRACTION`]: super::rule::LOCAL_MIN_NOISE_FRACTION
    pub material: bool,
}

/// Whiteness of the training residual.
#[derive(Debug, Clone, Serialize)]
pub struct ResidualChecks {
    /// Lag-1 autocorrelation of the training residual in position order (None without positions).
    pub lag1_autocorr_position: Option<f64>,
    /// Lag-1 autocorrelation in time order (row order without time).
    pub lag1_autocorr_time: f64,
    /// `|ρ₁|·√n` above ~3 says the residual is not white (structure is left).
    pub white_position: Option<bool>,
    pub white_time: bool,
}

/// The full result (`--json` writes this).
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    pub target: String,
    pub n_train: usize,
    pub n_holdout: usize,
    pub model: Vec<ModelTerm>,
    pub gap: Gap,
    #[serde(rename = "where")]
    pub where_: Vec<Region>,
    /// Where the verdict's refit removes most of the held-out gap (empty when the verdict is `none`).
    pub verdict_where: Vec<Region>,
    pub effects: Vec<Candidate>,
    pub verdict: String,
    /// The rule the verdict follows ([`VERDICT_RULE`]).
    ///
    /// [`VERDICT_RULE`]: super::rule::VERDICT_RULE
    pub verdict_rule: String,
    /// Why the verdict was chosen (ties, nothing beyond noise, ...).
    pub note: String,
    /// Candidates that explain the gap as well as the verdict (indistinguishable on held-out rows).
    pub ties: Vec<String>,
    /// Kinds not considered because their columns are absent or constant.
    pub not_applicable: Vec<String>,
    pub residual_checks: ResidualChecks,
    /// Noise level: training residual standard deviation (dof-corrected), µm.
    pub noise_um: f64,
    /// Base-model residual over all rows (for reports).
    #[serde(skip)]
    pub residual: Vec<f64>,
    /// The base model's columns over all rows, without the intercept (for oracle refits).
    #[serde(skip)]
    pub model_columns: Vec<Vec<f64>>,
}

impl Diagnosis {
    /// The verdict's candidate, if any.
    pub fn verdict_candidate(&self) -> Option<&Candidate> {
        self.effects.iter().find(|c| c.kind == self.verdict)
    }
}
