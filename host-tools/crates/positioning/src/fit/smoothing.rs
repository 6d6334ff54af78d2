//! Penalised least-squares B-splines with nested cross-validation of the smoothing parameter,
//! using per-fold sufficient statistics (cost linear in the number of points).
use super::types::{Curves, Evaluation, FitError, Kind, Problem, Structure};
use crate::spline::{BSplineBasis, Band, NormalStats, PiecewiseCubic, SplineError};

/// Candidate smoothing parameters ρ (dimensionless): 10^-9 … 10^3 in half decades.
pub(super) fn rho_grid() -> Vec<f64> {
    (0..=24)
        .map(|k| 10f64.powf(-9.0 + 0.5 * k as f64))
        .collect()
}
/// Coarser grid for the reversal curve of the joint model.
fn rho_rev_grid() -> Vec<f64> {
    (0..=6).map(|k| 10f64.powf(-6.0 + 2.0 * k as f64)).collect()
}

/// Blocks of one structure: statistics per fold and block, penalty matrices per block.
struct Design {
    basis: BSplineBasis,
    structure: Structure,
    /// stats[fold][block]
    stats: Vec<Vec<NormalStats>>,
    /// Penalties per block: list of (matrix, λ scale = tr(AᵀA)/tr(P)).
    penalties: Vec<Vec<(Band, f64)>>,
}

fn blocks(structure: Structure) -> usize {
    if structure == Structure::Separate {
        2
    } else {
        1
    }
}

/// Designs of several structures on one basis, accumulated in a single pass over the points.
fn build_many(p: &Problem, basis: &BSplineBasis, structures: &[Structure]) -> Vec<Design> {
    let nb = basis.len();
    let mut all: Vec<Vec<Vec<NormalStats>>> = structures
        .iter()
        .map(|&st| {
            let (n, w) = if st == Structure::MeanSmoothReversal {
                (2 * nb, 7)
            } else {
                (nb, 3)
            };
            vec![vec![NormalStats::zeros(n, w); blocks(st)]; p.folds]
        })
        .collect();
    let mut vals = [0.0f64; 8];
    for (o, &f) in p.obs.iter().zip(&p.fold) {
        let (j, v) = basis.values(o.target_mm);
        for (stats, &structure) in all.iter_mut().zip(structures) {
            match structure {
                Structure::Separate => {
                    if o.direction == 0 {
                        continue;
                    }
                    let b = usize::from(o.direction < 0);
                    stats[f][b].add_row_n(j, &v, o.deviation_um);
                }
                Structure::MeanSmoothReversal => {
                    let h = 0.5 * o.direction as f64;
                    // Interleaved columns 2j … 2j+7: mean coefficient, reversal coefficient, …
                    for r in 0..4 {
                        vals[2 * r] = v[r];
                        vals[2 * r + 1] = h * v[r];
                    }
                    stats[f][0].add_row_n(2 * j, &vals, o.deviation_um);
                }
                _ => stats[f][0].add_row_n(j, &v, o.deviation_um),
            }
        }
    }
    all.into_iter()
        .zip(structures)
        .map(|(stats, &st)| finish(basis.clone(), st, stats))
        .collect()
}

fn finish(basis: BSplineBasis, structure: Structure, stats: Vec<Vec<NormalStats>>) -> Design {
    let nb = basis.len();
    let joint = structure == Structure::MeanSmoothReversal;
    let (n, w) = if joint { (2 * nb, 7) } else { (nb, 3) };
    let nblocks = blocks(structure);
    let rough = basis.roughness();
    let mut penalties = Vec::new();
    for b in 0..nblocks {
        let mut total = NormalStats::zeros(n, w);
        for s in &stats {
            total.add(&s[b], 1.0);
        }
        if joint {
            let mut pm = Band::zeros(n, w);
            let mut pr = Band::zeros(n, w);
            for i in 0..nb {
                for k in 0..=3 {
                    if i + k < nb {
                        pm.add(2 * i, 2 * (i + k), rough.get(i, i + k));
                        pr.add(2 * i + 1, 2 * (i + k) + 1, rough.get(i, i + k));
                    }
                }
            }
            let sm = scale(&total.ata, &pm, true);
            let sr = scale(&total.ata, &pr, false);
            penalties.push(vec![(pm, sm), (pr, sr)]);
        } else {
            let s = scale(&total.ata, &rough, true);
            penalties.push(vec![(rough.clone(), s)]);
        }
    }
    Design {
        basis,
        structure,
        stats,
        penalties,
    }
}

