//! What every withheld-effect harness shares: the options every harness checks, the case schedule (which
//! case is null, which kind and SNR a non-null case gets), the validate loop, the oracle's held-out RMS,
//! the rates, the per-SNR grouping and the confusion matrix with its Markdown table.
//!
//! A harness ([`crate::axis`], [`crate::lines`], [`crate::rtest`], [`crate::probe`]) keeps what is specific
//! to its data kind: how a case is simulated and diagnosed, its case and summary records (their JSON is
//! the user's) and its own Markdown tables. Its case record implements [`CaseOutcome`], so that the
//! figures every harness reports (false alarms on null cases, top-1, per SNR) are computed once.
//!
//! Glossary: **null case** = a case with nothing withheld (no SNR); **share** = the fraction of `true`
//! among some booleans (NaN when there are none: "no cases" is not "0 %").

use axcomp_diagnose::lsq;

/// What the shared figures need of one diagnosed case.
pub trait CaseOutcome {
    /// The SNR of the withheld effect (`None` for a null case).
    fn snr(&self) -> Option<f64>;
    /// The withheld kind as the confusion matrix labels it (`none` for a null case).
    fn withheld_label(&self) -> &str;
    /// The diagnosis's verdict (`none` when it found nothing).
    fn verdict(&self) -> &str;
    /// The verdict is the withheld kind (`none` on a null case).
    fn correct(&self) -> bool;
    /// Seconds the diagnosis took.
    fn seconds(&self) -> f64;
    /// A null case (nothing withheld).
    fn is_null(&self) -> bool {
        self.snr().is_none()
    }
}

/// Implements [`CaseOutcome`] for a case record with the fields `snr: Option<f64>`, `verdict: String`,
/// `correct: bool`, `seconds: f64` and the `String` field naming the withheld kind for the confusion
/// matrix.
macro_rules! case_outcome {
    ($t:ty, $withheld:ident) => {
        impl $crate::harness::CaseOutcome for $t {
            fn snr(&self) -> Option<f64> {
                self.snr
            }
            fn withheld_label(&self) -> &str {
                &self.$withheld
            }
            fn verdict(&self) -> &str {
                &self.verdict
            }
            fn correct(&self) -> bool {
                self.correct
            }
            fn seconds(&self) -> f64 {
                self.seconds
            }
        }
    };
}
pub(crate) use case_outcome;

/// The checks every harness makes of its settings: `cases` ≥ 1, at least one SNR and every one finite
/// and > 0, noise σ finite and > 0, `null_every` ≥ 2; the messages name the command-line option
/// (`--cases`, `--snr`, `--noise-um`).
pub fn check_common(
    cases: usize,
    snrs: &[f64],
    noise_um: f64,
    null_every: usize,
) -> Result<(), String> {
    if cases == 0 {
        return Err("--cases must be ≥ 1".into());
    }
    if snrs.is_empty() || snrs.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(format!(
            "--snr: every SNR must be a finite number > 0, got {snrs:?}"
        ));
    }
    if !(noise_um.is_finite() && noise_um > 0.0) {
        return Err(format!("--noise-um must be > 0 µm, got {noise_um}"));
    }
    if null_every < 2 {
        return Err("null_every must be ≥ 2".into());
    }
    Ok(())
}

/// What case `index` withholds: every `null_every`-th case is null (`None`); the non-null cases cycle
/// through the `kinds` withheld kinds, then through the SNRs. Returns (kind index, SNR).
pub fn schedule(
    index: usize,
    null_every: usize,
    kinds: usize,
    snrs: &[f64],
) -> Option<(usize, f64)> {
    if index % null_every == null_every - 1 {
        return None;
    }
    // Index among the non-null cases.
    let j = index - index / null_every;
    Some((j % kinds, snrs[(j / kinds) % snrs.len()]))
}

