//! `axcomp-probe`: calibration of a touch-trigger probe on a reference sphere and correction of touches to
//! surface (contact) points (contract: "Touch probe: calibration and correction").
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

mod calibration;
mod centre;
pub mod evaluate;
mod fit;
pub mod geometry;
pub mod model;
mod outliers;
pub mod poses;
pub mod report;
pub mod touches;

pub use calibration::Calibration;
pub use centre::{
    SharedCentreError, centre_sensitivity, coefficient_covariance, fit_center,
    measured_diameter_mm, radial_about_fitted_centre, radial_residuals_um, shared_centre_error,
};
pub use fit::{
    CalibrationOptions, CalibrationResult, CandidateScore, ModelChoice, Outlier, calibrate,
};
pub use geometry::{Sphere, algebraic_sphere, geometric_sphere};
pub use model::{DirSpeed, Structure};
pub use outliers::{
    DEFAULT_OUTLIER_MAD, MIN_SCREENED_TOUCHES, flag_outliers, iterated_sphere_outliers,
};

use geometry::norm;

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
    #[error(transparent)]
    Data(#[from] axcomp_data::DataError),
    /// Data that cannot be used as given (the message names the rows or the option).
    #[error("{0}")]
    Input(String),
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
