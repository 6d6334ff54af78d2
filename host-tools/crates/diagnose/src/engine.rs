//! The diagnosis: fit the named model on the training rows, measure the held-out gap, locate it, and rank
//! the unmodelled candidate effects by refitting the whole model with each one added.
//!
//! Glossary: **base model** = intercept + the families of the `--model` kinds; **refit** = least squares
//! of base + candidate columns on the training rows (never a fit to the residual alone); **train test** =
//! nested-model F-test of the refit against the base model, Bonferroni-corrected over every searched
//! variant of every candidate; **σ** = the noise level, the refit's training residual standard deviation
//! (dof-corrected); **gap** = the base model's held-out RMS; **material** = the refit lowers the held-out
//! RMS by at least [`MIN_SHRINK_PCT`] % of the gap *and* by at least [`MIN_NOISE_FRACTION`]·σ, or — for a
//! localised candidate — by at least [`LOCAL_MIN_SHRINK_PCT`] % and [`LOCAL_MIN_NOISE_FRACTION`]·σ on the
//! held-out rows where it acts ([`LocalGain`]);
//! **score** = held-out ΔBIC, `n_ho·ln(RSS_before/RSS_after) − k·ln(n_ho)` with `k` = added columns +
//! searched parameters (reported and used to order, not to decide).
//!
//! **Verdict rule** ([`VERDICT_RULE`]): a candidate *explains* the gap when the train test passes at
//! `alpha` and its held-out improvement is material. Neither criterion of the held-out part depends on how
//! many rows are held out (a held-out p-value does: it is reported, not used to blame). **Ties** between
//! explaining candidates (nested effects such as `thermal_drift` / `thermal_lag`, or `time_drift` / a
//! sensor) are resolved by held-out evidence: the lowest held-out RMS leads, and a simpler candidate (a
//! physical input before the sensor-free `time_drift`, then fewer parameters, then the special case before
//! its generalisation) is preferred unless the leader beats it significantly on the held-out rows (paired
//! t ≥ 2) and either by a margin ([`TIE_GAIN_FRACTION`]) or with positive evidence (held-out ΔBIC ≥
//! [`TIE_EVIDENCE`]); the others within that are reported as ties.
//!
//! Further evidence per candidate (reported, not used for the verdict): the held-out paired test, residual
//! cross-correlation with the candidate's columns, blocked cross-validation by run (or time block) on the
//! training rows, and a block-bootstrap inclusion probability (stability selection over the candidate
//! library).
//!
//! Memory: a family's variants are built one at a time ([`basis::Variant::columns`]) and a refit uses
//! the base columns by reference, so the working set is O(rows·(model columns + candidates)), not
//! O(rows·searched variants).

use serde::Serialize;
use serde_json::{Map, Value};

use crate::EffectKind;
use crate::basis::{self, Context, Family};
use crate::locate::{self, Region};
use crate::lsq::{self, Projector};
use crate::obs::Observations;
use crate::stats;

/// Smallest held-out RMS reduction, in % of the gap (the base model's held-out RMS), that counts as
/// material.
pub const MIN_SHRINK_PCT: f64 = 5.0;
/// Smallest held-out RMS reduction, as a fraction of the noise σ, that counts as material.
pub const MIN_NOISE_FRACTION: f64 = 0.05;
/// Where a candidate acts: the held-out rows on which its fitted contribution reaches this fraction of its
/// held-out peak (chosen from the covariates and the training fit only, never from the held-out target).
pub const LOCAL_SUPPORT_FRACTION: f64 = 0.25;
/// A candidate that acts on at most [`LOCAL_MAX_SHARE`] of the held-out rows (a localised effect such as an
/// end decay) is also material when, on those rows, its refit lowers the held-out RMS by at least
/// [`LOCAL_MIN_SHRINK_PCT`] % and by at least [`LOCAL_MIN_NOISE_FRACTION`]·σ, with at least
/// [`LOCAL_MIN_ROWS`] rows — a few % of the stroke cannot move the RMS of the whole campaign by 5 %.
pub const LOCAL_MAX_SHARE: f64 = 0.5;
pub const LOCAL_MIN_ROWS: usize = 20;
pub const LOCAL_MIN_SHRINK_PCT: f64 = 20.0;
pub const LOCAL_MIN_NOISE_FRACTION: f64 = 0.25;
/// Share of the leader's held-out gain (reduction of the held-out squared residuals) that a simpler
/// candidate must reach to be tied with it (when the leader is also significantly better, paired t ≥ 2).
pub const TIE_GAIN_FRACTION: f64 = 0.9;
/// Held-out ΔBIC by which the leader must beat a simpler candidate whose gain is within
/// [`TIE_GAIN_FRACTION`] of its own (Kass & Raftery 1995: < 2 is "not worth more than a bare mention").
pub const TIE_EVIDENCE: f64 = 2.0;
/// The verdict rule in words (also in the JSON as `verdict_rule`).
pub const VERDICT_RULE: &str = "a candidate explains the gap when (1) the refit of the whole model with it passes the training F-test at alpha, Bonferroni-corrected over every searched variant, and (2) its held-out improvement is material: the held-out RMS falls by at least 5 % of the gap and by at least 0.05 σ (σ: the refit's training residual standard deviation); neither threshold depends on the number of held-out rows. A candidate acting on at most half of the held-out rows (where its fitted contribution reaches 25 % of its peak; at least 20 rows) is also material when, on those rows, the held-out RMS falls by at least 20 % and by at least 0.25 σ (a localised effect such as an end decay cannot move the RMS of the whole campaign by 5 %). Ties between explaining candidates are resolved by held-out evidence: the one with the lowest held-out RMS leads, and a simpler candidate (a physical input before the sensor-free time_drift, then fewer parameters, then thermal_drift before thermal_lag) is preferred unless the leader beats it on the held-out rows significantly (paired t of the squared residuals ≥ 2) and either by a margin (the simpler one removes < 90 % of the held-out squared gap the leader removes) or with positive evidence (held-out ΔBIC ≥ 2); otherwise the two are ties. Shares of `where` are fractions in 0..1.";

