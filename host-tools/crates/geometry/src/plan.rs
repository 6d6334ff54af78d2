//! `axcomp plan geometry`: which laser lines (and reflector offsets) make all 21 components identifiable
//! with the fewest lines, and the standard uncertainty each component would then have for noise σ.
//!
//! Method: greedy D-optimal selection. Candidates are axis lines at the four corner offsets, face diagonals
//! (each plane at both faces, simultaneous and step-wise), body diagonals (simultaneous and step-wise), each
//! with every reflector offset given. Starting from nothing, the line that most increases
//! `log det(AᵀA + εI)` (ε = 1e-6 of the mean diagonal, a weak prior that rewards new directions first) is
//! added until the stacked design has full column rank (same test as `fit geometry`) or `--lines` is reached.
//! Lines already measured (`--measured`) start the stacked design. The further lines listed after the plan
//! are the unused candidates ranked by the rank they add to the measured and chosen lines (the null
//! directions they reach, named by component), then by their information gain.

use axcomp_kinematics::lines::{LineSpec, axis_line, body_diagonals, face_diagonals};
use axcomp_kinematics::{Component, Topology};
use axcomp_numeric::lsq::symmetric_eigen;
use nalgebra::DMatrix;

use crate::GeometryError;
use crate::data::{LineData, LineReading};
use crate::fit::Layout;

/// Options of [`plan`].
#[derive(Debug, Clone)]
pub struct PlanOptions {
    pub stroke_mm: [f64; 3],
    pub max_lines: Option<usize>,
    pub tool_offsets: Vec<[f64; 3]>,
    pub sigma_um: f64,
    pub targets: usize,
    pub topology: Topology,
}

/// A proposed measurement plan.
#[derive(Debug, Clone)]
pub struct Plan {
    pub lines: Vec<LineSpec>,
    /// All 21 components identifiable.
    pub complete: bool,
    /// Components the selected lines cannot separate.
    pub not_identifiable: Vec<String>,
    /// Largest predicted standard uncertainty over each component's axis (µm or µrad), ISO order.
    pub uncertainty: Vec<(String, String, f64)>,
    pub candidates: usize,
    /// Further lines that would lower the identifiable floor of the measured and chosen lines: first those
    /// that add rank (reach what the lines cannot separate), then those that most shrink the uncertainty
    /// of what they determine only poorly.
    pub further: Vec<FurtherLine>,
}

/// The candidate lines.
pub fn candidates(opts: &PlanOptions) -> Vec<LineSpec> {
    let s = opts.stroke_mm;
    let n = opts.targets;
    let mut base = Vec::new();
    for a in 0..3 {
        let o: Vec<usize> = (0..3).filter(|b| *b != a).collect();
        for (i, (p, q)) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
            .iter()
            .enumerate()
        {
            let mut at = [0.0; 3];
            at[o[0]] = p * s[o[0]];
            at[o[1]] = q * s[o[1]];
            base.push(axis_line(
                &format!("{}{}", ['X', 'Y', 'Z'][a], i + 1),
                a,
                s,
                at,
                n,
            ));
        }
    }
    for (a, b) in [(0usize, 1usize), (0, 2), (1, 2)] {
        let c = 3 - a - b;
        for at in [0.0, s[c]] {
            for step in [false, true] {
                for mut l in face_diagonals(s, a, b, at, n, step) {
                    l.name = format!("{}@{}{}", l.name, at, if step { "s" } else { "" });
                    base.push(l);
                }
            }
        }
    }
    for step in [false, true] {
        for mut l in body_diagonals(s, n, step) {
            if step {
                l.name.push('s');
            }
            base.push(l);
        }
    }
    let mut out = Vec::new();
    let offsets = if opts.tool_offsets.is_empty() {
        vec![[0.0; 3]]
    } else {
        opts.tool_offsets.clone()
    };
    for t in &offsets {
        for l in &base {
            let mut l = l.clone().with_tool(*t);
            if *t != [0.0; 3] {
                l.name = format!("{}+t{}_{}_{}", l.name, t[0], t[1], t[2]);
            }
            out.push(l);
        }
    }
    out
}

fn design(layout: &Layout, topo: &Topology, data: &LineData, line: usize) -> DMatrix<f64> {
    let rows: Vec<Vec<f64>> = data
        .readings
        .iter()
        .filter(|r| r.line == line)
        .map(|r| layout.row(topo, r.q, r.tool, r.beam))
        .collect();
    DMatrix::from_fn(rows.len(), layout.p, |i, j| rows[i][j])
}

