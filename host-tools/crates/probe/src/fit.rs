//! The calibration fit ([`calibrate`]): the constant model and outlier screening, the candidates (constant,
//! the bilinear reference grid, harmonics) scored by cross-validation over direction folds, the chosen
//! model's joint fit of centre and coefficients, and the repeatability of repeated touches.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::geometry::{self, algebraic_sphere, norm, sub};
use crate::model::{self, DirSpeed, Structure};
use crate::{
    Calibration, FORMAT, ProbeError, Sphere, Touch, azimuth_gap, flag_outliers, validate_touches,
};

/// How the model is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelChoice {
    /// Lowest cross-validated RMS among all candidates.
    Auto,
    Constant,
    Bilinear,
    Harmonic,
}

impl std::str::FromStr for ModelChoice {
    type Err = ProbeError;
    fn from_str(s: &str) -> Result<Self, ProbeError> {
        Ok(match s {
            "auto" => ModelChoice::Auto,
            "constant" | "probe_radius" => ModelChoice::Constant,
            "bilinear" => ModelChoice::Bilinear,
            "harmonic" => ModelChoice::Harmonic,
            _ => {
                return Err(ProbeError::BadOption(format!(
                    "--pretravel-model `{s}`: expected auto, constant, bilinear or harmonic"
                )));
            }
        })
    }
}

/// Options of [`calibrate`].
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationOptions {
    pub sphere_diameter_mm: f64,
    pub model: ModelChoice,
    /// Outlier threshold in robust standard deviations.
    pub outlier_mad: f64,
    /// Number of cross-validation folds.
    pub folds: usize,
}

impl CalibrationOptions {
    pub fn new(sphere_diameter_mm: f64) -> Self {
        CalibrationOptions {
            sphere_diameter_mm,
            model: ModelChoice::Auto,
            outlier_mad: crate::DEFAULT_OUTLIER_MAD,
            folds: 5,
        }
    }
}

/// A cross-validated candidate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CandidateScore {
    pub model: String,
    pub structure: Structure,
    pub coefficients: usize,
    pub cv_rms_um: f64,
}

/// A flagged touch.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outlier {
    /// Index into the touches given to [`calibrate`].
    pub index: usize,
    pub row: String,
    /// Radial residual under the final model, µm (positive: latched short of the surface).
    pub residual_um: f64,
    /// `early trigger (false trip?)` or `late trigger (bounce / double trigger?)`.
    pub kind: String,
}

/// Everything [`calibrate`] finds.
#[derive(Debug, Clone)]
pub struct CalibrationResult {
    /// The chosen model.
    pub calibration: Calibration,
    /// The seed's reference method (bilinear grid + speed slope, centre from the plain sphere fit).
    pub reference: Calibration,
    /// One effective radius (the plain method).
    pub plain: Calibration,
    pub algebraic: Sphere,
    /// Free-radius geometric fit of the latched points (the seed's plain sphere fit, inliers).
    pub geometric_free: Sphere,
    pub candidates: Vec<CandidateScore>,
    pub why: String,
    pub outliers: Vec<Outlier>,
    /// Radial residual of every touch under the chosen model, µm.
    pub residual_um: Vec<f64>,
    /// Two standard deviations of repeated touches (same direction and speed), µm; `None` without repeats.
    pub repeatability_2sigma_um: Option<f64>,
    /// Number of repeat groups behind it.
    pub repeat_groups: usize,
}

/// Key of a direction (0.1° of azimuth and elevation; the azimuth is ignored at the pole).
fn direction_key(d: DirSpeed) -> (i64, i64) {
    let el = (d.elevation_deg() * 10.0).round() as i64;
    let az = if el >= 899 {
        0
    } else {
        ((d.azimuth_deg() * 10.0).round() as i64) % 3600
    };
    (az, el)
}

/// Linear least squares of `y` on the structure's basis over `rows`, with a tiny penalty for solvability
/// (bilinear: first differences between neighbouring nodes, so a node without data takes its neighbours'
/// value; otherwise a ridge on the non-constant coefficients). Returns `None` when singular.
fn fit_linear(s: &Structure, ds: &[DirSpeed], y: &[f64], rows: &[usize]) -> Option<Vec<f64>> {
    let (g, b) = gram(s, ds, y, rows);
    solve_penalised(s, g, b)
}

