//! Evidence reported next to the verdict, never deciding it: blocked cross-validation of each candidate
//! passing the training test, and stability selection (its share of block-bootstrap resamples in which it
//! has the best training ΔBIC).

use super::fitting::{Progress, rss_on, with_extra};
use super::types::{Campaign, Candidate, CandidateFamily};
use crate::lsq;

/// Block-bootstrap resamples of the stability selection.
const BOOTSTRAP_RESAMPLES: usize = 20;

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

/// Fills `cv_rms_before_um` / `cv_rms_after_um` (≥ 3 blocks) and `inclusion_probability` (≥ 2 blocks)
/// of the candidates passing the training test at `alpha`.
pub(super) fn add_evidence(
    effects: &mut [Candidate],
    candidates: &[CandidateFamily],
    c: &Campaign,
    alpha: f64,
    progress: &Progress,
) {
    let passing: Vec<usize> = (0..effects.len())
        .filter(|&k| effects[k].train_p_value < alpha)
        .collect();
    if passing.is_empty() {
        return;
    }
    if c.blocks.len() >= 3 {
        blocked_cv(effects, candidates, c, &passing, progress);
    }
    if c.blocks.len() >= 2 {
        stability(effects, candidates, c, &passing, progress);
    }
}

fn blocked_cv(
    effects: &mut [Candidate],
    candidates: &[CandidateFamily],
    c: &Campaign,
    passing: &[usize],
    progress: &Progress,
) {
    let (blocks, y, base_cols) = (&c.blocks, c.y, &c.base_columns);
    let n_tr = c.train.len();
    progress.step(|| format!("blocked CV over {} training blocks", blocks.len()));
    let cv0 = blocked_cv_rss(base_cols, y, blocks);
    for (done, &k) in passing.iter().enumerate() {
        progress.step(|| {
            format!(
                "blocked CV: candidate {} of {} ({})",
                done + 1,
                passing.len(),
                effects[k].kind
            )
        });
        let e = &mut effects[k];
        let v_cols = candidates[e.family_index].variants[e.variant_index].columns();
        e.cv_rms_before_um = Some((cv0 / n_tr as f64).sqrt());
        e.cv_rms_after_um =
            Some((blocked_cv_rss(&with_extra(base_cols, &v_cols), y, blocks) / n_tr as f64).sqrt());
    }
}

fn stability(
    effects: &mut [Candidate],
    candidates: &[CandidateFamily],
    c: &Campaign,
    passing: &[usize],
    progress: &Progress,
) {
    let (blocks, y, base_cols) = (&c.blocks, c.y, &c.base_columns);
    let n_tr = c.train.len();
    let b_count = BOOTSTRAP_RESAMPLES;
    progress.step(|| format!("block bootstrap ({b_count} resamples)"));
    let r0: Vec<f64> = (0..b_count)
        .map(|b| rss_on(base_cols, y, &bootstrap_rows(blocks, b, n_tr)))
        .collect();
    // dbic[k][b]: training ΔBIC of candidate k on resample b (one candidate's columns at a time).
    let mut dbic = vec![vec![f64::NEG_INFINITY; b_count]; effects.len()];
    for (done, &k) in passing.iter().enumerate() {
        let e = &effects[k];
        progress.step(|| {
            format!(
                "block bootstrap: candidate {} of {} ({}, {b_count} resamples)",
                done + 1,
                passing.len(),
                e.kind
            )
        });
        let v_cols = candidates[e.family_index].variants[e.variant_index].columns();
        let cols = with_extra(base_cols, &v_cols);
        for b in 0..b_count {
            let rows = bootstrap_rows(blocks, b, n_tr);
            let nb = rows.len() as f64;
            let r1 = rss_on(&cols, y, &rows);
            if r0[b] > 0.0 && r1 > 0.0 {
                dbic[k][b] = nb * (r0[b] / r1).ln() - e.n_params as f64 * nb.ln();
            }
        }
    }
    let mut wins = vec![0usize; effects.len()];
    #[allow(clippy::needless_range_loop)] // parallel arrays indexed together
    for b in 0..b_count {
        let mut best = (usize::MAX, 0.0f64);
        for &k in passing {
            if dbic[k][b] > best.1 {
                best = (k, dbic[k][b]);
            }
        }
        if best.0 != usize::MAX {
            wins[best.0] += 1;
        }
    }
    for (e, w) in effects.iter_mut().zip(wins) {
        e.inclusion_probability = w as f64 / b_count as f64;
    }
}
