//! The withheld-effect validation harness: many twin campaigns, each with one effect (or none) left out
//! of the model, diagnosed blind.
//!
//! Glossary: **case** = one simulated campaign + the model told to the diagnosis; **withheld** = the
//! effect present in the twin but not in the model (`None` = a null case: the model is complete);
//! **SNR** = peak |contribution| on the held-out rows of the withheld effect — or, when smaller, of its
//! *unabsorbed part* — divided by the noise σ (the effect is scaled exactly to it); the unabsorbed part is
//! what is left of the effect's true contribution after fitting the told model to it alone
//! ([`engine::model_residual`]). The diagnosis can only see that part: an end decay of a few mm is mostly
//! absorbed by the pitch-error spline (before this definition, 25 of 30 `end_effect` cases had an oracle
//! shrink below 5 % — invisible by construction), a lag mostly by a drift. Both the whole effect and its
//! unabsorbed part therefore peak at ≥ SNR·σ; `unabsorbed_peak_ratio` per case says how much was absorbed; **oracle** = the base model plus the *true* withheld contribution as
//! one column, refitted on the training rows (the best a diagnosis could do); **shrink** = held-out RMS
//! reduction in % (`100·(1 − after/before)`).
//!
//! **Plan**: every case, null or not, is measured with the same plan, the twin's standard survey
//! ([`twin::SurveyPlan::standard`], resized to `--rows`), designed so that any single effect *could*
//! show — the plan never depends on the withheld kind (that would leak the answer): ISO 230-2 runs over
//! the stroke at Abbe offsets 0/50/100 mm (30 % of the rows); ISO 230-2 runs over the first and last
//! 20 mm with targets every ≈ 0.5–1 mm (15 %; an end decay of a few mm touches many targets); scans at
//! 10–200 mm/s (15 %); load steps ±400 N (15 %); measurement rounds at 10/50/90 % of the stroke (25 %).
//! The heat load over the survey is not monotonic in time (duty 1 for the first 30 % of the time, 0.4
//! up to 50 %, idle up to 75 %, duty 1 again) and the air swings ±0.5 K over 4 h, so a lagged
//! temperature and a polynomial in time do not fit alike.
//!
//! **Model**: `pitch_error` and `reversal` (unless withheld) plus up to two further kinds drawn at
//! random from the rest (never the withheld one). Held out: runs with `run % 3 == 0`.
//!
//! **Profiles** ([`Profile`]): `standard` is the above (5,000 rows, SNR 3–8). `hard` is at least as hard as
//! a real campaign: fewer rows (1,500) and runs (3 ISO 230-2 cycles instead of 5), weaker effects (SNR 2–8,
//! down to twice the noise), and a held-out set *outside the training regime* — the last ISO 230-2 cycle
//! at each offset and in each end zone (forward in time), the fastest scan speed (200 mm/s, training sees
//! ≤ 100 mm/s), the largest loads (±400 N, training sees ≤ 300 N) and the thermal rounds of the last
//! quarter of the survey (the re-heat after the cool-down: the training rows cover only part of that
//! temperature history). The withheld effect is scaled to the SNR on those held-out rows, so an effect
//! may be weaker still on the training rows.

use std::time::Instant;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;

use axcomp_twin as twin;

use axcomp_diagnose::EffectKind;
use axcomp_diagnose::engine::{self, DiagnoseOptions};
use axcomp_diagnose::obs::{Named, Observations};
use axcomp_numeric::stats;

use crate::harness::{self, CaseOutcome, Unlisted};

/// Which case generator (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Profile {
    Standard,
    Hard,
}

impl Profile {
    pub fn parse(s: &str) -> Result<Profile, String> {
        match s {
            "standard" => Ok(Profile::Standard),
            "hard" => Ok(Profile::Hard),
            other => Err(format!(
                "unknown harness `{other}` (expected standard or hard)"
            )),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Profile::Standard => "standard",
            Profile::Hard => "hard",
        }
    }

    /// Default rows per case.
    pub fn default_rows(self) -> usize {
        match self {
            Profile::Standard => 5000,
            Profile::Hard => 1500,
        }
    }

