//! Row quality of a thermal campaign: single-sample glitches and stopped measurements, reported before the
//! fit (the fit itself does not drop them).
//!
//! Glossary:
//! - **glitch**: one sample that jumps away from both neighbours of its run and back (a spike): its
//!   departure from the neighbours' mean exceeds 10 robust standard deviations of such departures and 5 % of
//!   the column's range, and both steps have opposite signs.
//! - **stopped measurement**: the target holds exactly the same value for at least 10 rows and 10 minutes
//!   of a run while a sensor moves by 0.5 K or more (a displacement reading frozen while the machine is
//!   stopped).

use serde::Serialize;

use crate::runs::RunIndex;

/// Glitches of one column.
#[derive(Debug, Clone, Serialize)]
pub struct Glitches {
    pub column: String,
    /// Data rows (1-based, after `--where`) of the glitches.
    pub rows: Vec<usize>,
}

/// A stretch where the target holds still while temperatures move.
#[derive(Debug, Clone, Serialize)]
pub struct Stopped {
    pub run: String,
    /// First and last data row (1-based).
    pub from_row: usize,
    pub to_row: usize,
    pub duration_s: f64,
    /// Largest sensor change over the stretch (K).
    pub sensor_change_k: f64,
}

fn glitch_rows(values: &[f64], runs: &RunIndex) -> Vec<usize> {
    let mut dev = vec![];
    for rows in &runs.rows {
        for w in rows.windows(3) {
            dev.push(values[w[1]] - 0.5 * (values[w[0]] + values[w[2]]));
        }
    }
    if dev.is_empty() {
        return vec![];
    }
    let mut abs: Vec<f64> = dev.iter().map(|d| d.abs()).collect();
    let mad = axcomp_numeric::stats::upper_median(&mut abs);
    let lo = values.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = values.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let limit = (10.0 * 1.4826 * mad).max(0.05 * (hi - lo));
    let mut out = vec![];
    for rows in &runs.rows {
        for w in rows.windows(3) {
            let (a, b, c) = (values[w[0]], values[w[1]], values[w[2]]);
            let d = b - 0.5 * (a + c);
            if limit > 0.0
                && d.abs() > limit
                && (b - a).abs() > limit
                && (c - b).abs() > limit
                && (b - a) * (c - b) < 0.0
            {
                out.push(w[1] + 1);
            }
        }
    }
    out
}

/// Glitches per column (columns without any are left out).
pub fn glitches(columns: &[(&str, &[f64])], runs: &RunIndex) -> Vec<Glitches> {
    columns
        .iter()
        .filter_map(|(name, v)| {
            let rows = glitch_rows(v, runs);
            (!rows.is_empty()).then(|| Glitches {
                column: name.to_string(),
                rows,
            })
        })
        .collect()
}

/// Stretches of each run where the target holds still while a sensor moves (see the module docs).
pub fn stopped(
    target: &[f64],
    sensors: &[&[f64]],
    time_s: &[f64],
    runs: &RunIndex,
) -> Vec<Stopped> {
    let mut out = vec![];
    for (r, rows) in runs.rows.iter().enumerate() {
        let mut k = 0;
        while k < rows.len() {
            let mut e = k;
            while e + 1 < rows.len() && target[rows[e + 1]] == target[rows[k]] {
                e += 1;
            }
            let (a, b) = (rows[k], rows[e]);
            let duration = time_s[b] - time_s[a];
            if e - k + 1 >= 10 && duration >= 600.0 {
                let change = sensors
                    .iter()
                    .map(|s| {
                        let seg = rows[k..=e].iter().map(|&i| s[i]);
                        let (lo, hi) = seg.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                            (l.min(v), h.max(v))
                        });
                        hi - lo
                    })
                    .fold(0.0, f64::max);
                if change >= 0.5 {
                    out.push(Stopped {
                        run: runs.names[r].clone(),
                        from_row: a + 1,
                        to_row: b + 1,
                        duration_s: duration,
                        sensor_change_k: change,
                    });
                }
            }
            k = e + 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spike_is_a_glitch_and_a_frozen_target_under_moving_sensors_is_stopped() {
        // Reference: a constructed series, a 100 µm spike at row 6 of a ramp; the target frozen over rows
        // 11–25 (15 rows, 60 s apart) while the sensor rises 0.1 K a row.
        let n = 30;
        let t: Vec<f64> = (0..n).map(|i| 60.0 * i as f64).collect();
        let mut y: Vec<f64> = (0..n).map(|i| 0.3 * i as f64).collect();
        y[5] = 100.0;
        for v in y.iter_mut().take(25).skip(10) {
            *v = 3.0;
        }
        let s: Vec<f64> = (0..n).map(|i| 20.0 + 0.1 * i as f64).collect();
        let runs = RunIndex::new(None, n);
        let g = glitches(&[("y_um", &y)], &runs);
        assert_eq!(g.len(), 1);
        assert_eq!(g[0].rows, vec![6]);
        let st = stopped(&y, &[&s], &t, &runs);
        assert_eq!(st.len(), 1, "{st:?}");
        assert_eq!((st[0].from_row, st[0].to_row), (11, 25));
        assert!((st[0].sensor_change_k - 1.4).abs() < 1e-9);
    }
}