/// Null-space components of the normal matrix `g` (column-normalised; same tolerance as the fit).
fn unidentifiable(layout: &Layout, g: &DMatrix<f64>) -> Vec<usize> {
    let p = g.nrows();
    let d: Vec<f64> = (0..p).map(|i| g[(i, i)].max(0.0).sqrt()).collect();
    let dmax = d.iter().fold(0.0f64, |a, b| a.max(*b));
    let mut out = Vec::new();
    let live: Vec<usize> = (0..p).filter(|&i| d[i] > 1e-9 * dmax).collect();
    for (ci, &(s, k)) in layout.cols.iter().enumerate() {
        if (s..s + k).any(|j| d[j] <= 1e-9 * dmax) {
            out.push(ci);
        }
    }
    if live.is_empty() {
        return (0..layout.cols.len()).collect();
    }
    let gn = DMatrix::from_fn(live.len(), live.len(), |i, j| {
        g[(live[i], live[j])] / (d[live[i]] * d[live[j]])
    });
    let eig = symmetric_eigen(gn);
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |a, b| a.max(*b));
    for i in 0..live.len() {
        if eig.eigenvalues[i] <= 1e-12 * lmax {
            let v = eig.eigenvectors.column(i);
            for (ci, &(s, k)) in layout.cols.iter().enumerate() {
                let share: f64 = live
                    .iter()
                    .enumerate()
                    .filter(|(_, c)| **c >= s && **c < s + k)
                    .map(|(r, _)| v[r] * v[r])
                    .sum();
                if share > 0.01 && !out.contains(&ci) {
                    out.push(ci);
                }
            }
        }
    }
    out.sort();
    out
}

/// A further line and what it adds to the lines so far (measured, or planned).
#[derive(Debug, Clone)]
pub struct FurtherLine {
    pub line: LineSpec,
    /// Rank it adds to the stacked design: directions the lines so far cannot separate that it reaches.
    pub rank_gain: usize,
    /// Components of those directions (share of the reached null directions > 5 %), ISO order.
    pub reaches: Vec<String>,
    /// `log det(I + A M⁻¹ Aᵀ)` with the weak prior of the plan (D-optimal): how much it shrinks the joint
    /// uncertainty of what the lines so far determine only poorly.
    pub information_gain: f64,
}

/// How many further lines [`plan`] lists.
pub const FURTHER_LINES: usize = 8;

/// `M⁻¹` of the normal matrix `g` with the plan's weak prior `eps` on its diagonal.
fn prior_inverse(g: &DMatrix<f64>, eps: f64) -> DMatrix<f64> {
    let mut m = g.clone();
    for i in 0..m.nrows() {
        m[(i, i)] += eps;
    }
    m.cholesky()
        .expect("positive definite with the prior")
        .inverse()
}

/// `log det(I + A M⁻¹ Aᵀ)` (matrix determinant lemma): the information line design `a` adds.
fn information_gain(a: &DMatrix<f64>, minv: &DMatrix<f64>) -> f64 {
    let mut s = a * minv * a.transpose();
    for i in 0..s.nrows() {
        s[(i, i)] += 1.0;
    }
    s.cholesky()
        .map(|c| 2.0 * c.l().diagonal().iter().map(|x| x.ln()).sum::<f64>())
        .unwrap_or(f64::NEG_INFINITY)
}

/// Column scales of `g` (√diagonal; a column nothing reaches gets the mean scale, so it stays a null
/// direction) and the null directions of the scaled matrix (columns of the returned `p × k` matrix, in
/// scaled coordinates; same tolerance as [`unidentifiable`]).
fn null_directions(g: &DMatrix<f64>) -> (Vec<f64>, DMatrix<f64>) {
    let p = g.nrows();
    let d: Vec<f64> = (0..p).map(|i| g[(i, i)].max(0.0).sqrt()).collect();
    let dmax = d.iter().fold(0.0f64, |a, b| a.max(*b));
    let live: Vec<f64> = d.iter().copied().filter(|x| *x > 1e-9 * dmax).collect();
    let mean = if live.is_empty() {
        1.0
    } else {
        live.iter().sum::<f64>() / live.len() as f64
    };
    let scale: Vec<f64> = d
        .iter()
        .map(|x| if *x > 1e-9 * dmax { *x } else { mean })
        .collect();
    let gn = DMatrix::from_fn(p, p, |i, j| g[(i, j)] / (scale[i] * scale[j]));
    let eig = symmetric_eigen(gn);
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |a, b| a.max(*b));
    let null: Vec<usize> = (0..p)
        .filter(|&i| eig.eigenvalues[i] <= 1e-12 * lmax.max(1e-300))
        .collect();
    let v = DMatrix::from_fn(p, null.len(), |i, j| eig.eigenvectors[(i, null[j])]);
    (scale, v)
}

