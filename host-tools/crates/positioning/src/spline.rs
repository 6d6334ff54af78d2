//! Cubic curves of the deviation along the stroke: interpolating splines, least-squares (penalised)
//! B-splines solved through banded normal equations, and resampling to the firmware's uniform table.
//!
//! Glossary:
//! - *knot*: a breakpoint of a piecewise polynomial; a segment runs from one knot to the next.
//! - *piecewise cubic*: per segment `y = c0 + c1·u + c2·u² + c3·u³` with `u = x − knot` in mm.
//! - *natural* / *not-a-knot* / *clamped*: end conditions of an interpolating cubic spline (zero
//!   curvature; third derivative continuous across the second and last-but-one knot; given end slopes).
//! - *B-spline basis*: the cubic B-splines on a clamped knot vector; a least-squares fit in this basis has
//!   banded (bandwidth 3) normal equations, so its cost is linear in the number of points.
//! - *roughness penalty*: `λ·∫ f''(x)² dx`; λ is the smoothing parameter (chosen by cross-validation).
//! - *uniform table*: the firmware's form, uniform segments with Horner coefficients `[c0,c1,c2,c3]` in µm
//!   over the local parameter `t ∈ [0,1)`.

use thiserror::Error;

/// Why a curve could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum SplineError {
    #[error("need at least {needed} distinct positions, got {got}")]
    TooFewPoints { needed: usize, got: usize },
    #[error("positions must be strictly increasing and finite (index {index})")]
    NotIncreasing { index: usize },
    #[error("non-finite value at index {index}")]
    NonFinite { index: usize },
    #[error("the normal equations are singular (no data to determine the curve)")]
    Singular,
    #[error("segment count {0} is outside 1..=1024")]
    BadSegmentCount(usize),
}

/// A piecewise cubic in power form per segment (`u = x − knots[i]`, mm → µm). Outside
/// `[knots[0], knots[last]]` the end value is held (like the firmware's `OutsideStroke::Hold`).
#[derive(Debug, Clone, PartialEq)]
pub struct PiecewiseCubic {
    pub knots: Vec<f64>,
    pub coeffs: Vec<[f64; 4]>,
}

impl PiecewiseCubic {
    /// A constant curve over `[a, b]`.
    pub fn constant(a: f64, b: f64, value: f64) -> Self {
        let b = if b > a { b } else { a + 1.0 };
        PiecewiseCubic {
            knots: vec![a, b],
            coeffs: vec![[value, 0.0, 0.0, 0.0]],
        }
    }

    /// A straight line `value_at_a + slope·(x − a)` over `[a, b]`.
    pub fn line(a: f64, b: f64, value_at_a: f64, slope: f64) -> Self {
        let b = if b > a { b } else { a + 1.0 };
        PiecewiseCubic {
            knots: vec![a, b],
            coeffs: vec![[value_at_a, slope, 0.0, 0.0]],
        }
    }

    pub fn start(&self) -> f64 {
        self.knots[0]
    }
    pub fn end(&self) -> f64 {
        *self.knots.last().unwrap()
    }

    fn segment(&self, x: f64) -> usize {
        let n = self.coeffs.len();
        // partition_point: first knot > x.
        let i = self.knots.partition_point(|&k| k <= x);
        i.saturating_sub(1).min(n - 1)
    }

    /// Value at `x` (held at the end values outside the knot range).
    pub fn eval(&self, x: f64) -> f64 {
        let x = x.clamp(self.start(), self.end());
        let i = self.segment(x);
        let u = x - self.knots[i];
        let c = &self.coeffs[i];
        c[0] + u * (c[1] + u * (c[2] + u * c[3]))
    }

    /// First derivative at `x` (inside the range; at the ends the one-sided derivative).
    pub fn slope(&self, x: f64) -> f64 {
        let x = x.clamp(self.start(), self.end());
        let i = self.segment(x);
        let u = x - self.knots[i];
        let c = &self.coeffs[i];
        c[1] + u * (2.0 * c[2] + u * 3.0 * c[3])
    }

    /// Second derivative at `x`.
    pub fn curvature(&self, x: f64) -> f64 {
        let x = x.clamp(self.start(), self.end());
        let i = self.segment(x);
        let u = x - self.knots[i];
        let c = &self.coeffs[i];
        2.0 * c[2] + 6.0 * c[3] * u
    }

    /// Value at `x`, continuing the first / last piece's polynomial beyond the knot range.
    pub fn eval_extended(&self, x: f64) -> f64 {
        let (u, c) = self.piece_extended(x);
        c[0] + u * (c[1] + u * (c[2] + u * c[3]))
    }

