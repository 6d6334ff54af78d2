//! The prior of the geometry fit chosen by the training readings' marginal likelihood (empirical Bayes,
//! type-II maximum likelihood).
//!
//! # Glossary
//! - **prior block**: the parameters of one component (its constrained spline coefficients, or a
//!   squareness value) with a Gaussian prior of mean 0 and precision `α·S + (β·w + d)·I`: `S` the
//!   component's second-difference (roughness) penalty, `w` the mean squared norm of its design columns
//!   (so that α and β are relative to the data's weight on it), `d` the fit's fixed damping.
//! - **roughness precision α** and **size precision β**: the two hyperparameters of a prior group (one
//!   component, or several sharing them). A large α makes the function smooth, a large β small.
//! - **evidence**: the marginal likelihood of the training readings `y = Aθ + ε` (ε ~ N(0, σ²I)) with the
//!   prior `θ ~ N(0, σ²Q⁻¹)`: `−2 ln p(y) = n ln σ² + (yᵀy − rᵀθ̂)/σ² + ln det M − ln det Q + const`,
//!   `M = AᵀA + Q` the posterior precision (× σ²), `r = Aᵀy`, `θ̂ = M⁻¹r`. σ² is profiled out:
//!   `σ² = (yᵀy − rᵀθ̂)/n`.
//! - **MacKay update**: the fixed point of the evidence's stationarity in each hyperparameter h scaling
//!   a penalty R: `h ← h · tr((Q⁻¹ − M⁻¹)R) / (θ̂ᵀRθ̂/σ²)`; `h·tr((Q⁻¹ − M⁻¹)R)` is the number of
//!   parameters the data determine against that part of the prior. A component the readings barely see
//!   gets a large β (it shrinks to 0); one they see well a small one.

use axcomp_kinematics::{Component, ComponentKind};
use axcomp_numeric::lsq::cholesky_with_ridge;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// Bounds of the relative precisions α and β (they stay finite so every solve is determined).
pub const PRECISION_RANGE: (f64, f64) = (1e-9, 1e9);

/// How the evidence prior's hyperparameters are shared.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PriorGroups {
    /// Each component its own roughness and size precision.
    Component,
    /// One pair per kind: positioning, straightness, angular, squareness.
    Kind,
    /// One pair for all components.
    Global,
}

/// How [`Method::Auto`] chooses its prior (smoothing and size of the components).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Prior {
    /// One smoothing λ for all components by leave-one-line-out cross-validation, the fixed damping.
    LineCv,
    /// Roughness and size precisions per group by maximising the training readings' evidence.
    Evidence(PriorGroups),
}

pub fn prior_group(c: Component, groups: PriorGroups) -> usize {
    match groups {
        PriorGroups::Component => c.index(),
        PriorGroups::Global => 0,
        PriorGroups::Kind => match c.kind() {
            ComponentKind::Squareness => 3,
            ComponentKind::Angular { .. } => 2,
            _ if c.is_straightness() => 1,
            _ => 0,
        },
    }
}

/// Name of prior group `gi` of `groups`.
pub fn group_name(groups: PriorGroups, gi: usize) -> String {
    match groups {
        PriorGroups::Component => Component::ALL[gi].name().to_string(),
        PriorGroups::Global => "all".to_string(),
        PriorGroups::Kind => {
            ["positioning", "straightness", "angular", "squareness"][gi].to_string()
        }
    }
}

/// One component's parameters and their prior's shape.
#[derive(Debug, Clone)]
pub struct PriorBlock {
    /// Positions of the block's parameters in the solved (active) parameter vector.
    pub cols: Vec<usize>,
    /// Roughness penalty `S` (k × k), already scaled by `w`; zero for a squareness.
    pub rough: DMatrix<f64>,
    /// `w`: mean squared norm of the block's design columns.
    pub weight: f64,
    /// Index of the prior group whose α and β the block uses.
    pub group: usize,
    /// Index of the component (ISO order).
    pub component: usize,
}

