//! Sphere fits: algebraic (linear least squares on `|p|² = 2c·p + d`), then geometric (Levenberg–Marquardt
//! on the radial distances), with the radius free or fixed, and a small LM driver used by the calibration.

use nalgebra::{DMatrix, DVector};

use crate::ProbeError;

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(crate) fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// A fitted sphere.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sphere {
    pub center_mm: [f64; 3],
    pub radius_mm: f64,
    /// RMS of the radial residuals, µm.
    pub rms_um: f64,
}

/// Checks that the points span three dimensions (not all on one plane, i.e. not all on one circle of the
/// sphere such as a single great circle or one elevation ring). `labels` name the rows in the message.
pub fn check_not_coplanar(points: &[[f64; 3]], labels: &[String]) -> Result<(), ProbeError> {
    let n = points.len() as f64;
    let mut m = [0.0; 3];
    for p in points {
        for k in 0..3 {
            m[k] += p[k] / n;
        }
    }
    let mut s = nalgebra::Matrix3::<f64>::zeros();
    for p in points {
        let d = nalgebra::Vector3::new(p[0] - m[0], p[1] - m[1], p[2] - m[2]);
        s += d * d.transpose();
    }
    let e = s.symmetric_eigen().eigenvalues;
    let (lo, hi) = (e.min(), e.max());
    // Out-of-plane spread below 1e-3 of the in-plane spread (e.g. 14 µm on a Ø25 mm sphere): the centre
    // is not determined across the plane.
    if hi.is_nan() || hi <= 0.0 || lo / hi < 1e-6 {
        let first = labels.first().map(String::as_str).unwrap_or("?");
        let last = labels.last().map(String::as_str).unwrap_or("?");
        return Err(ProbeError::Degenerate(format!(
            "all {} touches ({first} … {last}) lie on one plane (one circle of the sphere, e.g. a single \
             great circle or one elevation ring): the sphere's centre is not determined; touch at least two \
             elevations",
            points.len()
        )));
    }
    Ok(())
}

/// Algebraic sphere fit with a free radius (needs ≥ 4 points not on one plane).
pub fn algebraic_sphere(points: &[[f64; 3]]) -> Result<Sphere, ProbeError> {
    let n = points.len();
    if n < 4 {
        return Err(ProbeError::TooFew {
            need: 4,
            got: n,
            what: "a sphere with a free radius".into(),
        });
    }
    // Centre the data for conditioning.
    let mut m = [0.0; 3];
    for p in points {
        for k in 0..3 {
            m[k] += p[k] / n as f64;
        }
    }
    let mut a = DMatrix::<f64>::zeros(n, 4);
    let mut b = DVector::<f64>::zeros(n);
    for (i, p) in points.iter().enumerate() {
        let d = sub(*p, m);
        a[(i, 0)] = 2.0 * d[0];
        a[(i, 1)] = 2.0 * d[1];
        a[(i, 2)] = 2.0 * d[2];
        a[(i, 3)] = 1.0;
        b[i] = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    }
    let svd = a.svd(true, true);
    let x = svd
        .solve(&b, 1e-12)
        .map_err(|e| ProbeError::Degenerate(format!("algebraic sphere fit: {e}")))?;
    let c = [x[0] + m[0], x[1] + m[1], x[2] + m[2]];
    let r2 = x[3] + x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    if r2.is_nan() || r2 <= 0.0 {
        return Err(ProbeError::Degenerate(
            "algebraic sphere fit gave no real radius".into(),
        ));
    }
    let r = r2.sqrt();
    Ok(Sphere {
        center_mm: c,
        radius_mm: r,
        rms_um: rms_radial(points, c, |_| r),
    })
}

/// RMS (µm) of `|p − c| − radius(i)`.
pub fn rms_radial(points: &[[f64; 3]], c: [f64; 3], radius: impl Fn(usize) -> f64) -> f64 {
    if points.is_empty() {
        return f64::NAN;
    }
    let s: f64 = points
        .iter()
        .enumerate()
        .map(|(i, p)| (norm(sub(*p, c)) - radius(i)).powi(2))
        .sum();
    (s / points.len() as f64).sqrt() * 1000.0
}