    /// First derivative, continuing the end pieces beyond the knot range (one-sided at the knots' ends).
    pub fn slope_extended(&self, x: f64) -> f64 {
        let (u, c) = self.piece_extended(x);
        c[1] + u * (2.0 * c[2] + u * 3.0 * c[3])
    }

    /// The piece `x` falls in (the first / last beyond the knot range) and `x`'s offset from its knot.
    fn piece_extended(&self, x: f64) -> (f64, &[f64; 4]) {
        let i = if x < self.start() {
            0
        } else {
            self.segment(x.min(self.end()))
        };
        (x - self.knots[i], &self.coeffs[i])
    }

    /// The curve over `[lo, hi]`: equal to this one on `[a, b]` (clamped into this curve's own range) and
    /// to its value at `a` before, at `b` after (the end values held beyond `[a, b]`, e.g. beyond the
    /// targets one approach direction reached), so that nothing is extrapolated from an end piece.
    pub fn held_beyond(&self, a: f64, b: f64, lo: f64, hi: f64) -> PiecewiseCubic {
        let a = a.clamp(self.start(), self.end()).max(lo);
        let b = b.clamp(a, self.end()).min(hi);
        let mut pieces: Vec<(f64, [f64; 4])> = Vec::new();
        if a > lo {
            pieces.push((lo, [self.eval(a), 0.0, 0.0, 0.0]));
        }
        for (i, c) in self.coeffs.iter().enumerate() {
            let (k0, k1) = (self.knots[i], self.knots[i + 1]);
            if k1 <= a || k0 >= b {
                continue;
            }
            // The piece re-based from k0 to its first point inside [a, b] (Taylor shift by d).
            let s = k0.max(a);
            let d = s - k0;
            pieces.push((
                s,
                [
                    c[0] + d * (c[1] + d * (c[2] + d * c[3])),
                    c[1] + d * (2.0 * c[2] + 3.0 * c[3] * d),
                    c[2] + 3.0 * c[3] * d,
                    c[3],
                ],
            ));
        }
        if b < hi {
            pieces.push((b, [self.eval(b), 0.0, 0.0, 0.0]));
        }
        let mut knots: Vec<f64> = pieces.iter().map(|p| p.0).collect();
        knots.push(hi);
        PiecewiseCubic {
            knots,
            coeffs: pieces.into_iter().map(|p| p.1).collect(),
        }
    }

    /// Pointwise linear combination `a·self + b·other` on the union of both knot sets.
    pub fn combine(&self, a: f64, other: &PiecewiseCubic, b: f64) -> PiecewiseCubic {
        let mut knots: Vec<f64> = self
            .knots
            .iter()
            .chain(other.knots.iter())
            .copied()
            .collect();
        knots.sort_by(f64::total_cmp);
        knots.dedup();
        let coeffs = knots
            .windows(2)
            .map(|w| {
                let (l, r) = (w[0], w[1]);
                let m = 0.5 * (l + r);
                let one = |p: &PiecewiseCubic| {
                    // Polynomial of p's segment containing the midpoint, re-expanded at l.
                    let i = p.segment(m.clamp(p.start(), p.end()));
                    if m < p.start() || m > p.end() {
                        return [p.eval(m), 0.0, 0.0, 0.0];
                    }
                    shift(&p.coeffs[i], l - p.knots[i])
                };
                let (ca, cb) = (one(self), one(other));
                [
                    a * ca[0] + b * cb[0],
                    a * ca[1] + b * cb[1],
                    a * ca[2] + b * cb[2],
                    a * ca[3] + b * cb[3],
                ]
            })
            .collect();
        PiecewiseCubic { knots, coeffs }
    }
}

/// Re-expands `c0 + c1 u + c2 u² + c3 u³` around `u = s` (Taylor shift).
fn shift(c: &[f64; 4], s: f64) -> [f64; 4] {
    [
        c[0] + s * (c[1] + s * (c[2] + s * c[3])),
        c[1] + s * (2.0 * c[2] + 3.0 * c[3] * s),
        c[2] + 3.0 * c[3] * s,
        c[3],
    ]
}

fn check_xy(x: &[f64], y: &[f64], needed: usize) -> Result<(), SplineError> {
    if x.len() < needed || y.len() != x.len() {
        return Err(SplineError::TooFewPoints {
            needed,
            got: x.len().min(y.len()),
        });
    }
    for i in 0..x.len() {
        if !x[i].is_finite() || !y[i].is_finite() {
            return Err(SplineError::NonFinite { index: i });
        }
        if i > 0 && x[i] <= x[i - 1] {
            return Err(SplineError::NotIncreasing { index: i });
        }
    }
    Ok(())
}

