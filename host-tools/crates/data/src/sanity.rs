//! Plausibility checks on measurement data, run before anything is fitted.
//!
//! Terms:
//! - *warning*: a finding that may be a data error but may also be real (an outlier, mixed units); commands
//!   print it on stderr, list it in their JSON (`warnings`) and, with `--strict`, refuse the data (exit 2);
//! - *several campaigns*: a `test_id` or `axis` column holding more than one value after `--where`; fitting
//!   one model to several axes or tests is never what was meant, so it is an error
//!   ([`DataError::SeveralValues`]) naming the values;
//! - *per-target outlier*: a value far from the other values measured at the same target and direction:
//!   |x − median of its group| > [`OUTLIER_K`] · s, with s = 1.4826 · the median absolute deviation of every
//!   value from its group's median, pooled over all groups of ≥ 3 values (a robust σ that one wild value
//!   cannot inflate); groups of fewer than 3 values are not judged;
//! - *unit mix*: the magnitudes |x| of a column fall into two clusters at least [`UNIT_GAP_DECADES`] decades
//!   apart (a gap with no value in it), each holding ≥ 5 % and ≥ 3 of the non-zero values — e.g. half the
//!   rows in mm in a µm column. Genuine data near zero does not do this: values crossing zero fill the
//!   small magnitudes continuously.

use serde::Serialize;

use crate::{DataError, Dataset};

/// Outlier threshold in robust standard deviations.
pub const OUTLIER_K: f64 = 6.0;

/// Minimum empty gap, in decades of |x|, between the two magnitude clusters of a unit mix.
pub const UNIT_GAP_DECADES: f64 = 2.0;

/// One plausibility finding.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DataWarning {
    /// `outlier`, `unit_mix`, `unit`, `implausible_magnitude` or `machine_kind`.
    pub kind: &'static str,
    /// The column concerned.
    pub column: String,
    /// For the user: what, where, and what to check.
    pub message: String,
    /// File lines of the rows concerned (at most 20 listed).
    pub lines: Vec<usize>,
}

/// Fails when any of `cols` holds more than one distinct value, listing them (at most 12).
pub fn single_campaign(ds: &Dataset, cols: &[&str]) -> Result<(), DataError> {
    for &col in cols {
        if !ds.has(col) {
            continue;
        }
        let text = ds.text(col)?;
        let mut values: Vec<&str> = Vec::new();
        for t in text {
            let t = t.trim();
            if !values.contains(&t) {
                values.push(t);
            }
        }
        if values.len() > 1 {
            let n = values.len();
            let mut list: Vec<String> = values.iter().take(12).map(|v| format!("`{v}`")).collect();
            if n > 12 {
                list.push(format!("… ({} more)", n - 12));
            }
            return Err(DataError::SeveralValues {
                file: ds.source().to_string(),
                column: col.to_string(),
                count: n,
                values: list.join(", "),
                example: values[0].to_string(),
            });
        }
    }
    Ok(())
}

use axcomp_numeric::stats::median;

/// Per-target outliers of `values` (see the module docs); `target` and `direction` give the groups.
/// `ds` is only used to name file lines. `None` when nothing is flagged.
pub fn per_target_outliers(
    ds: &Dataset,
    column: &str,
    values: &[f64],
    target: &[f64],
    direction: &[i8],
) -> Option<DataWarning> {
    let n = values.len();
    let groups = target_groups(values, target, direction);
    let mut resid = vec![f64::NAN; n];
    let mut pooled = Vec::new();
    for g in groups.iter().filter(|g| g.len() >= 3) {
        let mut v: Vec<f64> = g.iter().map(|&i| values[i]).collect();
        let m = median(&mut v);
        for &i in g {
            resid[i] = values[i] - m;
            pooled.push((values[i] - m).abs());
        }
    }
    if pooled.len() < 6 {
        return None;
    }
    let s = 1.4826 * median(&mut pooled);
    if s.is_nan() || s <= 0.0 {
        return None;
    }
    let flagged: Vec<usize> = (0..n).filter(|&i| resid[i].abs() > OUTLIER_K * s).collect();
    if flagged.is_empty() {
        return None;
    }
    let show: Vec<String> = flagged
        .iter()
        .take(5)
        .map(|&i| {
            format!(
                "line {} ({} at {} mm {}: {:.4} vs median {:.4})",
                ds.line_of_row(i),
                column,
                target[i],
                if direction[i] < 0 { "↓" } else { "↑" },
                values[i],
                values[i] - resid[i]
            )
        })
        .collect();
    Some(DataWarning {
        kind: "outlier",
        column: column.to_string(),
        message: format!(
            "{}: {} value(s) of `{column}` lie more than {OUTLIER_K} robust σ (σ = {s:.4}) from the other values \
             at the same target and direction: {}{} — a typo (e.g. ×10) or a bad reading? They are kept in the fit",
            ds.source(),
            flagged.len(),
            show.join("; "),
            if flagged.len() > 5 { "; …" } else { "" }
        ),
        lines: flagged
            .iter()
            .take(20)
            .map(|&i| ds.line_of_row(i))
            .collect(),
    })
}