    /// Default SNRs.
    pub fn default_snrs(self) -> Vec<f64> {
        match self {
            Profile::Standard => vec![3.0, 4.0, 6.0, 8.0],
            Profile::Hard => vec![2.0, 4.0, 6.0, 8.0],
        }
    }
}

/// Settings of a validation run (validated by [`ValidateOptions::build`]).
#[derive(Debug, Clone)]
pub struct ValidateOptions {
    pub profile: Profile,
    pub cases: usize,
    pub seed: u64,
    pub snrs: Vec<f64>,
    pub rows: usize,
    pub noise_um: f64,
    /// Every `null_every`-th case is a null case.
    pub null_every: usize,
}

impl Default for ValidateOptions {
    fn default() -> Self {
        ValidateOptions {
            profile: Profile::Standard,
            cases: 100,
            seed: 1,
            snrs: vec![3.0, 4.0, 6.0, 8.0],
            rows: 5000,
            noise_um: 0.5,
            null_every: 4,
        }
    }
}

impl ValidateOptions {
    pub fn build(self) -> Result<Self, String> {
        harness::check_common(self.cases, &self.snrs, self.noise_um, self.null_every)?;
        if self.rows < 100 {
            return Err(format!("--rows must be ≥ 100, got {}", self.rows));
        }
        Ok(self)
    }
}

/// The kinds the harness withholds, in rotation.
pub const WITHHELD: [EffectKind; 12] = [
    EffectKind::Reversal,
    EffectKind::Cogging,
    EffectKind::ThermalDrift,
    EffectKind::EndEffect,
    EffectKind::ForceDeflection,
    EffectKind::ScaleExpansion,
    EffectKind::InterpolationError,
    EffectKind::ThermalLag,
    EffectKind::FollowingError,
    EffectKind::Abbe,
    EffectKind::TimeDrift,
    EffectKind::PitchError,
];

/// One diagnosed case.
#[derive(Debug, Clone, Serialize)]
pub struct CaseResult {
    pub index: usize,
    pub seed: u64,
    pub plan: String,
    pub rows: usize,
    pub withheld: String,
    pub snr: Option<f64>,
    /// Held-out peak of the withheld effect's part the model cannot absorb / peak of the whole effect
    /// (the SNR is set on the former; the whole effect's peak is `snr / unabsorbed_peak_ratio`·σ).
    pub unabsorbed_peak_ratio: Option<f64>,
    pub model: Vec<String>,
    pub verdict: String,
    pub ties: Vec<String>,
    pub correct: bool,
    pub holdout_rms_before_um: f64,
    /// Shrink of the verdict's refit (0 when the verdict is `none`).
    pub shrink_pct: f64,
    pub oracle_shrink_pct: Option<f64>,
    /// The top `target_mm` region of the verdict's `verdict_where` (or of `where` when the verdict is
    /// `none`) captures ≥ 50 % of the withheld effect's held-out energy with lift ≥ 1.2 (only for the
    /// localised kind `end_effect`).
    pub localised: Option<bool>,
    /// Relative error of the searched parameter (period, τ, decay length) when the verdict is right.
    pub param_rel_error: Option<f64>,
    /// corr² between the fitted and the true contribution on held-out rows when the verdict is right.
    pub contribution_r2: Option<f64>,
    /// Shares of `where` and `verdict_where` outside 0..1 (must be 0).
    pub shares_out_of_range: usize,
    /// The candidates passing the training test: (kind, held-out shrink %, held-out gain / σ, material).
    pub significant: Vec<(String, f64, f64, bool)>,
    pub seconds: f64,
}

/// The plan of every case: the twin's standard survey ([`twin::SurveyPlan`]), whatever is withheld.
pub const PLAN: &str = "survey";