/// Straight segments through the points (C0).
pub fn piecewise_linear(x: &[f64], y: &[f64]) -> Result<PiecewiseCubic, SplineError> {
    check_xy(x, y, 1)?;
    if x.len() == 1 {
        return Ok(PiecewiseCubic::constant(x[0], x[0], y[0]));
    }
    let coeffs = (0..x.len() - 1)
        .map(|i| [y[i], (y[i + 1] - y[i]) / (x[i + 1] - x[i]), 0.0, 0.0])
        .collect();
    Ok(PiecewiseCubic {
        knots: x.to_vec(),
        coeffs,
    })
}

/// End condition of an interpolating cubic spline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EndCondition {
    /// Zero second derivative at both ends.
    Natural,
    /// Third derivative continuous at the second and the last-but-one knot (reproduces cubics).
    NotAKnot,
    /// Given first derivatives at the two ends.
    Clamped { start_slope: f64, end_slope: f64 },
}

/// Solves a tridiagonal system in place (Thomas algorithm): `sub[i]·m[i-1] + diag[i]·m[i] + sup[i]·m[i+1] = rhs[i]`.
fn solve_tridiagonal(sub: &[f64], diag: &[f64], sup: &[f64], rhs: &[f64]) -> Vec<f64> {
    let n = diag.len();
    let mut c = vec![0.0; n];
    let mut d = vec![0.0; n];
    c[0] = sup[0] / diag[0];
    d[0] = rhs[0] / diag[0];
    for i in 1..n {
        let den = diag[i] - sub[i] * c[i - 1];
        c[i] = if i + 1 < n { sup[i] / den } else { 0.0 };
        d[i] = (rhs[i] - sub[i] * d[i - 1]) / den;
    }
    let mut m = vec![0.0; n];
    m[n - 1] = d[n - 1];
    for i in (0..n - 1).rev() {
        m[i] = d[i] - c[i] * m[i + 1];
    }
    m
}

/// Power-form coefficients of the cubic spline with second derivatives `m` at the knots.
fn from_second_derivatives(x: &[f64], y: &[f64], m: &[f64]) -> PiecewiseCubic {
    let coeffs = (0..x.len() - 1)
        .map(|i| {
            let h = x[i + 1] - x[i];
            let c1 = (y[i + 1] - y[i]) / h - h * (2.0 * m[i] + m[i + 1]) / 6.0;
            [y[i], c1, m[i] / 2.0, (m[i + 1] - m[i]) / (6.0 * h)]
        })
        .collect();
    PiecewiseCubic {
        knots: x.to_vec(),
        coeffs,
    }
}

/// The C2 cubic spline through `(x[i], y[i])` (x strictly increasing) with the given end condition.
/// Two points give the straight line; not-a-knot through three points gives the parabola.
pub fn interpolate(x: &[f64], y: &[f64], end: EndCondition) -> Result<PiecewiseCubic, SplineError> {
    check_xy(x, y, 2)?;
    let n = x.len() - 1; // segments
    let h: Vec<f64> = (0..n).map(|i| x[i + 1] - x[i]).collect();
    let delta: Vec<f64> = (0..n).map(|i| (y[i + 1] - y[i]) / h[i]).collect();
    let m: Vec<f64> = match end {
        EndCondition::Clamped {
            start_slope,
            end_slope,
        } => {
            // Full (n+1) system with derivative rows at both ends.
            let k = n + 1;
            let (mut sub, mut diag, mut sup, mut rhs) =
                (vec![0.0; k], vec![0.0; k], vec![0.0; k], vec![0.0; k]);
            diag[0] = 2.0 * h[0];
            sup[0] = h[0];
            rhs[0] = 6.0 * (delta[0] - start_slope);
            for i in 1..n {
                sub[i] = h[i - 1];
                diag[i] = 2.0 * (h[i - 1] + h[i]);
                sup[i] = h[i];
                rhs[i] = 6.0 * (delta[i] - delta[i - 1]);
            }
            sub[n] = h[n - 1];
            diag[n] = 2.0 * h[n - 1];
            rhs[n] = 6.0 * (end_slope - delta[n - 1]);
            solve_tridiagonal(&sub, &diag, &sup, &rhs)
        }
        _ if n == 1 => vec![0.0, 0.0],
        EndCondition::NotAKnot if n == 2 => {
            let q = 2.0 * (delta[1] - delta[0]) / (h[0] + h[1]);
            vec![q, q, q]
        }
        EndCondition::Natural | EndCondition::NotAKnot => {
            // Interior unknowns m[1..n-1].
            let k = n - 1;
            let (mut sub, mut diag, mut sup, mut rhs) =
                (vec![0.0; k], vec![0.0; k], vec![0.0; k], vec![0.0; k]);
            for j in 0..k {
                let i = j + 1;
                sub[j] = h[i - 1];
                diag[j] = 2.0 * (h[i - 1] + h[i]);
                sup[j] = h[i];
                rhs[j] = 6.0 * (delta[i] - delta[i - 1]);
            }
            let nak = matches!(end, EndCondition::NotAKnot);
            if nak {
                // m0 = m1 (1 + h0/h1) − m2 h0/h1, substituted into the first row.
                let (h0, h1) = (h[0], h[1]);
                diag[0] += h0 * (1.0 + h0 / h1);
                sup[0] -= h0 * h0 / h1;
                // m_n = m_{n-1}(1 + h_{n-1}/h_{n-2}) − m_{n-2} h_{n-1}/h_{n-2}, into the last row.
                let (ha, hb) = (h[n - 2], h[n - 1]);
                diag[k - 1] += hb * (1.0 + hb / ha);
                sub[k - 1] -= hb * hb / ha;
            }
            let inner = solve_tridiagonal(&sub, &diag, &sup, &rhs);
            let mut m = vec![0.0; n + 1];
            m[1..n].copy_from_slice(&inner);
            if nak {
                m[0] = m[1] * (1.0 + h[0] / h[1]) - m[2] * h[0] / h[1];
                m[n] = m[n - 1] * (1.0 + h[n - 1] / h[n - 2]) - m[n - 2] * h[n - 1] / h[n - 2];
            }
            m
        }
    };
    Ok(from_second_derivatives(x, y, &m))
}