/// Groups of row indices with the same direction and target (within 1e-6 mm), sorted.
fn target_groups(values: &[f64], target: &[f64], direction: &[i8]) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..values.len())
        .filter(|&i| values[i].is_finite())
        .collect();
    order.sort_by(|&a, &b| {
        direction[a]
            .cmp(&direction[b])
            .then(target[a].total_cmp(&target[b]))
    });
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for &i in &order {
        match groups.last_mut() {
            Some(g)
                if direction[g[0]] == direction[i] && (target[i] - target[g[0]]).abs() <= 1e-6 =>
            {
                g.push(i)
            }
            _ => groups.push(vec![i]),
        }
    }
    groups
}

/// The largest gap (decades) in the sorted log-magnitudes `mags` with at least `min_side` values on each
/// side, and its position.
fn largest_gap(mags: &[(f64, usize)], min_side: usize) -> (f64, usize) {
    let (mut best, mut at) = (0.0, 0);
    if mags.len() < 2 * min_side {
        return (best, at);
    }
    for k in min_side..=(mags.len() - min_side) {
        let gap = mags[k].0 - mags[k - 1].0;
        if gap > best {
            best = gap;
            at = k;
        }
    }
    (best, at)
}

fn log_mags(values: &[f64], rows: impl Iterator<Item = usize>) -> Vec<(f64, usize)> {
    let mut m: Vec<(f64, usize)> = rows
        .filter(|&i| values[i].is_finite() && values[i] != 0.0)
        .map(|i| (values[i].abs().log10(), i))
        .collect();
    m.sort_by(|a, b| a.0.total_cmp(&b.0));
    m
}

