//! The thresholds of the verdict rule, the rule in words, and the materiality tests (whole held-out set
//! and the rows where a localised candidate acts).

use super::fitting::ss;
use super::types::LocalGain;

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
pub const VERDICT_HELP: &str = "Verdict rule (also in the JSON as `verdict_rule`, with per candidate `material`, `holdout_gain_um`, `noise_um`): a candidate explains the gap when (1) the refit of the whole model with it passes the training F-test at alpha = 0.01, Bonferroni-corrected over every searched variant, and (2) its held-out improvement is material: the held-out RMS falls by at least 5 % of the gap and by at least 0.05 σ (σ: the refit's training residual standard deviation). Neither threshold depends on the number of held-out rows. A candidate acting on at most half of the held-out rows (where its fitted contribution reaches 25 % of its peak; at least 20 rows) is also material when, on those rows, the held-out RMS falls by at least 20 % and by at least 0.25 σ (a localised effect such as an end decay cannot move the RMS of the whole campaign by 5 %). Ties are resolved by held-out evidence: the lowest held-out RMS leads; a simpler candidate (a physical input before the sensor-free time_drift, then fewer parameters, then thermal_drift before thermal_lag) is preferred unless the leader beats it on the held-out rows significantly (paired t ≥ 2) and either by a margin (the simpler one removes < 90 % of the held-out squared gap the leader removes) or with positive evidence (held-out ΔBIC ≥ 2). `where` shares are fractions 0..1 of the held-out gap (the console prints them in %).";

/// Whether a held-out RMS reduction `gain_um` is material next to the gap `gap_um` and the noise `sigma_um`.
pub fn is_material(gain_um: f64, gap_um: f64, sigma_um: f64) -> bool {
    gain_um >= MIN_SHRINK_PCT / 100.0 * gap_um && gain_um >= MIN_NOISE_FRACTION * sigma_um
}

/// The held-out gain where a candidate acts, if it is localised (see [`LocalGain`](super::types::LocalGain)).
pub(super) fn local_gain(
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
    if peak.is_nan() || peak <= 0.0 {
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