// ---------------------------------------------------------------------------------------------
// B-spline basis and banded least squares.

/// Cubic B-spline basis on a clamped knot vector over the breakpoints `b[0] < … < b[m]`
/// (`m` intervals, `m + 3` basis functions).
#[derive(Debug, Clone, PartialEq)]
pub struct BSplineBasis {
    breaks: Vec<f64>,
    knots: Vec<f64>, // clamped: b0 ×4, b1..b_{m-1}, b_m ×4
    uniform: bool,
    /// For non-uniform breakpoints: interval index at the left edge of each of `8·m` equal cells, so that
    /// finding a position's interval is a table lookup and a short scan instead of a binary search.
    cells: Vec<u32>,
    /// Per interval, the reciprocals of the six knot differences of the Cox–de Boor recursion, so that
    /// evaluating the basis needs no division.
    inv: Vec<[f64; 6]>,
}

impl BSplineBasis {
    pub fn new(breaks: Vec<f64>) -> Result<Self, SplineError> {
        let zeros = vec![0.0; breaks.len()];
        check_xy(&breaks, &zeros, 2)?;
        let m = breaks.len() - 1;
        let mut knots = Vec::with_capacity(m + 7);
        knots.extend_from_slice(&[breaks[0]; 3]);
        knots.extend_from_slice(&breaks);
        knots.extend_from_slice(&[breaks[m]; 3]);
        let h = (breaks[m] - breaks[0]) / m as f64;
        let uniform = breaks
            .iter()
            .enumerate()
            .all(|(i, &b)| (b - (breaks[0] + h * i as f64)).abs() <= 1e-12 * (1.0 + b.abs()));
        let cells = if uniform {
            Vec::new()
        } else {
            let nc = 8 * m;
            let w = (breaks[m] - breaks[0]) / nc as f64;
            (0..nc)
                .map(|c| {
                    let x = breaks[0] + w * c as f64;
                    (breaks
                        .partition_point(|&k| k <= x)
                        .saturating_sub(1)
                        .min(m - 1)) as u32
                })
                .collect()
        };
        let inv = (0..m)
            .map(|j| {
                let i = j + 3;
                let d = |a: usize, b: usize| 1.0 / (knots[i + a] - knots[i + 1 - b]);
                [d(1, 1), d(1, 2), d(2, 1), d(1, 3), d(2, 2), d(3, 1)]
            })
            .collect();
        Ok(BSplineBasis {
            breaks,
            knots,
            uniform,
            cells,
            inv,
        })
    }

    /// Uniform breakpoints: `intervals` equal intervals over `[a, b]`.
    pub fn uniform(a: f64, b: f64, intervals: usize) -> Result<Self, SplineError> {
        if intervals == 0 || !(b > a) {
            return Err(SplineError::TooFewPoints { needed: 2, got: 1 });
        }
        let h = (b - a) / intervals as f64;
        let mut breaks: Vec<f64> = (0..=intervals).map(|i| a + h * i as f64).collect();
        breaks[intervals] = b;
        Self::new(breaks)
    }

