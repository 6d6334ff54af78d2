//! The do-no-harm guard: a table is written only when it clearly helps on data it was not fitted on.
//!
//! Glossary:
//! - *raw RMS*: RMS of the measured deviations (what the axis does without compensation).
//! - *judged RMS*: RMS of deviation − prediction, where each prediction comes from a model that did not see
//!   that row (cross-validated or held-out).
//! - *paired check*: the same comparison within each run (fold) separately; a table that helps on average
//!   but harms several runs (drift, slip, a bad reference) is not trusted.
//!
//! Rule (both must hold):
//! 1. judged RMS ≤ `improvement_ratio` × raw RMS (default 0.8: at least 20 % better);
//! 2. in at least `runs_improved_fraction` of the runs (default 80 %), the run's judged RMS is below its raw RMS.

use serde::Serialize;

pub const DEFAULT_IMPROVEMENT_RATIO: f64 = 0.8;
pub const DEFAULT_RUNS_IMPROVED_FRACTION: f64 = 0.8;

/// Verdict of the guard, with the figures behind it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GuardVerdict {
    /// True when a table may be written.
    pub passed: bool,
    /// The rule applied, in words.
    pub rule: String,
    pub raw_rms_um: f64,
    pub judged_rms_um: f64,
    /// judged / raw.
    pub ratio: f64,
    pub runs: usize,
    pub runs_improved: usize,
    /// Why the guard refused (empty when passed).
    pub reasons: Vec<String>,
}

/// Judges predictions against the raw deviations. `fold[i]` is row i's run/fold index; `basis` names how
/// the predictions were obtained (e.g. `leave-one-run-out`, `holdout`).
pub fn judge(
    deviation: &[f64],
    predicted: &[f64],
    fold: &[usize],
    improvement_ratio: f64,
    runs_improved_fraction: f64,
    basis: &str,
) -> GuardVerdict {
    let n = deviation.len().min(predicted.len()).min(fold.len());
    let (mut raw, mut res) = (0.0, 0.0);
    let folds = fold.iter().take(n).copied().max().map_or(0, |m| m + 1);
    let mut per = vec![(0.0f64, 0.0f64, 0usize); folds];
    for i in 0..n {
        let r = deviation[i] - predicted[i];
        raw += deviation[i] * deviation[i];
        res += r * r;
        let p = &mut per[fold[i]];
        p.0 += deviation[i] * deviation[i];
        p.1 += r * r;
        p.2 += 1;
    }
    let raw_rms = (raw / n.max(1) as f64).sqrt();
    let judged = (res / n.max(1) as f64).sqrt();
    let ratio = if raw_rms > 0.0 {
        judged / raw_rms
    } else {
        f64::INFINITY
    };
    let used: Vec<_> = per.iter().filter(|p| p.2 > 0).collect();
    let runs = used.len();
    let runs_improved = used.iter().filter(|p| p.1 < p.0).count();
    let need = (runs_improved_fraction * runs as f64).ceil() as usize;
    let mut reasons = Vec::new();
    if n == 0 {
        reasons.push("no rows to judge the model on".to_string());
    }
    if !(ratio <= improvement_ratio) {
        reasons.push(format!(
            "{basis} RMS {judged:.3} µm is not clearly below the raw RMS {raw_rms:.3} µm (ratio {ratio:.3} > {improvement_ratio})"
        ));
    }
    if runs_improved < need {
        reasons.push(format!(
            "the model improves only {runs_improved} of {runs} runs/folds on their own held-out rows (need {need}): \
             run-to-run drift or scatter dominates the systematic error"
        ));
    }
    GuardVerdict {
        passed: reasons.is_empty(),
        rule: format!(
            "{basis} RMS ≤ {improvement_ratio} × raw RMS, and improvement in ≥ {:.0} % of the runs",
            100.0 * runs_improved_fraction
        ),
        raw_rms_um: raw_rms,
        judged_rms_um: judged,
        ratio,
        runs,
        runs_improved,
        reasons,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_a_clear_improvement_and_refuses_harm() {
        let dev = [10.0, -10.0, 12.0, -8.0, 9.0, -11.0];
        let fold = [0, 0, 1, 1, 2, 2];
        let good = [9.0, -9.5, 11.0, -8.5, 9.5, -10.0];
        let v = judge(&dev, &good, &fold, 0.8, 0.8, "cv");
        assert!(v.passed, "{v:?}");
        assert_eq!(v.runs_improved, 3);
        let bad = [0.0; 6].map(|_: f64| 20.0);
        let v = judge(&dev, &bad, &fold, 0.8, 0.8, "cv");
        assert!(!v.passed);
        assert!(v.reasons[0].contains("not clearly below"));
    }

    #[test]
    fn refuses_when_one_run_is_harmed() {
        // Overall 4× better, but run 2 is made worse: the paired check refuses (need 3 of 3 at 80 %).
        let dev = [10.0, -10.0, 10.0, -10.0, 1.0, -1.0];
        let pred = [10.0, -10.0, 10.0, -10.0, 3.0, -3.0];
        let fold = [0, 0, 1, 1, 2, 2];
        let v = judge(&dev, &pred, &fold, 0.8, 0.8, "cv");
        assert!(v.ratio < 0.8);
        assert!(!v.passed);
        assert_eq!(v.runs_improved, 2);
    }
}