/// Runs cases `0..cases` in order, calling `progress` after each; stops at the first error.
pub fn run_cases<C>(
    cases: usize,
    mut run_case: impl FnMut(usize) -> Result<C, String>,
    mut progress: impl FnMut(&C),
) -> Result<Vec<C>, String> {
    let mut results = Vec::with_capacity(cases);
    for i in 0..cases {
        let r = run_case(i)?;
        progress(&r);
        results.push(r);
    }
    Ok(results)
}

/// Held-out RMS of `y` after the columns `cols` are fitted (least squares) on the `train` rows; NaN when
/// `hold` is empty.
pub fn holdout_rms_after_fit<C: AsRef<[f64]>>(
    cols: &[C],
    y: &[f64],
    train: &[usize],
    hold: &[usize],
) -> f64 {
    let fit = lsq::fit(cols, y, train);
    axcomp_numeric::stats::rms(hold.iter().map(|&i| y[i] - fit.predict(cols, i)))
}

/// Held-out shrink in % (`100·(1 − after/before)`).
pub fn shrink_pct(before: f64, after: f64) -> f64 {
    100.0 * (1.0 - after / before)
}

/// The fraction of `true` (NaN when there is none).
pub fn share(v: impl IntoIterator<Item = bool>) -> f64 {
    scaled_share(v, 1.0)
}

/// The percentage of `true`, `100·k/n` (NaN when there is none).
pub fn pct(v: impl IntoIterator<Item = bool>) -> f64 {
    scaled_share(v, 100.0)
}

/// `scale·k/n` for k `true` among n (NaN when n = 0); `1·k` is exact, so [`share`] is `k/n` to the bit.
fn scaled_share(v: impl IntoIterator<Item = bool>, scale: f64) -> f64 {
    let (mut k, mut n) = (0usize, 0usize);
    for b in v {
        n += 1;
        k += b as usize;
    }
    if n == 0 {
        f64::NAN
    } else {
        scale * k as f64 / n as f64
    }
}

/// Share of null cases with a verdict other than `none`.
pub fn false_alarm_rate<C: CaseOutcome>(results: &[C]) -> f64 {
    share(
        results
            .iter()
            .filter(|c| c.is_null())
            .map(|c| c.verdict() != "none"),
    )
}

/// The distinct SNRs, ascending.
pub fn snr_levels(snrs: impl IntoIterator<Item = f64>) -> Vec<f64> {
    let mut v: Vec<f64> = snrs.into_iter().collect();
    v.sort_by(|a, b| a.total_cmp(b));
    v.dedup();
    v
}

/// The cases at SNR `snr`.
pub fn at_snr<'a, C: CaseOutcome>(
    results: impl IntoIterator<Item = &'a C>,
    snr: f64,
) -> Vec<&'a C> {
    with_snr(results, |s| s == snr)
}

/// The non-null cases at SNR ≥ `min`.
pub fn at_snr_ge<'a, C: CaseOutcome>(
    results: impl IntoIterator<Item = &'a C>,
    min: f64,
) -> Vec<&'a C> {
    with_snr(results, |s| s >= min)
}

fn with_snr<'a, C: CaseOutcome>(
    results: impl IntoIterator<Item = &'a C>,
    keep: impl Fn(f64) -> bool,
) -> Vec<&'a C> {
    results
        .into_iter()
        .filter(|c| c.snr().is_some_and(&keep))
        .collect()
}

/// The diagnosis times and their largest (0 for no cases).
pub fn seconds<C: CaseOutcome>(results: &[C]) -> (Vec<f64>, f64) {
    let secs: Vec<f64> = results.iter().map(|c| c.seconds()).collect();
    let max = secs.iter().cloned().fold(0.0, f64::max);
    (secs, max)
}

/// Where a label that is not in the list is counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unlisted {
    /// An unlisted verdict in an extra last column (`other`), an unlisted truth in the first row.
    OtherColumn,
    /// Both in the first row / column.
    First,
    /// Not counted.
    Skip,
}

/// `counts[withheld][verdict]` over `labels` for the cases.
pub fn confusion<C: CaseOutcome>(
    labels: &[String],
    results: &[C],
    unlisted: Unlisted,
) -> Vec<Vec<usize>> {
    confusion_of_pairs(
        labels,
        results.iter().map(|c| (c.withheld_label(), c.verdict())),
        unlisted,
    )
}

