//! The default model choice: candidate procedures, forward validation, the plain references and the
//! rule that picks the default.
//!
//! Glossary:
//! - **group**: training rows judged together: a run (with `--runs`), or a block of one thermal regime in a
//!   single recording ([`crate::blocks`]). Groups are ordered in time by their first row.
//! - **candidate**: a procedure that makes all its own choices (sensors, lags, penalty) on the groups it is
//!   given: plain least squares on every sensor the firmware takes, greedy selection with lags, forward
//!   selection with lags by inner cross-validation, fuzzy c-means + grey relational analysis, ridge.
//! - **condition validation**: with `--cv` conditions (operating conditions without an order), each
//!   condition is left out in turn and predicted from the others.
//! - **forward validation**: each group of the later half (at least from the third on) is predicted by
//!   every candidate chosen and fitted on all the groups *before* it only: the model is judged as it is
//!   used, on a run (or regime) that comes after everything it saw, fitted on at least half the campaign
//!   (as the final model is fitted on all of it); a group never has training data on both sides.
//! - **range guard**: on a row where a sensor of the model has risen (or fallen) beyond its range on the
//!   fitting rows by more than that range (at least 1 K), that sensor's term is dropped (its rise taken
//!   as zero) and the other terms stay: a linear model is not extrapolated to four times the rises it was
//!   fitted on. Dropping the whole thermal term instead (every rise zero) was measured worse: on the lathe,
//!   leave one run out, X 10.39 µm against 5.94 µm per sensor (run 20200821, where `pt10` rose 38 K:
//!   47.8 µm, above raw 46.5, against 13.7). `axcomp predict` and the firmware do the same.
//! - **rule**: among the candidates the firmware can take, the lowest validation RMS wins if it is one of
//!   the simple procedures (plain least squares, greedy selection with lags); a more elaborate one (forward
//!   selection by inner CV, FCM + GRA, ridge) must beat the better simple procedure by more than one
//!   standard error of the per-group paired difference of mean squared errors (the one-standard-error rule
//!   toward the simpler model), else that simple procedure is the default. The default is therefore never
//!   above plain least squares in validation.
//! - **references**: plain least squares on every sensor (no lag, no limit on the sensor count) and greedy
//!   selection with lags, judged by the same validation in the same run.

use nalgebra::DVector;
use serde::Serialize;

use crate::select::{self, Candidate, GramSet};

/// Sensors the greedy candidate (and reference) adds at most.
pub const GREEDY_SENSORS: usize = 4;

/// A candidate procedure (or reference) of the model choice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Every usable sensor the firmware takes (backward elimination to its limit), no lag.
    PlainLs,
    /// Every usable sensor, no lag, no sensor limit: the plain reference.
    PlainAll,
    GreedyLags,
    /// Every sensor the firmware takes, one lag per sensor (grid, inner CV).
    AllLags,
    ForwardLags,
    FcmGra,
    Ridge,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::PlainLs => "plain_ls",
            Kind::PlainAll => "plain_ls_all_sensors",
            Kind::GreedyLags => "greedy_lags",
            Kind::AllLags => "all_lags",
            Kind::ForwardLags => "forward_lags",
            Kind::FcmGra => "fcm_gra",
            Kind::Ridge => "ridge",
        }
    }
    /// The `chosen_method` value of the JSON.
    pub fn method_name(self) -> &'static str {
        match self {
            Kind::PlainLs | Kind::PlainAll | Kind::AllLags => "all",
            Kind::GreedyLags => "greedy_lags",
            Kind::ForwardLags => "forward_cv",
            Kind::FcmGra => "fcm_gra",
            Kind::Ridge => "ridge",
        }
    }
    pub fn what(self) -> &'static str {
        match self {
            Kind::PlainLs => {
                "every sensor (the firmware's 16 by backward elimination when there are more), no lag, least squares"
            }
            Kind::PlainAll => {
                "every sensor, no lag, least squares (reference; may exceed the firmware's 16)"
            }
            Kind::GreedyLags => {
                "greedy: up to 4 sensors, each with the lag (grid) that lowers the training error most"
            }
            Kind::AllLags => {
                "every sensor the firmware takes, one first-order lag each (grid, inner CV)"
            }
            Kind::ForwardLags => "forward selection of sensors and lags by inner cross-validation",
            Kind::FcmGra => {
                "fuzzy c-means + grey relational analysis (reference method), lags by inner CV"
            }
            Kind::Ridge => {
                "every sensor the firmware takes, no lag, ridge penalty chosen by inner CV"
            }
        }
    }
}