    pub fn breaks(&self) -> &[f64] {
        &self.breaks
    }
    pub fn intervals(&self) -> usize {
        self.breaks.len() - 1
    }
    pub fn len(&self) -> usize {
        self.breaks.len() + 2
    }
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Interval index containing `x` (clamped to the range).
    pub fn interval(&self, x: f64) -> usize {
        let m = self.intervals();
        let b = &self.breaks;
        if self.uniform {
            let h = (b[m] - b[0]) / m as f64;
            let j = ((x - b[0]) / h).floor();
            if !(j >= 0.0) {
                return 0;
            }
            let j = (j as usize).min(m - 1);
            // Guard against rounding at the break.
            if j + 1 < m && x >= b[j + 1] {
                return j + 1;
            }
            if j > 0 && x < b[j] {
                return j - 1;
            }
            j
        } else {
            let nc = self.cells.len();
            let c = ((x - b[0]) / (b[m] - b[0]) * nc as f64).floor();
            let c = if c >= 0.0 {
                (c as usize).min(nc - 1)
            } else {
                0
            };
            let mut j = self.cells[c] as usize;
            // The cell's left edge lies in interval j; x lies at or after it (up to rounding).
            while j > 0 && x < b[j] {
                j -= 1;
            }
            while j + 1 < m && x >= b[j + 1] {
                j += 1;
            }
            j
        }
    }

    /// The four nonzero basis values at `x` and the index of the first: `B_{j..j+4}(x)`.
    pub fn values(&self, x: f64) -> (usize, [f64; 4]) {
        let x = x.clamp(self.breaks[0], *self.breaks.last().unwrap());
        let j = self.interval(x);
        let i = j + 3; // span in the clamped knot vector
        let u = &self.knots;
        let inv = &self.inv[j];
        let mut n = [0.0; 4];
        let mut left = [0.0; 4];
        let mut right = [0.0; 4];
        n[0] = 1.0;
        let mut k = 0;
        for d in 1..=3 {
            left[d] = x - u[i + 1 - d];
            right[d] = u[i + d] - x;
            let mut saved = 0.0;
            for r in 0..d {
                // 1 / (right[r+1] + left[d-r]) = 1 / (u[i+r+1] − u[i+1−d+r]), precomputed.
                let temp = n[r] * inv[k];
                k += 1;
                n[r] = saved + right[r + 1] * temp;
                saved = left[d - r] * temp;
            }
            n[d] = saved;
        }
        (j, n)
    }

    /// Second derivatives of the four nonzero basis functions of interval `j`, evaluated at `x`
    /// with that interval's polynomial pieces (NURBS Book algorithm A2.3, n = 2).
    fn second_derivatives(&self, j: usize, x: f64) -> [f64; 4] {
        const P: usize = 3;
        let i = j + 3;
        let u = &self.knots;
        let mut ndu = [[0.0f64; 4]; 4];
        let mut left = [0.0; 4];
        let mut right = [0.0; 4];
        ndu[0][0] = 1.0;
        for d in 1..=P {
            left[d] = x - u[i + 1 - d];
            right[d] = u[i + d] - x;
            let mut saved = 0.0;
            for r in 0..d {
                ndu[d][r] = right[r + 1] + left[d - r];
                let temp = ndu[r][d - 1] / ndu[d][r];
                ndu[r][d] = saved + right[r + 1] * temp;
                saved = left[d - r] * temp;
            }
            ndu[d][d] = saved;
        }
        let mut ders = [[0.0f64; 4]; 3];
        for r in 0..=P {
            let mut a = [[0.0f64; 4]; 2];
            let (mut s1, mut s2) = (0usize, 1usize);
            a[0][0] = 1.0;
            for k in 1..=2usize {
                let mut d = 0.0;
                let rk = r as isize - k as isize;
                let pk = P - k;
                if r >= k {
                    let rk = rk as usize;
                    a[s2][0] = a[s1][0] / ndu[pk + 1][rk];
                    d = a[s2][0] * ndu[rk][pk];
                }
                let j1: usize = if rk >= -1 { 1 } else { (-rk) as usize };
                let j2: usize = if r as isize - 1 <= pk as isize {
                    k - 1
                } else {
                    P - r
                };
                for jj in j1..=j2 {
                    let idx = (rk + jj as isize) as usize;
                    a[s2][jj] = (a[s1][jj] - a[s1][jj - 1]) / ndu[pk + 1][idx];
                    d += a[s2][jj] * ndu[idx][pk];
                }
                if r <= pk {
                    a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
                    d += a[s2][k] * ndu[r][pk];
                }
                ders[k][r] = d;
                std::mem::swap(&mut s1, &mut s2);
            }
        }
        let mut out = ders[2];
        for v in &mut out {
            *v *= (P * (P - 1)) as f64;
        }
        out
    }

