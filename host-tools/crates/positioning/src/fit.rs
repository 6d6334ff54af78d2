//! Fitting positioning-error models and choosing among them by cross-validation.
//!
//! Glossary:
//! - *observation*: one measured point: target position (mm), approach direction, run, deviation (µm).
//! - *run*: one pass over all targets (ISO 230-2 "cycle"); cross-validation leaves one run out at a time, so a
//!   model is always judged on a run it has not seen.
//! - *fold*: the rows left out together (one run; or, without runs, every k-th row).
//! - *structure*: how the two approach directions are modelled: `separate` (forward and backward curves
//!   fitted independently), `mean+const_reversal` / `mean+linear_reversal` / `mean+smooth_reversal` (one
//!   mean curve plus a reversal curve = forward − backward), or `single` (no direction information).
//! - *kind*: the curve family: `linear`, `piecewise_linear`, `spline_natural`, `spline_not_a_knot` (these three
//!   interpolate per-target means), `smoothing_spline_uniform`, `smoothing_spline_feature` (penalised
//!   least-squares B-splines, uniform knots or knots placed where the curvature is high).
//! - *ρ (rho)*: the dimensionless smoothing parameter; `λ = ρ·tr(AᵀA)/tr(P)`. It is chosen by an inner
//!   cross-validation inside each outer fold (nested), so the reported CV figure is not tuned on its own fold.
//!
//! Selection: every candidate is fitted once per fold without that fold and predicts the fold's rows; the
//! candidate with the lowest CV RMS wins, except that a simpler one within 1 % of it is preferred (order:
//! linear, natural spline, not-a-knot spline, piecewise linear, smoothing uniform, smoothing feature; and
//! single, constant / linear / smooth reversal, separate). Interpolating kinds need repeated targets (a
//! grid of ≤ 1024 positions, ≥ 2 rows per position on average); with fewer than 3 runs the folds are every
//! k-th row. The chosen model is refitted on all rows and resampled to the uniform table (C2, exact when
//! the model's knots lie on the table grid; `resampling_max_um` reports the difference otherwise).

use std::collections::HashMap;

use axcomp_core::MAX_SEGMENTS;
use axcomp_numeric::stats::rms;

use crate::guard;
use crate::spline::{self, EndCondition, NormalStats, PiecewiseCubic, SplineError};
use crate::table_file::TableFile;

mod types;
pub use types::*;
use types::{Evaluation, Problem};

// ---------------------------------------------------------------------------------------------

/// Key of a target position (grid detection): rounded to 1 nm.
fn target_key(x: f64) -> i64 {
    (x * 1e6).round() as i64
}

/// Fits every candidate, chooses the best by cross-validation, resamples it to the uniform table.
pub fn fit(obs: &[Observation], opts: &FitOptions) -> Result<FitResult, FitError> {
    let (lo, hi) = stroke(obs)?;
    let (fold, folds, split) = make_folds(obs, opts.row_folds.max(3), opts.max_folds);
    let has_fwd = obs.iter().any(|o| o.direction > 0);
    let has_bwd = obs.iter().any(|o| o.direction < 0);
    let bidirectional = has_fwd && has_bwd;
    let p = Problem {
        obs,
        fold,
        folds,
        lo,
        hi,
        grid: target_grid(obs),
    };
    let mut evaluated = evaluate_candidates(&p, opts, bidirectional)?;
    let (chosen_idx, reason) = choose(&mut evaluated, &split.method);
    let chosen = &evaluated[chosen_idx];
    let chosen_preds: Vec<f64> = obs
        .iter()
        .zip(&p.fold)
        .map(|(o, &f)| chosen.fold_curves[f].predict(o.target_mm, o.direction))
        .collect();

    let raw_rms = rms(obs.iter().map(|o| o.deviation_um));
    let cv_rms = chosen.cand.cv_rms_um;
    let dev: Vec<f64> = obs.iter().map(|o| o.deviation_um).collect();
    let verdict = guard::judge(
        &dev,
        &chosen_preds,
        &p.fold,
        opts.improvement_ratio,
        opts.runs_improved_fraction,
        &split.method,
    );

    // Each direction's curve holds its end value beyond the targets that direction reached (when one
    // direction covers less of the stroke than the other), rather than extrapolating its last pieces.
    let curves = hold_beyond_each_direction(chosen.final_curves.clone(), obs, lo, hi);
    let (fwd, bwd, segment_mm, resampling_max) = resample_table(&curves, lo, hi, opts)?;
    let table = TableFile {
        format: crate::table_file::FORMAT.to_string(),
        axis: opts.axis.clone(),
        start_mm: lo,
        segment_mm,
        forward: fwd.coeffs,
        backward: bwd.map(|b| b.coeffs).unwrap_or_default(),
        model: chosen.cand.name.clone(),
        cv_rms_um: cv_rms,
        raw_rms_um: raw_rms,
        cv_method: split.method.clone(),
        provenance: None,
    };
    let candidates = evaluated.iter().map(|e| e.cand.clone()).collect();
    let chosen_name = chosen.cand.name.clone();
    let preds = chosen_preds;
    Ok(FitResult {
        table,
        curves,
        chosen: chosen_name,
        reason,
        candidates,
        cv_predictions: preds,
        fold_of_row: p.fold.clone(),
        split,
        raw_rms_um: raw_rms,
        cv_rms_um: cv_rms,
        resampling_max_um: resampling_max,
        guard: verdict,
    })
}