/// `counts[truth][verdict]` over `labels` for the (truth, verdict) pairs.
pub fn confusion_of_pairs<'a>(
    labels: &[String],
    pairs: impl IntoIterator<Item = (&'a str, &'a str)>,
    unlisted: Unlisted,
) -> Vec<Vec<usize>> {
    let n = labels.len();
    let cols = if unlisted == Unlisted::OtherColumn {
        n + 1
    } else {
        n
    };
    let mut counts = vec![vec![0usize; cols]; n];
    let at = |l: &str| labels.iter().position(|x| x == l);
    for (truth, verdict) in pairs {
        let (t, v) = match unlisted {
            Unlisted::OtherColumn => (at(truth).unwrap_or(0), at(verdict).unwrap_or(n)),
            Unlisted::First => (at(truth).unwrap_or(0), at(verdict).unwrap_or(0)),
            Unlisted::Skip => match (at(truth), at(verdict)) {
                (Some(t), Some(v)) => (t, v),
                _ => continue,
            },
        };
        counts[t][v] += 1;
    }
    counts
}

/// A Markdown table of counts: the corner cell, the column names, then one row per (name, counts). With
/// `only_non_empty`, the columns and rows that are all zero are left out.
pub fn counts_markdown(
    corner: &str,
    columns: &[String],
    rows: &[(String, &[usize])],
    only_non_empty: bool,
) -> String {
    let cols: Vec<usize> = (0..columns.len())
        .filter(|&j| !only_non_empty || rows.iter().any(|(_, r)| r[j] > 0))
        .collect();
    let mut s = format!("| {corner} |");
    for &j in &cols {
        s.push_str(&format!(" {} |", columns[j]));
    }
    s.push_str("\n|---|");
    s.push_str(&"---|".repeat(cols.len()));
    s.push('\n');
    for (name, row) in rows {
        if only_non_empty && row.iter().all(|&v| v == 0) {
            continue;
        }
        s.push_str(&format!("| {name} |"));
        for &j in &cols {
            s.push_str(&format!(" {} |", row[j]));
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedule_cycles_kinds_then_snrs_with_every_fourth_null() {
        let snrs = [3.0, 4.0];
        let got: Vec<Option<(usize, f64)>> = (0..8).map(|i| schedule(i, 4, 2, &snrs)).collect();
        assert_eq!(
            got,
            vec![
                Some((0, 3.0)),
                Some((1, 3.0)),
                Some((0, 4.0)),
                None,
                Some((1, 4.0)),
                Some((0, 3.0)),
                Some((1, 3.0)),
                None
            ]
        );
    }

    #[test]
    fn shares_and_percentages() {
        assert!(share(std::iter::empty()).is_nan());
        assert_eq!(share([true, false, false, true]), 0.5);
        assert_eq!(pct([true, false, false]), 100.0 / 3.0);
    }

    #[test]
    fn confusion_places_unlisted_labels_as_asked() {
        let labels: Vec<String> = ["none", "a"].iter().map(|s| s.to_string()).collect();
        let pairs = [("a", "a"), ("none", "b"), ("a", "none")];
        assert_eq!(
            confusion_of_pairs(&labels, pairs, Unlisted::OtherColumn),
            vec![vec![0, 0, 1], vec![1, 1, 0]]
        );
        assert_eq!(
            confusion_of_pairs(&labels, pairs, Unlisted::First),
            vec![vec![1, 0], vec![1, 1]]
        );
        assert_eq!(
            confusion_of_pairs(&labels, pairs, Unlisted::Skip),
            vec![vec![0, 0], vec![1, 1]]
        );
        let rows: Vec<(String, &[usize])> =
            vec![("none".into(), &[0, 0][..]), ("a".into(), &[1, 0][..])];
        assert_eq!(
            counts_markdown("t \\ v", &labels, &rows, true),
            "| t \\ v | none |\n|---|---|\n| a | 1 |\n"
        );
    }
}