/// Background kinds (modelled): `pitch_error` and `reversal`, plus up to two further kinds drawn at
/// random from the rest (never the withheld one).
fn background(withheld: Option<EffectKind>, rng: &mut StdRng) -> Vec<EffectKind> {
    use EffectKind::*;
    let base = [PitchError, Reversal];
    let mut out: Vec<EffectKind> = base.into_iter().filter(|k| Some(*k) != withheld).collect();
    let mut pool: Vec<EffectKind> = EffectKind::ALL
        .into_iter()
        .filter(|k| !base.contains(k) && Some(*k) != withheld)
        .collect();
    let n_extra = rng.gen_range(0..=2usize).min(pool.len());
    for _ in 0..n_extra {
        let j = rng.gen_range(0..pool.len());
        out.push(pool.remove(j));
    }
    out
}

/// Observations from a twin campaign (no CSV round trip), held out: `run % 3 == 0`.
pub fn observations_from_campaign(c: &twin::Campaign, deviation: &[f64]) -> Observations {
    let rows = &c.rows;
    let col = |f: &dyn Fn(&twin::Row) -> f64| -> Vec<f64> { rows.iter().map(f).collect() };
    Observations {
        target_name: "deviation_um".into(),
        target: deviation.to_vec(),
        held_out: rows.iter().map(|r| r.run % 3 == 0).collect(),
        position_mm: Some(col(&|r| r.target_mm)),
        direction: Some(col(&|r| f64::from(r.direction))),
        run: Some(rows.iter().map(|r| r.run as usize).collect()),
        time_s: Some(col(&|r| r.time_s)),
        temperatures: c
            .sensor_names
            .iter()
            .enumerate()
            .map(|(s, name)| Named {
                name: name.clone(),
                values: col(&|r| r.temps_degc[s]),
            })
            .collect(),
        forces: vec![Named {
            name: "force".into(),
            values: col(&|r| r.force_n),
        }],
        velocity_mm_s: Some(col(&|r| r.velocity_mm_s)),
        accel_mm_s2: Some(col(&|r| r.accel_mm_s2)),
        offset_mm: Some(col(&|r| r.offset_mm)),
    }
}

fn searched_param(
    kind: EffectKind,
    axis: &twin::Axis,
    params: &serde_json::Map<String, serde_json::Value>,
) -> Option<f64> {
    let get = |k: &str| params.get(k).and_then(|v| v.as_f64());
    match (kind, axis.effect(kind)?) {
        (EffectKind::Cogging, twin::Effect::Cogging(e)) => {
            Some((get("period_mm")? - e.period_mm).abs() / e.period_mm)
        }
        (EffectKind::InterpolationError, twin::Effect::InterpolationError(e)) => {
            let p = get("signal_period_um")? / get("harmonic")?;
            Some((p - e.signal_period_um).abs() / e.signal_period_um)
        }
        (EffectKind::ThermalLag, twin::Effect::ThermalLag(e)) => {
            let t = e.terms.first()?.tau_s;
            Some((get("tau_s")? - t).abs() / t)
        }
        (EffectKind::EndEffect, twin::Effect::EndEffect(e)) => {
            Some((get("decay_mm")? - e.decay_mm).abs() / e.decay_mm)
        }
        _ => None,
    }
}

fn corr2(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    if saa > 0.0 && sbb > 0.0 {
        sab * sab / (saa * sbb)
    } else {
        0.0
    }
}

/// ISO 230-2 cycles per offset / end zone in the hard profile (the standard survey has 5).
pub const HARD_ISO_CYCLES: usize = 3;

