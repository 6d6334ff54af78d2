//! `axcomp plan geometry`: which laser lines (and reflector offsets) make all 21 components identifiable
//! with the fewest lines, and the standard uncertainty each component would then have for noise σ.
//!
//! Method: greedy D-optimal selection. Candidates are axis lines at the four corner offsets, face diagonals
//! (each plane at both faces, simultaneous and step-wise), body diagonals (simultaneous and step-wise), each
//! with every reflector offset given. Starting from nothing, the line that most increases
//! `log det(AᵀA + εI)` (ε = 1e-6 of the mean diagonal, a weak prior that rewards new directions first) is
//! added until the stacked design has full column rank (same test as `fit geometry`) or `--lines` is reached.

use axcomp_kinematics::lines::{LineSpec, axis_line, body_diagonals, face_diagonals};
use axcomp_kinematics::{Component, Topology};
use nalgebra::{DMatrix, SymmetricEigen};

use crate::GeometryError;
use crate::data::LineData;
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
    let eig = SymmetricEigen::new(gn);
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

/// Proposes the lines (see the module docs).
pub fn plan(opts: &PlanOptions) -> Result<Plan, GeometryError> {
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
    let data = LineData::from_specs(&cands);
    let layout = Layout::new(&data, None);
    let p = layout.p;
    let designs: Vec<DMatrix<f64>> = (0..cands.len())
        .map(|i| design(&layout, &opts.topology, &data, i))
        .collect();
    let grams: Vec<DMatrix<f64>> = designs.iter().map(|a| a.transpose() * a).collect();
    let mean_diag = grams.iter().map(|g| g.trace()).sum::<f64>() / (cands.len() * p) as f64;
    let eps = 1e-6 * mean_diag;
    let mut g = DMatrix::<f64>::zeros(p, p);
    let mut chosen: Vec<usize> = Vec::new();
    let limit = opts.max_lines.unwrap_or(60).min(cands.len());
    let mut missing = unidentifiable(&layout, &g);
    // without --lines: stop as soon as everything is identifiable; with --lines N: N lines (the first
    // ones reach identifiability, the rest lower the uncertainties)
    while (opts.max_lines.is_some() || !missing.is_empty()) && chosen.len() < limit {
        let mut m = g.clone();
        for i in 0..p {
            m[(i, i)] += eps;
        }
        let minv = m
            .cholesky()
            .expect("positive definite with the prior")
            .inverse();
        let mut best = (f64::NEG_INFINITY, usize::MAX);
        for (ci, a) in designs.iter().enumerate() {
            if chosen.contains(&ci) {
                continue;
            }
            // log det(I + A M⁻¹ Aᵀ) (matrix determinant lemma)
            let mut s = a * &minv * a.transpose();
            for i in 0..s.nrows() {
                s[(i, i)] += 1.0;
            }
            let gain = s
                .cholesky()
                .map(|c| 2.0 * c.l().diagonal().iter().map(|x| x.ln()).sum::<f64>())
                .unwrap_or(f64::NEG_INFINITY);
            if gain > best.0 {
                best = (gain, ci);
            }
        }
        if best.1 == usize::MAX {
            break;
        }
        chosen.push(best.1);
        g += &grams[best.1];
        missing = unidentifiable(&layout, &g);
    }
    // predicted standard uncertainties: σ²·(AᵀA)⁻¹ on the identifiable parameters
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
        * (opts.sigma_um * opts.sigma_um);
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
    Ok(Plan {
        lines: chosen.iter().map(|&i| cands[i].clone()).collect(),
        complete: missing.is_empty(),
        not_identifiable: missing
            .iter()
            .map(|&i| Component::ALL[i].name().to_string())
            .collect(),
        uncertainty,
        candidates: cands.len(),
    })
}