/// ΦᵀΦ and Φᵀy over `rows`.
fn gram(s: &Structure, ds: &[DirSpeed], y: &[f64], rows: &[usize]) -> (DMatrix<f64>, DVector<f64>) {
    let p = s.len();
    let mut g = DMatrix::<f64>::zeros(p, p);
    let mut b = DVector::<f64>::zeros(p);
    let mut phi = vec![0.0; p];
    for &i in rows {
        s.basis(ds[i], &mut phi);
        for a in 0..p {
            if phi[a] == 0.0 {
                continue;
            }
            b[a] += phi[a] * y[i];
            for c in 0..p {
                g[(a, c)] += phi[a] * phi[c];
            }
        }
    }
    (g, b)
}

fn solve_penalised(s: &Structure, mut g: DMatrix<f64>, b: DVector<f64>) -> Option<Vec<f64>> {
    let p = s.len();
    let scale = (0..p).map(|k| g[(k, k)]).sum::<f64>() / p as f64;
    let lam = 1e-7 * scale.max(1e-12);
    match s {
        Structure::Bilinear {
            azimuth_nodes_deg: az,
            elevation_nodes_deg: el,
        } => {
            let na = az.len();
            let mut offs = Vec::new();
            let mut o = 0;
            for &e in el {
                offs.push(o);
                o += if e >= 89.9 { 1 } else { na };
            }
            let mut pair = |a: usize, c: usize| {
                if a == c {
                    return;
                }
                g[(a, a)] += lam;
                g[(c, c)] += lam;
                g[(a, c)] -= lam;
                g[(c, a)] -= lam;
            };
            for (j, &e) in el.iter().enumerate() {
                if e < 89.9 {
                    for k in 0..na {
                        pair(offs[j] + k, offs[j] + (k + 1) % na);
                    }
                }
                if j + 1 < el.len() {
                    for k in 0..na {
                        let a = offs[j] + if e >= 89.9 { 0 } else { k };
                        let c = offs[j + 1] + if el[j + 1] >= 89.9 { 0 } else { k };
                        pair(a, c);
                    }
                }
            }
            // The speed slope: a tiny ridge.
            g[(p - 1, p - 1)] += lam;
        }
        _ => {
            for k in 1..p {
                g[(k, k)] += lam;
            }
        }
    }
    let ch = g.cholesky()?;
    let x = ch.solve(&b);
    x.iter()
        .all(|v| v.is_finite())
        .then(|| x.iter().copied().collect())
}

/// Joint Levenberg–Marquardt fit of the centre and the coefficients of a structure (sphere radius fixed).
fn joint_fit(
    s: &Structure,
    touches: &[Touch],
    ds: &[DirSpeed],
    rows: &[usize],
    radius_mm: f64,
    center0: [f64; 3],
) -> Result<([f64; 3], Vec<f64>), ProbeError> {
    let y: Vec<f64> = touches
        .iter()
        .map(|t| norm(sub(t.position_mm, center0)) - radius_mm)
        .collect();
    let coef0 = fit_linear(s, ds, &y, rows)
        .ok_or_else(|| ProbeError::Degenerate(format!("{}: singular least squares", s.name())))?;
    let p = s.len();
    let mut x0 = DVector::zeros(3 + p);
    for k in 0..3 {
        x0[k] = center0[k];
    }
    for k in 0..p {
        x0[3 + k] = coef0[k];
    }
    let mut phi = vec![0.0; p];
    let x = geometry::levenberg_marquardt(
        x0,
        rows.len(),
        |x, r, j| {
            let c = [x[0], x[1], x[2]];
            for (ri, &i) in rows.iter().enumerate() {
                let d = sub(touches[i].position_mm, c);
                let l = norm(d).max(1e-300);
                s.basis(ds[i], &mut phi);
                let mut m = 0.0;
                for k in 0..p {
                    m += phi[k] * x[3 + k];
                    j[(ri, 3 + k)] = -phi[k];
                }
                r[ri] = l - radius_mm - m;
                for k in 0..3 {
                    j[(ri, k)] = -d[k] / l;
                }
            }
        },
        50,
    )?;
    Ok((
        [x[0], x[1], x[2]],
        (0..p).map(|k| x[3 + k]).collect::<Vec<_>>(),
    ))
}

