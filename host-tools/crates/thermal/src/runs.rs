//! Runs of a thermal campaign: which rows belong to which run, and the per-run reference of the
//! temperatures and of the target.
//!
//! Glossary:
//! - **run**: one recording from a cold machine (e.g. one day), told apart by the `--runs` column. A file
//!   without that column is one run.
//! - **reference reading**: a run's first row. A sensor's **rise** is its (lagged) reading minus the run's
//!   first reading, and the target of a run is zeroed at its first row: exactly what the firmware sees when
//!   it takes its references at switch-on.
//! - **lag restart**: each run's lag state starts in equilibrium with its first reading; inside a run the
//!   lag follows the actual time between rows, so rows left out (`--where`, a stop) are a longer step.

use axcomp_effects::thermal_model::{Series, ThermalModel};
use axcomp_numeric::lag::{alpha, lag};

/// The runs of the rows (file order kept inside each run).
#[derive(Debug, Clone)]
pub struct RunIndex {
    /// Run label, in order of first appearance.
    pub names: Vec<String>,
    /// Rows of each run, in file order.
    pub rows: Vec<Vec<usize>>,
    /// Run of each row.
    pub of_row: Vec<usize>,
    /// True when the rows come from a `--runs` column (per-run references); false for a single recording.
    pub per_run: bool,
}

impl RunIndex {
    /// One run holding every row (`labels` = `None`), or the runs named by `labels`.
    pub fn new(labels: Option<&[String]>, n: usize) -> RunIndex {
        let Some(labels) = labels else {
            return RunIndex {
                names: vec!["all rows".into()],
                rows: vec![(0..n).collect()],
                of_row: vec![0; n],
                per_run: false,
            };
        };
        let mut names: Vec<String> = vec![];
        let mut rows: Vec<Vec<usize>> = vec![];
        let mut of_row = vec![0; n];
        for (i, l) in labels.iter().enumerate() {
            let r = match names.iter().position(|x| x == l) {
                Some(r) => r,
                None => {
                    names.push(l.clone());
                    rows.push(vec![]);
                    names.len() - 1
                }
            };
            rows[r].push(i);
            of_row[i] = r;
        }
        RunIndex {
            names,
            rows,
            of_row,
            per_run: true,
        }
    }

    /// Number of runs.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.rows.iter().all(|r| r.is_empty())
    }

    /// The reference reading of each row: the first value of its run.
    pub fn reference(&self, values: &[f64]) -> Vec<f64> {
        self.of_row
            .iter()
            .map(|&r| values[self.rows[r][0]])
            .collect()
    }

    /// The rise of `values` through a first-order lag of `tau_s`: lagged per run (state restarting at the
    /// run's first row), minus the run's first reading. A single run is the whole file, lagged as
    /// [`axcomp_numeric::lag::lag`] does (restarting where the time does not increase).
    pub fn rise(&self, time_s: &[f64], values: &[f64], tau_s: f64) -> Vec<f64> {
        if !self.per_run {
            let v0 = values.first().copied().unwrap_or(0.0);
            return lag(time_s, values, tau_s)
                .into_iter()
                .map(|v| v - v0)
                .collect();
        }
        let mut out = vec![0.0; values.len()];
        for rows in &self.rows {
            let v0 = values[rows[0]];
            let mut y = v0;
            let mut t_prev = time_s[rows[0]];
            for &i in rows {
                let dt = time_s[i] - t_prev;
                if tau_s <= 0.0 || !(dt > 0.0) {
                    y = if tau_s <= 0.0 { values[i] } else { y };
                } else {
                    y += alpha(dt, tau_s) * (values[i] - y);
                }
                t_prev = time_s[i];
                out[i] = y - v0;
            }
        }
        out
    }

    /// The longest run's duration among the rows `keep` marks (seconds; 0 with no time span).
    pub fn longest_s(&self, time_s: &[f64], keep: &[bool]) -> f64 {
        self.rows
            .iter()
            .map(|rows| {
                let t: Vec<f64> = rows
                    .iter()
                    .filter(|&&i| keep[i])
                    .map(|&i| time_s[i])
                    .collect();
                let lo = t.iter().cloned().fold(f64::INFINITY, f64::min);
                let hi = t.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
                if hi > lo { hi - lo } else { 0.0 }
            })
            .fold(0.0, f64::max)
    }
}

