//! Thermal (thermo-force) error model: selection, lags, fitting, validation, do-no-harm guard.
//!
//! Glossary:
//! - **sensor**: a temperature column `NAME_degC`; its **rise** is `ΔT = lag(T, τ) − T_ref`, `T_ref` = the
//!   sensor's first reading.
//! - **term**: `b · ΔT` (µm/K) per selected sensor; **force term**: `χ · F` (µm/N) per force column, fitted
//!   jointly with the thermal terms (coupled thermo-force model).
//! - **model**: `e = b0 + Σ b_s ΔT_s + Σ χ_f F_f`, the predicted error (µm), which the firmware subtracts.
//! - **training / held-out rows**: `--holdout` rows are never used for fitting or selection, only to judge.
//! - **inner CV**: leave-one-group-out over the training rows only (groups = `--cv` conditions, or contiguous
//!   time blocks), used for selection, lag grid and ridge choice.
//! - **nested CV**: to compare the two selection methods fairly, each method's whole selection is re-run
//!   without the left-out group, then judged on it.
//! - **do-no-harm guard**: the model must not be worse than no compensation (raw) on the held-out rows
//!   (without `--holdout`: on the cross-validated training rows).

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::lag::lag;
use crate::linalg::{condition_number, lstsq, vif};
use crate::select::{self, Candidate, GramSet};
use crate::stats::rms;

/// A named column.
#[derive(Debug, Clone)]
pub struct Series {
    pub name: String,
    pub values: Vec<f64>,
}

/// What the fit reads (already filtered, renamed and scaled).
#[derive(Debug, Clone)]
pub struct ThermalInput {
    pub time_s: Vec<f64>,
    /// Temperature sensors (name without the `_degC` suffix).
    pub sensors: Vec<Series>,
    /// Force columns (`*_N`), used as linear terms.
    pub forces: Vec<Series>,
    /// The error channel to model (µm).
    pub target: Vec<f64>,
    /// Operating condition of each row (`--cv` column), if any.
    pub conditions: Option<Vec<String>>,
    /// Held-out rows (true = judge only).
    pub holdout: Option<Vec<bool>>,
}

/// Ridge setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Ridge {
    Off,
    Fixed(f64),
    /// λ chosen by inner CV from {0, 1e-6, …, 10}.
    Auto,
}

/// Which sensor selection to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Selection {
    /// The method with the lower nested CV RMS (FCM + GRA or forward selection).
    Auto,
    /// The reference method, fuzzy c-means + grey relational analysis.
    FcmGra,
    /// Forward selection scored by inner CV.
    Forward,
    /// Every usable sensor (no selection; a baseline).
    All,
}

/// Fit settings (validated by [`ThermalOptions::build`]).
#[derive(Debug, Clone, Copy)]
pub struct ThermalOptions {
    pub lags: bool,
    pub ridge: Ridge,
    /// Most sensors in the model (≤ `axcomp_core::MAX_SENSORS` = 16).
    pub max_sensors: usize,
    /// Time blocks for the inner CV when there are fewer than 3 conditions.
    pub time_blocks: usize,
    /// Lag grid size (besides τ = 0).
    pub lag_grid: usize,
    pub selection: Selection,
}

impl Default for ThermalOptions {
    fn default() -> Self {
        ThermalOptions {
            lags: false,
            ridge: Ridge::Off,
            max_sensors: 6,
            time_blocks: 5,
            lag_grid: 8,
            selection: Selection::Auto,
        }
    }
}

impl ThermalOptions {
    /// Checks the settings.
    pub fn build(self) -> Result<Self, ThermalError> {
        if self.max_sensors == 0 || self.max_sensors > 16 {
            return Err(ThermalError::Option("max_sensors must be 1..=16"));
        }
        if self.time_blocks < 3 {
            return Err(ThermalError::Option("time_blocks must be >= 3"));
        }
        if let Ridge::Fixed(l) = self.ridge
            && !(l >= 0.0 && l.is_finite())
        {
            return Err(ThermalError::Option("ridge must be a finite number >= 0"));
        }
        Ok(self)
    }
}

