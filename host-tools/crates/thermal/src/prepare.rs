//! What the thermal fit prepares before any candidate runs: training rows, runs, usable sensors, the
//! target's reference, the validation groups, the lag grid and the candidate columns.
//!
//! Glossary: see [`crate::thermal`] (rise, reference reading, lag support) and [`crate::choice`] (groups,
//! candidate columns).

use crate::choice::Design;
use crate::runs::RunIndex;
use crate::select::{Candidate, GramSet};
use axcomp_numeric::minimize::golden_min;

use crate::input::{LAG_CAP_FRACTION, ThermalError, ThermalInput, ThermalOptions};

/// What the fit prepares before any candidate runs.
pub(crate) struct Prepared {
    pub(crate) n: usize,
    pub(crate) held: Vec<bool>,
    pub(crate) train_idx: Vec<usize>,
    pub(crate) runs: RunIndex,
    /// Usable sensors (indices into `input.sensors`).
    pub(crate) sens: Vec<usize>,
    pub(crate) excluded: Vec<(String, String)>,
    /// Single recording: the target's reference value; several runs: 0 (each run its own first row).
    pub(crate) target_ref: f64,
    /// The target minus its reference (the raw figures).
    pub(crate) zeroed: Vec<f64>,
    /// What the model fits: the target (one recording, b0 absorbs its offset) or the zeroed target (runs).
    pub(crate) y_fit: Vec<f64>,
    pub(crate) blocks: crate::blocks::Blocks,
    pub(crate) grid: Vec<f64>,
    pub(crate) lag_cap: Vec<f64>,
}

fn usable_sensors(
    input: &ThermalInput,
    train_idx: &[usize],
) -> (Vec<usize>, Vec<(String, String)>) {
    let mut excluded = vec![];
    let mut sens = vec![];
    for (i, s) in input.sensors.iter().enumerate() {
        let v: Vec<f64> = train_idx.iter().map(|&r| s.values[r]).collect();
        if axcomp_numeric::stats::std_dev(&v) <= 1e-9 {
            excluded.push((s.name.clone(), "constant on the training rows".to_string()));
        } else {
            sens.push(i);
        }
    }
    (sens, excluded)
}

/// One validation group per run with training rows (time order = file order of first rows).
fn run_blocks(runs: &RunIndex, held: &[bool], time_s: &[f64]) -> crate::blocks::Blocks {
    let mut group_of_row = vec![None; held.len()];
    let mut names = vec![];
    for (r, rows) in runs.rows.iter().enumerate() {
        let train: Vec<usize> = rows.iter().copied().filter(|&i| !held[i]).collect();
        if train.is_empty() {
            continue;
        }
        for &i in &train {
            group_of_row[i] = Some(names.len());
        }
        let (t0, t1) = (time_s[train[0]], time_s[*train.last().expect("rows")]);
        names.push(format!(
            "run {} ({:.2}–{:.2} h)",
            runs.names[r],
            t0 / 3600.0,
            t1 / 3600.0
        ));
    }
    let k = names.len();
    crate::blocks::Blocks {
        group_of_row,
        rule: format!("{k} training runs (--runs), in file order"),
        order: (0..k).collect(),
        names,
        by_condition: true,
        regimes: k,
    }
}

/// The lag grid: τ = 0 and `lag_grid` values from max(2 sample intervals, L/300) to L/3 (runs) or L/2 (one
/// recording), L = the longest training run.
fn lag_grid(
    input: &ThermalInput,
    runs: &RunIndex,
    held: &[bool],
    opts: &ThermalOptions,
) -> Vec<f64> {
    let keep: Vec<bool> = held.iter().map(|h| !h).collect();
    let longest = runs.longest_s(&input.time_s, &keep);
    let mut dts: Vec<f64> = runs
        .rows
        .iter()
        .flat_map(|rows| {
            rows.windows(2)
                .map(|w| input.time_s[w[1]] - input.time_s[w[0]])
        })
        .filter(|d| *d > 0.0)
        .collect();
    let med_dt = axcomp_numeric::stats::upper_median(&mut dts);
    let mut grid = vec![0.0];
    if opts.lags && longest > 0.0 && med_dt.is_finite() {
        let lo = (2.0 * med_dt).max(longest / 300.0);
        // Several runs: a third of the longest run; one recording: half of it.
        let hi = (longest / if runs.per_run { 3.0 } else { 2.0 }).max(lo * 2.0);
        let m = opts.lag_grid.max(2);
        for k in 0..m {
            grid.push(lo * (hi / lo).powf(k as f64 / (m - 1) as f64));
        }
    }
    grid
}