/// The hard profile's held-out rows, in the survey's row order (see the module docs): per part of the
/// standard survey, the last ISO 230-2 cycle of each offset / end zone, the fastest scan passes, the largest
/// loads, and the thermal rounds in the last quarter of the survey's time.
pub fn hard_holdout(sp: &twin::SurveyPlan) -> Vec<bool> {
    let parts: Vec<Vec<twin::Sample>> = sp.parts.iter().map(|p| p.samples()).collect();
    let total: usize = parts.iter().map(Vec::len).sum();
    // Start time of each part on the survey's time line (parts follow one another after `gap_s`).
    let mut starts = Vec::with_capacity(parts.len());
    let mut end_s = 0.0;
    for samples in &parts {
        starts.push(end_s);
        let t_end = samples.iter().map(|s| s.time_s).fold(0.0, f64::max);
        end_s += t_end + sp.gap_s;
    }
    end_s -= sp.gap_s;
    let mut out = Vec::with_capacity(total);
    for ((part, samples), &t0) in sp.parts.iter().zip(&parts).zip(&starts) {
        match part {
            twin::Plan::Iso230(p) => {
                let cycles = p.cycles.max(1) as u32;
                out.extend(samples.iter().map(|s| s.run % cycles == 0));
            }
            twin::Plan::Scan(p) => {
                let vmax = p.speeds_mm_s.iter().cloned().fold(0.0, f64::max);
                // Runs are numbered pass by pass: speed k has runs 2k+1 and 2k+2.
                out.extend(samples.iter().map(|s| {
                    let k = ((s.run - 1) / 2) as usize;
                    p.speeds_mm_s.get(k).is_some_and(|&v| v >= vmax)
                }));
            }
            twin::Plan::Load(p) => {
                let fmax = p.forces_n.iter().map(|f| f.abs()).fold(0.0, f64::max);
                out.extend(samples.iter().map(|s| s.force_n.abs() >= fmax - 1e-9));
            }
            _ => out.extend(samples.iter().map(|s| s.time_s + t0 >= 0.75 * end_s)),
        }
    }
    out
}

/// One simulated case, ready to diagnose.
pub struct CaseData {
    pub index: usize,
    pub seed: u64,
    pub plan: &'static str,
    pub withheld: Option<EffectKind>,
    pub snr: Option<f64>,
    pub model: Vec<EffectKind>,
    pub axis: twin::Axis,
    /// Observations with the withheld effect scaled to the SNR.
    pub obs: Observations,
    /// The scaled withheld contribution per row (0 for null cases).
    pub truth_um: Vec<f64>,
    /// Held-out peak of the part of the withheld effect the told model cannot absorb / held-out peak of
    /// the whole effect (the SNR is defined on the former).
    pub unabsorbed_peak_ratio: Option<f64>,
}

/// A case whose withheld effect the told model absorbs to below this fraction of its peak is not made.
pub const MIN_UNABSORBED_FRACTION: f64 = 1e-3;