/// The verdict rule as `axcomp diagnose --help` prints it.
pub const VERDICT_HELP: &str = "Verdict rule (also in the JSON as `verdict_rule`, with per candidate `material`, `holdout_gain_um`, `noise_um`): a candidate explains the gap when (1) the refit of the whole model with it passes the training F-test at alpha = 0.01, Bonferroni-corrected over every searched variant, and (2) its held-out improvement is material: the held-out RMS falls by at least 5 % of the gap and by at least 0.05 σ (σ: the refit's training residual standard deviation). Neither threshold depends on the number of held-out rows. A candidate acting on at most half of the held-out rows (where its fitted contribution reaches 25 % of its peak; at least 20 rows) is also material when, on those rows, the held-out RMS falls by at least 20 % and by at least 0.25 σ (a localised effect such as an end decay cannot move the RMS of the whole campaign by 5 %). Ties are resolved by held-out evidence: the lowest held-out RMS leads; a simpler candidate (a physical input before the sensor-free time_drift, then fewer parameters, then thermal_drift before thermal_lag) is preferred unless the leader beats it on the held-out rows significantly (paired t ≥ 2) and either by a margin (the simpler one removes < 90 % of the held-out squared gap the leader removes) or with positive evidence (held-out ΔBIC ≥ 2). `where` shares are in 0..100 %.";

