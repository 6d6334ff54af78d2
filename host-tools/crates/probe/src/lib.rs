//! `axcomp-probe`: calibration of a touch-trigger probe on a reference sphere and correction of touches to
//! surface (contact) points (issue 12, seed 003; contract: "Touch probe: calibration and correction").
//!
//! # Glossary
//! - **touch**: one trigger: the latched stylus-tip centre `p` (mm), the unit **approach** vector `u` of the
//!   probing move (toward the surface) and the probing speed (`feed_mm_min`).
//! - **normal** `n = −u`: the surface normal at the contact (probing is along the normal); directions are
//!   named by the normal's azimuth θ and elevation φ (0° on the sphere's equator, 90° for a touch straight
//!   down).
//! - **effective radius** `r_eff(n, v)`: the distance the latched tip centre shows from the surface along the
//!   normal: `|p − C| = R + r_eff` on a sphere of radius `R` centred at `C`. It is the stylus ball radius minus
//!   the **pretravel** (how far the tip moved on after contact before the latch), which depends on the
//!   direction (three-lobe kinematic probes) and grows linearly with the speed (mechanics and latch latency).
//! - **stylus radius** (reported): the mean effective radius over the calibration directions at zero speed;
//!   **pretravel** (reported, µm) = stylus radius − `r_eff(n, v)`.
//! - **contact point**: the corrected surface point `s = p + r_eff(n, v)·u` (correction along the approach
//!   direction, which is the normal for a normal touch).
//! - **model structures** ([`Structure`]): `constant` (one effective radius: the plain method), `bilinear`
//!   (the seed's azimuth × elevation grid + one speed slope: the reference method) and `harmonic` (smooth
//!   azimuthal harmonics × even polynomials in sin φ + speed terms); chosen by cross-validation over
//!   direction groups (every 5th distinct direction held out per fold).
//! - **outlier**: a touch whose radial residual lies more than `outlier_mad` robust standard deviations
//!   (1.4826·MAD) from the median; positive = latched short of the surface (a false trigger), negative =
//!   latched too late (a bounce's second trigger). Outliers are excluded from the fit and always reported.
//!
//! # Fit
//! 1. algebraic sphere fit (free radius), checks (≥ 4 touches, not all on one plane / circle, approach toward
//!    the sphere);
//! 2. geometric fit (Levenberg–Marquardt) of the centre and a constant effective radius with the sphere's
//!    radius fixed at the given diameter, and of a free-radius sphere (the seed's plain fit);
//! 3. robust outlier detection on the radial residuals, refit on the inliers;
//! 4. candidates scored by cross-validation with the centre fixed; the lowest CV RMS wins (`auto`);
//! 5. final joint fit (centre + coefficients) of the chosen model; outliers re-detected with it.

pub mod geometry;
pub mod model;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

pub use geometry::{Sphere, algebraic_sphere, geometric_sphere};
pub use model::{DirSpeed, Structure};

use geometry::{norm, sub};

/// Value of the calibration file's `format` field.
pub const FORMAT: &str = "axcomp-probe-calibration/1";

/// Tolerance on the length of an approach vector.
pub const UNIT_TOLERANCE: f64 = 1e-3;

/// Everything that can be wrong with touches or a calibration.
#[derive(Debug, thiserror::Error)]
pub enum ProbeError {
    #[error("{row}: {what}")]
    BadTouch { row: String, what: String },
    #[error("{got} touches, but {what} needs at least {need}")]
    TooFew {
        need: usize,
        got: usize,
        what: String,
    },
    #[error("{0}")]
    Degenerate(String),
    #[error("{0}")]
    BadOption(String),
    #[error("{path}: {what}")]
    File { path: String, what: String },
}

/// One trigger.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Touch {
    /// Latched stylus-tip centre, mm.
    pub position_mm: [f64; 3],
    /// Unit approach vector (toward the surface).
    pub approach: [f64; 3],
    /// Probing speed, mm/min (0 when unknown).
    pub feed_mm_min: f64,
}

impl Touch {
    pub fn dir_speed(&self) -> DirSpeed {
        DirSpeed::from_approach(self.approach, self.feed_mm_min / 60.0)
    }
}