/// Simulates case `index` (deterministic in `opts.seed` and `index`).
pub fn make_case(opts: &ValidateOptions, index: usize) -> Result<CaseData, String> {
    let seed = opts.seed.wrapping_mul(1_000_003).wrapping_add(index as u64);
    let mut rng = StdRng::seed_from_u64(seed);
    let scheduled = harness::schedule(index, opts.null_every, WITHHELD.len(), &opts.snrs);
    let withheld = scheduled.map(|(k, _)| WITHHELD[k]);
    let snr = scheduled.map(|(_, s)| s);
    let plan_name = PLAN;
    let model = background(withheld, &mut rng);
    let mut kinds = model.clone();
    kinds.extend(withheld);
    let axis = twin::Axis::random(&kinds, &mut rng).with_noise_um(opts.noise_um);
    let mut survey = twin::SurveyPlan::standard(axis.start_mm, axis.end_mm);
    if opts.profile == Profile::Hard {
        for part in &mut survey.parts {
            if let twin::Plan::Iso230(p) = part {
                p.cycles = HARD_ISO_CYCLES;
            }
        }
    }
    let mut plan = twin::Plan::from(survey);
    plan.resize(opts.rows);
    let campaign = twin::simulate(&axis, &plan, None, seed).map_err(|e| e.to_string())?;
    let mut y = campaign.deviations_um();
    let mut probe = observations_from_campaign(&campaign, &y);
    if opts.profile == Profile::Hard {
        if let twin::Plan::Survey(sp) = &plan {
            probe.held_out = hard_holdout(sp);
        }
        if probe.validate().is_err() {
            return Err(format!(
                "case {index}: the hard held-out set is empty or covers every row"
            ));
        }
    }
    let hold = probe.holdout_rows();
    // Scale the withheld effect so that the held-out peaks of the whole effect and of its part the told
    // model cannot absorb are both ≥ snr·σ, the smaller one = snr·σ (see the module docs: an end decay is
    // mostly a pitch error, a lag mostly a drift).
    let mut truth_c = vec![0.0; y.len()];
    let mut peak_ratio = None;
    if let (Some(w), Some(snr)) = (withheld, snr) {
        let tk = w;
        let raw_peak = campaign.peak_contribution_um(tk, hold.iter().cloned());
        if raw_peak.is_nan() || raw_peak <= 0.0 {
            return Err(format!(
                "case {index}: withheld {w} has no contribution on the held-out rows"
            ));
        }
        let alone = Observations {
            target: (0..y.len())
                .map(|i| campaign.contribution_um(tk, i))
                .collect(),
            ..probe.clone()
        };
        let left = engine::model_residual(
            &alone,
            &model,
            DiagnoseOptions::default().pitch_segments_max,
        )
        .map_err(|e| format!("case {index}: {e}"))?;
        let left_peak = hold.iter().map(|&i| left[i].abs()).fold(0.0, f64::max);
        // Not above the bound, or either side NaN.
        if left_peak.partial_cmp(&(MIN_UNABSORBED_FRACTION * raw_peak))
            != Some(std::cmp::Ordering::Greater)
        {
            return Err(format!(
                "case {index}: the told model absorbs the withheld {w} (its part left over peaks at {left_peak:.3e} of {raw_peak:.3e} µm)"
            ));
        }
        peak_ratio = Some(left_peak / raw_peak);
        // Both the whole effect and its part the model cannot absorb peak at ≥ snr·σ.
        let peak = left_peak.min(raw_peak);
        let f = snr * opts.noise_um / peak;
        for i in 0..y.len() {
            let c = campaign.contribution_um(tk, i);
            y[i] += (f - 1.0) * c;
            truth_c[i] = f * c;
        }
    }
    let obs = Observations { target: y, ..probe };
    Ok(CaseData {
        index,
        seed,
        plan: plan_name,
        withheld,
        snr,
        model,
        axis,
        obs,
        truth_um: truth_c,
        unabsorbed_peak_ratio: peak_ratio,
    })
}