/// λ scale: trace of the data part over trace of the penalty (restricted to even/odd indices for joint).
fn scale(ata: &Band, pen: &Band, even: bool) -> f64 {
    let joint = ata.n != pen.n || ata.w == 7;
    let mut ta = 0.0;
    let mut tp = 0.0;
    for i in 0..ata.n {
        if joint && (i % 2 == 0) != even {
            continue;
        }
        ta += ata.get(i, i);
        tp += pen.get(i, i);
    }
    if tp > 0.0 && ta > 0.0 { ta / tp } else { 1.0 }
}

impl Design {
    fn sum(&self, block: usize, exclude: &[usize]) -> NormalStats {
        let s0 = &self.stats[0][block];
        let mut t = NormalStats::zeros(s0.ata.n, s0.ata.w);
        for (f, s) in self.stats.iter().enumerate() {
            if !exclude.contains(&f) {
                t.add(&s[block], 1.0);
            }
        }
        t
    }
    fn solve(&self, st: &NormalStats, block: usize, rho: &[f64]) -> Result<Vec<f64>, SplineError> {
        let pens: Vec<(&Band, f64)> = self.penalties[block]
            .iter()
            .zip(rho)
            .map(|((m, s), r)| (m, s * r))
            .collect();
        st.solve(&pens)
    }
    fn combos(&self) -> Vec<Vec<f64>> {
        if self.structure == Structure::MeanSmoothReversal {
            let mut v = Vec::new();
            for &a in &rho_grid() {
                for &b in &rho_rev_grid() {
                    v.push(vec![a, b]);
                }
            }
            v
        } else {
            rho_grid().into_iter().map(|r| vec![r]).collect()
        }
    }
    /// ρ minimising the CV error over the folds in `train` (each left out in turn), for one block.
    fn choose(&self, block: usize, train: &[usize]) -> Vec<f64> {
        let combos = self.combos();
        let outside: Vec<usize> = (0..self.stats.len())
            .filter(|f| !train.contains(f))
            .collect();
        let total = self.sum(block, &outside);
        let mut best = (f64::INFINITY, combos[combos.len() / 2].clone());
        for rho in combos {
            let mut sse = 0.0;
            for &h in train {
                let held = &self.stats[h][block];
                if held.rows == 0 {
                    continue;
                }
                let mut t = total.clone();
                t.add(held, -1.0);
                match self.solve(&t, block, &rho) {
                    Ok(c) => sse += held.sse(&c),
                    Err(_) => {
                        sse = f64::INFINITY;
                        break;
                    }
                }
            }
            if sse < best.0 {
                best = (sse, rho);
            }
        }
        best.1
    }
    /// Curves fitted on all folds except `exclude`, ρ chosen by CV over the remaining folds.
    fn fit_without(&self, exclude: Option<usize>) -> Result<(Curves, Vec<f64>), FitError> {
        let train: Vec<usize> = (0..self.stats.len())
            .filter(|&f| Some(f) != exclude)
            .collect();
        let ex: Vec<usize> = exclude.into_iter().collect();
        let nb = self.basis.len();
        match self.structure {
            Structure::Separate => {
                let mut curves = Vec::new();
                let mut rhos = Vec::new();
                for b in 0..2 {
                    let rho = self.choose(b, &train);
                    let c = self.solve(&self.sum(b, &ex), b, &rho)?;
                    curves.push(self.basis.to_piecewise(&c));
                    rhos.extend(rho);
                }
                let bwd = curves.pop();
                Ok((
                    Curves {
                        forward: curves.pop().unwrap(),
                        backward: bwd,
                    },
                    rhos,
                ))
            }
            Structure::MeanSmoothReversal => {
                let rho = self.choose(0, &train);
                let c = self.solve(&self.sum(0, &ex), 0, &rho)?;
                let fw: Vec<f64> = (0..nb).map(|i| c[2 * i] + 0.5 * c[2 * i + 1]).collect();
                let bw: Vec<f64> = (0..nb).map(|i| c[2 * i] - 0.5 * c[2 * i + 1]).collect();
                Ok((
                    Curves {
                        forward: self.basis.to_piecewise(&fw),
                        backward: Some(self.basis.to_piecewise(&bw)),
                    },
                    rho,
                ))
            }
            _ => {
                let rho = self.choose(0, &train);
                let c = self.solve(&self.sum(0, &ex), 0, &rho)?;
                Ok((
                    Curves {
                        forward: self.basis.to_piecewise(&c),
                        backward: None,
                    },
                    rho,
                ))
            }
        }
    }
}