/// Radial residuals (µm) of every touch under (centre, structure, coefficients).
fn residuals_um(
    s: &Structure,
    coef: &[f64],
    touches: &[Touch],
    ds: &[DirSpeed],
    c: [f64; 3],
    radius_mm: f64,
) -> Vec<f64> {
    touches
        .iter()
        .zip(ds)
        .map(|(t, d)| (norm(sub(t.position_mm, c)) - radius_mm - s.eval(coef, *d)) * 1000.0)
        .collect()
}

use axcomp_numeric::stats::rms;

/// Cross-validated RMS (µm) of a structure with the centre fixed, folds by direction group.
fn cv_rms(
    s: &Structure,
    ds: &[DirSpeed],
    y: &[f64],
    rows: &[usize],
    fold: &[usize],
    k: usize,
) -> f64 {
    let mut sse = 0.0;
    let mut n = 0usize;
    // Per-fold Gram matrices once; a fold's training Gram is the total minus its own.
    let tests: Vec<Vec<usize>> = (0..k)
        .map(|f| rows.iter().copied().filter(|&i| fold[i] == f).collect())
        .collect();
    let parts: Vec<(DMatrix<f64>, DVector<f64>)> =
        tests.iter().map(|t| gram(s, ds, y, t)).collect();
    let mut g_all = DMatrix::<f64>::zeros(s.len(), s.len());
    let mut b_all = DVector::<f64>::zeros(s.len());
    for (g, b) in &parts {
        g_all += g;
        b_all += b;
    }
    for (f, test) in tests.iter().enumerate() {
        if test.is_empty() {
            continue;
        }
        let Some(coef) = solve_penalised(s, &g_all - &parts[f].0, &b_all - &parts[f].1) else {
            return f64::INFINITY;
        };
        for &i in test {
            let e = (y[i] - s.eval(&coef, ds[i])) * 1000.0;
            sse += e * e;
            n += 1;
        }
    }
    if n == 0 {
        f64::INFINITY
    } else {
        (sse / n as f64).sqrt()
    }
}

/// Calibrates on touches of one reference sphere of diameter `opts.sphere_diameter_mm`.
/// Calibrates on touches of one reference sphere of diameter `opts.sphere_diameter_mm`.
pub fn calibrate(
    touches: &[Touch],
    labels: &[String],
    opts: &CalibrationOptions,
) -> Result<CalibrationResult, ProbeError> {
    let (pts, algebraic) = checked_points(touches, labels, opts)?;
    let radius = opts.sphere_diameter_mm / 2.0;
    let n = touches.len();
    let (ds, feed_range, one_speed) = dir_speeds(touches);
    let all: Vec<usize> = (0..n).collect();

    // ---- constant model and first outlier pass ----
    let constant = Structure::Constant;
    let (c0, k0) = joint_fit(&constant, touches, &ds, &all, radius, algebraic.center_mm)?;
    let res0 = residuals_um(&constant, &k0, touches, &ds, c0, radius);
    let out = flag_outliers(&res0, opts.outlier_mad);

    // ---- direction groups and folds, candidates ----
    let folds = DirectionFolds::new(&ds, opts.folds);
    let harmonic = harmonic_candidates(&folds.keys, one_speed);
    let (mut out, mut inl, centre) =
        screen_with_richest(&harmonic, touches, &ds, radius, c0, out, opts.outlier_mad)?;

    // Plain sphere fit (free radius) of the inliers: the seed's first step; its centre is the reference's.
    let inl_pts: Vec<[f64; 3]> = inl.iter().map(|&i| pts[i]).collect();
    let geometric_free = geometry::geometric_sphere(&inl_pts, None)?;
    let bilinear = bilinear_grid(&ds);
    let y_h: Vec<f64> = pts.iter().map(|p| norm(sub(*p, centre)) - radius).collect();
    let y_ref: Vec<f64> = pts
        .iter()
        .map(|p| norm(sub(*p, geometric_free.center_mm)) - radius)
        .collect();
    let candidates = score_candidates(
        &[(&constant, &y_h[..]), (&bilinear, &y_ref[..])],
        &harmonic,
        &y_h,
        &ds,
        &inl,
        &folds,
    );
    let (chosen, why) = choose(opts.model, &candidates, folds.k);

    let fitter = ModelFitter {
        touches,
        ds: &ds,
        radius,
        y_ref: &y_ref,
        reference_centre: geometric_free.center_mm,
        sphere_diameter_mm: opts.sphere_diameter_mm,
        feed_range,
        el_range: ds.iter().fold([90.0f64, -90.0f64], |a, d| {
            [a[0].min(d.elevation_deg()), a[1].max(d.elevation_deg())]
        }),
        az_gap: azimuth_gap(&ds),
    };
    let mut calibration = fitter.fit(&chosen, &inl, centre)?;
    // Outliers re-detected under the chosen model; refit once if they changed.
    let out2 = flag_outliers(&fitter.residuals(&calibration), opts.outlier_mad);
    if out2 != out {
        out = out2;
        inl = (0..n).filter(|&i| !out[i]).collect();
        calibration = fitter.fit(&chosen, &inl, calibration.sphere_center_mm)?;
    }
    let reference = fitter.fit(&bilinear, &inl, centre)?;
    let plain = fitter.fit(&constant, &inl, centre)?;
    let residual_um = fitter.residuals(&calibration);
    let outliers = outlier_list(&out, &residual_um, labels);
    let (repeatability_2sigma_um, repeat_groups) =
        repeatability(touches, &inl, &folds.group, calibration.sphere_center_mm);
    Ok(CalibrationResult {
        calibration,
        reference,
        plain,
        algebraic,
        geometric_free,
        candidates,
        why,
        outliers,
        residual_um,
        repeatability_2sigma_um,
        repeat_groups,
    })
}