/// Simulates and diagnoses case `index`.
pub fn run_case(opts: &ValidateOptions, index: usize) -> Result<CaseResult, String> {
    let case = make_case(opts, index)?;
    let CaseData {
        withheld,
        ref model,
        ref obs,
        truth_um: ref truth_c,
        ..
    } = case;
    let y = obs.target.clone();
    let hold = obs.holdout_rows();
    let train = obs.train_rows();
    let t0 = Instant::now();
    let d = engine::diagnose(obs, model, &DiagnoseOptions::default()).map_err(|e| e.to_string())?;
    let seconds = t0.elapsed().as_secs_f64();

    let expected = withheld.map_or("none", |w| w.name());
    let correct = d.verdict == expected;
    let shrink = d.verdict_candidate().map_or(0.0, |c| c.shrink_pct);
    // Oracle: base model + the true contribution as one column, refitted on the training rows.
    let oracle_shrink_pct = withheld.map(|_| {
        let mut cols = vec![vec![1.0; y.len()]];
        cols.extend(d.model_columns.iter().cloned());
        cols.push(truth_c.clone());
        let after = harness::holdout_rms_after_fit(&cols, &y, &train, &hold);
        harness::shrink_pct(d.gap.holdout_rms_um, after)
    });
    let (mut localised, mut param_rel_error, mut contribution_r2) = (None, None, None);
    if let Some(w) = withheld {
        if w == EffectKind::EndEffect {
            let energy: f64 = hold.iter().map(|&i| truth_c[i].powi(2)).sum();
            let x = obs.position_mm.as_ref().expect("positions");
            // Where the verdict acts, or (verdict `none`) where the gap lies.
            let regions = if d.verdict_where.is_empty() {
                &d.where_
            } else {
                &d.verdict_where
            };
            localised = Some(
                regions
                    .iter()
                    .find(|r| r.variable == "target_mm")
                    .is_some_and(|r| {
                        let inside: f64 = hold
                            .iter()
                            .filter(|&&i| x[i] >= r.from && x[i] <= r.to)
                            .map(|&i| truth_c[i].powi(2))
                            .sum();
                        inside >= 0.5 * energy && r.lift >= 1.2
                    }),
            );
        }
        if correct {
            let c = d.verdict_candidate().expect("verdict candidate");
            param_rel_error = searched_param(w, &case.axis, &c.params);
            let a: Vec<f64> = hold.iter().map(|&i| c.contribution_um[i]).collect();
            let b: Vec<f64> = hold.iter().map(|&i| truth_c[i]).collect();
            contribution_r2 = Some(corr2(&a, &b));
        }
    }
    Ok(CaseResult {
        index: case.index,
        seed: case.seed,
        plan: case.plan.into(),
        rows: y.len(),
        withheld: expected.into(),
        snr: case.snr,
        unabsorbed_peak_ratio: case.unabsorbed_peak_ratio,
        model: model.iter().map(|k| k.name().to_string()).collect(),
        verdict: d.verdict.clone(),
        ties: d.ties.clone(),
        correct,
        holdout_rms_before_um: d.gap.holdout_rms_um,
        shrink_pct: shrink,
        oracle_shrink_pct,
        localised,
        param_rel_error,
        contribution_r2,
        shares_out_of_range: d
            .where_
            .iter()
            .chain(&d.verdict_where)
            .filter(|r| !(0.0..=1.0).contains(&r.share))
            .count(),
        significant: d
            .effects
            .iter()
            .filter(|c| c.train_p_value < DiagnoseOptions::default().alpha)
            .map(|c| {
                (
                    c.kind.clone(),
                    c.shrink_pct,
                    c.holdout_gain_um / c.noise_um,
                    c.material,
                )
            })
            .collect(),
        seconds,
    })
}

/// Figures per SNR.
#[derive(Debug, Clone, Serialize)]
pub struct SnrRow {
    pub snr: f64,
    pub cases: usize,
    pub detection_rate: f64,
    pub top1_attribution: f64,
    pub median_shrink_ratio_to_oracle: f64,
    /// Cases whose oracle shrinks the held-out RMS by ≥ 1 % (the withheld effect is visible at all
    /// next to the model's own terms), and the top-1 attribution on them.
    pub identifiable_cases: usize,
    pub identifiable_top1_attribution: f64,
}

/// The validation summary (`--json` writes this with the cases).
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub harness: Profile,
    pub cases: usize,
    pub rows_per_case: usize,
    pub noise_um: f64,
    pub seed: u64,
    pub per_snr: Vec<SnrRow>,
    pub null_cases: usize,
    pub false_alarm_rate: f64,
    pub detection_rate: f64,
    pub top1_attribution: f64,
    /// Top-1 attribution over the non-null cases with SNR ≥ 4.
    pub top1_attribution_snr_ge_4: f64,
    pub cases_snr_ge_4: usize,
    /// The same over the identifiable ones (oracle shrink ≥ [`IDENTIFIABLE_ORACLE_SHRINK_PCT`]).
    pub identifiable_top1_attribution_snr_ge_4: f64,
    pub identifiable_cases_snr_ge_4: usize,
    /// Shares (of `where` / `verdict_where`) outside 0..1 over all cases.
    pub shares_out_of_range: usize,
    pub localisation_accuracy: Option<f64>,
    pub localisation_cases: usize,
    pub median_param_rel_error: Option<f64>,
    pub median_contribution_r2: Option<f64>,
    /// Median over non-null cases of shrink(verdict) / shrink(oracle) (verdict `none` counts as 0).
    pub median_shrink_ratio_to_oracle: f64,
    pub median_seconds: f64,
    pub max_seconds: f64,
    /// labels = `none` + the withheld kinds; `confusion[true][verdict]`.
    pub labels: Vec<String>,
    pub confusion: Vec<Vec<usize>>,
    pub case_results: Vec<CaseResult>,
}