/// Unit mix in `values` (see the module docs). With `groups` (target and direction per row) the test runs
/// per target: a target whose values split into two magnitude clusters ≥ [`UNIT_GAP_DECADES`] apart is
/// *split*, and a mix is reported when at least a quarter of the targets (and 2) are split — a clean
/// target only splits when its values straddle zero. Without groups (or no target measured twice) the
/// magnitudes of the whole column are tested, each cluster holding ≥ 5 % and ≥ 3 values.
/// `None` when nothing looks mixed.
pub fn unit_mix(
    ds: &Dataset,
    column: &str,
    values: &[f64],
    groups: Option<(&[f64], &[i8])>,
) -> Option<DataWarning> {
    // (rows of the smaller side, rows of the larger side, ratio of their mean magnitudes)
    let mut small_rows: Vec<usize> = Vec::new();
    let mut large_rows: Vec<usize> = Vec::new();
    let mut log_ratios: Vec<f64> = Vec::new();
    let repeated: Vec<Vec<usize>> = match groups {
        Some((t, d)) => target_groups(values, t, d)
            .into_iter()
            .filter(|g| g.len() >= 2)
            .collect(),
        None => Vec::new(),
    };
    let mean = |s: &[(f64, usize)]| s.iter().map(|m| m.0).sum::<f64>() / s.len() as f64;
    if !repeated.is_empty() {
        let mut split = 0;
        for g in &repeated {
            let mags = log_mags(values, g.iter().copied());
            let (gap, at) = largest_gap(&mags, 1);
            if gap >= UNIT_GAP_DECADES {
                split += 1;
                small_rows.extend(mags[..at].iter().map(|m| m.1));
                large_rows.extend(mags[at..].iter().map(|m| m.1));
                log_ratios.push(mean(&mags[at..]) - mean(&mags[..at]));
            }
        }
        if split < 2 || 4 * split < repeated.len() {
            return None;
        }
    } else {
        let mags = log_mags(values, 0..values.len());
        let min_side = 3.max((0.05 * mags.len() as f64).ceil() as usize);
        let (gap, at) = largest_gap(&mags, min_side);
        if gap < UNIT_GAP_DECADES {
            return None;
        }
        small_rows.extend(mags[..at].iter().map(|m| m.1));
        large_rows.extend(mags[at..].iter().map(|m| m.1));
        log_ratios.push(mean(&mags[at..]) - mean(&mags[..at]));
    }
    let ratio = 10f64.powf(axcomp_numeric::stats::upper_median(&mut log_ratios));
    let smaller_is_minority = small_rows.len() <= large_rows.len();
    let minority = if smaller_is_minority {
        &small_rows
    } else {
        &large_rows
    };
    let mut lines: Vec<usize> = minority.iter().map(|&i| ds.line_of_row(i)).collect();
    lines.sort_unstable();
    let hint = if (300.0..3000.0).contains(&ratio) {
        " (×1000: mm mixed with µm?)"
    } else if (3e5..3e6).contains(&ratio) {
        " (×10⁶: m mixed with µm?)"
    } else {
        ""
    };
    Some(DataWarning {
        kind: "unit_mix",
        column: column.to_string(),
        message: format!(
            "{}: `{column}` looks like two units: {} value(s) are about {ratio:.0}× smaller than {} others \
             measured at the same targets{hint}; first lines of the {} group: {}",
            ds.source(),
            small_rows.len(),
            large_rows.len(),
            if smaller_is_minority {
                "smaller"
            } else {
                "larger"
            },
            lines
                .iter()
                .take(8)
                .map(|l| l.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
        lines: lines.into_iter().take(20).collect(),
    })
}

/// A column whose typical magnitude is implausible for its unit: the median |x| above `max_typical`.
pub fn implausible_magnitude(
    ds: &Dataset,
    column: &str,
    values: &[f64],
    max_typical: f64,
    why: &str,
) -> Option<DataWarning> {
    let mut m: Vec<f64> = values
        .iter()
        .filter(|v| v.is_finite())
        .map(|v| v.abs())
        .collect();
    if m.is_empty() {
        return None;
    }
    let med = median(&mut m);
    (med > max_typical).then(|| DataWarning {
        kind: "implausible_magnitude",
        column: column.to_string(),
        message: format!(
            "{}: the median |{column}| is {med:.4}, more than {max_typical} — {why}",
            ds.source()
        ),
        lines: Vec::new(),
    })
}

/// Largest magnitude a measured value may have in any unit the tool reads (µm, mm, degrees, mm/min):
/// beyond it (1e300, `inf`) the cell is corrupt, not a measurement.
pub const ABSURD: f64 = 1e12;

/// A finite number below [`ABSURD`] in magnitude.
pub fn plausible_number(v: f64) -> bool {
    v.is_finite() && v.abs() < ABSURD
}

/// Fails at the first cell of `cols` (those `ds` has) that is infinite or at least [`ABSURD`] in
/// magnitude, naming file, line and column. `NaN` and text cells are left to the column's reader.
pub fn absurd_values(ds: &Dataset, cols: &[&str]) -> Result<(), DataError> {
    for &col in cols.iter().filter(|c| ds.has(c)) {
        let v = ds.numeric_or_nan(col)?;
        if let Some(i) = v.iter().position(|x| !x.is_nan() && !plausible_number(*x)) {
            return Err(DataError::Implausible {
                at: ds.locate(col, i),
                value: v[i],
            });
        }
    }
    Ok(())
}

/// Per-point outliers along sequences of rows (the readings of one laser line along the beam, the poses
/// of one R-test path in measuring order): each value's residual r from the median of its up to two
/// neighbours on each side. A value is flagged when |r| > [`OUTLIER_K`] · s (s the robust σ, 1.4826 ·
/// median |r|, pooled over every sequence), |r| exceeds the range its neighbours span, and its adjacent
/// values' residuals are below a quarter of its own: an isolated spike, not a step or a turn of the
/// path. The first and last value of a sequence (neighbours on one side only, where a curved path's
/// trend alone makes a residual) and sequences of fewer than 4 rows are not judged. `None` when
/// nothing is flagged.
pub fn neighbour_outliers(
    ds: &Dataset,
    column: &str,
    values: &[f64],
    sequences: &[Vec<usize>],
) -> Option<DataWarning> {
    // Per sequence: (row, residual, neighbours' median, their range), NaN where not judged.
    let resid: Vec<Vec<(usize, f64, f64, f64)>> = sequences
        .iter()
        .filter(|s| s.len() >= 4)
        .map(|seq| {
            (0..seq.len())
                .map(|k| {
                    let mut near: Vec<f64> = (k.saturating_sub(2)..(k + 3).min(seq.len()))
                        .filter(|&j| j != k)
                        .map(|j| values[seq[j]])
                        .filter(|v| v.is_finite())
                        .collect();
                    let span = near.iter().fold(f64::NEG_INFINITY, |a, v| a.max(*v))
                        - near.iter().fold(f64::INFINITY, |a, v| a.min(*v));
                    let m = if near.len() >= 2 {
                        median(&mut near)
                    } else {
                        f64::NAN
                    };
                    (seq[k], values[seq[k]] - m, m, span)
                })
                .collect()
        })
        .collect();
    let mut pooled: Vec<f64> = resid
        .iter()
        .flatten()
        .map(|r| r.1.abs())
        .filter(|r| r.is_finite())
        .collect();
    if pooled.len() < 8 {
        return None;
    }
    let s = 1.4826 * median(&mut pooled);
    if s.is_nan() || s <= 0.0 {
        return None;
    }
    let isolated = |seq: &[(usize, f64, f64, f64)], k: usize| {
        let r = seq[k].1.abs();
        let quiet = |j: usize| {
            seq.get(j)
                .is_none_or(|n| n.1.is_nan() || n.1.abs() * 4.0 < r)
        };
        let interior = k > 0 && k + 1 < seq.len();
        interior && r > OUTLIER_K * s && r > seq[k].3 && quiet(k - 1) && quiet(k + 1)
    };
    let flagged: Vec<(usize, f64)> = resid
        .iter()
        .flat_map(|seq| {
            (0..seq.len())
                .filter(|&k| isolated(seq, k))
                .map(|k| (seq[k].0, seq[k].2))
        })
        .collect();
    let show: Vec<String> = flagged
        .iter()
        .take(5)
        .map(|&(i, m)| {
            format!(
                "line {} ({column} {:.4} vs its neighbours' {m:.4})",
                ds.line_of_row(i),
                values[i]
            )
        })
        .collect();
    (!flagged.is_empty()).then(|| DataWarning {
        kind: "outlier",
        column: column.to_string(),
        message: format!(
            "{}: {} value(s) of `{column}` lie more than {OUTLIER_K} robust σ (σ = {s:.4}) from their \
             neighbours in measuring order: {}{} — a typo or a bad reading? They are kept in the fit",
            ds.source(),
            flagged.len(),
            show.join("; "),
            if flagged.len() > 5 { "; …" } else { "" }
        ),
        lines: flagged.iter().take(20).map(|r| ds.line_of_row(r.0)).collect(),
    })
}

/// An angle column (degrees) that looks like radians: it varies, and every value lies within ±2π
/// (a rotary campaign in degrees sweeps well beyond 6.3°). `None` otherwise.
pub fn radians_for_degrees(ds: &Dataset, column: &str, values: &[f64]) -> Option<DataWarning> {
    let finite = values.iter().filter(|v| v.is_finite());
    let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(*v), hi.max(*v))
    });
    let limit = std::f64::consts::TAU * 1.001;
    (hi - lo > 0.5 && lo >= -limit && hi <= limit).then(|| DataWarning {
        kind: "unit",
        column: column.to_string(),
        message: format!(
            "{}: `{column}` spans only {lo:.4} … {hi:.4}: degrees expected, these look like radians \
             (convert with --scale {column}=57.29577951308232)",
            ds.source()
        ),
        lines: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::LoadOptions;

    fn campaign(mutate: impl Fn(usize, f64) -> f64) -> (Dataset, Vec<f64>, Vec<f64>, Vec<i8>) {
        let mut s = String::from("target_mm,run,direction,deviation_um\n");
        let mut k = 0;
        for run in 1..=5 {
            for (d, sign) in [("+", 1i8), ("-", -1)] {
                for t in 0..9 {
                    let x = 5.0 * t as f64;
                    // Smooth error + run-to-run scatter (deterministic, ±1 µm).
                    let v = 20.0 * (x / 13.0).sin()
                        + 3.0 * f64::from(sign)
                        + ((k * 37 % 11) as f64 - 5.0) / 5.0;
                    s.push_str(&format!("{x},{run},{d},{}\n", mutate(k, v)));
                    k += 1;
                }
            }
        }
        let ds = Dataset::from_csv_str("c.csv", &s, &LoadOptions::default()).unwrap();
        let v = ds.numeric("deviation_um").unwrap().to_vec();
        let x = ds.numeric("target_mm").unwrap().to_vec();
        let d = ds.direction().unwrap().unwrap();
        (ds, v, x, d)
    }

    #[test]
    fn clean_data_has_no_warning() {
        let (ds, v, x, d) = campaign(|_, v| v);
        assert!(per_target_outliers(&ds, "deviation_um", &v, &x, &d).is_none());
        assert!(unit_mix(&ds, "deviation_um", &v, Some((&x, &d))).is_none());
        assert!(unit_mix(&ds, "deviation_um", &v, None).is_none());
    }

    #[test]
    fn a_value_typed_ten_times_too_large_is_flagged_with_its_line() {
        let (ds, v, x, d) = campaign(|k, v| if k == 20 { v * 10.0 } else { v });
        let w = per_target_outliers(&ds, "deviation_um", &v, &x, &d).expect("flagged");
        assert_eq!(w.lines, vec![22], "{}", w.message); // row 20 → line 22 (header on line 1)
        assert!(w.message.contains("line 22"), "{}", w.message);
    }

    #[test]
    fn half_the_rows_in_mm_is_a_unit_mix() {
        // Runs 3–5 (rows 36..90 of 90) logged in mm: every target holds 2 values in µm and 3 in mm.
        let (ds, v, x, d) = campaign(|k, v| if k >= 36 { v / 1000.0 } else { v });
        let w = unit_mix(&ds, "deviation_um", &v, Some((&x, &d))).expect("flagged");
        assert!(w.message.contains("mm mixed with µm"), "{}", w.message);
        assert_eq!(w.lines[0], 2, "the µm rows are the minority: {}", w.message);
        // Every fourth row in mm.
        let (ds, v, x, d) = campaign(|k, v| if k % 4 == 0 { v / 1000.0 } else { v });
        assert!(unit_mix(&ds, "deviation_um", &v, Some((&x, &d))).is_some());
    }

    /// A smooth line of 20 readings with a little scatter; `spike` replaces one reading.
    fn line(spike: Option<(usize, f64)>) -> (Dataset, Vec<f64>) {
        let mut s = String::from("x_mm,deviation_um\n");
        for k in 0..20 {
            let x = 10.0 * k as f64;
            let mut v = 5.0 * (x / 60.0).sin() + ((k * 7 % 5) as f64 - 2.0) * 0.05;
            if let Some((_, w)) = spike.filter(|s| s.0 == k) {
                v = w;
            }
            s.push_str(&format!("{x},{v}\n"));
        }
        let ds = Dataset::from_csv_str("l.csv", &s, &LoadOptions::default()).unwrap();
        let v = ds.numeric("deviation_um").unwrap().to_vec();
        (ds, v)
    }

    #[test]
    fn a_spike_along_a_line_is_flagged_with_its_line_and_a_smooth_line_is_not() {
        let seq = vec![(0..20).collect::<Vec<usize>>()];
        let (ds, v) = line(None);
        assert!(neighbour_outliers(&ds, "deviation_um", &v, &seq).is_none());
        let (ds, v) = line(Some((9, 5000.0)));
        let w = neighbour_outliers(&ds, "deviation_um", &v, &seq).expect("flagged");
        assert_eq!(w.lines, vec![11], "{}", w.message); // row 9 → line 11
    }

    #[test]
    fn angles_within_two_pi_look_like_radians() {
        let ds = Dataset::from_csv_str("a.csv", "c_deg\n0\n", &LoadOptions::default()).unwrap();
        let radians: Vec<f64> = (0..36).map(|k| f64::from(k) * 10f64.to_radians()).collect();
        let degrees: Vec<f64> = (0..36).map(|k| f64::from(k) * 10.0).collect();
        assert!(radians_for_degrees(&ds, "c_deg", &radians).is_some());
        assert!(radians_for_degrees(&ds, "c_deg", &degrees).is_none());
        assert!(radians_for_degrees(&ds, "c_deg", &[0.0; 5]).is_none());
    }

    #[test]
    fn several_test_ids_are_an_error_listing_them() {
        let ds = Dataset::from_csv_str(
            "f.csv",
            "test_id,axis,target_mm\nA,X,1\nB,X,2\nC,X,3\n",
            &LoadOptions::default(),
        )
        .unwrap();
        let e = single_campaign(&ds, &["test_id", "axis"])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`A`, `B`, `C`") && e.contains("--where test_id=A"),
            "{e}"
        );
        let one = ds.select_rows(&[true, false, false]);
        assert!(single_campaign(&one, &["test_id", "axis"]).is_ok());
    }
}