/// The stroke `(lo, hi)` of the targets, after checking there are enough finite rows.
fn stroke(obs: &[Observation]) -> Result<(f64, f64), FitError> {
    if obs.len() < 4 {
        return Err(FitError::TooFewPoints {
            needed: 4,
            got: obs.len(),
        });
    }
    for (i, o) in obs.iter().enumerate() {
        if !o.target_mm.is_finite() {
            return Err(FitError::NonFinite {
                row: i,
                what: "target_mm",
            });
        }
        if !o.deviation_um.is_finite() {
            return Err(FitError::NonFinite {
                row: i,
                what: "deviation",
            });
        }
    }
    let lo = obs
        .iter()
        .map(|o| o.target_mm)
        .fold(f64::INFINITY, f64::min);
    let hi = obs
        .iter()
        .map(|o| o.target_mm)
        .fold(f64::NEG_INFINITY, f64::max);
    if !(hi > lo) {
        return Err(FitError::NoStroke(lo));
    }
    Ok((lo, hi))
}

/// Most distinct target positions that still count as a grid of targets (ISO 230-2 style runs).
const MAX_GRID_TARGETS: usize = 1024;

/// The distinct targets, sorted, when the rows lie on a grid of targets (2..=1024 positions, ≥ 2 rows per
/// position on average); `None` for scattered positions.
fn target_grid(obs: &[Observation]) -> Option<Vec<f64>> {
    let mut keys: HashMap<i64, f64> = HashMap::new();
    let mut too_many = false;
    for o in obs {
        keys.entry(target_key(o.target_mm)).or_insert(o.target_mm);
        if keys.len() > MAX_GRID_TARGETS {
            too_many = true;
            break;
        }
    }
    if !too_many && keys.len() >= 2 && keys.len() * 2 <= obs.len() {
        let mut g: Vec<f64> = keys.into_values().collect();
        g.sort_by(f64::total_cmp);
        Some(g)
    } else {
        None
    }
}

/// A candidate evaluated: the per-fold curves are kept, not the per-row predictions (15 candidates × rows
/// would dominate the memory of a large campaign); the chosen one's predictions are computed again.
struct Evaluated {
    cand: Candidate,
    fold_curves: Vec<Curves>,
    final_curves: Curves,
}

/// The structures fitted for a model kind: one curve without two directions, else those of the kind.
fn structures_for(kind: Kind, bidirectional: bool) -> Vec<Structure> {
    if !bidirectional {
        return vec![Structure::Single];
    }
    match kind {
        Kind::Linear => vec![Structure::Separate, Structure::MeanConstReversal],
        Kind::PiecewiseLinear | Kind::SplineNatural | Kind::SplineNotAKnot => vec![
            Structure::Separate,
            Structure::MeanConstReversal,
            Structure::MeanLinearReversal,
        ],
        Kind::SmoothingSplineUniform | Kind::SmoothingSplineFeature => {
            vec![Structure::Separate, Structure::MeanSmoothReversal]
        }
    }
}