/// Why a thermal fit failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ThermalError {
    #[error("invalid option: {0}")]
    Option(&'static str),
    #[error("column `{column}` has {got} rows, expected {want}")]
    Length {
        column: String,
        got: usize,
        want: usize,
    },
    #[error("column `{column}`, data row {row}: value is not finite")]
    NonFinite { column: String, row: usize },
    #[error("no usable temperature sensor (`*_degC` column that varies on the training rows)")]
    NoSensors,
    #[error("too few training rows ({0}); need at least 10")]
    TooFewRows(usize),
    #[error("the holdout selects no rows")]
    EmptyHoldout,
    #[error("least squares failed: {0}")]
    Ls(#[from] crate::linalg::LsError),
}

/// One sensor term of a fitted model.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SensorTerm {
    pub sensor: String,
    pub reference_degc: f64,
    pub tau_s: f64,
    pub coef_um_per_k: f64,
}

/// One force term of a fitted model.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ForceTerm {
    pub column: String,
    pub chi_um_per_n: f64,
}

/// A fitted thermo-force model: `e = b0 + Σ b (lag(T, τ) − T_ref) + Σ χ F`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ThermalModel {
    pub b0_um: f64,
    pub terms: Vec<SensorTerm>,
    pub forces: Vec<ForceTerm>,
}

impl ThermalModel {
    /// Predicted error per row. Sensors and forces are looked up by name.
    pub fn predict(
        &self,
        time_s: &[f64],
        sensors: &[Series],
        forces: &[Series],
    ) -> Result<Vec<f64>, String> {
        let mut out = vec![self.b0_um; time_s.len()];
        for t in &self.terms {
            let s = sensors
                .iter()
                .find(|s| s.name == t.sensor)
                .ok_or_else(|| format!("sensor `{}` missing", t.sensor))?;
            let l = lag(time_s, &s.values, t.tau_s);
            for (o, v) in out.iter_mut().zip(l) {
                *o += t.coef_um_per_k * (v - t.reference_degc);
            }
        }
        for f in &self.forces {
            let s = forces
                .iter()
                .find(|s| s.name == f.column)
                .ok_or_else(|| format!("force column `{}` missing", f.column))?;
            for (o, v) in out.iter_mut().zip(&s.values) {
                *o += f.chi_um_per_n * v;
            }
        }
        Ok(out)
    }

    /// A one-line formula, e.g. `e = 1.2 + 3.4·ΔT(frame, τ=600 s) + 0.02·force_N`.
    pub fn formula(&self) -> String {
        let mut s = format!("e = {:.4}", self.b0_um);
        for t in &self.terms {
            s += &format!(
                " {:+.4}·ΔT({}, τ={:.0} s)",
                t.coef_um_per_k, t.sensor, t.tau_s
            );
        }
        for f in &self.forces {
            s += &format!(" {:+.6}·{}", f.chi_um_per_n, f.column);
        }
        s
    }
}

/// Report of one selection method.
#[derive(Debug, Clone, Serialize)]
pub struct MethodReport {
    pub method: String,
    /// Sensors chosen on all training rows.
    pub sensors: Vec<String>,
    pub tau_s: Vec<f64>,
    /// Inner CV RMS of the final choice (optimistic: the choice saw these folds).
    pub inner_cv_rms_um: f64,
    /// Nested CV RMS (selection re-run without each group): the figure the methods are compared by.
    pub nested_cv_rms_um: f64,
}

/// Everything a thermal fit reports (serialized into the `--json` file).
#[derive(Debug, Clone, Serialize)]
pub struct ThermalFit {
    /// Selected sensor names.
    pub sensors: Vec<String>,
    /// RMS of the target on the held-out rows (all rows without a holdout), before the model.
    pub raw_rms_um: f64,
    /// RMS of the residual on the held-out rows.
    pub holdout_rms_um: Option<f64>,
    /// Leave-one-condition-out RMS on the training rows (structure fixed, coefficients refit per fold).
    pub cv_rms_um: Option<f64>,
    pub train_raw_rms_um: f64,
    pub train_rms_um: f64,
    pub model: ThermalModel,
    pub formula: String,
    pub chosen_method: String,
    pub why: String,
    pub fcm_gra: MethodReport,
    pub forward: MethodReport,
    /// No selection (every usable sensor); `None` with more than 16 usable sensors.
    pub all_sensors: Option<MethodReport>,
    pub fcm_gra_detail: select::FcmGra,
    /// Forward selection path: (term added, inner CV RMS after it).
    pub forward_path: Vec<(String, f64)>,
    pub condition_number: f64,
    /// VIF per selected sensor term (same order as `model.terms`).
    pub vif: Vec<(String, f64)>,
    pub ridge_lambda: f64,
    pub lags: bool,
    pub lag_grid_s: Vec<f64>,
    /// How the inner CV grouped the training rows.
    pub inner_groups: String,
    pub per_condition: Vec<ConditionResidual>,
    pub excluded_sensors: Vec<(String, String)>,
    pub training_rows: usize,
    pub holdout_rows: usize,
    pub guard: Guard,
    /// Predictions per row (not serialized; for plots).
    #[serde(skip)]
    pub prediction: Vec<f64>,
}

