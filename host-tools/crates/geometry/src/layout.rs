//! The parameter layout of the geometric fit: the constrained spline bases of the 18 functions and the 3
//! squareness constants, and a reading's design row along its beam. A leaf the fit and its design share.
//!
//! Glossary: *constrained basis* the B-spline coefficients of a component with its zero-at-origin (and,
//! for a straightness, zero least-squares slope over the range) conditions eliminated; *parameter* one column of the design.

use axcomp_kinematics::{Component, Topology, dot, sensitivities};
use nalgebra::DMatrix;

use crate::data::LineData;
use crate::spline::AxisGrid;

/// Parameter layout: the constrained spline bases of the 18 functions and the 3 squareness constants.
#[derive(Debug, Clone)]
pub struct Layout {
    pub grids: [AxisGrid; 3],
    pub moved: [bool; 3],
    /// Null-space bases (n_basis × k) of the 18 functions.
    pub bases: Vec<DMatrix<f64>>,
    /// (first column, count) of each of the 21 components.
    pub cols: Vec<(usize, usize)>,
    pub p: usize,
}

impl Layout {
    /// Grids over `[min(0, lo), max(0, hi)]` of the readings' axis positions.
    pub fn new(data: &LineData, intervals: Option<usize>) -> Layout {
        let mut grids = [AxisGrid {
            lo: 0.0,
            hi: 1.0,
            intervals: 1,
        }; 3];
        let mut moved = [false; 3];
        for k in 0..3 {
            let mut v: Vec<i64> = data
                .readings
                .iter()
                .map(|r| (r.q[k] * 1e3).round() as i64)
                .collect();
            v.sort();
            v.dedup();
            let lo = (*v.first().unwrap_or(&0) as f64 / 1e3).min(0.0);
            let hi = (*v.last().unwrap_or(&0) as f64 / 1e3).max(0.0);
            moved[k] = hi - lo > 1e-3 && v.len() >= 2;
            let n = intervals.unwrap_or(v.len().saturating_sub(3).clamp(1, 12));
            grids[k] = if moved[k] {
                AxisGrid {
                    lo,
                    hi,
                    intervals: n.max(1),
                }
            } else {
                AxisGrid {
                    lo: lo.min(-1.0),
                    hi: hi.max(1.0),
                    intervals: 1,
                }
            };
        }
        let mut bases = Vec::new();
        let mut cols = Vec::new();
        let mut p = 0;
        for c in &Component::ALL[..18] {
            let g = grids[c.axis().unwrap().index()];
            let n = g.constrained_basis(c.is_straightness());
            cols.push((p, n.ncols()));
            p += n.ncols();
            bases.push(n);
        }
        for _ in 0..3 {
            cols.push((p, 1));
            p += 1;
        }
        Layout {
            grids,
            moved,
            bases,
            cols,
            p,
        }
    }

    /// Design row (µm per parameter) of one reading along its beam.
    pub fn row(&self, topo: &Topology, q: [f64; 3], t: [f64; 3], beam: [f64; 3]) -> Vec<f64> {
        let s = sensitivities(topo, q, t);
        let mut row = vec![0.0; self.p];
        for (i, c) in Component::ALL.iter().enumerate() {
            let sb = dot(s[i], beam);
            let (start, k) = self.cols[i];
            match c.axis() {
                Some(a) => {
                    if sb == 0.0 {
                        continue;
                    }
                    let g = &self.grids[a.index()];
                    let (j0, v) = g.local(q[a.index()]);
                    let n = &self.bases[i];
                    for col in 0..k {
                        let mut b = 0.0;
                        for m in 0..4 {
                            b += v[m] * n[(j0 + m, col)];
                        }
                        row[start + col] = sb * b;
                    }
                }
                None => row[start] = sb,
            }
        }
        row
    }

    /// Raw spline coefficients of component `i` from its parameters.
    pub fn coefficients(&self, i: usize, params: &[f64]) -> Vec<f64> {
        let (start, k) = self.cols[i];
        let n = &self.bases[i];
        (0..n.nrows())
            .map(|r| (0..k).map(|c| n[(r, c)] * params[start + c]).sum())
            .collect()
    }
}