/// The chosen prior (serialised as the report's `model.prior`).
#[derive(Debug, Clone, Serialize)]
pub struct Evidence {
    /// The groups sharing α and β: name and member components, indexed like `roughness` and `size`.
    pub groups: Vec<(String, Vec<String>)>,
    /// Roughness precision α of each group (relative).
    pub roughness: Vec<f64>,
    /// Size precision β of each group (relative).
    pub size: Vec<f64>,
    /// Damping `d` added to every parameter's precision (absolute).
    pub damping: f64,
    /// Noise variance σ² (µm²) at the maximum.
    pub sigma2: f64,
    /// `ln p(y)` at the maximum, up to the constant `−n/2·ln 2π`.
    pub log_evidence: f64,
    /// Effective number of parameters the readings determine (Σ over groups of h·tr((Q⁻¹ − M⁻¹)R)).
    pub effective_parameters: f64,
    pub iterations: usize,
    pub converged: bool,
    /// Order of the roughness penalty (the difference of the spline coefficients it penalises).
    pub roughness_order: usize,
    /// The knot grids (intervals X, Y, Z) and roughness orders compared and their `ln p(y)` (empty when
    /// the grid was given).
    pub knot_grids: Vec<PriorCandidate>,
}

/// One knot grid and roughness order the evidence compared.
#[derive(Debug, Clone, Serialize)]
pub struct PriorCandidate {
    /// Knot intervals X, Y, Z.
    pub intervals: [usize; 3],
    pub roughness_order: usize,
    /// `ln p(y)` at its maximum over the precisions.
    pub log_evidence: f64,
}

/// The prior precision `Q` (p × p) of hyperparameters `rough`, `size` (per group) and damping `d`.
pub fn prior_matrix(
    blocks: &[PriorBlock],
    rough: &[f64],
    size: &[f64],
    d: f64,
    p: usize,
) -> DMatrix<f64> {
    let mut q = DMatrix::identity(p, p) * d;
    for b in blocks {
        let qb = block_precision(b, rough[b.group], size[b.group], d);
        for (i, &ci) in b.cols.iter().enumerate() {
            for (j, &cj) in b.cols.iter().enumerate() {
                q[(ci, cj)] = qb[(i, j)];
            }
        }
    }
    q
}

fn block_precision(b: &PriorBlock, alpha: f64, beta: f64, d: f64) -> DMatrix<f64> {
    let k = b.cols.len();
    &b.rough * alpha + DMatrix::identity(k, k) * (beta * b.weight + d)
}

/// One evaluation at the current hyperparameters: θ̂, M⁻¹, σ² and ln p(y).
struct State {
    theta: DVector<f64>,
    m_inv: DMatrix<f64>,
    sigma2: f64,
    log_evidence: f64,
}

fn evaluate(
    g: &DMatrix<f64>,
    r: &DVector<f64>,
    yty: f64,
    n: usize,
    q: &DMatrix<f64>,
) -> Option<State> {
    let m = g + q;
    let ch = cholesky_with_ridge(&m)?;
    let theta = ch.solve(r);
    let sigma2 = ((yty - r.dot(&theta)) / n as f64).max(1e-12);
    let ld_m: f64 = 2.0 * ch.l().diagonal().iter().map(|x| x.ln()).sum::<f64>();
    let ld_q: f64 = 2.0
        * q.clone()
            .cholesky()?
            .l()
            .diagonal()
            .iter()
            .map(|x| x.ln())
            .sum::<f64>();
    let log_evidence = -0.5 * (n as f64 * sigma2.ln() + n as f64 + ld_m - ld_q);
    Some(State {
        theta,
        m_inv: ch.inverse(),
        sigma2,
        log_evidence,
    })
}

/// `tr((Q_b⁻¹ − M⁻¹_bb) R)` and `θ̂_bᵀ R θ̂_b` of block `b` for R = S (roughness), R = w·I (size) and
/// R = I (damping).
fn block_terms(b: &PriorBlock, st: &State, alpha: f64, beta: f64, d: f64) -> [(f64, f64); 3] {
    let k = b.cols.len();
    let qb = block_precision(b, alpha, beta, d);
    let q_inv = qb.try_inverse().unwrap_or_else(|| DMatrix::zeros(k, k));
    let mb = DMatrix::from_fn(k, k, |i, j| st.m_inv[(b.cols[i], b.cols[j])]);
    let diff = q_inv - mb;
    let th = DVector::from_fn(k, |i, _| st.theta[b.cols[i]]);
    let rough = ((&diff * &b.rough).trace(), th.dot(&(&b.rough * &th)));
    let plain = (diff.trace(), th.norm_squared());
    [rough, (plain.0 * b.weight, plain.1 * b.weight), plain]
}