/// A candidate's structure: its terms (indices into the candidate columns) and ridge λ.
#[derive(Debug, Clone)]
pub struct Structure {
    pub terms: Vec<usize>,
    pub ridge: f64,
}

/// Everything the candidates are built from.
pub struct Design {
    /// Usable sensor names.
    pub names: Vec<String>,
    pub cands: Vec<Candidate>,
    /// Candidate columns over every row (sensor rises through their lag, forces).
    pub cols: Vec<Vec<f64>>,
    /// Force terms (always in).
    pub forced: Vec<usize>,
    /// Unlagged rise of each usable sensor (the range guard reads it).
    pub rise0: Vec<Vec<f64>>,
    /// The fitted target.
    pub y: Vec<f64>,
    pub gs: GramSet,
    /// Training rows of each group.
    pub group_rows: Vec<Vec<usize>>,
    /// Groups in time order.
    pub order: Vec<usize>,
    /// Most sensors the firmware takes.
    pub sensor_limit: usize,
    /// Most sensors of the selecting candidates.
    pub max_sensors: usize,
    pub lags: bool,
    /// Per group and usable sensor: (min, max) of the unlagged rise.
    pub group_range: Vec<Vec<(f64, f64)>>,
    /// Forward validation (runs, regime blocks); false: leave one group out (`--cv` conditions).
    pub forward: bool,
}

/// The forward validation of a set of candidates.
#[derive(Debug, Clone)]
pub struct Validation {
    /// (fitting groups, predicted group).
    pub folds: Vec<(Vec<usize>, usize)>,
    /// Per candidate, per fold: squared error summed over the predicted group's rows.
    pub sse: Vec<Vec<f64>>,
    /// Rows of each fold's predicted group.
    pub rows: Vec<usize>,
}

impl Validation {
    /// Validation RMS of candidate `k` (NaN without folds).
    pub fn pooled_rms(&self, k: usize) -> f64 {
        let n: usize = self.rows.iter().sum();
        if n == 0 {
            return f64::NAN;
        }
        (self.sse[k].iter().sum::<f64>() / n as f64).sqrt()
    }
    /// Per-fold RMS of candidate `k`.
    pub fn fold_rms(&self, k: usize) -> Vec<f64> {
        self.sse[k]
            .iter()
            .zip(&self.rows)
            .map(|(s, &n)| (s / n.max(1) as f64).sqrt())
            .collect()
    }
    /// Whether `a`'s per-fold mean squared error is within one standard error of `b`'s (paired).
    pub fn within_one_se(&self, a: usize, b: usize) -> bool {
        let d: Vec<f64> = (0..self.rows.len())
            .map(|f| (self.sse[a][f] - self.sse[b][f]) / self.rows[f].max(1) as f64)
            .collect();
        if d.len() < 2 {
            return a == b;
        }
        let m = d.len() as f64;
        let mean = d.iter().sum::<f64>() / m;
        let sd = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (m - 1.0)).sqrt();
        mean <= sd / m.sqrt()
    }
}

/// Added to each side of a range-guard bound, K. Readings come at a fixed resolution (often 0.1 K) and a
/// bound is a sum of such readings, so a rise exactly at a bound is common; without the margin, whether it
/// counts as beyond would be decided by rounding (differently in the host's f64 and the firmware's f32).
/// With it, a rise at a bound is within on both, and f32 rounding (~1e-5 K at 100 °C) decides nothing.
pub const GUARD_TIE_MARGIN_K: f64 = 1e-4;

/// A structure's coefficients and range-guard bounds, fitted on some groups.
pub struct Fitted {
    pub beta: DVector<f64>,
    /// Allowed unlagged rise per usable sensor.
    pub bounds: Vec<(f64, f64)>,
}

