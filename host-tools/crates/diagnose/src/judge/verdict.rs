//! The verdict among the judged candidates: the explaining candidates the leader does not beat on the
//! held-out rows (ties), the simplest of them, the encompassing test that may replace it, and the note
//! saying why (see the module docs of [`super`] and [`super::rule::VERDICT_RULE`]).

use super::fitting::{fit_all, ss, with_extra};
use super::rule::{MIN_NOISE_FRACTION, MIN_SHRINK_PCT, TIE_EVIDENCE, TIE_GAIN_FRACTION};
use super::types::{Candidate, CandidateFamily};
use crate::stats;

/// What the verdict rule decided.
pub(super) struct Verdict {
    pub(super) verdict: String,
    pub(super) ties: Vec<String>,
    pub(super) note: String,
}

/// The numbers of the campaign the decision needs.
pub(super) struct Setting<'a> {
    pub(super) y: &'a [f64],
    pub(super) base_columns: &'a [Vec<f64>],
    pub(super) train: &'a [usize],
    pub(super) hold: &'a [usize],
    /// The base model's held-out sum of squares and RMS.
    pub(super) rss_holdout: f64,
    pub(super) holdout_rms_um: f64,
    pub(super) total_variants: usize,
    pub(super) alpha: f64,
}

/// Orders `effects` (explaining candidates first by held-out RMS, then the rest by score), decides the
/// verdict and moves it to the front.
pub(super) fn decide(
    effects: &mut Vec<Candidate>,
    candidates: &[CandidateFamily],
    s: &Setting,
) -> Verdict {
    effects.sort_by(|a, b| {
        b.explains.cmp(&a.explains).then(if a.explains {
            a.holdout_rms_after_um.total_cmp(&b.holdout_rms_after_um)
        } else {
            b.score.total_cmp(&a.score)
        })
    });
    let n_explain = effects.iter().take_while(|e| e.explains).count();
    if n_explain == 0 {
        return Verdict {
            verdict: "none".to_string(),
            ties: Vec::new(),
            note: note_none(effects, s.alpha),
        };
    }
    let group = tie_group(effects, n_explain, s);
    let family = |k: usize| &candidates[effects[k].family_index];
    // The simplest of the group: not a last resort (the sensor-free `time_drift`) first, then fewest
    // parameters, then the simplicity rank (a special case before its generalisation), then the lowest
    // held-out RMS.
    let simplest = *group
        .iter()
        .min_by(|&&a, &&b| {
            family(a)
                .last_resort
                .cmp(&family(b).last_resort)
                .then(effects[a].n_params.cmp(&effects[b].n_params))
                .then(family(a).simplicity.cmp(&family(b).simplicity))
                .then(a.cmp(&b))
        })
        .expect("the leader is in the group");
    let encompassed = encompassing(effects, candidates, &group, simplest, s);
    let pick = encompassed.as_ref().map_or(simplest, |e| e.0);
    let mut note = note_for(effects, &group, pick, s);
    if let Some((_, p_in, p_out)) = encompassed {
        let simpler = &effects[simplest].kind;
        note = note.replace("; the simpler is preferred", "");
        note = format!(
            "{note}; {} is chosen over the simpler {simpler}: on the training rows its columns add significantly to {simpler}'s refit (p = {p_in:.2e} after Bonferroni) while {simpler}'s add nothing to its own (p = {p_out:.2e}), and it is not worse on the held-out rows",
            effects[pick].kind
        );
    }
    let ties = group
        .iter()
        .filter(|&&j| j != pick && group.len() > 1)
        .map(|&j| effects[j].kind.clone())
        .collect();
    if pick != 0 {
        let c = effects.remove(pick);
        effects.insert(0, c);
    }
    Verdict {
        verdict: effects[0].kind.clone(),
        ties,
        note,
    }
}

/// The leader (index 0, lowest held-out RMS) and every explaining candidate it does not beat: paired t of
/// the held-out squared residuals < 2, or a gain within [`TIE_GAIN_FRACTION`] of the leader's without
/// positive held-out evidence (ΔBIC < [`TIE_EVIDENCE`]).
fn tie_group(effects: &[Candidate], n_explain: usize, s: &Setting) -> Vec<usize> {
    let lead = &effects[0];
    let gain_lead = s.rss_holdout - ss(&lead.residual_after, s.hold);
    (0..n_explain)
        .filter(|&j| {
            if j == 0 {
                return true;
            }
            let d: Vec<f64> = s
                .hold
                .iter()
                .map(|&i| effects[j].residual_after[i].powi(2) - lead.residual_after[i].powi(2))
                .collect();
            let (t, _) = stats::paired_t(&d);
            let gain_j = s.rss_holdout - ss(&effects[j].residual_after, s.hold);
            // Held-out ΔBIC of the leader over j (Kass & Raftery 1995: ≥ 2 is positive evidence).
            let evidence = lead.score - effects[j].score;
            t < 2.0 || (gain_j >= TIE_GAIN_FRACTION * gain_lead && evidence < TIE_EVIDENCE)
        })
        .collect()
}