    /// Roughness penalty matrix `P[a][b] = ∫ B_a'' B_b'' dx` in band storage (bandwidth 3), exact
    /// (B'' is linear on each interval).
    pub fn roughness(&self) -> Band {
        let mut p = Band::zeros(self.len(), 3);
        for j in 0..self.intervals() {
            let (a, b) = (self.breaks[j], self.breaks[j + 1]);
            let h = b - a;
            let dl = self.second_derivatives(j, a);
            let dr = self.second_derivatives(j, b);
            for r in 0..4 {
                for c in r..4 {
                    let v = h / 6.0
                        * (2.0 * dl[r] * dl[c]
                            + dl[r] * dr[c]
                            + dr[r] * dl[c]
                            + 2.0 * dr[r] * dr[c]);
                    p.add(j + r, j + c, v);
                }
            }
        }
        p
    }

    /// The curve with coefficients `coef` as a piecewise cubic over the breakpoints.
    pub fn to_piecewise(&self, coef: &[f64]) -> PiecewiseCubic {
        let coeffs = (0..self.intervals())
            .map(|j| {
                let (a, b) = (self.breaks[j], self.breaks[j + 1]);
                let h = b - a;
                // Exact cubic through four points of the piece (sampled with this interval's span).
                let us = [0.0, h / 3.0, 2.0 * h / 3.0, h];
                let mut ys = [0.0; 4];
                for (k, &du) in us.iter().enumerate() {
                    let x = a + du;
                    let vals = self.values_in(j, x);
                    ys[k] = (0..4).map(|r| vals[r] * coef[j + r]).sum();
                }
                newton_to_power(&us, &ys)
            })
            .collect();
        PiecewiseCubic {
            knots: self.breaks.clone(),
            coeffs,
        }
    }

    /// Basis values at `x` using interval `j`'s polynomial pieces (also valid at its right end).
    fn values_in(&self, j: usize, x: f64) -> [f64; 4] {
        let i = j + 3;
        let u = &self.knots;
        let mut n = [0.0; 4];
        let mut left = [0.0; 4];
        let mut right = [0.0; 4];
        n[0] = 1.0;
        for d in 1..=3 {
            left[d] = x - u[i + 1 - d];
            right[d] = u[i + d] - x;
            let mut saved = 0.0;
            for r in 0..d {
                let temp = n[r] / (right[r + 1] + left[d - r]);
                n[r] = saved + right[r + 1] * temp;
                saved = left[d - r] * temp;
            }
            n[d] = saved;
        }
        n
    }
}

/// Power-form coefficients (in `u`) of the cubic through `(us[k], ys[k])`, `us[0] = 0`.
fn newton_to_power(us: &[f64; 4], ys: &[f64; 4]) -> [f64; 4] {
    // Divided differences.
    let mut d = *ys;
    for level in 1..4 {
        for k in (level..4).rev() {
            d[k] = (d[k] - d[k - 1]) / (us[k] - us[k - level]);
        }
    }
    // p(u) = d0 + d1 (u-u0) + d2 (u-u0)(u-u1) + d3 (u-u0)(u-u1)(u-u2), u0 = 0.
    let (u1, u2) = (us[1], us[2]);
    [
        d[0],
        d[1] - d[2] * u1 + d[3] * u1 * u2,
        d[2] - d[3] * (u1 + u2),
        d[3],
    ]
}

/// Symmetric band matrix, upper band stored row-wise: `a[i*(w+1) + k] = A(i, i+k)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Band {
    pub n: usize,
    pub w: usize,
    pub a: Vec<f64>,
}