impl Design {
    /// Usable sensor of a candidate column (None for a force).
    pub fn sensor_of(&self, term: usize) -> Option<usize> {
        match self.cands[term] {
            Candidate::Sensor { sensor, .. } => Some(sensor),
            Candidate::Force { .. } => None,
        }
    }

    /// Index of the candidate column of sensor `s` with lag `tau`.
    pub fn cand_of(&self, s: usize, tau: f64) -> usize {
        self.cands
            .iter()
            .position(|c| {
                *c == Candidate::Sensor {
                    sensor: s,
                    tau_s: tau,
                }
            })
            .expect("every sensor has a τ = 0 column")
    }

    /// Number of sensors of a structure.
    pub fn sensors_in(&self, s: &Structure) -> usize {
        s.terms
            .iter()
            .filter(|&&t| self.sensor_of(t).is_some())
            .count()
    }

    /// Sum of squared training residuals of a least-squares fit of `terms` on `groups`.
    fn train_sse(&self, terms: &[usize], groups: &[usize]) -> f64 {
        match self.gs.fit(terms, groups, 0.0) {
            Some(b) => groups.iter().map(|&g| self.gs.sse(terms, &b, g)).sum(),
            None => f64::INFINITY,
        }
    }

    fn plain_terms(&self, limit: usize, groups: &[usize]) -> Vec<usize> {
        let mut t = self.forced.clone();
        t.extend((0..self.names.len()).map(|s| self.cand_of(s, 0.0)));
        // Backward elimination down to the firmware's limit: drop the sensor whose removal raises the
        // training error least.
        while t.len() - self.forced.len() > limit {
            let drop = (self.forced.len()..t.len())
                .map(|p| {
                    let mut u = t.clone();
                    u.remove(p);
                    (p, self.train_sse(&u, groups))
                })
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(p, _)| p)
                .expect("more terms than the limit");
            t.remove(drop);
        }
        t
    }

    fn greedy_terms(&self, groups: &[usize]) -> Vec<usize> {
        let mut t = self.forced.clone();
        let mut used: Vec<usize> = vec![];
        for _ in 0..GREEDY_SENSORS.min(self.max_sensors).min(self.names.len()) {
            let best = (0..self.cands.len())
                .filter(|&c| self.sensor_of(c).is_some_and(|s| !used.contains(&s)))
                .map(|c| {
                    let mut u = t.clone();
                    u.push(c);
                    (c, self.train_sse(&u, groups))
                })
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let Some((c, sse)) = best else { break };
            if !sse.is_finite() {
                break;
            }
            used.push(self.sensor_of(c).expect("a sensor column"));
            t.push(c);
        }
        t
    }

    fn fcm_terms(&self, groups: &[usize]) -> (select::FcmGra, Vec<usize>) {
        let rows: Vec<usize> = groups
            .iter()
            .flat_map(|&g| self.group_rows[g].iter().copied())
            .collect();
        let series: Vec<Vec<f64>> = self
            .rise0
            .iter()
            .map(|r| rows.iter().map(|&i| r[i]).collect())
            .collect();
        let target: Vec<f64> = rows.iter().map(|&i| self.y[i]).collect();
        let fg = select::fcm_gra(&series, &target, 6.min(self.max_sensors.max(2)));
        let mut t = self.forced.clone();
        t.extend(fg.selected.iter().map(|&s| self.cand_of(s, 0.0)));
        if self.lags && groups.len() >= 2 {
            let cur = self.gs.cv_rms(&t, groups, 0.0);
            select::improve_lags(&self.gs, &self.cands, &mut t, groups, cur);
        }
        (fg, t)
    }

    fn ridge_lambda(&self, terms: &[usize], groups: &[usize]) -> f64 {
        let mut best = (0.0, self.gs.cv_rms(terms, groups, 0.0));
        for e in -6..=1 {
            let l = 10f64.powi(e);
            let r = self.gs.cv_rms(terms, groups, l);
            if r < best.1 {
                best = (l, r);
            }
        }
        best.0
    }

    /// The structure candidate `kind` chooses on `groups`.
    pub fn structure(&self, kind: Kind, groups: &[usize]) -> Structure {
        let ls = |terms| Structure { terms, ridge: 0.0 };
        match kind {
            Kind::PlainLs => ls(self.plain_terms(self.sensor_limit, groups)),
            Kind::PlainAll => ls(self.plain_terms(usize::MAX, groups)),
            Kind::GreedyLags => ls(self.greedy_terms(groups)),
            Kind::AllLags => {
                let mut t = self.plain_terms(self.sensor_limit, groups);
                if self.lags && groups.len() >= 2 {
                    let cur = self.gs.cv_rms(&t, groups, 0.0);
                    select::improve_lags(&self.gs, &self.cands, &mut t, groups, cur);
                }
                ls(t)
            }
            Kind::ForwardLags => ls(select::forward(
                &self.gs,
                &self.cands,
                &self.forced,
                groups,
                self.max_sensors,
                0.01,
            )
            .terms),
            Kind::FcmGra => ls(self.fcm_terms(groups).1),
            Kind::Ridge => {
                let terms = self.plain_terms(self.sensor_limit, groups);
                let ridge = self.ridge_lambda(&terms, groups);
                Structure { terms, ridge }
            }
        }
    }

    /// FCM + GRA's details on `groups`.
    pub fn fcm_detail(&self, groups: &[usize]) -> select::FcmGra {
        self.fcm_terms(groups).0
    }

    /// The allowed unlagged rise of each usable sensor after fitting on `groups` (see the range guard): the
    /// fitted range widened by its width (at least 1 K) on each side, and by [`GUARD_TIE_MARGIN_K`] more.
    pub fn bounds(&self, groups: &[usize]) -> Vec<(f64, f64)> {
        (0..self.names.len())
            .map(|s| {
                let (lo, hi) = groups.iter().fold((0.0f64, 0.0f64), |(lo, hi), &g| {
                    let (a, b) = self.group_range[g][s];
                    (lo.min(a), hi.max(b))
                });
                let w = (hi - lo).max(1.0);
                (lo - w - GUARD_TIE_MARGIN_K, hi + w + GUARD_TIE_MARGIN_K)
            })
            .collect()
    }

    /// Fits a structure on `groups` (None if singular).
    pub fn fit(&self, s: &Structure, groups: &[usize]) -> Option<Fitted> {
        Some(Fitted {
            beta: self.gs.fit(&s.terms, groups, s.ridge)?,
            bounds: self.bounds(groups),
        })
    }

    /// Prediction of row `i` by a fitted structure, with the range guard (a sensor beyond its bounds
    /// drops its own term).
    pub fn predict_row(&self, s: &Structure, f: &Fitted, i: usize) -> f64 {
        let mut p = self.gs.y_mean + f.beta[0];
        for (j, &t) in s.terms.iter().enumerate() {
            let (m, sd) = self.gs.col_stats[t];
            let out_of_range = self.sensor_of(t).is_some_and(|k| {
                let v = self.rise0[k][i];
                v < f.bounds[k].0 || v > f.bounds[k].1
            });
            let x = if out_of_range { 0.0 } else { self.cols[t][i] };
            p += f.beta[j + 1] * (x - m) / sd;
        }
        p
    }

    /// Squared error of a structure fitted on `fit_groups` over group `g`'s rows (infinite if singular).
    pub fn group_sse(&self, s: &Structure, fit_groups: &[usize], g: usize) -> f64 {
        let Some(f) = self.fit(s, fit_groups) else {
            return f64::INFINITY;
        };
        self.group_rows[g]
            .iter()
            .map(|&i| (self.y[i] - self.predict_row(s, &f, i)).powi(2))
            .sum()
    }

    /// Forward validation folds: every group of the later half (at least from the third group on) predicted
    /// from all the groups before it. Empty with fewer than 3 groups.
    pub fn forward_folds(&self) -> Vec<(Vec<usize>, usize)> {
        let g = self.order.len();
        if g < 3 {
            return vec![];
        }
        let k0 = g.div_ceil(2).max(2);
        (k0..g)
            .map(|k| (self.order[..k].to_vec(), self.order[k]))
            .collect()
    }

    /// Validation folds: forward, or each group left out in turn (operating conditions without an order).
    pub fn folds(&self) -> Vec<(Vec<usize>, usize)> {
        if self.forward {
            return self.forward_folds();
        }
        if self.order.len() < 3 {
            return vec![];
        }
        self.order
            .iter()
            .map(|&g| (self.order.iter().copied().filter(|&h| h != g).collect(), g))
            .collect()
    }

    /// Validation of `kinds` (each re-run on each fold's fitting groups).
    pub fn validate(&self, kinds: &[Kind]) -> Validation {
        let folds = self.folds();
        let mut sse = vec![vec![0.0; folds.len()]; kinds.len()];
        for (fi, (fit_groups, g)) in folds.iter().enumerate() {
            for (ki, &k) in kinds.iter().enumerate() {
                let s = self.structure(k, fit_groups);
                sse[ki][fi] = self.group_sse(&s, fit_groups, *g);
            }
        }
        let rows = folds
            .iter()
            .map(|(_, g)| self.group_rows[*g].len())
            .collect();
        Validation { folds, sse, rows }
    }
}