/// Checks every touch: finite numbers, unit approach vector, speed ≥ 0. `labels[i]` names row `i`.
pub fn validate_touches(touches: &[Touch], labels: &[String]) -> Result<(), ProbeError> {
    for (i, t) in touches.iter().enumerate() {
        let row = || labels.get(i).cloned().unwrap_or_else(|| format!("row {i}"));
        let names = ["x_mm", "y_mm", "z_mm"];
        for k in 0..3 {
            if !t.position_mm[k].is_finite() {
                return Err(ProbeError::BadTouch {
                    row: row(),
                    what: format!("{} is {} (not a finite number)", names[k], t.position_mm[k]),
                });
            }
            if !t.approach[k].is_finite() {
                return Err(ProbeError::BadTouch {
                    row: row(),
                    what: format!(
                        "approach_{} is {} (not a finite number)",
                        ["x", "y", "z"][k],
                        t.approach[k]
                    ),
                });
            }
        }
        let l = norm(t.approach);
        if (l - 1.0).abs() > UNIT_TOLERANCE {
            return Err(ProbeError::BadTouch {
                row: row(),
                what: format!(
                    "approach vector ({}, {}, {}) has length {l:.6}, not a unit vector (±{UNIT_TOLERANCE})",
                    t.approach[0], t.approach[1], t.approach[2]
                ),
            });
        }
        if !(t.feed_mm_min.is_finite() && t.feed_mm_min >= 0.0) {
            return Err(ProbeError::BadTouch {
                row: row(),
                what: format!("feed_mm_min is {} (need a number ≥ 0)", t.feed_mm_min),
            });
        }
    }
    Ok(())
}

/// Elevation (degrees) from which a normal's azimuth is not told apart (touches near the pole).
pub const AZIMUTH_POLE_DEG: f64 = 80.0;

/// The widest azimuth arc without calibration touches that still counts as covered. A wider one is recorded
/// and its inside refused. 135°, not 90°: the four-direction shop-floor routine leaves arcs of 90° that
/// rounding or a slightly tilted artefact makes 90.000…1°, and a three-direction routine leaves 120°; a
/// sphere probed from one side leaves about 180°.
pub const AZIMUTH_GAP_COVERED_DEG: f64 = 135.0;

/// How far (degrees) beyond the calibrated directions a touch is still corrected (as for the elevation).
pub const DIRECTION_MARGIN_DEG: f64 = 10.0;

/// The widest arc of azimuths without a touch below [`AZIMUTH_POLE_DEG`], as `[from, to]` (counter-clockwise),
/// when wider than [`AZIMUTH_GAP_COVERED_DEG`]; `None` otherwise or without such touches.
pub fn azimuth_gap(dirs: &[DirSpeed]) -> Option<[f64; 2]> {
    let mut az: Vec<f64> = dirs
        .iter()
        .filter(|d| d.elevation_deg() < AZIMUTH_POLE_DEG)
        .map(|d| d.azimuth_deg())
        .collect();
    az.sort_by(f64::total_cmp);
    let (&first, &last) = (az.first()?, az.last()?);
    let mut widest = (first + 360.0 - last, last, first);
    for w in az.windows(2) {
        if w[1] - w[0] > widest.0 {
            widest = (w[1] - w[0], w[0], w[1]);
        }
    }
    (widest.0 > AZIMUTH_GAP_COVERED_DEG).then_some([widest.1, widest.2])
}

/// A probe calibration: the file `axcomp fit probe --out CAL` writes and `axcomp predict` reads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Always [`FORMAT`].
    pub format: String,
    pub sphere_center_mm: [f64; 3],
    pub sphere_diameter_mm: f64,
    /// Mean effective radius over the calibration directions at zero speed, mm.
    pub stylus_radius_mm: f64,
    /// The model of the effective radius.
    pub structure: Structure,
    /// Its coefficients (mm; speed coefficients in mm per mm/s).
    pub coef_mm: Vec<f64>,
    /// Probing speeds seen in calibration, mm/min.
    pub feed_range_mm_min: [f64; 2],
    /// Elevations (of the normal) seen in calibration, degrees.
    pub elevation_range_deg: [f64; 2],
    /// The widest azimuth arc `[from, to]` (degrees, counter-clockwise from `from`) without calibration
    /// touches below [`AZIMUTH_POLE_DEG`], when it is wider than [`AZIMUTH_GAP_COVERED_DEG`] (e.g. a sphere
    /// probed from one side only); `None` when the touches go round (and in files written before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub azimuth_gap_deg: Option<[f64; 2]>,
    /// RMS radial residual of the calibration touches (inliers), µm.
    pub fit_rms_um: f64,
}

impl Calibration {
    /// Effective radius (mm) for a touch.
    pub fn effective_radius_mm(&self, t: &Touch) -> f64 {
        self.structure.eval(&self.coef_mm, t.dir_speed())
    }

    /// Pretravel (µm) relative to the stylus radius: `stylus_radius − r_eff`.
    pub fn pretravel_um(&self, d: DirSpeed) -> f64 {
        (self.stylus_radius_mm - self.structure.eval(&self.coef_mm, d)) * 1000.0
    }