/// The training readings' normal equations: `g θ = r`, `yty` = yᵀy, `n` readings.
pub struct Normal<'a> {
    pub g: &'a DMatrix<f64>,
    pub r: &'a DVector<f64>,
    pub yty: f64,
    pub n: usize,
}

/// Where the search starts: α and β of every group, the damping `d` (absolute, added to every
/// parameter's precision), and whether `d` is a hyperparameter too (then kept within
/// [`PRECISION_RANGE`] × the mean diagonal of `g`).
#[derive(Debug, Clone, Copy)]
pub struct Start {
    pub roughness: f64,
    pub size: f64,
    pub damping: f64,
    pub free_damping: bool,
}

/// One MacKay step: each hyperparameter `v` scaled by the ratio `v·num/den` → `v·num/den` (clamped to
/// `range`), returning the largest |ln change|.
fn mackay_step(v: &mut f64, (num, den): (f64, f64), range: (f64, f64)) -> f64 {
    let new = if den > 0.0 {
        *v * num.max(0.0) / den
    } else {
        range.1
    };
    let new = new.clamp(range.0, range.1);
    let change = (new / *v).ln().abs();
    *v = new;
    change
}

/// `ln p(y)` (up to `−n/2·ln 2π`) of `normal` with hyperparameters `rough`, `size` (per group) and
/// damping `d`; `None` when the posterior precision cannot be factored.
pub fn log_evidence(
    normal: &Normal,
    blocks: &[PriorBlock],
    rough: &[f64],
    size: &[f64],
    d: f64,
) -> Option<f64> {
    let q = prior_matrix(blocks, rough, size, d, normal.g.nrows());
    evaluate(normal.g, normal.r, normal.yty, normal.n, &q).map(|s| s.log_evidence)
}