/// The checks before any fit (diameter, touches, ≥ 4 of them not on one plane, approach toward the
/// sphere): the latched points and their algebraic sphere.
fn checked_points(
    touches: &[Touch],
    labels: &[String],
    opts: &CalibrationOptions,
) -> Result<(Vec<[f64; 3]>, Sphere), ProbeError> {
    if !(opts.sphere_diameter_mm > 0.0 && opts.sphere_diameter_mm.is_finite()) {
        return Err(ProbeError::BadOption(format!(
            "--sphere-diameter-mm {}: must be > 0",
            opts.sphere_diameter_mm
        )));
    }
    validate_touches(touches, labels)?;
    let n = touches.len();
    if n < 4 {
        return Err(ProbeError::TooFew {
            need: 4,
            got: n,
            what: "a sphere fit (centre and effective radius)".into(),
        });
    }
    let pts: Vec<[f64; 3]> = touches.iter().map(|t| t.position_mm).collect();
    geometry::check_not_coplanar(&pts, labels)?;
    let algebraic = algebraic_sphere(&pts)?;
    // Approach toward the sphere: within 60° of the inward normal.
    for (i, t) in touches.iter().enumerate() {
        let inward = sub(algebraic.center_mm, t.position_mm);
        let l = norm(inward);
        let cosang = (0..3).map(|k| t.approach[k] * inward[k]).sum::<f64>() / l.max(1e-300);
        if cosang < 0.5 {
            return Err(ProbeError::BadTouch {
                row: labels.get(i).cloned().unwrap_or_else(|| format!("row {i}")),
                what: format!(
                    "approach vector ({}, {}, {}) points {:.0}° away from the sphere's centre (a touch on the \
                     sphere approaches within 60° of the inward normal)",
                    t.approach[0],
                    t.approach[1],
                    t.approach[2],
                    cosang.clamp(-1.0, 1.0).acos().to_degrees()
                ),
            });
        }
    }
    Ok((pts, algebraic))
}

/// Each touch's direction and speed, the feed range, and whether there was one speed only (then the speed
/// terms are not determined: the model holds at that speed only, with the speed set to 0).
fn dir_speeds(touches: &[Touch]) -> (Vec<DirSpeed>, [f64; 2], bool) {
    let mut ds: Vec<DirSpeed> = touches.iter().map(Touch::dir_speed).collect();
    let (flo, fhi) = touches
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, t| {
            (a.0.min(t.feed_mm_min), a.1.max(t.feed_mm_min))
        });
    let one_speed = fhi - flo <= 1e-9 * fhi.max(1.0);
    if one_speed {
        for d in &mut ds {
            d.v = 0.0;
        }
    }
    (ds, [flo, fhi], one_speed)
}

