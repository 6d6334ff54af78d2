//! Effective stylus radius as a function of direction and speed: `r_eff(n, v) = Φ(n, v)·β` (mm), linear in
//! its coefficients β for every model kind.
//!
//! Direction variables (of the surface normal `n = −approach`): `t = n_z = sin φ` (elevation φ) and the
//! azimuth θ = atan2(n_y, n_x). Speed `v` in mm/s (`feed_mm_min / 60`).
//!
//! - **constant** (`probe_radius`): one effective radius, `Φ = [1]`.
//! - **bilinear** (the seed's reference method): effective radii at the nodes of an azimuth × elevation grid,
//!   bilinear interpolation between the four neighbouring nodes (periodic in azimuth, the end value held
//!   beyond the first / last elevation; a node at the pole is one value for all azimuths), plus one global
//!   speed slope `s·v` (the seed: pretravel linear in speed).
//! - **harmonic** (smooth): zonal terms `t^{2j}` (j = 0..=D), azimuthal harmonics
//!   `(1 − t²)·t^{2j}·{cos kθ, sin kθ}` for k = 2..=K, j = 0..D−1, and speed terms `v` (and `v·t²` with two
//!   speed terms). The first-order terms `n_x, n_y, n_z` are left out on purpose: on one sphere they are
//!   indistinguishable from a shift of its centre (the fit puts them into `sphere_center_mm`).

use serde::{Deserialize, Serialize};

/// Direction and speed of one touch, precomputed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirSpeed {
    /// sin(elevation) of the normal.
    pub t: f64,
    /// Azimuth of the normal, radians.
    pub theta: f64,
    /// Probing speed, mm/s.
    pub v: f64,
}

impl DirSpeed {
    /// From the unit approach vector and the speed (mm/s).
    pub fn from_approach(u: [f64; 3], v_mm_s: f64) -> Self {
        let n = [-u[0], -u[1], -u[2]];
        DirSpeed {
            t: n[2].clamp(-1.0, 1.0),
            theta: n[1].atan2(n[0]),
            v: v_mm_s,
        }
    }
    pub fn azimuth_deg(&self) -> f64 {
        self.theta.to_degrees().rem_euclid(360.0)
    }
    pub fn elevation_deg(&self) -> f64 {
        self.t.asin().to_degrees()
    }
}

/// The model's structure (without coefficients).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Structure {
    Constant,
    Bilinear {
        azimuth_nodes_deg: Vec<f64>,
        elevation_nodes_deg: Vec<f64>,
    },
    Harmonic {
        /// Highest azimuthal order K (0 = no azimuth dependence).
        max_order: usize,
        /// Zonal degree D (in t²).
        elevation_degree: usize,
        /// 0, 1 (`v`) or 2 (`v`, `v·t²`).
        speed_terms: usize,
    },
}

/// Elevation node treated as the pole (one value for every azimuth).
const POLE_DEG: f64 = 89.9;

impl Structure {
    /// A short name for reports (`harmonic K=6 D=1 speed=1`).
    pub fn name(&self) -> String {
        match self {
            Structure::Constant => "constant (probe_radius)".into(),
            Structure::Bilinear {
                azimuth_nodes_deg,
                elevation_nodes_deg,
            } => format!(
                "bilinear {}×{} grid + speed slope (seed 003)",
                azimuth_nodes_deg.len(),
                elevation_nodes_deg.len()
            ),
            Structure::Harmonic {
                max_order,
                elevation_degree,
                speed_terms,
            } => format!("harmonic K={max_order} D={elevation_degree} speed_terms={speed_terms}"),
        }
    }