impl Band {
    pub fn zeros(n: usize, w: usize) -> Self {
        Band {
            n,
            w,
            a: vec![0.0; n * (w + 1)],
        }
    }
    #[inline]
    pub fn add(&mut self, i: usize, j: usize, v: f64) {
        let (i, j) = if i <= j { (i, j) } else { (j, i) };
        debug_assert!(j - i <= self.w);
        self.a[i * (self.w + 1) + (j - i)] += v;
    }
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (i, j) = if i <= j { (i, j) } else { (j, i) };
        if j - i > self.w {
            0.0
        } else {
            self.a[i * (self.w + 1) + (j - i)]
        }
    }
    /// `self += s·other` (same shape).
    pub fn add_scaled(&mut self, other: &Band, s: f64) {
        for (x, y) in self.a.iter_mut().zip(&other.a) {
            *x += s * y;
        }
    }
    pub fn trace(&self) -> f64 {
        (0..self.n).map(|i| self.a[i * (self.w + 1)]).sum()
    }
    /// `xᵀ A x`.
    pub fn quad(&self, x: &[f64]) -> f64 {
        let mut s = 0.0;
        for i in 0..self.n {
            let row = &self.a[i * (self.w + 1)..(i + 1) * (self.w + 1)];
            s += row[0] * x[i] * x[i];
            for k in 1..=self.w {
                if i + k < self.n {
                    s += 2.0 * row[k] * x[i] * x[i + k];
                }
            }
        }
        s
    }

    /// Solves `A x = b` by banded Cholesky (A symmetric positive definite).
    pub fn solve(&self, b: &[f64]) -> Result<Vec<f64>, SplineError> {
        let (n, w) = (self.n, self.w);
        let mut l = self.a.clone(); // upper factor U (A = UᵀU), same storage
        let tol = 1e-13
            * (0..n)
                .map(|i| self.a[i * (w + 1)].abs())
                .fold(0.0, f64::max);
        for i in 0..n {
            // U(i,i) = sqrt(A(i,i) − Σ_k U(k,i)²) over k in [i−w, i)
            let lo = i.saturating_sub(w);
            let mut d = l[i * (w + 1)];
            for k in lo..i {
                let u = l[k * (w + 1) + (i - k)];
                d -= u * u;
            }
            if !(d > tol) {
                return Err(SplineError::Singular);
            }
            let d = d.sqrt();
            l[i * (w + 1)] = d;
            for j in i + 1..=(i + w).min(n - 1) {
                let mut s = l[i * (w + 1) + (j - i)];
                let lo = j.saturating_sub(w).max(lo);
                for k in lo..i {
                    s -= l[k * (w + 1) + (i - k)] * l[k * (w + 1) + (j - k)];
                }
                l[i * (w + 1) + (j - i)] = s / d;
            }
        }
        // Uᵀ y = b
        let mut y = b.to_vec();
        for i in 0..n {
            let lo = i.saturating_sub(w);
            let mut s = y[i];
            for k in lo..i {
                s -= l[k * (w + 1) + (i - k)] * y[k];
            }
            y[i] = s / l[i * (w + 1)];
        }
        // U x = y
        for i in (0..n).rev() {
            let mut s = y[i];
            for j in i + 1..=(i + w).min(n - 1) {
                s -= l[i * (w + 1) + (j - i)] * y[j];
            }
            y[i] = s / l[i * (w + 1)];
        }
        Ok(y)
    }
}

/// Sufficient statistics of a weighted least-squares problem in a banded basis:
/// `AᵀA` (band), `Aᵀy`, `yᵀy` and the row count. Adding/subtracting statistics of row groups gives
/// the statistics of any union of groups, which makes leave-one-group-out cross-validation O(n).
#[derive(Debug, Clone, PartialEq)]
pub struct NormalStats {
    pub ata: Band,
    pub aty: Vec<f64>,
    pub yty: f64,
    pub rows: usize,
}

impl NormalStats {
    pub fn zeros(n: usize, w: usize) -> Self {
        NormalStats {
            ata: Band::zeros(n, w),
            aty: vec![0.0; n],
            yty: 0.0,
            rows: 0,
        }
    }
    /// Adds one row with nonzero entries `vals` at consecutive columns starting at `first`.
    #[inline]
    pub fn add_row(&mut self, first: usize, vals: &[f64], y: f64) {
        let w1 = self.ata.w + 1;
        for (r, &vr) in vals.iter().enumerate() {
            let row = (first + r) * w1;
            for (c, &vc) in vals.iter().enumerate().skip(r) {
                self.ata.a[row + (c - r)] += vr * vc;
            }
            self.aty[first + r] += vr * y;
        }
        self.yty += y * y;
        self.rows += 1;
    }
    /// [`NormalStats::add_row`] for a fixed number of entries `N` (≤ bandwidth + 1); the hot loop of the
    /// least-squares fits, written so that the compiler unrolls it.
    #[inline]
    pub fn add_row_n<const N: usize>(&mut self, first: usize, vals: &[f64; N], y: f64) {
        let w1 = self.ata.w + 1;
        assert!(N <= w1);
        let band = &mut self.ata.a[first * w1..(first + N) * w1];
        for r in 0..N {
            let row = &mut band[r * w1..r * w1 + (N - r)];
            for c in 0..N - r {
                row[c] += vals[r] * vals[r + c];
            }
        }
        let aty = &mut self.aty[first..first + N];
        for r in 0..N {
            aty[r] += vals[r] * y;
        }
        self.yty += y * y;
        self.rows += 1;
    }