/// Predicts a campaign with a fitted model: each term's rise taken against the model's fixed reference
/// (`runs` = `None`, one recording) or against each run's first reading (`runs`), lagged as the firmware
/// does; on a row where a model sensor's unlagged rise leaves its `bounds` (per term, see the range guard
/// of [`crate::choice`]) that sensor's term is dropped. Returns the predictions and which rows had a
/// term dropped.
pub fn predict_campaign(
    model: &ThermalModel,
    bounds: Option<&[(f64, f64)]>,
    time_s: &[f64],
    sensors: &[Series],
    forces: &[Series],
    runs: Option<&RunIndex>,
) -> Result<(Vec<f64>, Vec<bool>), String> {
    let n = time_s.len();
    let mut out = vec![model.b0_um; n];
    let mut guarded = vec![false; n];
    for (j, t) in model.terms.iter().enumerate() {
        let s = sensors
            .iter()
            .find(|s| s.name == t.sensor)
            .ok_or_else(|| format!("sensor `{}` missing", t.sensor))?;
        let (lagged, raw) = match runs {
            Some(r) => (
                r.rise(time_s, &s.values, t.tau_s),
                r.rise(time_s, &s.values, 0.0),
            ),
            None => (
                lag(time_s, &s.values, t.tau_s)
                    .into_iter()
                    .map(|v| v - t.reference_degc)
                    .collect(),
                s.values
                    .iter()
                    .map(|v| v - t.reference_degc)
                    .collect::<Vec<f64>>(),
            ),
        };
        let (lo, hi) = bounds
            .and_then(|b| b.get(j).copied())
            .unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
        for i in 0..n {
            if raw[i] < lo || raw[i] > hi {
                guarded[i] = true;
            } else {
                out[i] += t.coef_um_per_k * lagged[i];
            }
        }
    }
    for f in &model.forces {
        let s = forces
            .iter()
            .find(|s| s.name == f.column)
            .ok_or_else(|| format!("force column `{}` missing", f.column))?;
        for (o, v) in out.iter_mut().zip(&s.values) {
            *o += f.chi_um_per_n * v;
        }
    }
    Ok((out, guarded))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rises_restart_per_run_and_a_single_run_matches_the_plain_lag() {
        // Reference: the lag's exact discretisation restarted at each run's first row; tolerance 1e-12.
        let t = [0.0, 10.0, 20.0, 0.0, 10.0, 20.0];
        let u = [20.0, 21.0, 22.0, 30.0, 30.0, 33.0];
        let labels: Vec<String> = ["a", "a", "a", "b", "b", "b"].map(String::from).to_vec();
        let runs = RunIndex::new(Some(&labels), 6);
        assert_eq!(runs.len(), 2);
        let r = runs.rise(&t, &u, 0.0);
        assert_eq!(r, vec![0.0, 1.0, 2.0, 0.0, 0.0, 3.0]);
        let lagged = runs.rise(&t, &u, 10.0);
        let a = 1.0 - (-1.0f64).exp();
        let want_b2 = a * 3.0;
        assert!((lagged[5] - want_b2).abs() < 1e-12, "{lagged:?}");
        assert!(lagged[3].abs() < 1e-12 && lagged[4].abs() < 1e-12);
        let one = RunIndex::new(None, 3);
        let plain = lag(&t[..3], &u[..3], 10.0);
        let got = one.rise(&t[..3], &u[..3], 10.0);
        for k in 0..3 {
            assert!((got[k] - (plain[k] - 20.0)).abs() < 1e-12);
        }
    }
}