/// Whether a held-out RMS reduction `gain_um` is material next to the gap `gap_um` and the noise `sigma_um`.
pub fn is_material(gain_um: f64, gap_um: f64, sigma_um: f64) -> bool {
    gain_um >= MIN_SHRINK_PCT / 100.0 * gap_um && gain_um >= MIN_NOISE_FRACTION * sigma_um
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
    pub fn build(self) -> Result<Self, String> {
        if !(self.alpha > 0.0 && self.alpha < 0.5) {
            return Err(format!("alpha must be in (0, 0.5), got {}", self.alpha));
        }
        if self.pitch_segments_max == 0 {
            return Err("pitch_segments_max must be ≥ 1".into());
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
    pub material: bool,
    /// The held-out gain where the candidate acts (None when it acts on more than [`LOCAL_MAX_SHARE`] of
    /// the held-out rows or on fewer than [`LOCAL_MIN_ROWS`]).
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
    #[serde(skip)]
    pub kind_enum: Option<EffectKind>,
    /// The chosen variant (its columns are rebuilt on demand).
    #[serde(skip)]
    pub variant: Option<basis::Variant>,
    /// The candidate's own fitted contribution over all rows (µm).
    #[serde(skip)]
    pub contribution_um: Vec<f64>,
    /// Residual of the refit over all rows.
    #[serde(skip)]
    pub residual_after: Vec<f64>,
}

/// The held-out gain of a localised candidate on the rows where it acts (see [`LOCAL_SUPPORT_FRACTION`]).
#[derive(Debug, Clone, Serialize)]
pub struct LocalGain {
    /// Held-out rows where the candidate's contribution is ≥ [`LOCAL_SUPPORT_FRACTION`] of its peak.
    pub rows: usize,
    /// The base model's held-out RMS on those rows, µm.
    pub rms_before_um: f64,
    /// The refit's held-out RMS on those rows, µm.
    pub rms_after_um: f64,
    pub shrink_pct: f64,
    /// ≥ [`LOCAL_MIN_SHRINK_PCT`] % and ≥ [`LOCAL_MIN_NOISE_FRACTION`]·σ.
    pub material: bool,
}

/// The held-out gain where a candidate acts, if it is localised (see [`LocalGain`]).
fn local_gain(
    contribution: &[f64],
    base_resid: &[f64],
    refit_resid: &[f64],
    hold: &[usize],
    sigma_um: f64,
) -> Option<LocalGain> {
    let peak = hold
        .iter()
        .map(|&i| contribution[i].abs())
        .fold(0.0, f64::max);
    if !(peak > 0.0) {
        return None;
    }
    let rows: Vec<usize> = hold
        .iter()
        .cloned()
        .filter(|&i| contribution[i].abs() >= LOCAL_SUPPORT_FRACTION * peak)
        .collect();
    if rows.len() < LOCAL_MIN_ROWS || rows.len() as f64 > LOCAL_MAX_SHARE * hold.len() as f64 {
        return None;
    }
    let n = rows.len() as f64;
    let before = (ss(base_resid, &rows) / n).sqrt();
    let after = (ss(refit_resid, &rows) / n).sqrt();
    let shrink = if before > 0.0 {
        100.0 * (1.0 - after / before)
    } else {
        0.0
    };
    Some(LocalGain {
        rows: rows.len(),
        rms_before_um: before,
        rms_after_um: after,
        shrink_pct: shrink,
        material: shrink >= LOCAL_MIN_SHRINK_PCT
            && before - after >= LOCAL_MIN_NOISE_FRACTION * sigma_um,
    })
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

struct Fitted {
    fit: lsq::LsFit,
    resid: Vec<f64>,
}

fn fit_all<C: AsRef<[f64]>>(cols: &[C], y: &[f64], train: &[usize]) -> Fitted {
    let fit = lsq::fit(cols, y, train);
    let resid = (0..y.len()).map(|i| y[i] - fit.predict(cols, i)).collect();
    Fitted { fit, resid }
}

/// Sum of squared residuals on `rows` of a fit on `rows`.
fn rss_on<C: AsRef<[f64]>>(cols: &[C], y: &[f64], rows: &[usize]) -> f64 {
    let fit = lsq::fit(cols, y, rows);
    rows.iter()
        .map(|&i| (y[i] - fit.predict(cols, i)).powi(2))
        .sum()
}

/// The base columns followed by `extra`, by reference (no copy of the data).
fn with_extra<'a>(base: &'a [Vec<f64>], extra: &'a [Vec<f64>]) -> Vec<&'a [f64]> {
    base.iter()
        .chain(extra)
        .map(|c| c.as_slice())
        .collect::<Vec<&[f64]>>()
}

/// Training blocks for blocked CV and the block bootstrap: runs (grouped into at most 10 contiguous
/// blocks in run order), or 5 contiguous time blocks when there is no run column.
fn training_blocks(obs: &Observations, train: &[usize]) -> Vec<Vec<usize>> {
    match &obs.run {
        Some(run) => {
            let mut ids: Vec<usize> = train.iter().map(|&i| run[i]).collect();
            ids.sort_unstable();
            ids.dedup();
            let nb = ids.len().min(10);
            if nb < 2 {
                return vec![train.to_vec()];
            }
            let mut blocks = vec![Vec::new(); nb];
            for &i in train {
                let k = ids.binary_search(&run[i]).unwrap_or(0);
                blocks[k * nb / ids.len()].push(i);
            }
            blocks
        }
        None => {
            let order: Vec<usize> = obs
                .time_order()
                .into_iter()
                .filter(|&i| !obs.held_out[i])
                .collect();
            let nb = 5.min(order.len());
            (0..nb)
                .map(|k| order[k * order.len() / nb..(k + 1) * order.len() / nb].to_vec())
                .collect()
        }
    }
}

/// Sum of squared prediction errors of leave-one-block-out fits.
fn blocked_cv_rss<C: AsRef<[f64]>>(cols: &[C], y: &[f64], blocks: &[Vec<usize>]) -> f64 {
    let mut total = 0.0;
    for (k, b) in blocks.iter().enumerate() {
        let rows: Vec<usize> = blocks
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != k)
            .flat_map(|(_, r)| r.iter().cloned())
            .collect();
        let fit = lsq::fit(cols, y, &rows);
        total += b
            .iter()
            .map(|&i| (y[i] - fit.predict(cols, i)).powi(2))
            .sum::<f64>();
    }
    total
}

fn max_corr(r: &[f64], cols: &[Vec<f64>]) -> f64 {
    let n = r.len() as f64;
    let mr = r.iter().sum::<f64>() / n;
    let sr = r.iter().map(|v| (v - mr).powi(2)).sum::<f64>().sqrt();
    cols.iter()
        .map(|c| {
            let mc = c.iter().sum::<f64>() / n;
            let sc = c.iter().map(|v| (v - mc).powi(2)).sum::<f64>().sqrt();
            let cov: f64 = r.iter().zip(c).map(|(a, b)| (a - mr) * (b - mc)).sum();
            if sr > 0.0 && sc > 0.0 {
                (cov / (sr * sc)).abs()
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
}

fn restrict(cols: &[Vec<f64>], rows: &[usize]) -> Vec<Vec<f64>> {
    cols.iter()
        .map(|c| rows.iter().map(|&i| c[i]).collect())
        .collect()
}

fn ss(v: &[f64], rows: &[usize]) -> f64 {
    rows.iter().map(|&i| v[i] * v[i]).sum()
}

fn lag1(v: &[f64], order: &[usize]) -> f64 {
    if order.len() < 3 {
        return 0.0;
    }
    let m = order.iter().map(|&i| v[i]).sum::<f64>() / order.len() as f64;
    let den: f64 = order.iter().map(|&i| (v[i] - m).powi(2)).sum();
    let num: f64 = order
        .windows(2)
        .map(|w| (v[w[0]] - m) * (v[w[1]] - m))
        .sum();
    if den > 0.0 { num / den } else { 0.0 }
}

/// Best variant of `fam` by the training BIC of the whole refit, given the projector and residual of the
/// other columns: maximises `n·ln(RSS₀/(RSS₀ − drop)) − k·ln n` (`drop` = exact refit RSS drop). The
/// variants are built one at a time.
fn select_variant(
    fam: &Family,
    proj: &Projector,
    r: &[f64],
    ctx: &Context,
    obs: &Observations,
) -> (usize, f64) {
    let train = &ctx.train;
    let n = train.len() as f64;
    let rss0 = lsq::dot(r, r);
    let mut best = (0, f64::NEG_INFINITY, 0.0);
    for (k, v) in fam.variants.iter().enumerate() {
        let d = proj
            .rss_drop(r, &v.columns_on(ctx, obs, train))
            .clamp(0.0, rss0);
        let rest = (rss0 - d).max(rss0 * 1e-15).max(1e-300);
        let crit = n * (rss0.max(1e-300) / rest).ln() - v.n_params as f64 * n.ln();
        if crit > best.1 {
            best = (k, crit, d);
        }
    }
    (best.0, best.2)
}

/// Best variant of `fam` given the other columns `others`.
fn best_variant(
    fam: &Family,
    others: &[Vec<f64>],
    y: &[f64],
    ctx: &Context,
    obs: &Observations,
) -> (usize, f64) {
    let proj = Projector::new(others, &ctx.train);
    let base = fit_all(others, y, &ctx.train);
    let r: Vec<f64> = ctx.train.iter().map(|&i| base.resid[i]).collect();
    select_variant(fam, &proj, &r, ctx, obs)
}

/// Elapsed-time progress on stderr (when asked for).
struct Progress {
    on: bool,
    t0: std::time::Instant,
}

impl Progress {
    fn step(&self, what: impl FnOnce() -> String) {
        if self.on {
            eprintln!(
                "[{:>6.1} s] diagnose: {}",
                self.t0.elapsed().as_secs_f64(),
                what()
            );
        }
    }
}

/// The deterministic block-bootstrap resamples (xorshift64 over the block indices).
fn bootstrap_rows(blocks: &[Vec<usize>], b: usize, n_tr: usize) -> Vec<usize> {
    let mut rng = 0x2545_f491_4f6c_dd1du64 ^ (n_tr as u64);
    let mut rows = Vec::with_capacity(n_tr);
    for round in 0..=b {
        rows.clear();
        for _ in 0..blocks.len() {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            if round == b {
                rows.extend_from_slice(&blocks[(rng % blocks.len() as u64) as usize]);
            }
        }
    }
    rows
}

/// The residual of the named model fitted (on the training rows, with its variants chosen as
/// [`diagnose`] chooses them) to `obs.target` over all rows — what the model cannot represent of a signal.
/// The validation harness fits it to a withheld effect's true contribution alone, to size the effect by
/// the part the model cannot absorb.
pub fn model_residual(
    obs: &Observations,
    model: &[EffectKind],
    pitch_segments_max: usize,
) -> Result<Vec<f64>, String> {
    obs.validate()?;
    let ctx = Context::new(obs, pitch_segments_max);
    let y = &obs.target;
    let mut fams: Vec<Family> = Vec::new();
    for &k in model {
        match basis::family(k, obs, &ctx) {
            Some(f) => fams.push(f),
            None => {
                return Err(format!(
                    "model effect `{k}` cannot be built from this data: {}",
                    needs(k)
                ));
            }
        }
    }
    let mut choice = vec![0usize; fams.len()];
    let assemble = |choice: &[usize], skip: Option<usize>| -> Vec<Vec<f64>> {
        let mut cols = vec![vec![1.0; ctx.n]];
        for (j, f) in fams.iter().enumerate() {
            if Some(j) != skip {
                cols.extend(f.variants[choice[j]].columns(&ctx, obs));
            }
        }
        cols
    };
    for _pass in 0..2 {
        for j in 0..fams.len() {
            if fams[j].variants.len() > 1 {
                let others = assemble(&choice, Some(j));
                choice[j] = best_variant(&fams[j], &others, y, &ctx, obs).0;
            }
        }
    }
    Ok(fit_all(&assemble(&choice, None), y, &ctx.train).resid)
}

/// Runs the diagnosis.
pub fn diagnose(
    obs: &Observations,
    model: &[EffectKind],
    opts: &DiagnoseOptions,
) -> Result<Diagnosis, String> {
    obs.validate()?;
    let progress = Progress {
        on: opts.progress,
        t0: std::time::Instant::now(),
    };
    let ctx = Context::new(obs, opts.pitch_segments_max);
    let y = &obs.target;
    let train = ctx.train.clone();
    let hold = obs.holdout_rows();
    let n_tr = train.len();
    let n_ho = hold.len();

    // ---- base model ----
    progress.step(|| format!("fitting the model on {n_tr} training rows"));
    let mut fams: Vec<Family> = Vec::new();
    for &k in model {
        match basis::family(k, obs, &ctx) {
            Some(f) => fams.push(f),
            None => {
                return Err(format!(
                    "model effect `{k}` cannot be built from this data: {}",
                    needs(k)
                ));
            }
        }
    }
    let mut choice = vec![0usize; fams.len()];
    let assemble = |choice: &[usize], skip: Option<usize>| -> Vec<Vec<f64>> {
        let mut cols = vec![vec![1.0; ctx.n]];
        for (j, f) in fams.iter().enumerate() {
            if Some(j) != skip {
                cols.extend(f.variants[choice[j]].columns(&ctx, obs));
            }
        }
        cols
    };
    for _pass in 0..2 {
        for j in 0..fams.len() {
            if fams[j].variants.len() > 1 {
                let others = assemble(&choice, Some(j));
                choice[j] = best_variant(&fams[j], &others, y, &ctx, obs).0;
            }
        }
    }
    let mut base_cols = assemble(&choice, None);
    let base = fit_all(&base_cols, y, &train);
    let p0 = base.fit.rank;
    let rss0 = ss(&base.resid, &train);
    let rss_ho0 = ss(&base.resid, &hold);
    let dof0 = n_tr.saturating_sub(p0).max(1);
    let noise2 = rss0 / dof0 as f64;
    let gap = Gap {
        train_rms_um: (rss0 / n_tr as f64).sqrt(),
        holdout_rms_um: (rss_ho0 / n_ho as f64).sqrt(),
        holdout_max_um: hold
            .iter()
            .map(|&i| base.resid[i].abs())
            .fold(0.0, f64::max),
    };
    let mut model_terms = Vec::new();
    {
        let mut c = 1;
        for (j, f) in fams.iter().enumerate() {
            let v = &f.variants[choice[j]];
            let mut params = v.params.clone();
            let coefs: Vec<f64> = base.fit.coef[c..c + v.n_cols].to_vec();
            if coefs.len() <= 4 {
                params.insert("coefficients".into(), Value::from(coefs));
            }
            c += v.n_cols;
            model_terms.push(ModelTerm {
                kind: f.kind.name().into(),
                params,
                columns: v.n_cols,
            });
        }
    }

    // ---- where ----
    let where_ = locate::locate(obs, &base.resid, noise2);

    // ---- candidates ----
    let cand_kinds: Vec<EffectKind> = opts
        .candidates
        .clone()
        .unwrap_or_else(|| EffectKind::ALL.to_vec())
        .into_iter()
        .filter(|k| !model.contains(k))
        .collect();
    let mut not_applicable = Vec::new();
    let mut cand_fams = Vec::new();
    for k in cand_kinds {
        match basis::family(k, obs, &ctx) {
            Some(f) => cand_fams.push(f),
            None => not_applicable.push(k.name().to_string()),
        }
    }
    let total_variants: usize = cand_fams
        .iter()
        .map(|f| f.variants.len())
        .sum::<usize>()
        .max(1);
    let proj = Projector::new(&base_cols, &train);
    let r_tr: Vec<f64> = train.iter().map(|&i| base.resid[i]).collect();
    let mut effects = Vec::new();
    for f in &cand_fams {
        progress.step(|| {
            format!(
                "searching {} ({} variants)",
                f.kind.name(),
                f.variants.len()
            )
        });
        let best = select_variant(f, &proj, &r_tr, &ctx, obs);
        let v = &f.variants[best.0];
        let v_cols = v.columns(&ctx, obs);
        let cols = with_extra(&base_cols, &v_cols);
        let refit = fit_all(&cols, y, &train);
        let q = refit.fit.rank.saturating_sub(p0);
        let rss1 = ss(&refit.resid, &train).min(rss0);
        let rss_ho1 = ss(&refit.resid, &hold);
        let k_pen = (v.n_params - v.n_cols + q) as f64;
        let dof1 = n_tr.saturating_sub(p0 + q).max(1) as f64;
        let p_train = if q == 0 || rss1 <= 0.0 {
            if q > 0 && rss0 > 0.0 { 0.0 } else { 1.0 }
        } else {
            let fstat = ((rss0 - rss1) / q as f64) / (rss1 / dof1);
            (stats::f_sf(fstat, q as f64, dof1) * total_variants as f64).min(1.0)
        };
        let d: Vec<f64> = hold
            .iter()
            .map(|&i| base.resid[i].powi(2) - refit.resid[i].powi(2))
            .collect();
        let (_, p_ho) = stats::paired_t(&d);
        let rms_after = (rss_ho1 / n_ho as f64).sqrt();
        let shrink = if gap.holdout_rms_um > 0.0 {
            100.0 * (1.0 - rms_after / gap.holdout_rms_um)
        } else {
            0.0
        };
        let score = if rss_ho1 > 0.0 && rss_ho0 > 0.0 {
            n_ho as f64 * (rss_ho0 / rss_ho1).ln() - k_pen * (n_ho as f64).ln()
        } else {
            0.0
        };
        let train_delta_bic = if rss1 > 0.0 && rss0 > 0.0 {
            n_tr as f64 * (rss0 / rss1).ln() - k_pen * (n_tr as f64).ln()
        } else {
            0.0
        };
        let sigma = (rss1 / dof1).sqrt();
        let gain = gap.holdout_rms_um - rms_after;
        let mut params = v.params.clone();
        let coefs: Vec<f64> = refit.fit.coef[base_cols.len()..].to_vec();
        let contribution: Vec<f64> = (0..ctx.n)
            .map(|i| v_cols.iter().zip(&coefs).map(|(c, b)| c[i] * b).sum())
            .collect();
        let local = local_gain(&contribution, &base.resid, &refit.resid, &hold, sigma);
        let material = is_material(gain, gap.holdout_rms_um, sigma)
            || local.as_ref().is_some_and(|l| l.material);
        decorate(f.kind, &mut params, &coefs, &contribution, &hold);
        effects.push(Candidate {
            kind: f.kind.name().into(),
            score,
            params,
            holdout_rms_after_um: rms_after,
            shrink_pct: shrink,
            n_params: v.n_params,
            train_rms_after_um: (rss1 / n_tr as f64).sqrt(),
            train_delta_bic,
            train_p_value: p_train,
            holdout_p_value: p_ho,
            holdout_gain_um: gain,
            noise_um: sigma,
            material,
            local,
            explains: p_train < opts.alpha && material,
            residual_correlation: max_corr(&r_tr, &restrict(&v_cols, &train)),
            cv_rms_before_um: None,
            cv_rms_after_um: None,
            inclusion_probability: 0.0,
            kind_enum: Some(f.kind),
            variant: Some(v.clone()),
            contribution_um: contribution,
            residual_after: refit.resid,
        });
    }
    drop(proj);
    // ---- evidence: blocked CV and block-bootstrap stability selection ----
    let blocks = training_blocks(obs, &train);
    let passing: Vec<usize> = (0..effects.len())
        .filter(|&k| effects[k].train_p_value < opts.alpha)
        .collect();
    if blocks.len() >= 3 && !passing.is_empty() {
        progress.step(|| format!("blocked CV over {} training blocks", blocks.len()));
        let cv0 = blocked_cv_rss(&base_cols, y, &blocks);
        for &k in &passing {
            let c = &mut effects[k];
            let v_cols = c
                .variant
                .as_ref()
                .map_or(Vec::new(), |v| v.columns(&ctx, obs));
            c.cv_rms_before_um = Some((cv0 / n_tr as f64).sqrt());
            c.cv_rms_after_um = Some(
                (blocked_cv_rss(&with_extra(&base_cols, &v_cols), y, &blocks) / n_tr as f64).sqrt(),
            );
        }
    }
    if blocks.len() >= 2 && !passing.is_empty() {
        progress.step(|| "block bootstrap (20 resamples)".to_string());
        let b_count = 20;
        let r0: Vec<f64> = (0..b_count)
            .map(|b| rss_on(&base_cols, y, &bootstrap_rows(&blocks, b, n_tr)))
            .collect();
        // dbic[k][b]: training ΔBIC of candidate k on resample b (one candidate's columns at a time).
        let mut dbic = vec![vec![f64::NEG_INFINITY; b_count]; effects.len()];
        for &k in &passing {
            let c = &effects[k];
            let v_cols = c
                .variant
                .as_ref()
                .map_or(Vec::new(), |v| v.columns(&ctx, obs));
            let cols = with_extra(&base_cols, &v_cols);
            for b in 0..b_count {
                let rows = bootstrap_rows(&blocks, b, n_tr);
                let nb = rows.len() as f64;
                let r1 = rss_on(&cols, y, &rows);
                if r0[b] > 0.0 && r1 > 0.0 {
                    dbic[k][b] = nb * (r0[b] / r1).ln() - c.n_params as f64 * nb.ln();
                }
            }
        }
        let mut wins = vec![0usize; effects.len()];
        for b in 0..b_count {
            let mut best = (usize::MAX, 0.0f64);
            for &k in &passing {
                if dbic[k][b] > best.1 {
                    best = (k, dbic[k][b]);
                }
            }
            if best.0 != usize::MAX {
                wins[best.0] += 1;
            }
        }
        for (c, w) in effects.iter_mut().zip(wins) {
            c.inclusion_probability = w as f64 / b_count as f64;
        }
    }

    // Explaining candidates first, by held-out RMS after (lowest first), then the rest by score.
    effects.sort_by(|a, b| {
        b.explains.cmp(&a.explains).then(if a.explains {
            a.holdout_rms_after_um.total_cmp(&b.holdout_rms_after_um)
        } else {
            b.score.total_cmp(&a.score)
        })
    });

    // ---- verdict, ties ----
    let mut verdict = "none".to_string();
    let mut ties = Vec::new();
    let mut note;
    let n_explain = effects.iter().take_while(|c| c.explains).count();
    if n_explain > 0 {
        // The leader (lowest held-out RMS) and every explaining candidate it does not beat materially.
        let lead = &effects[0];
        let gain_lead = rss_ho0 - ss(&lead.residual_after, &hold);
        let group: Vec<usize> = (0..n_explain)
            .filter(|&j| {
                if j == 0 {
                    return true;
                }
                let d: Vec<f64> = hold
                    .iter()
                    .map(|&i| effects[j].residual_after[i].powi(2) - lead.residual_after[i].powi(2))
                    .collect();
                let (t, _) = stats::paired_t(&d);
                let rss_j = ss(&effects[j].residual_after, &hold);
                let gain_j = rss_ho0 - rss_j;
                // Held-out ΔBIC of the leader over j (Kass & Raftery 1995: ≥ 2 is positive evidence).
                let evidence = effects[0].score - effects[j].score;
                t < 2.0 || (gain_j >= TIE_GAIN_FRACTION * gain_lead && evidence < TIE_EVIDENCE)
            })
            .collect();
        // The simplest of the group: a candidate with a physical input before the sensor-free
        // `time_drift`, then fewest parameters, then the nesting order of the kinds (a special case
        // before its generalisation), then the lowest held-out RMS.
        let pick = *group
            .iter()
            .min_by(|&&a, &&b| {
                let time = |k: usize| effects[k].kind_enum == Some(EffectKind::TimeDrift);
                time(a)
                    .cmp(&time(b))
                    .then(effects[a].n_params.cmp(&effects[b].n_params))
                    .then(nesting_rank(&effects[a]).cmp(&nesting_rank(&effects[b])))
                    .then(a.cmp(&b))
            })
            .unwrap();
        // Encompassing test on the training rows: a tied candidate replaces the simpler pick when its columns
        // add significantly to the pick's refit (F-test, Bonferroni over its searched variants) while the
        // pick's columns add nothing significant to its own refit, and it is not worse on the held-out rows
        // (e.g. a time constant the drift cannot mimic, or a trend in time the temperatures do not carry).
        let mut pick = pick;
        let mut encompassed = None;
        for &j in &group {
            if j == pick || effects[j].holdout_rms_after_um > effects[pick].holdout_rms_after_um {
                continue;
            }
            let n_var = |k: usize| {
                cand_fams
                    .iter()
                    .find(|f| Some(f.kind) == effects[k].kind_enum)
                    .map_or(1, |f| f.variants.len())
            };
            let (Some(vp), Some(vj)) = (&effects[pick].variant, &effects[j].variant) else {
                continue;
            };
            let (cp, cj) = (vp.columns(&ctx, obs), vj.columns(&ctx, obs));
            let both: Vec<Vec<f64>> = cp.iter().chain(&cj).cloned().collect();
            let joint = fit_all(&with_extra(&base_cols, &both), y, &train);
            let rss_pj = ss(&joint.resid, &train);
            let dof = n_tr.saturating_sub(joint.fit.rank).max(1) as f64;
            let adds = |k: usize, q: usize| {
                let rss_k = ss(&effects[k].residual_after, &train);
                if q == 0 || rss_pj <= 0.0 || rss_k <= rss_pj {
                    return 1.0;
                }
                let f = ((rss_k - rss_pj) / q as f64) / (rss_pj / dof);
                (stats::f_sf(f, q as f64, dof) * n_var(if k == pick { j } else { pick }) as f64)
                    .min(1.0)
            };
            // p of j's columns added to the pick's refit, and of the pick's added to j's.
            let p_j_over_pick = adds(pick, cj.len());
            let p_pick_over_j = adds(j, cp.len());
            if p_j_over_pick < opts.alpha && p_pick_over_j >= opts.alpha {
                encompassed = Some((effects[pick].kind.clone(), p_j_over_pick, p_pick_over_j));
                pick = j;
                break;
            }
        }
        if group.len() > 1 {
            ties = group
                .iter()
                .filter(|&&j| j != pick)
                .map(|&j| effects[j].kind.clone())
                .collect();
            let others: Vec<String> = group
                .iter()
                .filter(|&&j| j != pick)
                .map(|&j| {
                    format!(
                        "{} ({} parameters, held-out RMS {:.3} µm)",
                        effects[j].kind, effects[j].n_params, effects[j].holdout_rms_after_um
                    )
                })
                .collect();
            note = format!(
                "{} ({} parameters, held-out RMS {:.3} µm) explains the gap as well as {} (not beaten on the held-out rows with paired t ≥ 2 and either a margin — it removes ≥ {} % of the held-out squared gap the best removes — or held-out ΔBIC ≥ 2); the simpler is preferred",
                effects[pick].kind,
                effects[pick].n_params,
                effects[pick].holdout_rms_after_um,
                others.join(", "),
                100.0 * TIE_GAIN_FRACTION
            );
        } else {
            note = format!(
                "{} explains the held-out gap beyond noise (train p = {:.2e} after Bonferroni over {} variants; held-out RMS {:.3} → {:.3} µm, shrink {:.1} % ≥ {} %, gain {:.3} µm ≥ {}·σ = {:.3} µm)",
                effects[pick].kind,
                effects[pick].train_p_value,
                total_variants,
                gap.holdout_rms_um,
                effects[pick].holdout_rms_after_um,
                effects[pick].shrink_pct,
                MIN_SHRINK_PCT,
                effects[pick].holdout_gain_um,
                MIN_NOISE_FRACTION,
                MIN_NOISE_FRACTION * effects[pick].noise_um
            );
        }
        if let Some((simpler, p_in, p_out)) = &encompassed {
            note = note.replace("; the simpler is preferred", "");
            note = format!(
                "{note}; {} is chosen over the simpler {simpler}: on the training rows its columns add significantly to {simpler}'s refit (p = {p_in:.2e} after Bonferroni) while {simpler}'s add nothing to its own (p = {p_out:.2e}), and it is not worse on the held-out rows",
                effects[pick].kind
            );
        }
        if pick != 0 {
            let c = effects.remove(pick);
            effects.insert(0, c);
        }
        verdict = effects[0].kind.clone();
    } else {
        let sig = effects.iter().find(|c| c.train_p_value < opts.alpha);
        note = match sig {
            Some(c) => format!(
                "no candidate explains the held-out gap beyond noise: the best significant one on the training rows, {}, changes the held-out RMS by {:.1} % ({:.3} µm; material needs ≥ {} % of the gap and ≥ {}·σ = {:.3} µm)",
                c.kind,
                c.shrink_pct,
                c.holdout_gain_um,
                MIN_SHRINK_PCT,
                MIN_NOISE_FRACTION,
                MIN_NOISE_FRACTION * c.noise_um
            ),
            None => "no candidate explains the held-out gap beyond noise (none passes the training test)".into(),
        };
    }

    let verdict_where = match effects.first() {
        Some(c) if c.kind == verdict => locate::locate_gain(obs, &base.resid, &c.residual_after),
        _ => Vec::new(),
    };
    // Only the verdict keeps its full-length columns (the report and the harness use them).
    for c in effects.iter_mut().filter(|c| c.kind != verdict) {
        c.residual_after = Vec::new();
        c.contribution_um = Vec::new();
    }

    // ---- residual checks ----
    let pos_order = obs.position_mm.as_ref().map(|x| {
        let mut o = train.clone();
        o.sort_by(|&a, &b| x[a].total_cmp(&x[b]));
        o
    });
    let time_order: Vec<usize> = ctx
        .time_order
        .iter()
        .cloned()
        .filter(|&i| !obs.held_out[i])
        .collect();
    let l1p = pos_order.as_ref().map(|o| lag1(&base.resid, o));
    let l1t = lag1(&base.resid, &time_order);
    let sq = (n_tr as f64).sqrt();
    let residual_checks = ResidualChecks {
        lag1_autocorr_position: l1p,
        lag1_autocorr_time: l1t,
        white_position: l1p.map(|r| r.abs() * sq < 3.0),
        white_time: l1t.abs() * sq < 3.0,
    };
    progress.step(|| format!("verdict {verdict}"));
    base_cols.remove(0);

    Ok(Diagnosis {
        target: obs.target_name.clone(),
        n_train: n_tr,
        n_holdout: n_ho,
        model: model_terms,
        gap,
        where_,
        verdict_where,
        effects,
        verdict,
        verdict_rule: VERDICT_RULE.to_string(),
        note,
        ties,
        not_applicable,
        residual_checks,
        noise_um: noise2.sqrt(),
        residual: base.resid,
        model_columns: base_cols,
    })
}

/// Tie order between kinds with as many parameters: a special case before its generalisation
/// (`thermal_drift` is `thermal_lag` with τ → 0), and a sensor-free `time_drift` after every kind with
/// a physical input (it stands for "something changed with time" and is blamed only when no input does).
fn nesting_rank(c: &Candidate) -> u8 {
    match c.kind_enum {
        Some(EffectKind::ThermalDrift) => 0,
        Some(EffectKind::ThermalLag) => 1,
        Some(EffectKind::TimeDrift) => 3,
        _ => 2,
    }
}

/// Adds physically meaningful parameters derived from the fitted coefficients.
fn decorate(
    kind: EffectKind,
    params: &mut Map<String, Value>,
    coefs: &[f64],
    contribution: &[f64],
    hold: &[usize],
) {
    let peak = hold
        .iter()
        .map(|&i| contribution[i].abs())
        .fold(0.0, f64::max);
    params.insert("peak_holdout_um".into(), Value::from(peak));
    match kind {
        EffectKind::Cogging | EffectKind::InterpolationError if coefs.len() == 2 => {
            params.insert("amplitude_um".into(), Value::from(coefs[0].hypot(coefs[1])));
        }
        EffectKind::ScaleExpansion if coefs.len() == 1 => {
            params.insert("c_um_per_m_k".into(), Value::from(1000.0 * coefs[0]));
        }
        EffectKind::Reversal if !coefs.is_empty() => {
            // d·b0 → the reversal value (difference between directions) is 2·b0 at mid-stroke.
            params.insert("reversal_mid_um".into(), Value::from(2.0 * coefs[0]));
        }
        _ => {
            params.insert("coefficients".into(), Value::from(coefs.to_vec()));
        }
    }
}

/// The columns an effect kind needs (for error messages).
pub fn needs(k: EffectKind) -> &'static str {
    match k {
        EffectKind::PitchError => "needs a varying `target_mm` column",
        EffectKind::Reversal => "needs a `direction` column with both directions",
        EffectKind::ScaleExpansion => "needs `target_mm` and a varying `*_degC` column",
        EffectKind::ThermalDrift => "needs a varying `*_degC` column",
        EffectKind::ThermalLag => "needs `time_s` (or `time`) and a varying `*_degC` column",
        EffectKind::ForceDeflection => "needs a varying `*_N` column",
        EffectKind::Cogging | EffectKind::InterpolationError | EffectKind::EndEffect => {
            "needs a varying `target_mm` column"
        }
        EffectKind::FollowingError => "needs a varying `velocity_mm_s` or `accel_mm_s2` column",
        EffectKind::Abbe => "needs a varying `offset_mm` column",
        EffectKind::TimeDrift => "needs `time_s` (or `time`)",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obs::Named;

    /// Deterministic normal noise (64-bit LCG + Box–Muller).
    use axcomp_numeric::noise::TestNoise as Noise;

    /// 2000 rows, 10 runs (run 4 and 9 held out), positions uniform on 0–200 mm, both directions,
    /// a smooth pitch error, an optional reversal of ±`rev` µm, noise σ 0.5 µm.
    fn positioning(rev: f64, seed: u64) -> Observations {
        let mut rng = Noise(seed);
        let n = 2000;
        let mut o = Observations {
            target_name: "deviation_um".into(),
            ..Default::default()
        };
        let (mut x, mut d, mut run, mut y) = (vec![], vec![], vec![], vec![]);
        for i in 0..n {
            let xi = 200.0 * rng.uniform();
            let di = if i % 2 == 0 { 1.0 } else { -1.0 };
            let pitch = 6.0 * (xi / 150.0).sin() + 0.02 * xi;
            x.push(xi);
            d.push(di);
            run.push(i / 200);
            y.push(pitch + rev * di + 0.5 * rng.normal());
        }
        o.held_out = run.iter().map(|r| *r == 4 || *r == 9).collect();
        o.position_mm = Some(x);
        o.direction = Some(d);
        o.run = Some(run);
        o.target = y;
        o
    }

    #[test]
    fn finds_a_withheld_reversal_and_says_none_when_complete() {
        // Reversal of ±1 µm (peak 2σ) withheld: verdict reversal, held-out RMS close to the noise σ = 0.5
        // (tolerance 15 %: 400 held-out rows).
        let obs = positioning(1.0, 11);
        let d = diagnose(&obs, &[EffectKind::PitchError], &DiagnoseOptions::default()).unwrap();
        assert_eq!(d.verdict, "reversal", "{}", d.note);
        let c = d.verdict_candidate().unwrap();
        assert!(
            (c.holdout_rms_after_um - 0.5).abs() < 0.075,
            "{}",
            c.holdout_rms_after_um
        );
        assert!(d.where_.iter().any(|r| r.variable == "target_mm"));
        // The complete model: nothing beyond noise, on several noise draws.
        for seed in 1..=5 {
            let obs = positioning(1.0, seed);
            let d = diagnose(
                &obs,
                &[EffectKind::PitchError, EffectKind::Reversal],
                &DiagnoseOptions::default(),
            )
            .unwrap();
            assert_eq!(d.verdict, "none", "seed {seed}: {}", d.note);
        }
    }

    #[test]
    fn verdict_does_not_hinge_on_the_held_out_size() {
        // Issue 13: a withheld reversal of ±0.5 µm (σ 0.5: the held-out gap shrinks by ≈ 29 %, 11–36 % on 20
        // rows) has, with only 20 held-out rows, a held-out paired p of 0.29 and 0.014 for seeds 21 and 23
        // (measured), so the former rule (held-out p < 0.01) said `none`. The rule now blames it with
        // 20 held-out rows as with 400, since the shrink is material either way; and a complete model stays
        // `none` with 20 held-out rows too.
        for seed in 21..=23 {
            for n_ho in [20usize, 400] {
                let mut obs = positioning(0.5, seed);
                obs.held_out = (0..obs.n_rows())
                    .map(|i| i >= obs.n_rows() - n_ho)
                    .collect();
                let d =
                    diagnose(&obs, &[EffectKind::PitchError], &DiagnoseOptions::default()).unwrap();
                assert_eq!(
                    d.verdict, "reversal",
                    "seed {seed}, {n_ho} held out: {}",
                    d.note
                );
                let c = d.verdict_candidate().unwrap();
                assert!(
                    c.material && c.shrink_pct >= MIN_SHRINK_PCT,
                    "{}",
                    c.shrink_pct
                );
                let d = diagnose(
                    &obs,
                    &[EffectKind::PitchError, EffectKind::Reversal],
                    &DiagnoseOptions::default(),
                )
                .unwrap();
                assert_eq!(
                    d.verdict, "none",
                    "seed {seed}, {n_ho} held out: {}",
                    d.note
                );
            }
        }
    }

    #[test]
    fn prefers_the_simpler_of_two_equal_explanations() {
        // Time series: error = 2 µm/K · ΔT of a slowly varying sensor (no lag). thermal_lag with a short τ
        // explains it as well as thermal_drift; the verdict must be the simpler thermal_drift, with the tie
        // reported.
        let mut rng = Noise(5);
        let n = 1500;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 10.0).collect();
        let temp: Vec<f64> = t
            .iter()
            .map(|s| 20.0 + 3.0 * (1.0 - (-s / 4000.0).exp()) + 0.5 * (s / 1500.0).sin())
            .collect();
        let y: Vec<f64> = temp
            .iter()
            .map(|v| 2.0 * (v - 20.0) + 0.3 * rng.normal())
            .collect();
        let obs = Observations {
            target_name: "drift_um".into(),
            target: y,
            held_out: (0..n).map(|i| (i / 100) % 3 == 2).collect(),
            time_s: Some(t),
            temperatures: vec![Named {
                name: "spindle".into(),
                values: temp,
            }],
            ..Default::default()
        };
        let d = diagnose(&obs, &[], &DiagnoseOptions::default()).unwrap();
        assert_eq!(d.verdict, "thermal_drift", "{}", d.note);
        assert!(
            d.ties.iter().any(|k| k == "thermal_lag"),
            "ties {:?}, note {}",
            d.ties,
            d.note
        );
        assert!(d.note.contains("simpler"), "{}", d.note);
        assert!(d.not_applicable.contains(&"cogging".to_string()));
    }

    #[test]
    fn rejects_a_model_effect_without_its_columns() {
        let obs = positioning(0.0, 3);
        let err = diagnose(
            &obs,
            &[EffectKind::ThermalDrift],
            &DiagnoseOptions::default(),
        )
        .unwrap_err();
        assert!(
            err.contains("thermal_drift") && err.contains("_degC"),
            "{err}"
        );
    }
}