    /// Adds a row whose entries are at arbitrary (increasing, within bandwidth) columns.
    #[inline]
    pub fn add_row_at(&mut self, cols: &[usize], vals: &[f64], y: f64) {
        for r in 0..cols.len() {
            for c in r..cols.len() {
                self.ata.add(cols[r], cols[c], vals[r] * vals[c]);
            }
            self.aty[cols[r]] += vals[r] * y;
        }
        self.yty += y * y;
        self.rows += 1;
    }
    pub fn add(&mut self, other: &NormalStats, s: f64) {
        self.ata.add_scaled(&other.ata, s);
        for (x, y) in self.aty.iter_mut().zip(&other.aty) {
            *x += s * y;
        }
        self.yty += s * other.yty;
        if s > 0.0 {
            self.rows += other.rows;
        } else {
            self.rows = self.rows.saturating_sub(other.rows);
        }
    }
    /// Sum of squared residuals of the coefficients `c` on the rows behind these statistics.
    pub fn sse(&self, c: &[f64]) -> f64 {
        let cy: f64 = c.iter().zip(&self.aty).map(|(a, b)| a * b).sum();
        (self.yty - 2.0 * cy + self.ata.quad(c)).max(0.0)
    }
    /// Minimises `‖y − A c‖² + Σ λ_k cᵀ P_k c` (a tiny ridge keeps unsupported coefficients defined).
    pub fn solve(&self, penalties: &[(&Band, f64)]) -> Result<Vec<f64>, SplineError> {
        let mut m = self.ata.clone();
        for (p, lambda) in penalties {
            m.add_scaled(p, *lambda);
        }
        let scale = m.trace() / m.n as f64;
        if !(scale > 0.0) {
            return Err(SplineError::Singular);
        }
        match m.solve(&self.aty) {
            Ok(c) => Ok(c),
            Err(_) => {
                // Coefficients without data or penalty: a tiny ridge pins them (to zero).
                for i in 0..m.n {
                    m.a[i * (m.w + 1)] += 1e-9 * scale;
                }
                m.solve(&self.aty)
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Resampling to the firmware's uniform table.

/// A curve resampled to uniform segments: `deviation_um = c0 + t(c1 + t(c2 + t c3))`,
/// `t = (x − start_mm)/segment_mm − i ∈ [0,1)` in segment `i`.
#[derive(Debug, Clone, PartialEq)]
pub struct UniformTable {
    pub start_mm: f64,
    pub segment_mm: f64,
    pub coeffs: Vec<[f64; 4]>,
}

impl UniformTable {
    /// Horner evaluation as the firmware does it (in f64 here), holding the end values outside.
    pub fn eval(&self, x_mm: f64) -> f64 {
        let n = self.coeffs.len();
        let s = (x_mm - self.start_mm) / self.segment_mm;
        let (i, t) = if !(s > 0.0) {
            (0, 0.0)
        } else if s >= n as f64 {
            (n - 1, 1.0)
        } else {
            let i = (s.floor() as usize).min(n - 1);
            (i, s - i as f64)
        };
        let c = &self.coeffs[i];
        c[0] + t * (c[1] + t * (c[2] + t * c[3]))
    }
}

/// Resamples `curve` over `[start, start + segments·segment_mm]` to a C2 uniform table: the clamped cubic
/// spline through the curve's values at the uniform knots with the curve's end slopes. When the curve is a
/// cubic spline whose knots all lie on the uniform grid, the table reproduces it exactly.
pub fn resample_uniform(
    curve: &PiecewiseCubic,
    start_mm: f64,
    segment_mm: f64,
    segments: usize,
) -> Result<UniformTable, SplineError> {
    if segments == 0 || segments > 1024 {
        return Err(SplineError::BadSegmentCount(segments));
    }
    let xs: Vec<f64> = (0..=segments)
        .map(|i| start_mm + segment_mm * i as f64)
        .collect();
    // Beyond the curve's range (at most part of a segment when the grid overhangs the stroke) the end
    // pieces' polynomials are continued, so the table stays smooth and equals the curve inside the range.
    let ys: Vec<f64> = xs.iter().map(|&x| curve.eval_extended(x)).collect();
    let s0 = curve.slope_extended(xs[0]);
    let s1 = curve.slope_extended(xs[segments]);
    let spline = interpolate(
        &xs,
        &ys,
        EndCondition::Clamped {
            start_slope: s0,
            end_slope: s1,
        },
    )?;
    let h = segment_mm;
    let coeffs = spline
        .coeffs
        .iter()
        .map(|c| [c[0], c[1] * h, c[2] * h * h, c[3] * h * h * h])
        .collect();
    Ok(UniformTable {
        start_mm,
        segment_mm,
        coeffs,
    })
}

#[cfg(test)]
mod tests;