/// Minimum oracle held-out shrink (%) for a case to count as identifiable.
pub const IDENTIFIABLE_ORACLE_SHRINK_PCT: f64 = engine::MIN_SHRINK_PCT;

fn identifiable(c: &CaseResult) -> bool {
    c.oracle_shrink_pct
        .is_some_and(|o| o >= IDENTIFIABLE_ORACLE_SHRINK_PCT)
}

fn ratio(c: &CaseResult) -> Option<f64> {
    let o = c.oracle_shrink_pct?;
    if o > 0.0 {
        Some(c.shrink_pct.max(0.0) / o)
    } else {
        None
    }
}

harness::case_outcome!(CaseResult, withheld);

/// Summarises case results.
pub fn summarise(opts: &ValidateOptions, results: Vec<CaseResult>) -> Summary {
    let non_null: Vec<&CaseResult> = results.iter().filter(|c| c.snr.is_some()).collect();
    let null_cases = results.iter().filter(|c| c.is_null()).count();
    let per_snr = harness::snr_levels(opts.snrs.iter().copied())
        .into_iter()
        .map(|s| {
            let cs = harness::at_snr(non_null.iter().copied(), s);
            let mut r: Vec<f64> = cs.iter().filter_map(|c| ratio(c)).collect();
            SnrRow {
                snr: s,
                cases: cs.len(),
                detection_rate: harness::share(cs.iter().map(|c| c.verdict != "none")),
                top1_attribution: harness::share(cs.iter().map(|c| c.correct)),
                median_shrink_ratio_to_oracle: stats::median(&mut r),
                identifiable_cases: cs.iter().filter(|c| identifiable(c)).count(),
                identifiable_top1_attribution: harness::share(
                    cs.iter().filter(|c| identifiable(c)).map(|c| c.correct),
                ),
            }
        })
        .collect();
    let mut labels = vec!["none".to_string()];
    labels.extend(WITHHELD.iter().map(|k| k.name().to_string()));
    let confusion = harness::confusion(&labels, &results, Unlisted::OtherColumn);
    let loc: Vec<bool> = results.iter().filter_map(|c| c.localised).collect();
    let mut pe: Vec<f64> = results.iter().filter_map(|c| c.param_rel_error).collect();
    let mut r2: Vec<f64> = results.iter().filter_map(|c| c.contribution_r2).collect();
    let mut ratios: Vec<f64> = non_null.iter().filter_map(|c| ratio(c)).collect();
    let (mut secs, max_seconds) = harness::seconds(&results);
    Summary {
        harness: opts.profile,
        cases: results.len(),
        rows_per_case: opts.rows,
        noise_um: opts.noise_um,
        seed: opts.seed,
        per_snr,
        null_cases,
        false_alarm_rate: harness::false_alarm_rate(&results),
        detection_rate: harness::share(non_null.iter().map(|c| c.verdict != "none")),
        top1_attribution: harness::share(non_null.iter().map(|c| c.correct)),
        top1_attribution_snr_ge_4: harness::share(
            non_null
                .iter()
                .filter(|c| c.snr.is_some_and(|s| s >= 4.0))
                .map(|c| c.correct),
        ),
        cases_snr_ge_4: non_null
            .iter()
            .filter(|c| c.snr.is_some_and(|s| s >= 4.0))
            .count(),
        identifiable_top1_attribution_snr_ge_4: harness::share(
            non_null
                .iter()
                .filter(|c| c.snr.is_some_and(|s| s >= 4.0) && identifiable(c))
                .map(|c| c.correct),
        ),
        identifiable_cases_snr_ge_4: non_null
            .iter()
            .filter(|c| c.snr.is_some_and(|s| s >= 4.0) && identifiable(c))
            .count(),
        shares_out_of_range: results.iter().map(|c| c.shares_out_of_range).sum(),
        localisation_accuracy: if loc.is_empty() {
            None
        } else {
            Some(harness::share(loc.iter().cloned()))
        },
        localisation_cases: loc.len(),
        median_param_rel_error: if pe.is_empty() {
            None
        } else {
            Some(stats::median(&mut pe))
        },
        median_contribution_r2: if r2.is_empty() {
            None
        } else {
            Some(stats::median(&mut r2))
        },
        median_shrink_ratio_to_oracle: stats::median(&mut ratios),
        median_seconds: stats::median(&mut secs),
        max_seconds,
        labels,
        confusion,
        case_results: results,
    }
}