/// Every candidate (kind × structure, filtered by `opts.only`) cross-validated; an error naming each
/// failure when none could be evaluated.
fn evaluate_candidates(
    p: &Problem,
    opts: &FitOptions,
    bidirectional: bool,
) -> Result<Vec<Evaluated>, FitError> {
    let (obs, folds) = (p.obs, p.folds);
    let mut kinds = vec![Kind::Linear];
    if p.grid.is_some() {
        kinds.extend([
            Kind::PiecewiseLinear,
            Kind::SplineNatural,
            Kind::SplineNotAKnot,
        ]);
    }
    kinds.extend([Kind::SmoothingSplineUniform, Kind::SmoothingSplineFeature]);
    let mut evaluated: Vec<Evaluated> = Vec::new();
    let mut failures: Vec<String> = Vec::new();
    for kind in kinds {
        let structures: Vec<Structure> = structures_for(kind, bidirectional)
            .into_iter()
            .filter(|st| {
                let name = format!("{}/{}", kind.name(), st.name());
                opts.only.is_empty() || opts.only.iter().any(|o| name.starts_with(o.as_str()))
            })
            .collect();
        if structures.is_empty() {
            continue;
        }
        let results = evaluate(p, kind, &structures);
        for (structure, ev) in structures.into_iter().zip(results) {
            let name = format!("{}/{}", kind.name(), structure.name());
            match ev {
                Ok((fold_curves, final_curves, rho)) => {
                    let cv = rms(obs.iter().zip(&p.fold).map(|(o, &f)| {
                        o.deviation_um - fold_curves[f].predict(o.target_mm, o.direction)
                    }));
                    if cv.is_finite() {
                        evaluated.push(Evaluated {
                            cand: Candidate {
                                name,
                                kind,
                                structure,
                                cv_rms_um: cv,
                                rho,
                                intervals: final_curves.forward.coeffs.len(),
                            },
                            fold_curves,
                            final_curves,
                        });
                    } else {
                        failures.push(format!("{name}: non-finite CV figure"));
                    }
                }
                Err(e) => failures.push(format!("{name}: {e}")),
            }
        }
        if let Some(note) = opts.progress.0 {
            note(&format!(
                "{} cross-validated in {folds} folds ({} candidates so far)",
                kind.name(),
                evaluated.len() + failures.len()
            ));
        }
    }
    if evaluated.is_empty() {
        return Err(FitError::NoCandidate(failures.join("; ")));
    }
    Ok(evaluated)
}

/// Sorts the candidates by CV RMS and picks the simplest within 1 % of the best: its index and the reason.
fn choose(evaluated: &mut [Evaluated], method: &str) -> (usize, String) {
    evaluated.sort_by(|a, b| a.cand.cv_rms_um.total_cmp(&b.cand.cv_rms_um));
    let best_cv = evaluated[0].cand.cv_rms_um;
    // Near-tie (within 1 % of the best CV RMS): prefer the simplest model.
    const TIE: f64 = 1.01;
    let chosen_idx = (0..evaluated.len())
        .filter(|&i| evaluated[i].cand.cv_rms_um <= best_cv * TIE)
        .min_by_key(|&i| {
            let c = &evaluated[i].cand;
            (c.kind.simplicity(), c.structure.simplicity())
        })
        .unwrap();
    let chosen = &evaluated[chosen_idx];
    let reason = if chosen_idx == 0 {
        format!(
            "lowest {} RMS ({:.3} µm) of {} candidates",
            method,
            chosen.cand.cv_rms_um,
            evaluated.len()
        )
    } else {
        format!(
            "simplest candidate within 1 % of the lowest {} RMS ({:.3} µm vs best {:.3} µm, {})",
            method, chosen.cand.cv_rms_um, best_cv, evaluated[0].cand.name
        )
    };

    (chosen_idx, reason)
}