/// Encompassing test on the training rows: a tied candidate replaces the simpler pick when its columns
/// add significantly to the pick's refit (F-test, Bonferroni over its searched variants) while the
/// pick's columns add nothing significant to its own refit, and it is not worse on the held-out rows
/// (e.g. a time constant the drift cannot mimic, or a trend in time the temperatures do not carry).
/// Returns (the replacing candidate, p of its columns over the pick, p of the pick's over it).
fn encompassing(
    effects: &[Candidate],
    candidates: &[CandidateFamily],
    group: &[usize],
    pick: usize,
    s: &Setting,
) -> Option<(usize, f64, f64)> {
    let family = |k: usize| &candidates[effects[k].family_index];
    let variant_of = |k: usize| &family(k).variants[effects[k].variant_index];
    let n_tr = s.train.len();
    for &j in group {
        if j == pick || effects[j].holdout_rms_after_um > effects[pick].holdout_rms_after_um {
            continue;
        }
        let cp = variant_of(pick).columns();
        let cj = variant_of(j).columns();
        let both: Vec<Vec<f64>> = cp.iter().chain(cj.iter()).cloned().collect();
        let joint = fit_all(&with_extra(s.base_columns, &both), s.y, s.train);
        let rss_pj = ss(&joint.resid, s.train);
        let dof = n_tr.saturating_sub(joint.fit.rank).max(1) as f64;
        let adds = |k: usize, q: usize| {
            let rss_k = ss(&effects[k].residual_after, s.train);
            if q == 0 || rss_pj <= 0.0 || rss_k <= rss_pj {
                return 1.0;
            }
            let f = ((rss_k - rss_pj) / q as f64) / (rss_pj / dof);
            let other = if k == pick { j } else { pick };
            (axcomp_numeric::stats::f_sf(f, q as f64, dof) * family(other).variants.len() as f64)
                .min(1.0)
        };
        // p of j's columns added to the pick's refit, and of the pick's added to j's.
        let p_j_over_pick = adds(pick, cj.len());
        let p_pick_over_j = adds(j, cp.len());
        if p_j_over_pick < s.alpha && p_pick_over_j >= s.alpha {
            return Some((j, p_j_over_pick, p_pick_over_j));
        }
    }
    None
}

/// Why `pick` is the verdict: tied with others (the simpler preferred), or alone beyond noise.
fn note_for(effects: &[Candidate], group: &[usize], pick: usize, s: &Setting) -> String {
    let e = &effects[pick];
    if group.len() > 1 {
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
        format!(
            "{} ({} parameters, held-out RMS {:.3} µm) explains the gap as well as {} (not beaten on the held-out rows with paired t ≥ 2 and either a margin — it removes ≥ {} % of the held-out squared gap the best removes — or held-out ΔBIC ≥ 2); the simpler is preferred",
            e.kind,
            e.n_params,
            e.holdout_rms_after_um,
            others.join(", "),
            100.0 * TIE_GAIN_FRACTION
        )
    } else {
        format!(
            "{} explains the held-out gap beyond noise (train p = {:.2e} after Bonferroni over {} variants; held-out RMS {:.3} → {:.3} µm, shrink {:.1} % ≥ {} %, gain {:.3} µm ≥ {}·σ = {:.3} µm)",
            e.kind,
            e.train_p_value,
            s.total_variants,
            s.holdout_rms_um,
            e.holdout_rms_after_um,
            e.shrink_pct,
            MIN_SHRINK_PCT,
            e.holdout_gain_um,
            MIN_NOISE_FRACTION,
            MIN_NOISE_FRACTION * e.noise_um
        )
    }
}

/// Why the verdict is `none`: the best candidate significant on the training rows is not material, or
/// none passes the training test.
fn note_none(effects: &[Candidate], alpha: f64) -> String {
    match effects.iter().find(|e| e.train_p_value < alpha) {
        Some(c) => format!(
            "no candidate explains the held-out gap beyond noise: the best significant one on the training rows, {}, changes the held-out RMS by {:.1} % ({:.3} µm; material needs ≥ {} % of the gap and ≥ {}·σ = {:.3} µm)",
            c.kind,
            c.shrink_pct,
            c.holdout_gain_um,
            MIN_SHRINK_PCT,
            MIN_NOISE_FRACTION,
            MIN_NOISE_FRACTION * c.noise_um
        ),
        None => {
            "no candidate explains the held-out gap beyond noise (none passes the training test)"
                .into()
        }
    }
}