/// Runs every case, calling `progress` after each.
pub fn validate(
    opts: &ValidateOptions,
    mut progress: impl FnMut(&CaseResult),
) -> Result<Summary, String> {
    let results = harness::run_cases(opts.cases, |i| run_case(opts, i), &mut progress)?;
    Ok(summarise(opts, results))
}

impl Summary {
    /// Markdown tables (per SNR, overall figures, confusion matrix).
    pub fn to_markdown(&self) -> String {
        let mut s = String::new();
        s.push_str(&format!(
            "Withheld-effect validation, {} harness: {} cases ({} null), {} rows each, noise σ {} µm, seed {}.\n\n",
            self.harness.name(),
            self.cases, self.null_cases, self.rows_per_case, self.noise_um, self.seed
        ));
        s.push_str("| SNR | cases | detection | top-1 attribution | median shrink / oracle | identifiable cases (oracle shrink ≥ 5 %, the verdict rule's floor) | top-1 on those |\n|---|---|---|---|---|---|---|\n");
        for r in &self.per_snr {
            s.push_str(&format!(
                "| {} | {} | {:.1} % | {:.1} % | {:.2} | {} | {:.1} % |\n",
                r.snr,
                r.cases,
                100.0 * r.detection_rate,
                100.0 * r.top1_attribution,
                r.median_shrink_ratio_to_oracle,
                r.identifiable_cases,
                100.0 * r.identifiable_top1_attribution
            ));
        }
        let opt = |v: Option<f64>, pct: bool| match v {
            Some(x) if pct => format!("{:.1} %", 100.0 * x),
            Some(x) => format!("{x:.3}"),
            None => "–".into(),
        };
        s.push_str(&format!(
            "\n| figure | value |\n|---|---|\n| false alarms on nulls | {:.1} % ({} cases) |\n| detection (all SNR) | {:.1} % |\n| top-1 attribution (all SNR) | {:.1} % |\n| top-1 attribution at SNR ≥ 4 | {:.1} % ({} cases) |\n| top-1 at SNR ≥ 4, identifiable cases | {:.1} % ({} cases) |\n| shares outside 0–100 % | {} |\n| localisation (end_effect, {} cases) | {} |\n| median relative error of the searched parameter | {} |\n| median corr² fitted vs true contribution | {} |\n| median held-out shrink / oracle | {:.2} |\n| diagnosis time per case (median / max) | {:.3} s / {:.3} s |\n",
            100.0 * self.false_alarm_rate,
            self.null_cases,
            100.0 * self.detection_rate,
            100.0 * self.top1_attribution,
            100.0 * self.top1_attribution_snr_ge_4,
            self.cases_snr_ge_4,
            100.0 * self.identifiable_top1_attribution_snr_ge_4,
            self.identifiable_cases_snr_ge_4,
            self.shares_out_of_range,
            self.localisation_cases,
            opt(self.localisation_accuracy, true),
            opt(self.median_param_rel_error, false),
            opt(self.median_contribution_r2, false),
            self.median_shrink_ratio_to_oracle,
            self.median_seconds,
            self.max_seconds
        ));
        s.push_str("\nConfusion matrix (rows: withheld, columns: verdict; only non-empty rows/columns):\n\n");
        let mut columns = self.labels.clone();
        columns.push("other".into());
        let rows: Vec<(String, &[usize])> = self
            .labels
            .iter()
            .cloned()
            .zip(self.confusion.iter().map(Vec::as_slice))
            .collect();
        s.push_str(&harness::counts_markdown(
            "withheld \\ verdict",
            &columns,
            &rows,
            true,
        ));
        s
    }
}