/// The candidates not yet used, ranked by the rank they add, then by their information gain; the first
/// [`FURTHER_LINES`].
fn further_lines(
    layout: &Layout,
    cands: &[LineSpec],
    designs: &[DMatrix<f64>],
    g: &DMatrix<f64>,
    used: &[usize],
    eps: f64,
) -> Vec<FurtherLine> {
    let (scale, null) = null_directions(g);
    let minv = prior_inverse(g, eps);
    let mut out: Vec<FurtherLine> = (0..cands.len())
        .filter(|i| !used.contains(i))
        .map(|ci| {
            let a = &designs[ci];
            let an = DMatrix::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)] / scale[j]);
            let (mut rank_gain, mut reaches) = (0, Vec::new());
            if null.ncols() > 0 {
                let b = &an * &null;
                let tol = 1e-6 * an.norm().max(1e-300);
                let svd = b.svd(false, true);
                let vt = svd.v_t.expect("SVD with Vᵀ");
                let mut share = [0.0f64; 21];
                for (k, sk) in svd.singular_values.iter().enumerate() {
                    if *sk > tol {
                        rank_gain += 1;
                        let w = &null * vt.row(k).transpose();
                        for (ci2, &(s, n)) in layout.cols.iter().enumerate() {
                            share[ci2] += (s..s + n).map(|j| w[j] * w[j]).sum::<f64>();
                        }
                    }
                }
                let total: f64 = share.iter().sum();
                reaches = (0..21)
                    .filter(|&c| total > 0.0 && share[c] > 0.05 * total)
                    .map(|c| Component::ALL[c].name().to_string())
                    .collect();
            }
            FurtherLine {
                line: cands[ci].clone(),
                rank_gain,
                reaches,
                information_gain: information_gain(a, &minv),
            }
        })
        .collect();
    out.sort_by(|x, y| {
        y.rank_gain
            .cmp(&x.rank_gain)
            .then(y.information_gain.total_cmp(&x.information_gain))
    });
    out.truncate(FURTHER_LINES);
    out
}

/// Greedy D-optimal choice from normal matrix `g` (see the module docs); returns the chosen candidates
/// and the normal matrix with them.
fn choose(
    layout: &Layout,
    designs: &[DMatrix<f64>],
    grams: &[DMatrix<f64>],
    mut g: DMatrix<f64>,
    max_lines: Option<usize>,
    eps: f64,
) -> (Vec<usize>, DMatrix<f64>) {
    let mut chosen: Vec<usize> = Vec::new();
    let limit = max_lines.unwrap_or(60).min(designs.len());
    let mut missing = unidentifiable(layout, &g);
    // without --lines: stop as soon as everything is identifiable; with --lines N: N lines (the first
    // ones reach identifiability, the rest lower the uncertainties)
    while (max_lines.is_some() || !missing.is_empty()) && chosen.len() < limit {
        let minv = prior_inverse(&g, eps);
        let mut best = (f64::NEG_INFINITY, usize::MAX);
        for (ci, a) in designs.iter().enumerate() {
            if chosen.contains(&ci) {
                continue;
            }
            let gain = information_gain(a, &minv);
            if gain > best.0 {
                best = (gain, ci);
            }
        }
        if best.1 == usize::MAX {
            break;
        }
        chosen.push(best.1);
        g += &grams[best.1];
        missing = unidentifiable(layout, &g);
    }
    (chosen, g)
}

/// Largest predicted standard uncertainty over each component's axis, σ²·(AᵀA)⁻¹ on the identifiable
/// parameters (NaN for the components in `missing`), ISO order.
fn predicted_uncertainty(
    layout: &Layout,
    g: &DMatrix<f64>,
    missing: &[usize],
    sigma_um: f64,
) -> Vec<(String, String, f64)> {
    let p = layout.p;
    let mut m = g.clone();
    let fixed_cols: Vec<usize> = missing
        .iter()
        .flat_map(|&ci| {
            let (s, k) = layout.cols[ci];
            s..s + k
        })
        .collect();
    for &j in &fixed_cols {
        for i in 0..p {
            m[(i, j)] = 0.0;
            m[(j, i)] = 0.0;
        }
        m[(j, j)] = 1.0;
    }
    let cov = m
        .clone()
        .cholesky()
        .map(|c| c.inverse())
        .unwrap_or_else(|| m.pseudo_inverse(1e-12).expect("finite"))
        * (sigma_um * sigma_um);
    let mut uncertainty = Vec::new();
    for (ci, c) in Component::ALL.iter().enumerate() {
        let (s, k) = layout.cols[ci];
        let u = if missing.contains(&ci) {
            f64::NAN
        } else {
            match c.axis() {
                Some(ax) => {
                    let grid = layout.grids[ax.index()];
                    let n = &layout.bases[ci];
                    grid.positions(21)
                        .into_iter()
                        .map(|q| {
                            let b = grid.basis(q);
                            let gv: Vec<f64> = (0..k)
                                .map(|col| (0..b.len()).map(|r| b[r] * n[(r, col)]).sum())
                                .collect();
                            let mut v = 0.0;
                            for a in 0..k {
                                for bb in 0..k {
                                    v += gv[a] * cov[(s + a, s + bb)] * gv[bb];
                                }
                            }
                            v.max(0.0).sqrt()
                        })
                        .fold(0.0, f64::max)
                }
                None => cov[(s, s)].max(0.0).sqrt(),
            }
        };
        uncertainty.push((c.name().to_string(), c.unit().to_string(), u));
    }
    uncertainty
}