    /// Number of coefficients.
    pub fn len(&self) -> usize {
        match self {
            Structure::Constant => 1,
            Structure::Bilinear {
                azimuth_nodes_deg,
                elevation_nodes_deg,
            } => {
                elevation_nodes_deg
                    .iter()
                    .map(|&e| {
                        if e >= POLE_DEG {
                            1
                        } else {
                            azimuth_nodes_deg.len()
                        }
                    })
                    .sum::<usize>()
                    + 1
            }
            Structure::Harmonic {
                max_order,
                elevation_degree,
                speed_terms,
            } => {
                let d = *elevation_degree;
                (d + 1) + 2 * max_order.saturating_sub(1) * d.max(1) + speed_terms
            }
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether the model depends on the speed.
    pub fn has_speed(&self) -> bool {
        match self {
            Structure::Constant => false,
            Structure::Bilinear { .. } => true,
            Structure::Harmonic { speed_terms, .. } => *speed_terms > 0,
        }
    }

    /// Index of the speed slope coefficient of a bilinear model.
    fn bilinear_speed_index(&self) -> usize {
        self.len() - 1
    }

    /// Fills `out` (length [`Structure::len`]) with Φ(n, v).
    pub fn basis(&self, d: DirSpeed, out: &mut [f64]) {
        out.iter_mut().for_each(|x| *x = 0.0);
        match self {
            Structure::Constant => out[0] = 1.0,
            Structure::Bilinear {
                azimuth_nodes_deg: az,
                elevation_nodes_deg: el,
            } => {
                let (ej, ew) = bracket_clamped(el, d.elevation_deg());
                let (ak, aw) = bracket_periodic(az, d.azimuth_deg());
                let mut offs = Vec::with_capacity(el.len());
                let mut o = 0;
                for &e in el {
                    offs.push(o);
                    o += if e >= POLE_DEG { 1 } else { az.len() };
                }
                for (j, wj) in [(ej.0, ew.0), (ej.1, ew.1)] {
                    if wj == 0.0 {
                        continue;
                    }
                    if el[j] >= POLE_DEG {
                        out[offs[j]] += wj;
                    } else {
                        out[offs[j] + ak.0] += wj * aw.0;
                        out[offs[j] + ak.1] += wj * aw.1;
                    }
                }
                out[self.bilinear_speed_index()] = d.v;
            }
            Structure::Harmonic {
                max_order,
                elevation_degree,
                speed_terms,
            } => {
                let t2 = d.t * d.t;
                let mut i = 0;
                let mut p = 1.0;
                for _ in 0..=*elevation_degree {
                    out[i] = p;
                    p *= t2;
                    i += 1;
                }
                let c2 = 1.0 - t2;
                for k in 2..=*max_order {
                    let (s, c) = (k as f64 * d.theta).sin_cos();
                    let mut p = c2;
                    for _ in 0..(*elevation_degree).max(1) {
                        out[i] = p * c;
                        out[i + 1] = p * s;
                        p *= t2;
                        i += 2;
                    }
                }
                if *speed_terms >= 1 {
                    out[i] = d.v;
                    i += 1;
                }
                if *speed_terms >= 2 {
                    out[i] = d.v * t2;
                }
            }
        }
    }

    /// Φ(n, v)·β.
    pub fn eval(&self, coef: &[f64], d: DirSpeed) -> f64 {
        let mut phi = vec![0.0; self.len()];
        self.basis(d, &mut phi);
        phi.iter().zip(coef).map(|(a, b)| a * b).sum()
    }

    /// The part of Φ·β that depends on the speed (coefficient of the speed terms times their basis).
    pub fn speed_part(&self, coef: &[f64], d: DirSpeed) -> f64 {
        if !self.has_speed() {
            return 0.0;
        }
        self.eval(coef, d) - self.eval(coef, DirSpeed { v: 0.0, ..d })
    }
}

/// Indices and weights of the two nodes around `x` in sorted `nodes`, the end value held outside.
fn bracket_clamped(nodes: &[f64], x: f64) -> ((usize, usize), (f64, f64)) {
    let n = nodes.len();
    if n == 1 || x <= nodes[0] {
        return ((0, 0), (1.0, 0.0));
    }
    if x >= nodes[n - 1] {
        return ((n - 1, n - 1), (1.0, 0.0));
    }
    let j = nodes.partition_point(|&v| v <= x).clamp(1, n - 1);
    let w = (x - nodes[j - 1]) / (nodes[j] - nodes[j - 1]);
    ((j - 1, j), (1.0 - w, w))
}

/// Indices and weights of the two nodes around azimuth `x` (degrees) in sorted `nodes` ⊂ [0, 360), periodic.
fn bracket_periodic(nodes: &[f64], x: f64) -> ((usize, usize), (f64, f64)) {
    let n = nodes.len();
    if n == 1 {
        return ((0, 0), (1.0, 0.0));
    }
    let x = x.rem_euclid(360.0);
    let j = nodes.partition_point(|&v| v <= x);
    let (a, b) = if j == 0 || j == n {
        (n - 1, 0)
    } else {
        (j - 1, j)
    };
    let span = (nodes[b] - nodes[a]).rem_euclid(360.0);
    let span = if span == 0.0 { 360.0 } else { span };
    let w = (x - nodes[a]).rem_euclid(360.0) / span;
    ((a, b), (1.0 - w, w))
}

/// Distinct values of `xs` (rounded to 0.01), sorted; `None` when there are more than `max`.
pub(crate) fn distinct_nodes(xs: impl Iterator<Item = f64>, max: usize) -> Option<Vec<f64>> {
    let mut v: Vec<f64> = xs.map(|x| (x * 100.0).round() / 100.0).collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    (v.len() <= max).then_some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_weights_interpolate_and_wrap() {
        // Reference: hand-computed bilinear weights; tolerance 1e-12.
        let s = Structure::Bilinear {
            azimuth_nodes_deg: vec![0.0, 90.0, 180.0, 270.0],
            elevation_nodes_deg: vec![0.0, 45.0, 90.0],
        };
        assert_eq!(s.len(), 4 + 4 + 1 + 1);
        // Node values = azimuth index + 10·elevation index; pole = 20; speed slope 0.
        let coef = [0.0, 1.0, 2.0, 3.0, 10.0, 11.0, 12.0, 13.0, 20.0, 0.0];
        let at = |az: f64, el: f64| {
            let (a, e) = (az.to_radians(), el.to_radians());
            let u = [-e.cos() * a.cos(), -e.cos() * a.sin(), -e.sin()];
            s.eval(&coef, DirSpeed::from_approach(u, 0.0))
        };
        assert!((at(45.0, 0.0) - 0.5).abs() < 1e-12);
        assert!((at(315.0, 0.0) - 1.5).abs() < 1e-12); // between 270° (3) and 0° (0)
        assert!((at(90.0, 22.5) - 6.0).abs() < 1e-12);
        assert!((at(0.0, 67.5) - 15.0).abs() < 1e-12);
        assert!((at(10.0, -20.0) - at(10.0, 0.0)).abs() < 1e-12); // held below the lowest ring
    }

    #[test]
    fn harmonic_length_matches_basis() {
        for k in [0, 2, 3, 6] {
            for d in [1, 2] {
                for sp in [0, 1, 2] {
                    let s = Structure::Harmonic {
                        max_order: k,
                        elevation_degree: d,
                        speed_terms: sp,
                    };
                    let mut phi = vec![f64::NAN; s.len()];
                    s.basis(
                        DirSpeed {
                            t: 0.3,
                            theta: 1.0,
                            v: 2.0,
                        },
                        &mut phi,
                    );
                    assert!(phi.iter().all(|x| x.is_finite()), "{k} {d} {sp}");
                }
            }
        }
    }
}