/// Direction groups of the touches and the cross-validation folds over them.
struct DirectionFolds {
    /// Distinct direction keys ([`direction_key`]).
    keys: Vec<(i64, i64)>,
    /// Each touch's index into `keys`.
    group: Vec<usize>,
    /// Each touch's fold.
    fold: Vec<usize>,
    /// Number of folds.
    k: usize,
}

impl DirectionFolds {
    /// Every `folds`-th distinct direction in one fold when there are at least two per fold, else every
    /// `folds`-th touch.
    fn new(ds: &[DirSpeed], folds: usize) -> Self {
        let mut keys: Vec<(i64, i64)> = Vec::new();
        let group: Vec<usize> = ds
            .iter()
            .map(|d| {
                let k = direction_key(*d);
                match keys.iter().position(|x| *x == k) {
                    Some(g) => g,
                    None => {
                        keys.push(k);
                        keys.len() - 1
                    }
                }
            })
            .collect();
        let k = folds.max(2);
        let fold: Vec<usize> = if keys.len() >= 2 * k {
            group.iter().map(|g| g % k).collect()
        } else {
            (0..ds.len()).map(|i| i % k).collect()
        };
        DirectionFolds {
            keys,
            group,
            fold,
            k,
        }
    }
}

/// The harmonic candidates the directions can carry: azimuthal orders whose 2K + 1 terms fit on the most
/// azimuths of one elevation ring, elevation degrees below the number of elevations, speed terms 0 … 2
/// (0 at one speed).
fn harmonic_candidates(keys: &[(i64, i64)], one_speed: bool) -> Vec<Structure> {
    let speed_terms: &[usize] = if one_speed { &[0] } else { &[0, 1, 2] };
    let ring_az = {
        let mut per: std::collections::HashMap<i64, std::collections::HashSet<i64>> =
            Default::default();
        for k in keys {
            per.entry(k.1).or_default().insert(k.0);
        }
        per.values().map(|s| s.len()).max().unwrap_or(1)
    };
    let n_el = {
        let mut e: Vec<i64> = keys.iter().map(|k| k.1).collect();
        e.sort();
        e.dedup();
        e.len()
    };
    let mut harmonic = Vec::new();
    for &kmax in &[0usize, 2, 3, 4, 6, 9, 12] {
        if kmax > 0 && 2 * kmax + 1 > ring_az {
            continue;
        }
        for &deg in &[1usize, 2] {
            if deg >= n_el {
                continue;
            }
            for &sp in speed_terms {
                harmonic.push(Structure::Harmonic {
                    max_order: kmax,
                    elevation_degree: deg,
                    speed_terms: sp,
                });
            }
        }
    }
    if harmonic.is_empty() {
        harmonic.push(Structure::Harmonic {
            max_order: 0,
            elevation_degree: 0,
            speed_terms: speed_terms[0],
        });
    }
    harmonic
}

/// Outlier flags, the inliers' indices and the centre.
type Screened = (Vec<bool>, Vec<usize>, [f64; 3]);

/// The richest harmonic model fixes the centre for the CV; it is refit on the inliers twice so that the
/// outlier flags come from a model that explains the lobing. Returns the flags, the inliers and the centre.
fn screen_with_richest(
    harmonic: &[Structure],
    touches: &[Touch],
    ds: &[DirSpeed],
    radius: f64,
    start: [f64; 3],
    mut out: Vec<bool>,
    outlier_mad: f64,
) -> Result<Screened, ProbeError> {
    let n = touches.len();
    let richest = harmonic
        .iter()
        .max_by_key(|s| s.len())
        .cloned()
        .expect("at least one candidate");
    let mut inl: Vec<usize> = (0..n).filter(|&i| !out[i]).collect();
    let mut centre = start;
    for _ in 0..2 {
        if inl.len() < richest.len() + 3 {
            break;
        }
        let (c, k) = joint_fit(&richest, touches, ds, &inl, radius, centre)?;
        centre = c;
        out = flag_outliers(
            &residuals_um(&richest, &k, touches, ds, c, radius),
            outlier_mad,
        );
        inl = (0..n).filter(|&i| !out[i]).collect();
    }
    if inl.len() < 4 {
        return Err(ProbeError::TooFew {
            need: 4,
            got: inl.len(),
            what: "a sphere fit after removing outliers".into(),
        });
    }
    Ok((out, inl, centre))
}