    /// The corrected contact (surface) point `p + r_eff·u`.
    pub fn contact_mm(&self, t: &Touch) -> [f64; 3] {
        let r = self.effective_radius_mm(t);
        [
            t.position_mm[0] + r * t.approach[0],
            t.position_mm[1] + r * t.approach[1],
            t.position_mm[2] + r * t.approach[2],
        ]
    }

    /// Whether the calibration can correct this touch: a speed inside what it can tell (the calibrated
    /// range, or up to 1.5× its top speed by the linear speed term), an elevation not more than 10° below the
    /// lowest calibrated one. The error says why.
    pub fn check_touch(&self, t: &Touch) -> Result<(), String> {
        let [lo, hi] = self.feed_range_mm_min;
        let f = t.feed_mm_min;
        if hi - lo <= 1e-9 * hi.max(1.0) {
            if hi == 0.0 && f != 0.0 {
                return Err(format!(
                    "feed_mm_min {f}: the calibration's touches had no feed_mm_min column (one speed, not \
                     known), so it cannot tell the pretravel at a given speed; leave the column out (--rename \
                     feed_mm_min=feed_unused) if these touches were probed at the calibration's speed, or \
                     calibrate with feed_mm_min"
                ));
            }
            if (f - lo).abs() > 0.01 * lo.max(1.0) {
                return Err(format!(
                    "feed_mm_min {f}: the calibration saw only {lo} mm/min, so it cannot tell the pretravel at \
                     another speed"
                ));
            }
        } else if !(f >= 0.0 && f <= 1.5 * hi) {
            return Err(format!(
                "feed_mm_min {f} is outside what the calibration can predict (0 … {} mm/min; calibrated \
                 {lo} … {hi})",
                1.5 * hi
            ));
        }
        let el = t.dir_speed().elevation_deg();
        if let Some([from, to]) = self.azimuth_gap_deg
            && el < AZIMUTH_POLE_DEG
        {
            let az = t.dir_speed().azimuth_deg();
            let width = match (to - from).rem_euclid(360.0) {
                0.0 => 360.0,
                w => w,
            };
            let inside = (az - from).rem_euclid(360.0);
            if inside > DIRECTION_MARGIN_DEG && inside < width - DIRECTION_MARGIN_DEG {
                return Err(format!(
                    "the surface normal's azimuth {az:.1}° lies in the arc {from:.1}° … {to:.1}° \
                     (counter-clockwise) where the calibration has no touches, more than \
                     {DIRECTION_MARGIN_DEG}° from the nearest calibrated azimuth: it cannot tell the \
                     pretravel there"
                ));
            }
        }
        if el < self.elevation_range_deg[0] - 10.0 {
            return Err(format!(
                "the surface normal's elevation {el:.1}° is more than 10° below the lowest calibrated \
                 elevation {:.1}°",
                self.elevation_range_deg[0]
            ));
        }
        Ok(())
    }

    /// Checks format and sizes.
    pub fn validate(&self) -> Result<(), String> {
        if self.format != FORMAT {
            return Err(format!("format is `{}`, expected `{FORMAT}`", self.format));
        }
        if self.coef_mm.len() != self.structure.len() {
            return Err(format!(
                "{} coefficients for a model with {}",
                self.coef_mm.len(),
                self.structure.len()
            ));
        }
        if self.coef_mm.iter().any(|c| !c.is_finite())
            || !self.stylus_radius_mm.is_finite()
            || self.sphere_diameter_mm.is_nan()
            || self.sphere_diameter_mm <= 0.0
        {
            return Err("non-finite coefficient, stylus radius or diameter".into());
        }
        let gap = self.azimuth_gap_deg.unwrap_or_default();
        let values = [
            ("sphere_center_mm", &self.sphere_center_mm[..]),
            ("sphere_diameter_mm", &[self.sphere_diameter_mm][..]),
            ("stylus_radius_mm", &[self.stylus_radius_mm][..]),
            ("coef_mm", &self.coef_mm[..]),
            ("feed_range_mm_min", &self.feed_range_mm_min[..]),
            ("elevation_range_deg", &self.elevation_range_deg[..]),
            ("azimuth_gap_deg", &gap[..]),
            ("fit_rms_um", &[self.fit_rms_um][..]),
        ];
        for (name, v) in values {
            if let Some((i, x)) = v
                .iter()
                .enumerate()
                .find(|(_, x)| !(x.is_finite() && x.abs() < 1e12))
            {
                return Err(format!(
                    "{name}[{i}] is {x:e}, not a finite number of plausible size"
                ));
            }
        }
        if self.feed_range_mm_min[0] > self.feed_range_mm_min[1]
            || self.elevation_range_deg[0] > self.elevation_range_deg[1]
        {
            return Err(
                "feed_range_mm_min / elevation_range_deg: lower end above upper end".into(),
            );
        }
        Ok(())
    }