/// Knot intervals: at the targets for a uniform grid of ≤ 64 targets, otherwise up to 128 (≤ n/8).
fn intervals(p: &Problem) -> usize {
    if let Some(g) = &p.grid {
        if g.len() <= 65 {
            return (g.len() - 1).max(1);
        }
    }
    (p.obs.len() / 8).clamp(1, 128)
}

/// Breakpoints with density ∝ √|f''| of the pilot curve (plus a floor of 25 % of its mean), so that
/// knots gather where the deviation bends sharply.
pub fn feature_breaks(pilot: &PiecewiseCubic, lo: f64, hi: f64, m: usize) -> Vec<f64> {
    let samples = (m * 32).max(256);
    let xs: Vec<f64> = (0..=samples)
        .map(|k| lo + (hi - lo) * k as f64 / samples as f64)
        .collect();
    let dens: Vec<f64> = xs
        .iter()
        .map(|&x| pilot.curvature(x).abs().sqrt())
        .collect();
    let mean = dens.iter().sum::<f64>() / dens.len() as f64;
    let floor = 0.25 * mean + 1e-12;
    let mut cum = vec![0.0; xs.len()];
    for k in 1..xs.len() {
        cum[k] = cum[k - 1] + 0.5 * (dens[k] + dens[k - 1] + 2.0 * floor) * (xs[k] - xs[k - 1]);
    }
    let total = cum[xs.len() - 1];
    let mut breaks = vec![lo];
    let mut k = 1;
    for q in 1..m {
        let target = total * q as f64 / m as f64;
        while k < xs.len() - 1 && cum[k] < target {
            k += 1;
        }
        let (c0, c1) = (cum[k - 1], cum[k]);
        let f = if c1 > c0 {
            (target - c0) / (c1 - c0)
        } else {
            0.0
        };
        let x = xs[k - 1] + f * (xs[k] - xs[k - 1]);
        let min_gap = 1e-6 * (hi - lo);
        if x > breaks.last().unwrap() + min_gap && x < hi - min_gap {
            breaks.push(x);
        }
    }
    breaks.push(hi);
    breaks
}

/// Evaluates `kind` with each of `structures`. Feature knots are placed per outer fold from a pilot fitted
/// on that fold's training rows only; all structures share one pass over the points per basis.
pub(super) fn evaluate_all(
    p: &Problem,
    kind: Kind,
    structures: &[Structure],
) -> Vec<Result<Evaluation, FitError>> {
    match evaluate_inner(p, kind, structures) {
        Ok(v) => v,
        Err(e) => structures.iter().map(|_| Err(e.clone())).collect(),
    }
}

fn evaluate_inner(
    p: &Problem,
    kind: Kind,
    structures: &[Structure],
) -> Result<Vec<Result<Evaluation, FitError>>, FitError> {
    let m = intervals(p);
    let uniform = BSplineBasis::uniform(p.lo, p.hi, m)?;
    if kind == Kind::SmoothingSplineUniform {
        let designs = build_many(p, &uniform, structures);
        return Ok(designs
            .iter()
            .map(|d| {
                let mut per_fold = Vec::with_capacity(p.folds);
                for f in 0..p.folds {
                    per_fold.push(d.fit_without(Some(f))?.0);
                }
                let (fin, rho) = d.fit_without(None)?;
                Ok((per_fold, fin, rho))
            })
            .collect());
    }
    // Feature knots: pilot = uniform single-curve smoothing spline on the training folds only.
    let pilot = build_many(p, &uniform, &[Structure::Single]).pop().unwrap();
    let mut per_fold: Vec<Vec<Result<Curves, FitError>>> = vec![Vec::new(); structures.len()];
    let mut finals = Vec::new();
    for exclude in (0..p.folds).map(Some).chain([None]) {
        let (pc, _) = pilot.fit_without(exclude)?;
        let breaks = feature_breaks(&pc.forward, p.lo, p.hi, m);
        let designs = build_many(p, &BSplineBasis::new(breaks)?, structures);
        for (k, d) in designs.iter().enumerate() {
            match exclude {
                Some(_) => per_fold[k].push(d.fit_without(exclude).map(|r| r.0)),
                None => finals.push(d.fit_without(None)),
            }
        }
    }
    Ok(per_fold
        .into_iter()
        .zip(finals)
        .map(|(folds, fin)| {
            let folds = folds.into_iter().collect::<Result<Vec<_>, _>>()?;
            let (fin, rho) = fin?;
            Ok((folds, fin, rho))
        })
        .collect())
}