/// RMS per operating condition (or per train/held-out part).
#[derive(Debug, Clone, Serialize)]
pub struct ConditionResidual {
    pub condition: String,
    pub rows: usize,
    pub held_out: bool,
    pub raw_rms_um: f64,
    pub rms_um: f64,
}

/// Outcome of the do-no-harm check.
#[derive(Debug, Clone, Serialize)]
pub struct Guard {
    pub passed: bool,
    /// What was compared.
    pub basis: String,
    pub reason: String,
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn check(input: &ThermalInput) -> Result<(), ThermalError> {
    let n = input.time_s.len();
    let mut cols: Vec<(&str, &[f64])> = vec![("time_s", &input.time_s), ("target", &input.target)];
    for s in input.sensors.iter().chain(&input.forces) {
        cols.push((&s.name, &s.values));
    }
    for (name, v) in cols {
        if v.len() != n {
            return Err(ThermalError::Length {
                column: name.into(),
                got: v.len(),
                want: n,
            });
        }
        if let Some(row) = v.iter().position(|x| !x.is_finite()) {
            return Err(ThermalError::NonFinite {
                column: name.into(),
                row: row + 1,
            });
        }
    }
    for (what, len) in [
        ("conditions", input.conditions.as_ref().map(|c| c.len())),
        ("holdout", input.holdout.as_ref().map(|c| c.len())),
    ] {
        if let Some(l) = len
            && l != n
        {
            return Err(ThermalError::Length {
                column: what.into(),
                got: l,
                want: n,
            });
        }
    }
    Ok(())
}

/// Fits a thermo-force model (see the module docs for the procedure).
pub fn fit_thermal(
    input: &ThermalInput,
    opts: &ThermalOptions,
) -> Result<ThermalFit, ThermalError> {
    let opts = opts.build()?;
    check(input)?;
    let n = input.time_s.len();
    let held: Vec<bool> = input.holdout.clone().unwrap_or_else(|| vec![false; n]);
    if input.holdout.is_some() && !held.iter().any(|h| *h) {
        return Err(ThermalError::EmptyHoldout);
    }
    let train_idx: Vec<usize> = (0..n).filter(|&i| !held[i]).collect();
    if train_idx.len() < 10 {
        return Err(ThermalError::TooFewRows(train_idx.len()));
    }

    // ---- usable sensors ----
    let mut excluded = vec![];
    let mut sens: Vec<usize> = vec![];
    for (i, s) in input.sensors.iter().enumerate() {
        let v: Vec<f64> = train_idx.iter().map(|&r| s.values[r]).collect();
        let sd = crate::stats::std_dev(&v);
        if sd <= 1e-9 {
            excluded.push((s.name.clone(), "constant on the training rows".to_string()));
        } else {
            sens.push(i);
        }
    }
    if sens.is_empty() {
        return Err(ThermalError::NoSensors);
    }
    let sname = |k: usize| input.sensors[sens[k]].name.clone();
    let reference: Vec<f64> = sens.iter().map(|&i| input.sensors[i].values[0]).collect();

    // ---- groups for the inner CV ----
    let mut group_of_row: Vec<Option<usize>> = vec![None; n];
    let mut group_names: Vec<String> = vec![];
    let mut cond_groups_ok = false;
    if let Some(c) = &input.conditions {
        for &i in &train_idx {
            let g = match group_names.iter().position(|x| *x == c[i]) {
                Some(g) => g,
                None => {
                    group_names.push(c[i].clone());
                    group_names.len() - 1
                }
            };
            group_of_row[i] = Some(g);
        }
        cond_groups_ok = group_names.len() >= 3;
    }
    let inner_groups;
    if !cond_groups_ok {
        let b = opts.time_blocks;
        group_names = (0..b).map(|k| format!("time block {}", k + 1)).collect();
        for (j, &i) in train_idx.iter().enumerate() {
            group_of_row[i] = Some(j * b / train_idx.len());
        }
        inner_groups = format!(
            "{} contiguous time blocks of the training rows{}",
            b,
            if input.conditions.is_some() {
                " (fewer than 3 conditions among the training rows)"
            } else {
                ""
            }
        );
    } else {
        inner_groups = format!(
            "leave-one-condition-out over {} training conditions",
            group_names.len()
        );
    }
    let n_groups = group_names.len();
    let all_groups: Vec<usize> = (0..n_groups).collect();

    // ---- lag grid and candidate columns ----
    let t_train: Vec<f64> = train_idx.iter().map(|&i| input.time_s[i]).collect();
    let duration = t_train.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - t_train.iter().cloned().fold(f64::INFINITY, f64::min);
    let dts: Vec<f64> = input
        .time_s
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    let med_dt = median(dts);
    let mut grid = vec![0.0];
    if opts.lags && duration > 0.0 && med_dt.is_finite() {
        let lo = (2.0 * med_dt).max(duration / 300.0);
        let hi = (duration / 2.0).max(lo * 2.0);
        let m = opts.lag_grid.max(2);
        for k in 0..m {
            grid.push(lo * (hi / lo).powf(k as f64 / (m - 1) as f64));
        }
    }
    let mut cands: Vec<Candidate> = vec![];
    let mut cols: Vec<Vec<f64>> = vec![];
    for (k, &si) in sens.iter().enumerate() {
        for &tau in &grid {
            let l = lag(&input.time_s, &input.sensors[si].values, tau);
            cols.push(l.iter().map(|v| v - reference[k]).collect());
            cands.push(Candidate::Sensor {
                sensor: k,
                tau_s: tau,
            });
        }
    }
    let forced: Vec<usize> = (0..input.forces.len())
        .map(|f| {
            cols.push(input.forces[f].values.clone());
            cands.push(Candidate::Force { force: f });
            cands.len() - 1
        })
        .collect();
    let col_refs: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
    let gs = GramSet::new(&col_refs, &input.target, &group_of_row, n_groups);
    let cand_of = |sensor: usize, tau: f64| {
        cands
            .iter()
            .position(|c| *c == Candidate::Sensor { sensor, tau_s: tau })
            .unwrap()
    };
    let max_sensors = opts.max_sensors.min(sens.len());

    // Method A (FCM + GRA) on the rows of `groups`.
    let method_a = |groups: &[usize]| -> (select::FcmGra, Vec<usize>, f64) {
        let rows: Vec<usize> = train_idx
            .iter()
            .cloned()
            .filter(|&i| group_of_row[i].is_some_and(|g| groups.contains(&g)))
            .collect();
        let series: Vec<Vec<f64>> = sens
            .iter()
            .map(|&si| rows.iter().map(|&r| input.sensors[si].values[r]).collect())
            .collect();
        let target: Vec<f64> = rows.iter().map(|&r| input.target[r]).collect();
        let fg = select::fcm_gra(&series, &target, 6.min(max_sensors.max(2)));
        let mut terms: Vec<usize> = forced.clone();
        terms.extend(fg.selected.iter().map(|&s| cand_of(s, 0.0)));
        let cur = gs.cv_rms(&terms, groups, 0.0);
        let cur = if opts.lags {
            select::improve_lags(&gs, &cands, &mut terms, groups, cur)
        } else {
            cur
        };
        (fg, terms, cur)
    };
    let method_b =
        |groups: &[usize]| select::forward(&gs, &cands, &forced, groups, max_sensors, 0.01);
    // Method C (no selection): every usable sensor, lags chosen on the grid; a candidate when the firmware
    // can take every usable sensor (at most `axcomp_core::MAX_SENSORS`).
    let all_allowed = sens.len() <= axcomp_core::MAX_SENSORS;
    let method_c = |groups: &[usize]| -> (Vec<usize>, f64) {
        let mut t = forced.clone();
        t.extend((0..sens.len()).map(|s| cand_of(s, 0.0)));
        let cur = gs.cv_rms(&t, groups, 0.0);
        let cur = if opts.lags {
            select::improve_lags(&gs, &cands, &mut t, groups, cur)
        } else {
            cur
        };
        (t, cur)
    };

    // ---- nested CV comparison ----
    let (mut sse_a, mut sse_b, mut sse_c, mut nn) = (0.0, 0.0, 0.0, 0usize);
    for &g in &all_groups {
        let inner: Vec<usize> = all_groups.iter().cloned().filter(|&h| h != g).collect();
        let (_, ta, _) = method_a(&inner);
        let fb = method_b(&inner);
        if all_allowed {
            let (tc, _) = method_c(&inner);
            sse_c += gs
                .fit(&tc, &inner, 0.0)
                .map_or(f64::INFINITY, |b| gs.sse(&tc, &b, g));
        }
        sse_a += gs
            .fit(&ta, &inner, 0.0)
            .map_or(f64::INFINITY, |b| gs.sse(&ta, &b, g));
        sse_b += gs
            .fit(&fb.terms, &inner, 0.0)
            .map_or(f64::INFINITY, |b| gs.sse(&fb.terms, &b, g));
        nn += gs.rows[g];
    }
    let nested_a = (sse_a / nn as f64).sqrt();
    let nested_b = (sse_b / nn as f64).sqrt();
    let nested_c = if all_allowed {
        (sse_c / nn as f64).sqrt()
    } else {
        f64::INFINITY
    };

    // ---- final selection on all training rows ----
    let (fg, terms_a, cv_a) = method_a(&all_groups);
    let fb = method_b(&all_groups);
    let describe = |terms: &[usize]| -> (Vec<String>, Vec<f64>) {
        terms
            .iter()
            .filter_map(|&t| match cands[t] {
                Candidate::Sensor { sensor, tau_s } => Some((sname(sensor), tau_s)),
                _ => None,
            })
            .unzip()
    };
    let (sa, ta) = describe(&terms_a);
    let (sb, tb) = describe(&fb.terms);
    let rep_a = MethodReport {
        method: "fcm_gra".into(),
        sensors: sa,
        tau_s: ta,
        inner_cv_rms_um: cv_a,
        nested_cv_rms_um: nested_a,
    };
    let rep_b = MethodReport {
        method: "forward_cv".into(),
        sensors: sb,
        tau_s: tb,
        inner_cv_rms_um: fb.cv_rms,
        nested_cv_rms_um: nested_b,
    };
    let (terms_c, cv_c) = method_c(&all_groups);
    let rep_c = all_allowed.then(|| {
        let (sc, tc) = describe(&terms_c);
        MethodReport {
            method: "all".into(),
            sensors: sc,
            tau_s: tc,
            inner_cv_rms_um: cv_c,
            nested_cv_rms_um: nested_c,
        }
    });
    let cmp = format!(
        "nested {inner_groups}: forward selection {nested_b:.4} µm, FCM+GRA {nested_a:.4} µm{}",
        if all_allowed {
            format!(", all {} sensors {nested_c:.4} µm", sens.len())
        } else {
            String::new()
        }
    );
    let best_auto = if nested_c < nested_a.min(nested_b) {
        Selection::All
    } else if nested_b < nested_a {
        Selection::Forward
    } else {
        Selection::FcmGra
    };
    let requested = opts.selection != Selection::Auto;
    let pick = if requested { opts.selection } else { best_auto };
    let tag = |name: &str| {
        if requested {
            format!("requested {name}; {cmp}")
        } else {
            format!("{cmp} → {name}")
        }
    };
    let (chosen_method, terms, why) = match pick {
        Selection::Forward => ("forward_cv", fb.terms.clone(), tag("forward_cv")),
        Selection::All => ("all", terms_c.clone(), tag("all")),
        _ => ("fcm_gra", terms_a.clone(), tag("fcm_gra")),
    };
    let forward_path = fb
        .steps
        .iter()
        .map(|s| match cands[s.candidate] {
            Candidate::Sensor { sensor, tau_s } => {
                (format!("{} (τ={:.0} s)", sname(sensor), tau_s), s.cv_rms)
            }
            Candidate::Force { force } => (input.forces[force].name.clone(), s.cv_rms),
        })
        .collect();

    // ---- chosen structure: sensors + τ, refined ----
    let mut sel: Vec<(usize, f64)> = terms
        .iter()
        .filter_map(|&t| match cands[t] {
            Candidate::Sensor { sensor, tau_s } => Some((sensor, tau_s)),
            _ => None,
        })
        .collect();
    let column = |sensor: usize, tau: f64| -> Vec<f64> {
        lag(&input.time_s, &input.sensors[sens[sensor]].values, tau)
            .into_iter()
            .map(|v| v - reference[sensor])
            .collect()
    };
    let small_cv = |sel: &[(usize, f64)], lambda: f64| -> f64 {
        let mut cs: Vec<Vec<f64>> = sel.iter().map(|&(s, t)| column(s, t)).collect();
        for f in &input.forces {
            cs.push(f.values.clone());
        }
        let refs: Vec<&[f64]> = cs.iter().map(|c| c.as_slice()).collect();
        let g = GramSet::new(&refs, &input.target, &group_of_row, n_groups);
        let all: Vec<usize> = (0..cs.len()).collect();
        g.cv_rms(&all, &all_groups, lambda)
    };
    if opts.lags {
        // Golden-section search on log τ between the grid neighbours of each selected τ (> 0), objective the
        // inner CV RMS; two coordinate sweeps (one sweep of 12 steps with more than 6 terms).
        let brackets: Vec<Option<(f64, f64)>> = sel
            .iter()
            .map(|&(_, tau)| {
                let pos = grid.iter().position(|g| *g == tau)?;
                if tau <= 0.0 {
                    return None;
                }
                let lo = if pos >= 2 { grid[pos - 1] } else { tau / 2.0 };
                let hi = if pos + 1 < grid.len() {
                    grid[pos + 1]
                } else {
                    tau * 2.0
                };
                Some((lo, hi))
            })
            .collect();
        // Many terms: one sweep with fewer steps keeps the fit fast.
        let (sweeps, steps) = if sel.len() > 6 { (1, 12) } else { (2, 20) };
        for _ in 0..sweeps {
            for j in 0..sel.len() {
                let Some((lo, hi)) = brackets[j] else {
                    continue;
                };
                let tau = sel[j].1;
                let mut f = |lt: f64| {
                    let mut s2 = sel.clone();
                    s2[j].1 = lt.exp();
                    small_cv(&s2, 0.0)
                };
                let best = golden_min(&mut f, lo.ln(), hi.ln(), steps);
                if f(best) < f(tau.ln()) {
                    sel[j].1 = best.exp();
                }
            }
        }
    }

    // ---- ridge ----
    let lambda = match opts.ridge {
        Ridge::Off => 0.0,
        Ridge::Fixed(l) => l,
        Ridge::Auto => {
            let mut best = (0.0, small_cv(&sel, 0.0));
            for e in -6..=1 {
                let l = 10f64.powi(e);
                let r = small_cv(&sel, l);
                if r < best.1 {
                    best = (l, r);
                }
            }
            best.0
        }
    };

    // ---- final coefficients by QR on the training rows ----
    let full_cols: Vec<Vec<f64>> = sel
        .iter()
        .map(|&(s, t)| column(s, t))
        .chain(input.forces.iter().map(|f| f.values.clone()))
        .collect();
    let p = full_cols.len() + 1;
    let x = DMatrix::from_fn(train_idx.len(), p, |r, c| {
        if c == 0 {
            1.0
        } else {
            full_cols[c - 1][train_idx[r]]
        }
    });
    let y_train: Vec<f64> = train_idx.iter().map(|&i| input.target[i]).collect();
    let ls = lstsq(&x, &y_train, lambda, Some(0))?;
    let cond = condition_number(&x);
    let vifs = vif(&(0..sel.len())
        .map(|j| {
            train_idx
                .iter()
                .map(|&i| full_cols[j][i])
                .collect::<Vec<f64>>()
        })
        .collect::<Vec<_>>());
    let model = ThermalModel {
        b0_um: ls.coef[0],
        terms: sel
            .iter()
            .enumerate()
            .map(|(j, &(s, t))| SensorTerm {
                sensor: sname(s),
                reference_degc: reference[s],
                tau_s: t,
                coef_um_per_k: ls.coef[j + 1],
            })
            .collect(),
        forces: input
            .forces
            .iter()
            .enumerate()
            .map(|(f, s)| ForceTerm {
                column: s.name.clone(),
                chi_um_per_n: ls.coef[sel.len() + 1 + f],
            })
            .collect(),
    };
    let prediction = model
        .predict(&input.time_s, &input.sensors, &input.forces)
        .expect("model built from these columns");
    let resid: Vec<f64> = input
        .target
        .iter()
        .zip(&prediction)
        .map(|(y, p)| y - p)
        .collect();
    let pick = |v: &[f64], want_held: bool| -> Vec<f64> {
        (0..n)
            .filter(|&i| held[i] == want_held)
            .map(|i| v[i])
            .collect()
    };
    let train_raw = rms(&pick(&input.target, false));
    let train_rms = rms(&pick(&resid, false));
    let (raw_rms, holdout_rms) = if input.holdout.is_some() {
        (
            rms(&pick(&input.target, true)),
            Some(rms(&pick(&resid, true))),
        )
    } else {
        (rms(&input.target), None)
    };
    let cv_rms = if cond_groups_ok {
        Some(small_cv(&sel, lambda))
    } else {
        None
    };

    // ---- per condition ----
    let mut per_condition = vec![];
    match &input.conditions {
        Some(c) => {
            let mut labels: Vec<&String> = vec![];
            for l in c {
                if !labels.contains(&l) {
                    labels.push(l);
                }
            }
            for l in labels {
                let rows: Vec<usize> = (0..n).filter(|&i| &c[i] == l).collect();
                per_condition.push(ConditionResidual {
                    condition: l.clone(),
                    rows: rows.len(),
                    held_out: rows.iter().all(|&i| held[i]),
                    raw_rms_um: rms(&rows.iter().map(|&i| input.target[i]).collect::<Vec<_>>()),
                    rms_um: rms(&rows.iter().map(|&i| resid[i]).collect::<Vec<_>>()),
                });
            }
        }
        None => {
            for (name, h) in [("training rows", false), ("held-out rows", true)] {
                let r = pick(&resid, h);
                if r.is_empty() {
                    continue;
                }
                per_condition.push(ConditionResidual {
                    condition: name.into(),
                    rows: r.len(),
                    held_out: h,
                    raw_rms_um: rms(&pick(&input.target, h)),
                    rms_um: rms(&r),
                });
            }
        }
    }

    // ---- do-no-harm guard ----
    let guard = match (holdout_rms, cv_rms) {
        (Some(h), _) => Guard {
            passed: h <= raw_rms,
            basis: "held-out rows".into(),
            reason: if h <= raw_rms {
                format!("held-out RMS {h:.3} µm <= raw {raw_rms:.3} µm")
            } else {
                format!(
                    "held-out RMS {h:.3} µm is worse than raw {raw_rms:.3} µm (no compensation)"
                )
            },
        },
        (None, cv) => {
            let cvr = cv.unwrap_or_else(|| small_cv(&sel, lambda));
            Guard {
                passed: cvr <= train_raw,
                basis: inner_groups.clone(),
                reason: if cvr <= train_raw {
                    format!("cross-validated RMS {cvr:.3} µm <= raw {train_raw:.3} µm")
                } else {
                    format!("cross-validated RMS {cvr:.3} µm is worse than raw {train_raw:.3} µm")
                },
            }
        }
    };

    Ok(ThermalFit {
        sensors: model.terms.iter().map(|t| t.sensor.clone()).collect(),
        raw_rms_um: raw_rms,
        holdout_rms_um: holdout_rms,
        cv_rms_um: cv_rms,
        train_raw_rms_um: train_raw,
        train_rms_um: train_rms,
        formula: model.formula(),
        vif: model
            .terms
            .iter()
            .map(|t| t.sensor.clone())
            .zip(vifs)
            .collect(),
        model,
        chosen_method: chosen_method.into(),
        why,
        fcm_gra: rep_a,
        forward: rep_b,
        all_sensors: rep_c,
        fcm_gra_detail: select::FcmGra {
            selected: fg.selected.clone(),
            ..fg
        },
        forward_path,
        condition_number: cond,
        ridge_lambda: lambda,
        lags: opts.lags,
        lag_grid_s: grid,
        inner_groups,
        per_condition,
        excluded_sensors: excluded,
        training_rows: train_idx.len(),
        holdout_rows: n - train_idx.len(),
        guard,
        prediction,
    })
}

/// Golden-section minimisation of `f` on `[a, b]`, `iters` steps; returns the abscissa of the minimum.
pub fn golden_min(f: &mut dyn FnMut(f64) -> f64, mut a: f64, mut b: f64, iters: usize) -> f64 {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    if fc < fd { c } else { d }
}
