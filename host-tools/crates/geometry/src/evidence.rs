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
}

/// The chosen prior.
#[derive(Debug, Clone)]
pub struct Evidence {
    /// Roughness precision α of each group (relative).
    pub roughness: Vec<f64>,
    /// Size precision β of each group (relative).
    pub size: Vec<f64>,
    /// Noise variance σ² (µm²) at the maximum.
    pub sigma2: f64,
    /// `ln p(y)` at the maximum, up to the constant `−n/2·ln 2π`.
    pub log_evidence: f64,
    /// Effective number of parameters the readings determine (Σ over groups of h·tr((Q⁻¹ − M⁻¹)R)).
    pub effective_parameters: f64,
    pub iterations: usize,
    pub converged: bool,
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

/// `tr((Q_b⁻¹ − M⁻¹_bb) R)` and `θ̂_bᵀ R θ̂_b` of block `b` for R = S (roughness) and R = w·I (size).
fn block_terms(b: &PriorBlock, st: &State, alpha: f64, beta: f64, d: f64) -> [(f64, f64); 2] {
    let k = b.cols.len();
    let qb = block_precision(b, alpha, beta, d);
    let q_inv = qb.try_inverse().unwrap_or_else(|| DMatrix::zeros(k, k));
    let mb = DMatrix::from_fn(k, k, |i, j| st.m_inv[(b.cols[i], b.cols[j])]);
    let diff = q_inv - mb;
    let th = DVector::from_fn(k, |i, _| st.theta[b.cols[i]]);
    let rough = ((&diff * &b.rough).trace(), th.dot(&(&b.rough * &th)));
    let size = (diff.trace() * b.weight, th.norm_squared() * b.weight);
    [rough, size]
}

/// Maximises the evidence of normal equations `g θ = r` (`yty` = yᵀy, `n` readings) over each group's
/// α and β by MacKay's fixed-point updates from `start` (α, β), at most `max_iter` steps; `d` is a fixed
/// damping added to every parameter's precision. `None` when the posterior precision cannot be factored.
pub fn maximise(
    g: &DMatrix<f64>,
    r: &DVector<f64>,
    yty: f64,
    n: usize,
    blocks: &[PriorBlock],
    d: f64,
    start: (f64, f64),
    max_iter: usize,
) -> Option<Evidence> {
    let groups = blocks.iter().map(|b| b.group + 1).max().unwrap_or(0);
    let has_rough: Vec<bool> = (0..groups)
        .map(|gi| blocks.iter().any(|b| b.group == gi && b.rough.norm() > 0.0))
        .collect();
    let mut rough: Vec<f64> = has_rough
        .iter()
        .map(|&h| if h { start.0 } else { 0.0 })
        .collect();
    let mut size = vec![start.1; groups];
    let p = g.nrows();
    let (lo, hi) = PRECISION_RANGE;
    let mut it = 0;
    let mut converged = false;
    let mut st = evaluate(g, r, yty, n, &prior_matrix(blocks, &rough, &size, d, p))?;
    let mut gamma = 0.0;
    while it < max_iter {
        it += 1;
        let mut acc = vec![[(0.0, 0.0); 2]; groups];
        for b in blocks {
            let t = block_terms(b, &st, rough[b.group], size[b.group], d);
            for h in 0..2 {
                acc[b.group][h].0 += t[h].0;
                acc[b.group][h].1 += t[h].1 / st.sigma2;
            }
        }
        let mut change = 0.0f64;
        gamma = 0.0;
        for gi in 0..groups {
            for (h, v) in [&mut rough, &mut size].into_iter().enumerate() {
                if h == 0 && !has_rough[gi] {
                    continue;
                }
                let (num, den) = acc[gi][h];
                gamma += v[gi] * num;
                let new = if den > 0.0 {
                    v[gi] * num.max(0.0) / den
                } else {
                    hi
                };
                let new = new.clamp(lo, hi);
                change = change.max((new / v[gi]).ln().abs());
                v[gi] = new;
            }
        }
        st = evaluate(g, r, yty, n, &prior_matrix(blocks, &rough, &size, d, p))?;
        if change < 1e-3 {
            converged = true;
            break;
        }
    }
    Some(Evidence {
        roughness: rough,
        size,
        sigma2: st.sigma2,
        log_evidence: st.log_evidence,
        effective_parameters: gamma,
        iterations: it,
        converged,
    })
}