impl Prepared {
    pub(crate) fn new(
        input: &ThermalInput,
        opts: &ThermalOptions,
    ) -> Result<Prepared, ThermalError> {
        let n = input.time_s.len();
        let held: Vec<bool> = input.holdout.clone().unwrap_or_else(|| vec![false; n]);
        if input.holdout.is_some() && !held.iter().any(|h| *h) {
            return Err(ThermalError::EmptyHoldout);
        }
        let train_idx: Vec<usize> = (0..n).filter(|&i| !held[i]).collect();
        if train_idx.len() < 10 {
            return Err(ThermalError::TooFewRows(train_idx.len()));
        }
        let runs = RunIndex::new(input.runs.as_deref(), n);
        let (sens, excluded) = usable_sensors(input, &train_idx);
        if sens.is_empty() {
            return Err(ThermalError::NoSensors);
        }
        let (target_ref, zeroed, y_fit) = if runs.per_run {
            let r = runs.reference(&input.target);
            let z: Vec<f64> = input.target.iter().zip(&r).map(|(y, r)| y - r).collect();
            (0.0, z.clone(), z)
        } else {
            let k0 = opts.reference_rows.clamp(1, n);
            let t = input.target[..k0].iter().sum::<f64>() / k0 as f64;
            let z = input.target.iter().map(|v| v - t).collect();
            (t, z, input.target.clone())
        };
        let blocks = if runs.per_run {
            run_blocks(&runs, &held, &input.time_s)
        } else {
            let cols: Vec<&[f64]> = sens
                .iter()
                .map(|&i| input.sensors[i].values.as_slice())
                .collect();
            crate::blocks::transfer_blocks(
                &input.time_s,
                &cols,
                input.conditions.as_deref(),
                &train_idx,
                opts.time_blocks,
            )
        };
        let grid = lag_grid(input, &runs, &held, opts);
        let t_train: Vec<f64> = train_idx.iter().map(|&i| input.time_s[i]).collect();
        // A single recording: a sensor with one episode of change gets lags up to a third of it; each run
        // of a campaign is an episode of its own.
        let lag_cap = sens
            .iter()
            .map(|&si| {
                if runs.per_run {
                    return f64::INFINITY;
                }
                let v: Vec<f64> = train_idx
                    .iter()
                    .map(|&i| input.sensors[si].values[i])
                    .collect();
                let (episodes, longest_s) = crate::blocks::lag_support(&t_train, &v);
                if episodes >= 2 {
                    f64::INFINITY
                } else {
                    LAG_CAP_FRACTION * longest_s
                }
            })
            .collect();
        Ok(Prepared {
            n,
            held,
            train_idx,
            runs,
            sens,
            excluded,
            target_ref,
            zeroed,
            y_fit,
            blocks,
            grid,
            lag_cap,
        })
    }

    pub(crate) fn sensor_rise(&self, input: &ThermalInput, k: usize, tau: f64) -> Vec<f64> {
        self.runs
            .rise(&input.time_s, &input.sensors[self.sens[k]].values, tau)
    }

