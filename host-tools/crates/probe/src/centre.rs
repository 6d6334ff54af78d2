//! Centres of spheres touched with a calibrated probe ([`fit_center`]), the error those centres share
//! through the one calibration ([`shared_centre_error`]), and the diameter of a free sphere through the
//! contact points ([`measured_diameter_mm`]).

use nalgebra::DMatrix;

use crate::geometry::{self, algebraic_sphere, geometric_sphere, norm, sub};
use crate::{Calibration, DirSpeed, ProbeError, Sphere, Touch};

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

/// Radial residuals (µm) of the contacts of `touches` under `cal` about the centre of `s`, for a sphere of
/// radius `radius_mm`.
pub fn radial_residuals_um(
    cal: &Calibration,
    touches: &[Touch],
    s: &Sphere,
    radius_mm: f64,
) -> Vec<f64> {
    touches
        .iter()
        .map(|t| (norm(sub(cal.contact_mm(t), s.center_mm)) - radius_mm) * 1000.0)
        .collect()
}

/// The sphere of radius `radius_mm` fitted ([`fit_center`]) to the contacts of `touches` and their radial
/// residuals (µm) about it.
pub fn radial_about_fitted_centre(
    cal: &Calibration,
    touches: &[Touch],
    radius_mm: f64,
) -> Result<(Sphere, Vec<f64>), ProbeError> {
    let s = fit_center(cal, touches, radius_mm)?;
    let res = radial_residuals_um(cal, touches, &s, radius_mm);
    Ok((s, res))
}