/// The seed's bilinear grid: nodes at the calibration directions' distinct azimuths and elevations.
fn bilinear_grid(ds: &[DirSpeed]) -> Structure {
    let az_nodes = model::distinct_nodes(
        ds.iter()
            .filter(|d| d.elevation_deg() < 89.9)
            .map(|d| d.azimuth_deg() % 360.0),
        72,
    )
    .unwrap_or_else(|| (0..36).map(|k| 10.0 * k as f64).collect());
    let el_nodes = model::distinct_nodes(
        ds.iter()
            .map(|d| d.elevation_deg())
            .map(|e| if e >= 89.9 { 90.0 } else { e }),
        12,
    )
    .unwrap_or_else(|| {
        let (lo, hi) = ds.iter().fold((90.0f64, -90.0f64), |a, d| {
            (a.0.min(d.elevation_deg()), a.1.max(d.elevation_deg()))
        });
        (0..5).map(|k| lo + (hi - lo) * k as f64 / 4.0).collect()
    });
    Structure::Bilinear {
        azimuth_nodes_deg: if az_nodes.is_empty() {
            vec![0.0]
        } else {
            az_nodes
        },
        elevation_nodes_deg: el_nodes,
    }
}

/// Cross-validated scores of the candidates: `fixed` (structure, its target) first, then the harmonics on
/// `y_h`. A candidate needs more training touches per fold than unknowns (its coefficients and the
/// centre); one that has not scores infinity.
fn score_candidates(
    fixed: &[(&Structure, &[f64])],
    harmonic: &[Structure],
    y_h: &[f64],
    ds: &[DirSpeed],
    inl: &[usize],
    folds: &DirectionFolds,
) -> Vec<CandidateScore> {
    let per_fold = inl.len() * (folds.k - 1) / folds.k;
    fixed
        .iter()
        .copied()
        .chain(harmonic.iter().map(|s| (s, y_h)))
        .map(|(s, y)| {
            let cv = if s.len() + 3 < per_fold {
                cv_rms(s, ds, y, inl, &folds.fold, folds.k)
            } else {
                f64::INFINITY
            };
            CandidateScore {
                model: s.name(),
                structure: s.clone(),
                coefficients: s.len(),
                cv_rms_um: cv,
            }
        })
        .collect()
}

/// The model `choice` picks among `candidates` (constant first, bilinear second, then harmonics) and why.
fn choose(choice: ModelChoice, candidates: &[CandidateScore], folds: usize) -> (Structure, String) {
    let best_of = |pred: &dyn Fn(&Structure) -> bool| {
        candidates
            .iter()
            .filter(|c| pred(&c.structure))
            .min_by(|a, b| a.cv_rms_um.total_cmp(&b.cv_rms_um))
            .cloned()
    };
    let best_h =
        best_of(&|s| matches!(s, Structure::Harmonic { .. })).expect("harmonic candidates");
    let cv_b = candidates[1].cv_rms_um;
    let cv_c = candidates[0].cv_rms_um;
    let forced = "forced by --pretravel-model";
    match choice {
        ModelChoice::Auto => {
            // The lowest CV; among candidates tied with it (within 1e-6 relative), the fewest coefficients.
            let lowest = best_of(&|_| true).expect("candidates").cv_rms_um;
            let best = candidates
                .iter()
                .filter(|c| c.cv_rms_um <= lowest * (1.0 + 1e-6) + 1e-9)
                .min_by_key(|c| c.coefficients)
                .cloned()
                .expect("candidates");
            let why = format!(
                "lowest cross-validated radial RMS over {} direction folds: {} {:.3} µm (bilinear reference \
                 {:.3} µm, constant {:.3} µm, best harmonic {:.3} µm)",
                folds, best.model, best.cv_rms_um, cv_b, cv_c, best_h.cv_rms_um
            );
            (best.structure, why)
        }
        ModelChoice::Constant => (candidates[0].structure.clone(), forced.into()),
        ModelChoice::Bilinear => (candidates[1].structure.clone(), forced.into()),
        ModelChoice::Harmonic => (
            best_h.structure.clone(),
            format!("{forced} (best harmonic by CV)"),
        ),
    }
}