/// Maximises the evidence of `normal` over each group's α and β (and the damping when free) by
/// MacKay's fixed-point updates from `start`, at most `max_iter` steps. `None` when the posterior
/// precision cannot be factored.
pub fn maximise(
    normal: &Normal,
    blocks: &[PriorBlock],
    start: Start,
    max_iter: usize,
) -> Option<Evidence> {
    let (g, r) = (normal.g, normal.r);
    let groups = blocks.iter().map(|b| b.group + 1).max().unwrap_or(0);
    let has_rough: Vec<bool> = (0..groups)
        .map(|gi| blocks.iter().any(|b| b.group == gi && b.rough.norm() > 0.0))
        .collect();
    let mut rough: Vec<f64> = has_rough
        .iter()
        .map(|&h| if h { start.roughness } else { 0.0 })
        .collect();
    let mut size = vec![start.size; groups];
    let mut d = start.damping;
    let p = g.nrows();
    let mean_diag = g.trace() / p.max(1) as f64;
    let d_range = (PRECISION_RANGE.0 * mean_diag, PRECISION_RANGE.1 * mean_diag);
    let solve = |rough: &[f64], size: &[f64], d: f64| {
        evaluate(
            g,
            r,
            normal.yty,
            normal.n,
            &prior_matrix(blocks, rough, size, d, p),
        )
    };
    let mut st = solve(&rough, &size, d)?;
    let (mut it, mut converged, mut gamma) = (0, false, 0.0);
    while it < max_iter && !converged {
        it += 1;
        let mut acc = vec![[(0.0, 0.0); 3]; groups];
        let mut acc_d = (0.0, 0.0);
        for b in blocks {
            let t = block_terms(b, &st, rough[b.group], size[b.group], d);
            for h in 0..2 {
                acc[b.group][h].0 += t[h].0;
                acc[b.group][h].1 += t[h].1 / st.sigma2;
            }
            acc_d = (acc_d.0 + t[2].0, acc_d.1 + t[2].1 / st.sigma2);
        }
        let mut change = 0.0f64;
        gamma = 0.0;
        for gi in 0..groups {
            if has_rough[gi] {
                gamma += rough[gi] * acc[gi][0].0;
                change = change.max(mackay_step(&mut rough[gi], acc[gi][0], PRECISION_RANGE));
            }
            gamma += size[gi] * acc[gi][1].0;
            change = change.max(mackay_step(&mut size[gi], acc[gi][1], PRECISION_RANGE));
        }
        if start.free_damping {
            gamma += d * acc_d.0;
            change = change.max(mackay_step(&mut d, acc_d, d_range));
        }
        st = solve(&rough, &size, d)?;
        converged = change < 1e-3;
    }
    Some(Evidence {
        groups: Vec::new(),
        knot_grids: Vec::new(),
        roughness_order: 2,
        roughness: rough,
        size,
        damping: d,
        sigma2: st.sigma2,
        log_evidence: st.log_evidence,
        effective_parameters: gamma,
        iterations: it,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth function sampled with noise σ = 0.1 on 40 points, fitted by 12 coefficients of a
    /// piecewise-linear hat basis in two blocks (the function, and the function × x), a third block
    /// the data never see. Reference: the evidence's maximum itself — moving any hyperparameter of the
    /// result by a factor of 1.3 either way lowers `ln p(y)` (tolerance 1e-6), the noise estimate is
    /// within a factor of 1.5 of the true σ², and the unseen block gets the largest size precision.
    #[test]
    fn mackay_updates_reach_the_evidence_maximum() {
        let n = 40;
        let k = 6;
        let hat = |x: f64, j: usize| (1.0 - ((x * (k - 1) as f64) - j as f64).abs()).max(0.0);
        let a = DMatrix::from_fn(n, 3 * k, |i, j| {
            let x = i as f64 / (n - 1) as f64;
            match j / k {
                0 => hat(x, j % k),
                1 => hat(x, j % k) * x,
                _ => 0.0,
            }
        });
        let mut rng = axcomp_numeric::noise::rng(7);
        let noise: Vec<f64> = (0..n)
            .map(|_| axcomp_numeric::noise::gauss(&mut rng, 0.1))
            .collect();
        let y = DVector::from_fn(n, |i, _| {
            let x = i as f64 / (n - 1) as f64;
            (3.0 * x).sin() + noise[i]
        });
        let g = a.transpose() * &a;
        let r = a.transpose() * &y;
        let normal = Normal {
            g: &g,
            r: &r,
            yty: y.norm_squared(),
            n,
        };
        let mut d2 = DMatrix::zeros(k - 2, k);
        for i in 0..k - 2 {
            d2[(i, i)] = 1.0;
            d2[(i, i + 1)] = -2.0;
            d2[(i, i + 2)] = 1.0;
        }
        let rough = d2.transpose() * d2;
        let blocks: Vec<PriorBlock> = (0..3)
            .map(|b| PriorBlock {
                cols: (b * k..(b + 1) * k).collect(),
                rough: rough.clone(),
                weight: 1.0,
                group: b,
                component: b,
            })
            .collect();
        let start = Start {
            roughness: 1.0,
            size: 1.0,
            damping: 1e-6,
            free_damping: false,
        };
        let ev = maximise(&normal, &blocks, start, 500).expect("factorable");
        assert!(ev.converged, "{ev:?}");
        let best = log_evidence(&normal, &blocks, &ev.roughness, &ev.size, ev.damping).unwrap();
        assert!((best - ev.log_evidence).abs() < 1e-9);
        for gi in 0..2 {
            for f in [1.3, 1.0 / 1.3] {
                let mut ro = ev.roughness.clone();
                ro[gi] = (ro[gi] * f).clamp(PRECISION_RANGE.0, PRECISION_RANGE.1);
                let l = log_evidence(&normal, &blocks, &ro, &ev.size, ev.damping).unwrap();
                assert!(l <= best + 1e-6, "roughness {gi} × {f}: {l} > {best}");
                let mut si = ev.size.clone();
                si[gi] = (si[gi] * f).clamp(PRECISION_RANGE.0, PRECISION_RANGE.1);
                let l = log_evidence(&normal, &blocks, &ev.roughness, &si, ev.damping).unwrap();
                assert!(l <= best + 1e-6, "size {gi} × {f}: {l} > {best}");
            }
        }
        assert!(
            ev.sigma2 > 0.01 / 1.5 && ev.sigma2 < 0.01 * 1.5,
            "σ² {}",
            ev.sigma2
        );
        assert!(ev.size[2] >= ev.size[0].max(ev.size[1]), "{:?}", ev.size);
    }
}
