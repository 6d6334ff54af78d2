//! Thermal (thermo-force) error model: selection, lags, fitting, validation, do-no-harm guard.
//!
//! Glossary:
//! - **sensor**: a temperature column `NAME_degC`; its **rise** is `ΔT = lag(T, τ) − T_ref`, `T_ref` = the
//!   sensor's first reading.
//! - **term**: `b · ΔT` (µm/K) per selected sensor; **force term**: `χ · F` (µm/N) per force column, fitted
//!   jointly with the thermal terms (coupled thermo-force model).
//! - **model**: `e = b0 + Σ b_s ΔT_s + Σ χ_f F_f`, the predicted error (µm), which the firmware subtracts.
//! - **training / held-out rows**: `--holdout` rows are never used for fitting or selection, only to judge.
//! - **raw**: the target minus its reference value (the mean of its first `reference_rows` rows, i.e. the
//!   state where every ΔT = 0); every raw figure (held-out, training, per condition, validation) uses it.
//! - **blocks**: the training rows cut by operating condition / thermal regime ([`crate::blocks`]); the inner
//!   CV (lag grid, ridge and elastic-net λ, forward selection) leaves one block out at a time.
//! - **transfer validation** (the default's model choice): every candidate procedure — plain least squares on
//!   every sensor, every sensor with one lag per sensor, ridge, elastic net, greedy forward selection with
//!   lags, FCM + GRA — is re-run without each block (all its own choices included) and predicts that block;
//!   the default is the candidate with the lowest RMS over the blocks among those that beat plain least
//!   squares by more than one standard error of the per-block paired difference (else plain least squares).
//!   With a single regime among the training rows only plain least squares and every-sensor-with-lags are
//!   eligible (the others are reported): these rows cannot show how dropping or shrinking collinear sensors
//!   transfers to another regime.
//! - **lag support**: a sensor whose training trace shows one episode of change (a step, a single rise) gets
//!   lags only up to a third of that episode ([`LAG_CAP_FRACTION`]); with two or more episodes, any lag on the
//!   grid.
//! - **do-no-harm guard**: with held-out rows, the model's RMS on them must not exceed raw; without, the
//!   default's validation RMS must not exceed raw over the same blocks (no candidate beats raw → refused), a
//!   forced selection's leave-one-block-out RMS must not exceed raw on the training rows.

use nalgebra::DMatrix;
use serde::Serialize;

use crate::lag::lag;
use crate::linalg::{condition_number, lstsq, vif};
use crate::select::{self, Candidate, GramSet};
use crate::stats::rms;

/// What the fit reads (already filtered, renamed and scaled).
#[derive(Debug, Clone)]
pub struct ThermalInput {
    pub time_s: Vec<f64>,
    /// Temperature sensors (name without the `_degC` suffix).
    pub sensors: Vec<Series>,
    /// Force columns (`*_N`), used as linear terms.
    pub forces: Vec<Series>,
    /// The error channel to model (µm).
    pub target: Vec<f64>,
    /// Operating condition of each row (`--cv` column), if any.
    pub conditions: Option<Vec<String>>,
    /// Held-out rows (true = judge only).
    pub holdout: Option<Vec<bool>>,
}

/// Ridge setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Ridge {
    Off,
    Fixed(f64),
    /// λ chosen by inner CV from {0, 1e-6, …, 10}.
    Auto,
}

/// Which sensor selection to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Selection {
    /// The method with the lower nested CV RMS (FCM + GRA or forward selection).
    Auto,
    /// The reference method, fuzzy c-means + grey relational analysis.
    FcmGra,
    /// Forward selection scored by inner CV.
    Forward,
    /// Every usable sensor (no selection; a baseline).
    All,
}

/// Fit settings (validated by [`ThermalOptions::build`]).
#[derive(Debug, Clone, Copy)]
pub struct ThermalOptions {
    pub lags: bool,
    pub ridge: Ridge,
    /// Most sensors in the model (≤ `axcomp_core::MAX_SENSORS` = 16).
    pub max_sensors: usize,
    /// Time blocks for the inner CV when there are fewer than 3 conditions.
    pub time_blocks: usize,
    /// Lag grid size (besides τ = 0).
    pub lag_grid: usize,
    pub selection: Selection,
    /// The target's reference value is the mean of its first `reference_rows` rows (file order): the raw
    /// figures are the target minus it (the sensors' reference readings are their first row).
    pub reference_rows: usize,
}

impl Default for ThermalOptions {
    fn default() -> Self {
        ThermalOptions {
            lags: false,
            ridge: Ridge::Off,
            max_sensors: 6,
            time_blocks: 5,
            lag_grid: 8,
            selection: Selection::Auto,
            reference_rows: 1,
        }
    }
}

impl ThermalOptions {
    /// Checks the settings.
    pub fn build(self) -> Result<Self, ThermalError> {
        if self.max_sensors == 0 || self.max_sensors > 16 {
            return Err(ThermalError::Option("max_sensors must be 1..=16"));
        }
        if self.time_blocks < 3 {
            return Err(ThermalError::Option("time_blocks must be >= 3"));
        }
        if let Ridge::Fixed(l) = self.ridge
            && !(l >= 0.0 && l.is_finite())
        {
            return Err(ThermalError::Option("ridge must be a finite number >= 0"));
        }
        Ok(self)
    }
}