    pub fn from_json(path: &str, text: &str) -> Result<Self, ProbeError> {
        let c: Calibration = serde_json::from_str(text).map_err(|e| ProbeError::File {
            path: path.into(),
            what: format!("not a probe calibration: {e}"),
        })?;
        c.validate().map_err(|what| ProbeError::File {
            path: path.into(),
            what,
        })?;
        Ok(c)
    }

    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("calibration serialises");
        s.push('\n');
        s
    }
}

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
            outlier_mad: 6.0,
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

use axcomp_numeric::stats::median;

/// Robust outlier flags on residuals (µm): |e − median| > k·max(1.4826·MAD, 0.05 µm), the median of an even
/// count being the mean of its two middle values ([`median`]). The one rule for gross outliers among
/// touches: the calibration here, and `axcomp fit probe`'s and `axcomp diagnose`'s per-sphere screening.
pub fn flag_outliers(res_um: &[f64], k: f64) -> Vec<bool> {
    let mut v = res_um.to_vec();
    let med = median(&mut v);
    let mut dev: Vec<f64> = res_um.iter().map(|e| (e - med).abs()).collect();
    let s = (1.4826 * median(&mut dev)).max(0.05);
    res_um.iter().map(|e| (e - med).abs() > k * s).collect()
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
pub fn calibrate(
    touches: &[Touch],
    labels: &[String],
    opts: &CalibrationOptions,
) -> Result<CalibrationResult, ProbeError> {
    if !(opts.sphere_diameter_mm > 0.0 && opts.sphere_diameter_mm.is_finite()) {
        return Err(ProbeError::BadOption(format!(
            "--sphere-diameter-mm {}: must be > 0",
            opts.sphere_diameter_mm
        )));
    }
    validate_touches(touches, labels)?;
    let radius = opts.sphere_diameter_mm / 2.0;
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
    let mut ds: Vec<DirSpeed> = touches.iter().map(Touch::dir_speed).collect();
    let (flo, fhi) = touches
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, t| {
            (a.0.min(t.feed_mm_min), a.1.max(t.feed_mm_min))
        });
    let one_speed = fhi - flo <= 1e-9 * fhi.max(1.0);
    if one_speed {
        // One speed: the speed terms are not determined; the model holds at that speed only.
        for d in &mut ds {
            d.v = 0.0;
        }
    }
    let all: Vec<usize> = (0..n).collect();

    // ---- constant model and first outlier pass ----
    let constant = Structure::Constant;
    let (c0, k0) = joint_fit(&constant, touches, &ds, &all, radius, algebraic.center_mm)?;
    let res0 = residuals_um(&constant, &k0, touches, &ds, c0, radius);
    let mut out = flag_outliers(&res0, opts.outlier_mad);

    // ---- direction groups and folds ----
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
    let n_dirs = keys.len();
    let folds = opts.folds.max(2);
    let fold: Vec<usize> = if n_dirs >= 2 * folds {
        group.iter().map(|g| g % folds).collect()
    } else {
        (0..n).map(|i| i % folds).collect()
    };

    // ---- candidates ----
    let speed_terms: &[usize] = if one_speed { &[0] } else { &[0, 1, 2] };
    let ring_az = {
        // The most azimuths on one elevation ring bounds the azimuthal order.
        let mut per: std::collections::HashMap<i64, std::collections::HashSet<i64>> =
            Default::default();
        for k in &keys {
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
    // The richest harmonic model fixes the centre for the CV (and is refit on the inliers twice so that
    // the outlier flags come from a model that explains the lobing).
    let richest = harmonic
        .iter()
        .max_by_key(|s| s.len())
        .cloned()
        .expect("at least one candidate");
    let mut inl: Vec<usize> = (0..n).filter(|&i| !out[i]).collect();
    let mut centre = c0;
    for _ in 0..2 {
        if inl.len() < richest.len() + 3 {
            break;
        }
        let (c, k) = joint_fit(&richest, touches, &ds, &inl, radius, centre)?;
        centre = c;
        out = flag_outliers(
            &residuals_um(&richest, &k, touches, &ds, c, radius),
            opts.outlier_mad,
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

    // Plain sphere fit (free radius) of the inliers: the seed's first step; its centre is the reference's.
    let inl_pts: Vec<[f64; 3]> = inl.iter().map(|&i| pts[i]).collect();
    let geometric_free = geometry::geometric_sphere(&inl_pts, None)?;

    // Bilinear grid from the calibration directions.
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
    let bilinear = Structure::Bilinear {
        azimuth_nodes_deg: if az_nodes.is_empty() {
            vec![0.0]
        } else {
            az_nodes
        },
        elevation_nodes_deg: el_nodes,
    };

    let y_h: Vec<f64> = pts.iter().map(|p| norm(sub(*p, centre)) - radius).collect();
    let y_ref: Vec<f64> = pts
        .iter()
        .map(|p| norm(sub(*p, geometric_free.center_mm)) - radius)
        .collect();
    let mut candidates = Vec::new();
    // A candidate needs more training touches per fold than unknowns (its coefficients and the centre).
    let per_fold = inl.len() * (folds - 1) / folds;
    let mut score = |s: &Structure, y: &[f64]| {
        let cv = if s.len() + 3 < per_fold {
            cv_rms(s, &ds, y, &inl, &fold, folds)
        } else {
            f64::INFINITY
        };
        candidates.push(CandidateScore {
            model: s.name(),
            structure: s.clone(),
            coefficients: s.len(),
            cv_rms_um: cv,
        });
    };
    score(&constant, &y_h);
    score(&bilinear, &y_ref);
    for s in &harmonic {
        score(s, &y_h);
    }
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
    let (chosen, why) = match opts.model {
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
        ModelChoice::Constant => (constant.clone(), "forced by --pretravel-model".into()),
        ModelChoice::Bilinear => (bilinear.clone(), "forced by --pretravel-model".into()),
        ModelChoice::Harmonic => (
            best_h.structure.clone(),
            "forced by --pretravel-model (best harmonic by CV)".into(),
        ),
    };

    let feed_range = [flo, fhi];
    let el_range = ds.iter().fold([90.0f64, -90.0f64], |a, d| {
        [a[0].min(d.elevation_deg()), a[1].max(d.elevation_deg())]
    });
    let az_gap = azimuth_gap(&ds);
    let make = |s: &Structure, c: [f64; 3], coef: Vec<f64>, rows: &[usize]| -> Calibration {
        // Stylus radius: mean effective radius over the calibration directions at zero speed.
        let r0 = rows
            .iter()
            .map(|&i| s.eval(&coef, DirSpeed { v: 0.0, ..ds[i] }))
            .sum::<f64>()
            / rows.len() as f64;
        let res = residuals_um(s, &coef, touches, &ds, c, radius);
        Calibration {
            format: FORMAT.into(),
            sphere_center_mm: c,
            sphere_diameter_mm: opts.sphere_diameter_mm,
            stylus_radius_mm: r0,
            structure: s.clone(),
            coef_mm: coef,
            feed_range_mm_min: feed_range,
            elevation_range_deg: el_range,
            azimuth_gap_deg: az_gap,
            fit_rms_um: rms(rows.iter().map(|&i| res[i])),
        }
    };
    let fit_model =
        |s: &Structure, rows: &[usize], start: [f64; 3]| -> Result<Calibration, ProbeError> {
            match s {
                Structure::Bilinear { .. } => {
                    let coef = fit_linear(s, &ds, &y_ref, rows).ok_or_else(|| {
                        ProbeError::Degenerate("bilinear grid: singular least squares".into())
                    })?;
                    Ok(make(s, geometric_free.center_mm, coef, rows))
                }
                _ => {
                    let (c, coef) = joint_fit(s, touches, &ds, rows, radius, start)?;
                    Ok(make(s, c, coef, rows))
                }
            }
        };
    let mut calibration = fit_model(&chosen, &inl, centre)?;
    // Outliers re-detected under the chosen model; refit once if they changed.
    let res = residuals_um(
        &calibration.structure,
        &calibration.coef_mm,
        touches,
        &ds,
        calibration.sphere_center_mm,
        radius,
    );
    let out2 = flag_outliers(&res, opts.outlier_mad);
    if out2 != out {
        out = out2;
        inl = (0..n).filter(|&i| !out[i]).collect();
        calibration = fit_model(&chosen, &inl, calibration.sphere_center_mm)?;
    }
    let reference = fit_model(&bilinear, &inl, centre)?;
    let plain = fit_model(&constant, &inl, centre)?;
    let residual_um = residuals_um(
        &calibration.structure,
        &calibration.coef_mm,
        touches,
        &ds,
        calibration.sphere_center_mm,
        radius,
    );
    let outliers = (0..n)
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
        .collect();

    // Repeatability: pooled standard deviation of the radial distance within groups of the same direction
    // and speed (inliers).
    let mut groups: std::collections::HashMap<(usize, i64), Vec<f64>> = Default::default();
    for &i in &inl {
        groups
            .entry((group[i], (touches[i].feed_mm_min * 1000.0).round() as i64))
            .or_default()
            .push(norm(sub(pts[i], calibration.sphere_center_mm)));
    }
    let (mut ss, mut dof, mut ng) = (0.0, 0usize, 0usize);
    for v in groups.values().filter(|v| v.len() >= 2) {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        ss += v.iter().map(|x| (x - m).powi(2)).sum::<f64>();
        dof += v.len() - 1;
        ng += 1;
    }
    let repeatability_2sigma_um = (dof > 0).then(|| 2.0 * (ss / dof as f64).sqrt() * 1000.0);

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
        repeat_groups: ng,
    })
}

/// Centre of a sphere of known radius from touches corrected by a calibration (e.g. one pose of a five-axis
/// calibration, or a held-out artefact): a geometric fit of the corrected contact points, radius fixed.
pub fn fit_center(
    cal: &Calibration,
    touches: &[Touch],
    radius_mm: f64,
) -> Result<Sphere, ProbeError> {
    let contacts: Vec<[f64; 3]> = touches.iter().map(|t| cal.contact_mm(t)).collect();
    let start = if contacts.len() >= 4 {
        algebraic_sphere(&contacts).map(|s| s.center_mm).ok()
    } else {
        None
    };
    let start = start.unwrap_or_else(|| {
        // Fewer than 4 touches: start inside along the mean approach.
        let n = contacts.len().max(1) as f64;
        let mut c = [0.0; 3];
        for (p, t) in contacts.iter().zip(touches) {
            for k in 0..3 {
                c[k] += (p[k] + radius_mm * t.approach[k]) / n;
            }
        }
        c
    });
    geometry::geometric_sphere_from(&contacts, Some(radius_mm), start, radius_mm)
}

/// The direction-and-speed variables a calibration's model is evaluated at for `t` (the speed set to 0 when
/// the calibration saw one speed only, as in [`calibrate`]).
fn cal_dir_speed(cal: &Calibration, t: &Touch) -> DirSpeed {
    let [lo, hi] = cal.feed_range_mm_min;
    let mut d = t.dir_speed();
    if hi - lo <= 1e-9 * hi.max(1.0) {
        d.v = 0.0;
    }
    d
}

/// Covariance (mm², p × p) of a calibration's effective-radius coefficients from its linearised joint fit
/// (centre and coefficients, the sphere's radius fixed) on its inlier touches `touches`:
/// `σ̂²·[(JᵀJ)⁺]_ββ`, `J = [∂r/∂c | ∂r/∂β] = [−(p − c)/|p − c| | −Φ]`, `σ̂² = RSS/(n − rank)`. Directions of
/// the coefficient space the touches do not reach (a bilinear node without a touch, the speed slope at one
/// speed) get no variance (pseudo-inverse): they cannot move a centre fitted from touches in the same
/// directions either.
pub fn coefficient_covariance(
    cal: &Calibration,
    touches: &[Touch],
) -> Result<DMatrix<f64>, ProbeError> {
    let p = cal.structure.len();
    let n = touches.len();
    let radius = cal.sphere_diameter_mm / 2.0;
    let mut j = DMatrix::<f64>::zeros(n, 3 + p);
    let mut rss = 0.0;
    let mut phi = vec![0.0; p];
    for (i, t) in touches.iter().enumerate() {
        let d = sub(t.position_mm, cal.sphere_center_mm);
        let l = norm(d).max(1e-300);
        let ds = cal_dir_speed(cal, t);
        cal.structure.basis(ds, &mut phi);
        for k in 0..3 {
            j[(i, k)] = -d[k] / l;
        }
        for k in 0..p {
            j[(i, 3 + k)] = -phi[k];
        }
        rss += (l - radius - cal.structure.eval(&cal.coef_mm, ds)).powi(2);
    }
    let svd = (j.transpose() * &j).svd(true, true);
    let smax = svd.singular_values.iter().fold(0.0f64, |m, v| m.max(*v));
    let rank = svd
        .singular_values
        .iter()
        .filter(|v| **v > 1e-10 * smax)
        .count();
    if n <= rank {
        return Err(ProbeError::TooFew {
            need: rank + 1,
            got: n,
            what: "the calibration's coefficient uncertainty (more touches than unknowns)".into(),
        });
    }
    let inv = svd
        .pseudo_inverse(1e-10 * smax)
        .map_err(|e| ProbeError::Degenerate(e.to_string()))?;
    let s2 = rss / (n - rank) as f64;
    Ok(inv.view((3, 3), (p, p)) * s2)
}

/// Sensitivity (mm per unit coefficient, 3 × p) of the centre [`fit_center`] fits to `touches` at `centre`
/// to the calibration's coefficients: `−(J_cᵀJ_c)⁻¹·J_cᵀ·J_β` with `J_c = −e`, `J_β = (e·u)·Φ` (`e` the unit
/// vector from the centre to the corrected contact, `u` the approach).
pub fn centre_sensitivity(
    cal: &Calibration,
    touches: &[Touch],
    centre: [f64; 3],
) -> Result<DMatrix<f64>, ProbeError> {
    let p = cal.structure.len();
    let n = touches.len();
    let mut jc = DMatrix::<f64>::zeros(n, 3);
    let mut jb = DMatrix::<f64>::zeros(n, p);
    let mut phi = vec![0.0; p];
    for (i, t) in touches.iter().enumerate() {
        let c = cal.contact_mm(t);
        let d = sub(c, centre);
        let l = norm(d).max(1e-300);
        let e = [d[0] / l, d[1] / l, d[2] / l];
        let eu = e[0] * t.approach[0] + e[1] * t.approach[1] + e[2] * t.approach[2];
        cal.structure.basis(cal_dir_speed(cal, t), &mut phi);
        for k in 0..3 {
            jc[(i, k)] = -e[k];
        }
        for k in 0..p {
            jb[(i, k)] = eu * phi[k];
        }
    }
    let ata = jc.transpose() * &jc;
    let inv = ata
        .try_inverse()
        .ok_or_else(|| ProbeError::Degenerate("centre fit: singular normal matrix".into()))?;
    Ok(-(inv * jc.transpose() * jb))
}

/// The error the centres of several spheres (the poses of a five-axis calibration) share because they are
/// fitted with one calibration: group `g`'s centre error holds `Σ_k u_k·loadings_um[g][k]`, `u_k`
/// independent, mean 0, variance 1.
#[derive(Debug, Clone, PartialEq)]
pub struct SharedCentreError {
    /// Per group, per component: µm along X, Y, Z.
    pub loadings_um: Vec<Vec<[f64; 3]>>,
    /// Share of the shared error's total variance the components hold (the rest, below 1e-2 of the largest
    /// singular value, is left out: its variance at most 1e-4 of the largest component's each).
    pub captured_share: f64,
    /// Its standard uncertainty per axis (µm), root mean square over the groups.
    pub std_um: [f64; 3],
}

impl SharedCentreError {
    /// Number of components.
    pub fn components(&self) -> usize {
        self.loadings_um.first().map_or(0, Vec::len)
    }
}

/// [`SharedCentreError`] of the centres fitted ([`fit_center`]) with `cal` to each group's touches (the
/// touches used, the fitted centre): the coefficients' covariance `C` ([`coefficient_covariance`] on the
/// calibration's inlier touches), `C = V·Λ·Vᵀ`, moves group `g`'s centre by `A_g·V·Λ^½·u`
/// ([`centre_sensitivity`]); the stacked `B = [A_g·V·Λ^½]` is reduced by its SVD to its components above
/// 1e-2 of the largest singular value (three when every pose is touched in the same directions).
pub fn shared_centre_error(
    cal: &Calibration,
    calibration_inliers: &[Touch],
    groups: &[(&[Touch], [f64; 3])],
) -> Result<SharedCentreError, ProbeError> {
    let cov = coefficient_covariance(cal, calibration_inliers)?;
    let eig = cov.clone().symmetric_eigen();
    let p = cov.nrows();
    let mut half = DMatrix::<f64>::zeros(p, p);
    for k in 0..p {
        let l = eig.eigenvalues[k].max(0.0).sqrt();
        for r in 0..p {
            half[(r, k)] = eig.eigenvectors[(r, k)] * l * 1000.0;
        }
    }
    let mut b = DMatrix::<f64>::zeros(3 * groups.len(), p);
    for (g, (touches, centre)) in groups.iter().enumerate() {
        let a = centre_sensitivity(cal, touches, *centre)?;
        b.view_mut((3 * g, 0), (3, p)).copy_from(&(a * &half));
    }
    let svd = b.clone().svd(true, false);
    let u = svd.u.as_ref().expect("U computed");
    let sv = &svd.singular_values;
    let smax = sv.iter().fold(0.0f64, |m, v| m.max(*v));
    let total: f64 = sv.iter().map(|v| v * v).sum();
    let mut keep: Vec<usize> = (0..sv.len()).filter(|&k| sv[k] > 1e-2 * smax).collect();
    keep.sort_by(|&x, &y| sv[y].total_cmp(&sv[x]));
    let kept: f64 = keep.iter().map(|&k| sv[k] * sv[k]).sum();
    let loadings_um = (0..groups.len())
        .map(|g| {
            keep.iter()
                .map(|&k| [0, 1, 2].map(|c| u[(3 * g + c, k)] * sv[k]))
                .collect()
        })
        .collect();
    let n = groups.len().max(1) as f64;
    let std_um = [0, 1, 2].map(|c| {
        ((0..groups.len())
            .map(|g| (0..p).map(|k| b[(3 * g + c, k)].powi(2)).sum::<f64>())
            .sum::<f64>()
            / n)
            .sqrt()
    });
    Ok(SharedCentreError {
        loadings_um,
        captured_share: if total > 0.0 { kept / total } else { 1.0 },
        std_um,
    })
}

/// Diameter (mm) of the free-radius sphere through the contact points of `touches` under `radius_of`
/// (the effective radius used for each touch).
pub fn measured_diameter_mm(
    touches: &[Touch],
    radius_of: impl Fn(&Touch) -> f64,
) -> Result<Sphere, ProbeError> {
    let contacts: Vec<[f64; 3]> = touches
        .iter()
        .map(|t| {
            let r = radius_of(t);
            [
                t.position_mm[0] + r * t.approach[0],
                t.position_mm[1] + r * t.approach[1],
                t.position_mm[2] + r * t.approach[2],
            ]
        })
        .collect();
    geometric_sphere(&contacts, None)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: the arcs between the azimuths given (degrees). Four directions (90° arcs, one of them
    /// 90° + 1e-9 as a tilted artefact gives) and three (120°) count as going round; one side of the sphere
    /// (azimuths −90° … 90° every 15°, an empty arc of 180°) is recorded as that arc.
    #[test]
    fn the_uncovered_azimuth_arc_is_recorded_only_beyond_routine_spacings() {
        let dirs = |az: &[f64]| -> Vec<DirSpeed> {
            az.iter()
                .map(|a: &f64| DirSpeed {
                    t: 0.0,
                    theta: a.to_radians(),
                    v: 1.0,
                })
                .collect()
        };
        assert_eq!(azimuth_gap(&dirs(&[0.0, 90.0, 180.0 + 1e-9, 270.0])), None);
        assert_eq!(azimuth_gap(&dirs(&[0.0, 120.0, 240.0])), None);
        let one_side: Vec<f64> = (-6..=6).map(|k| 15.0 * k as f64).collect();
        let [from, to] = azimuth_gap(&dirs(&one_side)).expect("an arc of 180° is recorded");
        assert!(
            (from - 90.0).abs() < 1e-9 && (to - 270.0).abs() < 1e-9,
            "{from} … {to}"
        );
    }

    fn exact(n_az: usize, els: &[f64], r_eff: f64) -> Vec<Touch> {
        let mut v = Vec::new();
        for &el in els {
            for k in 0..n_az {
                let (a, e) = (
                    (360.0 * k as f64 / n_az as f64 + el).to_radians(),
                    el.to_radians(),
                );
                let n = [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()];
                let d = 12.5 + r_eff;
                v.push(Touch {
                    position_mm: [1.0 + d * n[0], 2.0 + d * n[1], 3.0 + d * n[2]],
                    approach: [-n[0], -n[1], -n[2]],
                    feed_mm_min: 100.0,
                });
            }
        }
        v
    }

    #[test]
    fn few_exact_touches_give_the_plain_radius_and_the_centre() {
        // Exact touches (one effective radius 1.49 mm): every candidate ties at zero CV error or has too few
        // touches, so the fewest coefficients win. Reference: the generating values; tolerance 1e-9 mm.
        for (n_az, els) in [
            (2usize, &[0.0, 60.0][..]),
            (3, &[0.0, 45.0][..]),
            (8, &[30.0, 60.0][..]),
        ] {
            let t = exact(n_az, els, 1.49);
            let labels: Vec<String> = (0..t.len()).map(|i| format!("row {i}")).collect();
            let r = calibrate(&t, &labels, &CalibrationOptions::new(25.0)).unwrap();
            assert_eq!(r.calibration.structure, Structure::Constant, "{n_az}");
            assert!((r.calibration.stylus_radius_mm - 1.49).abs() < 1e-9);
            let c = r.calibration.sphere_center_mm;
            assert!(
                (c[0] - 1.0).abs() < 1e-9 && (c[1] - 2.0).abs() < 1e-9 && (c[2] - 3.0).abs() < 1e-9
            );
            assert!(r.outliers.is_empty());
        }
    }

    #[test]
    fn contact_point_is_the_latched_point_moved_by_the_effective_radius() {
        let t = exact(8, &[0.0, 45.0], 1.49);
        let labels: Vec<String> = (0..t.len()).map(|i| format!("row {i}")).collect();
        let r = calibrate(&t, &labels, &CalibrationOptions::new(25.0)).unwrap();
        // Reference: the generating sphere's surface; tolerance 1e-9 mm.
        for x in &t {
            let s = r.calibration.contact_mm(x);
            let d = ((s[0] - 1.0).powi(2) + (s[1] - 2.0).powi(2) + (s[2] - 3.0).powi(2)).sqrt();
            assert!((d - 12.5).abs() < 1e-9, "{d}");
        }
    }
}