/// The chosen curves resampled to the uniform table: forward and backward tables, segment length, and the
/// largest difference between the tables and the curves over the stroke.
#[allow(clippy::type_complexity)]
fn resample_table(
    curves: &Curves,
    lo: f64,
    hi: f64,
    opts: &FitOptions,
) -> Result<(spline::UniformTable, Option<spline::UniformTable>, f64, f64), FitError> {
    let (segments, segment_mm) = table_grid(curves, lo, hi, opts)?;
    let fwd = spline::resample_uniform(&curves.forward, lo, segment_mm, segments)?;
    let bwd = match &curves.backward {
        Some(b) => Some(spline::resample_uniform(b, lo, segment_mm, segments)?),
        None => None,
    };
    let mut resampling_max = 0.0f64;
    let probes = (segments * 16).max(400);
    for k in 0..=probes {
        let x = lo + (hi - lo) * k as f64 / probes as f64;
        resampling_max = resampling_max.max((fwd.eval(x) - curves.forward.eval(x)).abs());
        if let (Some(bt), Some(bc)) = (&bwd, &curves.backward) {
            resampling_max = resampling_max.max((bt.eval(x) - bc.eval(x)).abs());
        }
    }
    Ok((fwd, bwd, segment_mm, resampling_max))
}

/// The targets each approach direction reached, `[forward, backward]` as `(min, max)` mm (`None` for a
/// direction without rows).
pub fn direction_ranges(obs: &[Observation]) -> [Option<(f64, f64)>; 2] {
    let range = |want: i8| {
        obs.iter()
            .filter(|o| o.direction == want)
            .fold(None, |r: Option<(f64, f64)>, o| {
                let v = o.target_mm;
                Some(r.map_or((v, v), |(a, b)| (a.min(v), b.max(v))))
            })
    };
    [range(1), range(-1)]
}

/// Bidirectional curves with each direction's curve held at its end values beyond the targets that
/// direction reached, where that is less than the stroke `[lo, hi]` (else unchanged).
fn hold_beyond_each_direction(curves: Curves, obs: &[Observation], lo: f64, hi: f64) -> Curves {
    let Some(backward) = curves.backward else {
        return curves;
    };
    let tol = 1e-9 * (hi - lo).abs().max(1.0);
    let hold = |c: PiecewiseCubic, r: Option<(f64, f64)>| match r {
        Some((a, b)) if a > lo + tol || b < hi - tol => c.held_beyond(a, b, lo, hi),
        _ => c,
    };
    let [fwd, bwd] = direction_ranges(obs);
    Curves {
        forward: hold(curves.forward, fwd),
        backward: Some(hold(backward, bwd)),
    }
}

/// Fold index per row: leave-one-run-out when there are 3 ..= `max_folds` runs, consecutive runs grouped
/// into `max_folds` folds when there are more (`leave-runs-out`), otherwise every k-th row.
fn make_folds(
    obs: &[Observation],
    row_folds: usize,
    max_folds: usize,
) -> (Vec<usize>, usize, CvSplit) {
    let mut runs: Vec<i64> = obs.iter().map(|o| o.run).collect();
    runs.sort_unstable();
    runs.dedup();
    let max_folds = max_folds.max(3);
    if runs.len() > max_folds {
        // Run index i of n goes to group ⌊i·k/n⌋: k groups of consecutive runs, sizes differing by ≤ 1.
        let (n, k) = (runs.len(), max_folds);
        let index: HashMap<i64, usize> = runs
            .iter()
            .enumerate()
            .map(|(i, &r)| (r, i * k / n))
            .collect();
        let fold = obs.iter().map(|o| index[&o.run]).collect();
        return (
            fold,
            k,
            CvSplit {
                method: "leave-runs-out".into(),
                folds: k,
            },
        );
    }
    if runs.len() >= 3 {
        let index: HashMap<i64, usize> = runs.iter().enumerate().map(|(i, &r)| (r, i)).collect();
        let fold = obs.iter().map(|o| index[&o.run]).collect();
        (
            fold,
            runs.len(),
            CvSplit {
                method: "leave-one-run-out".into(),
                folds: runs.len(),
            },
        )
    } else {
        let k = row_folds.min(obs.len());
        let fold = (0..obs.len()).map(|i| i % k).collect();
        (
            fold,
            k,
            CvSplit {
                method: "k-fold-by-row".into(),
                folds: k,
            },
        )
    }
}