/// Why a thermal fit failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ThermalError {
    #[error("invalid option: {0}")]
    Option(&'static str),
    #[error("column `{column}` has {got} rows, expected {want}")]
    Length {
        column: String,
        got: usize,
        want: usize,
    },
    #[error("column `{column}`, data row {row}: value is not finite")]
    NonFinite { column: String, row: usize },
    #[error("no usable temperature sensor (`*_degC` column that varies on the training rows)")]
    NoSensors,
    #[error("too few training rows ({0}); need at least 10")]
    TooFewRows(usize),
    #[error("the holdout selects no rows")]
    EmptyHoldout,
    #[error("least squares failed: {0}")]
    Ls(#[from] crate::linalg::LsError),
}

pub use axcomp_effects::thermal_model::{ForceTerm, SensorTerm, Series, ThermalModel};

/// Report of one selection method.
#[derive(Debug, Clone, Serialize)]
pub struct MethodReport {
    pub method: String,
    /// Sensors chosen on all training rows.
    pub sensors: Vec<String>,
    pub tau_s: Vec<f64>,
    /// Inner CV RMS of the final choice (optimistic: the choice saw these folds).
    pub inner_cv_rms_um: f64,
    /// Transfer-validation RMS (the method re-run without each predicted block): the figure the candidates
    /// are compared by (`null` when not run).
    pub nested_cv_rms_um: f64,
    /// False when a forced selection (`--select`) did not run this method.
    pub ran: bool,
}

/// One candidate of the default model choice and its transfer-validation score.
#[derive(Debug, Clone, Serialize)]
pub struct CandidateReport {
    /// `plain_ls`, `all_lags`, `ridge`, `elastic_net`, `forward_lags` / `forward`, `fcm_gra`.
    pub name: String,
    pub what: String,
    /// Structure chosen on all training rows.
    pub sensors: Vec<String>,
    pub tau_s: Vec<f64>,
    pub penalty: String,
    /// RMS over the predicted blocks, each predicted by the candidate chosen and fitted without it.
    pub validation_rms_um: f64,
    /// Per predicted block (same order as `validation.predicted_blocks`).
    pub validation_block_rms_um: Vec<f64>,
    /// The candidate as fitted on all training rows, on the held-out rows (reported, never used to choose).
    pub holdout_rms_um: Option<f64>,
    /// False for the sensor-dropping candidates when the training rows hold a single regime.
    pub eligible: bool,
    /// Lower mean squared error than the reference (the first candidate, plain least squares) by more than
    /// one standard error of the per-block paired difference.
    pub beats_reference: bool,
    pub chosen: bool,
}

/// How the candidates were judged.
#[derive(Debug, Clone, Serialize)]
pub struct ValidationReport {
    /// `leave one block out` (`none` for a forced selection).
    pub scheme: String,
    /// The rule that cut the training rows into blocks.
    pub rule: String,
    pub blocks: Vec<String>,
    /// The blocks the scores are computed on.
    pub predicted_blocks: Vec<String>,
    /// RMS of the raw (zeroed) target over the predicted blocks.
    pub raw_rms_um: f64,
}

/// With one episode of change in the training rows (a step, a single rise), a sensor's lag is tried only up
/// to this fraction of that episode's duration: a longer lag of it is, on these rows, only a function of the
/// time since the start.
pub const LAG_CAP_FRACTION: f64 = 1.0 / 3.0;

/// Elastic-net mixing α (0.5: half LASSO, half ridge).
pub const ENET_ALPHA: f64 = 0.5;

/// A candidate procedure of the default model choice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    PlainLs,
    AllLags,
    Ridge,
    ElasticNet,
    Forward,
    FcmGra,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::PlainLs => "plain_ls",
            Kind::AllLags => "all_lags",
            Kind::Ridge => "ridge",
            Kind::ElasticNet => "elastic_net",
            Kind::Forward => "forward_lags",
            Kind::FcmGra => "fcm_gra",
        }
    }
    /// The `chosen_method` value (kept from the earlier contract: `all`, `forward_cv`, `fcm_gra`).
    fn method_name(self) -> &'static str {
        match self {
            Kind::PlainLs | Kind::AllLags => "all",
            Kind::Ridge => "ridge",
            Kind::ElasticNet => "elastic_net",
            Kind::Forward => "forward_cv",
            Kind::FcmGra => "fcm_gra",
        }
    }
    fn what(self) -> &'static str {
        match self {
            Kind::PlainLs => "every sensor, no lag, least squares",
            Kind::AllLags => {
                "every sensor, one first-order lag per sensor (grid, inner CV), least squares"
            }
            Kind::Ridge => "every sensor with its lag, ridge penalty chosen by inner CV",
            Kind::ElasticNet => {
                "every sensor with its lag, elastic net (α = 0.5), λ chosen by inner CV"
            }
            Kind::Forward => "greedy forward selection of sensors and lags by inner CV",
            Kind::FcmGra => {
                "fuzzy c-means + grey relational analysis (reference method), lags by inner CV"
            }
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Shrink {
    None,
    Ridge(f64),
    ElasticNet(f64),
}

impl Shrink {
    fn describe(self) -> String {
        match self {
            Shrink::None => "none".into(),
            Shrink::Ridge(l) => format!("ridge λ = {l:e}"),
            Shrink::ElasticNet(l) => format!("elastic net α = {ENET_ALPHA}, λ = {l:.4e}"),
        }
    }
}

#[derive(Debug, Clone)]
struct Structure {
    terms: Vec<usize>,
    shrink: Shrink,
}

impl Structure {
    fn ls(terms: Vec<usize>) -> Self {
        Structure {
            terms,
            shrink: Shrink::None,
        }
    }
}

/// Everything a thermal fit reports (serialized into the `--json` file).
#[derive(Debug, Clone, Serialize)]
pub struct ThermalFit {
    /// Selected sensor names.
    pub sensors: Vec<String>,
    /// RMS of the target minus its reference value (`raw_reference_um`) on the held-out rows (all rows
    /// without a holdout), before the model.
    pub raw_rms_um: f64,
    /// RMS of the residual on the held-out rows.
    pub holdout_rms_um: Option<f64>,
    /// Leave-one-condition-out RMS on the training rows (structure fixed, coefficients refit per fold).
    pub cv_rms_um: Option<f64>,
    pub train_raw_rms_um: f64,
    pub train_rms_um: f64,
    pub model: ThermalModel,
    pub formula: String,
    pub chosen_method: String,
    pub why: String,
    pub fcm_gra: MethodReport,
    pub forward: MethodReport,
    /// No selection (every usable sensor); `None` with more than 16 usable sensors.
    pub all_sensors: Option<MethodReport>,
    /// FCM + GRA details (`null` when a forced selection did not run it).
    pub fcm_gra_detail: Option<select::FcmGra>,
    /// The target's reference value (µm): raw figures are the target minus it.
    pub raw_reference_um: f64,
    /// The default's candidates with their transfer-validation scores (empty for a forced selection).
    pub candidates: Vec<CandidateReport>,
    pub validation: ValidationReport,
    /// Forward selection path: (term added, inner CV RMS after it).
    pub forward_path: Vec<(String, f64)>,
    pub condition_number: f64,
    /// VIF per selected sensor term (same order as `model.terms`).
    pub vif: Vec<(String, f64)>,
    pub ridge_lambda: f64,
    pub lags: bool,
    pub lag_grid_s: Vec<f64>,
    /// Per usable sensor: whether the training rows support a lag for it (two or more separate episodes of
    /// change; otherwise only τ = 0 is tried).
    pub lag_supported: Vec<(String, bool)>,
    /// Per usable sensor (same order): the longest lag tried (s); `null` (infinite) with two or more
    /// episodes of change.
    pub lag_cap_s: Vec<f64>,
    /// How the inner CV grouped the training rows.
    pub inner_groups: String,
    pub per_condition: Vec<ConditionResidual>,
    pub excluded_sensors: Vec<(String, String)>,
    pub training_rows: usize,
    pub holdout_rows: usize,
    pub guard: Guard,
    /// Predictions per row (not serialized; for plots).
    #[serde(skip)]
    pub prediction: Vec<f64>,
}

/// RMS per operating condition (or per train/held-out part).
#[derive(Debug, Clone, Serialize)]
pub struct ConditionResidual {
    pub condition: String,
    pub rows: usize,
    pub held_out: bool,
    pub raw_rms_um: f64,
    pub rms_um: f64,
}

/// Outcome of the do-no-harm check.
#[derive(Debug, Clone, Serialize)]
pub struct Guard {
    pub passed: bool,
    /// What was compared.
    pub basis: String,
    pub reason: String,
}

fn check(input: &ThermalInput) -> Result<(), ThermalError> {
    let n = input.time_s.len();
    let mut cols: Vec<(&str, &[f64])> = vec![("time_s", &input.time_s), ("target", &input.target)];
    for s in input.sensors.iter().chain(&input.forces) {
        cols.push((&s.name, &s.values));
    }
    for (name, v) in cols {
        if v.len() != n {
            return Err(ThermalError::Length {
                column: name.into(),
                got: v.len(),
                want: n,
            });
        }
        if let Some(row) = v.iter().position(|x| !x.is_finite()) {
            return Err(ThermalError::NonFinite {
                column: name.into(),
                row: row + 1,
            });
        }
    }
    for (what, len) in [
        ("conditions", input.conditions.as_ref().map(|c| c.len())),
        ("holdout", input.holdout.as_ref().map(|c| c.len())),
    ] {
        if let Some(l) = len
            && l != n
        {
            return Err(ThermalError::Length {
                column: what.into(),
                got: l,
                want: n,
            });
        }
    }
    Ok(())
}

/// Fits a thermo-force model (see the module docs for the procedure).
pub fn fit_thermal(
    input: &ThermalInput,
    opts: &ThermalOptions,
) -> Result<ThermalFit, ThermalError> {
    let opts = opts.build()?;
    check(input)?;
    let n = input.time_s.len();
    let held: Vec<bool> = input.holdout.clone().unwrap_or_else(|| vec![false; n]);
    if input.holdout.is_some() && !held.iter().any(|h| *h) {
        return Err(ThermalError::EmptyHoldout);
    }
    let train_idx: Vec<usize> = (0..n).filter(|&i| !held[i]).collect();
    if train_idx.len() < 10 {
        return Err(ThermalError::TooFewRows(train_idx.len()));
    }

    // ---- usable sensors ----
    let mut excluded = vec![];
    let mut sens: Vec<usize> = vec![];
    for (i, s) in input.sensors.iter().enumerate() {
        let v: Vec<f64> = train_idx.iter().map(|&r| s.values[r]).collect();
        let sd = crate::stats::std_dev(&v);
        if sd <= 1e-9 {
            excluded.push((s.name.clone(), "constant on the training rows".to_string()));
        } else {
            sens.push(i);
        }
    }
    if sens.is_empty() {
        return Err(ThermalError::NoSensors);
    }
    let sname = |k: usize| input.sensors[sens[k]].name.clone();
    let reference: Vec<f64> = sens.iter().map(|&i| input.sensors[i].values[0]).collect();

    // ---- target reference: the raw figures are the target minus it (the state where every ΔT = 0) ----
    let k0 = opts.reference_rows.clamp(1, n);
    let target_ref = input.target[..k0].iter().sum::<f64>() / k0 as f64;
    let zeroed: Vec<f64> = input.target.iter().map(|v| v - target_ref).collect();

    // ---- validation blocks (inner CV groups and the transfer validation) ----
    let sens_cols: Vec<&[f64]> = sens
        .iter()
        .map(|&i| input.sensors[i].values.as_slice())
        .collect();
    let blocks = crate::blocks::transfer_blocks(
        &input.time_s,
        &sens_cols,
        input.conditions.as_deref(),
        &train_idx,
        opts.time_blocks,
    );
    let group_of_row = blocks.group_of_row.clone();
    let cond_groups_ok = blocks.by_condition;
    let inner_groups = blocks.rule.clone();
    let n_groups = blocks.names.len();
    let all_groups: Vec<usize> = (0..n_groups).collect();

    // ---- lag grid and candidate columns ----
    let t_train: Vec<f64> = train_idx.iter().map(|&i| input.time_s[i]).collect();
    let duration = t_train.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - t_train.iter().cloned().fold(f64::INFINITY, f64::min);
    let mut dts: Vec<f64> = input
        .time_s
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    let med_dt = axcomp_numeric::stats::upper_median(&mut dts);
    let mut grid = vec![0.0];
    if opts.lags && duration > 0.0 && med_dt.is_finite() {
        let lo = (2.0 * med_dt).max(duration / 300.0);
        let hi = (duration / 2.0).max(lo * 2.0);
        let m = opts.lag_grid.max(2);
        for k in 0..m {
            grid.push(lo * (hi / lo).powf(k as f64 / (m - 1) as f64));
        }
    }
    let mut cands: Vec<Candidate> = vec![];
    let mut cols: Vec<Vec<f64>> = vec![];
    // A lag per sensor only where the training rows support one (see `blocks::lag_supported`).
    let lag_cap: Vec<f64> = sens
        .iter()
        .map(|&si| {
            let v: Vec<f64> = train_idx
                .iter()
                .map(|&i| input.sensors[si].values[i])
                .collect();
            let (episodes, longest_s) = crate::blocks::lag_support(&t_train, &v);
            if episodes >= 2 {
                f64::INFINITY
            } else {
                LAG_CAP_FRACTION * longest_s
            }
        })
        .collect();
    let lag_ok: Vec<bool> = lag_cap
        .iter()
        .map(|c| *c >= grid.get(1).copied().unwrap_or(f64::INFINITY))
        .collect();
    for (k, &si) in sens.iter().enumerate() {
        for &tau in &grid {
            if tau > lag_cap[k] {
                continue;
            }
            let l = lag(&input.time_s, &input.sensors[si].values, tau);
            cols.push(l.iter().map(|v| v - reference[k]).collect());
            cands.push(Candidate::Sensor {
                sensor: k,
                tau_s: tau,
            });
        }
    }
    let forced: Vec<usize> = (0..input.forces.len())
        .map(|f| {
            cols.push(input.forces[f].values.clone());
            cands.push(Candidate::Force { force: f });
            cands.len() - 1
        })
        .collect();
    let col_refs: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
    let gs = GramSet::new(&col_refs, &input.target, &group_of_row, n_groups);
    drop(cols);
    let cand_of = |sensor: usize, tau: f64| {
        cands
            .iter()
            .position(|c| *c == Candidate::Sensor { sensor, tau_s: tau })
            .unwrap()
    };
    let max_sensors = opts.max_sensors.min(sens.len());
    let all_allowed = sens.len() <= axcomp_core::MAX_SENSORS;

    // ---- the candidate procedures: each makes all its own choices on the groups it is given ----
    let plain_terms = || -> Vec<usize> {
        let mut t = forced.clone();
        t.extend((0..sens.len()).map(|s| cand_of(s, 0.0)));
        t
    };
    let all_lags = |groups: &[usize]| -> Vec<usize> {
        let mut t = plain_terms();
        if opts.lags {
            let cur = gs.cv_rms(&t, groups, 0.0);
            select::improve_lags(&gs, &cands, &mut t, groups, cur);
        }
        t
    };
    let run_fcm = |groups: &[usize]| -> (select::FcmGra, Vec<usize>) {
        let rows: Vec<usize> = train_idx
            .iter()
            .cloned()
            .filter(|&i| group_of_row[i].is_some_and(|g| groups.contains(&g)))
            .collect();
        let series: Vec<Vec<f64>> = sens
            .iter()
            .map(|&si| rows.iter().map(|&r| input.sensors[si].values[r]).collect())
            .collect();
        let target: Vec<f64> = rows.iter().map(|&r| input.target[r]).collect();
        let fg = select::fcm_gra(&series, &target, 6.min(max_sensors.max(2)));
        let mut terms: Vec<usize> = forced.clone();
        terms.extend(fg.selected.iter().map(|&s| cand_of(s, 0.0)));
        if opts.lags {
            let cur = gs.cv_rms(&terms, groups, 0.0);
            select::improve_lags(&gs, &cands, &mut terms, groups, cur);
        }
        (fg, terms)
    };
    let run_forward =
        |groups: &[usize]| select::forward(&gs, &cands, &forced, groups, max_sensors, 0.01);
    let ridge_grid: Vec<f64> = (-6..=1).map(|e| 10f64.powi(e)).collect();
    let choose_ridge = |terms: &[usize], groups: &[usize]| -> f64 {
        let mut best = (ridge_grid[0], f64::INFINITY);
        for &l in &ridge_grid {
            let r = gs.cv_rms(terms, groups, l);
            if r < best.1 {
                best = (l, r);
            }
        }
        best.0
    };
    let choose_enet = |terms: &[usize], groups: &[usize]| -> f64 {
        let lmax = gs.enet_lambda_max(terms, groups, ENET_ALPHA);
        let mut best = (lmax * 1e-4, f64::INFINITY);
        for k in 1..=16 {
            let l = lmax * 10f64.powf(-(k as f64) / 4.0);
            let r = gs.cv_rms_enet(terms, groups, l, ENET_ALPHA);
            if r < best.1 {
                best = (l, r);
            }
        }
        best.0
    };
    // One candidate's structure chosen on `groups`; `lagged` caches the all-sensors-with-lags terms.
    let structure = |kind: Kind, groups: &[usize], lagged: &mut Option<Vec<usize>>| -> Structure {
        let mut base = || lagged.get_or_insert_with(|| all_lags(groups)).clone();
        match kind {
            Kind::PlainLs => Structure::ls(plain_terms()),
            Kind::AllLags => Structure::ls(base()),
            Kind::Forward => Structure::ls(run_forward(groups).terms),
            Kind::FcmGra => Structure::ls(run_fcm(groups).1),
            Kind::Ridge => {
                let t = base();
                let l = choose_ridge(&t, groups);
                Structure {
                    terms: t,
                    shrink: Shrink::Ridge(l),
                }
            }
            Kind::ElasticNet => {
                let t = base();
                let l = choose_enet(&t, groups);
                Structure {
                    terms: t,
                    shrink: Shrink::ElasticNet(l),
                }
            }
        }
    };
    let sse_of = |s: &Structure, fit_groups: &[usize], g: usize| -> f64 {
        let beta = match s.shrink {
            Shrink::None => gs.fit(&s.terms, fit_groups, 0.0),
            Shrink::Ridge(l) => gs.fit(&s.terms, fit_groups, l),
            Shrink::ElasticNet(l) => gs.fit_enet(&s.terms, fit_groups, l, ENET_ALPHA),
        };
        beta.map_or(f64::INFINITY, |b| gs.sse(&s.terms, &b, g))
    };

    // ---- which candidates ----
    let requested = opts.selection != Selection::Auto;
    let kinds: Vec<Kind> = match opts.selection {
        Selection::Auto => {
            let mut k = vec![];
            if all_allowed {
                k.push(Kind::PlainLs);
                if opts.lags {
                    k.push(Kind::AllLags);
                }
                if opts.ridge == Ridge::Auto {
                    k.push(Kind::Ridge);
                    k.push(Kind::ElasticNet);
                }
            }
            k.push(Kind::Forward);
            k.push(Kind::FcmGra);
            k
        }
        Selection::All if opts.lags => vec![Kind::AllLags],
        Selection::All => vec![Kind::PlainLs],
        Selection::Forward => vec![Kind::Forward],
        Selection::FcmGra => vec![Kind::FcmGra],
    };
    if requested && opts.selection == Selection::All && !all_allowed {
        return Err(ThermalError::Option(
            "--select all: more usable sensors than the firmware takes (16)",
        ));
    }

    // ---- transfer validation: each block predicted by candidates chosen and fitted without it ----
    // Leave one block out: every block (a condition, or a heating / cooling run, or a part of one) is
    // predicted by each candidate chosen and fitted on the other blocks only.
    let folds: Vec<(Vec<usize>, usize)> = if requested {
        vec![]
    } else {
        all_groups
            .iter()
            .map(|&g| (all_groups.iter().cloned().filter(|&h| h != g).collect(), g))
            .collect()
    };
    let mut block_sse = vec![vec![0.0; folds.len()]; kinds.len()];
    for (fi, (fit_groups, g)) in folds.iter().enumerate() {
        let mut lagged = None;
        for (ki, &kind) in kinds.iter().enumerate() {
            let s = structure(kind, fit_groups, &mut lagged);
            block_sse[ki][fi] = sse_of(&s, fit_groups, *g);
        }
    }
    let zeroed_sq = |g: usize| -> f64 {
        train_idx
            .iter()
            .filter(|&&i| group_of_row[i] == Some(g))
            .map(|&i| zeroed[i] * zeroed[i])
            .sum()
    };
    let val_rows: usize = folds.iter().map(|(_, g)| gs.rows[*g]).sum();
    let val_raw = if folds.is_empty() {
        f64::NAN
    } else {
        (folds.iter().map(|(_, g)| zeroed_sq(*g)).sum::<f64>() / val_rows as f64).sqrt()
    };
    let val_score: Vec<f64> = block_sse
        .iter()
        .map(|v| {
            if folds.is_empty() {
                f64::NAN
            } else {
                (v.iter().sum::<f64>() / val_rows as f64).sqrt()
            }
        })
        .collect();

    // ---- every candidate's structure on all training rows ----
    let mut lagged_all = None;
    let finals: Vec<Structure> = kinds
        .iter()
        .map(|&k| structure(k, &all_groups, &mut lagged_all))
        .collect();
    let fg_detail = kinds
        .contains(&Kind::FcmGra)
        .then(|| run_fcm(&all_groups).0);
    let fwd_final = kinds
        .contains(&Kind::Forward)
        .then(|| run_forward(&all_groups));
    let describe = |terms: &[usize]| -> (Vec<String>, Vec<f64>) {
        terms
            .iter()
            .filter_map(|&t| match cands[t] {
                Candidate::Sensor { sensor, tau_s } => Some((sname(sensor), tau_s)),
                _ => None,
            })
            .unzip()
    };
    // Held-out RMS of each candidate as fitted on all training rows (reported, never used to choose).
    let held_idx: Vec<usize> = (0..n).filter(|&i| held[i]).collect();
    let cand_holdout = |s: &Structure| -> Option<f64> {
        if held_idx.is_empty() {
            return None;
        }
        let beta = match s.shrink {
            Shrink::None => gs.fit(&s.terms, &all_groups, 0.0),
            Shrink::Ridge(l) => gs.fit(&s.terms, &all_groups, l),
            Shrink::ElasticNet(l) => gs.fit_enet(&s.terms, &all_groups, l, ENET_ALPHA),
        }?;
        let mut pred = vec![gs.y_mean + beta[0]; n];
        for (j, &t) in s.terms.iter().enumerate() {
            let (m, sd) = gs.col_stats[t];
            let col: Vec<f64> = match cands[t] {
                Candidate::Sensor { sensor, tau_s } => {
                    lag(&input.time_s, &input.sensors[sens[sensor]].values, tau_s)
                        .into_iter()
                        .map(|v| v - reference[sensor])
                        .collect()
                }
                Candidate::Force { force } => input.forces[force].values.clone(),
            };
            for &i in &held_idx {
                pred[i] += beta[j + 1] * (col[i] - m) / sd;
            }
        }
        let sse: f64 = held_idx
            .iter()
            .map(|&i| (input.target[i] - pred[i]).powi(2))
            .sum();
        Some((sse / held_idx.len() as f64).sqrt())
    };
    let mut candidates: Vec<CandidateReport> = kinds
        .iter()
        .zip(&finals)
        .enumerate()
        .map(|(ki, (&kind, s))| {
            let (ss, ts) = describe(&s.terms);
            CandidateReport {
                name: kind.name().into(),
                what: kind.what().into(),
                sensors: ss,
                tau_s: ts,
                penalty: s.shrink.describe(),
                validation_rms_um: val_score[ki],
                validation_block_rms_um: folds
                    .iter()
                    .enumerate()
                    .map(|(fi, (_, g))| (block_sse[ki][fi] / gs.rows[*g].max(1) as f64).sqrt())
                    .collect(),
                holdout_rms_um: cand_holdout(s),
                eligible: true,
                beats_reference: false,
                chosen: false,
            }
        })
        .collect();
    // ---- the choice ----
    // Eligibility: with a single regime among the training rows the validation cannot judge how a candidate
    // transfers to another regime; the default then stays with the reference structure (every sensor, least
    // squares, lags where the data support them) and the other candidates are reported only.
    let single_regime = blocks.regimes < 2;
    let eligible: Vec<bool> = kinds
        .iter()
        .map(|k| !single_regime || matches!(k, Kind::PlainLs | Kind::AllLags))
        .collect();
    // One-standard-error rule against the reference (plain least squares, the first candidate): another
    // candidate is chosen only if its mean squared error over the predicted blocks is lower by more than one
    // standard error of the per-block paired difference; then the lowest validation RMS among those wins.
    let beats_reference = |k: usize| -> bool {
        if k == 0 || folds.is_empty() {
            return k == 0;
        }
        let d: Vec<f64> = folds
            .iter()
            .enumerate()
            .map(|(fi, (_, g))| (block_sse[k][fi] - block_sse[0][fi]) / gs.rows[*g].max(1) as f64)
            .collect();
        let b = d.len() as f64;
        let mean = d.iter().sum::<f64>() / b;
        let sd = if d.len() > 1 {
            (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (b - 1.0)).sqrt()
        } else {
            f64::INFINITY
        };
        val_score[k] < val_score[0] && mean + sd / b.sqrt() < 0.0
    };
    let chosen_idx = if requested {
        0
    } else {
        let mut best = 0;
        for k in 1..kinds.len() {
            if eligible[k] && beats_reference(k) && val_score[k] < val_score[best] {
                best = k;
            }
        }
        best
    };
    for (k, c) in candidates.iter_mut().enumerate() {
        c.eligible = eligible[k];
        c.beats_reference = beats_reference(k) && k != 0;
    }
    candidates[chosen_idx].chosen = true;
    if requested {
        // A forced selection compares nothing: no candidate table.
        candidates.clear();
    }
    let chosen_kind = kinds[chosen_idx];
    let chosen = finals[chosen_idx].clone();
    let table = candidates
        .iter()
        .map(|c| format!("{} {:.4} µm", c.name, c.validation_rms_um))
        .collect::<Vec<_>>()
        .join(", ");
    let why = if requested {
        format!(
            "requested {} (a forced selection: no comparison of candidates was run)",
            chosen_kind.name()
        )
    } else {
        format!(
            "leave-one-block-out validation ({}; raw {val_raw:.4} µm): {table} → {}",
            inner_groups,
            chosen_kind.name()
        )
    };
    let method_report = |kind: Kind, method: &str| -> MethodReport {
        match kinds.iter().position(|&k| k == kind) {
            Some(k) => {
                let (sensors, tau_s) = describe(&finals[k].terms);
                MethodReport {
                    method: method.into(),
                    sensors,
                    tau_s,
                    inner_cv_rms_um: gs.cv_rms(&finals[k].terms, &all_groups, 0.0),
                    nested_cv_rms_um: val_score[k],
                    ran: true,
                }
            }
            None => MethodReport {
                method: method.into(),
                sensors: vec![],
                tau_s: vec![],
                inner_cv_rms_um: f64::NAN,
                nested_cv_rms_um: f64::NAN,
                ran: false,
            },
        }
    };
    let rep_a = method_report(Kind::FcmGra, "fcm_gra");
    let rep_b = method_report(Kind::Forward, "forward_cv");
    let rep_c = all_allowed.then(|| {
        if kinds.contains(&Kind::AllLags) {
            method_report(Kind::AllLags, "all")
        } else {
            method_report(Kind::PlainLs, "all")
        }
    });
    let forward_path = fwd_final
        .as_ref()
        .map(|fb| {
            fb.steps
                .iter()
                .map(|s| match cands[s.candidate] {
                    Candidate::Sensor { sensor, tau_s } => {
                        (format!("{} (τ={:.0} s)", sname(sensor), tau_s), s.cv_rms)
                    }
                    Candidate::Force { force } => (input.forces[force].name.clone(), s.cv_rms),
                })
                .collect()
        })
        .unwrap_or_default();
    let chosen_method = chosen_kind.method_name();
    let terms = chosen.terms.clone();

    // ---- chosen structure: sensors + τ, refined ----
    let mut sel: Vec<(usize, f64)> = terms
        .iter()
        .filter_map(|&t| match cands[t] {
            Candidate::Sensor { sensor, tau_s } => Some((sensor, tau_s)),
            _ => None,
        })
        .collect();
    let column = |sensor: usize, tau: f64| -> Vec<f64> {
        lag(&input.time_s, &input.sensors[sens[sensor]].values, tau)
            .into_iter()
            .map(|v| v - reference[sensor])
            .collect()
    };
    let small_cv = |sel: &[(usize, f64)], lambda: f64| -> f64 {
        let mut cs: Vec<Vec<f64>> = sel.iter().map(|&(s, t)| column(s, t)).collect();
        for f in &input.forces {
            cs.push(f.values.clone());
        }
        let refs: Vec<&[f64]> = cs.iter().map(|c| c.as_slice()).collect();
        let g = GramSet::new(&refs, &input.target, &group_of_row, n_groups);
        let all: Vec<usize> = (0..cs.len()).collect();
        g.cv_rms(&all, &all_groups, lambda)
    };
    let refine_lambda = match chosen.shrink {
        Shrink::Ridge(l) => Some(l),
        Shrink::None => Some(0.0),
        Shrink::ElasticNet(_) => None,
    };
    if let (true, Some(rl)) = (opts.lags, refine_lambda) {
        // Golden-section search on log τ between the grid neighbours of each selected τ (> 0), objective the
        // inner CV RMS; two coordinate sweeps (one sweep of 12 steps with more than 6 terms).
        let brackets: Vec<Option<(f64, f64)>> = sel
            .iter()
            .map(|&(_, tau)| {
                let pos = grid.iter().position(|g| *g == tau)?;
                if tau <= 0.0 {
                    return None;
                }
                let lo = if pos >= 2 { grid[pos - 1] } else { tau / 2.0 };
                let hi = if pos + 1 < grid.len() {
                    grid[pos + 1]
                } else {
                    tau * 2.0
                };
                Some((lo, hi))
            })
            .collect();
        // Many terms: fewer changes and steps keep the fit fast. Each round searches every τ given the
        // others and keeps the one change that helps most, so the result does not depend on the order of
        // the sensor columns in the file (a sweep in file order did: up to 4× the held-out RMS on the
        // Voron cooling phase with the sensor columns reversed).
        let (sweeps, steps) = if sel.len() > 6 { (1, 12) } else { (2, 20) };
        let mut cur = small_cv(&sel, rl);
        for _ in 0..sweeps * sel.len() {
            let mut best: Option<(usize, f64, f64)> = None;
            for j in 0..sel.len() {
                let Some((lo, hi)) = brackets[j] else {
                    continue;
                };
                let mut f = |lt: f64| {
                    let mut s2 = sel.clone();
                    s2[j].1 = lt.exp();
                    small_cv(&s2, rl)
                };
                let t = golden_min(&mut f, lo.ln(), hi.ln(), steps);
                let r = f(t);
                if r < best.map_or(cur, |b| b.2) {
                    best = Some((j, t.exp(), r));
                }
            }
            match best {
                Some((j, tau, r)) => {
                    sel[j].1 = tau;
                    cur = r;
                }
                None => break,
            }
        }
    }

    // ---- ridge: the chosen candidate's own penalty; a forced selection takes --ridge as before ----
    let lambda = match (chosen.shrink, opts.ridge) {
        (Shrink::Ridge(l), _) => l,
        (Shrink::ElasticNet(_), _) => 0.0,
        (Shrink::None, Ridge::Off) => 0.0,
        (Shrink::None, Ridge::Fixed(l)) => l,
        (Shrink::None, Ridge::Auto) if !requested => 0.0,
        (Shrink::None, Ridge::Auto) => {
            let mut best = (0.0, small_cv(&sel, 0.0));
            for e in -6..=1 {
                let l = 10f64.powi(e);
                let r = small_cv(&sel, l);
                if r < best.1 {
                    best = (l, r);
                }
            }
            best.0
        }
    };

    // ---- final coefficients by QR on the training rows ----
    let full_cols: Vec<Vec<f64>> = sel
        .iter()
        .map(|&(s, t)| column(s, t))
        .chain(input.forces.iter().map(|f| f.values.clone()))
        .collect();
    let p = full_cols.len() + 1;
    let x = DMatrix::from_fn(train_idx.len(), p, |r, c| {
        if c == 0 {
            1.0
        } else {
            full_cols[c - 1][train_idx[r]]
        }
    });
    let y_train: Vec<f64> = train_idx.iter().map(|&i| input.target[i]).collect();
    let mut ls = lstsq(&x, &y_train, lambda, Some(0))?;
    if let Shrink::ElasticNet(l) = chosen.shrink {
        // Elastic-net coefficients on the same columns (standardized over the training rows).
        let refs: Vec<&[f64]> = full_cols.iter().map(|c| c.as_slice()).collect();
        let g = GramSet::new(&refs, &input.target, &group_of_row, n_groups);
        let all: Vec<usize> = (0..full_cols.len()).collect();
        if let Some(beta) = g.fit_enet(&all, &all_groups, l, ENET_ALPHA) {
            let mut b0 = g.y_mean + beta[0];
            for j in 0..full_cols.len() {
                let (m, sd) = g.col_stats[j];
                ls.coef[j + 1] = beta[j + 1] / sd;
                b0 -= beta[j + 1] * m / sd;
            }
            ls.coef[0] = b0;
        }
    }
    let cond = condition_number(&x);
    let vifs = vif(&(0..sel.len())
        .map(|j| {
            train_idx
                .iter()
                .map(|&i| full_cols[j][i])
                .collect::<Vec<f64>>()
        })
        .collect::<Vec<_>>());
    let vif_named: Vec<(String, f64)> = sel
        .iter()
        .enumerate()
        .filter(|(j, _)| ls.coef[j + 1] != 0.0)
        .map(|(j, &(s, _))| (sname(s), vifs[j]))
        .collect();
    let model = ThermalModel {
        b0_um: ls.coef[0],
        terms: sel
            .iter()
            .enumerate()
            .map(|(j, &(s, t))| SensorTerm {
                sensor: sname(s),
                reference_degc: reference[s],
                tau_s: t,
                coef_um_per_k: ls.coef[j + 1],
            })
            // The elastic net can set a term exactly to 0: the firmware need not read that sensor.
            .filter(|t| t.coef_um_per_k != 0.0)
            .collect(),
        forces: input
            .forces
            .iter()
            .enumerate()
            .map(|(f, s)| ForceTerm {
                column: s.name.clone(),
                chi_um_per_n: ls.coef[sel.len() + 1 + f],
            })
            .collect(),
    };
    let prediction = model
        .predict(&input.time_s, &input.sensors, &input.forces)
        .expect("model built from these columns");
    let resid: Vec<f64> = input
        .target
        .iter()
        .zip(&prediction)
        .map(|(y, p)| y - p)
        .collect();
    let pick = |v: &[f64], want_held: bool| -> Vec<f64> {
        (0..n)
            .filter(|&i| held[i] == want_held)
            .map(|i| v[i])
            .collect()
    };
    // Raw figures: the target minus its reference value (see `raw_reference_um`), one definition everywhere.
    let train_raw = rms(&pick(&zeroed, false));
    let train_rms = rms(&pick(&resid, false));
    let (raw_rms, holdout_rms) = if input.holdout.is_some() {
        (rms(&pick(&zeroed, true)), Some(rms(&pick(&resid, true))))
    } else {
        (rms(&zeroed), None)
    };
    let cv_rms = if cond_groups_ok {
        Some(small_cv(&sel, lambda))
    } else {
        None
    };

    // ---- per condition ----
    let mut per_condition = vec![];
    match &input.conditions {
        Some(c) => {
            let mut labels: Vec<&String> = vec![];
            for l in c {
                if !labels.contains(&l) {
                    labels.push(l);
                }
            }
            for l in labels {
                let rows: Vec<usize> = (0..n).filter(|&i| &c[i] == l).collect();
                per_condition.push(ConditionResidual {
                    condition: l.clone(),
                    rows: rows.len(),
                    held_out: rows.iter().all(|&i| held[i]),
                    raw_rms_um: rms(&rows.iter().map(|&i| zeroed[i]).collect::<Vec<_>>()),
                    rms_um: rms(&rows.iter().map(|&i| resid[i]).collect::<Vec<_>>()),
                });
            }
        }
        None => {
            for (name, h) in [("training rows", false), ("held-out rows", true)] {
                let r = pick(&resid, h);
                if r.is_empty() {
                    continue;
                }
                per_condition.push(ConditionResidual {
                    condition: name.into(),
                    rows: r.len(),
                    held_out: h,
                    raw_rms_um: rms(&pick(&zeroed, h)),
                    rms_um: rms(&r),
                });
            }
        }
    }

    // ---- do-no-harm guard ----
    // Rule: with held-out rows, the model's RMS on them must be <= raw (the target minus its reference
    // value) on them. Without held-out rows: the default's leave-one-block-out validation RMS must be <= raw
    // over the same blocks (no candidate beats raw → refused); a forced selection's own leave-one-block-out
    // RMS (structure fixed, coefficients refitted) must be <= raw on the training rows.
    let val_note = if requested || folds.is_empty() {
        String::new()
    } else {
        format!(
            "; leave-one-block-out validation RMS {:.3} µm vs raw {val_raw:.3} µm",
            val_score[chosen_idx]
        )
    };
    let guard = match holdout_rms {
        Some(h) => Guard {
            passed: h <= raw_rms,
            basis: "held-out rows".into(),
            reason: if h <= raw_rms {
                format!("held-out RMS {h:.3} µm <= raw {raw_rms:.3} µm{val_note}")
            } else {
                format!(
                    "held-out RMS {h:.3} µm is worse than raw {raw_rms:.3} µm (no compensation){val_note}"
                )
            },
        },
        None if !requested && !folds.is_empty() => {
            let v = val_score[chosen_idx];
            Guard {
                passed: v <= val_raw,
                basis: format!("leave-one-block-out validation over {inner_groups}"),
                reason: if v <= val_raw {
                    format!("validation RMS {v:.3} µm <= raw {val_raw:.3} µm")
                } else {
                    format!(
                        "no candidate beats raw in the leave-one-block-out validation (best {v:.3} µm, raw \
                         {val_raw:.3} µm)"
                    )
                },
            }
        }
        None => {
            let cvr = cv_rms.unwrap_or_else(|| small_cv(&sel, lambda));
            Guard {
                passed: cvr <= train_raw,
                basis: inner_groups.clone(),
                reason: if cvr <= train_raw {
                    format!("cross-validated RMS {cvr:.3} µm <= raw {train_raw:.3} µm")
                } else {
                    format!("cross-validated RMS {cvr:.3} µm is worse than raw {train_raw:.3} µm")
                },
            }
        }
    };

    Ok(ThermalFit {
        sensors: model.terms.iter().map(|t| t.sensor.clone()).collect(),
        raw_rms_um: raw_rms,
        holdout_rms_um: holdout_rms,
        cv_rms_um: cv_rms,
        train_raw_rms_um: train_raw,
        train_rms_um: train_rms,
        formula: model.formula(),
        vif: vif_named,
        model,
        chosen_method: chosen_method.into(),
        why,
        fcm_gra: rep_a,
        forward: rep_b,
        all_sensors: rep_c,
        fcm_gra_detail: fg_detail,
        raw_reference_um: target_ref,
        candidates,
        validation: ValidationReport {
            scheme: if requested {
                "none (forced selection)".into()
            } else {
                "leave one block out".into()
            },
            blocks: blocks.names.clone(),
            rule: inner_groups.clone(),
            predicted_blocks: folds
                .iter()
                .map(|(_, g)| blocks.names[*g].clone())
                .collect(),
            raw_rms_um: val_raw,
        },
        forward_path,
        condition_number: cond,
        ridge_lambda: lambda,
        lags: opts.lags,
        lag_grid_s: grid,
        lag_cap_s: lag_cap.clone(),
        lag_supported: sens
            .iter()
            .map(|&si| input.sensors[si].name.clone())
            .zip(lag_ok)
            .collect(),
        inner_groups,
        per_condition,
        excluded_sensors: excluded,
        training_rows: train_idx.len(),
        holdout_rows: n - train_idx.len(),
        guard,
        prediction,
    })
}

/// Golden-section minimisation of `f` on `[a, b]`, `iters` steps; returns the abscissa of the minimum.
pub fn golden_min(f: &mut dyn FnMut(f64) -> f64, mut a: f64, mut b: f64, iters: usize) -> f64 {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    if fc < fd { c } else { d }
}