    /// The candidate columns, their Gram matrices and everything the candidates need.
    pub(crate) fn design(&self, input: &ThermalInput, opts: &ThermalOptions) -> Design {
        let mut cands = vec![];
        let mut cols = vec![];
        for k in 0..self.sens.len() {
            for &tau in &self.grid {
                if tau > self.lag_cap[k] {
                    continue;
                }
                cols.push(self.sensor_rise(input, k, tau));
                cands.push(Candidate::Sensor {
                    sensor: k,
                    tau_s: tau,
                });
            }
        }
        let mut forced = vec![];
        for (f, s) in input.forces.iter().enumerate() {
            cols.push(s.values.clone());
            cands.push(Candidate::Force { force: f });
            forced.push(cands.len() - 1);
        }
        let n_groups = self.blocks.names.len();
        let refs: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
        let gs = GramSet::new(&refs, &self.y_fit, &self.blocks.group_of_row, n_groups);
        let mut group_rows = vec![vec![]; n_groups];
        for (i, g) in self.blocks.group_of_row.iter().enumerate() {
            if let Some(g) = g {
                group_rows[*g].push(i);
            }
        }
        let mut order: Vec<usize> = (0..n_groups)
            .filter(|&g| !group_rows[g].is_empty())
            .collect();
        order.sort_by_key(|&g| group_rows[g][0]);
        let rise0: Vec<Vec<f64>> = (0..self.sens.len())
            .map(|k| self.sensor_rise(input, k, 0.0))
            .collect();
        let group_range = group_rows
            .iter()
            .map(|rows| {
                rise0
                    .iter()
                    .map(|r| {
                        rows.iter()
                            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &i| {
                                (lo.min(r[i]), hi.max(r[i]))
                            })
                    })
                    .collect()
            })
            .collect();
        Design {
            names: self
                .sens
                .iter()
                .map(|&i| input.sensors[i].name.clone())
                .collect(),
            cands,
            cols,
            forced,
            rise0,
            y: self.y_fit.clone(),
            gs,
            group_rows,
            order,
            sensor_limit: axcomp_core::MAX_SENSORS,
            max_sensors: opts.max_sensors.min(self.sens.len()),
            lags: opts.lags,
            group_range,
            forward: self.runs.per_run || !self.blocks.by_condition,
        }
    }
}

/// Golden-section refinement of each selected τ (> 0) between its grid neighbours, objective the
/// leave-one-group-out RMS; each round keeps the one change over all terms that helps most (so the result
/// does not depend on the order of the sensor columns in the file).
pub(crate) fn refine_lags(
    p: &Prepared,
    input: &ThermalInput,
    sel: &mut [(usize, f64)],
    lambda: f64,
) {
    let n_groups = p.blocks.names.len();
    let all: Vec<usize> = (0..n_groups).collect();
    let small_cv = |sel: &[(usize, f64)]| -> f64 {
        let mut cs: Vec<Vec<f64>> = sel
            .iter()
            .map(|&(s, t)| p.sensor_rise(input, s, t))
            .collect();
        cs.extend(input.forces.iter().map(|f| f.values.clone()));
        let refs: Vec<&[f64]> = cs.iter().map(|c| c.as_slice()).collect();
        let g = GramSet::new(&refs, &p.y_fit, &p.blocks.group_of_row, n_groups);
        let terms: Vec<usize> = (0..cs.len()).collect();
        g.cv_rms(&terms, &all, lambda)
    };
    let grid = &p.grid;
    let brackets: Vec<Option<(f64, f64)>> = sel
        .iter()
        .map(|&(_, tau)| {
            let pos = grid.iter().position(|g| *g == tau)?;
            if tau <= 0.0 {
                return None;
            }
            let lo = if pos >= 2 { grid[pos - 1] } else { tau / 2.0 };
            let hi = grid.get(pos + 1).copied().unwrap_or(tau);
            Some((lo, hi))
        })
        .collect();
    let (sweeps, steps) = if sel.len() > 6 { (1, 12) } else { (2, 20) };
    let mut cur = small_cv(sel);
    for _ in 0..sweeps * sel.len() {
        let mut best: Option<(usize, f64, f64)> = None;
        for j in 0..sel.len() {
            let Some((lo, hi)) = brackets[j] else {
                continue;
            };
            let mut f = |lt: f64| {
                let mut s2 = sel.to_vec();
                s2[j].1 = lt.exp();
                small_cv(&s2)
            };
            let t = golden_min(&mut f, lo.ln(), hi.ln(), steps);
            let r = f(t);
            if r < best.map_or(cur, |b| b.2) {
                best = Some((j, t.exp(), r));
            }
        }
        match best {
            Some((j, tau, r)) => {
                sel[j].1 = tau;
                cur = r;
            }
            None => break,
        }
    }
}