/// Number and length of the uniform table segments covering `[lo, hi]`.
fn table_grid(
    curves: &Curves,
    lo: f64,
    hi: f64,
    opts: &FitOptions,
) -> Result<(usize, f64), FitError> {
    let range = hi - lo;
    match (opts.segments, opts.segment_mm) {
        (Some(_), Some(_)) => Err(FitError::BadTable(
            "give either segments or segment_mm, not both".into(),
        )),
        (Some(n), None) => {
            if n == 0 || n > MAX_SEGMENTS {
                return Err(FitError::BadTable(format!(
                    "segments = {n} is outside 1..={MAX_SEGMENTS}"
                )));
            }
            Ok((n, range / n as f64))
        }
        (None, Some(s)) => {
            if !(s > 0.0) || !s.is_finite() {
                return Err(FitError::BadTable(format!("segment_mm = {s} must be > 0")));
            }
            let n = (range / s - 1e-9).ceil().max(1.0) as usize;
            if n > MAX_SEGMENTS {
                return Err(FitError::BadTable(format!(
                    "segment_mm = {s} needs {n} segments over {range} mm (at most {MAX_SEGMENTS})"
                )));
            }
            Ok((n, s))
        }
        (None, None) => {
            // Four table segments per shortest knot interval of the model, at most the firmware's MAX_SEGMENTS.
            let min_gap = curves
                .forward
                .knots
                .windows(2)
                .map(|w| w[1] - w[0])
                .chain(
                    curves
                        .backward
                        .iter()
                        .flat_map(|b| b.knots.windows(2).map(|w| w[1] - w[0])),
                )
                .fold(f64::INFINITY, f64::min);
            let n = if min_gap.is_finite() && min_gap > 0.0 {
                (range / (min_gap / 4.0))
                    .round()
                    .clamp(16.0, MAX_SEGMENTS as f64) as usize
            } else {
                64
            };
            Ok((n, range / n as f64))
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Candidate evaluation: per-fold curves (fitted without the fold) and the final curves (all rows).

fn evaluate(
    p: &Problem,
    kind: Kind,
    structures: &[Structure],
) -> Vec<Result<Evaluation, FitError>> {
    match kind {
        Kind::SmoothingSplineUniform | Kind::SmoothingSplineFeature => {
            smoothing::evaluate_all(p, kind, structures)
        }
        Kind::Linear => structures
            .iter()
            .map(|&st| linear::evaluate(p, st))
            .collect(),
        _ => structures
            .iter()
            .map(|&structure| {
                let mut per_fold = Vec::with_capacity(p.folds);
                for f in 0..p.folds {
                    let train: Vec<&Observation> = p
                        .obs
                        .iter()
                        .zip(&p.fold)
                        .filter(|(_, g)| **g != f)
                        .map(|(o, _)| o)
                        .collect();
                    per_fold.push(fit_simple(p, kind, structure, &train)?);
                }
                let all: Vec<&Observation> = p.obs.iter().collect();
                let fin = fit_simple(p, kind, structure, &all)?;
                Ok((per_fold, fin, Vec::new()))
            })
            .collect(),
    }
}

mod linear {
    //! Straight lines by least squares from per-fold sufficient statistics (one pass over the points).
    use super::*;

    pub(super) fn evaluate(p: &Problem, structure: Structure) -> Result<Evaluation, FitError> {
        // Columns: Single/Separate [1, x−lo] per block; MeanConstReversal [1, x−lo, d/2].
        let (k, blocks) = match structure {
            Structure::Single => (2, 1),
            Structure::Separate => (2, 2),
            Structure::MeanConstReversal => (3, 1),
            _ => {
                return Err(FitError::NoCandidate(format!(
                    "linear with {}",
                    structure.name()
                )));
            }
        };
        let mut stats = vec![vec![NormalStats::zeros(k, k - 1); blocks]; p.folds];
        for (o, &f) in p.obs.iter().zip(&p.fold) {
            let u = o.target_mm - p.lo;
            match structure {
                Structure::Single => stats[f][0].add_row(0, &[1.0, u], o.deviation_um),
                Structure::Separate => {
                    if o.direction != 0 {
                        stats[f][usize::from(o.direction < 0)].add_row(
                            0,
                            &[1.0, u],
                            o.deviation_um,
                        );
                    }
                }
                _ => stats[f][0].add_row(0, &[1.0, u, 0.5 * o.direction as f64], o.deviation_um),
            }
        }
        let fit_without = |exclude: Option<usize>| -> Result<Curves, FitError> {
            let mut c = Vec::new();
            for b in 0..blocks {
                let mut t = NormalStats::zeros(k, k - 1);
                for (f, s) in stats.iter().enumerate() {
                    if Some(f) != exclude {
                        t.add(&s[b], 1.0);
                    }
                }
                if t.rows < k {
                    return Err(FitError::TooFewPoints {
                        needed: k,
                        got: t.rows,
                    });
                }
                c.push(t.ata.solve(&t.aty)?);
            }
            let (lo, hi) = (p.lo, p.hi);
            Ok(match structure {
                Structure::Single => Curves {
                    forward: PiecewiseCubic::line(lo, hi, c[0][0], c[0][1]),
                    backward: None,
                },
                Structure::Separate => Curves {
                    forward: PiecewiseCubic::line(lo, hi, c[0][0], c[0][1]),
                    backward: Some(PiecewiseCubic::line(lo, hi, c[1][0], c[1][1])),
                },
                _ => {
                    let c = &c[0];
                    Curves {
                        forward: PiecewiseCubic::line(lo, hi, c[0] + 0.5 * c[2], c[1]),
                        backward: Some(PiecewiseCubic::line(lo, hi, c[0] - 0.5 * c[2], c[1])),
                    }
                }
            })
        };
        let per_fold = (0..p.folds)
            .map(|f| fit_without(Some(f)))
            .collect::<Result<Vec<_>, _>>()?;
        Ok((per_fold, fit_without(None)?, Vec::new()))
    }
}

/// Least squares on a few dense columns: the host numeric layer's QR solve
/// (`axcomp_numeric::lsq::lstsq`, no ridge, no column treated as intercept); a rank-deficient
/// design (e.g. every reversal at one target) is [`SplineError::Singular`] as before.
fn dense_lstsq(
    rows: impl Iterator<Item = (Vec<f64>, f64)>,
    k: usize,
) -> Result<Vec<f64>, FitError> {
    let (xs, ys): (Vec<Vec<f64>>, Vec<f64>) = rows.unzip();
    let x = axcomp_numeric::lsq::DMatrix::from_fn(xs.len(), k, |i, j| xs[i][j]);
    axcomp_numeric::lsq::lstsq(&x, &ys, 0.0, None)
        .map(|f| f.coef)
        .map_err(|_| FitError::Spline(SplineError::Singular))
}

/// Per-target mean of the given rows, sorted by target.
fn target_means<'a>(rows: impl Iterator<Item = &'a Observation>) -> Vec<(f64, f64)> {
    let mut m: HashMap<i64, (f64, f64, usize)> = HashMap::new();
    for o in rows {
        let e = m
            .entry(target_key(o.target_mm))
            .or_insert((o.target_mm, 0.0, 0));
        e.1 += o.deviation_um;
        e.2 += 1;
    }
    let mut v: Vec<(f64, f64)> = m.into_values().map(|(x, s, n)| (x, s / n as f64)).collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v
}

fn interpolate_kind(
    kind: Kind,
    pts: &[(f64, f64)],
    lo: f64,
    hi: f64,
) -> Result<PiecewiseCubic, FitError> {
    if pts.is_empty() {
        return Err(FitError::TooFewPoints { needed: 1, got: 0 });
    }
    if pts.len() == 1 {
        return Ok(PiecewiseCubic::constant(lo, hi, pts[0].1));
    }
    let x: Vec<f64> = pts.iter().map(|p| p.0).collect();
    let y: Vec<f64> = pts.iter().map(|p| p.1).collect();
    Ok(match kind {
        Kind::PiecewiseLinear => spline::piecewise_linear(&x, &y)?,
        Kind::SplineNatural => spline::interpolate(&x, &y, EndCondition::Natural)?,
        Kind::SplineNotAKnot => spline::interpolate(&x, &y, EndCondition::NotAKnot)?,
        _ => unreachable!("not an interpolating kind"),
    })
}

/// Linear and interpolating kinds fitted on `train`.
fn fit_simple(
    p: &Problem,
    kind: Kind,
    structure: Structure,
    train: &[&Observation],
) -> Result<Curves, FitError> {
    let (lo, hi) = (p.lo, p.hi);
    let fwd: Vec<&Observation> = train.iter().copied().filter(|o| o.direction > 0).collect();
    let bwd: Vec<&Observation> = train.iter().copied().filter(|o| o.direction < 0).collect();
    match (kind, structure) {
        (k, Structure::Single) if k.is_grid() => Ok(Curves {
            forward: interpolate_kind(k, &target_means(train.iter().copied()), lo, hi)?,
            backward: None,
        }),
        (k, Structure::Separate) if k.is_grid() => Ok(Curves {
            forward: interpolate_kind(k, &target_means(fwd.iter().copied()), lo, hi)?,
            backward: Some(interpolate_kind(
                k,
                &target_means(bwd.iter().copied()),
                lo,
                hi,
            )?),
        }),
        (k, Structure::MeanConstReversal | Structure::MeanLinearReversal) if k.is_grid() => {
            let mf = target_means(fwd.iter().copied());
            let mb = target_means(bwd.iter().copied());
            let bmap: HashMap<i64, f64> = mb.iter().map(|&(x, y)| (target_key(x), y)).collect();
            let fmap: HashMap<i64, f64> = mf.iter().map(|&(x, y)| (target_key(x), y)).collect();
            // Reversal (forward − backward) at targets measured both ways.
            let rev: Vec<(f64, f64)> = mf
                .iter()
                .filter_map(|&(x, yf)| bmap.get(&target_key(x)).map(|yb| (x, yf - yb)))
                .collect();
            if rev.is_empty() {
                return Err(FitError::TooFewPoints { needed: 1, got: 0 });
            }
            let reversal = if structure == Structure::MeanConstReversal || rev.len() < 2 {
                let r = rev.iter().map(|r| r.1).sum::<f64>() / rev.len() as f64;
                PiecewiseCubic::constant(lo, hi, r)
            } else {
                let c = dense_lstsq(rev.iter().map(|&(x, r)| (vec![1.0, x - lo], r)), 2)?;
                PiecewiseCubic::line(lo, hi, c[0], c[1])
            };
            // Mean curve through per-target means of the two directions.
            let mut targets: Vec<f64> = mf.iter().chain(mb.iter()).map(|p| p.0).collect();
            targets.sort_by(f64::total_cmp);
            targets.dedup_by(|a, b| target_key(*a) == target_key(*b));
            let mean: Vec<(f64, f64)> = targets
                .iter()
                .map(|&x| {
                    let k = target_key(x);
                    let r = reversal.eval(x);
                    let y = match (fmap.get(&k), bmap.get(&k)) {
                        (Some(f), Some(b)) => 0.5 * (f + b),
                        (Some(f), None) => f - 0.5 * r,
                        (None, Some(b)) => b + 0.5 * r,
                        (None, None) => unreachable!(),
                    };
                    (x, y)
                })
                .collect();
            let mean = interpolate_kind(k, &mean, lo, hi)?;
            Ok(Curves {
                forward: mean.combine(1.0, &reversal, 0.5),
                backward: Some(mean.combine(1.0, &reversal, -0.5)),
            })
        }
        _ => Err(FitError::NoCandidate(format!(
            "{} with {}",
            kind.name(),
            structure.name()
        ))),
    }
}

// ---------------------------------------------------------------------------------------------

mod smoothing;
pub use smoothing::feature_breaks;

#[cfg(test)]
pub(crate) mod tests;