/// What the final fits of [`calibrate`] share.
struct ModelFitter<'a> {
    touches: &'a [Touch],
    ds: &'a [DirSpeed],
    radius: f64,
    /// Radial distances about the plain sphere's centre minus the radius (the bilinear reference's target).
    y_ref: &'a [f64],
    /// The plain (free-radius) sphere's centre: the bilinear reference's.
    reference_centre: [f64; 3],
    sphere_diameter_mm: f64,
    feed_range: [f64; 2],
    el_range: [f64; 2],
    az_gap: Option<[f64; 2]>,
}

impl ModelFitter<'_> {
    /// Fits structure `s` on `rows`: the bilinear reference linearly about the plain sphere's centre, the
    /// others jointly with the centre from `start`.
    fn fit(
        &self,
        s: &Structure,
        rows: &[usize],
        start: [f64; 3],
    ) -> Result<Calibration, ProbeError> {
        match s {
            Structure::Bilinear { .. } => {
                let coef = fit_linear(s, self.ds, self.y_ref, rows).ok_or_else(|| {
                    ProbeError::Degenerate("bilinear grid: singular least squares".into())
                })?;
                Ok(self.calibration(s, self.reference_centre, coef, rows))
            }
            _ => {
                let (c, coef) = joint_fit(s, self.touches, self.ds, rows, self.radius, start)?;
                Ok(self.calibration(s, c, coef, rows))
            }
        }
    }

    /// Radial residuals (µm) of every touch under a calibration.
    fn residuals(&self, cal: &Calibration) -> Vec<f64> {
        residuals_um(
            &cal.structure,
            &cal.coef_mm,
            self.touches,
            self.ds,
            cal.sphere_center_mm,
            self.radius,
        )
    }

    fn calibration(
        &self,
        s: &Structure,
        c: [f64; 3],
        coef: Vec<f64>,
        rows: &[usize],
    ) -> Calibration {
        // Stylus radius: mean effective radius over the calibration directions at zero speed.
        let r0 = rows
            .iter()
            .map(|&i| {
                s.eval(
                    &coef,
                    DirSpeed {
                        v: 0.0,
                        ..self.ds[i]
                    },
                )
            })
            .sum::<f64>()
            / rows.len() as f64;
        let res = residuals_um(s, &coef, self.touches, self.ds, c, self.radius);
        Calibration {
            format: FORMAT.into(),
            sphere_center_mm: c,
            sphere_diameter_mm: self.sphere_diameter_mm,
            stylus_radius_mm: r0,
            structure: s.clone(),
            coef_mm: coef,
            feed_range_mm_min: self.feed_range,
            elevation_range_deg: self.el_range,
            azimuth_gap_deg: self.az_gap,
            fit_rms_um: rms(rows.iter().map(|&i| res[i])),
        }
    }
}

/// The flagged touches with their residual under the final model and what they look like.
fn outlier_list(out: &[bool], residual_um: &[f64], labels: &[String]) -> Vec<Outlier> {
    (0..out.len())
        .filter(|&i| out[i])
        .map(|i| Outlier {
            index: i,
            row: labels.get(i).cloned().unwrap_or_else(|| format!("row {i}")),
            residual_um: residual_um[i],
            kind: if residual_um[i] > 0.0 {
                "early trigger (false trip?)".into()
            } else {
                "late trigger (bounce / double trigger?)".into()
            },
        })
        .collect()
}

/// Repeatability: 2 × the pooled standard deviation (µm) of the radial distance about `centre` within
/// groups of the same direction (`group`) and speed (inliers `inl`), and the number of such groups;
/// `None` without repeats.
fn repeatability(
    touches: &[Touch],
    inl: &[usize],
    group: &[usize],
    centre: [f64; 3],
) -> (Option<f64>, usize) {
    // Ordered, so that the pooled sum (and the figure's last digits) is the same on every run.
    let mut groups: std::collections::BTreeMap<(usize, i64), Vec<f64>> = Default::default();
    for &i in inl {
        groups
            .entry((group[i], (touches[i].feed_mm_min * 1000.0).round() as i64))
            .or_default()
            .push(norm(sub(touches[i].position_mm, centre)));
    }
    let (mut ss, mut dof, mut ng) = (0.0, 0usize, 0usize);
    for v in groups.values().filter(|v| v.len() >= 2) {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        ss += v.iter().map(|x| (x - m).powi(2)).sum::<f64>();
        dof += v.len() - 1;
        ng += 1;
    }
    (
        (dof > 0).then(|| 2.0 * (ss / dof as f64).sqrt() * 1000.0),
        ng,
    )
}