/// Proposes the lines (see the module docs).
pub fn plan(opts: &PlanOptions) -> Result<Plan, GeometryError> {
    plan_after(opts, None)
}

/// Proposes the lines to add to lines already `measured` (their readings' positions, tool offsets and
/// beams; none: start from nothing), and lists the further lines that lower the identifiable floor of
/// the measured and chosen lines together ([`Plan::further`]).
pub fn plan_after(opts: &PlanOptions, measured: Option<&LineData>) -> Result<Plan, GeometryError> {
    if opts.stroke_mm.iter().any(|s| !s.is_finite() || *s <= 0.0) {
        return Err(GeometryError::Plan(format!(
            "--stroke {:?}: every stroke must be a positive number of mm",
            opts.stroke_mm
        )));
    }
    if opts.targets < 4 {
        return Err(GeometryError::Plan("--targets must be at least 4".into()));
    }
    let cands = candidates(opts);
    let mut data = LineData::from_specs(&cands);
    if let Some(m) = measured {
        let n_lines = data.lines.len();
        data.readings.extend(m.readings.iter().map(|r| LineReading {
            line: r.line + n_lines,
            ..r.clone()
        }));
        data.lines.extend(m.lines.iter().cloned());
    }
    let layout = Layout::new(&data, None);
    let p = layout.p;
    let designs: Vec<DMatrix<f64>> = (0..cands.len())
        .map(|i| design(&layout, &opts.topology, &data, i))
        .collect();
    let grams: Vec<DMatrix<f64>> = designs.iter().map(|a| a.transpose() * a).collect();
    let mean_diag = grams.iter().map(|g| g.trace()).sum::<f64>() / (cands.len() * p) as f64;
    let eps = 1e-6 * mean_diag;
    let mut g0 = DMatrix::<f64>::zeros(p, p);
    for li in cands.len()..data.lines.len() {
        let a = design(&layout, &opts.topology, &data, li);
        g0 += a.transpose() * &a;
    }
    let (chosen, g) = choose(&layout, &designs, &grams, g0, opts.max_lines, eps);
    let missing = unidentifiable(&layout, &g);
    let further = further_lines(&layout, &cands, &designs, &g, &chosen, eps);
    Ok(Plan {
        lines: chosen.iter().map(|&i| cands[i].clone()).collect(),
        complete: missing.is_empty(),
        not_identifiable: missing
            .iter()
            .map(|&i| Component::ALL[i].name().to_string())
            .collect(),
        uncertainty: predicted_uncertainty(&layout, &g, &missing, opts.sigma_um),
        candidates: cands.len(),
        further,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use axcomp_kinematics::lines::seven_line;

    /// Further lines after the seven-line set and the Y and Z axis lines (measured lines leave spline
    /// coefficients that no reading reaches: zero rows of the normal matrix, on which nalgebra's symmetric
    /// eigen-decomposition once returned NaN and the ranking's SVD never ended). Reference: the
    /// seven-line set cannot separate ECY, EAZ, EBZ, ECZ (zero reflector offset); tolerance: the first
    /// further line with a 150 mm reflector offset adds rank and reaches only those.
    #[test]
    fn further_lines_after_measured_lines_with_unreached_coefficients() {
        let s = [800.0, 600.0, 500.0];
        let mut lines = seven_line(s, 15);
        lines.push(axis_line("Y0", 1, s, [0.0; 3], 15));
        lines.push(axis_line("Z0", 2, s, [0.0; 3], 15));
        let opts = PlanOptions {
            stroke_mm: s,
            max_lines: Some(0),
            tool_offsets: vec![[0.0; 3], [0.0, 0.0, 150.0]],
            sigma_um: 0.3,
            targets: 15,
            topology: Topology::default(),
        };
        let plan = plan_after(&opts, Some(&LineData::from_specs(&lines))).unwrap();
        let first = &plan.further[0];
        assert!(first.rank_gain > 0, "{first:?}");
        assert!(first.line.tool != [0.0; 3], "{first:?}");
        assert!(
            first
                .reaches
                .iter()
                .all(|c| ["ECY", "EAZ", "EBZ", "ECZ"].contains(&c.as_str())),
            "{first:?}"
        );
        assert!(first.information_gain.is_finite());
    }
}