/// Levenberg–Marquardt on `r(x)` with Jacobian `J(x)` (normal equations, Marquardt scaling). `eval` fills
/// the residuals and the Jacobian for the parameters; returns the parameters at convergence.
pub(crate) fn levenberg_marquardt(
    mut x: DVector<f64>,
    n_res: usize,
    mut eval: impl FnMut(&DVector<f64>, &mut DVector<f64>, &mut DMatrix<f64>),
    max_iter: usize,
) -> Result<DVector<f64>, ProbeError> {
    let m = x.len();
    let mut r = DVector::zeros(n_res);
    let mut j = DMatrix::zeros(n_res, m);
    eval(&x, &mut r, &mut j);
    let mut cost = r.norm_squared();
    let mut lambda = 1e-6;
    let mut r_try = DVector::zeros(n_res);
    let mut j_try = DMatrix::zeros(n_res, m);
    for _ in 0..max_iter {
        let jtj = j.tr_mul(&j);
        let g = j.tr_mul(&r);
        let mut improved = false;
        for _ in 0..12 {
            let mut a = jtj.clone();
            for k in 0..m {
                a[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
            }
            let Some(ch) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let step = ch.solve(&(-&g));
            let x_try = &x + &step;
            eval(&x_try, &mut r_try, &mut j_try);
            let c_try = r_try.norm_squared();
            if c_try.is_finite() && c_try <= cost {
                let rel = (cost - c_try) / cost.max(1e-300);
                let small = step.norm() <= 1e-12 * (1.0 + x.norm());
                x = x_try;
                std::mem::swap(&mut r, &mut r_try);
                std::mem::swap(&mut j, &mut j_try);
                cost = c_try;
                lambda = (lambda * 0.1).max(1e-12);
                improved = true;
                if rel < 1e-14 || small {
                    return Ok(x);
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    if x.iter().all(|v| v.is_finite()) {
        Ok(x)
    } else {
        Err(ProbeError::Degenerate(
            "geometric fit did not converge".into(),
        ))
    }
}

/// Geometric sphere fit: minimises Σ(|p − c| − ρ)²; the radius is free (`fixed_radius_mm = None`) or fixed.
/// Starts from the algebraic fit.
pub fn geometric_sphere(
    points: &[[f64; 3]],
    fixed_radius_mm: Option<f64>,
) -> Result<Sphere, ProbeError> {
    let start = algebraic_sphere(points)?;
    geometric_sphere_from(points, fixed_radius_mm, start.center_mm, start.radius_mm)
}

/// Geometric sphere fit from a given start (needs ≥ 3 points with a fixed radius, ≥ 4 free).
pub fn geometric_sphere_from(
    points: &[[f64; 3]],
    fixed_radius_mm: Option<f64>,
    center0: [f64; 3],
    radius0: f64,
) -> Result<Sphere, ProbeError> {
    let free = fixed_radius_mm.is_none();
    let m = if free { 4 } else { 3 };
    if points.len() < m {
        return Err(ProbeError::TooFew {
            need: m,
            got: points.len(),
            what: "a sphere".into(),
        });
    }
    let mut x0 = DVector::from_column_slice(&[center0[0], center0[1], center0[2], radius0]);
    if !free {
        x0 = x0.rows(0, 3).into_owned();
    }
    let x = levenberg_marquardt(
        x0,
        points.len(),
        |x, r, j| {
            let c = [x[0], x[1], x[2]];
            let rho = fixed_radius_mm.unwrap_or_else(|| x[3]);
            for (i, p) in points.iter().enumerate() {
                let d = sub(*p, c);
                let l = norm(d).max(1e-300);
                r[i] = l - rho;
                for k in 0..3 {
                    j[(i, k)] = -d[k] / l;
                }
                if free {
                    j[(i, 3)] = -1.0;
                }
            }
        },
        100,
    )?;
    let c = [x[0], x[1], x[2]];
    let rho = fixed_radius_mm.unwrap_or_else(|| x[3]);
    Ok(Sphere {
        center_mm: c,
        radius_mm: rho,
        rms_um: rms_radial(points, c, |_| rho),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn on_sphere(c: [f64; 3], r: f64) -> Vec<[f64; 3]> {
        let mut v = Vec::new();
        for el in [0.0f64, 30.0, 60.0, 85.0] {
            for k in 0..12 {
                let (a, e) = ((30.0 * k as f64 + el).to_radians(), el.to_radians());
                v.push([
                    c[0] + r * e.cos() * a.cos(),
                    c[1] + r * e.cos() * a.sin(),
                    c[2] + r * e.sin(),
                ]);
            }
        }
        v
    }

    #[test]
    fn exact_sphere_is_recovered() {
        // Reference: the generating sphere; tolerance 1e-9 mm (exact data, rounding only).
        let pts = on_sphere([10.0, -5.0, 3.0], 7.5);
        let a = algebraic_sphere(&pts).unwrap();
        let g = geometric_sphere(&pts, None).unwrap();
        let f = geometric_sphere(&pts, Some(7.5)).unwrap();
        for s in [a, g, f] {
            assert!((s.center_mm[0] - 10.0).abs() < 1e-9);
            assert!((s.center_mm[1] + 5.0).abs() < 1e-9);
            assert!((s.center_mm[2] - 3.0).abs() < 1e-9);
            assert!((s.radius_mm - 7.5).abs() < 1e-9);
        }
    }

    #[test]
    fn one_ring_is_degenerate() {
        let pts: Vec<[f64; 3]> = on_sphere([0.0; 3], 5.0).into_iter().take(12).collect();
        let labels: Vec<String> = (0..12).map(|i| format!("row {i}")).collect();
        let e = check_not_coplanar(&pts, &labels).unwrap_err().to_string();
        assert!(e.contains("one plane") && e.contains("row 0"), "{e}");
    }
}