/// The outcome of the rule.
#[derive(Debug, Clone, Serialize)]
pub struct Decision {
    /// Index (into the kinds) of the default.
    pub chosen: usize,
    /// Index of the lowest validation RMS among the eligible candidates.
    pub best: usize,
    pub why: String,
}

/// Applies the rule (module docs) to validated candidates. `eligible[k]`: the firmware can take it;
/// `reference[k]`: one of the simple procedures (plain least squares, greedy with lags); `plain`: the index
/// of plain least squares.
pub fn decide(
    kinds: &[Kind],
    v: &Validation,
    eligible: &[bool],
    reference: &[bool],
    plain: usize,
) -> Decision {
    let score: Vec<f64> = (0..kinds.len()).map(|k| v.pooled_rms(k)).collect();
    if v.folds.is_empty() {
        return Decision {
            chosen: plain,
            best: plain,
            why: "too few groups for a forward validation (need 3): plain least squares".into(),
        };
    }
    let lowest = |keep: &dyn Fn(usize) -> bool| {
        (0..kinds.len())
            .filter(|&k| eligible[k] && score[k].is_finite() && keep(k))
            .min_by(|&a, &b| score[a].total_cmp(&score[b]))
    };
    let best = lowest(&|_| true).unwrap_or(plain);
    let simple = lowest(&|k| reference[k]).unwrap_or(plain);
    let (chosen, why) = if reference[best] {
        (
            best,
            format!("lowest forward-validation RMS ({:.4} µm)", score[best]),
        )
    } else if v.within_one_se(simple, best) {
        (
            simple,
            format!(
                "{} has the lowest validation RMS ({:.4} µm) but is within one standard error of the \
                 simpler {} ({:.4} µm): the simpler procedure",
                kinds[best].name(),
                score[best],
                kinds[simple].name(),
                score[simple]
            ),
        )
    } else {
        (
            best,
            format!(
                "lowest forward-validation RMS ({:.4} µm), better than the simple procedures' best ({}, \
                 {:.4} µm) by more than one standard error",
                score[best],
                kinds[simple].name(),
                score[simple]
            ),
        )
    };
    Decision { chosen, best, why }
}

/// Spearman rank correlation of two equally long lists (None with fewer than 3 pairs).
pub fn rank_correlation(a: &[f64], b: &[f64]) -> Option<f64> {
    if a.len() < 3 || a.len() != b.len() {
        return None;
    }
    let ranks = |v: &[f64]| -> Vec<f64> {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|&i, &j| v[i].total_cmp(&v[j]));
        let mut r = vec![0.0; v.len()];
        let mut k = 0;
        while k < idx.len() {
            let mut e = k;
            while e + 1 < idx.len() && v[idx[e + 1]] == v[idx[k]] {
                e += 1;
            }
            for &i in &idx[k..=e] {
                r[i] = (k + e) as f64 / 2.0;
            }
            k = e + 1;
        }
        r
    };
    let (ra, rb) = (ranks(a), ranks(b));
    let m = (a.len() as f64 - 1.0) / 2.0;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in ra.iter().zip(&rb) {
        sab += (x - m) * (y - m);
        saa += (x - m).powi(2);
        sbb += (y - m).powi(2);
    }
    (saa > 0.0 && sbb > 0.0).then(|| sab / (saa * sbb).sqrt())
}
